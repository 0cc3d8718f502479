//! Figures of paper 002's fractal-dimension region tree on the shared real DEMs.
//!
//! ```text
//! cargo run --release -p relief-server --example fractal_figure -- OUTDIR
//! ```
//!
//! - `OUTDIR/fractal_histogram.svg`: the box-counting dimension of every 64-cell tile of the
//!   finest pyramid level of each DEM, with the default thresholds: the figure that justifies
//!   them (`docs/fractal.md`);
//! - `OUTDIR/{dem}_leaves.png`: the region tree's leaves over the DEM's hillshade, tinted by
//!   dimension (blue at or below `flat`, red at or above `rough`);
//! - on stdout: the dimension's quantiles per DEM and level, the leaves per level, and how
//!   the dimension of a finest tile predicts its `rqt` triangles and its grid error.

#[path = "common/dems.rs"]
mod dems;

use relief_proto::tile::TileShape;
use relief_proto::tile::body::grid_height;
use relief_server::dem::Dem;
use relief_server::lod::tile::mesh::HeightGrid;
use relief_server::lod::tile::mesh::fractal::{FractalParams, box_dimension, fractal_leaves};
use relief_server::lod::tile::mesh::rqt::RqtErrors;
use std::fmt::Write as _;
use std::path::Path;

/// Tolerance, metres, at which tiles are meshed for the correlation.
const TOL: f32 = 5.0;

