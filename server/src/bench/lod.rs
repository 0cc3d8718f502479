//! `relief-server bench lod`: the vertex stream over a camera path, in process.
//!
//! One session flies the path. For every pose the server updates its cut and encodes the delta as
//! it would go on the wire; a client-side mirror decodes it, applies it, checks the digest and
//! updates its fans incrementally. In the same run, the cut is also recomputed from scratch for
//! the same camera, to compare update costs. On measured frames the mirror's mesh (with
//! geomorphs applied, as a client draws it) is checked against the brute-force oracle and for
//! cracks, and its pixel error is measured against the DEM (DESIGN.md section 7).

use super::flight::{CostSummary, Flight, PxAccum, PxSummary, WireBytes, WireSummary};
use super::stats::{median, quantile};
use crate::dem::Dem;
use crate::lod::vertex::session::VertexSession;
use crate::lod::vertex::{LodParams, UpdateStats, VertexEngine};
use glam::Vec3;
use relief_proto::codec;
use relief_proto::cut::Cut;
use relief_proto::delta::{BodyModels, Known};
use relief_proto::mesh::{self, FanMesh, MorphRule, drawn_position};
use relief_proto::mirror::Mirror;
use relief_proto::msg::{ServerMsg, SessionDelta, WireDelta};
use relief_proto::path::{PATH_HZ, PathKind};
use relief_proto::terrain::TerrainGeometry;
use relief_proto::tree::NodeId;
use relief_proto::view::{Lens, ViewState};
use serde::Serialize;
use std::time::Instant;

/// What to run.
#[derive(Clone, Debug)]
pub struct LodBenchOptions {
    /// Which path to fly.
    /// Which path was flown.
    pub path: PathKind,
    /// LOD thresholds.
    pub params: LodParams,
    /// Measure pixel error on every k-th frame; `None` picks k so that at least 60 frames and
    /// about 20 M samples are measured.
    pub px_every: Option<usize>,
    /// Minimum grid samples in each measured frame's stratified lattice (all samples on grids
    /// smaller than this); about a quarter of them lie in view on the standard path.
    pub px_min_samples: u64,
    /// Check the incremental mesh against the oracle on this many evenly spread frames.
    pub oracle_frames: usize,
    /// Also run the paper's full pass and the from-scratch cut every pose (their costs and
    /// agreement); `bench compare` leaves them out, as they change none of its figures.
    pub cross_checks: bool,
    /// Fly only the path's first poses (`None`: all of them).
    pub poses: Option<usize>,
    /// Show progress on stderr.
    pub progress: bool,
}

impl Default for LodBenchOptions {
    fn default() -> Self {
        LodBenchOptions {
            path: PathKind::Standard,
            params: LodParams::default(),
            px_every: None,
            px_min_samples: 4_000_000,
            oracle_frames: 12,
            cross_checks: true,
            poses: None,
            progress: false,
        }
    }
}

