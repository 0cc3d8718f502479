//! `relief-server bench compare`: every stream over the same path at the same *measured* pixel
//! error (DESIGN.md section 7).
//!
//! For each stream, the threshold tau is tuned until the measured p99 pixel error (the median
//! over measured frames of each frame's 99th percentile, as `bench lod` and `bench tiles`
//! report it) is within `--within` (5 %) of the target; then its bytes, triangles and costs are
//! read from that run. The tuning starts at tau = target, scales tau by target / measured until
//! the two sides are bracketed, then interpolates in log-log space between the bracket's ends,
//! at least a quarter of the way in from either (at most `--tries` flights). A stream whose error cannot be brought into the band (a finest
//! level that is not exact enough, a threshold the selection ignores) is reported with its
//! closest flight and `converged: false`.
//!
//! Streams: `vertex` (the Haar vertex stream); `tiles/grid+skirts` (the Cesium-style baseline,
//! each tile sent once into an unlimited client cache); `tiles/grid+patches`;
//! `tiles/rqt+skirts` and `tiles/rqt+patches` (paper 002's mesh, with skirts or with its crack
//! curtains, paper 001's patches generalised); `tiles/tin+shared-borders` (paper 003,
//! crack-free by its shared border points). One store is built per mesh
//! kind and flown at every threshold. Bytes are the messages as they go on the WebSocket, raw
//! and with each message gzipped.
//!
//! The baseline's tiles are also encoded as Cesium quantized-mesh tiles (the standard formats' encoder,
//! each tile gzipped on its own as a tile server sends it), reported beside it as
//! `quantized-mesh`: the same tiles, tau and error, in the standard format.
//!
//! The curve: each stream is also tuned to the target's other `--levels` (e.g. 0.5x and 2x),
//! which gives bytes against measured error at three error levels, plotted to an SVG.

use super::flight::{CostSummary, Flight, PxSummary, WireSummary};
use super::{lod, tiles};
use crate::dem::Dem;
use crate::preprocess::BuildOptions;
use relief_proto::msg::CrackMode;
use relief_proto::path::PathKind;
use relief_proto::tile::body::MeshKind;
use serde::Serialize;

/// What to run.
#[derive(Clone, Debug)]
pub struct CompareOptions {
    /// Which path to fly.
    pub path: PathKind,
    /// The measured p99 pixel error every stream is tuned to.
    pub target_px: f64,
    /// How close the measured p99 must come, as a fraction of the target.
    pub within: f64,
    /// Error levels for the curve, as multiples of the target (1 is always flown).
    pub levels: Vec<f64>,
    /// Flights per stream and level at most.
    pub tries: usize,
    /// Tile size, cells.
    pub tile_size: u32,
    /// Measure pixel error on every k-th frame (`None`: at least 60 frames).
    pub px_every: Option<usize>,
    /// Fly only the path's first poses (`None`: all).
    pub poses: Option<usize>,
    /// Only these streams (`None`: all).
    pub only: Option<Vec<String>>,
    /// Show progress on stderr.
    pub progress: bool,
}

impl Default for CompareOptions {
    fn default() -> Self {
        CompareOptions {
            path: PathKind::Standard,
            target_px: 1.0,
            within: 0.05,
            levels: vec![0.5, 2.0],
            tries: 10,
            tile_size: crate::store::DEFAULT_TILE_SIZE,
            px_every: None,
            poses: None,
            only: None,
            progress: false,
        }
    }
}

/// A stream to compare.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StreamSpec {
    /// The vertex stream.
    Vertex,
    /// The tile stream with this mesh and crack strategy.
    Tiles(MeshKind, CrackMode),
}

impl StreamSpec {
    /// The Cesium-style baseline, `tiles/grid+skirts` (also reported as quantized-mesh bytes).
    pub const BASELINE: StreamSpec = StreamSpec::Tiles(MeshKind::Grid, CrackMode::Skirts);

