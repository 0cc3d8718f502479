//! `relief-server bench tiles`: the tile stream over a camera path, in process (DESIGN.md
//! section 7).
//!
//! One tile session flies the path with an unlimited client cache. For every pose the server
//! selects the restricted tile set and encodes the delta as it goes on the wire; a client mirror
//! decodes it, applies it, checks the digest and builds the added tiles' triangles (what a thin
//! client does). In the same run the selection is also made from scratch, for its cost.
//!
//! Beyond the vertex bench's common fields it reports the crack strategies' triangles (paper
//! 001, table 1: patches against skirts, over the whole pyramid and over the drawn set),
//! restriction violations, how often paper 001's ratio > 3 held, tile bytes plain and gzipped,
//! and the *pop*: at every tile switch, the largest distance in pixels between where a vertex of
//! the new tile was drawn before (on the surface of the tiles it replaces) and where it is drawn
//! now, for the pose's camera.

use super::flight::{CostSummary, Flight, PxAccum, PxSummary, WireBytes, WireSummary, gzip_len};
use super::stats::{mean, median, quantile};
use crate::dem::Dem;
use crate::formats::quantized_mesh::{self, QmExtensions, QmMesh};
use crate::lod::measure::Projector;
use crate::lod::tile::TileEngine;
use crate::lod::tile::bits::TileBits;
use crate::lod::tile::session::TileSession;
use crate::store::tiles::crack_triangles;
use glam::Vec3;
use relief_proto::codec;
use relief_proto::msg::{CrackMode, ServerMsg, SessionDelta, TileStreamParams, WireDelta};
use relief_proto::path::{PATH_HZ, PathKind};
use relief_proto::tile::body::MeshKind;
use relief_proto::tile::delta::put_varint;
use relief_proto::tile::geometry::{Surface, tile_triangles};
use relief_proto::tile::mirror::{TileChanges, TileData, TileMirror};
use relief_proto::tile::snapshot::restriction_violations;
use relief_proto::view::{Lens, ViewState};
use serde::Serialize;
use std::time::Instant;

/// What to run.
#[derive(Clone, Debug)]
pub struct TileBenchOptions {
    /// Which path to fly.
    pub path: PathKind,
    /// Split threshold, pixels.
    pub tau: f32,
    /// What tiles carry against cracks.
    pub crack: CrackMode,
    /// Tile size, cells.
    pub tile_size: u32,
    /// The tiles' mesh kind.
    pub tile_mesh: MeshKind,
    /// Measure pixel error on every k-th frame (`None`: at least 60 frames).
    pub px_every: Option<usize>,
    /// Minimum samples of each measured frame's lattice.
    pub px_min_samples: u64,
    /// Fly only the path's first poses (`None`: all of them).
    pub poses: Option<usize>,
    /// Also select from scratch every pose and measure the pops (their costs and figures);
    /// `bench compare` leaves them out, as they change none of its figures.
    pub cross_checks: bool,
    /// Also encode every tile sent as Cesium quantized-mesh ([`quantized_mesh_of`]) and
    /// report those bytes ([`TileBenchReport::quantized_mesh`]).
    pub quantized_mesh: bool,
    /// Show progress on stderr.
    pub progress: bool,
}

impl Default for TileBenchOptions {
    fn default() -> Self {
        TileBenchOptions {
            path: PathKind::Standard,
            tau: 1.0,
            crack: CrackMode::Patches,
            tile_size: crate::store::DEFAULT_TILE_SIZE,
            tile_mesh: MeshKind::Grid,
            px_every: None,
            px_min_samples: 4_000_000,
            poses: None,
            cross_checks: true,
            quantized_mesh: false,
            progress: false,
        }
    }
}

