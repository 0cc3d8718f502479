//! Scale-out: three `relief-server` processes on 127.0.0.1, each building its own
//! store of the embedded terrain into its own cache, behind Debian's HAProxy running
//! `deploy/haproxy.cfg` (leastconn, no stickiness). Through the balancer, 200 sessions (100
//! vertex, 100 tiles) fly the standard loop in lock step with `relief_client::chaos`, while a
//! prober asks `POST /v1/query`:
//! - without incident, for the reference digests;
//! - with one replica killed by SIGKILL mid-run: every session on it reconnects through the
//!   balancer and resumes on another replica, 0 lost, 0 desyncs, every final cut the
//!   reference's, reconnect gap p99 within 2 s, and the queries keep being answered;
//! - with a rolling restart (SIGTERM to each replica in turn, restarted after each): the same.
//!
//! `tests/setup.sh` installs HAProxy; without it this test fails and says so.

use relief_client::chaos::{self, ChaosOptions, ChaosReport, Drill};
use relief_tests::{ChildServer, Reaped, free_addr, repo};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_relief-test-server");

/// The replicas, restartable in place.
struct Replicas {
    /// Each replica's address, cache folder and process (`None` while it is down).
    nodes: Vec<(SocketAddr, PathBuf, Option<ChildServer>)>,
}

impl Replicas {
    async fn start(addr: SocketAddr, cache: &Path) -> ChildServer {
        let config = repo().join("deploy/relief.toml");
        ChildServer::start_with_args(
            Path::new(BIN),
            addr,
            &[
                "--cache-dir",
                cache.to_str().unwrap(),
                "--config",
                config.to_str().unwrap(),
            ],
            &[],
        )
        .await
    }
}

impl Drill for Replicas {
    fn act<'a>(
        &'a mut self,
        action: &'a str,
    ) -> futures_util::future::BoxFuture<'a, Result<(), String>> {
        Box::pin(async move {
            let (verb, k) = action.split_once(' ').ok_or("action: VERB INDEX")?;
            let k: usize = k.parse().map_err(|_| "action: bad index")?;
            let (addr, cache, child) = &mut self.nodes[k];
            match verb {
                "kill" => {
                    let c = child.as_mut().ok_or("already down")?;
                    c.signal(nix::sys::signal::Signal::SIGKILL);
                    c.wait(Duration::from_secs(5)).ok_or("did not die")?;
                    *child = None;
                }
                "restart" => {
                    // SIGTERM: the replica drains (its sessions are told to reconnect), exits,
                    // and starts again on the same port with the same cache.
                    if let Some(mut c) = child.take() {
                        c.signal(nix::sys::signal::Signal::SIGTERM);
                        c.wait(Duration::from_secs(15)).ok_or("did not drain")?;
                    }
                    *child = Some(Self::start(*addr, cache).await);
                }
                "start" => *child = Some(Self::start(*addr, cache).await),
                _ => return Err(format!("unknown action {action:?}")),
            }
            Ok(())
        })
    }
}

