//! Helpers for Relief's end-to-end tests (the tests themselves are in `tests/`): a store built
//! from the committed Fuji crop, the real server started in process or as a child process on
//! 127.0.0.1, camera paths over the terrain, and raw protocol frames.
//!
//! - [`raw`]: raw sockets for the hostile-input tests.
//! - [`bystander`]: a session that flies on during an attack and records its latency.
//! - [`http`]: plain HTTP/1.1 GETs over a socket, status and headers as sent.
//! - [`shots`]: screenshots, not blank and against golden images.

pub mod bystander;
pub mod http;
pub mod raw;
pub mod shots;

use relief_proto::codec;
use relief_proto::msg::{ClientMsg, Hello, PROTOCOL_VERSION, StreamKind};
use relief_proto::path::{PathKind, camera_path};
use relief_proto::view::{Camera, Lens};
use relief_server::serve::config::{Limits, ServeConfig, TerrainSource};
use relief_server::serve::state::AppState;
use relief_server::serve::{ServeError, Server};
use relief_server::store::Store;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

/// The repository's root.
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Cargo's target directory: `CARGO_TARGET_DIR` where it is set (CI keeps one outside the
/// clone; a relative one is taken from the repository's root), `target/` of the repository
/// otherwise.
pub fn target_dir() -> PathBuf {
    match std::env::var_os("CARGO_TARGET_DIR") {
        Some(d) => repo().join(d),
        None => repo().join("target"),
    }
}

/// The store of the embedded crop, built once per test binary.
pub fn test_store() -> &'static Path {
    static STORE: OnceLock<(tempfile::TempDir, PathBuf)> = OnceLock::new();
    let (_, p) = STORE.get_or_init(|| {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = dir.path().join("fuji.relief");
        let d = relief_server::dem::embedded_default().expect("embedded DEM");
        relief_server::preprocess::build_store(&d, &path, &Default::default()).expect("store");
        (dir, path)
    });
    p
}

/// A server configuration for tests: the test store on a free loopback port.
pub fn config(limits: Limits) -> ServeConfig {
    ServeConfig {
        source: TerrainSource::Store(test_store().to_path_buf()),
        addr: "127.0.0.1:0".parse().expect("address"),
        cache_dir: std::env::temp_dir().join("relief-test-cache"),
        limits,
        web_lib: relief_server::serve::config::DEFAULT_WEB_LIB.into(),
        public_url: None,
    }
}

/// The real server, running in this process.
pub struct TestServer {
    /// Where it listens.
    pub addr: SocketAddr,
    /// Its state, to look inside.
    pub state: Arc<AppState>,
    /// Completes the shutdown future.
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    /// The serving task.
    task: tokio::task::JoinHandle<Result<(), ServeError>>,
}

impl TestServer {
    /// Starts a server with `limits` and waits until it is ready.
    pub async fn start(limits: Limits) -> TestServer {
        Self::start_with(config(limits)).await
    }

    /// Starts a server with `config` and waits until it is ready.
    pub async fn start_with(config: ServeConfig) -> TestServer {
        let server = Server::bind(config).await.expect("bind");
        let addr = server.local_addr();
        let state = server.state();
        let (tx, rx) = tokio::sync::oneshot::channel();
        let task = tokio::spawn(server.run(async {
            let _ = rx.await;
        }));
        let deadline = Instant::now() + Duration::from_secs(30);
        while state.terrain().is_none() {
            assert!(Instant::now() < deadline, "server not ready");
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        TestServer {
            addr,
            state,
            stop: Some(tx),
            task,
        }
    }

    /// The stream URL.
    pub fn url(&self) -> String {
        format!("ws://{}/v1/stream", self.addr)
    }

    /// The HTTP base URL.
    pub fn http(&self) -> String {
        format!("http://{}", self.addr)
    }

    /// Shuts down (drain included) and returns how long it took.
    pub async fn stop(mut self) -> Duration {
        let t = Instant::now();
        if let Some(s) = self.stop.take() {
            let _ = s.send(());
        }
        let _ = (&mut self.task).await;
        t.elapsed()
    }
}

/// A child process that is killed and reaped when dropped, a failed assertion's unwinding
/// included: a process left running would hold the test harness's output pipe open, and the
/// run that reads it would wait for it forever.
pub struct Reaped(pub std::process::Child);

impl Drop for Reaped {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

impl std::ops::Deref for Reaped {
    type Target = std::process::Child;
    fn deref(&self) -> &std::process::Child {
        &self.0
    }
}

impl std::ops::DerefMut for Reaped {
    fn deref_mut(&mut self) -> &mut std::process::Child {
        &mut self.0
    }
}

/// The server as a child process (the `relief-test-server` binary, which is `relief-server`).
pub struct ChildServer {
    /// The process.
    pub child: Reaped,
    /// Where it listens.
    pub addr: SocketAddr,
}

impl ChildServer {
    /// Starts `relief-server serve` on `addr` with extra arguments and waits for `/readyz`.
    pub async fn start(bin: &Path, addr: SocketAddr, extra: &[&str]) -> ChildServer {
        Self::start_env(bin, addr, extra, &[]).await
    }

