//! `relief-client chaos`: the deployment's replica drill, against any deployment behind a load
//! balancer. Sessions (half vertex, half tiles) fly the standard loop in lock step (each pose
//! sent when the last is answered, so that every pose is served and a run's final cuts do not
//! depend on timing), each from its own phase; a prober asks `POST /v1/query` through the same
//! balancer on a clock; and when the fleet has flown given fractions of its poses, the drill's
//! actions run (kill a replica, restart one). The report says whether every session survived
//! (none lost, no desyncs, resumed rather than started afresh), how long reconnections took,
//! and whether the queries kept being answered. Its final digests, compared with a run
//! without actions, show that the sessions end with the cuts they would have had.

use crate::flight::{PathSpec, server_path};
use crate::http;
use crate::load::stats::Dist;
use crate::session::{Session, SessionConfig};
use futures_util::future::BoxFuture;
use relief_proto::msg::{CrackMode, StreamKind, TileStreamParams};
use relief_proto::path::PathKind;
use relief_proto::view::Camera;
use serde::Serialize;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::time::{Duration, Instant};

/// What a drill does at its moments.
pub trait Drill: Send {
    /// Carries out `action` (as given in [`ChaosOptions::actions`]); an error stops the drill.
    fn act<'a>(&'a mut self, action: &'a str) -> BoxFuture<'a, Result<(), String>>;
}

/// A drill of shell commands: each action is run with `sh -c`, and must exit 0.
pub struct ShellDrill;

impl Drill for ShellDrill {
    fn act<'a>(&'a mut self, action: &'a str) -> BoxFuture<'a, Result<(), String>> {
        Box::pin(async move {
            let status = tokio::process::Command::new("sh")
                .arg("-c")
                .arg(action)
                .status()
                .await
                .map_err(|e| format!("cannot run {action:?}: {e}"))?;
            if status.success() {
                Ok(())
            } else {
                Err(format!("{action:?} failed: {status}"))
            }
        })
    }
}

/// One run of the drill.
#[derive(Clone, Debug)]
pub struct ChaosOptions {
    /// The stream URL through the balancer.
    pub url: String,
    /// Sessions: the first half vertex, the rest tiles (with crack patches).
    pub sessions: usize,
    /// Poses of the standard loop each session flies.
    pub poses: usize,
    /// `(fraction, action)`: when the fleet has flown this fraction of all its poses, the
    /// action runs (in order; the fleet flies on meanwhile).
    pub actions: Vec<(f64, String)>,
    /// How often the prober asks `POST /v1/query` (`None`: no prober).
    pub query_every: Option<Duration>,
    /// Longest a session may take to reconnect before it counts as lost.
    pub reconnect_deadline: Duration,
}

/// What a run saw.
#[derive(Clone, Debug, Default, Serialize)]
pub struct ChaosReport {
    /// Sessions started.
    pub sessions: usize,
    /// Sessions that flew every pose.
    pub completed: usize,
    /// Sessions that stopped with an error (lost).
    pub lost: usize,
    /// Up to five distinct errors of lost sessions.
    pub errors: Vec<String>,
    /// Digest mismatches, all sessions.
    pub desyncs: u64,
    /// Reconnections, all sessions.
    pub reconnects: u64,
    /// Of those, resumed from the client's snapshot.
    pub resumes: u64,
    /// Sessions that reconnected at least once.
    pub sessions_reconnected: usize,
    /// Reconnection times, from noticing the drop to the new welcome, milliseconds.
    pub reconnect_gap_ms: Dist,
    /// Queries answered by the prober.
    pub queries_ok: u64,
    /// Queries that failed (an error status or no answer).
    pub queries_failed: u64,
    /// Longest time without an answered query, milliseconds.
    pub query_gap_max_ms: f64,
    /// Each action as it ran.
    pub actions: Vec<ActionRecord>,
    /// Seconds the run took.
    pub wall_s: f64,
    /// Each session's final digest, by session index (0 for a lost session).
    pub digests: Vec<u64>,
}

/// One action of a run.
#[derive(Clone, Debug, Default, Serialize)]
pub struct ActionRecord {
    /// The action.
    pub action: String,
    /// When it started, seconds since the run's start.
    pub at_s: f64,
    /// How long it took, seconds.
    pub took_s: f64,
    /// The fraction of all poses flown when it started.
    pub flown_before: f64,
    /// The fraction flown when it ended: below 1 if the fleet was still flying.
    pub flown_after: f64,
}