    /// Every stream, in report order.
    pub const ALL: [StreamSpec; 6] = [
        StreamSpec::Vertex,
        StreamSpec::Tiles(MeshKind::Grid, CrackMode::Skirts),
        StreamSpec::Tiles(MeshKind::Grid, CrackMode::Patches),
        StreamSpec::Tiles(MeshKind::Rqt, CrackMode::Skirts),
        StreamSpec::Tiles(MeshKind::Rqt, CrackMode::Patches),
        StreamSpec::Tiles(MeshKind::Tin, CrackMode::Patches),
    ];

    /// Its name in the report.
    pub fn name(self) -> String {
        match self {
            StreamSpec::Vertex => "vertex".into(),
            StreamSpec::Tiles(m, c) => {
                let crack = match (m, c) {
                    (MeshKind::Tin, CrackMode::Patches) => "shared-borders",
                    (_, CrackMode::Patches) => "patches",
                    (_, CrackMode::Skirts) => "skirts",
                    (_, CrackMode::None) => "none",
                };
                format!("tiles/{}+{crack}", m.name())
            }
        }
    }

    /// The mesh kind its store needs.
    fn mesh(self) -> MeshKind {
        match self {
            StreamSpec::Vertex => MeshKind::Grid,
            StreamSpec::Tiles(m, _) => m,
        }
    }
}

/// One flight of a stream at one threshold.
#[derive(Clone, Debug, Serialize)]
pub struct Flown {
    /// The threshold, pixels.
    pub tau: f64,
    /// Measured p99 pixel error (median over measured frames).
    pub p99_px: f64,
    /// Bytes over the whole path, raw.
    pub bytes_total: u64,
    /// Same, each message gzipped.
    pub gzip_bytes_total: u64,
    /// Raw bytes per second after the first frame: mean and p99 of one-second bins.
    pub bytes_per_s: (f64, f64),
    /// Gzipped, the same.
    pub gzip_bytes_per_s: (f64, f64),
    /// Triangles drawn per frame, median.
    pub triangles_median: f64,
    /// Server microseconds per update, median.
    pub server_us_median: f64,
    /// Client microseconds per update, median.
    pub client_us_median: f64,
    /// Deltas the client could not apply.
    pub desyncs: u64,
    /// For `tiles/grid+skirts`: the same tiles sent as Cesium quantized-mesh tiles (each
    /// gzipped on its own), the standard-format baseline.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub quantized_mesh: Option<WireSummary>,
}

impl Flown {
    /// A flight's figures from a bench report's parts.
    fn of(
        tau: f64,
        px: &PxSummary,
        wire: &WireSummary,
        triangles_median: f64,
        cost: &CostSummary,
        desyncs: u64,
    ) -> Flown {
        Flown {
            tau,
            p99_px: px.px_error_p99_median,
            bytes_total: wire.bytes_total,
            gzip_bytes_total: wire.gzip_bytes_total,
            bytes_per_s: (wire.bytes_per_s_mean, wire.bytes_per_s_p99),
            gzip_bytes_per_s: (wire.gzip_bytes_per_s_mean, wire.gzip_bytes_per_s_p99),
            triangles_median,
            server_us_median: cost.update_us_median,
            client_us_median: cost.client_us_median,
            desyncs,
            quantized_mesh: None,
        }
    }
}

/// A stream tuned to one error level.
#[derive(Clone, Debug, Serialize)]
pub struct Tuned {
    /// The target p99, pixels.
    pub target_px: f64,
    /// Whether a flight came within the band.
    pub converged: bool,
    /// The flight closest to the target (the one reported).
    pub best: Flown,
    /// Every flight, in order: (tau, measured p99).
    pub tries: Vec<(f64, f64)>,
}

/// One stream's results.
#[derive(Clone, Debug, Serialize)]
pub struct StreamResult {
    /// Its name.
    pub stream: String,
    /// At the target error.
    pub at_target: Tuned,
    /// At the other levels (for the curve).
    pub curve: Vec<Tuned>,
}

