//! A soak's files (`--report DIR`): `soak.json` (settings, counts, RSS figures, verdict and the
//! samples), `samples.csv`, `rss.png` (the server's RSS over time, the warm-up marked, the
//! tolerance band drawn) and `summary.md`; and the text printed at the end of a run.

use super::SoakReport;
use super::verdict::mib;
use crate::load::report::ReportError;
use crate::plot::{Chart, Series, render_png};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

fn write(path: &Path, text: &str) -> Result<(), ReportError> {
    std::fs::write(path, text).map_err(|source| ReportError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// The samples as CSV, one line each, with a header.
pub fn csv(r: &SoakReport) -> String {
    let mut s = String::from(
        "t_s,rss_bytes,rss_mib,sessions,server_cpu_s,cycles,resumes,desyncs,errors,warmup\n",
    );
    for x in &r.samples {
        let _ = writeln!(
            s,
            "{:.3},{:.0},{:.3},{},{:.3},{},{},{},{},{}",
            x.t_s,
            x.rss_bytes,
            mib(x.rss_bytes),
            x.sessions,
            x.cpu_s,
            x.cycles,
            x.resumes,
            x.desyncs,
            x.errors,
            u8::from(x.t_s < r.warmup_s)
        );
    }
    s
}

/// The RSS chart: minutes on x for soaks of ten minutes or more, seconds below.
pub fn rss_chart(r: &SoakReport) -> Chart {
    let (scale, unit) = if r.duration_s >= 600.0 {
        (60.0, "minutes")
    } else {
        (1.0, "seconds")
    };
    let points: Vec<(f64, f64)> = r
        .samples
        .iter()
        .map(|s| (s.t_s / scale, mib(s.rss_bytes)))
        .collect();
    let top = points.iter().map(|p| p.1).fold(0.0, f64::max);
    let x1 = r.duration_s / scale;
    let w = r.warmup_s / scale;
    let mut series = vec![Series {
        label: "server RSS".into(),
        points,
        markers: true,
    }];
    series.push(Series {
        label: "end of warm-up".into(),
        points: vec![(w, 0.0), (w, top * 1.08)],
        markers: false,
    });
    if let Some(f) = &r.rss {
        let (lo, band) = (mib(f.min_bytes), mib(f.min_bytes) * (1.0 + r.rss_tolerance));
        series.push(Series {
            label: "lowest after warm-up".into(),
            points: vec![(w, lo), (x1, lo)],
            markers: false,
        });
        series.push(Series {
            label: format!("lowest + {:.0} % (tolerance)", r.rss_tolerance * 100.0),
            points: vec![(w, band), (x1, band)],
            markers: false,
        });
    }
    let verdict = if r.verdict.pass { "pass" } else { "FAIL" };
    let spread = r.rss.as_ref().map_or("-".to_string(), |f| {
        format!(
            "{:.2} %, slope {:+.2} MiB/h",
            f.spread * 100.0,
            mib(f.slope_bytes_per_h)
        )
    });
    Chart {
        title: format!(
            "Server RSS, {} sessions cycling for {}",
            r.sessions,
            super::duration::humane(std::time::Duration::from_secs_f64(r.duration_s))
        ),
        x_label: unit.into(),
        y_label: "resident memory, MiB".into(),
        series,
        notes: vec![
            format!(
                "Sampled from /metrics every {} s; the verdict ({verdict}) reads the samples after the warm-up: spread {spread}.",
                r.sample_every_s
            ),
            format!(
                "Each client: connect, fly {}-{} poses at {} Hz, drop the socket, resume, fly ... ({}-{} drops), close, again.",
                r.segment_poses.0,
                r.segment_poses.1,
                r.rate_hz,
                r.drops_per_cycle.0,
                r.drops_per_cycle.1
            ),
        ],
        ..Chart::default()
    }
}

/// Writes `soak.json`, `samples.csv`, `rss.png` and `summary.md` into `dir`; returns the files.
pub fn write_report(dir: &Path, r: &SoakReport) -> Result<Vec<PathBuf>, ReportError> {
    std::fs::create_dir_all(dir).map_err(|source| ReportError::Io {
        path: dir.display().to_string(),
        source,
    })?;
    let mut files = Vec::new();
    let p = dir.join("soak.json");
    write(&p, &serde_json::to_string_pretty(r).unwrap_or_default())?;
    files.push(p);
    let p = dir.join("samples.csv");
    write(&p, &csv(r))?;
    files.push(p);
    let p = dir.join("rss.png");
    render_png(&rss_chart(r), &p, 900, 500)?;
    files.push(p);
    let p = dir.join("summary.md");
    write(&p, &markdown(r, Some("rss.png")))?;
    files.push(p);
    Ok(files)
}

/// The figures in Markdown (also what the command prints), with the plot if given.
pub fn markdown(r: &SoakReport, plot: Option<&str>) -> String {
    let mut s = String::from("# Relief soak\n\n");
    let t = &r.totals;
    let hum = |secs: f64| super::duration::humane(std::time::Duration::from_secs_f64(secs));
    let _ = writeln!(
        s,
        "{} sessions cycling for {} (stream {}, path `{}`, tau {} px, {} poses/s, seed {}); started over {}, RSS sampled every {}, warm-up {} left out; tolerance {:.1} %.\n",
        r.sessions,
        hum(r.duration_s),
        r.stream,
        r.path,
        r.tau,
        r.rate_hz,
        r.seed,
        hum(r.ramp_s.max(0.001)),
        hum(r.sample_every_s),
        hum(r.warmup_s),
        r.rss_tolerance * 100.0
    );
    let verdict = if r.verdict.pass {
        "**pass**"
    } else {
        "**FAIL**"
    };
    let _ = writeln!(s, "Verdict: {verdict}.");
    for f in &r.verdict.failures {
        let _ = writeln!(s, "- failed: {f}");
    }
    for w in &r.verdict.warnings {
        let _ = writeln!(s, "- warning: {w}");
    }
    s.push_str("\n| figure | value |\n|---|---|\n");
    let mut row = |k: &str, v: String| {
        let _ = writeln!(s, "| {k} | {v} |");
    };
    match &r.rss {
        Some(f) => {
            row("RSS samples after warm-up", f.samples.to_string());
            row(
                "RSS min / mean / max",
                format!(
                    "{:.1} / {:.1} / {:.1} MiB",
                    mib(f.min_bytes),
                    mib(f.mean_bytes),
                    mib(f.max_bytes)
                ),
            );
            row(
                "RSS spread (max - min) / min",
                format!("{:.2} %", f.spread * 100.0),
            );
            row(
                "RSS trend (least squares)",
                format!(
                    "{:+.2} MiB/h ({:+.2} % over the window{})",
                    mib(f.slope_bytes_per_h),
                    f.fitted_rise * 100.0,
                    if f.rising { ", rising" } else { "" }
                ),
            );
        }
        None => row("RSS samples after warm-up", "fewer than two".into()),
    }
    row(
        "RSS before the clients",
        format!("{:.1} MiB", mib(r.rss_start_bytes)),
    );
    row("cycles completed", t.cycles.to_string());
    row(
        "drops / resumed / not resumed",
        format!("{} / {} / {}", t.drops, t.resumes, t.resumes_missed),
    );
    row("desyncs", t.desyncs.to_string());
    row("client errors", t.errors.to_string());
    row("reconnects (all causes)", t.reconnects.to_string());
    row("poses / deltas", format!("{} / {}", t.poses, t.deltas));
    row(
        "latency ms p50 / p99 / max",
        format!(
            "{:.1} / {:.1} / {:.1}",
            r.latency_ms.0, r.latency_ms.1, r.latency_ms.2
        ),
    );
    row(
        "server: sessions welcomed / resumes",
        format!("{} / {}", r.server_sessions, r.server_resumes),
    );
    row("server CPU (cores busy)", format!("{:.2}", r.server_cpu));
    let errs: Vec<String> = r
        .server_errors
        .iter()
        .map(|(k, v)| format!("{v} {k}"))
        .collect();
    row(
        "server errors",
        if errs.is_empty() {
            "none".into()
        } else {
            errs.join(", ")
        },
    );
    row("failed scrapes", r.failed_scrapes.to_string());
    row("wall time", hum(r.wall_s));
    if !t.error_samples.is_empty() {
        s.push_str("\nErrors:\n");
        for e in &t.error_samples {
            let _ = writeln!(s, "- {e}");
        }
    }
    if let Some(p) = plot {
        let _ = writeln!(s, "\n![Server RSS over time]({p})");
    }
    s
}
