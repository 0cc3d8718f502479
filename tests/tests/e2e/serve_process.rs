//! End to end with the server as a real process: killed and restarted under connected
//! clients, which resume with nothing lost; and SIGTERM, which drains and exits in bounded time.

use nix::sys::signal::Signal;
use relief_client::session::{Session, SessionConfig};
use relief_tests::{ChildServer, free_addr, path};
use std::collections::BTreeSet;
use std::path::Path;
use std::time::Duration;

const BIN: &str = env!("CARGO_BIN_EXE_relief-test-server");

async fn fly_span(s: &mut Session, cams: &[relief_proto::view::Camera]) {
    for cam in cams {
        let seq = s.send_pose(*cam).await.unwrap();
        s.wait_for_pose(seq).await.unwrap();
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn clients_resume_across_a_server_restart_with_nothing_lost() {
    let addr = free_addr();
    let url = format!("ws://{addr}/v1/stream");
    let mut server = ChildServer::start(Path::new(BIN), addr, &[]).await;
    let cams: Vec<_> = (0..4).map(|i| path(i, 60)).collect();
    let mut sessions = Vec::new();
    for c in &cams {
        let mut s = Session::connect(SessionConfig::new(&url)).await.unwrap();
        fly_span(&mut s, &c[..30]).await;
        sessions.push(s);
    }
    // A crash: no drain, no goodbye.
    server.signal(Signal::SIGKILL);
    assert!(server.wait(Duration::from_secs(5)).is_some());
    drop(server);
    let restart = tokio::spawn(async move {
        tokio::time::sleep(Duration::from_millis(300)).await;
        ChildServer::start(Path::new(BIN), addr, &[]).await
    });
    // The clients fly on; their sessions reconnect (with backoff) and resume.
    let mut flown = Vec::new();
    for (mut s, c) in sessions.into_iter().zip(&cams) {
        let t = tokio::spawn({
            let c = c.clone();
            async move {
                fly_span(&mut s, &c[30..]).await;
                s
            }
        });
        flown.push(t);
    }
    let _server = restart.await.unwrap();
    for (t, c) in flown.into_iter().zip(&cams) {
        let s = t.await.unwrap();
        let k = s.counters();
        assert_eq!(k.desyncs, 0);
        assert!(k.reconnects >= 1 && k.resumes >= 1, "{k:?}");
        // Nothing lost: the same mesh as a session that flew the whole path on one server.
        let mut whole = Session::connect(SessionConfig::new(&url)).await.unwrap();
        fly_span(&mut whole, c).await;
        assert_eq!(whole.mirror().cut().digest(), s.mirror().cut().digest());
        let a: BTreeSet<_> = whole.mesh().triangles().into_iter().collect();
        let b: BTreeSet<_> = s.mesh().triangles().into_iter().collect();
        assert_eq!(a, b);
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigterm_drains_and_exits_in_bounded_time() {
    let addr = free_addr();
    let url = format!("ws://{addr}/v1/stream");
    let mut server = ChildServer::start(Path::new(BIN), addr, &["--drain-timeout-s", "2"]).await;
    let mut sessions = Vec::new();
    for i in 0..3 {
        let mut cfg = SessionConfig::new(&url);
        cfg.reconnect_deadline = Duration::from_millis(300);
        let mut s = Session::connect(cfg).await.unwrap();
        fly_span(&mut s, &path(i, 5)).await;
        sessions.push(s);
    }
    server.signal(Signal::SIGTERM);
    let took = server
        .wait(Duration::from_secs(10))
        .expect("the server did not exit");
    assert!(took < Duration::from_secs(3), "exit took {took:?}");
    // Each client was told to reconnect; with the server gone for good, reconnecting fails.
    for mut s in sessions {
        let e = s.next_delta().await.unwrap_err().to_string();
        assert!(e.contains("cannot connect"), "{e}");
        assert!(s.counters().reconnects >= 1);
    }
}

/// How many sessions from this address the server at `url` admits, trying up to `n`.
async fn admitted(url: &str, n: usize) -> usize {
    use futures_util::{SinkExt, StreamExt};
    use tokio_tungstenite::tungstenite::Message;
    let mut held = Vec::new();
    for _ in 0..n {
        let (mut ws, _) = tokio_tungstenite::connect_async(url).await.unwrap();
        ws.send(Message::Binary(relief_tests::hello().into()))
            .await
            .unwrap();
        match ws.next().await {
            Some(Ok(Message::Binary(_))) => held.push(ws),
            _ => break,
        }
    }
    held.len()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn flags_beat_environment_variables_which_beat_the_config_file() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("relief.toml");
    std::fs::write(&file, "max_sessions_per_ip = 3\nidle_timeout_s = 30\n").unwrap();
    let file = file.to_str().unwrap();
    let addr = free_addr();
    let url = format!("ws://{addr}/v1/stream");
    {
        let _s = ChildServer::start(Path::new(BIN), addr, &["--config", file]).await;
        assert_eq!(admitted(&url, 5).await, 3, "the file sets the limit");
    }
    let env = [("RELIEF_MAX_SESSIONS_PER_IP", "1")];
    {
        let _s = ChildServer::start_env(Path::new(BIN), addr, &["--config", file], &env).await;
        assert_eq!(admitted(&url, 5).await, 1, "the variable beats the file");
    }
    {
        let flags = ["--config", file, "--max-sessions-per-ip", "2"];
        let _s = ChildServer::start_env(Path::new(BIN), addr, &flags, &env).await;
        assert_eq!(admitted(&url, 5).await, 2, "the flag beats the variable");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_drain_does_not_wait_for_connections_that_said_nothing() {
    use relief_tests::raw::{Closed, binary, connect_from, lo, read_close, ws_open};
    use tokio::io::AsyncWriteExt;
    let addr = free_addr();
    let mut server = ChildServer::start(Path::new(BIN), addr, &[]).await;
    // An upgraded WebSocket that never says hello, one that sends half a hello, and a request
    // with half its headers.
    let mut silent = ws_open(lo(1), addr).await;
    let mut halting = ws_open(lo(1), addr).await;
    let hello = binary(&relief_tests::hello());
    halting.write_all(&hello[..hello.len() / 2]).await.unwrap();
    let mut half = connect_from(lo(1), addr).await.unwrap();
    half.write_all(b"GET /v1/terrain HTTP/1.1\r\nHost: x\r\n")
        .await
        .unwrap();
    tokio::time::sleep(Duration::from_millis(200)).await;
    server.signal(Signal::SIGTERM);
    let took = server
        .wait(Duration::from_secs(10))
        .expect("the server did not exit");
    eprintln!("exit took {took:?}");
    assert!(
        took < Duration::from_secs(2),
        "the drain waited {took:?} for connections that said nothing"
    );
    for ws in [&mut silent, &mut halting] {
        match read_close(ws).await {
            Closed::Code(code, text) => {
                assert_eq!(code, 1012, "{text}");
                assert!(text.starts_with("draining: "), "{text}");
            }
            other => panic!("no close frame: {other:?}"),
        }
    }
}
