//! `relief-client fly`: one session flown along a camera path, with the figures of DESIGN.md
//! section 7 that the network adds: deltas, bytes per second, camera-to-delta-applied latency,
//! desyncs.
//!
//! The path is the one the server's in-process benchmark flies (`relief_proto::path`), placed
//! over the served terrain with heights from `POST /v1/heights`; poses go out at the path's
//! 10 Hz in real time (or as fast as deltas come back with `rate = 0`). How latency is measured:
//! [`crate::flight`].

use crate::flight::{self, quantile};
use crate::http;
use crate::session::{ClientError, Session, SessionConfig};
use relief_proto::path::{PATH_HZ, PathKind};
use serde::Serialize;
use std::time::Instant;

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
    /// The server's mean time to compute an update during the flight, milliseconds (from its
    /// `/metrics` histogram; includes any other session's updates on a shared server).
    pub server_update_ms_mean: f64,
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

/// Flies the path and reports.
pub async fn fly(opts: &FlyOptions) -> Result<FlyReport, FlyError> {
    let base = http::base_of(&opts.session.url)?;
    let before = update_totals(&base).await?;
    let mut session = Session::connect(opts.session.clone()).await?;
    let extent = flight::extent(session.terrain());
    let spec = flight::PathSpec::Kind(opts.path);
    let cams = flight::server_path(&opts.session.url, extent, spec).await?;
    let t0 = Instant::now();
    let log = flight::fly_poses(&mut session, &cams, opts.rate_hz, t0, None).await?;
    let duration_s = t0.elapsed().as_secs_f64();
    let mut all = log.latencies_ms.clone();
    all.extend(log.first_latency_ms);
    all.sort_by(f64::total_cmp);
    let mut later = log.latencies_ms.clone();
    later.sort_by(f64::total_cmp);
    let c = session.counters();
    let after = update_totals(&base).await?;
    let updates = after.1 - before.1;
    let report = FlyReport {
        poses: log.poses,
        deltas: c.deltas,
        duration_s,
        bytes: c.bytes_in,
        bytes_per_s_mean: c.bytes_in as f64 / duration_s.max(1e-9),
        bytes_per_s_max: log.bytes_per_second.iter().copied().max().unwrap_or(0) as f64,
        first_delta_bytes: log.first_delta_bytes,
        latency_ms_p50: quantile(&all, 0.5),
        latency_ms_p99: quantile(&all, 0.99),
        latency_ms_max: all.last().copied().unwrap_or(0.0),
        latency_samples: all.len(),
        latency_ms_p99_after_first: quantile(&later, 0.99),
        desyncs: c.desyncs,
        reconnects: c.reconnects,
        triangles_final: session.triangle_count(),
        active_final: session.active_count(),
        server_update_ms_mean: if updates > 0.0 {
            (after.0 - before.0) * 1e3 / updates
        } else {
            0.0
        },
    };
    session.close().await;
    Ok(report)
}

/// The server's update-time sum (seconds) and count, from `/metrics`.
async fn update_totals(base: &str) -> Result<(f64, f64), FlyError> {
    let body = http::request("GET", &format!("{base}/metrics"), "text/plain", Vec::new()).await?;
    let m = crate::load::parse_metrics(&String::from_utf8_lossy(&body));
    let get = |k: &str| m.get(k).copied().unwrap_or(0.0);
    Ok((
        get("relief_update_seconds_sum"),
        get("relief_update_seconds_count"),
    ))
}

/// The path's pose rate.
pub const DEFAULT_RATE_HZ: f64 = PATH_HZ as f64;
