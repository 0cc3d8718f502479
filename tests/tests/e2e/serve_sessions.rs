//! End to end over 127.0.0.1: many sessions at once, a dropped connection resumed, a budgeted
//! session, and a client that stops reading.

use futures_util::{SinkExt, StreamExt};
use relief_client::session::{Session, SessionConfig};
use relief_proto::codec;
use relief_proto::msg::{ClientMsg, WireCamera};
use relief_proto::snapshot::Snapshot;
use relief_server::serve::config::Limits;
use relief_tests::{TestServer, hello, path};
use std::collections::BTreeSet;
use tokio_tungstenite::tungstenite::Message;

/// Flies `cams` lock-step in a vertex session (see [`relief_tests::fly`]).
async fn fly(url: &str, cams: &[relief_proto::view::Camera], drop_at: Option<usize>) -> Session {
    relief_tests::fly(SessionConfig::new(url), cams, drop_at).await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn fifty_sessions_on_different_paths_never_desync() {
    let server = TestServer::start(Limits::default()).await;
    let url = server.url();
    let mut tasks = Vec::new();
    for i in 0..50 {
        let url = url.clone();
        tasks.push(tokio::spawn(async move {
            let cams = path(i, 40);
            let s = fly(&url, &cams, None).await;
            let c = s.counters();
            let digest = s.mirror().cut().digest();
            s.close().await;
            (c, digest)
        }));
    }
    let mut digests = BTreeSet::new();
    for t in tasks {
        let (c, digest) = t.await.unwrap();
        // Every delta's digest was checked against the mirror as it was applied.
        assert_eq!(c.desyncs, 0);
        assert_eq!(c.reconnects, 0);
        assert!(c.deltas >= 40, "{c:?}");
        digests.insert(digest);
    }
    // Different paths end in different cuts.
    assert!(digests.len() > 10, "{} distinct cuts", digests.len());
    let m = server.state.metrics.render();
    assert!(m.contains("relief_sessions_total 50"), "{m}");
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_dropped_connection_resumes_to_the_same_mesh() {
    let server = TestServer::start(Limits::default()).await;
    let cams = path(3, 80);
    let whole = fly(&server.url(), &cams, None).await;
    let resumed = fly(&server.url(), &cams, Some(40)).await;
    let c = resumed.counters();
    assert_eq!(c.reconnects, 1);
    assert_eq!(c.resumes, 1, "the server resumed from the snapshot");
    assert_eq!(c.desyncs, 0);
    assert_eq!(
        whole.mirror().cut().digest(),
        resumed.mirror().cut().digest()
    );
    let a: BTreeSet<_> = whole.mesh().triangles().into_iter().collect();
    let b: BTreeSet<_> = resumed.mesh().triangles().into_iter().collect();
    assert_eq!(a, b, "the resumed mesh differs");
    assert!(
        server
            .state
            .metrics
            .render()
            .contains("relief_resumes_total 1")
    );
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_budgeted_session_stays_consistent_and_within_budget() {
    let server = TestServer::start(Limits::default()).await;
    let budget = 4_000u32;
    let mut cfg = SessionConfig::new(&server.url());
    cfg.budget = Some(budget);
    let mut s = Session::connect(cfg).await.unwrap();
    let cams = path(0, 20);
    let t0 = std::time::Instant::now();
    let mut incomplete = 0;
    for cam in &cams {
        let seq = s.send_pose(*cam).await.unwrap();
        for a in s.wait_for_pose(seq).await.unwrap() {
            incomplete += usize::from(!a.complete);
        }
    }
    let secs = t0.elapsed().as_secs_f64();
    let c = s.counters();
    assert_eq!(c.desyncs, 0);
    // The first cut alone is larger than the budget's one-second burst, so it came in parts.
    assert!(incomplete > 0, "no delta was held back by the budget");
    // Bytes over the flight stay within a second of burst plus the budget's rate (framing of
    // a few bytes per message aside).
    let allowed = budget as f64 * (secs + 1.0) + 64.0 * c.deltas as f64;
    assert!(
        (c.bytes_in as f64) <= allowed,
        "{} bytes in {secs:.2} s exceeds {allowed:.0}",
        c.bytes_in
    );
    // The last wait ended on a complete delta: the cut meets tau for the last pose, and it is
    // a consistent cut (its snapshot rebuilds with the same digest).
    let shape = &s.geometry().shape;
    let snap = Snapshot::of(shape, s.mirror().cut());
    assert_eq!(
        snap.to_cut(shape, usize::MAX).unwrap().digest(),
        snap.digest
    );
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_that_stops_reading_holds_a_bounded_window() {
    let limits = Limits {
        max_in_flight: 3,
        ..Limits::default()
    };
    let server = TestServer::start(limits).await;
    let (mut ws, _) = tokio_tungstenite::connect_async(server.url())
        .await
        .unwrap();
    ws.send(Message::Binary(hello().into())).await.unwrap();
    // Hundreds of poses, never reading a delta nor acknowledging one.
    for (i, cam) in path(1, 400).into_iter().enumerate() {
        let pose = ClientMsg::Pose {
            seq: i as u64 + 1,
            camera: WireCamera::from(cam),
        };
        ws.send(Message::Binary(codec::encode(&pose).into()))
            .await
            .unwrap();
    }
    tokio::time::sleep(std::time::Duration::from_millis(500)).await;
    let reports = server.state.session_reports(true);
    assert_eq!(reports.len(), 1);
    let r = &reports[0];
    assert!(r.deltas <= 3, "{r:?}");
    assert!(r.unacked <= 3, "{r:?}");
    // The session's state is its cut, not a queue of deltas: far below a megabyte here.
    assert!(r.memory_bytes < 1 << 20, "{r:?}");
    // Everyone else is served meanwhile.
    let other = fly(&server.url(), &path(2, 10), None).await;
    assert_eq!(other.counters().desyncs, 0);
    // Reading resumes the stream: the deltas held back arrive, and acknowledging opens the window.
    let mut got = 0;
    while got < 3 {
        if let Some(Ok(Message::Binary(_))) = ws.next().await {
            got += 1;
        }
    }
    drop(ws);
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_at_rest_keeps_its_session_alive() {
    let limits = Limits {
        idle_timeout: std::time::Duration::from_millis(400),
        ..Limits::default()
    };
    let server = TestServer::start(limits).await;
    let cams = path(5, 2);
    let mut s = Session::connect(SessionConfig::new(&server.url()))
        .await
        .unwrap();
    let seq = s.send_pose(cams[0]).await.unwrap();
    s.wait_for_pose(seq).await.unwrap();
    // Four idle timeouts without a pose: the session pings and is not closed.
    let waited = tokio::time::timeout(std::time::Duration::from_millis(1600), s.next_delta()).await;
    assert!(waited.is_err(), "a delta arrived at rest: {waited:?}");
    let seq = s.send_pose(cams[1]).await.unwrap();
    s.wait_for_pose(seq).await.unwrap();
    assert_eq!(s.counters().reconnects, 0);
    assert!(
        server
            .state
            .metrics
            .render()
            .contains("relief_errors_total{kind=\"idle\"} 0")
    );
    server.stop().await;
}