fn main() -> anyhow::Result<()> {
    let out = std::env::args().nth(1).unwrap_or_else(|| ".".into());
    let out = Path::new(&out);
    std::fs::create_dir_all(out)?;
    let p = FractalParams::default();
    let mut series = Vec::new();
    let mut pairs = Vec::new();
    for name in dems::NAMES {
        let dem = dems::load(name)?;
        let g = HeightGrid::new(dem.width as usize, dem.height as usize, &dem.heights)
            .ok_or_else(|| anyhow::anyhow!("{name}: bad grid"))?;
        let spacing = [dem.spacing_x, dem.spacing_y];
        let shape = TileShape::new(dem.width, dem.height, 64)?;
        for level in 0..=shape.depth() {
            let (nx, ny) = shape.level_dims(level);
            let mut ds: Vec<f32> = (0..ny)
                .flat_map(|y| (0..nx).map(move |x| relief_proto::tile::TileId { level, x, y }))
                .filter_map(|t| {
                    let s = shape.span(t);
                    box_dimension(&g, spacing, s.cols, s.rows, p.scales)
                })
                .collect();
            ds.sort_by(f32::total_cmp);
            let q = |f: f64| {
                ds.get(((ds.len() - 1) as f64 * f) as usize)
                    .copied()
                    .unwrap_or(0.0)
            };
            println!(
                "{name} level {level}: {} tiles, D p10 {:.3} p50 {:.3} p90 {:.3} max {:.3}",
                ds.len(),
                q(0.1),
                q(0.5),
                q(0.9),
                q(1.0)
            );
            if level == shape.depth() {
                series.push((name, ds));
            }
        }
        // The finest tiles: dimension against rqt triangles (full 65 x 65 only).
        for (c0, r0, z) in dems::crops(&dem, 65) {
            let t = HeightGrid::new(65, 65, &z).expect("65 x 65");
            let tris = RqtErrors::new(&t).expect("2^k+1").triangle_count(TOL);
            if let Some(d) = box_dimension(&g, spacing, (c0, c0 + 64), (r0, r0 + 64), p.scales) {
                pairs.push((name, d, tris as f32, slope(&z, spacing)));
            }
        }
        let leaves = fractal_leaves(&g, spacing, &shape, &p);
        let mut per_level = vec![0usize; shape.depth() as usize + 1];
        for l in &leaves {
            per_level[l.tile.level as usize] += 1;
        }
        let finest = shape.level_dims(shape.depth());
        println!(
            "{name}: {} leaves (per level {per_level:?}); a full tree has {} finest tiles",
            leaves.len(),
            finest.0 * finest.1
        );
        // The pyramid stopping at the leaves: the grid error of each leaf above the finest
        // level against the largest error of its level's tiles.
        let mut stops: Vec<(u8, f32, f32)> = leaves
            .iter()
            .filter(|l| l.tile.level < shape.depth())
            .map(|l| {
                (
                    l.tile.level,
                    l.dimension.unwrap_or(0.0),
                    grid_error(&dem, &shape.span(l.tile)),
                )
            })
            .collect();
        stops.sort_by(|a, b| b.2.total_cmp(&a.2));
        for (level, d, e) in stops.iter().take(3) {
            let (nx, ny) = shape.level_dims(*level);
            let worst = (0..ny)
                .flat_map(|y| {
                    (0..nx).map(move |x| relief_proto::tile::TileId {
                        level: *level,
                        x,
                        y,
                    })
                })
                .map(|t| grid_error(&dem, &shape.span(t)))
                .fold(0.0f32, f32::max);
            println!(
                "  leaf at level {level}, D {d:.3}: grid error {e:.1} m (level {level}'s largest {worst:.1} m; finest level 0 m)"
            );
        }
        let spans: Vec<_> = leaves
            .iter()
            .map(|l| (shape.span(l.tile), l.dimension))
            .collect();
        draw_leaves(&dem, &spans, &p, &out.join(format!("{name}_leaves.png")))?;
    }
    for name in dems::NAMES.into_iter().chain(["all"]) {
        let sel: Vec<_> = pairs
            .iter()
            .filter(|p| name == "all" || p.0 == name)
            .collect();
        let d: Vec<f32> = sel.iter().map(|p| p.1).collect();
        let tris: Vec<f32> = sel.iter().map(|p| p.2).collect();
        let slopes: Vec<f32> = sel.iter().map(|p| p.3).collect();
        println!(
            "{name}: {} tiles; Spearman rho(D, rqt triangles at {TOL} m) = {:.2}; rho(mean slope, triangles) = {:.2}",
            sel.len(),
            spearman(&d, &tris),
            spearman(&slopes, &tris)
        );
    }
    for (name, ds) in &series {
        let share =
            |f: &dyn Fn(f32) -> bool| ds.iter().filter(|&&d| f(d)).count() as f64 / ds.len() as f64;
        println!(
            "{name}: finest tiles at or below flat {:.0}%, at or above rough {:.0}%",
            100.0 * share(&|d| d <= p.flat),
            100.0 * share(&|d| d >= p.rough)
        );
    }
    let mut relief: Vec<f32> = series
        .iter()
        .filter(|(name, _)| !name.contains("plains"))
        .flat_map(|(_, ds)| ds.iter().copied())
        .collect();
    relief.sort_by(f32::total_cmp);
    println!(
        "relief DEMs' finest tiles pooled: p10 {:.3} median {:.3} p90 {:.3}",
        relief[relief.len() / 10],
        relief[relief.len() / 2],
        relief[relief.len() * 9 / 10]
    );
    std::fs::write(out.join("fractal_histogram.svg"), histogram(&series, &p))?;
    Ok(())
}

/// Mean gradient magnitude of a 65 x 65 tile (a simpler predictor to compare with).
fn slope(z: &[f32], spacing: [f64; 2]) -> f32 {
    let mut s = 0.0f64;
    for r in 0..64 {
        for c in 0..64 {
            let gx = f64::from(z[r * 65 + c + 1] - z[r * 65 + c]) / spacing[0];
            let gy = f64::from(z[(r + 1) * 65 + c] - z[r * 65 + c]) / spacing[1];
            s += gx.hypot(gy);
        }
    }
    (s / 4096.0) as f32
}

