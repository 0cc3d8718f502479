//! A load stage's figures: bandwidth per session and in aggregate, deltas and changes per
//! second, latency from an HDR histogram, errors, and the server's CPU and memory as scraped.
//! Field meanings are listed in the README's load-test table.

use super::{LoadOptions, ServerSample, SessionOutcome};
use crate::flight::quantile;
use hdrhistogram::Histogram;
use serde::Serialize;

/// Mean and percentiles of a set of values.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct Dist {
    /// Mean.
    pub mean: f64,
    /// Median.
    pub p50: f64,
    /// 99th percentile.
    pub p99: f64,
    /// Largest.
    pub max: f64,
}

impl Dist {
    pub(crate) fn of(mut v: Vec<f64>) -> Dist {
        if v.is_empty() {
            return Dist::default();
        }
        v.sort_by(f64::total_cmp);
        Dist {
            mean: v.iter().sum::<f64>() / v.len() as f64,
            p50: quantile(&v, 0.5),
            p99: quantile(&v, 0.99),
            max: v[v.len() - 1],
        }
    }
}

/// Latency percentiles from the HDR histogram, milliseconds.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct Latency {
    /// Median.
    pub p50: f64,
    /// 90th percentile.
    pub p90: f64,
    /// 99th percentile.
    pub p99: f64,
    /// Largest.
    pub max: f64,
    /// Poses measured.
    pub samples: u64,
}

/// The server's side of a stage, from `/metrics`.
#[derive(Clone, Debug, Default, Serialize)]
pub struct ServerFigures {
    /// CPU seconds the server process used during the stage.
    pub cpu_s: f64,
    /// LOD updates it computed.
    pub updates: f64,
    /// CPU milliseconds per update (all of the process's CPU over updates).
    pub cpu_ms_per_update: f64,
    /// CPU seconds per wall second (1.0 = one core busy).
    pub cpu_utilisation: f64,
    /// Resident memory before the stage, bytes.
    pub rss_before_bytes: f64,
    /// Largest resident memory during the stage, bytes.
    pub rss_peak_bytes: f64,
    /// `(peak - before) / sessions`: memory per session beyond the shared store.
    pub rss_per_session_bytes: f64,
    /// Errors the server counted during the stage (all kinds).
    pub errors: f64,
    /// The same by kind (kinds with none left out): e.g. `rate_limited` when the load
    /// generator opens connections faster than the server's per-IP rate allows.
    pub errors_by_kind: std::collections::BTreeMap<String, f64>,
    /// Message bytes the server sent during the stage.
    pub bytes_out: f64,
    /// Queries the server answered during the stage (`relief_queries_total`).
    pub queries: f64,
    /// CPU microseconds per query answered (all of the process's CPU over queries).
    pub cpu_us_per_query: f64,
}

/// One second of the stage, for the bandwidth plot.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct TimelinePoint {
    /// Seconds since the stage began.
    pub t_s: f64,
    /// Bytes received by all sessions in this second.
    pub bytes_per_s: f64,
    /// Sessions open on the server.
    pub sessions: f64,
    /// Server CPU seconds per second.
    pub server_cpu: f64,
}

/// Everything one stage measured.
#[derive(Clone, Debug, Default, Serialize)]
pub struct StageReport {
    /// Concurrent sessions asked for.
    pub sessions: usize,
    /// Path kind.
    pub path: String,
    /// Tau, pixels.
    pub tau: f32,
    /// Per-session budget, bytes per second.
    pub budget: Option<u32>,
    /// Poses per second per session.
    pub rate_hz: f64,
    /// Whether fans were rebuilt.
    pub mesh: bool,
    /// The stream: `vertex`, or `tiles` with its crack mode and cache limit.
    pub stream: String,
    /// Tiles received with their body, all sessions (tile stream).
    pub tiles_sent: u64,
    /// Tiles activated from the sessions' caches (tile stream).
    pub tiles_from_cache: u64,
    /// Seconds of the measured window (after the ramp).
    pub steady_s: f64,
    /// Sessions that flew to the end.
    pub sessions_ok: usize,
    /// Sessions that stopped with an error.
    pub errors: usize,
    /// Up to five distinct error messages.
    pub error_samples: Vec<String>,
    /// Digest mismatches.
    pub desyncs: u64,
    /// Reconnections.
    pub reconnects: u64,
    /// Poses sent.
    pub poses: u64,
    /// Deltas applied.
    pub deltas: u64,
    /// Deltas per second, all sessions, over the whole stage.
    pub deltas_per_s: f64,
    /// Splits and merges applied per second, all sessions.
    pub changes_per_s: f64,
    /// Bytes all sessions received (payloads).
    pub bytes_client: u64,
    /// Bytes per second over all sessions, per second of the measured window.
    pub aggregate_bytes_per_s: Dist,
    /// Each session's mean bytes per second, over sessions.
    pub session_bytes_per_s: Dist,
    /// Camera-to-delta-applied latency of every pose but each session's first.
    pub latency_ms: Latency,
    /// Latency of each session's first pose (its delta builds the whole cut).
    pub first_latency_ms: Dist,
    /// The server's figures.
    pub server: ServerFigures,
    /// Per second: aggregate bandwidth, sessions, server CPU.
    pub timeline: Vec<TimelinePoint>,
    /// Latency CDF: (milliseconds, fraction of poses at or below).
    pub latency_cdf: Vec<(f64, f64)>,
    /// Query back ends: queries answered, all back ends.
    pub queries: u64,
    /// Query back ends: of those, answered with an error.
    pub query_faults: u64,
    /// Query back ends: queries answered per second, summed over back ends (each over the
    /// time it ran).
    pub queries_per_s: f64,
}

