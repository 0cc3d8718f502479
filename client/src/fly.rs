//! `relief-client fly`: one session flown along a camera path, with the figures of DESIGN.md
//! section 7 that the network adds: deltas, bytes per second, camera-to-delta-applied latency,
//! desyncs.
//!
//! The path is the one the server's in-process benchmark flies (`relief_proto::path`), placed
//! over the served terrain with heights from `POST /v1/heights`. Poses go out at the path's
//! 10 Hz in real time (or as fast as deltas come back with `rate = 0`). A pose's latency runs
//! from just before it is sent to when the complete delta answering it has been applied to the
//! mirror and the mesh. Poses that the server coalesced into a newer one have no delta of their
//! own and no latency sample.

use crate::http;
use crate::session::{ClientError, Session, SessionConfig};
use relief_proto::path::{PATH_HZ, PathKind, camera_path};
use serde::Serialize;
use std::collections::HashMap;
use std::time::{Duration, Instant};

/// What to fly.
#[derive(Clone, Debug)]
pub struct FlyOptions {
    /// The session's settings (URL, lens, tau, budget).
    pub session: SessionConfig,
    /// Which path.
    pub path: PathKind,
    /// Poses per second; 0 sends the next pose as soon as the previous one is answered.
    pub rate_hz: f64,
}

/// The figures of one flight.
#[derive(Clone, Debug, Default, Serialize)]
pub struct FlyReport {
    /// Poses sent.
    pub poses: usize,
    /// Deltas applied.
    pub deltas: u64,
    /// Seconds from the first pose to the last delta.
    pub duration_s: f64,
    /// Bytes of messages received in all.
    pub bytes: u64,
    /// Mean bytes per second over the flight.
    pub bytes_per_s_mean: f64,
    /// Largest bytes received in any one-second window (aligned to the first pose).
    pub bytes_per_s_max: f64,
    /// Bytes of the first delta (the cut from the root).
    pub first_delta_bytes: u64,
    /// Camera-to-delta-applied latency, median, milliseconds.
    pub latency_ms_p50: f64,
    /// 99th percentile, milliseconds.
    pub latency_ms_p99: f64,
    /// Largest, milliseconds.
    pub latency_ms_max: f64,
    /// Poses with a latency sample.
    pub latency_samples: usize,
    /// The same latency without the first pose (whose delta builds the whole cut), p99.
    pub latency_ms_p99_after_first: f64,
    /// Deltas whose digest did not match.
    pub desyncs: u64,
    /// Reconnections during the flight.
    pub reconnects: u64,
    /// Triangles in the mesh at the end.
    pub triangles_final: usize,
    /// Active nodes at the end.
    pub active_final: u64,
}

/// The `q`-quantile of sorted values.
fn quantile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let i = ((sorted.len() as f64 - 1.0) * q).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