/// The whole comparison.
#[derive(Clone, Debug, Serialize)]
pub struct CompareReport {
    /// The DEM.
    pub dem: String,
    /// Grid size, samples.
    pub width: u32,
    /// Grid size, samples.
    pub height: u32,
    /// The path flown.
    pub path: String,
    /// Poses flown.
    pub frames: usize,
    /// The target p99, pixels.
    pub target_px: f64,
    /// The band's half-width, fraction of the target.
    pub within: f64,
    /// Tile size, cells.
    pub tile_size: u32,
    /// Seconds each store took to build, by mesh kind.
    pub build_s: Vec<(String, f64)>,
    /// Each stream.
    pub streams: Vec<StreamResult>,
    /// The vertex stream's total gzipped bytes over the baseline's (`tiles/grid+skirts`), at
    /// the target (at most 0.25).
    pub vertex_over_baseline: Option<f64>,
}

/// Flies `spec` over `flight` at `tau`.
fn fly(
    dem: &Dem,
    flight: &Flight,
    spec: StreamSpec,
    tau: f64,
    o: &CompareOptions,
) -> anyhow::Result<Flown> {
    Ok(match spec {
        StreamSpec::Vertex => {
            let mut opts = lod::LodBenchOptions {
                path: o.path,
                px_every: o.px_every,
                poses: o.poses,
                oracle_frames: 1,
                cross_checks: false,
                ..Default::default()
            };
            opts.params.tau = tau as f32;
            let r = lod::fly(dem, flight, &opts)?;
            let (px, wire) = (r.px, r.wire);
            Flown::of(tau, &px, &wire, r.triangles_median, &r.cost, r.desyncs)
        }
        StreamSpec::Tiles(mesh, crack) => {
            let opts = tiles::TileBenchOptions {
                path: o.path,
                tau: tau as f32,
                crack,
                tile_size: o.tile_size,
                tile_mesh: mesh,
                px_every: o.px_every,
                poses: o.poses,
                cross_checks: false,
                quantized_mesh: spec == StreamSpec::BASELINE,
                ..Default::default()
            };
            let r = tiles::fly(dem, flight, &opts)?;
            Flown {
                quantized_mesh: r.quantized_mesh,
                ..Flown::of(tau, &r.px, &r.wire, r.triangles_median, &r.cost, r.desyncs)
            }
        }
    })
}

/// The next threshold to try for `target`, from the flights so far (see the module docs).
pub fn next_tau(tries: &[(f64, f64)], target: f64) -> f64 {
    let Some(&(tau, p)) = tries.last() else {
        return target;
    };
    let below = tries
        .iter()
        .filter(|t| t.1 < target && t.1 > 0.0)
        .max_by(|a, b| a.0.total_cmp(&b.0));
    let above = tries
        .iter()
        .filter(|t| t.1 > target)
        .min_by(|a, b| a.0.total_cmp(&b.0));
    match (below, above) {
        (Some(&(t0, p0)), Some(&(t1, p1))) if t1 > t0 && p1 > p0 => {
            // Log-log interpolation between the bracket's ends, kept off them so that the
            // bracket shrinks by a quarter at least (the error is a step function of tau).
            let f = ((target.ln() - p0.ln()) / (p1.ln() - p0.ln())).clamp(0.25, 0.75);
            (t0.ln() + f * (t1.ln() - t0.ln())).exp()
        }
        (Some(&(t0, _)), Some(&(t1, _))) => (t0 * t1).sqrt(),
        _ if p <= 0.0 => tau * 4.0,
        _ => tau * (target / p).clamp(0.125, 8.0),
    }
}

/// Tunes `spec` to `target` on `flight`.
fn tune(
    dem: &Dem,
    flight: &Flight,
    spec: StreamSpec,
    target: f64,
    o: &CompareOptions,
) -> anyhow::Result<Tuned> {
    let mut tries = Vec::new();
    let mut best: Option<Flown> = None;
    for _ in 0..o.tries.max(1) {
        let tau = next_tau(&tries, target);
        if tries
            .iter()
            .any(|t: &(f64, f64)| (t.0 - tau).abs() <= 1e-6 * tau)
        {
            break;
        }
        let f = fly(dem, flight, spec, tau, o)?;
        if o.progress {
            eprintln!(
                "{:>26}  target {target:.2} px  tau {tau:8.3}  p99 {:.3} px",
                spec.name(),
                f.p99_px
            );
        }
        tries.push((tau, f.p99_px));
        let off = |f: &Flown| (f.p99_px / target).ln().abs();
        let done = (f.p99_px - target).abs() <= o.within * target;
        if best.as_ref().is_none_or(|b| off(&f) < off(b)) {
            best = Some(f);
        }
        if done {
            break;
        }
    }
    let best = best.ok_or_else(|| anyhow::anyhow!("no flight"))?;
    Ok(Tuned {
        target_px: target,
        converged: (best.p99_px - target).abs() <= o.within * target,
        best,
        tries,
    })
}

