//! `relief-server bench sessions`: many vertex-stream sessions on one core, in process, the way
//! a loaded server runs them (the load targets of `docs/vertex-stream.md`).
//!
//! Each session flies its own seeded random loop, the paths of `relief-client load --path
//! random` (session `i` flies [`random_path`]`(seed + i)`, with the ground heights from the
//! DEM), and at every pose each session takes one camera update: what a server's session does
//! per camera message ([`Stream::update`]: the event-driven update and the delta's packed body),
//! without the WebSocket, the runtime or the kernel. The same updates run twice:
//!
//! - **interleaved**: pose after pose, every session in turn, as on a loaded server: each update
//!   finds its session's state (schedule, bitset, models) where the other sessions' updates
//!   have left the caches;
//! - **one session at a time**: each session flies its whole path before the next starts, so
//!   its state stays warm between its updates, as in `bench lod`.
//!
//! Both runs make the same deltas (the digests and bodies are compared: the command fails if
//! any differs), so the ratio of their times is what the caches cost a loaded server per
//! update, and the interleaved time bounds how many sessions one core can update at 10 Hz
//! before anything else a server does (`sessions_per_core_at_10hz`). Each session's first
//! update (its whole initial cut, from the root) is timed apart.

use super::flight::Flight;
use super::stats::{mean, median, quantile};
use crate::dem::Dem;
use crate::lod::vertex::{LodParams, VertexEngine};
use crate::serve::stream::{Produced, Stream};
use crate::store::Store;
use relief_proto::cut::Cut;
use relief_proto::path::{PATH_HZ, PathKind, random_path};
use relief_proto::view::{Camera, Lens};
use serde::Serialize;
use std::time::Instant;

/// What to run.
#[derive(Clone, Debug)]
pub struct SessionsBenchOptions {
    /// Sessions updated in turn.
    pub sessions: usize,
    /// Poses each session flies (its first update included).
    pub poses: usize,
    /// Seed of the first session's path, as `relief-client load --seed`.
    pub seed: u64,
    /// Screen-error threshold and the rest of the LOD parameters.
    pub params: LodParams,
    /// The cap on a session's interior nodes (the server's `--max-cut-nodes` default).
    pub max_interior: usize,
    /// Show progress bars.
    pub progress: bool,
}

impl Default for SessionsBenchOptions {
    fn default() -> Self {
        SessionsBenchOptions {
            sessions: 100,
            poses: 100,
            seed: 1,
            params: LodParams::default(),
            max_interior: 8_000_000,
            progress: false,
        }
    }
}

/// The benchmark's figures. Times are of one update on one core, microseconds, over every
/// update but each session's first.
#[derive(Clone, Debug, Serialize)]
pub struct SessionsBenchReport {
    /// The DEM flown over.
    pub dem: String,
    /// Grid width, samples.
    pub width: u32,
    /// Grid height, samples.
    pub height: u32,
    /// Sessions updated in turn.
    pub sessions: usize,
    /// Poses each session flew.
    pub poses: usize,
    /// Seed of the first session's path.
    pub seed: u64,
    /// Screen-space error threshold, pixels.
    pub tau_px: f32,
    /// Updates timed (each session's first left out).
    pub updates: usize,
    /// Splits and merges per update, median and 90th percentile.
    pub changes_median: f64,
    /// See `changes_median`.
    pub changes_p90: f64,
    /// Bytes of a delta's packed body, mean.
    pub body_bytes_mean: f64,
    /// A session's first update (its initial cut from the root), median.
    pub initial_us_median: f64,
    /// Interleaved: median, 90th and 99th percentiles and mean of an update.
    pub interleaved_us_median: f64,
    /// See `interleaved_us_median`.
    pub interleaved_us_p90: f64,
    /// See `interleaved_us_median`.
    pub interleaved_us_p99: f64,
    /// See `interleaved_us_median`.
    pub interleaved_us_mean: f64,
    /// Interleaved: all updates' time over all their changes, nanoseconds.
    pub interleaved_ns_per_change: f64,
    /// One session at a time: the same figures.
    pub alone_us_median: f64,
    /// See `alone_us_median`.
    pub alone_us_p90: f64,
    /// See `alone_us_median`.
    pub alone_us_p99: f64,
    /// See `alone_us_median`.
    pub alone_us_mean: f64,
    /// See `interleaved_ns_per_change`.
    pub alone_ns_per_change: f64,
    /// `interleaved_us_mean / alone_us_mean`: what the caches cost an update on a loaded server.
    pub interleaved_over_alone: f64,
    /// `1e6 / (10 * interleaved_us_mean)`: the sessions one core updates at 10 Hz doing nothing
    /// else, a ceiling on a server's knee (the load test's `cpu_ms_per_update` holds the rest:
    /// the WebSocket, the runtime, the kernel).
    pub sessions_per_core_at_10hz: f64,
    /// A session's memory after its flight (its cut, schedule and models), mean, bytes.
    pub session_bytes_mean: f64,
}

