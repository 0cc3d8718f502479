//! `relief-client load`: many real protocol sessions at once against one server, for the
//! engineer who load-tests LOD update bandwidth.
//!
//! Each virtual client is a [`Session`] (mirror, digest check, acknowledgements; fans too with
//! `mesh`; or, for the tile stream, a light tile mirror that decodes and checks every tile and
//! digest but keeps no tile data, the decoded tiles too with `mesh`) flying its own path: the
//! standard or stress loop phase-shifted by its index, or a seeded random loop. Sessions start spread over the ramp, fly until the stage ends, and stop
//! by themselves. Meanwhile a sampler scrapes the server's `/metrics` once a second for its CPU
//! time, resident memory, sessions and updates.
//!
//! - [`stats`]: turning the flights and samples into a [`StageReport`].
//! - [`report`]: the JSON file, the Markdown summary and the plots of `--report DIR`.
//! - [`soak`]: `--soak DURATION`: sessions cycling (connect, fly, drop, resume) for a long,
//!   bounded time while the server's resident memory is sampled and judged.

pub mod query;
pub mod report;
pub mod soak;
pub mod stats;

use crate::flight::{self, FlightLog, PathSpec};
use crate::http::{self, HttpError};
use crate::session::{Counters, Session, SessionConfig};
use relief_proto::path::PathKind;
use relief_proto::view::Camera;
use std::collections::HashMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::time::{Duration, Instant};

pub use stats::StageReport;

/// Which paths the sessions fly.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LoadPath {
    /// The standard loop, phase-shifted per session.
    Standard,
    /// The stress loop, phase-shifted per session.
    Stress,
    /// A seeded random loop per session.
    Random,
}

impl std::str::FromStr for LoadPath {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "standard" => Ok(LoadPath::Standard),
            "stress" => Ok(LoadPath::Stress),
            "random" => Ok(LoadPath::Random),
            _ => Err(format!(
                "unknown path {s:?}: use standard, stress or random"
            )),
        }
    }
}

/// One stage of a load run.
#[derive(Clone, Debug)]
pub struct LoadOptions {
    /// The stream's URL.
    pub url: String,
    /// Concurrent sessions.
    pub sessions: usize,
    /// How long every session flies once all have started.
    pub duration: Duration,
    /// Over how long the sessions start (evenly spread).
    pub ramp: Duration,
    /// Which paths.
    pub path: LoadPath,
    /// Seed of the random paths.
    pub seed: u64,
    /// Screen-space error threshold, pixels.
    pub tau: f32,
    /// Per-session bandwidth budget, bytes per second.
    pub budget: Option<u32>,
    /// The stream every session asks for (tile sessions apply every tile delta to their tile
    /// mirror and check its digest; they build no triangles, and keep no tile data unless
    /// `mesh`).
    pub stream: relief_proto::msg::StreamKind,
    /// Poses per second per session (0: each as soon as the previous is answered).
    pub rate_hz: f64,
    /// Rebuild fans as a viewer would (tile sessions: keep the decoded tiles).
    pub mesh: bool,
    /// Show a progress bar.
    pub progress: bool,
    /// Simulator back ends asking terrain queries instead of viewers streaming
    /// ([`query`]): each session is a back end, each pose a batch.
    pub queries: Option<query::QueryLoad>,
}

/// A load run that could not be made.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// The server's HTTP API failed.
    #[error(transparent)]
    Http(#[from] HttpError),
    /// The options make no sense.
    #[error("{0}")]
    Options(String),
}

/// What one virtual client did.
#[derive(Debug, Default)]
pub struct SessionOutcome {
    /// Its flight.
    pub log: FlightLog,
    /// Its session counters.
    pub counters: Counters,
    /// Why it stopped early, if it did.
    pub error: Option<String>,
    /// Seconds it flew.
    pub flown_s: f64,
    /// Queries answered (query back ends).
    pub queries: u64,
    /// Of those, answered with an error (query back ends).
    pub query_faults: u64,
}

/// One scrape of the server's `/metrics`.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct ServerSample {
    /// Seconds since the stage began.
    pub t_s: f64,
    /// `process_cpu_seconds_total`.
    pub cpu_s: f64,
    /// `process_resident_memory_bytes`.
    pub rss_bytes: f64,
    /// `relief_sessions_active`.
    pub sessions: f64,
    /// `relief_updates_total`.
    pub updates: f64,
    /// `relief_sessions_total`.
    pub sessions_total: f64,
    /// `relief_queries_total`.
    pub queries: f64,
    /// `relief_resumes_total`.
    pub resumes: f64,
    /// `relief_bytes_out_total`.
    pub bytes_out: f64,
    /// Sum of `relief_errors_total` over kinds.
    pub errors: f64,
    /// `relief_errors_total` by kind.
    pub errors_by_kind: std::collections::BTreeMap<String, f64>,
}

