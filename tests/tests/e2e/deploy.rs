//! `deploy/`: the Dockerfile under hadolint, compose.yaml under the compose
//! specification's schema, the Kubernetes base under `kubernetes-validate --strict` (each also
//! shown to refuse a broken copy, so a pass means something), the server configuration they
//! carry, and the image's root file system as a folder: the static server runs from an empty
//! root under `chroot`, as the image's user, and serves.
//!
//! `tests/setup.sh` (the README's test command) installs the validators into
//! `target/deploy-venv` (under `CARGO_TARGET_DIR` where that is set) and builds the static
//! server; without them these tests fail and say so.

use relief_server::serve::config::FileConfig;
use relief_tests::{Reaped, free_addr, repo, target_dir};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

/// A validator installed by tests/setup.sh.
fn tool(name: &str) -> PathBuf {
    let p = target_dir().join("deploy-venv/bin").join(name);
    assert!(
        p.exists(),
        "{} is missing: run `bash tests/setup.sh` (the README's test command does)",
        p.display()
    );
    p
}

/// Runs `tool args`; returns whether it passed and what it printed.
fn run(tool: &Path, args: &[&Path]) -> (bool, String) {
    let out = Command::new(tool)
        .args(args)
        .output()
        .expect("run validator");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.success(), text)
}

/// `file` with `from` replaced by `to`, written into `dir` under the same name.
fn broken(dir: &Path, file: &Path, from: &str, to: &str) -> PathBuf {
    let text = std::fs::read_to_string(file).unwrap();
    assert!(text.contains(from), "{} has no {from:?}", file.display());
    let p = dir.join(file.file_name().unwrap());
    std::fs::write(&p, text.replacen(from, to, 1)).unwrap();
    p
}

#[test]
fn the_dockerfile_passes_hadolint_and_a_broken_one_does_not() {
    let hadolint = tool("hadolint");
    let file = repo().join("deploy/Dockerfile");
    let (ok, text) = run(&hadolint, &[&file]);
    assert!(ok, "hadolint: {text}");
    let dir = tempfile::tempdir().unwrap();
    // An unpinned base image.
    let bad = broken(dir.path(), &file, "rust:1.95-bookworm", "rust:latest");
    let (ok, text) = run(&hadolint, &[&bad]);
    assert!(!ok && text.contains("DL3007"), "{text}");
}

#[test]
fn compose_matches_the_compose_specification_and_a_broken_one_does_not() {
    let check = tool("check-jsonschema");
    let file = repo().join("deploy/compose.yaml");
    let schema = Path::new("--builtin-schema");
    let spec = Path::new("vendor.compose-spec");
    let (ok, text) = run(&check, &[schema, spec, &file]);
    assert!(ok, "check-jsonschema: {text}");
    let dir = tempfile::tempdir().unwrap();
    let bad = broken(
        dir.path(),
        &file,
        "stop_grace_period:",
        "stop_grace_seconds:",
    );
    let (ok, text) = run(&check, &[schema, spec, &bad]);
    assert!(!ok, "a misspelt key passed: {text}");
}

#[test]
fn the_kubernetes_base_is_strictly_valid_and_complete() {
    let validate = tool("kubernetes-validate");
    let dir = repo().join("deploy/kubernetes");
    let kustomization = std::fs::read_to_string(dir.join("kustomization.yaml")).unwrap();
    let mut manifests: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "yaml"))
        .filter(|p| !p.ends_with("kustomization.yaml"))
        .collect();
    manifests.sort();
    assert!(manifests.len() >= 6, "{manifests:?}");
    for m in &manifests {
        let name = m.file_name().unwrap().to_str().unwrap();
        assert!(
            kustomization.contains(&format!("- {name}")),
            "kustomization.yaml does not list {name}"
        );
        let strict = Path::new("--strict");
        let (ok, text) = run(&validate, &[strict, m]);
        assert!(ok && text.contains("passed"), "{name}: {text}");
    }
    // Kinds a deployment needs.
    let all: String = manifests
        .iter()
        .map(|m| std::fs::read_to_string(m).unwrap())
        .collect();
    for kind in [
        "kind: Deployment",
        "kind: Service",
        "kind: PodDisruptionBudget",
        "kind: HorizontalPodAutoscaler",
        "kind: ConfigMap",
        "kind: Ingress",
        "readinessProbe",
        "livenessProbe",
        "preStop",
        "terminationGracePeriodSeconds",
        "initContainers",
    ] {
        assert!(all.contains(kind), "the base has no {kind}");
    }
    // An unknown field is refused under --strict.
    let tmp = tempfile::tempdir().unwrap();
    let bad = broken(
        tmp.path(),
        &dir.join("deployment.yaml"),
        "terminationGracePeriodSeconds:",
        "terminationGraceSeconds:",
    );
    let (ok, text) = run(&validate, &[Path::new("--strict"), &bad]);
    assert!(!ok, "an unknown field passed: {text}");
}

