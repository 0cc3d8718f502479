//! Server counters and their Prometheus text exposition (`GET /metrics`).
//!
//! Plain atomics, no registry: a handful of series, updated on the hot path without locks.

use relief_proto::close::CloseReason;
use std::fmt::Write;
use std::sync::atomic::{AtomicI64, AtomicU64, Ordering::Relaxed};

/// Upper bounds of the update-latency histogram, seconds.
pub const LATENCY_BUCKETS: [f64; 14] = [
    0.0001, 0.00025, 0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5,
];

/// Error kinds outside session closes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ErrorKind {
    /// An HTTP request was refused as bad input.
    BadRequest,
    /// A connection was refused for exceeding the per-IP connection rate.
    RateLimited,
    /// A connection was dropped for sending its headers too slowly, or a connection error.
    Connection,
    /// A connection was refused: the server's or its address's connection limit was reached.
    ConnectionLimit,
    /// A request body did not arrive within the body timeout.
    BodyTimeout,
    /// A query batch was refused because its answer would pass the memory budget (sessions
    /// closed for it count as `server_full` closes).
    MemoryBudget,
}

impl ErrorKind {
    const ALL: [ErrorKind; 6] = [
        ErrorKind::BadRequest,
        ErrorKind::RateLimited,
        ErrorKind::Connection,
        ErrorKind::ConnectionLimit,
        ErrorKind::BodyTimeout,
        ErrorKind::MemoryBudget,
    ];

    fn name(self) -> &'static str {
        match self {
            ErrorKind::BadRequest => "bad_request",
            ErrorKind::RateLimited => "rate_limited",
            ErrorKind::Connection => "connection",
            ErrorKind::ConnectionLimit => "connection_limit",
            ErrorKind::BodyTimeout => "body_timeout",
            ErrorKind::MemoryBudget => "memory_budget",
        }
    }
}

/// The server's counters.
#[derive(Debug, Default)]
pub struct Metrics {
    /// Sessions open now.
    pub sessions_active: AtomicI64,
    /// Sessions ever welcomed.
    pub sessions_total: AtomicU64,
    /// Sessions that resumed from a snapshot.
    pub resumes_total: AtomicU64,
    /// LOD updates computed (session deltas and one-shots).
    pub updates_total: AtomicU64,
    /// Deltas sent on sessions.
    pub deltas_total: AtomicU64,
    /// Bytes of messages sent on sessions and one-shot responses.
    pub bytes_out_total: AtomicU64,
    /// Bytes of messages received on sessions.
    pub bytes_in_total: AtomicU64,
    /// Query batches answered (`POST /v1/query` and query sessions).
    pub query_batches_total: AtomicU64,
    /// Queries answered, items of those batches.
    pub queries_total: AtomicU64,
    /// Update computation time histogram: counts per bucket of [`LATENCY_BUCKETS`], then +Inf.
    update_buckets: [AtomicU64; LATENCY_BUCKETS.len() + 1],
    /// Sum of update computation times, microseconds.
    update_us_sum: AtomicU64,
    /// Sessions closed, per [`CloseReason`] (in [`CloseReason::ALL`] order).
    closes: [AtomicU64; CloseReason::ALL.len()],
    /// Other errors per [`ErrorKind`].
    errors: [AtomicU64; ErrorKind::ALL.len()],
}

impl Metrics {
    /// Records one update's computation time.
    pub fn observe_update(&self, seconds: f64) {
        self.updates_total.fetch_add(1, Relaxed);
        let i = LATENCY_BUCKETS.partition_point(|&b| b < seconds);
        self.update_buckets[i].fetch_add(1, Relaxed);
        self.update_us_sum
            .fetch_add((seconds * 1e6).round() as u64, Relaxed);
    }

    /// Counts a session close.
    pub fn close(&self, reason: CloseReason) {
        if let Some(i) = CloseReason::ALL.iter().position(|&r| r == reason) {
            self.closes[i].fetch_add(1, Relaxed);
        }
    }

    /// Counts an error outside sessions.
    pub fn error(&self, kind: ErrorKind) {
        if let Some(i) = ErrorKind::ALL.iter().position(|&k| k == kind) {
            self.errors[i].fetch_add(1, Relaxed);
        }
    }

