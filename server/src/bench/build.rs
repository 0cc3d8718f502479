//! `relief-server bench build`: how fast a store is built, on how many threads, in how much
//! memory.
//!
//! One build per run, in this process, on a pool of `--threads` threads (every parallel step of
//! the build runs on rayon's pool; the pool is made with that many threads before anything is
//! read): the input read (or generated) and its voids filled, then the store built and written
//! to a temporary folder (or `--output`). Reported:
//! - wall seconds of each phase and in all, and the CPU seconds of the process (user and
//!   system), so that the cores really used show beside the cores offered;
//! - samples a second in all (over the whole run, reading included) and per thread;
//! - peak resident memory (the process's high-water mark, `getrusage`), in bytes and bytes a
//!   sample;
//! - the store's bytes and bytes a sample;
//! - for file and URL inputs, the bytes read from the source against its size.
//!
//! Figures of a single run; pair runs with `--threads 1` and `--threads 2` for the speed-up.

use crate::dem::DemArgs;
use crate::preprocess::{BuildOptions, build_store};
use serde::Serialize;
use std::path::PathBuf;
use std::time::Instant;

/// What to build, and how.
pub struct BuildBenchOptions {
    /// The input specs (as `build` takes them).
    pub inputs: Vec<String>,
    /// How to read them.
    pub dem: DemArgs,
    /// The store's quantum, tile size, mesh kind.
    pub build: BuildOptions,
    /// Threads of the pool (`None`: one per core).
    pub threads: Option<usize>,
    /// Where to write the store; `None`: a temporary folder, removed after.
    pub output: Option<PathBuf>,
}

/// The figures of one build.
#[derive(Clone, Debug, Serialize)]
pub struct BuildBenchReport {
    /// The input, as given.
    pub input: String,
    /// Grid width, samples.
    pub width: u32,
    /// Grid height, samples.
    pub height: u32,
    /// `width * height`.
    pub samples: u64,
    /// Threads of the pool the build ran on.
    pub threads: usize,
    /// The mesh kind of the tile pyramid.
    pub tile_mesh: String,
    /// Seconds reading (or generating) the input, with void filling.
    pub read_s: f64,
    /// Seconds building the vertex tree.
    pub tree_s: f64,
    /// Seconds building the tile pyramid.
    pub tiles_s: f64,
    /// Seconds of the rest of the build: checks, node records, writing and syncing the file.
    pub write_s: f64,
    /// Seconds in all.
    pub total_s: f64,
    /// CPU seconds of the process over the run, user and system.
    pub cpu_s: f64,
    /// `cpu_s / total_s`: the cores in use on average.
    pub cores_used: f64,
    /// Samples a second over the whole run.
    pub samples_per_s: f64,
    /// `samples_per_s / threads`.
    pub samples_per_s_per_thread: f64,
    /// Samples a second of the build alone (reading excluded).
    pub build_samples_per_s: f64,
    /// The process's peak resident memory, bytes.
    pub peak_rss_bytes: u64,
    /// `peak_rss_bytes / samples`.
    pub peak_rss_bytes_per_sample: f64,
    /// Size of the store, bytes.
    pub store_bytes: u64,
    /// `store_bytes / samples`.
    pub store_bytes_per_sample: f64,
    /// Bytes read from the input files or URLs (0 for synthetic input): a file's bytes each
    /// time they are read (the decoder reads a TIFF's directory more than once), a URL's as
    /// fetched (its blocks are cached).
    pub source_bytes_read: u64,
    /// Their size, bytes.
    pub source_bytes: u64,
}

/// CPU seconds (user and system) and peak resident bytes of this process so far.
fn usage() -> (f64, u64) {
    use nix::sys::resource::{UsageWho, getrusage};
    match getrusage(UsageWho::RUSAGE_SELF) {
        Ok(u) => {
            let secs = |t: nix::sys::time::TimeVal| t.tv_sec() as f64 + t.tv_usec() as f64 * 1e-6;
            // Linux reports the high-water mark in KiB.
            let rss = u64::try_from(u.max_rss()).unwrap_or(0) * 1024;
            (secs(u.user_time()) + secs(u.system_time()), rss)
        }
        Err(_) => (0.0, 0),
    }
}

