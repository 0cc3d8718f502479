//! Hostile input, against the real binary: a store changed under the
//! server (truncated, overwritten), a z quantum that would corrupt heights, and a foreign
//! store copied over a cache entry.

use relief_client::http::request;
use relief_tests::{ChildServer, free_addr};
use std::path::Path;
use std::process::Command;
use std::time::Duration;

const BIN: &str = env!("CARGO_BIN_EXE_relief-test-server");

async fn get_json(addr: std::net::SocketAddr, path: &str) -> serde_json::Value {
    let b = request(
        "GET",
        &format!("http://{addr}{path}"),
        "text/plain",
        Vec::new(),
    )
    .await
    .expect("GET");
    serde_json::from_slice(&b).expect("JSON")
}

async fn heights(addr: std::net::SocketAddr) -> Vec<serde_json::Value> {
    let body = br#"{"points":[[100,100],[2000,1500],[4000,3000],[6000,4000]]}"#.to_vec();
    let b = request(
        "POST",
        &format!("http://{addr}/v1/heights"),
        "application/json",
        body,
    )
    .await
    .expect("heights");
    let v: serde_json::Value = serde_json::from_slice(&b).unwrap();
    v["heights"].as_array().unwrap().clone()
}

/// Flies a few poses on a fresh session; returns its desyncs.
async fn fly(addr: std::net::SocketAddr) -> u64 {
    let url = format!("ws://{addr}/v1/stream");
    let s = relief_tests::fly(
        relief_client::session::SessionConfig::new(&url),
        &relief_tests::path(0, 10),
        None,
    )
    .await;
    s.counters().desyncs
}