/// The stream in words: `vertex`, or e.g. `tiles (patches, cache 512)`.
pub(crate) fn stream_name(s: relief_proto::msg::StreamKind) -> String {
    match s {
        relief_proto::msg::StreamKind::Vertex => "vertex".into(),
        relief_proto::msg::StreamKind::Query => "query".into(),
        relief_proto::msg::StreamKind::Tiles(p) => {
            let cache = if p.cache_tiles == u32::MAX {
                "unlimited".to_string()
            } else {
                p.cache_tiles.to_string()
            };
            format!("tiles ({:?}, cache {cache})", p.crack).to_lowercase()
        }
    }
}

/// Builds the report of a stage whose measured window starts `ramp_s` after its start.
pub fn summarise(
    opts: &LoadOptions,
    outcomes: &[SessionOutcome],
    samples: &[ServerSample],
    ramp_s: f64,
) -> StageReport {
    // Latencies in microseconds, 1 us to 10 min, 3 significant digits.
    let mut hist = Histogram::<u64>::new_with_bounds(1, 600_000_000, 3)
        .expect("constant histogram bounds are valid");
    let mut bins: Vec<f64> = Vec::new();
    let mut errors = Vec::new();
    let mut r = StageReport {
        sessions: opts.sessions,
        path: format!("{:?}", opts.path).to_lowercase(),
        tau: opts.tau,
        budget: opts.budget,
        rate_hz: opts.rate_hz,
        mesh: opts.mesh,
        stream: match opts.queries {
            Some(q) => format!("query ({}; {} entities per back end)", q.mix, q.entities),
            None => stream_name(opts.stream),
        },
        ..StageReport::default()
    };
    let mut firsts = Vec::new();
    let mut session_rates = Vec::new();
    for o in outcomes {
        match &o.error {
            Some(e) => errors.push(e.clone()),
            None => r.sessions_ok += 1,
        }
        r.desyncs += o.counters.desyncs;
        r.reconnects += o.counters.reconnects;
        r.deltas += o.counters.deltas;
        r.tiles_sent += o.counters.tiles_sent;
        r.tiles_from_cache += o.counters.tiles_from_cache;
        r.bytes_client += o.counters.bytes_in;
        r.poses += o.log.poses as u64;
        firsts.extend(o.log.first_latency_ms);
        for &ms in &o.log.latencies_ms {
            let _ = hist.record(((ms * 1e3).round() as u64).max(1));
        }
        if o.flown_s > 0.0 {
            session_rates.push(o.counters.bytes_in as f64 / o.flown_s);
        }
        for (s, &b) in o.log.bytes_per_second.iter().enumerate() {
            if bins.len() <= s {
                bins.resize(s + 1, 0.0);
            }
            bins[s] += b as f64;
        }
        r.changes_per_s += o.log.changes as f64;
        r.queries += o.queries;
        r.query_faults += o.query_faults;
        if o.flown_s > 0.0 {
            r.queries_per_s += o.queries as f64 / o.flown_s;
        }
    }
    r.errors = errors.len();
    errors.sort();
    errors.dedup();
    r.error_samples = errors.into_iter().take(5).collect();
    let wall = samples.last().map_or(0.0, |s| s.t_s).max(1e-9);
    r.steady_s = (wall - ramp_s).max(0.0);
    r.deltas_per_s = r.deltas as f64 / wall;
    r.changes_per_s /= wall;
    // The measured window: whole seconds after the ramp (the last, partial second left out).
    let first = ramp_s.ceil() as usize;
    let last = (wall.floor() as usize).min(bins.len());
    r.aggregate_bytes_per_s = Dist::of(bins.get(first..last).unwrap_or(&[]).to_vec());
    r.session_bytes_per_s = Dist::of(session_rates);
    r.first_latency_ms = Dist::of(firsts);
    let ms = |q: f64| hist.value_at_quantile(q) as f64 / 1e3;
    r.latency_ms = Latency {
        p50: ms(0.5),
        p90: ms(0.9),
        p99: ms(0.99),
        max: hist.max() as f64 / 1e3,
        samples: hist.len(),
    };
    r.latency_cdf = cdf(&hist);
    if let (Some(a), Some(b)) = (samples.first(), samples.last()) {
        let peak = samples
            .iter()
            .map(|s| s.rss_bytes)
            .fold(a.rss_bytes, f64::max);
        let updates = b.updates - a.updates;
        let queries = b.queries - a.queries;
        r.server = ServerFigures {
            queries,
            cpu_us_per_query: if queries > 0.0 {
                (b.cpu_s - a.cpu_s) * 1e6 / queries
            } else {
                0.0
            },
            cpu_s: b.cpu_s - a.cpu_s,
            updates,
            cpu_ms_per_update: if updates > 0.0 {
                (b.cpu_s - a.cpu_s) * 1e3 / updates
            } else {
                0.0
            },
            cpu_utilisation: (b.cpu_s - a.cpu_s) / wall,
            rss_before_bytes: a.rss_bytes,
            rss_peak_bytes: peak,
            rss_per_session_bytes: (peak - a.rss_bytes) / opts.sessions.max(1) as f64,
            errors: b.errors - a.errors,
            errors_by_kind: b
                .errors_by_kind
                .iter()
                .map(|(k, v)| {
                    (
                        k.clone(),
                        v - a.errors_by_kind.get(k).copied().unwrap_or(0.0),
                    )
                })
                .filter(|(_, v)| *v > 0.0)
                .collect(),
            bytes_out: b.bytes_out - a.bytes_out,
        };
    }
    // One point per whole second of bytes, with the server sample that closes that second.
    r.timeline = bins
        .iter()
        .enumerate()
        .filter(|_| !samples.is_empty())
        .map(|(sec, &bytes)| {
            let end = samples
                .iter()
                .position(|x| x.t_s >= sec as f64 + 1.0)
                .unwrap_or(samples.len().saturating_sub(1));
            let (prev, cur) = (&samples[end.saturating_sub(1)], &samples[end]);
            TimelinePoint {
                t_s: sec as f64 + 0.5,
                bytes_per_s: bytes,
                sessions: cur.sessions,
                server_cpu: (cur.cpu_s - prev.cpu_s) / (cur.t_s - prev.t_s).max(1e-9),
            }
        })
        .collect();
    r
}