/// Runs the comparison on `dem`.
pub fn run(dem: &Dem, o: &CompareOptions) -> anyhow::Result<CompareReport> {
    let specs: Vec<StreamSpec> = StreamSpec::ALL
        .into_iter()
        .filter(|s| o.only.as_ref().is_none_or(|only| only.contains(&s.name())))
        .collect();
    if specs.is_empty() {
        anyhow::bail!(
            "--only names no stream; the streams are {}",
            StreamSpec::ALL.map(|s| s.name()).join(", ")
        );
    }
    let mut streams = Vec::new();
    let mut build_s = Vec::new();
    let mut frames = 0;
    for mesh in [MeshKind::Grid, MeshKind::Rqt, MeshKind::Tin] {
        let mine: Vec<StreamSpec> = specs.iter().copied().filter(|s| s.mesh() == mesh).collect();
        if mine.is_empty() {
            continue;
        }
        if o.progress {
            eprintln!("building the {} store", mesh.name());
        }
        let build = BuildOptions {
            tile_size: o.tile_size,
            tile_mesh: mesh,
            ..Default::default()
        };
        let flight = Flight::prepare(dem, o.path, build, o.px_every, 4_000_000, o.progress)?
            .first_poses(o.poses);
        frames = flight.cams.len();
        build_s.push((
            mesh.name().to_string(),
            flight.built.tree_s + flight.built.tiles_s,
        ));
        for spec in mine {
            let at_target = tune(dem, &flight, spec, o.target_px, o)?;
            let mut curve = Vec::new();
            for &l in &o.levels {
                curve.push(tune(dem, &flight, spec, o.target_px * l, o)?);
            }
            streams.push(StreamResult {
                stream: spec.name(),
                at_target,
                curve,
            });
        }
    }
    streams.sort_by_key(|s| {
        StreamSpec::ALL
            .iter()
            .position(|a| a.name() == s.stream)
            .unwrap_or(usize::MAX)
    });
    let gz = |name: &str| {
        streams
            .iter()
            .find(|s| s.stream == name)
            .map(|s| s.at_target.best.gzip_bytes_total as f64)
    };
    let vertex_over_baseline = match (gz("vertex"), gz("tiles/grid+skirts")) {
        (Some(v), Some(b)) if b > 0.0 => Some(v / b),
        _ => None,
    };
    Ok(CompareReport {
        dem: dem.source.clone(),
        width: dem.width,
        height: dem.height,
        path: format!("{:?}", o.path).to_lowercase(),
        frames,
        target_px: o.target_px,
        within: o.within,
        tile_size: o.tile_size,
        build_s,
        streams,
        vertex_over_baseline,
    })
}