/// One update's outcome, to compare the two orders.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
struct Outcome {
    digest: u64,
    body_len: usize,
    body_hash: u64,
}

impl Outcome {
    fn of(p: &Produced) -> Outcome {
        Outcome {
            digest: p.digest,
            body_len: p.body.len(),
            // FNV-1a: only to tell two bodies apart.
            body_hash: p.body.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
                (h ^ b as u64).wrapping_mul(0x0100_0000_01b3)
            }),
        }
    }
}

/// Times of the updates after each session's first, and what each update made.
#[derive(Default)]
struct Run {
    initial_us: Vec<f64>,
    us: Vec<f64>,
    changes: Vec<f64>,
    body_bytes: Vec<f64>,
    /// `outcomes[session][pose]`.
    outcomes: Vec<Vec<Outcome>>,
    session_bytes: Vec<f64>,
}

impl Run {
    fn new(sessions: usize, poses: usize) -> Run {
        Run {
            outcomes: vec![Vec::with_capacity(poses); sessions],
            ..Run::default()
        }
    }

    fn record(&mut self, session: usize, first: bool, us: f64, p: &Produced) {
        if first {
            self.initial_us.push(us);
        } else {
            self.us.push(us);
            self.changes.push(p.changes as f64);
            self.body_bytes.push(p.body.len() as f64);
        }
        self.outcomes[session].push(Outcome::of(p));
    }

    fn ns_per_change(&self) -> f64 {
        1e3 * self.us.iter().sum::<f64>() / self.changes.iter().sum::<f64>().max(1.0)
    }
}

/// Runs the benchmark over `dem`.
pub fn run(dem: &Dem, opts: &SessionsBenchOptions) -> anyhow::Result<SessionsBenchReport> {
    anyhow::ensure!(opts.sessions >= 1, "--sessions must be at least 1");
    anyhow::ensure!(opts.poses >= 2, "--poses must be at least 2");
    let flight = Flight::prepare(
        dem,
        PathKind::Standard,
        Default::default(),
        Some(1),
        0,
        opts.progress,
    )?;
    let store = &flight.store;
    let paths: Vec<Vec<Camera>> = Flight::paths_over(dem, store, |extent, ground| {
        (0..opts.sessions)
            .map(|i| {
                let mut p =
                    random_path(opts.seed.wrapping_add(i as u64), extent.0, extent.1, ground);
                p.truncate(opts.poses);
                p
            })
            .collect()
    });
    let poses = paths[0].len();
    let total = 2 * (opts.sessions * poses) as u64;
    let bar = super::progress_bar(opts.progress, total, "updating");

    let (inter, streams) = interleaved(store, &paths, opts, &bar);
    drop(streams);
    let alone = one_at_a_time(store, &paths, opts, &bar);
    bar.finish_and_clear();

    let differ = (0..opts.sessions)
        .filter(|&i| inter.outcomes[i] != alone.outcomes[i])
        .count();
    anyhow::ensure!(
        differ == 0,
        "{differ} of {} sessions made different deltas interleaved and alone",
        opts.sessions
    );

    let shape = &store.geometry().shape;
    let inter_mean = mean(&inter.us);
    let alone_mean = mean(&alone.us);
    Ok(SessionsBenchReport {
        dem: dem.source.clone(),
        width: shape.width(),
        height: shape.height(),
        sessions: opts.sessions,
        poses,
        seed: opts.seed,
        tau_px: opts.params.tau,
        updates: inter.us.len(),
        changes_median: median(&inter.changes),
        changes_p90: quantile(&inter.changes, 0.9),
        body_bytes_mean: mean(&inter.body_bytes),
        initial_us_median: median(&inter.initial_us),
        interleaved_us_median: median(&inter.us),
        interleaved_us_p90: quantile(&inter.us, 0.9),
        interleaved_us_p99: quantile(&inter.us, 0.99),
        interleaved_us_mean: inter_mean,
        interleaved_ns_per_change: inter.ns_per_change(),
        alone_us_median: median(&alone.us),
        alone_us_p90: quantile(&alone.us, 0.9),
        alone_us_p99: quantile(&alone.us, 0.99),
        alone_us_mean: alone_mean,
        alone_ns_per_change: alone.ns_per_change(),
        interleaved_over_alone: inter_mean / alone_mean,
        sessions_per_core_at_10hz: 1e6 / (PATH_HZ as f64 * inter_mean),
        session_bytes_mean: mean(&inter.session_bytes),
    })
}