/// The benchmark's figures; field meanings are in the README's benchmark section.
#[derive(Clone, Debug, Serialize)]
pub struct LodBenchReport {
    /// The DEM flown over.
    pub dem: String,
    /// Grid width, samples.
    pub width: u32,
    /// Grid height, samples.
    pub height: u32,
    /// Which path was flown.
    pub path: String,
    /// Poses flown.
    pub frames: usize,
    /// Split threshold, pixels.
    pub tau_px: f32,
    /// Triangles the client draws per frame: median.
    pub triangles_median: f64,
    /// Triangles the client draws per frame: maximum.
    pub triangles_max: f64,
    /// Triangles of the full-resolution grid, for scale.
    pub full_res_triangles: u64,
    /// Measured pixel error.
    #[serde(flatten)]
    pub px: PxSummary,
    /// Directed edges without a twin inside the mesh, over measured frames.
    pub cracks: u64,
    /// Triangles not counter-clockwise seen from above, over measured frames.
    pub folds: u64,
    /// Frames whose incremental mesh was compared with the brute-force rule.
    pub oracle_checks: usize,
    /// Of those, frames where the two differed.
    pub oracle_mismatches: u64,
    /// Deltas whose digest did not match the mirror's cut.
    pub desyncs: u64,
    /// Server and client time per pose.
    #[serde(flatten)]
    pub cost: CostSummary,
    /// The paper's full top-down pass for the same pose, median, microseconds.
    pub paper_pass_us_median: f64,
    /// Poses where the full pass's cut differed from the session's (must be 0).
    pub paper_pass_mismatches: u64,
    /// Splits plus merges per pose: median.
    pub changes_median: f64,
    /// Splits plus merges per pose: 90th percentile.
    pub changes_p90: f64,
    /// Server update time (update and wire encoding) per change, nanoseconds: median over the
    /// poses that changed anything.
    pub server_ns_per_change_median: f64,
    /// Client time (decode, mirror, fans) per change, nanoseconds: median over the poses that
    /// changed anything.
    pub client_ns_per_change_median: f64,
    /// Screen errors the session evaluated per change, over the whole flight.
    pub evaluations_per_change: f64,
    /// Screen errors the session evaluated per pose, median.
    pub nodes_visited_median: f64,
    /// Screen errors the full pass evaluated per pose, median.
    pub paper_pass_visited_median: f64,
    /// Active nodes in the cut, median.
    pub active_nodes_median: f64,
    /// Splits sent, initial delta included.
    pub splits_total: u64,
    /// Merges sent.
    pub merges_total: u64,
    /// Wire bytes of all deltas (initial one included) per split.
    pub split_bytes_mean: f64,
    /// Order-0 entropy of the same deltas' split payloads (positions, details, error residuals)
    /// under the body coder's contexts, bytes per split: what these contexts allow any coder
    /// ([`relief_proto::delta::SplitEntropy`]).
    pub split_entropy_bytes: f64,
    /// The same with the merge positions added, per split: what one static model per context,
    /// fitted to the whole run, would spend on the bodies
    /// ([`relief_proto::delta::SplitEntropy::delta_bytes_per_split`]).
    pub delta_entropy_bytes: f64,
    /// Wire bytes of the session's first delta.
    pub initial_delta_bytes: u64,
    /// Wire bytes per second of flight after the first delta.
    pub delta_bytes_per_s_mean: f64,
    /// Bytes over the whole path, raw and gzipped, with their rates.
    #[serde(flatten)]
    pub wire: WireSummary,
    /// Server memory of the session's state (its cut and schedule, and the connection's body
    /// models), bytes, median over poses.
    pub session_bytes: f64,
    /// The same per active node, median over poses.
    pub session_bytes_per_active_node: f64,
    /// Seconds to build the tree (one core).
    pub build_s: f64,
    /// Samples per second of the tree build.
    pub build_samples_per_s: f64,
    /// Size of the store file.
    pub store_bytes: u64,
}

/// Runs the benchmark on `dem`, building its store in a temporary directory.
pub fn run(dem: &Dem, opts: &LodBenchOptions) -> anyhow::Result<LodBenchReport> {
    let flight = Flight::prepare(
        dem,
        opts.path,
        Default::default(),
        opts.px_every,
        opts.px_min_samples,
        opts.progress,
    )?;
    fly(dem, &flight.first_poses(opts.poses), opts)
}