/// The latency CDF as (milliseconds, fraction at or below): one point at every percentile from
/// the minimum, then 99.9 %, 99.99 % and the maximum (none without samples).
pub fn cdf(hist: &hdrhistogram::Histogram<u64>) -> Vec<(f64, f64)> {
    if hist.is_empty() {
        return Vec::new();
    }
    let mut qs: Vec<f64> = (0..=100).map(|p| p as f64 / 100.0).collect();
    qs.splice(100..100, [0.999, 0.9999]);
    let ms = |v: u64| v as f64 / 1e3;
    let mut out: Vec<(f64, f64)> = qs
        .into_iter()
        .map(|q| {
            let v = if q == 0.0 {
                hist.min()
            } else if q == 1.0 {
                hist.max()
            } else {
                hist.value_at_quantile(q)
            };
            (ms(v), q)
        })
        .collect();
    out.dedup();
    out
}

/// Where a sweep breaks away: the first stage whose p99 latency exceeds `p99_ms` or that has
/// errors or desyncs, with the reason; `None` if every stage held.
pub fn knee(stages: &[StageReport], p99_ms: f64) -> Option<(usize, String)> {
    stages.iter().find_map(|s| {
        if s.errors > 0 || s.server.errors > 0.0 {
            let kinds: Vec<String> = s
                .server
                .errors_by_kind
                .iter()
                .map(|(k, v)| format!("{v} {k}"))
                .collect();
            let kinds = if kinds.is_empty() {
                "none".to_string()
            } else {
                kinds.join(", ")
            };
            Some((
                s.sessions,
                format!("{} client errors; server errors: {kinds}", s.errors),
            ))
        } else if s.desyncs > 0 {
            Some((s.sessions, format!("{} desyncs", s.desyncs)))
        } else if s.latency_ms.p99 > p99_ms {
            Some((
                s.sessions,
                format!("p99 latency {:.1} ms over {p99_ms} ms", s.latency_ms.p99),
            ))
        } else {
            None
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flight::FlightLog;
    use crate::load::LoadPath;
    use crate::session::Counters;
    use std::time::Duration;

    fn opts(sessions: usize) -> LoadOptions {
        LoadOptions {
            url: "ws://127.0.0.1:1/v1/stream".into(),
            sessions,
            duration: Duration::from_secs(4),
            ramp: Duration::from_secs(1),
            path: LoadPath::Standard,
            seed: 1,
            tau: 1.0,
            budget: None,
            stream: relief_proto::msg::StreamKind::Vertex,
            rate_hz: 10.0,
            mesh: false,
            progress: false,
            queries: None,
        }
    }

    fn outcome(latencies: Vec<f64>, bytes: Vec<u64>, error: Option<&str>) -> SessionOutcome {
        let total: u64 = bytes.iter().sum();
        SessionOutcome {
            log: FlightLog {
                poses: latencies.len() + 1,
                first_latency_ms: Some(100.0),
                latencies_ms: latencies,
                bytes_per_second: bytes,
                first_delta_bytes: 10,
                changes: 50,
            },
            counters: Counters {
                deltas: 10,
                bytes_in: total,
                desyncs: 0,
                reconnects: 1,
                resumes: 1,
                ..Counters::default()
            },
            error: error.map(str::to_string),
            flown_s: 5.0,
            ..SessionOutcome::default()
        }
    }

    fn sample(t_s: f64, cpu_s: f64, rss: f64, updates: f64, bad: f64) -> ServerSample {
        ServerSample {
            t_s,
            cpu_s,
            rss_bytes: rss,
            sessions: 2.0,
            updates,
            sessions_total: 0.0,
            resumes: 0.0,
            bytes_out: 0.0,
            queries: 0.0,
            errors: bad,
            errors_by_kind: [("bad_camera".to_string(), bad)].into_iter().collect(),
        }
    }

    #[test]
    fn figures_follow_from_the_flights_and_samples() {
        let outcomes = vec![
            outcome(
                (1..=100).map(f64::from).collect(),
                vec![100, 200, 300, 400, 500],
                None,
            ),
            outcome(vec![1000.0], vec![0, 0, 100, 100, 100], Some("boom")),
        ];
        let samples = vec![
            sample(0.0, 10.0, 1e6, 0.0, 0.0),
            sample(2.5, 11.0, 3e6, 10.0, 0.0),
            sample(5.0, 12.0, 2e6, 20.0, 3.0),
        ];
        let r = summarise(&opts(2), &outcomes, &samples, 1.0);
        assert_eq!((r.sessions_ok, r.errors), (1, 1));
        assert_eq!(r.error_samples, vec!["boom".to_string()]);
        assert_eq!((r.deltas, r.reconnects, r.poses), (20, 2, 103));
        assert_eq!(r.bytes_client, 1500 + 300);
        // Whole seconds 1..5 after a 1 s ramp: 200, 400, 500, 600.
        assert_eq!(r.aggregate_bytes_per_s.mean, 425.0);
        assert_eq!(r.aggregate_bytes_per_s.max, 600.0);
        // 101 samples of 1..=100 ms and 1000 ms (first poses excluded).
        assert_eq!(r.latency_ms.samples, 101);
        assert!((r.latency_ms.p50 - 51.0).abs() < 0.1, "{:?}", r.latency_ms);
        assert!(
            (r.latency_ms.max - 1000.0).abs() < 1.0,
            "{:?}",
            r.latency_ms
        );
        assert_eq!(r.first_latency_ms.p50, 100.0);
        // Server: 2 CPU seconds over 20 updates; peak RSS 3 MB over a 1 MB start, per session.
        assert!((r.server.cpu_ms_per_update - 100.0).abs() < 1e-9);
        assert!((r.server.rss_per_session_bytes - 1e6).abs() < 1e-6);
        assert_eq!(r.server.errors_by_kind.get("bad_camera"), Some(&3.0));
        assert_eq!(r.timeline.len(), 5);
    }

    #[test]
    fn the_knee_is_the_first_stage_that_breaks_away() {
        let mut a = StageReport {
            sessions: 10,
            ..StageReport::default()
        };
        a.latency_ms.p99 = 20.0;
        let mut b = a.clone();
        b.sessions = 100;
        b.latency_ms.p99 = 80.0;
        let mut c = a.clone();
        c.sessions = 1000;
        c.errors = 3;
        assert_eq!(knee(&[a.clone()], 50.0), None);
        let k = knee(&[a.clone(), b, c.clone()], 50.0).unwrap();
        assert_eq!(k.0, 100);
        assert!(k.1.contains("80.0 ms"));
        let k = knee(&[a, c], 50.0).unwrap();
        assert_eq!(k.0, 1000);
        assert!(k.1.contains("3 client errors"));
    }
}