/// The report as a Markdown table (what `bench compare` prints without `--json`).
pub fn markdown(r: &CompareReport) -> String {
    let mut s = format!(
        "# Streams at equal measured error\n\n{} ({} x {}), path `{}`, {} poses; every stream tuned \
         to a measured p99 of {:.2} px (within {:.0} %). Bytes: each message as sent, and gzipped.\n\n",
        r.dem,
        r.width,
        r.height,
        r.path,
        r.frames,
        r.target_px,
        r.within * 100.0
    );
    s.push_str(
        "| stream | tau | p99 px | total bytes | gzip total | gzip B/s mean | gzip B/s p99 | \
         triangles (median) | server us | client us | desyncs |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for st in &r.streams {
        let t = &st.at_target;
        let b = &t.best;
        s.push_str(&format!(
            "| {}{} | {:.3} | {:.3} | {} | {} | {:.0} | {:.0} | {:.0} | {:.1} | {:.1} | {} |\n",
            st.stream,
            if t.converged { "" } else { " (not converged)" },
            b.tau,
            b.p99_px,
            b.bytes_total,
            b.gzip_bytes_total,
            b.gzip_bytes_per_s.0,
            b.gzip_bytes_per_s.1,
            b.triangles_median,
            b.server_us_median,
            b.client_us_median,
            b.desyncs
        ));
        if let Some(q) = &b.quantized_mesh {
            s.push_str(&format!(
                "| quantized-mesh (the same tiles) | {:.3} | {:.3} | {} | {} | {:.0} | {:.0} | {:.0} | | | |\n",
                b.tau,
                b.p99_px,
                q.bytes_total,
                q.gzip_bytes_total,
                q.gzip_bytes_per_s_mean,
                q.gzip_bytes_per_s_p99,
                b.triangles_median,
            ));
        }
    }
    if let Some(v) = r.vertex_over_baseline {
        s.push_str(&format!(
            "\nVertex stream over the baseline (gzip bytes over the path): {v:.3}x.\n"
        ));
    }
    s.push_str(
        "\n## Bytes against measured error\n\n| stream | p99 px | gzip total |\n|---|---|---|\n",
    );
    for st in &r.streams {
        let mut pts: Vec<&Tuned> = std::iter::once(&st.at_target).chain(&st.curve).collect();
        pts.sort_by(|a, b| a.best.p99_px.total_cmp(&b.best.p99_px));
        for t in &pts {
            s.push_str(&format!(
                "| {} | {:.3} | {} |\n",
                st.stream, t.best.p99_px, t.best.gzip_bytes_total
            ));
        }
        for t in &pts {
            if let Some(q) = &t.best.quantized_mesh {
                s.push_str(&format!(
                    "| quantized-mesh ({} tiles) | {:.3} | {} |\n",
                    st.stream, t.best.p99_px, q.gzip_bytes_total
                ));
            }
        }
    }
    s
}