/// A flight that could not be flown.
#[derive(Debug, thiserror::Error)]
pub enum FlyError {
    /// The session failed.
    #[error(transparent)]
    Session(#[from] ClientError),
    /// An HTTP request failed.
    #[error(transparent)]
    Http(#[from] http::HttpError),
    /// The server's answer made no sense.
    #[error("unexpected answer from the server: {0}")]
    Answer(String),
}

/// Ground heights for the path, from the server.
async fn ground_heights(
    base: &str,
    points: &[[f32; 2]],
) -> Result<HashMap<(u32, u32), f32>, FlyError> {
    let body = serde_json::json!({ "points": points });
    let v = http::post_json(&format!("{base}/v1/heights"), &body).await?;
    let hs = v["heights"]
        .as_array()
        .ok_or_else(|| FlyError::Answer("no heights".into()))?;
    Ok(points
        .iter()
        .zip(hs)
        .map(|(p, h)| {
            (
                (p[0].to_bits(), p[1].to_bits()),
                h.as_f64().unwrap_or(0.0) as f32,
            )
        })
        .collect())
}

/// Flies the path and reports.
pub async fn fly(opts: &FlyOptions) -> Result<FlyReport, FlyError> {
    let base = http::base_of(&opts.session.url)?;
    let mut session = Session::connect(opts.session.clone()).await?;
    let info = session.terrain().clone();
    let extent = (
        info.width.saturating_sub(1) as f32 * info.spacing_x,
        info.height.saturating_sub(1) as f32 * info.spacing_y,
    );
    // The path asks for ground heights at points it chooses: collect them, fetch, then fly.
    let wanted = std::cell::RefCell::new(Vec::new());
    let _ = camera_path(opts.path, extent.0, extent.1, |x, y| {
        wanted.borrow_mut().push([x, y]);
        0.0
    });
    let heights = ground_heights(&base, &wanted.into_inner()).await?;
    let cams = camera_path(opts.path, extent.0, extent.1, |x, y| {
        heights
            .get(&(x.to_bits(), y.to_bits()))
            .copied()
            .unwrap_or(0.0)
    });

    let t0 = Instant::now();
    let period = if opts.rate_hz > 0.0 {
        Some(Duration::from_secs_f64(1.0 / opts.rate_hz))
    } else {
        None
    };
    let mut sent_at: HashMap<u64, Instant> = HashMap::new();
    let mut latencies = Vec::new();
    let mut first_latency = None;
    let mut per_second: Vec<u64> = Vec::new();
    let mut first_delta_bytes = 0;
    let mut record = |a: &crate::session::Applied, sent_at: &mut HashMap<u64, Instant>| {
        let now = Instant::now();
        let sec = now.duration_since(t0).as_secs() as usize;
        if per_second.len() <= sec {
            per_second.resize(sec + 1, 0);
        }
        per_second[sec] += a.bytes as u64;
        if first_delta_bytes == 0 {
            first_delta_bytes = a.bytes as u64;
        }
        if a.complete
            && let Some(s) = sent_at.remove(&a.pose_seq)
        {
            let ms = now.duration_since(s).as_secs_f64() * 1e3;
            if first_latency.is_none() {
                first_latency = Some(ms);
            } else {
                latencies.push(ms);
            }
            sent_at.retain(|&k, _| k > a.pose_seq);
        }
    };
    for (i, cam) in cams.iter().enumerate() {
        if let Some(p) = period {
            let due = t0 + p.mul_f64(i as f64);
            // Apply whatever arrives until the pose is due.
            while !sent_at.is_empty() {
                let now = Instant::now();
                if now >= due {
                    break;
                }
                match tokio::time::timeout(due - now, session.next_delta()).await {
                    Ok(a) => record(&a?, &mut sent_at),
                    Err(_) => break,
                }
            }
            tokio::time::sleep_until(due.into()).await;
        }
        let now = Instant::now();
        let seq = session.send_pose(*cam).await?;
        sent_at.insert(seq, now);
        if period.is_none() {
            for a in session.wait_for_pose(seq).await? {
                record(&a, &mut sent_at);
            }
        }
    }
    // The last pose's answer.
    if let Some(&last) = sent_at.keys().max() {
        for a in session.wait_for_pose(last).await? {
            record(&a, &mut sent_at);
        }
    }
    let duration_s = t0.elapsed().as_secs_f64();
    let mut all = latencies.clone();
    all.extend(first_latency);
    all.sort_by(f64::total_cmp);
    latencies.sort_by(f64::total_cmp);
    let c = session.counters();
    let report = FlyReport {
        poses: cams.len(),
        deltas: c.deltas,
        duration_s,
        bytes: c.bytes_in,
        bytes_per_s_mean: c.bytes_in as f64 / duration_s.max(1e-9),
        bytes_per_s_max: per_second.iter().copied().max().unwrap_or(0) as f64,
        first_delta_bytes,
        latency_ms_p50: quantile(&all, 0.5),
        latency_ms_p99: quantile(&all, 0.99),
        latency_ms_max: all.last().copied().unwrap_or(0.0),
        latency_samples: all.len(),
        latency_ms_p99_after_first: quantile(&latencies, 0.99),
        desyncs: c.desyncs,
        reconnects: c.reconnects,
        triangles_final: session.mesh().triangle_count(),
        active_final: session.mirror().cut().active_count(),
    };
    session.close().await;
    Ok(report)
}

/// The path's pose rate.
pub const DEFAULT_RATE_HZ: f64 = PATH_HZ as f64;