/// Flies `flight`'s path over its store with `opts`' stream settings (its path, tile size and
/// mesh are the flight's; the store is not rebuilt, so `bench compare` flies one store at many
/// thresholds).
pub fn fly(dem: &Dem, flight: &Flight, opts: &LodBenchOptions) -> anyhow::Result<LodBenchReport> {
    let store = &flight.store;
    let engine = VertexEngine::new(store);
    let geom = store.geometry();
    let shape = &geom.shape;
    let (w, h) = (shape.width(), shape.height());
    let lens = Lens::STANDARD;
    let p = opts.params;
    let cams = &flight.cams;
    let frames = cams.len();
    let px_every = flight.px_every;
    let oracle_every = (frames / opts.oracle_frames.max(1)).max(1);

    // Session start: the initial cut, sent as one delta of splits.
    let root_z = store.root_z();
    let mut mirror = Mirror::new(geom, root_z);
    let view0 = ViewState::new(&cams[0], &lens);
    let mut session = VertexSession::new(&engine, &view0, &p);
    // The paper's full top-down pass, run beside the session for its cost (same decisions).
    let mut paper_cut = session.cut();
    let first = engine.full_delta(&paper_cut, 0);
    // The connection's body models, the server's and the client's (docs/protocol.md 5.2).
    let (mut server_models, mut client_models) = (BodyModels::new(), BodyModels::new());
    let first_bytes = wire(&first, &engine, session.cut_ref(), &mut server_models);
    let mut entropy = relief_proto::delta::SplitEntropy::default();
    entropy.add(
        &first,
        &geom.shape,
        geom.z_quantum,
        Known {
            parents: &engine,
            cut: session.cut_ref(),
        },
    );
    let decoded = unwire(&first_bytes, geom, &mut client_models, &mirror)?;
    mirror.apply(geom, &decoded, |_, _| {})?;
    let mut mesh = FanMesh::new(shape, mirror.cut());

    let mut r = Accum::default();
    r.bytes += first_bytes.len() as u64;
    r.wire.push(&first_bytes);
    r.splits += first.splits.len() as u64;
    let bar = super::progress_bar(opts.progress, frames as u64, "flying");
    for (f, cam) in cams.iter().enumerate().skip(1) {
        let view = ViewState::new(cam, &lens);
        let mut st = UpdateStats::default();
        let t0 = Instant::now();
        let delta = session.update(&engine, &view, &p, f as u64, &mut st);
        let bytes = wire(&delta, &engine, session.cut_ref(), &mut server_models);
        r.update_us.push(t0.elapsed().as_secs_f64() * 1e6);
        entropy.add(
            &delta,
            &geom.shape,
            geom.z_quantum,
            Known {
                parents: &engine,
                cut: session.cut_ref(),
            },
        );
        r.visited.push(st.visited as f64);

        if opts.cross_checks {
            let mut pst = UpdateStats::default();
            let t0 = Instant::now();
            let paper = engine.update(&mut paper_cut, &view, &p, f as u64, &mut pst);
            r.paper_us.push(t0.elapsed().as_secs_f64() * 1e6);
            r.paper_visited.push(pst.visited as f64);
            if paper.digest != delta.digest {
                r.paper_mismatches += 1;
            }

            let t0 = Instant::now();
            let scratch = engine.initial_cut(&view, &p, &mut UpdateStats::default());
            r.scratch_us.push(t0.elapsed().as_secs_f64() * 1e6);
            std::hint::black_box(scratch.digest());
        }

        let t0 = Instant::now();
        let decoded = unwire(&bytes, geom, &mut client_models, &mirror)?;
        match mirror.apply(geom, &decoded, |c, ch| {
            mesh.update_around(shape, c, ch.node())
        }) {
            Ok(()) => {}
            Err(e) => {
                r.desyncs += 1;
                tracing::warn!("frame {f}: {e}");
            }
        }
        r.client_us.push(t0.elapsed().as_secs_f64() * 1e6);
        r.path_bytes += bytes.len() as u64;
        r.bytes += bytes.len() as u64;
        r.wire.push(&bytes);
        r.splits += delta.splits.len() as u64;
        r.merges += delta.merges.len() as u64;
        let changes = (delta.splits.len() + delta.merges.len()) as f64;
        r.changes.push(changes);
        if changes > 0.0 {
            let n = r.update_us.len() - 1;
            r.server_ns.push(r.update_us[n] * 1e3 / changes);
            r.client_ns.push(r.client_us[n] * 1e3 / changes);
        }
        r.active.push(session.active_count() as f64);
        r.triangles.push(mesh.triangle_count() as f64);
        r.session_bytes
            .push((session.memory_bytes() + size_of::<BodyModels>()) as f64);

        if (f - 1) % oracle_every == 0 {
            r.oracle_checks += 1;
            let oracle = mesh::oracle(shape, mirror.cut());
            if mesh.triangles() != oracle {
                r.oracle_mismatches += 1;
            }
        }
        if (f - 1) % px_every == 0 {
            let tris = drawn_triangles(&mesh, &mirror, geom, &view, &p);
            let rep = mesh::check_mesh(shape, |n| shape.grid_pos(n), &mesh.triangles());
            r.cracks += rep.cracks as u64;
            r.folds += rep.folds as u64;
            r.px.measure(flight, dem, &tris, f, &lens);
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    let seconds = (frames - 1) as f64 / PATH_HZ as f64;
    Ok(LodBenchReport {
        dem: dem.source.clone(),
        width: w,
        height: h,
        path: format!("{:?}", opts.path).to_lowercase(),
        frames,
        tau_px: p.tau,
        triangles_median: median(&r.triangles),
        triangles_max: quantile(&r.triangles, 1.0),
        full_res_triangles: 2 * (w as u64 - 1) * (h as u64 - 1),
        px: r.px.summary(flight),
        cracks: r.cracks,
        folds: r.folds,
        oracle_checks: r.oracle_checks,
        oracle_mismatches: r.oracle_mismatches,
        desyncs: r.desyncs,
        cost: CostSummary::of(&r.update_us, &r.scratch_us, &r.client_us),
        paper_pass_us_median: median(&r.paper_us),
        paper_pass_mismatches: r.paper_mismatches,
        changes_median: median(&r.changes),
        changes_p90: quantile(&r.changes, 0.9),
        server_ns_per_change_median: median(&r.server_ns),
        client_ns_per_change_median: median(&r.client_ns),
        evaluations_per_change: r.visited.iter().sum::<f64>()
            / r.changes.iter().sum::<f64>().max(1.0),
        nodes_visited_median: median(&r.visited),
        paper_pass_visited_median: median(&r.paper_visited),
        active_nodes_median: median(&r.active),
        splits_total: r.splits,
        merges_total: r.merges,
        split_bytes_mean: r.bytes as f64 / r.splits.max(1) as f64,
        split_entropy_bytes: entropy.bytes_per_split(),
        delta_entropy_bytes: entropy.delta_bytes_per_split(),
        initial_delta_bytes: first_bytes.len() as u64,
        delta_bytes_per_s_mean: r.path_bytes as f64 / seconds,
        wire: r.wire.summary(PATH_HZ as usize),
        session_bytes: median(&r.session_bytes),
        session_bytes_per_active_node: median(
            &r.session_bytes
                .iter()
                .zip(&r.active)
                .map(|(b, a)| b / a)
                .collect::<Vec<_>>(),
        ),
        build_s: flight.built.tree_s,
        build_samples_per_s: (w as f64 * h as f64) / flight.built.tree_s.max(1e-9),
        store_bytes: flight.built.bytes,
    })
}

/// Per-frame series gathered during the run.
#[derive(Default)]
struct Accum {
    update_us: Vec<f64>,
    scratch_us: Vec<f64>,
    paper_us: Vec<f64>,
    paper_visited: Vec<f64>,
    paper_mismatches: u64,
    client_us: Vec<f64>,
    changes: Vec<f64>,
    server_ns: Vec<f64>,
    client_ns: Vec<f64>,
    visited: Vec<f64>,
    active: Vec<f64>,
    triangles: Vec<f64>,
    px: PxAccum,
    bytes: u64,
    path_bytes: u64,
    wire: WireBytes,
    splits: u64,
    merges: u64,
    desyncs: u64,
    cracks: u64,
    folds: u64,
    oracle_checks: usize,
    oracle_mismatches: u64,
    session_bytes: Vec<f64>,
}

fn wire(
    delta: &relief_proto::delta::Delta,
    engine: &VertexEngine,
    after: &Cut,
    models: &mut BodyModels,
) -> Vec<u8> {
    let geom = engine.geometry();
    codec::encode(&ServerMsg::Delta(SessionDelta {
        pose_seq: delta.seq,
        complete: true,
        delta: WireDelta::pack_in(
            delta,
            &geom.shape,
            models,
            geom.z_quantum,
            Known {
                parents: engine,
                cut: after,
            },
        ),
    }))
}

fn unwire(
    bytes: &[u8],
    geom: &TerrainGeometry,
    models: &mut BodyModels,
    mirror: &Mirror,
) -> anyhow::Result<relief_proto::delta::Delta> {
    match codec::decode::<ServerMsg>(bytes, codec::HARD_LIMIT)? {
        ServerMsg::Delta(d) => {
            Ok(d.delta
                .unpack_in(&geom.shape, geom.z_quantum, models, Known::mirror(mirror))?)
        }
        other => anyhow::bail!("expected a delta, got {other:?}"),
    }
}

/// The mirror's triangles in world space as a client draws them, geomorphs applied down the
/// chain of ancestors (paper 000, section 3.6; [`mesh::morph`]). Splits are taken as old, so
/// only the error-driven alpha applies.
fn drawn_triangles(
    mesh: &FanMesh,
    mirror: &Mirror,
    geom: &TerrainGeometry,
    view: &ViewState,
    p: &LodParams,
) -> Vec<[Vec3; 3]> {
    let rule = MorphRule {
        tau: p.tau,
        lambda: p.lambda,
        duration: 0.0,
    };
    let pos = |n: NodeId| drawn_position(geom, mirror, view, &rule, n, |_| f32::INFINITY);
    mesh.triangles().iter().map(|t| t.0.map(pos)).collect()
}
