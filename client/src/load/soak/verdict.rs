//! The soak's figures and verdict, from its samples and counts (pure; no I/O).
//!
//! After the warm-up, the server's RSS samples must stay within the tolerance: (max - min) / min
//! at most `--rss-tolerance`. A least-squares line through the same samples gives the trend in
//! MiB per hour; a fitted rise over the window of more than half the tolerance is reported as a
//! steady upward trend (a warning: a slow leak that has not yet left the band). The run also
//! fails on any desync, any client error, any dropped connection that came back without the
//! server's `resumed`, and when no cycle or no resume happened at all.

use serde::Serialize;

/// One scrape of the server during a soak, with the clients' running counts at that moment.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct SoakSample {
    /// Seconds since the soak began.
    pub t_s: f64,
    /// The server's resident memory (`process_resident_memory_bytes`), bytes.
    pub rss_bytes: f64,
    /// Sessions open on the server (`relief_sessions_active`).
    pub sessions: f64,
    /// The server process's CPU seconds so far (`process_cpu_seconds_total`).
    pub cpu_s: f64,
    /// Cycles the virtual clients completed so far.
    pub cycles: u64,
    /// Dropped connections resumed so far (the server said `resumed`).
    pub resumes: u64,
    /// Digest mismatches so far.
    pub desyncs: u64,
    /// Client errors so far.
    pub errors: u64,
}

/// What the virtual clients did over the whole soak.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Totals {
    /// Cycles completed: connect, fly, drop and resume (once or more), fly, close.
    pub cycles: u64,
    /// Connections dropped on purpose (the socket closed without a close handshake).
    pub drops: u64,
    /// Drops after which the reconnect was resumed from the snapshot (the server said
    /// `resumed` and the digests agreed).
    pub resumes: u64,
    /// Drops after which the session had to start again from scratch instead.
    pub resumes_missed: u64,
    /// Reconnections of any kind (drops, and any the server caused).
    pub reconnects: u64,
    /// Digest mismatches.
    pub desyncs: u64,
    /// Cycles that ended with an error (the client then starts a new one).
    pub errors: u64,
    /// Up to five distinct error messages.
    pub error_samples: Vec<String>,
    /// Poses sent.
    pub poses: u64,
    /// Deltas applied.
    pub deltas: u64,
    /// Payload bytes received.
    pub bytes_in: u64,
}

/// The server's RSS over the samples after the warm-up.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct RssFigures {
    /// Samples after the warm-up.
    pub samples: usize,
    /// Their smallest RSS, bytes.
    pub min_bytes: f64,
    /// Their largest RSS, bytes.
    pub max_bytes: f64,
    /// Their mean RSS, bytes.
    pub mean_bytes: f64,
    /// (max - min) / min.
    pub spread: f64,
    /// The least-squares slope of RSS over time, bytes per hour.
    pub slope_bytes_per_h: f64,
    /// The fitted line's rise from the first to the last sample, as a fraction of the mean.
    pub fitted_rise: f64,
    /// Whether the fitted rise exceeds half the tolerance: a steady upward trend.
    pub rising: bool,
}

/// Pass or fail, with the reasons.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Verdict {
    /// Whether every check held.
    pub pass: bool,
    /// The checks that failed, in words.
    pub failures: Vec<String>,
    /// What the reader should know although the run passed (e.g. an upward trend).
    pub warnings: Vec<String>,
}

/// Bytes as MiB.
pub fn mib(bytes: f64) -> f64 {
    bytes / (1024.0 * 1024.0)
}

/// The RSS figures of the samples taken at or after `warmup_s` (`None` with fewer than two).
pub fn rss_figures(samples: &[SoakSample], warmup_s: f64, tolerance: f64) -> Option<RssFigures> {
    let post: Vec<(f64, f64)> = samples
        .iter()
        .filter(|s| s.t_s >= warmup_s)
        .map(|s| (s.t_s, s.rss_bytes))
        .collect();
    if post.len() < 2 {
        return None;
    }
    let n = post.len() as f64;
    let min = post.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
    let max = post.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
    let mean = post.iter().map(|p| p.1).sum::<f64>() / n;
    let slope = slope(&post);
    let window = post[post.len() - 1].0 - post[0].0;
    let fitted_rise = if mean > 0.0 {
        slope * window / mean
    } else {
        0.0
    };
    Some(RssFigures {
        samples: post.len(),
        min_bytes: min,
        max_bytes: max,
        mean_bytes: mean,
        spread: if min > 0.0 {
            (max - min) / min
        } else {
            f64::INFINITY
        },
        slope_bytes_per_h: slope * 3600.0,
        fitted_rise,
        rising: fitted_rise > tolerance / 2.0,
    })
}

/// The least-squares slope of y over x (0 when x does not vary).
pub fn slope(points: &[(f64, f64)]) -> f64 {
    let n = points.len() as f64;
    if points.len() < 2 {
        return 0.0;
    }
    let mx = points.iter().map(|p| p.0).sum::<f64>() / n;
    let my = points.iter().map(|p| p.1).sum::<f64>() / n;
    let sxy: f64 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let sxx: f64 = points.iter().map(|p| (p.0 - mx).powi(2)).sum();
    if sxx > 0.0 { sxy / sxx } else { 0.0 }
}