/// Parses Prometheus text into series -> value.
pub fn parse_metrics(text: &str) -> HashMap<String, f64> {
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.is_empty())
        .filter_map(|l| {
            let (k, v) = l.rsplit_once(' ')?;
            Some((k.to_string(), v.parse().ok()?))
        })
        .collect()
}

/// Scrapes the server's metrics.
pub async fn scrape(base: &str, t_s: f64) -> Result<ServerSample, HttpError> {
    let body = http::request("GET", &format!("{base}/metrics"), "text/plain", Vec::new()).await?;
    let m = parse_metrics(&String::from_utf8_lossy(&body));
    let get = |k: &str| m.get(k).copied().unwrap_or(0.0);
    Ok(ServerSample {
        t_s,
        cpu_s: get("process_cpu_seconds_total"),
        rss_bytes: get("process_resident_memory_bytes"),
        sessions: get("relief_sessions_active"),
        updates: get("relief_updates_total"),
        sessions_total: get("relief_sessions_total"),
        queries: get("relief_queries_total"),
        resumes: get("relief_resumes_total"),
        bytes_out: get("relief_bytes_out_total"),
        errors: m
            .iter()
            .filter(|(k, _)| k.starts_with("relief_errors_total{"))
            .map(|(_, v)| v)
            .sum(),
        errors_by_kind: m
            .iter()
            .filter_map(|(k, v)| {
                let kind = k.strip_prefix("relief_errors_total{kind=\"")?;
                Some((kind.trim_end_matches("\"}").to_string(), *v))
            })
            .collect(),
    })
}

/// The terrain's extent, from `GET /v1/terrain`.
pub(crate) async fn terrain_extent(base: &str) -> Result<(f32, f32), LoadError> {
    let t = http::get_json(&format!("{base}/v1/terrain")).await?;
    let e = t["extent_m"]
        .as_array()
        .and_then(|a| Some((a.first()?.as_f64()? as f32, a.get(1)?.as_f64()? as f32)))
        .ok_or_else(|| LoadError::Options("the server's /v1/terrain has no extent_m".into()))?;
    Ok(e)
}

/// One virtual client's plan.
struct Plan {
    /// Its session settings.
    config: SessionConfig,
    /// Its path.
    cams: Arc<Vec<Camera>>,
    /// Where on the path it starts, poses.
    phase: usize,
    /// Poses per second.
    rate_hz: f64,
    /// The stage's clock.
    t0: Instant,
    /// When it connects.
    start: Instant,
    /// When it stops.
    stop: Instant,
    /// The stage's running count of deltas, for the progress bar.
    deltas: Arc<AtomicU64>,
}

/// Flies one virtual client: connect at its start, fly until its stop.
async fn virtual_client(plan: Plan) -> SessionOutcome {
    let Plan {
        config,
        cams,
        phase,
        rate_hz,
        t0,
        start,
        stop,
        deltas,
    } = plan;
    tokio::time::sleep_until(start.into()).await;
    let began = Instant::now();
    let mut out = SessionOutcome::default();
    let mut session = match Session::connect(config).await {
        Ok(s) => s,
        Err(e) => {
            out.error = Some(e.to_string());
            return out;
        }
    };
    let n = cams.len();
    let shifted: Vec<Camera> = (0..n).map(|k| cams[(phase + k) % n]).collect();
    match flight::fly_poses(&mut session, &shifted, rate_hz, t0, Some(stop)).await {
        Ok(log) => out.log = log,
        Err(e) => out.error = Some(e.to_string()),
    }
    out.counters = session.counters();
    deltas.fetch_add(out.counters.deltas, Relaxed);
    out.flown_s = began.elapsed().as_secs_f64();
    session.close().await;
    out
}

/// The options every stage shares, checked (the session count is checked per stage).
fn check(opts: &LoadOptions) -> Result<(), LoadError> {
    if !(opts.rate_hz.is_finite() && opts.rate_hz >= 0.0) {
        return Err(LoadError::Options("--rate must be 0 or more".into()));
    }
    if let Some(q) = opts.queries {
        if q.entities == 0 {
            return Err(LoadError::Options("--entities must be at least 1".into()));
        }
        let n = q.batch_len();
        if n > relief_proto::query::MAX_BATCH {
            return Err(LoadError::Options(format!(
                "--entities {} with --queries {} makes batches of {n} queries; the server takes at most {}",
                q.entities,
                q.mix,
                relief_proto::query::MAX_BATCH
            )));
        }
        if q.mix.rays + q.mix.sights > relief_proto::query::MAX_BATCH_RAYS {
            return Err(LoadError::Options(format!(
                "--queries {}: at most {} rays and lines of sight per batch",
                q.mix,
                relief_proto::query::MAX_BATCH_RAYS
            )));
        }
    }
    Ok(())
}

