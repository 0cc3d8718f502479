//! One soak client's life: cycles of connect (a new session), fly, drop the connection (the
//! socket closes with no close handshake, as a network failure would), resume (the next pose
//! reconnects with a snapshot of the cut; the server must answer `resumed`), fly, and so on,
//! then close and start again, until the soak ends. Segment lengths, the drops per cycle and
//! the pauses are drawn from a seeded generator per client, so that clients do not move in
//! lock-step; the counts go to [`Shared`] as they happen.

use super::verdict::Totals;
use crate::flight::{self, FlightLog};
use crate::session::{ClientError, Counters, Session, SessionConfig};
use hdrhistogram::Histogram;
use relief_proto::view::Camera;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The shape of a cycle: how long a segment is and how often a cycle drops its connection.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CycleShape {
    /// Poses per flight segment, fewest and most (drawn uniformly).
    pub segment_poses: (u32, u32),
    /// Drops per cycle, fewest and most (drawn uniformly; each is followed by a resume and a
    /// segment).
    pub drops: (u32, u32),
    /// The longest the client stays offline after a drop or between cycles, milliseconds.
    pub max_pause_ms: u32,
}

impl Default for CycleShape {
    /// Segments of 50 to 200 poses (5 to 20 s at 10 Hz), 1 to 3 drops a cycle, pauses up to 2 s:
    /// a cycle lasts about 40 s on average, and 500 clients open about 40 connections a second,
    /// well within the server's default per-address rate of 100.
    fn default() -> Self {
        CycleShape {
            segment_poses: (50, 200),
            drops: (1, 3),
            max_pause_ms: 2000,
        }
    }
}

/// The seeded generator each client draws its plan from.
pub use relief_proto::rng::Rng;

/// The counts every client adds to as it goes (read by the sampler while the soak runs).
#[derive(Debug)]
pub struct Shared {
    /// Cycles completed.
    pub cycles: AtomicU64,
    /// Connections dropped on purpose.
    pub drops: AtomicU64,
    /// Drops resumed from the snapshot.
    pub resumes: AtomicU64,
    /// Drops after which the session started again from scratch.
    pub resumes_missed: AtomicU64,
    /// Reconnections of any kind.
    pub reconnects: AtomicU64,
    /// Digest mismatches.
    pub desyncs: AtomicU64,
    /// Cycles that ended with an error.
    pub errors: AtomicU64,
    /// Poses sent.
    pub poses: AtomicU64,
    /// Deltas applied.
    pub deltas: AtomicU64,
    /// Payload bytes received.
    pub bytes_in: AtomicU64,
    /// Up to five distinct error messages.
    pub error_samples: Mutex<Vec<String>>,
    /// Camera-to-delta-applied latency of every pose but each flight segment's first,
    /// microseconds.
    pub latency_us: Mutex<Histogram<u64>>,
}

impl Default for Shared {
    fn default() -> Self {
        Shared {
            cycles: AtomicU64::new(0),
            drops: AtomicU64::new(0),
            resumes: AtomicU64::new(0),
            resumes_missed: AtomicU64::new(0),
            reconnects: AtomicU64::new(0),
            desyncs: AtomicU64::new(0),
            errors: AtomicU64::new(0),
            poses: AtomicU64::new(0),
            deltas: AtomicU64::new(0),
            bytes_in: AtomicU64::new(0),
            error_samples: Mutex::new(Vec::new()),
            // 1 us to 10 min, 3 significant digits.
            latency_us: Mutex::new(
                Histogram::new_with_bounds(1, 600_000_000, 3)
                    .expect("constant histogram bounds are valid"),
            ),
        }
    }
}

impl Shared {
    /// The counts now.
    pub fn totals(&self) -> Totals {
        Totals {
            cycles: self.cycles.load(Relaxed),
            drops: self.drops.load(Relaxed),
            resumes: self.resumes.load(Relaxed),
            resumes_missed: self.resumes_missed.load(Relaxed),
            reconnects: self.reconnects.load(Relaxed),
            desyncs: self.desyncs.load(Relaxed),
            errors: self.errors.load(Relaxed),
            error_samples: self
                .error_samples
                .lock()
                .map(|e| e.clone())
                .unwrap_or_default(),
            poses: self.poses.load(Relaxed),
            deltas: self.deltas.load(Relaxed),
            bytes_in: self.bytes_in.load(Relaxed),
        }
    }

    fn error(&self, e: &ClientError) {
        self.errors.fetch_add(1, Relaxed);
        if let Ok(mut v) = self.error_samples.lock() {
            let text = e.to_string();
            if v.len() < 5 && !v.contains(&text) {
                v.push(text);
            }
        }
    }

    fn flight(&self, log: &FlightLog) {
        self.poses.fetch_add(log.poses as u64, Relaxed);
        if let Ok(mut h) = self.latency_us.lock() {
            for &ms in &log.latencies_ms {
                let _ = h.record(((ms * 1e3).round() as u64).max(1));
            }
        }
    }

    /// Adds what a session counted since `seen`, and moves `seen` on.
    fn session(&self, seen: &mut Counters, now: Counters) {
        self.reconnects
            .fetch_add(now.reconnects - seen.reconnects, Relaxed);
        self.desyncs.fetch_add(now.desyncs - seen.desyncs, Relaxed);
        self.deltas.fetch_add(now.deltas - seen.deltas, Relaxed);
        self.bytes_in
            .fetch_add(now.bytes_in - seen.bytes_in, Relaxed);
        *seen = now;
    }
}