/// The benchmark's figures; field meanings are in the README's benchmark section.
#[derive(Clone, Debug, Serialize)]
pub struct TileBenchReport {
    /// The DEM flown over.
    pub dem: String,
    /// Grid width, samples.
    pub width: u32,
    /// Grid height, samples.
    pub height: u32,
    /// Which path was flown.
    pub path: String,
    /// `patches`, `skirts` or `none`.
    pub crack: String,
    /// The tiles' mesh kind: `grid`, `rqt` or `tin`.
    pub tile_mesh: String,
    /// Poses flown.
    pub frames: usize,
    /// Split threshold, pixels.
    pub tau_px: f32,
    /// Cells per tile side.
    pub tile_size: u32,
    /// Levels of the pyramid (depth + 1).
    pub levels: u32,
    /// Triangles the client draws per frame (tiles plus patches or skirts): median.
    pub triangles_median: f64,
    /// Same, maximum.
    pub triangles_max: f64,
    /// Triangles of the full-resolution grid, for scale.
    pub full_res_triangles: u64,
    /// Measured pixel error of the drawn tiles.
    #[serde(flatten)]
    pub px: PxSummary,
    /// Deltas whose digest did not match the mirror's set.
    pub desyncs: u64,
    /// Messages beyond one per pose: deltas over `MAX_DELTA_BODY` go out in parts.
    pub extra_parts: u64,
    /// Server and client time per pose.
    #[serde(flatten)]
    pub cost: CostSummary,
    /// Active tiles, median.
    pub tiles_active_median: f64,
    /// Tiles whose screen error was evaluated per pose, median.
    pub tiles_visited_median: f64,
    /// Patch triangles of every tile of the pyramid.
    pub patch_triangles: u64,
    /// Skirt triangles of every tile of the pyramid (2 per edge segment).
    pub skirt_triangles: u64,
    /// `patch_triangles / skirt_triangles`.
    pub patch_to_skirt: f64,
    /// Patch triangles of the drawn set, median over frames.
    pub patch_triangles_drawn_median: f64,
    /// Skirt triangles of the drawn set, median over frames.
    pub skirt_triangles_drawn_median: f64,
    /// Their ratio, summed over frames.
    pub patch_to_skirt_drawn: f64,
    /// Pairs of edge-adjacent drawn tiles more than one level apart, over all frames.
    pub restriction_violations: u64,
    /// Splits the restriction added per pose, mean.
    pub forced_splits_mean: f64,
    /// Share of poses whose plain selection was already restricted.
    pub plain_restricted_share: f64,
    /// Share of drawn tiles (root excluded) whose paper-001 ratio exceeded 3.
    pub ratio_gt_3_share: f64,
    /// Share of poses in which every drawn tile's ratio exceeded 3 (theorem 1 applied).
    pub ratio_gt_3_frame_share: f64,
    /// Tile bodies sent.
    pub tiles_sent: u64,
    /// Bytes of a tile body as sent (lengths, mesh, patches), mean.
    pub tile_bytes_mean: f64,
    /// Same, gzip-compressed (as `GET /v1/tiles` serves it), mean.
    pub gzip_tile_bytes_mean: f64,
    /// Wire bytes of the first delta.
    pub initial_delta_bytes: u64,
    /// Wire bytes per second of flight after the first delta.
    pub delta_bytes_per_s_mean: f64,
    /// Bytes over the whole path, raw and gzipped (each message), with their rates.
    #[serde(flatten)]
    pub wire: WireSummary,
    /// With [`TileBenchOptions::quantized_mesh`]: the same tiles, each sent as a Cesium
    /// quantized-mesh tile (gzipped on its own, as a tile server sends it), frame by frame.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub quantized_mesh: Option<WireSummary>,
    /// Largest vertex jump at a tile switch, pixels.
    pub pop_px_max: f64,
    /// 99th percentile over switches of each switch's largest jump, pixels.
    pub pop_px_p99: f64,
    /// Median over switches of each switch's largest jump, pixels.
    pub pop_px_median: f64,
    /// Tile switches measured (tiles added after the first pose, with a vertex in view).
    pub pop_switches: usize,
    /// The largest jump with the client's morph (interior vertices of a split's children start
    /// on the parent's mesh; border vertices and merges still jump), pixels.
    pub pop_morphed_px_max: f64,
    /// 99th percentile of that over switches, pixels.
    pub pop_morphed_px_p99: f64,
    /// Server memory of the session's state, bytes, median over poses.
    pub session_bytes: f64,
    /// Seconds to build the tile pyramid (one core).
    pub build_tiles_s: f64,
    /// Size of the store file (tree and tiles).
    pub store_bytes: u64,
}