/// The sessions' paths, with ground heights from the server: one shared loop for standard and
/// stress (each session phase-shifted along it), or one seeded random loop per session.
pub(crate) async fn paths(
    opts: &LoadOptions,
    extent: (f32, f32),
) -> Result<Vec<Arc<Vec<Camera>>>, LoadError> {
    let kind = match opts.path {
        LoadPath::Standard => PathKind::Standard,
        LoadPath::Stress => PathKind::Stress,
        LoadPath::Random => {
            let mut v = Vec::with_capacity(opts.sessions);
            for i in 0..opts.sessions {
                let spec = PathSpec::Random(opts.seed.wrapping_add(i as u64));
                v.push(Arc::new(
                    flight::server_path(&opts.url, extent, spec).await?,
                ));
                // One heights request each: stay well under the per-address connection rate.
                tokio::time::sleep(Duration::from_millis(25)).await;
            }
            return Ok(v);
        }
    };
    let cams = flight::server_path(&opts.url, extent, PathSpec::Kind(kind)).await?;
    Ok(vec![Arc::new(cams)])
}

/// When session `i` of the stage or soak starts, after the stage's start: spread evenly over
/// the ramp.
pub(crate) fn session_start(i: usize, opts: &LoadOptions) -> Duration {
    opts.ramp.mul_f64(i as f64 / opts.sessions as f64)
}

/// Where session `i` of `n` begins on its path of `len` poses: on a loop shared by all
/// (`paths` = 1), its share of the loop plus the poses it would have flown had it started with
/// the first session, so that once the ramp is over the sessions are evenly spread along the
/// loop; on a path of its own, the start.
///
/// Without the second term, a 12.5 s ramp on the standard loop left a fifth of it empty: the
/// gap travelled round with the sessions, and the server's memory rose and fell with the
/// detail under them (a 3-4 % wave with the loop's period in the 3-minute soak).
pub(crate) fn loop_phase(
    i: usize,
    n: usize,
    paths: usize,
    len: usize,
    opts: &LoadOptions,
) -> usize {
    if paths != 1 || len == 0 {
        return 0;
    }
    let lead = (session_start(i, opts).as_secs_f64() * opts.rate_hz).round() as usize;
    (i * len / n + lead) % len
}

/// Runs one stage and reports it.
pub async fn run_stage(opts: &LoadOptions) -> Result<StageReport, LoadError> {
    if opts.sessions == 0 {
        return Err(LoadError::Options("--sessions must be at least 1".into()));
    }
    check(opts)?;
    let base = http::base_of(&opts.url)?;
    let extent = terrain_extent(&base).await?;
    // Query back ends fly no path.
    let paths = match opts.queries {
        Some(_) => Vec::new(),
        None => paths(opts, extent).await?,
    };
    let before = scrape(&base, 0.0).await?;
    let t0 = Instant::now();
    let ramp_end = t0 + opts.ramp;
    let stop = ramp_end + opts.duration;
    let deltas = Arc::new(AtomicU64::new(0));
    let mut tasks = Vec::with_capacity(opts.sessions);
    for i in 0..opts.sessions {
        if let Some(load) = opts.queries {
            tasks.push(tokio::spawn(query::back_end(query::BackEnd {
                opts: opts.clone(),
                load,
                index: i,
                t0,
                start: t0 + session_start(i, opts),
                stop,
                answered: deltas.clone(),
            })));
            continue;
        }
        let mut config = SessionConfig::new(&opts.url);
        config.tau = opts.tau;
        config.budget = opts.budget;
        config.stream = opts.stream;
        config.mesh = opts.mesh;
        let cams = paths[i % paths.len()].clone();
        let phase = loop_phase(i, opts.sessions, paths.len(), cams.len(), opts);
        tasks.push(tokio::spawn(virtual_client(Plan {
            config,
            cams,
            phase,
            rate_hz: opts.rate_hz,
            t0,
            start: t0 + session_start(i, opts),
            stop,
            deltas: deltas.clone(),
        })));
    }
    // The sampler and the progress bar, until every session is done.
    let total = (opts.ramp + opts.duration).as_secs().max(1);
    let bar = progress_bar(opts.progress, total);
    let mut samples = vec![before.clone()];
    let all_done = futures_util::future::join_all(tasks);
    tokio::pin!(all_done);
    let mut tick = tokio::time::interval(Duration::from_secs(1));
    let outcomes = loop {
        tokio::select! {
            done = &mut all_done => break done,
            _ = tick.tick() => {
                let t = t0.elapsed().as_secs_f64();
                if let Ok(s) = scrape(&base, t).await {
                    bar.set_message(format!(
                        "{} sessions on the server, {} updates",
                        s.sessions, s.updates - before.updates
                    ));
                    samples.push(s);
                }
                bar.set_position((t as u64).min(total));
            }
        }
    };
    bar.finish_and_clear();
    samples.push(scrape(&base, t0.elapsed().as_secs_f64()).await?);
    let outcomes: Vec<SessionOutcome> = outcomes
        .into_iter()
        .map(|r| {
            r.unwrap_or_else(|e| SessionOutcome {
                error: Some(format!("virtual client panicked: {e}")),
                ..SessionOutcome::default()
            })
        })
        .collect();
    Ok(stats::summarise(
        opts,
        &outcomes,
        &samples,
        opts.ramp.as_secs_f64(),
    ))
}

