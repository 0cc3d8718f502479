//! `relief-client render-bench`: what the renderer costs on the client along a camera path.
//!
//! One session flies the path in lock step (each pose answered before the next is sent). For
//! every pose the client's work on the deltas that answer it is timed in three parts: decoding
//! and applying them to the mirror and the fans (`apply`), bringing the node and cell records up
//! to date (`scene`), and handing the changed pages to wgpu (`upload`). Then one frame is drawn
//! offscreen (geomorph pass and terrain pass) and waited for: its time gives the frame rate at
//! that cut. Figures are medians and 99th percentiles over the path's poses.

use super::follow::Follower;
use super::frame::{FrameParams, MorphStage};
use super::gpu::Gpu;
use super::offscreen::{FORMAT, Offscreen};
use super::renderer::Renderer;
use super::shot::ShotError;
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
    let mut follower = Follower::new(&mut session);
    let target = Offscreen::new(&gpu, lens.width, lens.height);
    let mut renderer = Renderer::new(&gpu, FORMAT, &mut follower.scene);
    let (mut apply, mut scene, mut upload, mut total) = (vec![], vec![], vec![], vec![]);
    let (mut bytes, mut frame, mut tris) = (vec![], vec![], vec![]);
    let bar = indicatif::ProgressBar::new(count as u64);
    for (k, cam) in cams.iter().enumerate().take(count) {
        let now = k as f32 / PATH_HZ;
        let seq = session.send_pose(*cam).await?;
        let applied = session.wait_for_pose(seq).await?;
        let a: f64 = applied.iter().map(|a| a.apply_us).sum();
        let t = Instant::now();
        follower.sync(&mut session, now);
        let s = t.elapsed().as_secs_f64() * 1e6;
        let t = Instant::now();
        let b = renderer.upload(&gpu, &mut follower.scene);
        let u = t.elapsed().as_secs_f64() * 1e6;
        apply.push(a);
        scene.push(s);
        upload.push(u);
        total.push(a + s + u);
        bytes.push(b as f64);
        let params = FrameParams {
            morph: opts.morph,
            ..FrameParams::offscreen(&session, *cam, lens, now + 1.0 / PATH_HZ)
        };
        let t = Instant::now();
        renderer.render(&gpu, &target.view, &params);
        gpu.wait();
        frame.push(t.elapsed().as_secs_f64() * 1e3);
        tris.push(session.mesh().triangle_count() as f64);
        bar.inc(1);
    }
    bar.finish_and_clear();
    let frame_ms = Spread::of(frame);
    let report = RenderBenchReport {
        adapter: gpu.describe(),
        size: (lens.width, lens.height),
        poses: count,
        deltas: session.counters().deltas,
        apply_us: Spread::of(apply),
        scene_us: Spread::of(scene),
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
    };
    session.close().await;
    Ok(report)
}
