//! Hostile input: request bodies that never finish, and connection floods.
//! Bodies are timed out (408) and hold no computation slot; connections are limited in all
//! and per address, below the open-file limit; `/healthz` answers at the limits; and a
//! bystander session keeps its latency throughout.

use relief_proto::codec;
use relief_proto::msg::{LodRequest, PROTOCOL_VERSION, WireCamera};
use relief_proto::view::Lens;
use relief_server::serve::config::Limits;
use relief_tests::bystander::{Bystander, assert_kept};
use relief_tests::raw::{get_from, lo, partial_post, read_response};
use relief_tests::{Reaped, TestServer, free_addr, path, test_store};
use std::time::{Duration, Instant};
use tokio::net::TcpStream;

fn lod_body() -> Vec<u8> {
    codec::encode(&LodRequest {
        version: PROTOCOL_VERSION,
        lens: Lens::STANDARD.into(),
        tau: 1.0,
        camera: WireCamera::from(path(0, 1)[0]),
        base: None,
    })
}

/// Holds `n` connections from `from`, each a `POST` to `path` whose body never finishes.
async fn hold(from: u8, server: std::net::SocketAddr, path: &str, n: usize) -> Vec<TcpStream> {
    let mut v = Vec::new();
    for _ in 0..n {
        v.push(
            partial_post(lo(from), server, path, 100_000, b"{\"points\":[[1,")
                .await
                .expect("connect"),
        );
    }
    v
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn slow_one_shot_bodies_hold_no_computation_slot_and_time_out() {
    let limits = Limits {
        body_timeout: Duration::from_millis(1500),
        ..Limits::default()
    };
    let server = TestServer::start(limits).await;
    let by = Bystander::start(&server.url(), 0).await;
    let calm = by.measure(Duration::from_millis(400)).await;
    let slots = 2 * std::thread::available_parallelism().map_or(2, |n| n.get());
    let ((mut held, took), attacked) = by
        .during(async {
            // More slow bodies than there are computation slots.
            let held = hold(2, server.addr, "/v1/lod", slots + 4).await;
            tokio::time::sleep(Duration::from_millis(200)).await;
            let t = Instant::now();
            let r = relief_client::http::request(
                "POST",
                &format!("{}/v1/lod", server.http()),
                "application/octet-stream",
                lod_body(),
            )
            .await;
            assert!(r.is_ok(), "{r:?}");
            (held, t.elapsed())
        })
        .await;
    eprintln!("a one-shot behind {} slow bodies took {took:?}", slots + 4);
    assert!(
        took < Duration::from_millis(1000),
        "the one-shot waited {took:?} behind slow bodies"
    );
    for tcp in &mut held {
        let (status, body) = read_response(tcp, Duration::from_secs(5))
            .await
            .expect("a response to the slow body");
        assert_eq!(status, 408, "{body}");
        assert!(body.contains("did not arrive within 2 s"), "{body}");
    }
    let m = server.state.metrics.render();
    let want = format!("relief_errors_total{{kind=\"body_timeout\"}} {}", slots + 4);
    assert!(m.contains(&want), "{want} missing:\n{m}");
    assert_kept("slow one-shot bodies", calm, attacked);
    assert_eq!(by.stop().await.desyncs, 0);
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn slow_heights_bodies_are_limited_per_address_and_health_still_answers() {
    let limits = Limits {
        body_timeout: Duration::from_secs(2),
        max_connections_per_ip: 40,
        conn_rate_per_ip: 1000.0,
        ..Limits::default()
    };
    let server = TestServer::start(limits).await;
    let by = Bystander::start(&server.url(), 2).await;
    let calm = by.measure(Duration::from_millis(400)).await;
    let (mut held, attacked) = by
        .during(async {
            let mut held = hold(2, server.addr, "/v1/heights", 50).await;
            // The ten over the address's limit are answered at once, unread.
            for tcp in &mut held[40..] {
                let (status, body) = read_response(tcp, Duration::from_secs(2))
                    .await
                    .expect("a refusal");
                assert_eq!(status, 429, "{body}");
                assert!(body.contains("maximum of connections"), "{body}");
            }
            // Health and readiness still answer the flooding address; nothing else does.
            assert_eq!(
                get_from(lo(2), server.addr, "/healthz").await.unwrap().0,
                200
            );
            assert_eq!(
                get_from(lo(2), server.addr, "/readyz").await.unwrap().0,
                200
            );
            assert_eq!(
                get_from(lo(2), server.addr, "/v1/terrain").await.unwrap().0,
                429
            );
            // Another address is served as usual.
            assert_eq!(
                get_from(lo(3), server.addr, "/v1/terrain").await.unwrap().0,
                200
            );
            held.truncate(40);
            held
        })
        .await;
    // The slow bodies are cut off by the body timeout, and the address is served again.
    for tcp in &mut held {
        let (status, _) = read_response(tcp, Duration::from_secs(5))
            .await
            .expect("408");
        assert_eq!(status, 408);
    }
    drop(held);
    tokio::time::sleep(Duration::from_millis(100)).await;
    assert_eq!(
        get_from(lo(2), server.addr, "/v1/terrain").await.unwrap().0,
        200
    );
    assert_kept("a per-address connection flood", calm, attacked);
    assert_eq!(by.stop().await.desyncs, 0);
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn at_the_total_connection_limit_health_answers_and_the_rest_is_told_to_retry() {
    let limits = Limits {
        max_connections: 30,
        body_timeout: Duration::from_secs(30),
        ..Limits::default()
    };
    let server = TestServer::start(limits).await;
    // The bystander's own connection is one of the thirty.
    let by = Bystander::start(&server.url(), 4).await;
    let calm = by.measure(Duration::from_millis(400)).await;
    let (held, attacked) = by
        .during(async {
            let mut held = Vec::new();
            for ip in 2..5 {
                held.extend(hold(ip, server.addr, "/v1/heights", 10).await);
            }
            tokio::time::sleep(Duration::from_millis(100)).await;
            assert_eq!(
                get_from(lo(9), server.addr, "/healthz").await.unwrap().0,
                200
            );
            assert_eq!(
                get_from(lo(9), server.addr, "/readyz").await.unwrap().0,
                200
            );
            let (status, body) = get_from(lo(9), server.addr, "/v1/terrain").await.unwrap();
            assert_eq!(status, 503, "{body}");
            assert!(body.contains("retry later"), "{body}");
            held
        })
        .await;
    drop(held);
    tokio::time::sleep(Duration::from_millis(100)).await;
    assert_eq!(
        get_from(lo(9), server.addr, "/v1/terrain").await.unwrap().0,
        200
    );
    let m = server.state.metrics.render();
    assert!(
        !m.contains("relief_errors_total{kind=\"connection_limit\"} 0"),
        "{m}"
    );
    assert_kept("a total connection flood", calm, attacked);
    assert_eq!(by.stop().await.desyncs, 0);
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn under_an_open_file_limit_of_300_accept_and_health_keep_working() {
    // The reproduction: `ulimit -n 300`, 300 held connections; the server used to log
    // `accept failed: Too many open files` and `/healthz` stopped answering.
    let addr = free_addr();
    let log = tempfile::NamedTempFile::new().unwrap();
    let script = format!(
        "ulimit -n 300 && exec {} serve --store {} --addr {addr} --body-timeout-s 60",
        env!("CARGO_BIN_EXE_relief-test-server"),
        test_store().display()
    );
    let child = Reaped(
        std::process::Command::new("sh")
            .args(["-c", &script])
            .env("RELIEF_LOG", "warn")
            .stderr(log.reopen().unwrap())
            .spawn()
            .expect("spawn"),
    );
    let deadline = Instant::now() + Duration::from_secs(30);
    while get_from(lo(1), addr, "/readyz").await.map(|r| r.0) != Some(200) {
        assert!(Instant::now() < deadline, "server not ready");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    // 360 slow bodies against the 204 connections that fit: the server answers those over the
    // limit and closes them, so a body written after that close fails (a broken pipe), which
    // is the server doing its job, not the test's concern.
    let mut held = Vec::new();
    for ip in 2..6 {
        for _ in 0..90 {
            let body = partial_post(lo(ip), addr, "/v1/heights", 100_000, b"{\"points\":[[1,");
            held.extend(body.await.ok());
        }
    }
    tokio::time::sleep(Duration::from_millis(300)).await;
    for _ in 0..5 {
        let r = get_from(lo(9), addr, "/healthz").await;
        assert_eq!(r.map(|r| r.0), Some(200));
    }
    drop(held);
    tokio::time::sleep(Duration::from_millis(200)).await;
    assert_eq!(
        get_from(lo(9), addr, "/v1/terrain").await.map(|r| r.0),
        Some(200)
    );
    drop(child);
    let text = std::fs::read_to_string(log.path()).unwrap();
    assert!(!text.contains("accept failed"), "{text}");
    assert!(
        text.contains("allows"),
        "the lowered limit is not logged: {text}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_idle_kept_alive_connection_is_closed_after_the_header_timeout() {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let limits = Limits {
        header_timeout: Duration::from_millis(500),
        ..Limits::default()
    };
    let server = TestServer::start(limits).await;
    let mut tcp = relief_tests::raw::connect_from(lo(2), server.addr)
        .await
        .unwrap();
    tcp.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n")
        .await
        .unwrap();
    let (status, _) = read_response(&mut tcp, Duration::from_secs(2))
        .await
        .unwrap();
    assert_eq!(status, 200);
    // Kept alive, then silent: closed once the next request's headers are overdue.
    let t = Instant::now();
    let mut buf = [0u8; 64];
    let r = tokio::time::timeout(Duration::from_secs(5), tcp.read(&mut buf)).await;
    assert!(matches!(r, Ok(Ok(0)) | Ok(Err(_))), "{r:?}");
    assert!(
        t.elapsed() >= Duration::from_millis(400),
        "{:?}",
        t.elapsed()
    );
    server.stop().await;
}