fn progress_bar(show: bool, total: u64) -> indicatif::ProgressBar {
    if !show {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new(total);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{elapsed_precise} [{bar:30}] {pos}/{len} s  {msg}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
        .progress_chars("=> "),
    );
    bar
}

/// Runs the stages of a sweep in turn (each with `sessions` replaced) and reports them all.
pub async fn run_sweep(
    opts: &LoadOptions,
    counts: &[usize],
) -> Result<Vec<StageReport>, LoadError> {
    // Every stage's options are checked before the first starts, so a bad one fails at once.
    if counts.contains(&0) {
        return Err(LoadError::Options(if counts.len() > 1 {
            "--sweep: every stage needs at least 1 session".into()
        } else {
            "--sessions must be at least 1".into()
        }));
    }
    check(opts)?;
    let mut stages = Vec::new();
    for &n in counts {
        let o = LoadOptions {
            sessions: n,
            ..opts.clone()
        };
        if opts.progress {
            eprintln!("stage: {n} session{}", if n == 1 { "" } else { "s" });
        }
        stages.push(run_stage(&o).await?);
        // Let the server settle (sessions close, memory returns) between stages.
        tokio::time::sleep(Duration::from_secs(1)).await;
    }
    Ok(stages)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn opts(sessions: usize, ramp_s: f64, rate_hz: f64) -> LoadOptions {
        LoadOptions {
            url: "ws://127.0.0.1:1/v1/stream".into(),
            sessions,
            duration: Duration::from_secs(60),
            ramp: Duration::from_secs_f64(ramp_s),
            path: LoadPath::Standard,
            seed: 1,
            tau: 1.0,
            budget: None,
            stream: relief_proto::msg::StreamKind::Vertex,
            rate_hz,
            mesh: false,
            progress: false,
            queries: None,
        }
    }

    /// Where each session is on the loop once the last has started (poses flown since each
    /// session's own start added to its phase).
    fn positions_after_ramp(o: &LoadOptions, len: usize) -> Vec<usize> {
        let end = o.ramp.as_secs_f64();
        (0..o.sessions)
            .map(|i| {
                let flown = (end - session_start(i, o).as_secs_f64()) * o.rate_hz;
                (loop_phase(i, o.sessions, 1, len, o) + flown.round() as usize) % len
            })
            .collect()
    }

    #[test]
    fn sessions_on_a_shared_loop_are_evenly_spread_once_the_ramp_is_over() {
        let (len, o) = (650, opts(500, 12.5, 10.0));
        let mut pos = positions_after_ramp(&o, len);
        pos.sort_unstable();
        // The largest gap between neighbours (round the loop) is about len / n, not the
        // ramp's 125 poses.
        let gaps = pos.windows(2).map(|w| w[1] - w[0]);
        let wrap = pos[0] + len - pos[pos.len() - 1];
        let widest = gaps.chain([wrap]).max().unwrap();
        assert!(widest <= 3, "widest gap {widest} poses");
    }

    #[test]
    fn own_paths_and_lock_step_start_at_the_beginning_or_the_share() {
        let o = opts(4, 10.0, 0.0);
        // Lock step (rate 0): the share alone.
        let phases: Vec<usize> = (0..4).map(|i| loop_phase(i, 4, 1, 100, &o)).collect();
        assert_eq!(phases, [0, 25, 50, 75]);
        // A path per session: from its start.
        assert_eq!(loop_phase(3, 4, 4, 100, &opts(4, 10.0, 10.0)), 0);
        assert_eq!(loop_phase(1, 4, 1, 0, &o), 0);
    }
}