/// One session's outcome.
struct Flown {
    digest: u64,
    error: Option<String>,
    desyncs: u64,
    reconnects: u64,
    resumes: u64,
    gaps: Vec<f64>,
}

/// The stream of session `i` of `n`: the first half vertex, the rest tiles.
fn stream_of(i: usize, n: usize) -> StreamKind {
    if i < n / 2 {
        StreamKind::Vertex
    } else {
        StreamKind::Tiles(TileStreamParams {
            cache_tiles: 512,
            crack: CrackMode::Patches,
        })
    }
}

async fn fly(
    opts: &ChaosOptions,
    i: usize,
    cams: Arc<Vec<Camera>>,
    flown: Arc<AtomicU64>,
) -> Flown {
    let config = SessionConfig {
        stream: stream_of(i, opts.sessions),
        mesh: false,
        reconnect_deadline: opts.reconnect_deadline,
        ..SessionConfig::new(&opts.url)
    };
    let mut out = Flown {
        digest: 0,
        error: None,
        desyncs: 0,
        reconnects: 0,
        resumes: 0,
        gaps: Vec::new(),
    };
    let mut session = match Session::connect(config).await {
        Ok(s) => s,
        Err(e) => {
            out.error = Some(format!("session {i}: {e}"));
            return out;
        }
    };
    let phase = i * cams.len() / opts.sessions.max(1);
    for k in 0..opts.poses {
        let cam = cams[(phase + k) % cams.len()];
        let r = match session.send_pose(cam).await {
            Ok(seq) => session.wait_for_pose(seq).await.map(|_| ()),
            Err(e) => Err(e),
        };
        if let Err(e) = r {
            out.error = Some(format!("session {i}: {e}"));
            break;
        }
        flown.fetch_add(1, Relaxed);
    }
    let c = session.counters();
    out.desyncs = c.desyncs;
    out.reconnects = c.reconnects;
    out.resumes = c.resumes;
    out.gaps = session.reconnect_gaps_ms().to_vec();
    if out.error.is_none() {
        out.digest = session.digest();
    }
    session.close().await;
    out
}

/// What the prober saw.
#[derive(Default)]
struct Probed {
    ok: u64,
    failed: u64,
    longest_gap_ms: f64,
}

/// Asks `POST /v1/query` every `every` until `stop` turns true.
async fn probe(base: String, every: Duration, stop: Arc<AtomicU64>) -> Probed {
    let mut p = Probed::default();
    let mut last_ok = Instant::now();
    let body = serde_json::json!({"queries": [
        {"hat": {"at": [1000.0, 1000.0, 3000.0]}},
        {"ray": {"origin": [500.0, 500.0, 4000.0], "dir": [1.0, 1.0, -0.3]}},
    ]});
    let mut tick = tokio::time::interval(every);
    while stop.load(Relaxed) == 0 {
        tick.tick().await;
        let url = format!("{base}/v1/query");
        match tokio::time::timeout(Duration::from_secs(5), http::post_json(&url, &body)).await {
            Ok(Ok(v)) if v["answers"].as_array().is_some_and(|a| a.len() == 2) => {
                p.ok += 1;
                last_ok = Instant::now();
            }
            _ => p.failed += 1,
        }
        p.longest_gap_ms = p.longest_gap_ms.max(last_ok.elapsed().as_secs_f64() * 1e3);
    }
    p
}

