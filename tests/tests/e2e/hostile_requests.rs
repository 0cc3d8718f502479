//! Hostile requests from the second round of probes, each answered at once, in the documented
//! `{"error": ...}` form, and no larger than it need be:
//! - a body declared larger than the endpoint takes (by `Content-Length`, or behind `Expect:
//!   100-continue`) got a 408 after 10 s, or a `100 Continue`;
//! - bad query strings got axum's plain text, and a long target an empty 414;
//! - `/v1/sessions` showed every client's address to anyone;
//! - the `Host` header went unchecked into TileJSON tile URLs, cacheable by anyone;
//! - an error answer wrote out `f64`s in full, 26 times the size of its query;
//! - a ray from far away answered a point off the surface.

use relief_proto::codec;
use relief_proto::query::{Answer, AnswerBatch, Fault, Query, QueryBatch};
use relief_server::serve::config::{Limits, Secret};
use relief_tests::TestServer;
use std::net::SocketAddr;
use std::time::{Duration, Instant};
use tokio::io::{AsyncReadExt, AsyncWriteExt};

/// Writes `req` on a fresh connection and reads until the server closes it or 5 s pass:
/// status, head and body.
async fn raw(addr: SocketAddr, req: &[u8]) -> (u16, String, Vec<u8>) {
    let mut s = tokio::net::TcpStream::connect(addr).await.unwrap();
    s.write_all(req).await.unwrap();
    let mut got = Vec::new();
    let _ = tokio::time::timeout(Duration::from_secs(5), s.read_to_end(&mut got)).await;
    let split = got
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .unwrap_or(got.len());
    let head = String::from_utf8_lossy(&got[..split]).into_owned();
    let status = head.get(9..12).and_then(|s| s.parse().ok()).unwrap_or(0);
    let body = got.get(split + 4..).unwrap_or_default().to_vec();
    (status, head, body)
}