/// Largest vertical distance, metres, between the grid mesh of `span` and the samples under it.
fn grid_error(dem: &Dem, span: &relief_proto::tile::TileSpan) -> f32 {
    let w = dem.width;
    let z: Vec<f32> = (0..span.vertex_count() as u32)
        .map(|v| {
            let (c, r) = span.vertex_pos(v);
            dem.heights[(r * w + c) as usize]
        })
        .collect();
    let mut worst = 0.0f32;
    for r in span.rows.0..=span.rows.1 {
        for c in span.cols.0..=span.cols.1 {
            let m = grid_height(span, &z, c as f32, r as f32);
            worst = worst.max((m - dem.heights[(r * w + c) as usize]).abs());
        }
    }
    worst
}

/// Spearman's rank correlation.
fn spearman(a: &[f32], b: &[f32]) -> f64 {
    let rank = |v: &[f32]| {
        let mut idx: Vec<usize> = (0..v.len()).collect();
        idx.sort_by(|&i, &j| v[i].total_cmp(&v[j]));
        let mut r = vec![0.0f64; v.len()];
        for (k, &i) in idx.iter().enumerate() {
            r[i] = k as f64;
        }
        r
    };
    let (ra, rb) = (rank(a), rank(b));
    let n = ra.len() as f64;
    let m = (n - 1.0) / 2.0;
    let cov: f64 = ra.iter().zip(&rb).map(|(x, y)| (x - m) * (y - m)).sum();
    let var: f64 = ra.iter().map(|x| (x - m).powi(2)).sum();
    cov / var
}

/// The hillshade of `dem` (sun from the north-west, 45 degrees up) with each leaf tinted by
/// its dimension and outlined.
fn draw_leaves(
    dem: &Dem,
    leaves: &[(relief_proto::tile::TileSpan, Option<f32>)],
    p: &FractalParams,
    path: &Path,
) -> anyhow::Result<()> {
    let (w, h) = (dem.width, dem.height);
    let z = |c: u32, r: u32| f64::from(dem.heights[(r.min(h - 1) * w + c.min(w - 1)) as usize]);
    let mut img = image::RgbImage::new(w, h);
    let (az, alt) = (315f64.to_radians(), 45f64.to_radians());
    let sun = [alt.cos() * az.sin(), alt.cos() * az.cos(), alt.sin()];
    for r in 0..h {
        for c in 0..w {
            let dx = (z(c + 1, r) - z(c.saturating_sub(1), r)) / (2.0 * dem.spacing_x);
            let dy = (z(c, r.saturating_sub(1)) - z(c, r + 1)) / (2.0 * dem.spacing_y);
            let n = [-dx, -dy, 1.0];
            let len = (n[0] * n[0] + n[1] * n[1] + 1.0).sqrt();
            let shade = ((n[0] * sun[0] + n[1] * sun[1] + n[2] * sun[2]) / len).max(0.0);
            let v = (40.0 + 215.0 * shade) as u8;
            img.put_pixel(c, r, image::Rgb([v, v, v]));
        }
    }
    for (s, d) in leaves {
        let f = d.map_or(0.0, |d| ((d - p.flat) / (p.rough - p.flat)).clamp(0.0, 1.0));
        let col = [255.0 * f, 60.0, 255.0 * (1.0 - f)];
        for r in s.rows.0..=s.rows.1.min(h - 1) {
            for c in s.cols.0..=s.cols.1.min(w - 1) {
                let edge = r == s.rows.0 || r == s.rows.1 || c == s.cols.0 || c == s.cols.1;
                let a = if edge { 1.0 } else { 0.3 };
                let px = img.get_pixel_mut(c, r);
                for (v, c) in px.0.iter_mut().zip(col) {
                    *v = (f32::from(*v) * (1.0 - a) + c * a) as u8;
                }
            }
        }
    }
    // 500 pixels across at most: the figure goes in the docs.
    let k = w.max(h).div_ceil(500);
    Ok(
        image::imageops::resize(&img, w / k, h / k, image::imageops::FilterType::Triangle)
            .save(path)?,
    )
}