/// Runs the drill: flies the sessions, runs the actions at their moments, and reports.
pub async fn run(opts: &ChaosOptions, drill: &mut dyn Drill) -> Result<ChaosReport, String> {
    if opts.sessions == 0 || opts.poses == 0 {
        return Err("--sessions and --poses must be at least 1".into());
    }
    for (at, a) in &opts.actions {
        if !(0.0..=1.0).contains(at) {
            return Err(format!("action {a:?} at {at}: the fraction must be 0 to 1"));
        }
    }
    let base = http::base_of(&opts.url).map_err(|e| e.to_string())?;
    let ext = crate::load::terrain_extent(&base)
        .await
        .map_err(|e| e.to_string())?;
    let cams = Arc::new(
        server_path(&opts.url, ext, PathSpec::Kind(PathKind::Standard))
            .await
            .map_err(|e| e.to_string())?,
    );
    let t0 = Instant::now();
    let flown = Arc::new(AtomicU64::new(0));
    let stop = Arc::new(AtomicU64::new(0));
    let prober = opts
        .query_every
        .map(|every| tokio::spawn(probe(base.clone(), every, stop.clone())));
    let tasks: Vec<_> = (0..opts.sessions)
        .map(|i| {
            let (o, c, f) = (opts.clone(), cams.clone(), flown.clone());
            tokio::spawn(async move { fly(&o, i, c, f).await })
        })
        .collect();
    let total = (opts.sessions * opts.poses) as f64;
    let mut done_actions = Vec::new();
    let mut actions = opts.actions.clone();
    actions.sort_by(|a, b| a.0.total_cmp(&b.0));
    for (at, action) in actions {
        while (flown.load(Relaxed) as f64) < at * total && !tasks.iter().all(|t| t.is_finished()) {
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        let (at_s, flown_before) = (
            t0.elapsed().as_secs_f64(),
            flown.load(Relaxed) as f64 / total,
        );
        drill.act(&action).await?;
        done_actions.push(ActionRecord {
            action,
            at_s,
            took_s: t0.elapsed().as_secs_f64() - at_s,
            flown_before,
            flown_after: flown.load(Relaxed) as f64 / total,
        });
    }
    let results = futures_util::future::join_all(tasks).await;
    stop.store(1, Relaxed);
    let probed = match prober {
        Some(p) => p.await.unwrap_or_default(),
        None => Probed::default(),
    };
    let mut r = ChaosReport {
        sessions: opts.sessions,
        actions: done_actions,
        queries_ok: probed.ok,
        queries_failed: probed.failed,
        query_gap_max_ms: probed.longest_gap_ms,
        wall_s: t0.elapsed().as_secs_f64(),
        ..ChaosReport::default()
    };
    let mut gaps = Vec::new();
    let mut errors = Vec::new();
    for res in results {
        let f = res.unwrap_or_else(|e| Flown {
            digest: 0,
            error: Some(format!("session task failed: {e}")),
            desyncs: 0,
            reconnects: 0,
            resumes: 0,
            gaps: Vec::new(),
        });
        match f.error {
            Some(e) => {
                r.lost += 1;
                errors.push(e);
            }
            None => r.completed += 1,
        }
        r.desyncs += f.desyncs;
        r.reconnects += f.reconnects;
        r.resumes += f.resumes;
        if f.reconnects > 0 {
            r.sessions_reconnected += 1;
        }
        gaps.extend(f.gaps);
        r.digests.push(f.digest);
    }
    errors.sort();
    errors.dedup();
    r.errors = errors.into_iter().take(5).collect();
    r.reconnect_gap_ms = Dist::of(gaps);
    Ok(r)
}

/// The report in words, for the command line.
pub fn summary(r: &ChaosReport) -> String {
    let mut s = format!(
        "{} sessions: {} completed, {} lost, {} desyncs; {} reconnections in {} sessions, {} \
         resumed; reconnect gap p50 {:.0} ms, p99 {:.0} ms, max {:.0} ms; queries {} answered, \
         {} failed, longest gap {:.0} ms; {:.1} s",
        r.sessions,
        r.completed,
        r.lost,
        r.desyncs,
        r.reconnects,
        r.sessions_reconnected,
        r.resumes,
        r.reconnect_gap_ms.p50,
        r.reconnect_gap_ms.p99,
        r.reconnect_gap_ms.max,
        r.queries_ok,
        r.queries_failed,
        r.query_gap_max_ms,
        r.wall_s
    );
    for a in &r.actions {
        s.push_str(&format!(
            "\n  at {:.1} s ({:.0} % flown): {} (took {:.2} s; {:.0} % flown after)",
            a.at_s,
            100.0 * a.flown_before,
            a.action,
            a.took_s,
            100.0 * a.flown_after
        ));
    }
    for e in &r.errors {
        s.push_str(&format!("\n  lost: {e}"));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn half_the_sessions_are_tiles() {
        assert_eq!(stream_of(0, 4), StreamKind::Vertex);
        assert_eq!(stream_of(1, 4), StreamKind::Vertex);
        assert!(matches!(stream_of(2, 4), StreamKind::Tiles(_)));
    }

    #[tokio::test]
    async fn a_shell_drill_reports_a_failing_command() {
        let mut d = ShellDrill;
        assert!(d.act("true").await.is_ok());
        let e = d.act("exit 3").await.unwrap_err();
        assert!(e.contains("exit 3"), "{e}");
    }
}
