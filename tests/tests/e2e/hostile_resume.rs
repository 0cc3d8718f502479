//! Hostile input: resume amplification. A resume hello carrying the full cut
//! of synthetic:2049 (175 KB, with a correct digest) used to cost the server 24 MB and 1 s of
//! CPU, and forty of them delayed a bystander's first delta from 0.2 s to 34 s. Now a resumed
//! session costs memory in proportion to its snapshot, accounted from the hello; resumes are
//! paced per address; large ones take turns until their first delta; and bystanders keep
//! their latency.

use futures_util::{SinkExt, StreamExt};
use relief_client::session::{Session, SessionConfig};
use relief_proto::close::CloseReason;
use relief_proto::codec;
use relief_proto::cut::Cut;
use relief_proto::msg::{ClientMsg, Hello, PROTOCOL_VERSION, Resume, StreamKind, WireCamera};
use relief_proto::snapshot::Snapshot;
use relief_proto::tree::NodeId;
use relief_proto::view::Lens;
use relief_server::serve::config::{Limits, ServeConfig, TerrainSource};
use relief_tests::TestServer;
use relief_tests::bystander::{Bystander, Latency, assert_kept};
use relief_tests::raw::{Closed, binary, lo, read_close_or, ws_open};
use std::time::{Duration, Instant};
use tokio::io::AsyncWriteExt;

/// A server on synthetic:2049 and the full cut's resume hello.
async fn setup(dir: &std::path::Path) -> (TestServer, Vec<u8>, usize) {
    let store = dir.join("s2049.relief");
    let d = relief_server::dem::load("synthetic:2049", &Default::default()).unwrap();
    relief_server::preprocess::build_store(&d, &store, &Default::default()).unwrap();
    let server = TestServer::start_with(ServeConfig {
        source: TerrainSource::Store(store),
        addr: "127.0.0.1:0".parse().unwrap(),
        cache_dir: dir.join("cache"),
        limits: Limits::default(),
        web_lib: relief_server::serve::config::DEFAULT_WEB_LIB.into(),
        public_url: None,
    })
    .await;
    let t = server.state.terrain().unwrap();
    let shape = &t.store.geometry().shape;
    let mut cut = Cut::root(shape);
    for level in 0..shape.depth() {
        let (w, h) = shape.level_dims(level);
        for y in 0..h {
            for x in 0..w {
                cut.split(shape, NodeId { level, x, y }).unwrap();
            }
        }
    }
    let snapshot = Snapshot::of(shape, &cut);
    let bytes = snapshot.bits.len();
    let hello = codec::encode(&ClientMsg::Hello(Hello {
        version: PROTOCOL_VERSION,
        kind: StreamKind::Vertex,
        lens: Lens::STANDARD.into(),
        tau: 1.0,
        budget: None,
        resume: Some(Resume {
            terrain_id: t.info.id,
            snapshot,
        }),
    }));
    (server, hello, bytes)
}

/// A pose over the middle of the terrain.
fn pose(server: &TestServer) -> Vec<u8> {
    let i = &server.state.terrain().unwrap().info;
    let (w, h) = (i.width as f32 * i.spacing_x, i.height as f32 * i.spacing_y);
    codec::encode(&ClientMsg::Pose {
        seq: 1,
        camera: WireCamera {
            eye: [w / 2.0, h / 2.0, i.height_range[1] + 500.0],
            yaw: 0.5,
            pitch: -0.4,
        },
    })
}

/// An attacker from `ip`: the resume hello, then a pose, then it reads until the server
/// closes, or the welcome and the first delta came.
async fn attack(ip: u8, addr: std::net::SocketAddr, hello: Vec<u8>, pose: Vec<u8>) -> Closed {
    let mut tcp = ws_open(lo(ip), addr).await;
    if tcp.write_all(&binary(&hello)).await.is_err() {
        return Closed::NoFrame;
    }
    let _ = tcp.write_all(&binary(&pose)).await;
    read_close_or(&mut tcp, 2).await
}

