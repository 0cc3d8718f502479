//! `relief-client load --soak DURATION`: many sessions cycling for a long, bounded time while
//! the server's resident memory is sampled, to show that it stays flat.
//!
//! Each virtual client cycles until the end ([`cycle`]): connect, fly, drop the connection,
//! resume from its snapshot, fly, ..., close, and again, with seeded random segment lengths.
//! Meanwhile the server's `/metrics` is scraped every `sample_every`; the samples after the
//! warm-up give the verdict ([`verdict`]): RSS within the tolerance, no desyncs, no errors,
//! every drop resumed. [`report`] writes the samples (JSON, CSV), the RSS plot and a summary.
//!
//! - [`duration`]: humane durations (`2m`, `1h`) and the one-week bound.

pub mod cycle;
pub mod duration;
pub mod report;
pub mod verdict;

use super::{LoadError, LoadOptions, ServerSample, progress_bar, scrape};
use crate::http;
use crate::session::SessionConfig;
use cycle::{ClientPlan, CycleShape, Rng, Shared};
use serde::Serialize;
use std::sync::Arc;
use std::time::{Duration, Instant};
use verdict::{RssFigures, SoakSample, Totals, Verdict, mib};

/// A soak's settings.
#[derive(Clone, Debug)]
pub struct SoakOptions {
    /// The sessions' settings: `duration` is the soak's length, `ramp` how long the clients
    /// take to start (evenly spread), `rate_hz` must be above 0.
    pub load: LoadOptions,
    /// How often the server's RSS is sampled.
    pub sample_every: Duration,
    /// How long after the start samples are left out of the verdict.
    pub warmup: Duration,
    /// The largest (max - min) / min of the RSS after the warm-up that passes.
    pub rss_tolerance: f64,
    /// The cycles' shape.
    pub shape: CycleShape,
}

/// Sessions a soak runs unless told otherwise.
pub const DEFAULT_SESSIONS: usize = 500;

/// Clients started per second during the ramp, at most: the server's default per-address
/// connection rate is 100 a second, and cycling clients reconnect meanwhile.
const RAMP_PER_S: f64 = 40.0;

impl SoakOptions {
    /// The default warm-up for a soak of `duration` sampled every `sample_every`: a tenth of
    /// the duration, at least one sample interval.
    pub fn default_warmup(duration: Duration, sample_every: Duration) -> Duration {
        (duration / 10).max(sample_every)
    }

    /// The default ramp for `sessions`: 40 a second, at most `warmup`.
    pub fn default_ramp(sessions: usize, warmup: Duration) -> Duration {
        Duration::from_secs_f64(sessions as f64 / RAMP_PER_S).min(warmup)
    }

    /// Checks the settings, in the user's terms.
    pub fn check(&self) -> Result<(), LoadError> {
        let bad = |m: String| Err(LoadError::Options(m));
        let (d, every, warm) = (self.load.duration, self.sample_every, self.warmup);
        if d > duration::MAX_SOAK {
            return bad(format!(
                "--soak {} is longer than the limit of {}: a soak must be bounded",
                duration::humane(d),
                duration::humane(duration::MAX_SOAK)
            ));
        }
        if self.load.sessions == 0 {
            return bad("--sessions must be at least 1".into());
        }
        if !(self.load.rate_hz.is_finite() && self.load.rate_hz > 0.0) {
            return bad("--rate must be above 0 for a soak (its sessions fly in real time)".into());
        }
        if !(self.rss_tolerance.is_finite() && self.rss_tolerance > 0.0) {
            return bad("--rss-tolerance must be a positive fraction (0.05 is 5 %)".into());
        }
        if every < Duration::from_millis(100) {
            return bad("--sample-every must be at least 100ms".into());
        }
        if warm >= d {
            return bad(format!(
                "the warm-up ({}) must be shorter than the soak ({})",
                duration::humane(warm),
                duration::humane(d)
            ));
        }
        // Samples are taken at whole multiples of the interval, up to the duration.
        let n = (d.as_secs_f64() / every.as_secs_f64() + 1e-9).floor();
        let first = (warm.as_secs_f64() / every.as_secs_f64() - 1e-9).ceil();
        if n - first + 1.0 < 3.0 {
            return bad(format!(
                "a soak of {} sampled every {} with a warm-up of {} leaves fewer than 3 samples to judge: sample more often or soak longer",
                duration::humane(d),
                duration::humane(every),
                duration::humane(warm)
            ));
        }
        let (lo, hi) = self.shape.segment_poses;
        if lo == 0 || hi < lo {
            return bad("segment lengths must be at least 1 pose, fewest first".into());
        }
        Ok(())
    }
}

