//! Hostile input over 127.0.0.1: bad messages and limits each end with a
//! close frame carrying a clear reason, and a bystander session keeps its latency.

use futures_util::{SinkExt, StreamExt};
use relief_client::session::{Session, SessionConfig};
use relief_proto::close::CloseReason;
use relief_proto::codec;
use relief_proto::msg::{ClientMsg, Hello, PROTOCOL_VERSION, Resume, StreamKind, WireCamera};
use relief_proto::snapshot::Snapshot;
use relief_proto::view::Lens;
use relief_server::serve::config::Limits;
use relief_tests::bystander::{Bystander, assert_kept};
use relief_tests::raw::{connect_from, lo};
use relief_tests::{TestServer, hello, hello_frame, path};
use std::time::{Duration, Instant};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio_tungstenite::tungstenite::Message;

type Ws =
    tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

/// Reads until the server's close frame; returns its code and text.
async fn close_of(ws: &mut Ws) -> (u16, String) {
    let limit = tokio::time::sleep(Duration::from_secs(20));
    tokio::pin!(limit);
    loop {
        tokio::select! {
            _ = &mut limit => panic!("no close frame"),
            m = ws.next() => match m {
                Some(Ok(Message::Close(Some(f)))) => return (u16::from(f.code), f.reason.to_string()),
                Some(Ok(_)) => continue,
                other => panic!("connection ended without a close frame: {other:?}"),
            },
        }
    }
}

/// Connects, sends `frames`, and returns the close code and text.
async fn send_and_close(url: &str, frames: Vec<Message>) -> (u16, String) {
    let (mut ws, _) = tokio_tungstenite::connect_async(url).await.unwrap();
    for f in frames {
        if ws.send(f).await.is_err() {
            break;
        }
    }
    close_of(&mut ws).await
}

fn bin(msg: &ClientMsg) -> Message {
    Message::Binary(codec::encode(msg).into())
}

fn pose(seq: u64, eye: [f32; 3]) -> Message {
    bin(&ClientMsg::Pose {
        seq,
        camera: WireCamera {
            eye,
            yaw: 0.3,
            pitch: -0.3,
        },
    })
}