    /// The Prometheus text exposition (format 0.0.4).
    pub fn render(&self) -> String {
        let mut s = String::with_capacity(4096);
        let mut counter = |name: &str, help: &str, v: u64| {
            let _ = writeln!(s, "# HELP {name} {help}\n# TYPE {name} counter\n{name} {v}");
        };
        counter(
            "relief_sessions_total",
            "Sessions welcomed since start.",
            self.sessions_total.load(Relaxed),
        );
        counter(
            "relief_resumes_total",
            "Sessions resumed from a snapshot.",
            self.resumes_total.load(Relaxed),
        );
        counter(
            "relief_updates_total",
            "LOD updates computed.",
            self.updates_total.load(Relaxed),
        );
        counter(
            "relief_deltas_total",
            "Deltas sent on sessions.",
            self.deltas_total.load(Relaxed),
        );
        counter(
            "relief_bytes_out_total",
            "Bytes of messages sent.",
            self.bytes_out_total.load(Relaxed),
        );
        counter(
            "relief_bytes_in_total",
            "Bytes of session messages received.",
            self.bytes_in_total.load(Relaxed),
        );
        counter(
            "relief_query_batches_total",
            "Query batches answered.",
            self.query_batches_total.load(Relaxed),
        );
        counter(
            "relief_queries_total",
            "Queries answered (items of the batches, errors included).",
            self.queries_total.load(Relaxed),
        );
        let _ = writeln!(
            s,
            "# HELP relief_sessions_active Sessions open now.\n# TYPE relief_sessions_active gauge\nrelief_sessions_active {}",
            self.sessions_active.load(Relaxed)
        );
        let _ = writeln!(
            s,
            "# HELP relief_update_seconds Time to compute one LOD update.\n# TYPE relief_update_seconds histogram"
        );
        let mut cumulative = 0u64;
        for (i, b) in LATENCY_BUCKETS.iter().enumerate() {
            cumulative += self.update_buckets[i].load(Relaxed);
            let _ = writeln!(s, "relief_update_seconds_bucket{{le=\"{b}\"}} {cumulative}");
        }
        cumulative += self.update_buckets[LATENCY_BUCKETS.len()].load(Relaxed);
        let _ = writeln!(
            s,
            "relief_update_seconds_bucket{{le=\"+Inf\"}} {cumulative}"
        );
        let _ = writeln!(
            s,
            "relief_update_seconds_sum {}\nrelief_update_seconds_count {cumulative}",
            self.update_us_sum.load(Relaxed) as f64 / 1e6
        );
        let _ = writeln!(
            s,
            "# HELP relief_session_closes_total Sessions closed, by reason.\n# TYPE relief_session_closes_total counter"
        );
        for (i, r) in CloseReason::ALL.iter().enumerate() {
            let _ = writeln!(
                s,
                "relief_session_closes_total{{reason=\"{}\"}} {}",
                r.name(),
                self.closes[i].load(Relaxed)
            );
        }
        let _ = writeln!(
            s,
            "# HELP relief_errors_total Errors by kind: session closes for bad input or faults, refused requests and connections.\n# TYPE relief_errors_total counter"
        );
        for (i, r) in CloseReason::ALL.iter().enumerate() {
            if !matches!(r, CloseReason::Draining) {
                let _ = writeln!(
                    s,
                    "relief_errors_total{{kind=\"{}\"}} {}",
                    r.name(),
                    self.closes[i].load(Relaxed)
                );
            }
        }
        for (i, k) in ErrorKind::ALL.iter().enumerate() {
            let _ = writeln!(
                s,
                "relief_errors_total{{kind=\"{}\"}} {}",
                k.name(),
                self.errors[i].load(Relaxed)
            );
        }
        if let Some((cpu, rss)) = process_usage() {
            let _ = writeln!(
                s,
                "# HELP process_cpu_seconds_total User and system CPU time of the server process.\n# TYPE process_cpu_seconds_total counter\nprocess_cpu_seconds_total {cpu}"
            );
            let _ = writeln!(
                s,
                "# HELP process_resident_memory_bytes Resident memory of the server process (the mapped store included).\n# TYPE process_resident_memory_bytes gauge\nprocess_resident_memory_bytes {rss}"
            );
        }
        s
    }
}

/// CPU seconds and resident bytes of this process, from `/proc` (Linux; `None` elsewhere).
fn process_usage() -> Option<(f64, u64)> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the parenthesised command name; utime and stime are the 12th and 13th.
    let rest = &stat[stat.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    // Clock ticks are USER_HZ, 100 on every Linux ABI.
    let ticks = f.get(11)?.parse::<u64>().ok()? + f.get(12)?.parse::<u64>().ok()?;
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let kb = status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))?
        .trim()
        .trim_end_matches("kB")
        .trim()
        .parse::<u64>()
        .ok()?;
    Some((ticks as f64 / 100.0, kb * 1024))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn histogram_is_cumulative_and_counts_match() {
        let m = Metrics::default();
        m.observe_update(0.0002);
        m.observe_update(0.003);
        m.observe_update(10.0);
        m.close(CloseReason::BadCamera);
        m.error(ErrorKind::RateLimited);
        let text = m.render();
        assert!(text.contains("relief_update_seconds_bucket{le=\"0.00025\"} 1"));
        assert!(text.contains("relief_update_seconds_bucket{le=\"0.005\"} 2"));
        assert!(text.contains("relief_update_seconds_bucket{le=\"+Inf\"} 3"));
        assert!(text.contains("relief_update_seconds_count 3"));
        assert!(text.contains("relief_updates_total 3"));
        assert!(text.contains("relief_errors_total{kind=\"bad_camera\"} 1"));
        assert!(text.contains("relief_errors_total{kind=\"rate_limited\"} 1"));
    }
}
