//! The load generator against the real server on 127.0.0.1: a short run of 50
//! sessions for 10 s, its report files, and byte counts that agree between client and server.

use relief_client::load::{self, LoadOptions, LoadPath};
use relief_server::serve::config::Limits;
use relief_tests::TestServer;
use std::time::Duration;

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn fifty_sessions_for_ten_seconds_report_consistent_figures() {
    let server = TestServer::start(Limits::default()).await;
    let opts = LoadOptions {
        url: server.url(),
        sessions: 50,
        duration: Duration::from_secs(10),
        ramp: Duration::from_secs(1),
        path: LoadPath::Random,
        seed: 7,
        tau: 1.0,
        budget: None,
        stream: relief_proto::msg::StreamKind::Vertex,
        rate_hz: 10.0,
        mesh: true,
        progress: false,
        queries: None,
    };
    let stages = load::run_sweep(&opts, &[50]).await.unwrap();
    let r = &stages[0];
    assert_eq!(
        (r.sessions_ok, r.errors, r.desyncs),
        (50, 0, 0),
        "{:?}",
        r.error_samples
    );
    // About 10 poses a second per session over ~11 s.
    assert!((4_000..=6_000).contains(&r.poses), "{} poses", r.poses);
    assert!(r.latency_ms.samples > 3_000, "{:?}", r.latency_ms);
    assert!(r.latency_ms.p50 <= r.latency_ms.p99 && r.latency_ms.p99 <= r.latency_ms.max);
    assert!(r.aggregate_bytes_per_s.mean > 0.0 && r.changes_per_s > 0.0);
    // Every byte the server sent was received: payload counts agree exactly (framing is
    // counted by neither side).
    assert_eq!(r.bytes_client as f64, r.server.bytes_out, "{r:?}");
    assert!(r.server.updates >= r.deltas as f64);

    let dir = tempfile::tempdir().unwrap();
    let files = load::report::write_report(dir.path(), &stages, 50.0).unwrap();
    for name in [
        "report.json",
        "summary.md",
        "bandwidth.png",
        "latency_cdf.png",
    ] {
        let p = dir.path().join(name);
        assert!(files.contains(&p), "{name} not written");
        assert!(
            std::fs::metadata(&p).unwrap().len() > 100,
            "{name} is empty"
        );
    }
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("report.json")).unwrap()).unwrap();
    let stage = &json["stages"][0];
    for field in [
        "sessions",
        "sessions_ok",
        "errors",
        "desyncs",
        "reconnects",
        "deltas_per_s",
        "changes_per_s",
        "bytes_client",
        "aggregate_bytes_per_s",
        "session_bytes_per_s",
        "latency_ms",
        "first_latency_ms",
        "server",
        "timeline",
        "latency_cdf",
    ] {
        assert!(!stage[field].is_null(), "report.json lacks {field}");
    }
    for field in ["p50", "p90", "p99", "max", "samples"] {
        assert!(
            stage["latency_ms"][field].is_number(),
            "latency_ms lacks {field}"
        );
    }
    for field in [
        "cpu_ms_per_update",
        "rss_per_session_bytes",
        "cpu_utilisation",
    ] {
        assert!(stage["server"][field].is_number(), "server lacks {field}");
    }
    assert!(json["knee_p99_ms"].is_number());
    let md = std::fs::read_to_string(dir.path().join("summary.md")).unwrap();
    assert!(md.contains("![Latency CDF](latency_cdf.png)"), "{md}");
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn query_back_ends_report_queries_latency_and_server_cpu() {
    let server = TestServer::start(Limits::default()).await;
    let load = load::query::QueryLoad {
        mix: "hat,ray=5,sight=5".parse().unwrap(),
        entities: 200,
    };
    let opts = LoadOptions {
        url: server.url(),
        sessions: 4,
        duration: Duration::from_secs(3),
        ramp: Duration::from_millis(500),
        path: LoadPath::Standard,
        seed: 3,
        tau: 1.0,
        budget: None,
        stream: relief_proto::msg::StreamKind::Query,
        rate_hz: 20.0,
        mesh: false,
        progress: false,
        queries: Some(load),
    };
    let stages = load::run_sweep(&opts, &[4]).await.unwrap();
    let r = &stages[0];
    assert_eq!((r.sessions_ok, r.errors), (4, 0), "{:?}", r.error_samples);
    // 20 batches a second per back end for about 3.5 s, each answered.
    assert!((200..=320).contains(&r.poses), "{} batches", r.poses);
    assert_eq!(r.deltas, r.poses);
    assert_eq!(r.queries, r.poses * load.batch_len() as u64);
    // Entities over the terrain ask nothing that fails.
    assert_eq!(r.query_faults, 0);
    // What the back ends counted is what the server counted.
    assert_eq!(r.queries as f64, r.server.queries, "{:?}", r.server);
    assert!(r.server.cpu_us_per_query > 0.0 && r.queries_per_s > 0.0);
    assert!(
        r.latency_ms.samples > 150 && r.latency_ms.p99 < 1000.0,
        "{:?}",
        r.latency_ms
    );
    assert!(
        r.stream
            .starts_with("query (hat,ray=5,sight=5; 200 entities"),
        "{}",
        r.stream
    );
    let md = load::report::markdown(&stages, 50.0, &[]);
    assert!(
        md.contains("queries/s") && md.contains("server CPU us/query"),
        "{md}"
    );
    let dir = tempfile::tempdir().unwrap();
    let files = load::report::write_report(dir.path(), &stages, 50.0).unwrap();
    for name in ["report.json", "summary.md", "latency_cdf.png"] {
        assert!(files.contains(&dir.path().join(name)), "{name} not written");
    }
    server.stop().await;
}