/// Everything a soak measured.
#[derive(Clone, Debug, Default, Serialize)]
pub struct SoakReport {
    /// Virtual clients.
    pub sessions: usize,
    /// Seconds the soak lasted, as asked.
    pub duration_s: f64,
    /// Seconds between samples.
    pub sample_every_s: f64,
    /// Seconds of warm-up left out of the verdict.
    pub warmup_s: f64,
    /// Seconds over which the clients started.
    pub ramp_s: f64,
    /// The RSS tolerance, a fraction.
    pub rss_tolerance: f64,
    /// The stream (`vertex` or `tiles ...`).
    pub stream: String,
    /// The path kind.
    pub path: String,
    /// Poses per second per session.
    pub rate_hz: f64,
    /// Tau, pixels.
    pub tau: f32,
    /// The seed of the clients' generators (and of random paths).
    pub seed: u64,
    /// Poses per segment, fewest and most.
    pub segment_poses: (u32, u32),
    /// Drops per cycle, fewest and most.
    pub drops_per_cycle: (u32, u32),
    /// Seconds from the first client's start until the last one stopped.
    pub wall_s: f64,
    /// What the clients did.
    pub totals: Totals,
    /// Camera-to-delta-applied latency, milliseconds: median, 99th percentile, largest.
    pub latency_ms: (f64, f64, f64),
    /// Sessions the server welcomed during the soak (`relief_sessions_total`).
    pub server_sessions: f64,
    /// Resumes the server counted during the soak (`relief_resumes_total`).
    pub server_resumes: f64,
    /// Errors the server counted during the soak, by kind (kinds with none left out).
    pub server_errors: std::collections::BTreeMap<String, f64>,
    /// Server CPU seconds per wall second over the soak.
    pub server_cpu: f64,
    /// RSS before the first client started, bytes.
    pub rss_start_bytes: f64,
    /// RSS after the warm-up (`None`: fewer than two samples).
    pub rss: Option<RssFigures>,
    /// Scrapes that failed (left out of the samples).
    pub failed_scrapes: u64,
    /// The samples, the first one before any client started.
    pub samples: Vec<SoakSample>,
    /// Pass or fail.
    pub verdict: Verdict,
}

/// Runs a soak and judges it. Errors only when it cannot start (bad options, no server); a
/// failed verdict is in the report.
pub async fn run_soak(opts: &SoakOptions) -> Result<SoakReport, LoadError> {
    opts.check()?;
    let lo = &opts.load;
    let base = http::base_of(&lo.url)?;
    let extent = super::terrain_extent(&http::base_of(&lo.url)?).await?;
    let paths = super::paths(lo, extent).await?;
    let shared = Arc::new(Shared::default());
    let sample = |s: ServerSample, shared: &Shared| {
        let t = shared.totals();
        SoakSample {
            t_s: s.t_s,
            rss_bytes: s.rss_bytes,
            sessions: s.sessions,
            cpu_s: s.cpu_s,
            cycles: t.cycles,
            resumes: t.resumes,
            desyncs: t.desyncs,
            errors: t.errors,
        }
    };
    let before = scrape(&base, 0.0).await?;
    let t0 = Instant::now();
    // The clients run a little past the last sample, so that it sees the full load.
    let end = t0 + lo.duration;
    let stop = end + opts.sample_every.min(Duration::from_secs(5));
    let mut seeds = Rng::new(lo.seed);
    let mut tasks = Vec::with_capacity(lo.sessions);
    for i in 0..lo.sessions {
        let cams = paths[i % paths.len()].clone();
        let cursor = super::loop_phase(i, lo.sessions, paths.len(), cams.len(), lo);
        let config = SessionConfig {
            tau: lo.tau,
            budget: lo.budget,
            stream: lo.stream,
            mesh: lo.mesh,
            ..SessionConfig::new(&lo.url)
        };
        tasks.push(tokio::spawn(cycle::run_client(ClientPlan {
            config,
            cams,
            cursor,
            rate_hz: lo.rate_hz,
            start: t0 + super::session_start(i, lo),
            stop,
            shape: opts.shape,
            rng: Rng::new(seeds.next_u64()),
            shared: shared.clone(),
        })));
    }
    let bar = progress_bar(lo.progress, lo.duration.as_secs().max(1));
    let mut samples = vec![sample(before.clone(), &shared)];
    let mut failed_scrapes = 0;
    let mut k = 1u32;
    loop {
        let due = t0 + opts.sample_every * k;
        if due > end + Duration::from_millis(1) {
            break;
        }
        tokio::time::sleep_until(due.into()).await;
        let t = t0.elapsed().as_secs_f64();
        match scrape(&base, t).await {
            Ok(s) => {
                let s = sample(s, &shared);
                if lo.progress {
                    bar.suspend(|| eprintln!("{}", progress_line(&s, opts.warmup)));
                }
                samples.push(s);
            }
            Err(e) => {
                failed_scrapes += 1;
                tracing::warn!("scrape at {t:.0} s failed: {e}");
            }
        }
        bar.set_position(t as u64);
        k += 1;
    }
    bar.finish_and_clear();
    for t in tasks {
        if let Err(e) = t.await {
            shared
                .errors
                .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            tracing::warn!("a soak client panicked: {e}");
        }
    }
    let wall_s = t0.elapsed().as_secs_f64();
    let after = scrape(&base, wall_s).await?;
    Ok(summarise(
        opts,
        &shared,
        &before,
        &after,
        samples,
        failed_scrapes,
        wall_s,
    ))
}