fn build(dem: &str, out: &Path, extra: &[&str]) -> std::process::Output {
    Command::new(BIN)
        .args(["build", dem, "-o"])
        .arg(out)
        .args(extra)
        .arg("--quiet")
        .output()
        .expect("run build")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_store_truncated_or_overwritten_under_the_server_changes_nothing_it_serves() {
    // Truncation used to kill the server with SIGBUS; overwriting the heights made
    // /v1/heights answer 2,139,062,144 m.
    let dir = tempfile::tempdir().unwrap();
    let store = dir.path().join("fuji.relief");
    std::fs::copy(relief_tests::test_store(), &store).unwrap();
    let addr = free_addr();
    let cache = dir.path().join("cache");
    let args = [
        "--store",
        store.to_str().unwrap(),
        "--cache-dir",
        cache.to_str().unwrap(),
    ];
    let mut server = ChildServer::start_with_args(Path::new(BIN), addr, &args, &[]).await;
    let before = heights(addr).await;
    assert!(before.iter().all(|h| h.is_number()), "{before:?}");
    let len = std::fs::metadata(&store).unwrap().len();
    std::fs::OpenOptions::new()
        .write(true)
        .open(&store)
        .unwrap()
        .set_len(len / 4)
        .unwrap();
    assert_eq!(heights(addr).await, before);
    assert_eq!(fly(addr).await, 0);
    std::fs::write(&store, vec![0x7f; len as usize]).unwrap();
    assert_eq!(heights(addr).await, before);
    assert_eq!(fly(addr).await, 0);
    std::fs::remove_file(&store).unwrap();
    assert_eq!(heights(addr).await, before);
    assert!(
        server.child.try_wait().unwrap().is_none(),
        "the server died"
    );
    // The private copy has no name in the cache folder.
    let named: Vec<_> = std::fs::read_dir(&cache)
        .map(|d| d.flatten().map(|e| e.path()).collect())
        .unwrap_or_default();
    assert!(named.is_empty(), "{named:?}");
    server.signal(nix::sys::signal::Signal::SIGTERM);
    assert!(server.wait(Duration::from_secs(10)).is_some());
}

#[test]
fn a_z_quantum_that_would_corrupt_heights_is_refused_by_build() {
    // At 1e-9 every height became 2.147 m, at 1e9 0 m, silently.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("q.relief");
    for (q, needle) in [("1e-9", "24-bit"), ("1e9", "height range")] {
        let o = build("synthetic:65", &out, &["--z-quantum", q]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{q} was accepted");
        assert!(err.contains(needle), "{q}: {err}");
        assert!(!out.exists());
    }
    assert!(
        build("synthetic:65", &out, &["--z-quantum", "0.01"])
            .status
            .success()
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_foreign_store_copied_over_a_cache_entry_is_rebuilt_not_served() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache");
    let args = [
        "--dem",
        "synthetic:129:7",
        "--cache-dir",
        cache.to_str().unwrap(),
    ];
    let addr = free_addr();
    let server = ChildServer::start_with_args(Path::new(BIN), addr, &args, &[]).await;
    let id = get_json(addr, "/v1/terrain").await["id"].clone();
    drop(server);
    let entry = std::fs::read_dir(&cache)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .find(|p| p.extension().is_some_and(|x| x == "relief"))
        .expect("a cache entry");
    // A valid store of another terrain, under the entry's name.
    assert!(build("synthetic:129:8", &entry, &[]).status.success());
    let addr = free_addr();
    let _server = ChildServer::start_with_args(Path::new(BIN), addr, &args, &[]).await;
    let t = get_json(addr, "/v1/terrain").await;
    assert_eq!(t["id"], id, "{t}");
    assert_eq!(t["source"], "synthetic:129:7", "{t}");
}

/// `relief-server ARGS` with files limited to `kib` KiB (`ulimit -f`; the signal a write past
/// it raises is ignored, so the write fails with `EFBIG`, as on a full disk).
fn run_limited(kib: u64, args: &[&str]) -> std::process::Output {
    let mut script = format!("trap '' XFSZ; ulimit -f {kib}; exec \"$0\"");
    for i in 1..=args.len() {
        script.push_str(&format!(" \"${i}\""));
    }
    Command::new("bash")
        .arg("-c")
        .arg(script)
        .arg(BIN)
        .args(args)
        .env("RELIEF_LOG", "info")
        .output()
        .expect("run the server")
}

/// Files in `dir` whose name ends with `suffix`.
fn files_ending(dir: &Path, suffix: &str) -> Vec<String> {
    std::fs::read_dir(dir)
        .map(|d| {
            d.flatten()
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| n.ends_with(suffix))
                .collect()
        })
        .unwrap_or_default()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_full_disk_leaves_no_partial_file_and_no_needless_rebuild() {
    let dir = tempfile::tempdir().unwrap();
    let cache = dir.path().join("cache");
    let cache_s = cache.to_str().unwrap();
    let serve = ["serve", "--cache-dir", cache_s, "--addr", "127.0.0.1:0"];
    // A build that does not fit: it fails, says which file, and leaves nothing behind.
    let out = run_limited(64, &serve);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains(".tmp-build"),
        "the message names the file that failed: {err}"
    );
    assert_eq!(files_ending(&cache, ".tmp-build"), Vec::<String>::new());
    // Built with room, then restarted where its private copy does not fit: the server says
    // where the copy failed and leaves the valid store alone.
    let addr = free_addr();
    let a = addr.to_string();
    let server =
        ChildServer::start_with_args(Path::new(BIN), addr, &["--cache-dir", cache_s], &[]).await;
    drop(server);
    let stores = files_ending(&cache, ".relief");
    assert_eq!(stores.len(), 1, "{stores:?}");
    let store = cache.join(&stores[0]);
    let built = std::fs::metadata(&store).unwrap().modified().unwrap();
    let out = run_limited(64, &["serve", "--cache-dir", cache_s, "--addr", &a]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains("scratch folder"),
        "the message names the copy: {err}"
    );
    assert!(
        !err.contains("rebuilding"),
        "a valid store was rebuilt: {err}"
    );
    assert_eq!(
        std::fs::metadata(&store).unwrap().modified().unwrap(),
        built
    );
    assert_eq!(files_ending(&cache, ".tmp-build"), Vec::<String>::new());
}