/// The TOML of the ConfigMap's `relief.toml` key.
fn configmap_toml() -> String {
    let text = std::fs::read_to_string(repo().join("deploy/kubernetes/configmap.yaml")).unwrap();
    let start = text.find("relief.toml: |").expect("relief.toml key") + "relief.toml: |".len();
    text[start..]
        .lines()
        .skip(1)
        .map(|l| l.strip_prefix("    ").unwrap_or(l))
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn the_deployments_configuration_is_the_servers_and_agrees_between_them() {
    let compose: FileConfig =
        toml::from_str(&std::fs::read_to_string(repo().join("deploy/relief.toml")).unwrap())
            .expect("deploy/relief.toml is a server configuration");
    let k8s: FileConfig =
        toml::from_str(&configmap_toml()).expect("the ConfigMap holds a server configuration");
    assert_eq!(format!("{compose:?}"), format!("{k8s:?}"));
    // The grace periods cover the drain.
    let drain = compose.drain_timeout_s.expect("drain_timeout_s set");
    let deployment =
        std::fs::read_to_string(repo().join("deploy/kubernetes/deployment.yaml")).unwrap();
    let grace: f64 = deployment
        .lines()
        .find_map(|l| l.trim().strip_prefix("terminationGracePeriodSeconds:"))
        .unwrap()
        .trim()
        .parse()
        .unwrap();
    assert!(grace > drain + 3.0, "grace {grace} s, drain {drain} s");
}

/// The static server tests/setup.sh builds.
fn static_server() -> PathBuf {
    let p = target_dir().join("x86_64-unknown-linux-musl/dist/relief-server");
    assert!(
        p.exists(),
        "{} is missing: run `bash tests/setup.sh` (the README's test command does)",
        p.display()
    );
    p
}

/// Whether the ELF file at `p` asks for a dynamic loader (has a PT_INTERP program header).
fn has_interpreter(p: &Path) -> bool {
    let b = std::fs::read(p).unwrap();
    assert_eq!(&b[..4], b"\x7fELF");
    assert_eq!(b[4], 2, "64-bit ELF");
    let u64_at = |o: usize| u64::from_le_bytes(b[o..o + 8].try_into().unwrap()) as usize;
    let u16_at = |o: usize| u16::from_le_bytes(b[o..o + 2].try_into().unwrap()) as usize;
    let (phoff, phentsize, phnum) = (u64_at(0x20), u16_at(0x36), u16_at(0x38));
    (0..phnum).any(|i| {
        let h = phoff + i * phentsize;
        u32::from_le_bytes(b[h..h + 4].try_into().unwrap()) == 3
    })
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_static_server_serves_from_an_empty_root() {
    let bin = static_server();
    let size = std::fs::metadata(&bin).unwrap().len();
    println!("static relief-server: {size} bytes");
    assert!(size < 30 << 20, "{size} bytes: the image's limit is 30 MB");
    assert!(!has_interpreter(&bin), "the server is not static");
    assert!(
        nix::unistd::geteuid().is_root(),
        "chroot needs root: run the tests as root, as CI does"
    );
    // The image's root file system, as deploy/Dockerfile lays it out.
    let root = tempfile::tempdir().unwrap();
    let r = root.path();
    std::fs::copy(&bin, r.join("relief-server")).unwrap();
    for d in ["srv", "var/cache/relief", "tmp"] {
        std::fs::create_dir_all(r.join(d)).unwrap();
    }
    let chroot = |user: &str| {
        let mut c = Command::new("chroot");
        c.arg(format!("--userspec={user}"))
            .arg(r)
            .arg("/relief-server");
        c
    };
    let built = chroot("0:0")
        .args([
            "build",
            "embedded",
            "--output",
            "/srv/terrain.relief",
            "--quiet",
        ])
        .status()
        .unwrap();
    assert!(built.success());
    for d in ["var/cache/relief", "tmp"] {
        nix::unistd::chown(
            &r.join(d),
            Some(nix::unistd::Uid::from_raw(10001)),
            Some(nix::unistd::Gid::from_raw(10001)),
        )
        .unwrap();
    }
    let addr = free_addr();
    let mut child = Reaped(
        chroot("10001:10001")
            .arg("serve")
            .env_clear()
            .env("PATH", "/usr/sbin:/usr/bin:/sbin:/bin")
            .env("RELIEF_ADDR", addr.to_string())
            .env("RELIEF_STORE", "/srv/terrain.relief")
            .env("RELIEF_CACHE_DIR", "/var/cache/relief")
            .env("RELIEF_LOG", "warn")
            .spawn()
            .unwrap(),
    );
    let base = format!("http://{addr}");
    let deadline = Instant::now() + Duration::from_secs(30);
    while relief_client::http::request("GET", &format!("{base}/readyz"), "text/plain", vec![])
        .await
        .is_err()
    {
        assert!(
            Instant::now() < deadline,
            "the chrooted server never became ready"
        );
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let t = relief_client::http::get_json(&format!("{base}/v1/terrain"))
        .await
        .unwrap();
    assert_eq!(t["width"], 257);
    let q = relief_client::http::post_json(
        &format!("{base}/v1/query"),
        &serde_json::json!({"queries": [{"hat": {"at": [1000.0, 1000.0, 3000.0]}}]}),
    )
    .await
    .unwrap();
    assert!(
        q["answers"][0]["hat"]["hot"].as_f64().unwrap() > 500.0,
        "{q}"
    );
    // The image's HEALTHCHECK, from inside the root.
    let health = chroot("10001:10001")
        .args(["health", "--url", &format!("{base}/healthz")])
        .status()
        .unwrap();
    assert!(health.success());
    let pid = nix::unistd::Pid::from_raw(child.id() as i32);
    nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGTERM).unwrap();
    let status = child.wait().unwrap();
    assert!(status.success(), "{status:?}");
    // Once it is gone, the health check says so.
    let health_down = Command::new(&bin)
        .args([
            "health",
            "--url",
            &format!("{base}/healthz"),
            "--timeout",
            "1",
        ])
        .status()
        .unwrap();
    assert!(!health_down.success());
}

#[test]
fn the_capacity_model_covers_every_committed_sweep() {
    let out = Command::new("python3")
        .arg(repo().join("deploy/capacity.py"))
        .args(["--sessions", "100000"])
        .output()
        .expect("python3 (tests/setup.sh installs python3-venv, which brings it)");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    println!("{text}");
    let rows: Vec<&str> = text
        .lines()
        .filter(|l| l.starts_with("| ") && !l.starts_with("| workload"))
        .collect();
    for sweep in ["crop", "synthetic4097", "tiles-fuji", "tiles-synthetic4097"] {
        assert!(
            rows.iter().any(|r| r.starts_with(&format!("| {sweep}:"))),
            "no row for {sweep}: {text}"
        );
    }
    // Bad assumptions are refused.
    let bad = Command::new("python3")
        .arg(repo().join("deploy/capacity.py"))
        .args(["--cores", "0"])
        .output()
        .unwrap();
    assert!(!bad.status.success());
}