/// Bytes (gzipped, over the path) against measured p99 pixel error, one line per stream, both
/// axes logarithmic, as SVG.
pub fn svg(r: &CompareReport) -> String {
    let (w, h, ml, mr, mt, mb) = (760.0, 460.0, 80.0, 220.0, 40.0, 50.0);
    let series = |st: &StreamResult, bytes: &dyn Fn(&Flown) -> Option<u64>| {
        let mut v: Vec<(f64, f64)> = std::iter::once(&st.at_target)
            .chain(&st.curve)
            .filter_map(|t| Some((t.best.p99_px, bytes(&t.best)? as f64)))
            .filter(|p| p.0 > 0.0 && p.1 > 0.0)
            .collect();
        v.sort_by(|a, b| a.0.total_cmp(&b.0));
        v
    };
    let mut pts: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for st in &r.streams {
        pts.push((st.stream.clone(), series(st, &|f| Some(f.gzip_bytes_total))));
        let qm = series(st, &|f| f.quantized_mesh.map(|q| q.gzip_bytes_total));
        if !qm.is_empty() {
            pts.push(("quantized-mesh".into(), qm));
        }
    }
    let all = pts.iter().flat_map(|p| p.1.iter());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in all {
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    if x0 > x1 {
        (x0, x1, y0, y1) = (0.5, 2.0, 1.0, 10.0);
    }
    let (lx0, lx1) = ((x0 / 1.2).log10(), (x1 * 1.2).log10());
    let (ly0, ly1) = ((y0 / 1.5).log10(), (y1 * 1.5).log10());
    let px = |x: f64| ml + (x.log10() - lx0) / (lx1 - lx0) * (w - ml - mr);
    let py = |y: f64| h - mb - (y.log10() - ly0) / (ly1 - ly0) * (h - mt - mb);
    let colours = [
        "#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#7f7f7f",
    ];
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" font-family=\"sans-serif\" font-size=\"12\">\n\
         <rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n\
         <text x=\"{ml}\" y=\"22\" font-size=\"14\">{}: gzipped bytes over the path against measured p99 pixel error</text>\n\
         <rect x=\"{ml}\" y=\"{mt}\" width=\"{}\" height=\"{}\" fill=\"none\" stroke=\"#888\"/>\n",
        r.dem,
        w - ml - mr,
        h - mt - mb
    );
    // Decade ticks on y, and the measured error levels on x.
    let mut d = 10f64.powf(ly0.floor());
    while d <= 10f64.powf(ly1) {
        if d.log10() >= ly0 {
            s.push_str(&format!(
                "<line x1=\"{ml}\" x2=\"{}\" y1=\"{y:.1}\" y2=\"{y:.1}\" stroke=\"#eee\"/><text x=\"{}\" y=\"{:.1}\" text-anchor=\"end\">{d:.0e}</text>\n",
                w - mr,
                ml - 6.0,
                py(d) + 4.0,
                y = py(d)
            ));
        }
        d *= 10.0;
    }
    for l in [0.25, 0.5, 1.0, 2.0, 4.0] {
        let lx = l * r.target_px;
        if lx.log10() >= lx0 && lx.log10() <= lx1 {
            s.push_str(&format!(
                "<line x1=\"{x:.1}\" x2=\"{x:.1}\" y1=\"{mt}\" y2=\"{}\" stroke=\"#eee\"/><text x=\"{x:.1}\" y=\"{}\" text-anchor=\"middle\">{lx}</text>\n",
                h - mb,
                h - mb + 16.0,
                x = px(lx)
            ));
        }
    }
    s.push_str(&format!(
        "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">measured p99 pixel error</text>\n",
        ml + (w - ml - mr) / 2.0,
        h - 12.0
    ));
    for (k, (name, v)) in pts.iter().enumerate() {
        let c = colours[k % colours.len()];
        let line: Vec<String> = v
            .iter()
            .map(|&(x, y)| format!("{:.1},{:.1}", px(x), py(y)))
            .collect();
        s.push_str(&format!(
            "<polyline points=\"{}\" fill=\"none\" stroke=\"{c}\" stroke-width=\"2\"/>\n",
            line.join(" ")
        ));
        for &(x, y) in v {
            s.push_str(&format!(
                "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"3.5\" fill=\"{c}\"/>\n",
                px(x),
                py(y)
            ));
        }
        let ly = mt + 20.0 + 20.0 * k as f64;
        s.push_str(&format!(
            "<line x1=\"{}\" x2=\"{}\" y1=\"{ly}\" y2=\"{ly}\" stroke=\"{c}\" stroke-width=\"2\"/><text x=\"{}\" y=\"{}\">{name}</text>\n",
            w - mr + 12.0,
            w - mr + 36.0,
            w - mr + 42.0,
            ly + 4.0
        ));
    }
    s.push_str("</svg>\n");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tau_moves_towards_the_target_then_interpolates_inside_the_bracket() {
        assert_eq!(next_tau(&[], 1.0), 1.0);
        // Error proportional to tau: one step lands on it.
        assert!((next_tau(&[(1.0, 0.25)], 1.0) - 4.0).abs() < 1e-9);
        // Far off: the step is clamped.
        assert!((next_tau(&[(1.0, 0.01)], 1.0) - 8.0).abs() < 1e-9);
        assert!((next_tau(&[(1.0, 0.0)], 1.0) - 4.0).abs() < 1e-9);
        // Bracketed: p = tau^2 between (1, 1) ... (4, 16), target 4 -> tau 2.
        let t = next_tau(&[(1.0, 1.0), (4.0, 16.0)], 4.0);
        assert!((t - 2.0).abs() < 1e-9, "{t}");
        // Near an end: a quarter of the way in (log tau), not at the end.
        let t = next_tau(&[(1.0, 0.01), (16.0, 1.1)], 1.0);
        assert!((t - 8.0).abs() < 1e-9, "{t}");
        // Inside the bracket whatever the order of the tries.
        let t = next_tau(&[(4.0, 16.0), (1.0, 1.0), (3.0, 9.5)], 4.0);
        assert!(t > 1.0 && t < 3.0, "{t}");
    }

    #[test]
    fn stream_names_are_the_issues() {
        let names: Vec<String> = StreamSpec::ALL.iter().map(|s| s.name()).collect();
        assert_eq!(
            names,
            [
                "vertex",
                "tiles/grid+skirts",
                "tiles/grid+patches",
                "tiles/rqt+skirts",
                "tiles/rqt+patches",
                "tiles/tin+shared-borders"
            ]
        );
    }
}