    /// As [`ChildServer::start`], with extra environment variables.
    pub async fn start_env(
        bin: &Path,
        addr: SocketAddr,
        extra: &[&str],
        envs: &[(&str, &str)],
    ) -> ChildServer {
        let store = test_store().display().to_string();
        let mut args = vec!["--store", store.as_str()];
        args.extend_from_slice(extra);
        Self::start_with_args(bin, addr, &args, envs).await
    }

    /// `relief-server serve --addr ADDR` with `args` (which name the terrain) and extra
    /// environment variables; waits for `/readyz`.
    pub async fn start_with_args(
        bin: &Path,
        addr: SocketAddr,
        args: &[&str],
        envs: &[(&str, &str)],
    ) -> ChildServer {
        let child = std::process::Command::new(bin)
            .arg("serve")
            .arg("--addr")
            .arg(addr.to_string())
            .args(args)
            .env("RELIEF_LOG", "warn")
            .envs(envs.iter().copied())
            .spawn()
            .expect("spawn server");
        let s = ChildServer {
            child: Reaped(child),
            addr,
        };
        let deadline = Instant::now() + Duration::from_secs(30);
        loop {
            let ok = relief_client::http::request(
                "GET",
                &format!("http://{addr}/readyz"),
                "text/plain",
                Vec::new(),
            )
            .await
            .is_ok();
            if ok {
                return s;
            }
            assert!(Instant::now() < deadline, "child server not ready");
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    }

    /// Sends `signal` (e.g. `SIGTERM`, `SIGKILL`) to the process.
    pub fn signal(&self, signal: nix::sys::signal::Signal) {
        let pid = nix::unistd::Pid::from_raw(self.child.id() as i32);
        nix::sys::signal::kill(pid, signal).expect("signal the server");
    }

    /// Waits for the process to exit, up to `limit`; returns how long it took, or `None`.
    pub fn wait(&mut self, limit: Duration) -> Option<Duration> {
        let t = Instant::now();
        while t.elapsed() < limit {
            if let Ok(Some(_)) = self.child.try_wait() {
                return Some(t.elapsed());
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        None
    }
}

/// A free loopback address (bound and released; good enough for a test restart).
pub fn free_addr() -> SocketAddr {
    let l = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
    l.local_addr().expect("address")
}

/// Camera paths over the test terrain: path `i` of many, alternating the standard and stress
/// loops, each starting at a different phase, `len` poses long.
pub fn path(i: usize, len: usize) -> Vec<Camera> {
    let store = Store::open(test_store()).expect("store");
    let g = store.geometry();
    let (w, h) = (g.shape.width(), g.shape.height());
    let ground = |x: f32, y: f32| {
        let (c, r) = g.frame.to_grid(x, y);
        let c = (c.round().max(0.0) as u32).min(w - 1);
        let r = (r.round().max(0.0) as u32).min(h - 1);
        store.sample_z(c, r) as f32 * g.z_quantum
    };
    let kind = if i.is_multiple_of(2) {
        PathKind::Standard
    } else {
        PathKind::Stress
    };
    let ex = (w - 1) as f32 * g.frame.dx;
    let ey = (h - 1) as f32 * g.frame.dy;
    let cams = camera_path(kind, ex, ey, ground);
    let start = (i * 37) % cams.len();
    (0..len).map(|k| cams[(start + k) % cams.len()]).collect()
}

/// A hello frame with the standard lens, tau 1 and no budget.
pub fn hello_frame(version: u32) -> Vec<u8> {
    codec::encode(&ClientMsg::Hello(Hello {
        version,
        kind: StreamKind::Vertex,
        lens: Lens::STANDARD.into(),
        tau: 1.0,
        budget: None,
        resume: None,
    }))
}

/// A query session's hello (`StreamKind::Query`).
pub fn query_hello() -> Vec<u8> {
    codec::encode(&ClientMsg::Hello(Hello {
        version: PROTOCOL_VERSION,
        kind: StreamKind::Query,
        lens: Lens::STANDARD.into(),
        tau: 1.0,
        budget: None,
        resume: None,
    }))
}

/// A query-session message: batch `id` of 40,000 HAT queries over the test terrain (about
/// 1 MiB; its answer about 1.2 MB).
pub fn hat_batch(id: u64) -> Vec<u8> {
    codec::encode(&ClientMsg::Query(relief_proto::query::QueryBatch {
        id,
        queries: (0..40_000)
            .map(|i| relief_proto::query::Query::Hat {
                at: [(i % 250) as f64 * 40.0, (i / 250) as f64 * 40.0, 3000.0],
            })
            .collect(),
    }))
}

/// The current protocol's hello.
pub fn hello() -> Vec<u8> {
    hello_frame(PROTOCOL_VERSION)
}

/// Flies `cams` lock-step (each pose answered before the next) in a session opened with
/// `config`, dropping the connection just before pose `drop_at`; returns the session.
pub async fn fly(
    config: relief_client::session::SessionConfig,
    cams: &[Camera],
    drop_at: Option<usize>,
) -> relief_client::session::Session {
    let mut s = relief_client::session::Session::connect(config)
        .await
        .expect("connect");
    for (i, cam) in cams.iter().enumerate() {
        if drop_at == Some(i) {
            s.drop_connection();
        }
        let seq = s.send_pose(*cam).await.expect("pose");
        s.wait_for_pose(seq).await.expect("delta");
    }
    s
}

/// The crack tests' three views of a path camera: as it is, looking down 80 degrees (the
/// terrain fills the frame) and grazing 3 degrees down (cracks open widest).
pub fn crack_views(cam: Camera) -> [Camera; 3] {
    let tilt = |deg: f32| Camera {
        pitch: (-deg).to_radians(),
        ..cam
    };
    [cam, tilt(80.0), tilt(3.0)]
}

/// Runs `node web/tests/<script> <url> <args>` (a browser test script) and returns the JSON
/// line it prints last; fails with the script's error, the page's console and stderr when it
/// did not succeed.
pub async fn node_json(script: &str, url: &str, args: &[&str]) -> serde_json::Value {
    let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../web/tests")).join(script);
    let mut cmd = std::process::Command::new("node");
    cmd.arg(&path).arg(url).args(args);
    let started = Instant::now();
    let out = tokio::task::spawn_blocking(move || cmd.output())
        .await
        .expect("the node task")
        .unwrap_or_else(|e| panic!("cannot run node {}: {e}", path.display()));
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    let line = stdout.lines().last().unwrap_or("");
    let v: serde_json::Value = serde_json::from_str(line).unwrap_or_else(|e| {
        panic!(
            "{script} printed no JSON result ({e}; exit {:?}).\nstdout: {stdout}\nstderr: {stderr}",
            out.status.code()
        )
    });
    assert!(
        v["ok"] == true,
        "{script} failed: {}\nconsole: {}\nstderr: {stderr}",
        v["error"],
        v["console"]
    );
    println!("{script}: {:.1} s", started.elapsed().as_secs_f64());
    v
}

/// A server of the embedded crop built with `tile_size`-cell tiles meshed as `mesh`, and the
/// folder its store lives in (keep it while the server runs).
pub async fn serve_tiles_of(
    tile_size: u32,
    mesh: relief_proto::tile::body::MeshKind,
) -> (tempfile::TempDir, TestServer) {
    let dir = tempfile::tempdir().expect("temp dir");
    let store = dir.path().join("crop.relief");
    let dem = relief_server::dem::embedded_default().expect("embedded DEM");
    let opts = relief_server::preprocess::BuildOptions {
        tile_size,
        tile_mesh: mesh,
        ..Default::default()
    };
    relief_server::preprocess::build_store(&dem, &store, &opts).expect("store");
    let server = TestServer::start_with(ServeConfig {
        source: TerrainSource::Store(store),
        addr: "127.0.0.1:0".parse().expect("address"),
        cache_dir: dir.path().join("cache"),
        limits: Limits::default(),
        web_lib: relief_server::serve::config::DEFAULT_WEB_LIB.into(),
        public_url: None,
    })
    .await;
    (dir, server)
}