/// An SVG histogram of each series' dimensions, with the thresholds marked.
fn histogram(series: &[(&str, Vec<f32>)], p: &FractalParams) -> String {
    let (lo, hi, bins) = (1.995f32, 2.095f32, 40usize);
    let (w, h, ml, mb, mt, mr) = (760.0, 420.0, 60.0, 50.0, 40.0, 20.0);
    let x = |d: f32| ml + (w - ml - mr) * f64::from((d - lo) / (hi - lo));
    let counts: Vec<Vec<f64>> = series
        .iter()
        .map(|(_, ds)| {
            let mut c = vec![0.0; bins];
            for &d in ds {
                let b = (((d - lo) / (hi - lo)) * bins as f32)
                    .floor()
                    .clamp(0.0, bins as f32 - 1.0);
                c[b as usize] += 1.0 / ds.len() as f64;
            }
            c
        })
        .collect();
    let top = counts.iter().flatten().copied().fold(0.0, f64::max) * 1.1;
    let y = |f: f64| h - mb - (h - mb - mt) * f / top;
    let colours = ["#d62728", "#9467bd", "#1f77b4", "#2ca02c"];
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n<text x=\"{ml}\" y=\"22\" font-size=\"14\">Box-counting dimension of the 64-cell tiles of the finest level (fraction of each DEM's tiles)</text>\n"
    );
    let _ = writeln!(
        s,
        "<line x1=\"{ml}\" y1=\"{0}\" x2=\"{1}\" y2=\"{0}\" stroke=\"black\"/><line x1=\"{ml}\" y1=\"{mt}\" x2=\"{ml}\" y2=\"{0}\" stroke=\"black\"/>",
        h - mb,
        w - mr
    );
    for k in 0..=((hi - lo) / 0.01).round() as usize {
        let d = lo + 0.005 + 0.01 * k as f32;
        if d > hi {
            break;
        }
        let _ = writeln!(
            s,
            "<text x=\"{:.1}\" y=\"{}\" text-anchor=\"middle\">{d:.3}</text>",
            x(d),
            h - mb + 16.0
        );
    }
    let _ = writeln!(
        s,
        "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">D (box counting, eps = 1..16 cells)</text>",
        (w + ml) / 2.0,
        h - 12.0
    );
    for (k, c) in counts.iter().enumerate() {
        let mut pts = format!("{:.1},{:.1}", x(lo), y(0.0));
        for (b, &v) in c.iter().enumerate() {
            let (d0, d1) = (
                lo + (hi - lo) * b as f32 / bins as f32,
                lo + (hi - lo) * (b + 1) as f32 / bins as f32,
            );
            let _ = write!(pts, " {:.1},{:.1} {:.1},{:.1}", x(d0), y(v), x(d1), y(v));
        }
        let _ = write!(pts, " {:.1},{:.1}", x(hi), y(0.0));
        let _ = writeln!(
            s,
            "<polyline points=\"{pts}\" fill=\"none\" stroke=\"{}\" stroke-width=\"1.5\"/>",
            colours[k % 4]
        );
        let _ = writeln!(
            s,
            "<text x=\"{}\" y=\"{}\" fill=\"{}\">{} ({} tiles)</text>",
            w - mr - 250.0,
            mt + 20.0 + 16.0 * k as f64,
            colours[k % 4],
            series[k].0,
            series[k].1.len()
        );
    }
    for (d, label) in [(p.flat, "flat"), (p.rough, "rough")] {
        let _ = writeln!(
            s,
            "<line x1=\"{0:.1}\" y1=\"{mt}\" x2=\"{0:.1}\" y2=\"{1}\" stroke=\"black\" stroke-dasharray=\"4 3\"/><text x=\"{2:.1}\" y=\"{3}\">{label} = {d}</text>",
            x(d),
            h - mb,
            x(d) + 4.0,
            mt + 12.0
        );
    }
    s.push_str("</svg>\n");
    s
}