/// A fresh session's time to its first delta.
async fn first_delta(url: &str) -> Duration {
    let t = Instant::now();
    let mut s = Session::connect(SessionConfig::new(url)).await.unwrap();
    let seq = s.send_pose(relief_tests::path(0, 1)[0]).await.unwrap();
    s.wait_for_pose(seq).await.unwrap();
    t.elapsed()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_resumed_full_cut_costs_memory_in_proportion_accounted_from_the_hello() {
    let dir = tempfile::tempdir().unwrap();
    let (server, hello, snapshot_bytes) = setup(dir.path()).await;
    let (mut ws, _) = tokio_tungstenite::connect_async(server.url())
        .await
        .unwrap();
    let t = Instant::now();
    ws.send(tokio_tungstenite::tungstenite::Message::Binary(
        hello.into(),
    ))
    .await
    .unwrap();
    // Accounted before the welcome (the reports are polled while the session opens).
    let mut first_seen = None;
    let welcome = loop {
        tokio::select! {
            m = ws.next() => break m,
            _ = tokio::time::sleep(Duration::from_millis(1)) => {
                if first_seen.is_none() {
                    let r = server.state.session_reports(true);
                    if let Some(s) = r.first().filter(|s| s.memory_bytes > 4096) {
                        first_seen = Some((t.elapsed(), s.memory_bytes));
                    }
                }
            }
        }
    };
    assert!(matches!(welcome, Some(Ok(_))));
    let opened = t.elapsed();
    let held = server.state.session_reports(true)[0].memory_bytes;
    eprintln!(
        "full-cut resume of synthetic:2049: snapshot {snapshot_bytes} B; accounted {first_seen:?} \
         before the welcome at {opened:?}; {held} B held after it ({:.1}x the snapshot)",
        held as f64 / snapshot_bytes as f64
    );
    let (_, early) = first_seen.expect("memory accounted before the welcome");
    assert!(early as usize >= snapshot_bytes);
    // In proportion to its own cut: a few bytes per snapshot byte, not 24 MB.
    assert!(
        (held as usize) < 16 * snapshot_bytes + 65_536,
        "{held} B for a {snapshot_bytes} B snapshot"
    );
    server.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn forty_full_cut_resumes_leave_bystanders_their_latency() {
    let dir = tempfile::tempdir().unwrap();
    let (server, hello, _) = setup(dir.path()).await;
    let addr = server.addr;
    let pose = pose(&server);
    let by = Bystander::start(&server.url(), 0).await;
    let calm = by.measure(Duration::from_millis(500)).await;
    let calm_first = first_delta(&server.url()).await;
    let (closes, attacked) = by
        .during(async {
            // Twenty from one address, twenty from twenty others.
            let mut tasks = Vec::new();
            for k in 0..40u8 {
                let ip = if k < 20 { 2 } else { 10 + k };
                tasks.push(tokio::spawn(attack(ip, addr, hello.clone(), pose.clone())));
            }
            tokio::time::sleep(Duration::from_millis(300)).await;
            let mut firsts = Vec::new();
            for _ in 0..5 {
                firsts.push(first_delta(&server.url()).await);
            }
            let mut closes = Vec::new();
            for t in tasks {
                closes.push(t.await.unwrap());
            }
            (closes, firsts)
        })
        .await;
    let (closes, firsts) = closes;
    let paced = closes
        .iter()
        .filter(|c| matches!(c, Closed::Code(code, text)
            if *code == CloseReason::TooManyFromAddress.code() && text.contains("resumed more than")))
        .count();
    let firsts_ms = Latency::of(&firsts);
    eprintln!(
        "40 full-cut resumes: {paced} refused by the per-address pace; a fresh session's first \
         delta took {calm_first:?} calm and {firsts_ms:?} under the flood"
    );
    assert!(paced >= 10, "{closes:?}");
    assert!(
        firsts_ms.max_ms < 2000.0,
        "a fresh session waited {firsts_ms:?} for its first delta"
    );
    assert_kept("forty full-cut resumes", calm, attacked);
    assert_eq!(by.stop().await.desyncs, 0);
    server.stop().await;
}