/// One sample as a line for the terminal.
fn progress_line(s: &SoakSample, warmup: Duration) -> String {
    format!(
        "{:>7.0} s  RSS {:>8.1} MiB  {:>5} sessions  {} cycles  {} resumes  {} desyncs  {} errors{}",
        s.t_s,
        mib(s.rss_bytes),
        s.sessions,
        s.cycles,
        s.resumes,
        s.desyncs,
        s.errors,
        if s.t_s < warmup.as_secs_f64() {
            "  (warm-up)"
        } else {
            ""
        }
    )
}

/// The report of a soak from its counts and samples.
fn summarise(
    opts: &SoakOptions,
    shared: &Shared,
    before: &ServerSample,
    after: &ServerSample,
    samples: Vec<SoakSample>,
    failed_scrapes: u64,
    wall_s: f64,
) -> SoakReport {
    let lo = &opts.load;
    let totals = shared.totals();
    let warmup_s = opts.warmup.as_secs_f64();
    let rss = verdict::rss_figures(&samples, warmup_s, opts.rss_tolerance);
    let verdict = verdict::verdict(rss.as_ref(), opts.rss_tolerance, &totals);
    let latency_ms = shared.latency_us.lock().map_or((0.0, 0.0, 0.0), |h| {
        let ms = |v: u64| v as f64 / 1e3;
        if h.is_empty() {
            (0.0, 0.0, 0.0)
        } else {
            (
                ms(h.value_at_quantile(0.5)),
                ms(h.value_at_quantile(0.99)),
                ms(h.max()),
            )
        }
    });
    SoakReport {
        sessions: lo.sessions,
        duration_s: lo.duration.as_secs_f64(),
        sample_every_s: opts.sample_every.as_secs_f64(),
        warmup_s,
        ramp_s: lo.ramp.as_secs_f64(),
        rss_tolerance: opts.rss_tolerance,
        stream: super::stats::stream_name(lo.stream),
        path: format!("{:?}", lo.path).to_lowercase(),
        rate_hz: lo.rate_hz,
        tau: lo.tau,
        seed: lo.seed,
        segment_poses: opts.shape.segment_poses,
        drops_per_cycle: opts.shape.drops,
        wall_s,
        totals,
        latency_ms,
        server_sessions: after.sessions_total - before.sessions_total,
        server_resumes: after.resumes - before.resumes,
        server_errors: after
            .errors_by_kind
            .iter()
            .map(|(k, v)| {
                (
                    k.clone(),
                    v - before.errors_by_kind.get(k).copied().unwrap_or(0.0),
                )
            })
            .filter(|(_, v)| *v > 0.0)
            .collect(),
        server_cpu: (after.cpu_s - before.cpu_s) / wall_s.max(1e-9),
        rss_start_bytes: before.rss_bytes,
        rss,
        failed_scrapes,
        samples,
        verdict,
    }
}