/// Builds once and measures it.
pub fn run(opts: &BuildBenchOptions) -> anyhow::Result<BuildBenchReport> {
    use anyhow::Context;
    let pool = crate::preprocess::thread_pool(opts.threads).map_err(anyhow::Error::msg)?;
    let threads = pool.current_num_threads();
    let dir = tempfile::tempdir().context("cannot make a temporary folder for the store")?;
    let path = opts
        .output
        .clone()
        .unwrap_or_else(|| dir.path().join("bench.relief"));
    let (cpu0, _) = usage();
    let t0 = Instant::now();
    let (dem, read_s, rep) = pool.install(|| -> anyhow::Result<_> {
        let dem = opts.dem.load(&opts.inputs).context("cannot load the DEM")?;
        let read_s = t0.elapsed().as_secs_f64();
        let rep = build_store(&dem, &path, &opts.build).context("cannot build the store")?;
        Ok((dem, read_s, rep))
    })?;
    let total_s = t0.elapsed().as_secs_f64();
    let (cpu1, peak_rss_bytes) = usage();
    let samples = u64::from(dem.width) * u64::from(dem.height);
    let n = samples as f64;
    let build_s = total_s - read_s;
    let cpu_s = cpu1 - cpu0;
    let samples_per_s = n / total_s.max(1e-9);
    Ok(BuildBenchReport {
        input: opts.inputs.join(" "),
        width: dem.width,
        height: dem.height,
        samples,
        threads,
        tile_mesh: opts.build.tile_mesh.name().to_string(),
        read_s,
        tree_s: rep.tree_s,
        tiles_s: rep.tiles_s,
        write_s: (build_s - rep.tree_s - rep.tiles_s).max(0.0),
        total_s,
        cpu_s,
        cores_used: cpu_s / total_s.max(1e-9),
        samples_per_s,
        samples_per_s_per_thread: samples_per_s / threads as f64,
        build_samples_per_s: n / build_s.max(1e-9),
        peak_rss_bytes,
        peak_rss_bytes_per_sample: peak_rss_bytes as f64 / n,
        store_bytes: rep.bytes,
        store_bytes_per_sample: rep.bytes as f64 / n,
        source_bytes_read: dem.io.bytes_read,
        source_bytes: dem.io.source_bytes,
    })
}

/// The report as a table.
pub fn print(r: &BuildBenchReport) {
    let m = |v: f64| v / 1e6;
    println!(
        "build of {} ({} x {} = {:.1} M samples, {} tiles) on {} thread(s)",
        r.input,
        r.width,
        r.height,
        m(r.samples as f64),
        r.tile_mesh,
        r.threads
    );
    println!("| phase | seconds |");
    println!("|---|---|");
    for (what, s) in [
        ("read (and fill voids)", r.read_s),
        ("vertex tree", r.tree_s),
        ("tile pyramid", r.tiles_s),
        ("records, write, sync", r.write_s),
        ("all", r.total_s),
    ] {
        println!("| {what} | {s:.2} |");
    }
    println!(
        "{:.2} M samples/s in all, {:.2} M per thread ({:.2} M/s building alone); {:.2} CPU s, {:.2} cores used",
        m(r.samples_per_s),
        m(r.samples_per_s_per_thread),
        m(r.build_samples_per_s),
        r.cpu_s,
        r.cores_used
    );
    println!(
        "peak resident {:.1} MiB ({:.1} bytes a sample); store {:.1} MiB ({:.2} bytes a sample)",
        r.peak_rss_bytes as f64 / 1048576.0,
        r.peak_rss_bytes_per_sample,
        r.store_bytes as f64 / 1048576.0,
        r.store_bytes_per_sample
    );
    if r.source_bytes > 0 {
        println!(
            "read {} of the source's {} bytes ({:.1} %)",
            r.source_bytes_read,
            r.source_bytes,
            100.0 * r.source_bytes_read as f64 / r.source_bytes as f64
        );
    }
}
