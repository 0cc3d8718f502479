//! `relief-client render-bench`: what the renderer costs on the client along a camera path.
//!
//! One session flies the path in lock step (each pose answered before the next is sent). For
//! every pose the client's work on the deltas that answer it is timed in three parts: decoding
//! and applying them to the mirror and the fans, or to the tile mirror (`apply`), bringing the
//! node and cell records, or the new active tiles' triangles, up to date (`scene`), and handing
//! the changed pages, or the new tiles' buffers, to wgpu (`upload`). Then one frame is drawn
//! offscreen and waited for: its time gives the frame rate at that cut. Figures are medians and
//! 99th percentiles over the path's poses.

use super::frame::{FrameParams, MorphStage};
use super::gpu::Gpu;
use super::offscreen::{FORMAT, Offscreen};
use super::shot::ShotError;
use super::stream::{StreamRenderer, StreamScene};
use crate::flight::{PathSpec, extent, quantile, server_path};
use crate::session::{Session, SessionConfig};
use relief_proto::path::{PATH_HZ, PathKind};
use serde::Serialize;
use std::time::Instant;

/// What to measure.
#[derive(Clone, Debug)]
pub struct RenderBenchOptions {
    /// The session; its lens's size is the frame's.
    pub session: SessionConfig,
    /// The path.
    pub path: PathKind,
    /// Poses to fly (the path's first ones; 0: all).
    pub poses: usize,
    /// Where the geomorph is evaluated.
    pub morph: MorphStage,
    /// Tile stream: draw the dropped crack patches alone (a diagnostic).
    pub dropped_only: bool,
}

/// Median and 99th percentile of a series.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct Spread {
    /// Median.
    pub median: f64,
    /// 99th percentile.
    pub p99: f64,
}

impl Spread {
    fn of(mut v: Vec<f64>) -> Spread {
        v.sort_by(f64::total_cmp);
        Spread {
            median: quantile(&v, 0.5),
            p99: quantile(&v, 0.99),
        }
    }
}

/// The figures.
#[derive(Clone, Debug, Serialize)]
pub struct RenderBenchReport {
    /// The adapter.
    pub adapter: String,
    /// `vertex` or `tiles`.
    pub stream: &'static str,
    /// Frame width and height.
    pub size: (u32, u32),
    /// Poses flown.
    pub poses: usize,
    /// Deltas applied.
    pub deltas: u64,
    /// Decode + apply to the mirror + fans, per pose, microseconds.
    pub apply_us: Spread,
    /// Node and cell records, per pose, microseconds.
    pub scene_us: Spread,
    /// Handing changed pages to wgpu, per pose, microseconds.
    pub upload_us: Spread,
    /// The three together, per pose, microseconds.
    pub client_us: Spread,
    /// Bytes of records uploaded per pose (median and p99).
    pub upload_bytes: Spread,
    /// Time to draw one frame and wait for it, milliseconds.
    pub frame_ms: Spread,
    /// Frames per second at the median frame time.
    pub fps_median: f64,
    /// Triangles drawn (median and p99 over the poses).
    pub triangles: Spread,
    /// Active nodes of the cut, or active tiles (median and p99 over the poses).
    pub active: Spread,
    /// Tiles received with their body (tile stream).
    pub tiles_sent: u64,
    /// Tiles activated from the client's cache (tile stream).
    pub tiles_from_cache: u64,
}

/// Flies the path and measures.
pub async fn render_bench(opts: &RenderBenchOptions) -> Result<RenderBenchReport, ShotError> {
    let gpu = Gpu::headless()?;
    let lens = opts.session.lens;
    let config = super::renderer_config(opts.session.clone());
    let mut session = Session::connect(config).await?;
    let cams = server_path(
        session.url(),
        extent(session.terrain()),
        PathSpec::Kind(opts.path),
    )
    .await?;
    let count = if opts.poses == 0 {
        cams.len()
    } else {
        opts.poses.min(cams.len())
    };
    let mut scene = StreamScene::new(&mut session);
    let target = Offscreen::new(&gpu, lens.width, lens.height);
    let mut renderer = StreamRenderer::new(&gpu, FORMAT, &mut scene);
    let (mut apply, mut scene_t, mut upload, mut total) = (vec![], vec![], vec![], vec![]);
    let (mut bytes, mut frame, mut tris, mut active) = (vec![], vec![], vec![], vec![]);
    let bar = indicatif::ProgressBar::new(count as u64);
    for (k, cam) in cams.iter().enumerate().take(count) {
        let now = k as f32 / PATH_HZ;
        let seq = session.send_pose(*cam).await?;
        let applied = session.wait_for_pose(seq).await?;
        let a: f64 = applied.iter().map(|a| a.apply_us).sum();
        let t = Instant::now();
        scene.sync(&mut session, now);
        let s = t.elapsed().as_secs_f64() * 1e6;
        let t = Instant::now();
        let b = renderer.upload(&gpu, &mut scene);
        let u = t.elapsed().as_secs_f64() * 1e6;
        apply.push(a);
        scene_t.push(s);
        upload.push(u);
        total.push(a + s + u);
        bytes.push(b as f64);
        let params = FrameParams {
            morph: opts.morph,
            dropped_only: opts.dropped_only,
            ..FrameParams::offscreen(&session, *cam, lens, now + 1.0 / PATH_HZ)
        };
        let t = Instant::now();
        renderer.render(&gpu, &target.view, &params);
        gpu.wait();
        frame.push(t.elapsed().as_secs_f64() * 1e3);
        tris.push(match &scene {
            StreamScene::Tiles(t) => t.triangles(opts.dropped_only),
            StreamScene::Vertex(_) => session.triangle_count(),
        } as f64);
        active.push(session.active_count() as f64);
        bar.inc(1);
    }
    bar.finish_and_clear();
    let frame_ms = Spread::of(frame);
    let c = session.counters();
    let report = RenderBenchReport {
        adapter: gpu.describe(),
        stream: if session.is_tiles() {
            "tiles"
        } else {
            "vertex"
        },
        size: (lens.width, lens.height),
        poses: count,
        deltas: c.deltas,
        apply_us: Spread::of(apply),
        scene_us: Spread::of(scene_t),
        upload_us: Spread::of(upload),
        client_us: Spread::of(total),
        upload_bytes: Spread::of(bytes),
        frame_ms,
        fps_median: if frame_ms.median > 0.0 {
            1e3 / frame_ms.median
        } else {
            0.0
        },
        triangles: Spread::of(tris),
        active: Spread::of(active),
        tiles_sent: c.tiles_sent,
        tiles_from_cache: c.tiles_from_cache,
    };
    session.close().await;
    Ok(report)
}
