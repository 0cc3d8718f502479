//! End to end over 127.0.0.1: the HTTP API: the stateless one-shot round trip,
//! Prometheus text, terrain metadata, heights, health and readiness, errors as JSON.

use relief_client::http::{HttpError, get_json, post_json, request};
use relief_proto::codec;
use relief_proto::delta::Known;
use relief_proto::mirror::Mirror;
use relief_proto::msg::{LodRequest, LodResponse, PROTOCOL_VERSION, Resume, WireCamera};
use relief_proto::view::Lens;
use relief_server::serve::config::Limits;
use relief_tests::{TestServer, path};

async fn one_shot(base: &str, req: &LodRequest) -> Result<LodResponse, HttpError> {
    let body = request(
        "POST",
        &format!("{base}/v1/lod"),
        "application/octet-stream",
        codec::encode(req),
    )
    .await?;
    Ok(codec::decode(&body, codec::HARD_LIMIT).expect("a response that decodes"))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn one_shot_round_trips_from_the_root_and_from_a_base_cut() {
    let server = TestServer::start(Limits::default()).await;
    let base = server.http();
    let info = server.state.terrain().unwrap().info.clone();
    let geom = info.geometry().unwrap();
    let mut mirror = Mirror::new(&geom, info.root_z);
    let cams = path(0, 120);
    let mut snapshot = None;
    let mut merges = 0;
    for cam in cams.iter().step_by(20) {
        let req = LodRequest {
            version: PROTOCOL_VERSION,
            lens: Lens::STANDARD.into(),
            tau: 1.0,
            camera: WireCamera::from(*cam),
            base: snapshot.take().map(|s| Resume {
                terrain_id: info.id,
                snapshot: s,
            }),
        };
        let resp = one_shot(&base, &req).await.unwrap();
        let delta = resp
            .delta
            .unpack(&geom.shape, geom.z_quantum, Known::mirror(&mirror))
            .unwrap();
        merges += delta.merges.len();
        // The mirror applies the delta and lands on the server's cut: digests checked inside.
        mirror.apply(&geom, &delta, |_, _| {}).unwrap();
        assert_eq!(mirror.cut().digest(), resp.snapshot.digest);
        snapshot = Some(resp.snapshot);
    }
    assert!(merges > 0, "the flight never coarsened: a weak test");
    // Bad requests are refused with a JSON error naming the problem.
    let mut bad = LodRequest {
        version: 77,
        lens: Lens::STANDARD.into(),
        tau: 1.0,
        camera: WireCamera::from(cams[0]),
        base: None,
    };
    let e = one_shot(&base, &bad).await.unwrap_err().to_string();
    assert!(
        e.contains("400") && e.contains("protocol version 77"),
        "{e}"
    );
    bad.version = PROTOCOL_VERSION;
    bad.camera.eye[0] = f32::INFINITY;
    let e = one_shot(&base, &bad).await.unwrap_err().to_string();
    assert!(e.contains("400") && e.contains("camera"), "{e}");
    let e = request(
        "POST",
        &format!("{base}/v1/lod"),
        "application/octet-stream",
        vec![1, 2, 3],
    )
    .await
    .unwrap_err()
    .to_string();
    assert!(e.contains("400") && e.contains("\"error\""), "{e}");
    server.stop().await;
}

/// Checks Prometheus text format 0.0.4 line by line; returns the samples by series.
fn parse_prometheus(text: &str) -> Vec<(String, f64)> {
    let mut samples = Vec::new();
    for line in text.lines() {
        if line.is_empty() {
            continue;
        }
        if let Some(rest) = line.strip_prefix('#') {
            let words: Vec<&str> = rest.split_whitespace().collect();
            assert!(
                matches!(words.first(), Some(&"HELP") | Some(&"TYPE")),
                "bad comment: {line}"
            );
            if words[0] == "TYPE" {
                assert!(
                    ["counter", "gauge", "histogram", "summary", "untyped"].contains(&words[2]),
                    "{line}"
                );
            }
            continue;
        }
        let (series, value) = line.rsplit_once(' ').expect("series and value");
        let name_end = series.find('{').unwrap_or(series.len());
        let name = &series[..name_end];
        assert!(
            !name.is_empty()
                && name
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == ':'),
            "bad metric name in {line}"
        );
        if name_end < series.len() {
            let labels = &series[name_end..];
            assert!(labels.ends_with('}'), "{line}");
            for pair in labels[1..labels.len() - 1].split(',') {
                let (k, v) = pair.split_once('=').expect("label=value");
                assert!(
                    k.chars().all(|c| c.is_ascii_alphanumeric() || c == '_'),
                    "{line}"
                );
                assert!(v.starts_with('"') && v.ends_with('"'), "{line}");
            }
        }
        let v: f64 = match value {
            "+Inf" => f64::INFINITY,
            "-Inf" => f64::NEG_INFINITY,
            v => v.parse().unwrap_or_else(|_| panic!("bad value in {line}")),
        };
        samples.push((series.to_string(), v));
    }
    samples
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn metrics_terrain_heights_and_health() {
    let server = TestServer::start(Limits::default()).await;
    let base = server.http();
    // Some traffic first, so the counters move.
    let mut s = relief_client::Session::connect(relief_client::SessionConfig::new(&server.url()))
        .await
        .unwrap();
    for cam in path(1, 5) {
        let seq = s.send_pose(cam).await.unwrap();
        s.wait_for_pose(seq).await.unwrap();
    }
    s.close().await;

    let text = String::from_utf8(
        request("GET", &format!("{base}/metrics"), "text/plain", Vec::new())
            .await
            .unwrap()
            .to_vec(),
    )
    .unwrap();
    let samples = parse_prometheus(&text);
    let get = |k: &str| samples.iter().find(|(s, _)| s == k).map(|(_, v)| *v);
    assert_eq!(get("relief_sessions_total"), Some(1.0));
    assert!(get("relief_updates_total").unwrap() >= 5.0);
    assert!(get("relief_bytes_out_total").unwrap() > 1000.0);
    assert_eq!(
        get("relief_update_seconds_count"),
        get("relief_update_seconds_bucket{le=\"+Inf\"}")
    );
    assert!(get("relief_errors_total{kind=\"bad_camera\"}").is_some());

    let t = get_json(&format!("{base}/v1/terrain")).await.unwrap();
    assert_eq!(t["width"], 257);
    assert_eq!(t["height"], 193);
    assert_eq!(t["protocol_version"], PROTOCOL_VERSION);
    let h = post_json(
        &format!("{base}/v1/heights"),
        &serde_json::json!({ "points": [[9000.0, 9000.0], [-5e5, 0.0]] }),
    )
    .await
    .unwrap();
    let hs = h["heights"].as_array().unwrap();
    let z = hs[0].as_f64().unwrap();
    assert!((500.0..4000.0).contains(&z), "{z}");
    assert!(hs[1].is_null());
    let e = post_json(
        &format!("{base}/v1/heights"),
        &serde_json::json!({ "pts": [] }),
    )
    .await
    .unwrap_err()
    .to_string();
    assert!(e.contains("400"), "{e}");
    let ok = request("GET", &format!("{base}/healthz"), "text/plain", Vec::new()).await;
    assert!(ok.is_ok());
    let ok = request("GET", &format!("{base}/readyz"), "text/plain", Vec::new()).await;
    assert!(ok.is_ok());
    let e = get_json(&format!("{base}/nope"))
        .await
        .unwrap_err()
        .to_string();
    assert!(e.contains("404") && e.contains("no such endpoint"), "{e}");
    // The client's close only sends its Close frame: the server leaves the list when it has
    // read that frame, which on a loaded machine can come after the requests above.
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
    loop {
        let sessions = get_json(&format!("{base}/v1/sessions")).await.unwrap();
        let sessions = sessions.as_array().unwrap();
        if sessions.is_empty() {
            break;
        }
        assert!(
            std::time::Instant::now() < deadline,
            "a closed session is still listed after 10 s: {sessions:?}"
        );
        tokio::time::sleep(std::time::Duration::from_millis(20)).await;
    }
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_oversized_one_shot_is_refused_with_a_reason() {
    let limits = Limits {
        max_message_bytes: 1024,
        ..Limits::default()
    };
    let server = TestServer::start(limits).await;
    let e = request(
        "POST",
        &format!("{}/v1/lod", server.http()),
        "application/octet-stream",
        vec![0; 5000],
    )
    .await
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("413") && e.contains("larger than 1024 bytes"),
        "{e}"
    );
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn fifty_thousand_points_in_ordinary_json_are_answered() {
    // Hardening: the documented 50,000 points, written by a JSON library at full precision
    // (over 2 MB), were refused with 400 by a 1 MiB body limit.
    let server = TestServer::start(Limits::default()).await;
    let points: Vec<[f64; 2]> = (0..50_000)
        .map(|i| {
            let f = f64::from(i);
            [
                1_000.123_456_789_012_3 + f * 0.1,
                2_000.987_654_321_098_7 + f * 0.05,
            ]
        })
        .collect();
    let body = serde_json::to_vec(&serde_json::json!({ "points": points })).unwrap();
    assert!(body.len() > 1_900_000, "{}", body.len());
    let b = request(
        "POST",
        &format!("{}/v1/heights", server.http()),
        "application/json",
        body,
    )
    .await
    .unwrap();
    let v: serde_json::Value = serde_json::from_slice(&b).unwrap();
    assert_eq!(v["heights"].as_array().unwrap().len(), 50_000);
    // One more point is refused, naming the limit.
    let body =
        serde_json::to_vec(&serde_json::json!({ "points": vec![[1.0, 1.0]; 50_001] })).unwrap();
    let e = request(
        "POST",
        &format!("{}/v1/heights", server.http()),
        "application/json",
        body,
    )
    .await
    .unwrap_err()
    .to_string();
    assert!(e.contains("400") && e.contains("at most 50000"), "{e}");
    server.stop().await;
}