/// One soak client's plan.
pub struct ClientPlan {
    /// Its sessions' settings.
    pub config: SessionConfig,
    /// Its path, flown in order and round again.
    pub cams: Arc<Vec<Camera>>,
    /// Where on the path it is, poses.
    pub cursor: usize,
    /// Poses per second (above 0).
    pub rate_hz: f64,
    /// When it first connects.
    pub start: Instant,
    /// When it stops (a segment under way is cut short there).
    pub stop: Instant,
    /// Its cycles' shape.
    pub shape: CycleShape,
    /// Its generator.
    pub rng: Rng,
    /// Where its counts go.
    pub shared: Arc<Shared>,
}

/// Runs one client's cycles until its stop.
pub async fn run_client(mut plan: ClientPlan) {
    tokio::time::sleep_until(plan.start.into()).await;
    while Instant::now() < plan.stop {
        match cycle(&mut plan).await {
            Ok(true) => {
                plan.shared.cycles.fetch_add(1, Relaxed);
            }
            Ok(false) => {}
            Err(e) => {
                plan.shared.error(&e);
                // Start again after a second, as a user would retry.
                pause(Duration::from_secs(1), plan.stop).await;
            }
        }
        let ms = plan.rng.between(0, plan.shape.max_pause_ms);
        pause(Duration::from_millis(u64::from(ms)), plan.stop).await;
    }
}

/// Sleeps for `d`, but not past `stop`.
async fn pause(d: Duration, stop: Instant) {
    let until = (Instant::now() + d).min(stop);
    tokio::time::sleep_until(until.into()).await;
}

/// One cycle: true when it completed, false when the soak's end cut it short.
async fn cycle(plan: &mut ClientPlan) -> Result<bool, ClientError> {
    let mut session = Session::connect(plan.config.clone()).await?;
    let mut seen = Counters::default();
    let drops = plan.rng.between(plan.shape.drops.0, plan.shape.drops.1);
    let r = segments(plan, &mut session, &mut seen, drops).await;
    plan.shared.session(&mut seen, session.counters());
    session.close().await;
    r
}

/// The cycle's segments on `session`, with `drops` drops between them; `seen` is what the
/// session had counted when its counts last went to [`Shared`].
async fn segments(
    plan: &mut ClientPlan,
    session: &mut Session,
    seen: &mut Counters,
    drops: u32,
) -> Result<bool, ClientError> {
    let period = Duration::from_secs_f64(1.0 / plan.rate_hz);
    for seg in 0..=drops {
        let poses = plan
            .rng
            .between(plan.shape.segment_poses.0, plan.shape.segment_poses.1)
            .max(1);
        if seg == 0 {
            let flown = fly(plan, session, poses, period).await?;
            plan.shared.session(seen, session.counters());
            if !flown {
                return Ok(false);
            }
            continue;
        }
        // Drop only with time left to fly after the resume: a drop that is never resumed
        // would be counted as missed.
        if Instant::now() + period * 2 + plan.pause_max() >= plan.stop {
            return Ok(false);
        }
        let before = session.counters().resumes;
        session.drop_connection();
        plan.shared.drops.fetch_add(1, Relaxed);
        let ms = plan.rng.between(0, plan.shape.max_pause_ms);
        tokio::time::sleep(Duration::from_millis(u64::from(ms))).await;
        // The segment's first pose reconnects with the snapshot.
        let flown = fly(plan, session, poses, period).await?;
        plan.shared.session(seen, session.counters());
        if session.counters().resumes > before {
            plan.shared.resumes.fetch_add(1, Relaxed);
        } else {
            plan.shared.resumes_missed.fetch_add(1, Relaxed);
        }
        if !flown {
            return Ok(false);
        }
    }
    Ok(true)
}

impl ClientPlan {
    fn pause_max(&self) -> Duration {
        Duration::from_millis(u64::from(self.shape.max_pause_ms))
    }
}

/// Flies the next `poses` poses of the path at the plan's rate; false when the soak's end cut
/// the segment short.
async fn fly(
    plan: &mut ClientPlan,
    session: &mut Session,
    poses: u32,
    period: Duration,
) -> Result<bool, ClientError> {
    let n = plan.cams.len();
    let cams: Vec<Camera> = (0..poses as usize)
        .map(|k| plan.cams[(plan.cursor + k) % n])
        .collect();
    // Half a period short of the last pose's slot, so that exactly `poses` poses are due before
    // it (or fewer at the soak's end).
    let planned = Instant::now() + period.mul_f64(f64::from(poses) - 0.5);
    let cut = plan.stop < planned;
    let t0 = Instant::now();
    let log = flight::fly_poses(
        session,
        &cams,
        plan.rate_hz,
        t0,
        Some(planned.min(plan.stop)),
    )
    .await?;
    plan.cursor = (plan.cursor + log.poses) % n;
    plan.shared.flight(&log);
    Ok(!cut)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_generator_is_seeded_and_stays_in_range() {
        let (mut a, mut b) = (Rng::new(7), Rng::new(7));
        let xs: Vec<u32> = (0..1000).map(|_| a.between(50, 200)).collect();
        let ys: Vec<u32> = (0..1000).map(|_| b.between(50, 200)).collect();
        assert_eq!(xs, ys);
        assert!(xs.iter().all(|x| (50..=200).contains(x)));
        // Both ends are reached and the values spread.
        assert!(xs.contains(&50) && xs.contains(&200));
        let mut c = Rng::new(8);
        assert_ne!(
            xs,
            (0..1000).map(|_| c.between(50, 200)).collect::<Vec<_>>()
        );
        assert_eq!(a.between(3, 3), 3);
        assert_eq!(a.between(5, 1), 5);
    }
}
