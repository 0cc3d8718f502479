//! The soak against the real server as a child process (the hardening issue): 500 sessions
//! cycle for three minutes (connect, fly, drop, resume, ..., close, again) while the server's RSS
//! is sampled every 5 s; over the two minutes after a 1-minute warm-up it must stay within 5 %
//! (30 s of warm-up was too short: the RSS was still settling, +1.1 MiB over the window with
//! jemalloc, spread 5.6 %), with no desyncs or
//! errors, every drop resumed, and cycles and resumes under way.
//!
//! The sessions are evenly spread along the shared loop once the ramp is over
//! (`load::loop_phase`). Before that, the ramp left a fifth of the loop empty, and the RSS rose
//! and fell by 3-5 % with the loop's period (one CI run failed at 5.02 %); with it, 2.0 %.
//!
//! Ignored in the plain test run (it takes three minutes and both cores); CI runs it:
//! `cargo test --release -p relief-tests --test e2e -- --ignored soak_`.

use relief_client::load::soak::cycle::CycleShape;
use relief_client::load::soak::{self, SoakOptions};
use relief_client::load::{LoadOptions, LoadPath};
use relief_tests::{ChildServer, free_addr};
use std::path::Path;
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_relief-test-server");

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[ignore = "a 3-minute soak of 500 sessions; CI runs it with --ignored soak_"]
async fn soak_three_minutes_of_cycling_sessions_keep_the_server_rss_flat() {
    let started = Instant::now();
    let addr = free_addr();
    let _server = ChildServer::start(Path::new(BIN), addr, &[]).await;
    let warmup = Duration::from_secs(60);
    let sessions = 500;
    let opts = SoakOptions {
        load: LoadOptions {
            url: format!("ws://{addr}/v1/stream"),
            sessions,
            duration: Duration::from_secs(180),
            ramp: SoakOptions::default_ramp(sessions, warmup),
            path: LoadPath::Standard,
            seed: 1,
            tau: 1.0,
            budget: None,
            stream: relief_proto::msg::StreamKind::Vertex,
            rate_hz: 10.0,
            mesh: false,
            progress: false,
            queries: None,
        },
        sample_every: Duration::from_secs(5),
        warmup,
        rss_tolerance: 0.05,
        shape: CycleShape::default(),
    };
    let r = soak::run_soak(&opts).await.expect("the soak runs");
    eprintln!("{}", soak::report::markdown(&r, None));
    eprintln!("test wall time {:.1} s", started.elapsed().as_secs_f64());

    let t = &r.totals;
    assert!(r.verdict.pass, "{:?}", r.verdict);
    assert_eq!((t.desyncs, t.errors, t.resumes_missed), (0, 0, 0), "{t:?}");
    assert!(t.cycles > 0 && t.resumes > 0, "{t:?}");
    let rss = r.rss.expect("RSS figures");
    assert!(rss.spread <= 0.05, "{rss:?}");
    // 5 s samples from 60 s to 180 s.
    assert!(rss.samples >= 24, "{rss:?}");
    // The server counted every resume the clients saw (and no more than they attempted).
    assert!(r.server_resumes >= t.resumes as f64, "{r:?}");
    assert!(r.server_resumes <= t.drops as f64, "{r:?}");
    // The load was real: about 10 poses a second from most sessions.
    assert!(t.poses > 300_000, "{} poses", t.poses);

    let dir = tempfile::tempdir().unwrap();
    let files = soak::report::write_report(dir.path(), &r).unwrap();
    for name in ["soak.json", "samples.csv", "rss.png", "summary.md"] {
        let p = dir.path().join(name);
        assert!(files.contains(&p), "{name} not written");
        assert!(
            std::fs::metadata(&p).unwrap().len() > 100,
            "{name} is empty"
        );
    }
    let csv = std::fs::read_to_string(dir.path().join("samples.csv")).unwrap();
    assert_eq!(csv.lines().count(), r.samples.len() + 1);
    assert!(
        started.elapsed() < Duration::from_secs(210),
        "the soak test took {:?}",
        started.elapsed()
    );
}