/// Every session in turn at each pose; gives back the sessions, so that dropping them is not
/// part of the run.
fn interleaved(
    store: &Store,
    paths: &[Vec<Camera>],
    opts: &SessionsBenchOptions,
    bar: &indicatif::ProgressBar,
) -> (Run, Vec<Stream>) {
    let poses = paths[0].len();
    let mut run = Run::new(paths.len(), poses);
    let mut streams: Vec<Stream> = paths.iter().map(|_| new_stream(store, opts)).collect();
    for t in 0..poses {
        turn(&mut streams, store, paths, t, &mut run);
        bar.inc(streams.len() as u64);
    }
    run.session_bytes = streams.iter().map(|s| s.memory_bytes() as f64).collect();
    (run, streams)
}

/// Pose `t` of every session, interleaved. Not inlined, so that a profile can collect the
/// interleaved updates alone (`valgrind --tool=callgrind --cache-sim=yes
/// --toggle-collect='*sessions::turn*'`; each session's first update is pose 0).
#[inline(never)]
fn turn(streams: &mut [Stream], store: &Store, paths: &[Vec<Camera>], t: usize, run: &mut Run) {
    for (i, s) in streams.iter_mut().enumerate() {
        let (us, p) = timed(s, store, &paths[i][t]);
        run.record(i, t == 0, us, &p);
    }
}

/// Each session's whole flight before the next one's, each from the root again. Not inlined
/// (see [`turn`]).
#[inline(never)]
fn one_at_a_time(
    store: &Store,
    paths: &[Vec<Camera>],
    opts: &SessionsBenchOptions,
    bar: &indicatif::ProgressBar,
) -> Run {
    let mut run = Run::new(paths.len(), paths[0].len());
    for (i, path) in paths.iter().enumerate() {
        let mut s = new_stream(store, opts);
        for (t, cam) in path.iter().enumerate() {
            let (us, p) = timed(&mut s, store, cam);
            run.record(i, t == 0, us, &p);
            bar.inc(1);
        }
    }
    run
}

/// A session as the server opens one without a snapshot: from the root, unbudgeted.
fn new_stream(store: &Store, opts: &SessionsBenchOptions) -> Stream {
    let engine = VertexEngine::new(store);
    let root = Cut::root(&store.geometry().shape);
    Stream::new(
        &engine,
        &root,
        opts.params,
        Lens::STANDARD,
        false,
        opts.max_interior,
    )
}

/// One update, timed in microseconds.
fn timed(s: &mut Stream, store: &Store, cam: &Camera) -> (f64, Produced) {
    let t0 = Instant::now();
    let p = s.update(store, cam, usize::MAX);
    (t0.elapsed().as_secs_f64() * 1e6, p)
}
