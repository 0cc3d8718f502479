//! One session flown along camera poses, with what a measurement needs: per-pose latency,
//! bytes over time, and change counts. Shared by `fly` (one session) and `load` (many).
//!
//! Poses go out at a fixed rate in real time (or each as soon as the previous one is answered,
//! at rate 0). A pose's latency runs from just before it is sent to when the complete delta
//! answering it has been applied. Poses the server coalesced into a newer one have no delta of
//! their own and no latency sample.

use crate::http::{self, HttpError};
use crate::session::{Applied, ClientError, Session};
use relief_proto::msg::TerrainInfo;
use relief_proto::path::{PathKind, camera_path, random_path};
use relief_proto::view::Camera;
use std::collections::HashMap;
use std::time::{Duration, Instant};

/// What one flight recorded.
#[derive(Clone, Debug, Default)]
pub struct FlightLog {
    /// Poses sent.
    pub poses: usize,
    /// Latency of the first pose (its delta builds the whole cut), milliseconds.
    pub first_latency_ms: Option<f64>,
    /// Latencies of the other poses, milliseconds, in flight order.
    pub latencies_ms: Vec<f64>,
    /// Bytes received per whole second since the flight's clock started.
    pub bytes_per_second: Vec<u64>,
    /// Bytes of the first delta.
    pub first_delta_bytes: u64,
    /// Splits and merges applied.
    pub changes: u64,
}

impl FlightLog {
    /// Applies deltas until a complete one reflects pose `seq`, recording each as it arrives
    /// (not all at the end, as collecting them with [`Session::wait_for_pose`] would: that put
    /// every byte of a late answer into the second the wait ended, and overstated the latency
    /// of the poses answered on the way).
    async fn await_pose(
        &mut self,
        session: &mut Session,
        seq: u64,
        t0: Instant,
        sent_at: &mut HashMap<u64, Instant>,
    ) -> Result<(), ClientError> {
        loop {
            let a = session.next_delta().await?;
            self.record(&a, t0, sent_at);
            if a.pose_seq >= seq && a.complete {
                return Ok(());
            }
        }
    }

    fn record(&mut self, a: &Applied, t0: Instant, sent_at: &mut HashMap<u64, Instant>) {
        let now = Instant::now();
        let sec = now.duration_since(t0).as_secs() as usize;
        if self.bytes_per_second.len() <= sec {
            self.bytes_per_second.resize(sec + 1, 0);
        }
        self.bytes_per_second[sec] += a.bytes as u64;
        if self.first_delta_bytes == 0 {
            self.first_delta_bytes = a.bytes as u64;
        }
        self.changes += a.changes as u64;
        if a.complete
            && let Some(s) = sent_at.remove(&a.pose_seq)
        {
            let ms = now.duration_since(s).as_secs_f64() * 1e3;
            if self.first_latency_ms.is_none() && self.latencies_ms.is_empty() {
                self.first_latency_ms = Some(ms);
            } else {
                self.latencies_ms.push(ms);
            }
            sent_at.retain(|&k, _| k > a.pose_seq);
        }
    }
}

/// Flies `cams` in order (cycling until `stop`, if given, else once) at `rate_hz` (0: lock
/// step). `t0` is the clock the byte bins count from.
pub async fn fly_poses(
    session: &mut Session,
    cams: &[Camera],
    rate_hz: f64,
    t0: Instant,
    stop: Option<Instant>,
) -> Result<FlightLog, ClientError> {
    let mut log = FlightLog::default();
    let mut sent_at: HashMap<u64, Instant> = HashMap::new();
    let period = (rate_hz > 0.0).then(|| Duration::from_secs_f64(1.0 / rate_hz));
    let start = Instant::now();
    let count = if stop.is_some() {
        usize::MAX
    } else {
        cams.len()
    };
    for i in 0..count {
        let cam = cams[i % cams.len()];
        if let Some(p) = period {
            let due = start + p.mul_f64(i as f64);
            if stop.is_some_and(|s| due >= s) {
                break;
            }
            // Apply whatever arrives until the pose is due.
            while !sent_at.is_empty() {
                let now = Instant::now();
                if now >= due {
                    break;
                }
                match tokio::time::timeout(due - now, session.next_delta()).await {
                    Ok(a) => log.record(&a?, t0, &mut sent_at),
                    Err(_) => break,
                }
            }
            tokio::time::sleep_until(due.into()).await;
        } else if stop.is_some_and(|s| Instant::now() >= s) {
            break;
        }
        let now = Instant::now();
        let seq = session.send_pose(cam).await?;
        sent_at.insert(seq, now);
        log.poses += 1;
        if period.is_none() {
            log.await_pose(session, seq, t0, &mut sent_at).await?;
        }
    }
    // The last pose's answer.
    if let Some(&last) = sent_at.keys().max() {
        log.await_pose(session, last, t0, &mut sent_at).await?;
    }
    Ok(log)
}

/// Which path a flight takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathSpec {
    /// The standard or stress loop.
    Kind(PathKind),
    /// A seeded random loop ([`relief_proto::path::random_path`]).
    Random(u64),
}

impl PathSpec {
    fn poses(self, extent: (f32, f32), ground: impl Fn(f32, f32) -> f32) -> Vec<Camera> {
        match self {
            PathSpec::Kind(k) => camera_path(k, extent.0, extent.1, ground),
            PathSpec::Random(seed) => random_path(seed, extent.0, extent.1, ground),
        }
    }
}

/// The extent of a terrain in metres (the grid's, from the first sample to the last).
pub fn extent(info: &TerrainInfo) -> (f32, f32) {
    (
        info.width.saturating_sub(1) as f32 * info.spacing_x,
        info.height.saturating_sub(1) as f32 * info.spacing_y,
    )
}

/// The path `spec` over a terrain of `extent` metres, with ground heights from the server's
/// `POST /v1/heights`.
pub async fn server_path(
    stream_url: &str,
    extent: (f32, f32),
    spec: PathSpec,
) -> Result<Vec<Camera>, HttpError> {
    let base = http::base_of(stream_url)?;
    // The path asks for ground heights at points it chooses: collect them, fetch, then build.
    let wanted = std::cell::RefCell::new(Vec::new());
    let _ = spec.poses(extent, |x, y| {
        wanted.borrow_mut().push([x, y]);
        0.0
    });
    let points = wanted.into_inner();
    let body = serde_json::json!({ "points": points });
    let url = format!("{base}/v1/heights");
    let v = http::post_json(&url, &body).await?;
    let hs = v["heights"].as_array().cloned().unwrap_or_default();
    if hs.len() != points.len() {
        return Err(HttpError::Io {
            url,
            message: format!("asked {} heights, got {}", points.len(), hs.len()),
        });
    }
    let heights: HashMap<(u32, u32), f32> = points
        .iter()
        .zip(&hs)
        .map(|(p, h)| {
            (
                (p[0].to_bits(), p[1].to_bits()),
                h.as_f64().unwrap_or(0.0) as f32,
            )
        })
        .collect();
    Ok(spec.poses(extent, |x, y| {
        heights
            .get(&(x.to_bits(), y.to_bits()))
            .copied()
            .unwrap_or(0.0)
    }))
}

/// The `q`-quantile of sorted values (0 for none).
pub fn quantile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let i = ((sorted.len() as f64 - 1.0) * q).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}