/// Per-frame series.
#[derive(Default)]
struct Accum {
    update_us: Vec<f64>,
    scratch_us: Vec<f64>,
    client_us: Vec<f64>,
    active: Vec<f64>,
    visited: Vec<f64>,
    triangles: Vec<f64>,
    patch_drawn: Vec<f64>,
    skirt_drawn: Vec<f64>,
    forced: Vec<f64>,
    ratio_ok: u64,
    ratio_tiles: u64,
    ratio_frames: u64,
    plain_ok: u64,
    violations: u64,
    desyncs: u64,
    parts: u64,
    tile_bytes: Vec<f64>,
    gzip_bytes: Vec<f64>,
    path_bytes: u64,
    wire: WireBytes,
    qm: WireBytes,
    pops: Vec<f64>,
    morphed_pops: Vec<f64>,
    session_bytes: Vec<f64>,
    px: PxAccum,
}

/// Runs the benchmark on `dem`, building its store in a temporary directory.
pub fn run(dem: &Dem, opts: &TileBenchOptions) -> anyhow::Result<TileBenchReport> {
    let flight = Flight::prepare(
        dem,
        opts.path,
        crate::preprocess::BuildOptions {
            tile_size: opts.tile_size,
            tile_mesh: opts.tile_mesh,
            ..Default::default()
        },
        opts.px_every,
        opts.px_min_samples,
        opts.progress,
    )?;
    fly(dem, &flight.first_poses(opts.poses), opts)
}