/// The `error` string of a JSON error body.
fn error_of(body: &[u8]) -> String {
    let v: serde_json::Value = serde_json::from_slice(body)
        .unwrap_or_else(|e| panic!("not JSON ({e}): {}", String::from_utf8_lossy(body)));
    v["error"].as_str().expect("an error field").to_string()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bodies_declared_too_large_are_refused_at_once() {
    let server = TestServer::start(Limits::default()).await;
    let a = server.addr;
    for (what, req) in [
        (
            "content-length",
            "POST /v1/lod HTTP/1.1\r\nHost: x\r\nContent-Length: 99999999999\r\n\r\n",
        ),
        (
            "expect 100-continue",
            "POST /v1/heights HTTP/1.1\r\nHost: x\r\nContent-Length: 99999999\r\nExpect: 100-continue\r\n\r\n",
        ),
    ] {
        let t = Instant::now();
        let (status, head, body) = raw(a, req.as_bytes()).await;
        eprintln!("{what}: {status} in {:?}", t.elapsed());
        assert!(
            !head.contains("100 Continue"),
            "{what}: told to send: {head}"
        );
        assert_eq!(status, 413, "{what}: {head}");
        assert!(
            t.elapsed() < Duration::from_secs(2),
            "{what}: took {:?}",
            t.elapsed()
        );
        assert!(error_of(&body).contains("larger than"), "{what}");
    }
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_query_strings_and_long_targets_get_json_errors() {
    let server = TestServer::start(Limits::default()).await;
    let a = server.addr;
    for target in [
        "/tiles/terrain-rgb.json?tile_size=abc",
        "/tiles/terrain-rgb.json?tile_size=-1",
        "/tiles/terrain-rgb.json?tile_size=99999999999",
        "/v1/tiles/0/0/0?crack=none&crack=patches",
        "/v1/raycast.png?camera=1,2,3,4,5&camera=1,2,3,4,5",
    ] {
        let req = format!("GET {target} HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n");
        let (status, head, body) = raw(a, req.as_bytes()).await;
        assert_eq!(status, 400, "{target}: {head}");
        assert!(head.contains("application/json"), "{target}: {head}");
        let e = error_of(&body);
        assert!(e.starts_with("bad query string: "), "{target}: {e}");
    }
    let long = format!("/v1/terrain?pad={}", "a".repeat(20_000));
    let req = format!("GET {long} HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n");
    let (status, _, body) = raw(a, req.as_bytes()).await;
    assert_eq!(status, 414);
    assert!(error_of(&body).contains("at most 8192"));
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn session_addresses_are_shown_only_with_the_operator_token() {
    let limits = Limits {
        operator_token: Some(Secret("s3cret".into())),
        ..Limits::default()
    };
    let server = TestServer::start(limits).await;
    let a = server.addr;
    let s = relief_client::session::Session::connect(relief_client::session::SessionConfig::new(
        &server.url(),
    ))
    .await
    .unwrap();
    let get = |auth: &str| {
        format!("GET /v1/sessions HTTP/1.1\r\nHost: x\r\nConnection: close\r\n{auth}\r\n")
    };
    let (status, _, body) = raw(a, get("").as_bytes()).await;
    assert_eq!(status, 200);
    let list: serde_json::Value = serde_json::from_slice(&body).unwrap();
    assert_eq!(list.as_array().unwrap().len(), 1);
    assert!(
        list[0].get("peer").is_none(),
        "an address without the token: {list}"
    );
    let (status, _, body) = raw(a, get("Authorization: Bearer wrong\r\n").as_bytes()).await;
    assert_eq!(status, 401);
    assert!(error_of(&body).contains("operator token"));
    let (status, _, body) = raw(a, get("Authorization: Bearer s3cret\r\n").as_bytes()).await;
    assert_eq!(status, 200);
    let list: serde_json::Value = serde_json::from_slice(&body).unwrap();
    assert!(list[0]["peer"].as_str().unwrap().starts_with("127.0.0.1:"));
    s.close().await;
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn tilejson_urls_never_carry_a_forged_host() {
    let server = TestServer::start(Limits::default()).await;
    let a = server.addr;
    let tilejson = |host: &str| {
        format!("GET /tiles/terrain-rgb.json HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n")
    };
    // A host that is no host name is refused.
    let (status, _, body) = raw(a, tilejson("evil.example\"/><script>").as_bytes()).await;
    assert_eq!(status, 400, "{}", String::from_utf8_lossy(&body));
    // A well-formed one is used, and caches are told the answer depends on it.
    let (status, head, body) = raw(a, tilejson("evil.example:666").as_bytes()).await;
    assert_eq!(status, 200);
    assert!(head.to_lowercase().contains("vary: host"), "{head}");
    let v: serde_json::Value = serde_json::from_slice(&body).unwrap();
    assert!(
        v["tiles"][0]
            .as_str()
            .unwrap()
            .starts_with("http://evil.example:666/")
    );
    server.stop().await;
    // With a public URL configured, the Host header is not used at all.
    let mut config = relief_tests::config(Limits::default());
    config.public_url = Some("https://terrain.example.com/".into());
    let server = TestServer::start_with(config).await;
    let (status, head, body) = raw(server.addr, tilejson("evil.example:666").as_bytes()).await;
    assert_eq!(status, 200);
    assert!(!head.to_lowercase().contains("vary: host"), "{head}");
    let v: serde_json::Value = serde_json::from_slice(&body).unwrap();
    let url = v["tiles"][0].as_str().unwrap();
    assert!(
        url.starts_with("https://terrain.example.com/tiles/"),
        "{url}"
    );
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn error_answers_stay_short_and_far_rays_are_refused() {
    let server = TestServer::start(Limits::default()).await;
    let far = -1.797e308;
    let batch = QueryBatch {
        id: 1,
        queries: (0..10_000)
            .map(|_| Query::Hat {
                at: [far, far, 0.0],
            })
            .chain([1e16, 1e20, 1e100].map(|o| Query::Ray {
                origin: [o, o, o],
                dir: [-1.0, -1.0, -1.0],
                max_dist: None,
            }))
            .collect(),
    };
    let body = codec::encode(&batch);
    let answer = relief_client::http::request(
        "POST",
        &format!("{}/v1/query", server.http()),
        "application/octet-stream",
        body.clone(),
    )
    .await
    .unwrap();
    let ratio = answer.len() as f64 / body.len() as f64;
    eprintln!(
        "{} bytes of queries, {} bytes of answers: {ratio:.2}x",
        body.len(),
        answer.len()
    );
    assert!(ratio < 3.0, "answers are {ratio:.1} times their queries");
    let a: AnswerBatch = codec::decode(&answer, 64 << 20).unwrap();
    let Answer::Error { fault, message } = &a.answers[0] else {
        panic!("{:?}", a.answers[0]);
    };
    assert_eq!(*fault, Fault::Outside);
    assert!(message.len() <= 96, "{message}");
    for r in &a.answers[10_000..] {
        let Answer::Error { fault, message } = r else {
            panic!("a ray from far away answered {r:?}");
        };
        assert_eq!(*fault, Fault::Outside);
        assert!(message.contains("more than 1e6 m"), "{message}");
    }
    server.stop().await;
}
