//! `--report DIR`: `report.json` (every stage, the knee), `summary.md` (tables and the plots),
//! and PNG plots: bandwidth over time, the latency CDF, and, for sweeps, latency and server CPU
//! against sessions.

use super::stats::{StageReport, knee};
use crate::plot::{Chart, PlotError, Series, render_png};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// What `report.json` holds.
#[derive(Debug, Serialize)]
pub struct RunReport<'a> {
    /// The stages, in the order run.
    pub stages: &'a [StageReport],
    /// The p99 latency, milliseconds, above which a stage counts as broken away.
    pub knee_p99_ms: f64,
    /// The first stage that broke away (sessions), if any.
    pub knee_sessions: Option<usize>,
    /// Why it broke away.
    pub knee_reason: Option<String>,
}

/// Writing the report failed.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// A file could not be written.
    #[error("cannot write {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// A plot could not be drawn.
    #[error(transparent)]
    Plot(#[from] PlotError),
}

fn write(path: &Path, text: &str) -> Result<(), ReportError> {
    std::fs::write(path, text).map_err(|source| ReportError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// The run's JSON.
pub fn json(stages: &[StageReport], knee_p99_ms: f64) -> String {
    let k = knee(stages, knee_p99_ms);
    let r = RunReport {
        stages,
        knee_p99_ms,
        knee_sessions: k.as_ref().map(|k| k.0),
        knee_reason: k.map(|k| k.1),
    };
    serde_json::to_string_pretty(&r).unwrap_or_default()
}

/// Under the bandwidth plot: how its bins are counted, and why a line can run past the stage.
const BANDWIDTH_NOTES: [&str; 2] = [
    "Bytes in the second the client applied them. Poses stop at the stage's duration; past the knee, sessions",
    "stay open until their last pose is answered, so the line runs on while the server's backlog drains.",
];

/// Writes `report.json`, the plots and `summary.md` into `dir`; returns the files written.
pub fn write_report(
    dir: &Path,
    stages: &[StageReport],
    knee_p99_ms: f64,
) -> Result<Vec<PathBuf>, ReportError> {
    std::fs::create_dir_all(dir).map_err(|source| ReportError::Io {
        path: dir.display().to_string(),
        source,
    })?;
    let mut files = Vec::new();
    let p = dir.join("report.json");
    write(&p, &json(stages, knee_p99_ms))?;
    files.push(p);

    let mut plots = Vec::new();
    let sessions = |n: usize| format!("{n} session{}", if n == 1 { "" } else { "s" });
    let bandwidth = Chart {
        title: "Aggregate bandwidth over time".into(),
        x_label: "seconds".into(),
        y_label: "bytes per second".into(),
        series: stages
            .iter()
            .map(|s| Series {
                label: sessions(s.sessions),
                points: s.timeline.iter().map(|t| (t.t_s, t.bytes_per_s)).collect(),
                markers: false,
            })
            .collect(),
        notes: BANDWIDTH_NOTES.map(String::from).into(),
        ..Chart::default()
    };
    plots.push(("bandwidth.png", "Bandwidth over time", bandwidth));
    let cdf = Chart {
        title: "Camera-to-delta-applied latency CDF".into(),
        x_label: "milliseconds".into(),
        y_label: "fraction of poses".into(),
        series: stages
            .iter()
            .map(|s| Series {
                label: sessions(s.sessions),
                points: s.latency_cdf.clone(),
                markers: false,
            })
            .collect(),
        log_x: true,
        y_range: Some((0.0, 1.0)),
        notes: vec![
            "One point per percentile of each stage's pose latencies, then 99.9 %, 99.99 % and the maximum."
                .into(),
        ],
        ..Chart::default()
    };
    plots.push(("latency_cdf.png", "Latency CDF", cdf));
    if stages.len() > 1 {
        let against = |title: &str, y: &str, log_y: bool, f: &dyn Fn(&StageReport) -> f64| Chart {
            title: title.into(),
            x_label: "sessions".into(),
            y_label: y.into(),
            series: vec![Series {
                label: y.into(),
                points: stages.iter().map(|s| (s.sessions as f64, f(s))).collect(),
                markers: true,
            }],
            log_x: true,
            log_y,
            ..Chart::default()
        };
        plots.push((
            "latency_vs_sessions.png",
            "p99 latency against sessions",
            against(
                "p99 latency against sessions",
                "p99 latency ms",
                true,
                &|s| s.latency_ms.p99,
            ),
        ));
        plots.push((
            "cpu_vs_sessions.png",
            "Server CPU against sessions",
            against(
                "Server CPU against sessions",
                "server cores busy",
                false,
                &|s| s.server.cpu_utilisation,
            ),
        ));
    }
    let mut embedded = Vec::new();
    for (name, caption, chart) in &plots {
        let p = dir.join(name);
        // A chart with no data (e.g. no latency samples) is skipped, not an error.
        match render_png(chart, &p, 900, 500) {
            Ok(()) => {
                files.push(p);
                embedded.push((*name, *caption));
            }
            Err(PlotError::NoData) => {}
            Err(e) => return Err(e.into()),
        }
    }
    let p = dir.join("summary.md");
    write(&p, &markdown(stages, knee_p99_ms, &embedded))?;
    files.push(p);
    Ok(files)
}

fn kib(b: f64) -> String {
    format!("{:.1}", b / 1024.0)
}

/// The Markdown summary.
pub fn markdown(stages: &[StageReport], knee_p99_ms: f64, plots: &[(&str, &str)]) -> String {
    let mut s = String::from("# Relief load test\n\n");
    if let Some(first) = stages.first().filter(|r| r.stream.starts_with("query")) {
        let _ = writeln!(
            s,
            "Back ends: {}, {} batches/s per back end (0: each as soon as the last is answered).\n",
            first.stream, first.rate_hz,
        );
    } else if let Some(first) = stages.first() {
        let _ = writeln!(
            s,
            "Stream {}, path `{}`, tau {} px, {} poses/s per session, budget {}, fans {}.\n",
            first.stream,
            first.path,
            first.tau,
            first.rate_hz,
            first
                .budget
                .map_or("none".to_string(), |b| format!("{b} B/s")),
            if first.mesh { "rebuilt" } else { "not rebuilt" },
        );
    }
    if stages.iter().any(|r| r.stream.starts_with("query")) {
        query_table(&mut s, stages);
    } else {
        stream_table(&mut s, stages);
    }
    match knee(stages, knee_p99_ms) {
        Some((n, why)) => {
            let plural = if n == 1 { "" } else { "s" };
            let _ = writeln!(s, "\n**Knee:** at {n} session{plural} ({why}).");
        }
        None => {
            let _ = writeln!(
                s,
                "\n**Knee:** not reached: every stage kept p99 latency within {knee_p99_ms} ms with no errors or desyncs."
            );
        }
    }
    for r in stages.iter().filter(|r| !r.error_samples.is_empty()) {
        let _ = writeln!(s, "\nErrors at {} sessions:", r.sessions);
        for e in &r.error_samples {
            let _ = writeln!(s, "- {e}");
        }
    }
    for (file, caption) in plots {
        let _ = writeln!(s, "\n## {caption}\n\n![{caption}]({file})");
    }
    s
}

/// The stream load test's table: one row per stage.
fn stream_table(s: &mut String, stages: &[StageReport]) {
    s.push_str("| sessions | ok | errors | desyncs | reconnects | deltas/s | changes/s | aggregate KiB/s mean / p99 | per-session KiB/s mean / p99 | latency ms p50 / p90 / p99 / max | server CPU ms/update | server cores | RSS/session KiB |\n");
    s.push_str("|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for r in stages {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {:.0} | {:.0} | {} / {} | {} / {} | {:.1} / {:.1} / {:.1} / {:.1} | {:.2} | {:.2} | {:.1} |",
            r.sessions,
            r.sessions_ok,
            r.errors,
            r.desyncs,
            r.reconnects,
            r.deltas_per_s,
            r.changes_per_s,
            kib(r.aggregate_bytes_per_s.mean),
            kib(r.aggregate_bytes_per_s.p99),
            kib(r.session_bytes_per_s.mean),
            kib(r.session_bytes_per_s.p99),
            r.latency_ms.p50,
            r.latency_ms.p90,
            r.latency_ms.p99,
            r.latency_ms.max,
            r.server.cpu_ms_per_update,
            r.server.cpu_utilisation,
            r.server.rss_per_session_bytes / 1024.0,
        );
    }
}

/// The query load test's table: one row per stage (a session is a back end, a pose a batch).
fn query_table(s: &mut String, stages: &[StageReport]) {
    s.push_str("| back ends | ok | errors | batches/s | queries/s | faults | latency ms p50 / p90 / p99 / max | server CPU us/query | server cores | KiB/s answers |\n");
    s.push_str("|---|---|---|---|---|---|---|---|---|---|\n");
    for r in stages {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.0} | {:.0} | {} | {:.2} / {:.2} / {:.2} / {:.2} | {:.3} | {:.2} | {} |",
            r.sessions,
            r.sessions_ok,
            r.errors,
            r.deltas_per_s,
            r.queries_per_s,
            r.query_faults,
            r.latency_ms.p50,
            r.latency_ms.p90,
            r.latency_ms.p99,
            r.latency_ms.max,
            r.server.cpu_us_per_query,
            r.server.cpu_utilisation,
            kib(r.aggregate_bytes_per_s.mean),
        );
    }
}