/// Flies `flight`'s path over its store with `opts`' stream settings (its path, tile size and
/// mesh are the flight's; the store is not rebuilt, so `bench compare` flies one store at many
/// thresholds).
pub fn fly(dem: &Dem, flight: &Flight, opts: &TileBenchOptions) -> anyhow::Result<TileBenchReport> {
    let store = &flight.store;
    let engine = TileEngine::new(store);
    let shape = engine.shape();
    let geom = store.geometry();
    let (w, h) = flight.size();
    let lens = Lens::STANDARD;
    let params = TileStreamParams {
        cache_tiles: u32::MAX,
        crack: opts.crack,
    };
    let mut session = TileSession::new(shape.tile_count(), params, opts.tau, 0.9);
    let mut mirror = TileMirror::new(shape.clone(), params);
    let info = store.tile_info();
    let mut r = Accum::default();
    let mut first_bytes = 0;
    let bar = super::progress_bar(opts.progress, flight.cams.len() as u64, "flying");
    for (f, cam) in flight.cams.iter().enumerate() {
        let view = ViewState::new(cam, &lens);
        // A delta over MAX_DELTA_BODY goes out in parts, as the server sends it: one frame's
        // bytes and times are those of all its parts.
        let (mut update_us, mut client_us) = (0.0, 0.0);
        let (mut raw, mut gz) = (0u64, 0u64);
        let mut qm = (0u64, 0u64);
        let mut changes = TileChanges::default();
        let mut desync = false;
        let u = loop {
            let t0 = Instant::now();
            let u = session.update(&engine, &view, usize::MAX);
            let msg = codec::encode(&ServerMsg::Delta(SessionDelta {
                pose_seq: f as u64 + 1,
                complete: u.complete,
                delta: WireDelta {
                    seq: f as u64 + 1,
                    digest: u.digest,
                    body: u.delta.encode(),
                },
            }));
            update_us += t0.elapsed().as_secs_f64() * 1e6;

            let t0 = Instant::now();
            let applied = match codec::decode::<ServerMsg>(&msg, codec::HARD_LIMIT)? {
                ServerMsg::Delta(d) => mirror.apply(&d.delta),
                other => anyhow::bail!("expected a delta, got {other:?}"),
            };
            match applied {
                Ok(c) => {
                    changes.removed.extend(c.removed);
                    changes.added.extend(c.added);
                }
                Err(e) => {
                    r.desyncs += 1;
                    tracing::warn!("frame {f}: {e}");
                    desync = true;
                    break u;
                }
            }
            for a in &u.delta.added {
                if a.body.is_some()
                    && let Some(t) = mirror.tile(a.tile)
                {
                    let skirt =
                        (opts.crack == CrackMode::Skirts).then(|| info.skirt_height(t.tile.level));
                    std::hint::black_box(tile_triangles(&geom.frame, geom.z_quantum, t, skirt));
                }
            }
            client_us += t0.elapsed().as_secs_f64() * 1e6;
            raw += msg.len() as u64;
            gz += gzip_len(&msg) as u64;
            if opts.quantized_mesh {
                for b in u
                    .delta
                    .added
                    .iter()
                    .filter(|a| a.body.is_some())
                    .filter_map(|a| mirror.tile(a.tile))
                    .filter_map(|t| quantized_mesh_of(t, geom.z_quantum))
                {
                    qm.0 += b.len() as u64;
                    qm.1 += gzip_len(&b) as u64;
                }
            }
            for a in u.delta.added.iter().filter_map(|a| a.body.as_ref()) {
                let mut body = Vec::with_capacity(a.mesh.len() + a.patches.len() + 8);
                put_varint(&mut body, a.mesh.len() as u32);
                put_varint(&mut body, a.patches.len() as u32);
                body.extend_from_slice(&a.mesh);
                body.extend_from_slice(&a.patches);
                r.tile_bytes.push(body.len() as f64);
                r.gzip_bytes.push(gzip_len(&body) as f64);
            }
            if u.complete {
                break u;
            }
            r.parts += 1;
        };
        if desync {
            continue;
        }

        let t0 = Instant::now();
        if opts.cross_checks {
            let scratch = engine.select(&view, opts.tau, 0.9, &TileBits::default(), false);
            std::hint::black_box(scratch.stats.forced);
        }
        let scratch_us = t0.elapsed().as_secs_f64() * 1e6;
        r.wire.push_sizes(raw, gz);
        if opts.quantized_mesh {
            r.qm.push_sizes(qm.0, qm.1);
        }
        if f == 0 {
            first_bytes = raw;
        } else {
            r.update_us.push(update_us);
            r.scratch_us.push(scratch_us);
            r.client_us.push(client_us);
            r.path_bytes += raw;
        }

        let active = mirror.active();
        let (patch, _) = crack_triangles(shape, store.tile_records(), &active);
        let (mesh_tris, skirt) =
            active
                .iter()
                .filter_map(|&i| mirror.tile(i))
                .fold((0u64, 0u64), |(m, s), t| {
                    (
                        m + t.triangle_count() as u64,
                        s + t.skirt_triangle_count() as u64,
                    )
                });
        let extra = match opts.crack {
            CrackMode::Patches => patch,
            CrackMode::Skirts => skirt,
            CrackMode::None => 0,
        };
        r.triangles.push((mesh_tris + extra) as f64);
        r.patch_drawn.push(patch as f64);
        r.skirt_drawn.push(skirt as f64);
        r.active.push(active.len() as f64);
        r.visited.push(u.stats.visited as f64);
        r.forced.push(u.stats.forced as f64);
        r.plain_ok += u64::from(u.stats.forced == 0);
        r.ratio_ok += u.stats.ratio_gt_3;
        r.ratio_tiles += u.stats.ratio_tiles;
        r.ratio_frames += u64::from(u.stats.ratio_gt_3 == u.stats.ratio_tiles);
        r.violations += restriction_violations(shape, &active) as u64;
        r.session_bytes.push(session.memory_bytes() as f64);
        if f > 0 && opts.cross_checks {
            pops(
                &mirror,
                &changes.removed,
                &changes.added,
                &Projector::new(cam, &lens),
                geom,
                &mut r.pops,
                &mut r.morphed_pops,
            );
        }
        if f % flight.px_every == 0 {
            let tris = world_triangles(&mirror, &active, geom);
            r.px.measure(flight, dem, &tris, f, &lens);
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    let all: Vec<u32> = (0..shape.tile_count()).collect();
    let (patch_all, skirt_all) = crack_triangles(shape, store.tile_records(), &all);
    let frames = flight.cams.len();
    let seconds = (frames - 1) as f64 / PATH_HZ as f64;
    let n = r.forced.len().max(1) as f64;
    Ok(TileBenchReport {
        dem: dem.source.clone(),
        width: w,
        height: h,
        path: format!("{:?}", opts.path).to_lowercase(),
        crack: format!("{:?}", opts.crack).to_lowercase(),
        tile_mesh: opts.tile_mesh.name().into(),
        frames,
        tau_px: opts.tau,
        tile_size: opts.tile_size,
        levels: u32::from(shape.depth()) + 1,
        triangles_median: median(&r.triangles),
        triangles_max: quantile(&r.triangles, 1.0),
        full_res_triangles: 2 * (w as u64 - 1) * (h as u64 - 1),
        px: r.px.summary(flight),
        desyncs: r.desyncs,
        extra_parts: r.parts,
        cost: CostSummary::of(&r.update_us, &r.scratch_us, &r.client_us),
        tiles_active_median: median(&r.active),
        tiles_visited_median: median(&r.visited),
        patch_triangles: patch_all,
        skirt_triangles: skirt_all,
        patch_to_skirt: patch_all as f64 / skirt_all.max(1) as f64,
        patch_triangles_drawn_median: median(&r.patch_drawn),
        skirt_triangles_drawn_median: median(&r.skirt_drawn),
        patch_to_skirt_drawn: r.patch_drawn.iter().sum::<f64>()
            / r.skirt_drawn.iter().sum::<f64>().max(1.0),
        restriction_violations: r.violations,
        forced_splits_mean: mean(&r.forced),
        plain_restricted_share: r.plain_ok as f64 / n,
        ratio_gt_3_share: r.ratio_ok as f64 / r.ratio_tiles.max(1) as f64,
        ratio_gt_3_frame_share: r.ratio_frames as f64 / n,
        tiles_sent: r.tile_bytes.len() as u64,
        tile_bytes_mean: mean(&r.tile_bytes),
        gzip_tile_bytes_mean: mean(&r.gzip_bytes),
        initial_delta_bytes: first_bytes,
        delta_bytes_per_s_mean: r.path_bytes as f64 / seconds,
        wire: r.wire.summary(PATH_HZ as usize),
        quantized_mesh: opts.quantized_mesh.then(|| r.qm.summary(PATH_HZ as usize)),
        pop_px_max: quantile(&r.pops, 1.0),
        pop_px_p99: quantile(&r.pops, 0.99),
        pop_px_median: median(&r.pops),
        pop_switches: r.pops.len(),
        pop_morphed_px_max: quantile(&r.morphed_pops, 1.0),
        pop_morphed_px_p99: quantile(&r.morphed_pops, 0.99),
        session_bytes: median(&r.session_bytes),
        build_tiles_s: flight.built.tiles_s,
        store_bytes: flight.built.bytes,
    })
}

/// Tile `t` as a Cesium quantized-mesh tile (no extensions): the same vertices and triangles,
/// heights in metres, the samples placed on a nominal geographic grid of 1e-4 degrees a sample
/// (quantized-mesh positions are relative to the tile's bounds, so the bytes do not depend on
/// where the tile lies). What a Cesium client of the same tiles receives.
pub fn quantized_mesh_of(t: &TileData, z_quantum: f32) -> Option<Vec<u8>> {
    const DEG: f64 = 1e-4;
    let s = &t.span;
    let mesh = QmMesh {
        west: f64::from(s.cols.0) * DEG,
        east: f64::from(s.cols.1) * DEG,
        // Rows run south.
        north: -f64::from(s.rows.0) * DEG,
        south: -f64::from(s.rows.1) * DEG,
        vertices: (0..t.z.len() as u32)
            .map(|v| {
                let (c, r) = t.vertex_pos(v);
                let z = f64::from(t.z[v as usize]) * f64::from(z_quantum);
                [f64::from(c) * DEG, -f64::from(r) * DEG, z]
            })
            .collect(),
        triangles: t.triangles(),
    };
    quantized_mesh::encode(&mesh, &QmExtensions::default()).ok()
}

/// The active tiles' surface triangles in world metres (patches and skirts are vertical and
/// carry no height of their own over the grid).
fn world_triangles(
    mirror: &TileMirror,
    active: &[u32],
    geom: &relief_proto::terrain::TerrainGeometry,
) -> Vec<[Vec3; 3]> {
    let mut out = Vec::new();
    for &i in active {
        if let Some(t) = mirror.tile(i) {
            let tt = tile_triangles(&geom.frame, geom.z_quantum, t, None);
            out.extend(
                tt.mesh
                    .iter()
                    .map(|tri| tri.map(|v| Vec3::from(tt.positions[v as usize]))),
            );
        }
    }
    out
}

/// For each added tile, the largest pixel distance between its vertices as drawn now and the
/// surface of the removed tiles it replaces at the same ground position, for `proj`; into
/// `morphed`, the same with the client's morph (only border vertices of a split's children).
fn pops(
    mirror: &TileMirror,
    removed: &[u32],
    added: &[u32],
    proj: &Projector,
    geom: &relief_proto::terrain::TerrainGeometry,
    out: &mut Vec<f64>,
    morphed: &mut Vec<f64>,
) {
    let q = geom.z_quantum;
    let old: Vec<_> = removed.iter().filter_map(|&i| mirror.tile(i)).collect();
    let surfaces: Vec<Surface> = old.iter().map(|t| Surface::new(t)).collect();
    for &i in added {
        let Some(t) = mirror.tile(i) else { continue };
        let sp = t.span;
        let overlapping: Vec<usize> = (0..old.len())
            .filter(|&k| {
                let o = old[k].span;
                o.cols.0 <= sp.cols.1
                    && sp.cols.0 <= o.cols.1
                    && o.rows.0 <= sp.rows.1
                    && sp.rows.0 <= o.rows.1
            })
            .collect();
        let mut worst: Option<f64> = None;
        let mut worst_edge: Option<f64> = None;
        for v in 0..t.z.len() as u32 {
            let (c, rr) = t.vertex_pos(v);
            let Some(&k) = overlapping.iter().find(|&&k| {
                let o = old[k].span;
                (o.cols.0..=o.cols.1).contains(&c) && (o.rows.0..=o.rows.1).contains(&rr)
            }) else {
                continue;
            };
            let Some(before) = surfaces[k].height_at(c as f32, rr as f32) else {
                continue;
            };
            let before = before * q;
            let (x, y) = geom.frame.to_world(c as f32, rr as f32);
            let now = Vec3::new(x, y, t.z[v as usize] as f32 * q);
            let was = Vec3::new(x, y, before);
            if let (Some(a), Some(b)) = (proj.project(now), proj.project(was)) {
                let d = f64::from(a.distance(b));
                worst = Some(worst.map_or(d, |m| m.max(d)));
                let on_edge =
                    c == sp.cols.0 || c == sp.cols.1 || rr == sp.rows.0 || rr == sp.rows.1;
                if on_edge {
                    worst_edge = Some(worst_edge.map_or(d, |m| m.max(d)));
                }
            }
        }
        // A split's children morph their interior vertices from the parent's mesh.
        let split = overlapping
            .iter()
            .all(|&k| old[k].tile.level < t.tile.level);
        if let Some(m) = worst {
            out.push(m);
            morphed.push(if split { worst_edge.unwrap_or(0.0) } else { m });
        }
    }
}