/// The verdict on the RSS figures (`None`: too few samples after the warm-up) and the counts.
pub fn verdict(rss: Option<&RssFigures>, tolerance: f64, totals: &Totals) -> Verdict {
    let mut failures = Vec::new();
    let mut warnings = Vec::new();
    match rss {
        None => failures.push(
            "fewer than two RSS samples after the warm-up: nothing to judge (was the server reachable?)"
                .to_string(),
        ),
        Some(r) => {
            if r.spread > tolerance {
                failures.push(format!(
                    "RSS spread {:.2} % after the warm-up ({:.1} to {:.1} MiB) exceeds {:.2} %",
                    r.spread * 100.0,
                    mib(r.min_bytes),
                    mib(r.max_bytes),
                    tolerance * 100.0
                ));
            }
            if r.rising {
                warnings.push(format!(
                    "RSS trends upward: {:+.2} MiB/h, a fitted rise of {:.2} % over the window (more than half the tolerance)",
                    mib(r.slope_bytes_per_h),
                    r.fitted_rise * 100.0
                ));
            }
        }
    }
    if totals.desyncs > 0 {
        failures.push(format!("{} desyncs", totals.desyncs));
    }
    if totals.errors > 0 {
        failures.push(format!("{} client errors", totals.errors));
    }
    if totals.resumes_missed > 0 {
        failures.push(format!(
            "{} of {} drops were not resumed (the session started again from scratch)",
            totals.resumes_missed, totals.drops
        ));
    }
    if totals.cycles == 0 {
        failures.push("no cycle completed".into());
    }
    if totals.resumes == 0 {
        failures.push("no connection was resumed".into());
    }
    Verdict {
        pass: failures.is_empty(),
        failures,
        warnings,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn samples(rss: &[f64]) -> Vec<SoakSample> {
        rss.iter()
            .enumerate()
            .map(|(i, &r)| SoakSample {
                t_s: i as f64 * 60.0,
                rss_bytes: r,
                ..SoakSample::default()
            })
            .collect()
    }

    fn healthy() -> Totals {
        Totals {
            cycles: 10,
            drops: 20,
            resumes: 20,
            ..Totals::default()
        }
    }

    #[test]
    fn the_warm_up_is_left_out_and_the_spread_is_max_over_min() {
        // Warm-up samples at 0 and 60 s climb; after them 100..=104 MB.
        let s = samples(&[10e6, 50e6, 100e6, 104e6, 102e6, 101e6]);
        let r = rss_figures(&s, 120.0, 0.05).unwrap();
        assert_eq!(r.samples, 4);
        assert_eq!((r.min_bytes, r.max_bytes), (100e6, 104e6));
        assert!((r.spread - 0.04).abs() < 1e-12);
        let v = verdict(Some(&r), 0.05, &healthy());
        assert!(v.pass, "{v:?}");
        let v = verdict(Some(&r), 0.03, &healthy());
        assert!(!v.pass && v.failures[0].contains("4.00 %"), "{v:?}");
    }

    #[test]
    fn a_steady_climb_is_a_trend_even_within_the_band() {
        // 1 MB a minute on 100 MB: the slope is 60 MB/h, 4 % over the window.
        let s = samples(&[100e6, 101e6, 102e6, 103e6, 104e6]);
        let r = rss_figures(&s, 0.0, 0.05).unwrap();
        assert!((r.slope_bytes_per_h - 60e6).abs() < 1.0, "{r:?}");
        assert!(r.rising);
        let v = verdict(Some(&r), 0.05, &healthy());
        assert!(v.pass && v.warnings.len() == 1, "{v:?}");
        // Noise around a flat line is no trend.
        let s = samples(&[100e6, 102e6, 100e6, 102e6, 100e6]);
        assert!(!rss_figures(&s, 0.0, 0.05).unwrap().rising);
    }

    #[test]
    fn counts_and_missing_samples_fail_the_run() {
        assert!(rss_figures(&samples(&[1e6, 1e6]), 100.0, 0.05).is_none());
        let v = verdict(None, 0.05, &healthy());
        assert!(!v.pass && v.failures[0].contains("fewer than two"));
        let r = rss_figures(&samples(&[1e6, 1e6]), 0.0, 0.05).unwrap();
        let bad = Totals {
            desyncs: 1,
            errors: 2,
            resumes_missed: 3,
            ..healthy()
        };
        let v = verdict(Some(&r), 0.05, &bad);
        assert_eq!(v.failures.len(), 3, "{v:?}");
        let v = verdict(Some(&r), 0.05, &Totals::default());
        assert_eq!(
            v.failures,
            vec!["no cycle completed", "no connection was resumed"]
        );
    }

    #[test]
    fn slope_is_least_squares() {
        assert_eq!(slope(&[(0.0, 1.0), (1.0, 3.0), (2.0, 5.0)]), 2.0);
        assert_eq!(slope(&[(1.0, 1.0), (1.0, 3.0)]), 0.0);
        assert_eq!(slope(&[]), 0.0);
    }
}