/// HAProxy running deploy/haproxy.cfg in the foreground, killed on drop.
struct Haproxy(#[allow(dead_code, reason = "held: dropping it stops haproxy")] Reaped);

async fn haproxy(front: SocketAddr, replicas: &[SocketAddr]) -> Haproxy {
    let bin = ["/usr/sbin/haproxy", "/usr/bin/haproxy"]
        .into_iter()
        .find(|p| Path::new(p).exists())
        .expect("haproxy is missing: run `bash tests/setup.sh` (the README's test command does)");
    let stats = free_addr();
    let child = std::process::Command::new(bin)
        .args(["-db", "-q", "-f"])
        .arg(repo().join("deploy/haproxy.cfg"))
        .env("RELIEF_1", replicas[0].to_string())
        .env("RELIEF_2", replicas[1].to_string())
        .env("RELIEF_3", replicas[2].to_string())
        .env("RELIEF_FRONT", front.to_string())
        .env("RELIEF_STATS", stats.to_string())
        .spawn()
        .expect("start haproxy");
    let h = Haproxy(Reaped(child));
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        let ok = relief_client::http::request(
            "GET",
            &format!("http://{front}/readyz"),
            "text/plain",
            Vec::new(),
        )
        .await
        .is_ok();
        if ok {
            return h;
        }
        assert!(Instant::now() < deadline, "haproxy never answered");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

fn assert_survived(what: &str, r: &ChaosReport, reference: &ChaosReport) {
    println!("{what}: {}", chaos::summary(r));
    assert_eq!((r.lost, r.desyncs), (0, 0), "{what}: {:?}", r.errors);
    // Every action hit the fleet in flight.
    for a in &r.actions {
        assert!(
            a.flown_after < 1.0,
            "{what}: {} came after the flights",
            a.action
        );
    }
    assert!(r.sessions_reconnected > 0, "{what}: nobody reconnected");
    assert_eq!(r.resumes, r.reconnects, "{what}: a session started afresh");
    let differ = r
        .digests
        .iter()
        .zip(&reference.digests)
        .filter(|(a, b)| a != b)
        .count();
    assert_eq!(
        differ, 0,
        "{what}: final cuts differ from the uninterrupted run's"
    );
    assert!(
        r.reconnect_gap_ms.p99 <= 2000.0,
        "{what}: reconnect gap p99 {:.0} ms",
        r.reconnect_gap_ms.p99
    );
    assert!(
        r.queries_ok > 10 && r.query_gap_max_ms <= 2000.0,
        "{what}: queries {} answered, longest gap {:.0} ms",
        r.queries_ok,
        r.query_gap_max_ms
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn three_replicas_behind_haproxy_survive_a_kill_and_a_rolling_restart() {
    let dirs: Vec<tempfile::TempDir> = (0..3).map(|_| tempfile::tempdir().unwrap()).collect();
    let mut nodes = Vec::new();
    for d in &dirs {
        let addr = free_addr();
        nodes.push((
            addr,
            d.path().to_path_buf(),
            Some(Replicas::start(addr, d.path()).await),
        ));
    }
    // Each replica built its own store: byte-identical, so one terrain id.
    let mut ids = Vec::new();
    for (addr, _, _) in &nodes {
        let t = relief_client::http::get_json(&format!("http://{addr}/v1/terrain"))
            .await
            .unwrap();
        ids.push(t["id"].as_str().unwrap().to_string());
    }
    assert!(
        ids.iter().all(|i| *i == ids[0]),
        "terrain ids differ: {ids:?}"
    );
    let addrs: Vec<SocketAddr> = nodes.iter().map(|n| n.0).collect();
    let front = free_addr();
    let _lb = haproxy(front, &addrs).await;
    let mut replicas = Replicas { nodes };
    let opts = |actions: &[(f64, &str)]| ChaosOptions {
        url: format!("ws://{front}/v1/stream"),
        sessions: 200,
        poses: 300,
        actions: actions.iter().map(|(f, a)| (*f, a.to_string())).collect(),
        query_every: Some(Duration::from_millis(50)),
        reconnect_deadline: Duration::from_secs(30),
    };
    let reference = chaos::run(&opts(&[]), &mut replicas).await.unwrap();
    println!("uninterrupted: {}", chaos::summary(&reference));
    assert_eq!(
        (reference.lost, reference.desyncs, reference.reconnects),
        (0, 0, 0)
    );

    let killed = chaos::run(&opts(&[(0.4, "kill 1")]), &mut replicas)
        .await
        .unwrap();
    assert_survived("one replica of three killed", &killed, &reference);
    replicas.act("start 1").await.unwrap();

    let rolling = chaos::run(
        &opts(&[
            (0.15, "restart 0"),
            (0.45, "restart 1"),
            (0.75, "restart 2"),
        ]),
        &mut replicas,
    )
    .await
    .unwrap();
    assert_survived("rolling restart", &rolling, &reference);
}