fn assert_reason(got: (u16, String), want: CloseReason, needle: &str) {
    assert_eq!(got.0, want.code(), "{got:?}");
    assert!(got.1.starts_with(want.name()), "{got:?}");
    assert!(got.1.contains(needle), "{got:?} lacks {needle:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_frames_close_with_a_reason_and_others_keep_going() {
    let limits = Limits {
        max_message_bytes: 4096,
        ..Limits::default()
    };
    let server = TestServer::start(limits).await;
    let url = server.url();
    // A session that flies on through all of it.
    let by = Bystander::start(&url, 4).await;
    let calm = by.measure(Duration::from_millis(400)).await;
    let ((), attacked) = by
        .during(async {
            let hb = || Message::Binary(hello().into());
            let ok_eye = [9000.0, 9000.0, 4000.0];

            let r = send_and_close(&url, vec![Message::Binary(vec![0u8; 10_000].into())]).await;
            assert_reason(r, CloseReason::TooLarge, "4096");
            let r = send_and_close(&url, vec![Message::Binary(vec![9, 9, 9, 9, 9].into())]).await;
            assert_reason(r, CloseReason::Malformed, "malformed");
            let r = send_and_close(&url, vec![Message::Text("hello".into())]).await;
            assert_reason(r, CloseReason::Malformed, "text frames");
            let r = send_and_close(&url, vec![Message::Binary(hello_frame(99).into())]).await;
            assert_reason(r, CloseReason::Version, "99");
            let r = send_and_close(&url, vec![pose(1, ok_eye)]).await;
            assert_reason(r, CloseReason::Protocol, "hello");
            let r = send_and_close(&url, vec![hb(), pose(1, [f32::NAN, 0.0, 100.0])]).await;
            assert_reason(r, CloseReason::BadCamera, "not finite");
            let r = send_and_close(&url, vec![hb(), pose(1, [1e9, 0.0, 100.0])]).await;
            assert_reason(r, CloseReason::BadCamera, "away from the terrain");
            let r = send_and_close(&url, vec![hb(), bin(&ClientMsg::Ack { seq: 5 })]).await;
            assert_reason(r, CloseReason::Protocol, "acknowledged delta 5");
            let r = send_and_close(&url, vec![hb(), hb()]).await;
            assert_reason(r, CloseReason::Protocol, "second hello");

            let mk = |tau: f32, resume: Option<Resume>| {
                bin(&ClientMsg::Hello(Hello {
                    version: PROTOCOL_VERSION,
                    kind: StreamKind::Vertex,
                    lens: Lens::STANDARD.into(),
                    tau,
                    budget: None,
                    resume,
                }))
            };
            let r = send_and_close(&url, vec![mk(f32::NAN, None)]).await;
            assert_reason(r, CloseReason::BadParams, "tau");
            let id = server.state.terrain().unwrap().info.id;
            let other_terrain = Resume {
                terrain_id: id ^ 1,
                snapshot: Snapshot {
                    digest: 0,
                    bits: vec![0],
                },
            };
            let r = send_and_close(&url, vec![mk(1.0, Some(other_terrain))]).await;
            assert_reason(r, CloseReason::BadSnapshot, "terrain");
            let garbage = Resume {
                terrain_id: id,
                snapshot: Snapshot {
                    digest: 12345,
                    bits: vec![0xFF; 64],
                },
            };
            let r = send_and_close(&url, vec![mk(1.0, Some(garbage))]).await;
            assert_reason(r, CloseReason::BadSnapshot, "snapshot");
        })
        .await;
    assert_kept("bad messages", calm, attacked);
    let c = by.stop().await;
    assert_eq!((c.desyncs, c.reconnects), (0, 0));
    let m = server.state.metrics.render();
    for kind in [
        "too_large",
        "malformed",
        "version",
        "protocol",
        "bad_camera",
        "bad_params",
        "bad_snapshot",
    ] {
        assert!(
            !m.contains(&format!("relief_errors_total{{kind=\"{kind}\"}} 0")),
            "{kind} not counted:\n{m}"
        );
    }
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn session_limits_and_idle_timeout() {
    let limits = Limits {
        max_sessions_per_ip: 2,
        idle_timeout: Duration::from_millis(600),
        ..Limits::default()
    };
    let server = TestServer::start(limits).await;
    let url = server.url();
    let mut held = Vec::new();
    for _ in 0..2 {
        let (mut ws, _) = tokio_tungstenite::connect_async(&url).await.unwrap();
        ws.send(Message::Binary(hello().into())).await.unwrap();
        // The welcome.
        assert!(matches!(ws.next().await, Some(Ok(Message::Binary(_)))));
        held.push(ws);
    }
    let r = send_and_close(&url, vec![Message::Binary(hello().into())]).await;
    assert_reason(r, CloseReason::TooManyFromAddress, "127.0.0.1");
    // The held sessions say nothing and time out.
    let t = Instant::now();
    for ws in &mut held {
        assert_reason(close_of(ws).await, CloseReason::Idle, "no message");
    }
    assert!(t.elapsed() < Duration::from_secs(5));
    // Their slots are free again.
    let mut s = Session::connect(SessionConfig::new(&url)).await.unwrap();
    let seq = s.send_pose(path(0, 1)[0]).await.unwrap();
    s.wait_for_pose(seq).await.unwrap();
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn slowloris_and_connection_rate_are_cut_off() {
    let limits = Limits {
        header_timeout: Duration::from_millis(500),
        conn_rate_per_ip: 5.0,
        ..Limits::default()
    };
    let server = TestServer::start(limits).await;
    let by = Bystander::start(&server.url(), 2).await;
    let calm = by.measure(Duration::from_millis(400)).await;
    let ((), attacked) = by
        .during(async {
            // Headers that never finish: the connection is closed after the header timeout.
            let mut slow = connect_from(lo(2), server.addr).await.unwrap();
            slow.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\n")
                .await
                .unwrap();
            let t = Instant::now();
            let mut buf = [0u8; 512];
            loop {
                // Trickle a byte now and then, as slowloris does; the deadline holds regardless.
                match tokio::time::timeout(Duration::from_millis(200), slow.read(&mut buf)).await {
                    Ok(Ok(0)) | Ok(Err(_)) => break,
                    Ok(Ok(_)) => {}
                    Err(_) => {
                        let _ = slow.write_all(b"X").await;
                    }
                }
                assert!(
                    t.elapsed() < Duration::from_secs(5),
                    "slow headers not cut off"
                );
            }
            assert!(t.elapsed() >= Duration::from_millis(400));

            // Thirty connections at once: the burst (10) passes, the rest get 429.
            let mut refused = 0;
            for _ in 0..30 {
                let mut c = connect_from(lo(2), server.addr).await.unwrap();
                let _ = c
                    .write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")
                    .await;
                let mut text = Vec::new();
                let _ =
                    tokio::time::timeout(Duration::from_secs(2), c.read_to_end(&mut text)).await;
                let text = String::from_utf8_lossy(&text);
                if text.starts_with("HTTP/1.1 429") {
                    assert!(text.contains("too many connections"), "{text}");
                    refused += 1;
                } else {
                    assert!(text.starts_with("HTTP/1.1 200"), "{text}");
                }
            }
            assert!((15..=21).contains(&refused), "{refused} refused");
            assert!(server.state.metrics.render().contains(&format!(
                "relief_errors_total{{kind=\"rate_limited\"}} {refused}"
            )));
        })
        .await;
    assert_kept("slowloris and a connection burst", calm, attacked);
    assert_eq!(by.stop().await.desyncs, 0);
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn shutdown_drains_sessions_within_the_timeout() {
    let limits = Limits {
        drain_timeout: Duration::from_secs(3),
        ..Limits::default()
    };
    let server = TestServer::start(limits).await;
    let mut held = Vec::new();
    for _ in 0..5 {
        let (mut ws, _) = tokio_tungstenite::connect_async(server.url())
            .await
            .unwrap();
        ws.send(Message::Binary(hello().into())).await.unwrap();
        assert!(matches!(ws.next().await, Some(Ok(Message::Binary(_)))));
        held.push(ws);
    }
    let readers = held
        .into_iter()
        .map(|mut ws| {
            tokio::spawn(async move {
                let mut reconnect = false;
                loop {
                    match ws.next().await {
                        Some(Ok(Message::Binary(b))) => {
                            reconnect |= matches!(
                                codec::decode::<relief_proto::msg::ServerMsg>(&b, 1 << 20),
                                Ok(relief_proto::msg::ServerMsg::Reconnect { .. })
                            );
                        }
                        Some(Ok(Message::Close(Some(f)))) => return (reconnect, u16::from(f.code)),
                        Some(Ok(_)) => {}
                        _ => return (reconnect, 0),
                    }
                }
            })
        })
        .collect::<Vec<_>>();
    let took = server.stop().await;
    assert!(took < Duration::from_secs(3), "drain took {took:?}");
    for r in readers {
        assert_eq!(r.await.unwrap(), (true, CloseReason::Draining.code()));
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_cut_past_the_node_limit_ends_the_session_with_a_reason() {
    let limits = Limits {
        max_cut_nodes: 100,
        ..Limits::default()
    };
    let server = TestServer::start(limits).await;
    let cam = path(0, 1)[0];
    let pose = bin(&ClientMsg::Pose {
        seq: 1,
        camera: WireCamera::from(cam),
    });
    let r = send_and_close(&server.url(), vec![Message::Binary(hello().into()), pose]).await;
    assert_reason(r, CloseReason::CutLimit, "limit of 100 interior nodes");
    // The one-shot applies the same limit, in the same words.
    let req = relief_proto::msg::LodRequest {
        version: PROTOCOL_VERSION,
        lens: Lens::STANDARD.into(),
        tau: 1.0,
        camera: WireCamera::from(cam),
        base: None,
    };
    let e = relief_client::http::request(
        "POST",
        &format!("{}/v1/lod", server.http()),
        "application/octet-stream",
        codec::encode(&req),
    )
    .await
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("400")
            && e.contains("cut_limit: the cut reached the server's limit of 100 interior nodes"),
        "{e}"
    );
    server.stop().await;
}
