//! The `relief-server` command line: `serve`, `build`, `info` and `bench`. It lives in the
//! library so that the binary stays a one-liner and end-to-end tests can run the same program
//! as a child process.

use crate::bench::lod::{self, LodBenchOptions};
use crate::dem::DemArgs;
use crate::lod::tile::mesh::fractal::FractalParams;

use crate::lod::vertex::LodParams;
use crate::preprocess;
use anyhow::Context;
use clap::{Parser, Subcommand};
use relief_proto::path::PathKind;
use std::path::PathBuf;

mod health;
mod info;
mod store_args;

#[derive(Parser)]
#[command(
    name = "relief-server",
    version,
    about = "Relief terrain LOD streaming server"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Serve a terrain: WebSocket sessions on /v1/stream (vertex, tiles or queries), HTTP on
    /// /v1/terrain, /v1/lod, /v1/heights, /v1/query, /v1/raycast.png, /v1/sessions, /metrics,
    /// /healthz and /readyz, the standard formats under /cesium and /tiles, and the pages. With
    /// no options it serves the
    /// embedded terrain on 127.0.0.1:8080. Stops on SIGTERM or Ctrl-C after draining.
    Serve(Box<crate::serve::ServeArgs>),
    /// Preprocess a DEM into a store (the vertex quadtree, memory-mapped by the server).
    Build {
        /// The DEM: a GeoTIFF (int16, uint16, int32, float32, float64; striped, tiled or
        /// Cloud-Optimized, read tile by tile; deflate, LZW or zstd, predictors 2 and 3), an
        /// `http://` or `https://` URL of one (read by HTTP range requests, fetching only its
        /// directory and tiles: S3, GCS, MinIO and nginx serve them), a 16-bit grayscale PNG,
        /// an SRTM `.hgt` file (1" or 3", placed by its name, e.g. N35E138.hgt), a terrain-RGB
        /// or Terrarium PNG tile (with --encoding), or `synthetic:SIZE[:SEED]` for a
        /// deterministic fractal terrain. Several files make one mosaic, e.g. `N35E138.hgt
        /// N35E139.hgt` or `tiles/12/*/*.png`, and a folder stands for the .tif and .tiff files
        /// in it (a folder of COGs as one mosaic, as GDAL's VRTs are used): they must share a
        /// CRS and grid step and lie on one grid; the store covers the box around them,
        /// samples none covers are voids (filled like the others), and where files overlap
        /// (neighbouring .hgt files share an edge row or column) the later file's heights win,
        /// except its voids. `embedded` is the terrain `serve` uses by default (a Mt Fuji crop
        /// built into the binary).
        #[arg(required = true, num_args = 1.., value_name = "INPUT")]
        inputs: Vec<String>,
        /// Where to write the store.
        #[arg(short, long)]
        output: PathBuf,
        #[command(flatten)]
        store: store_args::StoreArgs,
        #[command(flatten)]
        dem: DemArgs,
    },
    /// Check a store completely (header, sizes, checksums) and print what it holds, as JSON.
    /// With --fractal, also paper 002's fractal region tree over the store's heights.
    #[command(after_help = INFO_HELP)]
    Info {
        /// The store file.
        store: PathBuf,
        /// Also build paper 002's region tree (section 2.1) over the store's heights and tile
        /// pyramid, and print it under the key "fractal": every leaf (tile level, x, y, sample
        /// columns and rows, box-counting dimension, why it stopped) and a summary (leaves per
        /// level, by stop, a histogram of dimensions in bins 0.01 wide).
        #[arg(long)]
        fractal: bool,
        /// With --fractal: the dimension at or below which a region stops subdividing, whatever
        /// its size (from 2 to 3; at most --rough).
        #[arg(long, requires = "fractal", value_name = "D",
              default_value_t = FractalParams::default().flat,
              value_parser = info::dimension_arg, allow_negative_numbers = true)]
        flat: f32,
        /// With --fractal: the dimension at or above which a region subdivides down to the
        /// finest tiles (from 2 to 3). In between, the largest leaf shrinks log-linearly by
        /// pyramid level. Paper 002 calls about 2.0 flat and about 2.3 rough; real DEMs
        /// measure 2.00 to 2.09 here (docs/fractal.md).
        #[arg(long, requires = "fractal", value_name = "D",
              default_value_t = FractalParams::default().rough,
              value_parser = info::dimension_arg, allow_negative_numbers = true)]
        rough: f32,
    },
    /// Ask a running server whether it is healthy: GET the URL and exit 0 on 200, 1 on anything
    /// else (a container's HEALTHCHECK: the image has no curl).
    Health {
        /// What to ask.
        #[arg(long, default_value = "http://127.0.0.1:8080/healthz")]
        url: String,
        /// Seconds to wait for the answer.
        #[arg(long, default_value_t = 3.0)]
        timeout: f64,
    },
    /// Benchmarks.
    Bench {
        #[command(subcommand)]
        which: BenchCommand,
    },
}

/// The end of `info --help`.
const INFO_HELP: &str = "\
With --fractal, each leaf's \"stop\" says why it is a leaf: \"flat\" (dimension at or below --flat), \
\"sized\" (between the thresholds, and no larger than its dimension allows), \"finest\" (rough \
enough to split further, but a finest-level tile) or \"no_dimension\" (under 16 cells across). \
The heights are the store's, rounded to its z quantum. Thresholds, the box counting and what the \
tree is good for: docs/fractal.md. Example:
  relief-server info terrain.relief --fractal --rough 2.3 | jq '.fractal.per_level'";

#[derive(Subcommand)]
enum BenchCommand {
    /// Build a store once, in this process, and report how fast and in how much memory:
    /// seconds by phase, samples a second in all and per thread, the cores really used, peak
    /// resident memory, store bytes a sample, and for file and URL inputs the bytes read
    /// against the source's size. Pair `--threads 1` with `--threads 2` for the speed-up.
    Build {
        /// The DEM (same forms as `build`'s inputs).
        #[arg(long, required = true, num_args = 1..)]
        dem: Vec<String>,
        #[command(flatten)]
        store: store_args::StoreArgs,
        /// Keep the store at this path [default: a temporary folder, removed after].
        #[arg(long)]
        output: Option<PathBuf>,
        /// Print one JSON object instead of a table.
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        dem_args: DemArgs,
    },
    /// Fly a camera path through the vertex stream in process and report its figures.
    Lod {
        #[command(flatten)]
        run: BenchArgs,
    },
    /// Fly a camera path through the tile stream in process and report its figures: pixel
    /// error, triangles, bytes, update cost, patches against skirts, restriction, pops.
    Tiles {
        #[command(flatten)]
        run: BenchArgs,
        /// What tiles carry against cracks: `patches` (paper 001), `skirts` (the baseline) or
        /// `none`.
        #[arg(long, default_value = "patches")]
        crack: Crack,
        /// Cells per tile side (a power of two from 2 to 256).
        #[arg(long, default_value_t = crate::store::DEFAULT_TILE_SIZE)]
        tile_size: u32,
        /// The tiles' mesh kind (as `build --tile-mesh`).
        #[arg(long, value_enum, default_value = "grid")]
        tile_mesh: TileMeshArg,
    },
    /// Fly the path once per stream (vertex; tiles grid+skirts, grid+patches, rqt+skirts,
    /// rqt+patches, tin+shared-borders), each tuned until its measured p99 pixel error is within 5 % of the
    /// target, and compare bytes (raw and gzipped), triangles and costs. Prints Markdown, or
    /// JSON with --json; --plot writes bytes against measured error as SVG.
    Compare {
        #[command(flatten)]
        run: BenchArgs,
        /// Measured p99 pixel error every stream is tuned to (--tau is not used: each stream's
        /// tuning starts at tau = this target).
        #[arg(long, default_value_t = 1.0)]
        target_px: f64,
        /// How close the measured p99 must come, as a fraction of the target.
        #[arg(long, default_value_t = 0.05)]
        within: f64,
        /// The curve's other error levels, as multiples of the target.
        #[arg(long, value_delimiter = ',', default_value = "0.5,2")]
        levels: Vec<f64>,
        /// Flights per stream and level at most.
        #[arg(long, default_value_t = 10)]
        tries: usize,
        /// Cells per tile side (a power of two from 2 to 256).
        #[arg(long, default_value_t = crate::store::DEFAULT_TILE_SIZE)]
        tile_size: u32,
        /// Compare only these streams (comma-separated names, e.g. vertex,tiles/grid+skirts).
        #[arg(long, value_delimiter = ',')]
        only: Option<Vec<String>>,
        /// Write the bytes-against-error plot here (SVG).
        #[arg(long)]
        plot: Option<PathBuf>,
    },
    /// Make the standard formats' tiles over a whole terrain, as `serve` makes them on request
    /// (Cesium quantized-mesh with grid, rqt and tin meshes, with normals and metadata;
    /// terrain-RGB and Terrarium PNGs), and report bytes (raw and gzipped, mean and p99),
    /// triangles and the time to make each tile (median and p99, one thread).
    Formats {
        /// The DEM (same forms as `build`'s inputs); it needs a georeference (GeoTIFF tags,
        /// or --origin).
        #[arg(long, required = true, num_args = 1..)]
        dem: Vec<String>,
        /// Most tiles per level (beyond it, an even sample of the level's tiles, the same for
        /// every mesh kind).
        #[arg(long, default_value_t = 64)]
        max_per_level: usize,
        /// PNG tile size in pixels: 256 or 512.
        #[arg(long, default_value_t = 256, value_parser = png_tile_size)]
        tile_size: u32,
        /// Print one JSON object instead of a table.
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        dem_args: DemArgs,
    },
    /// Many vertex-stream sessions on one core, without the network: each flies its own seeded
    /// random loop (the paths of `relief-client load --path random`), and at every pose each
    /// takes one camera update (the update and its packed delta, as a server's session does).
    /// The same updates run interleaved (every session in turn at each pose, as on a loaded
    /// server, so each finds its state out of the caches) and one session at a time; both must
    /// make the same deltas. Prints the time per update both ways, their ratio, and the
    /// sessions one core could update at 10 Hz doing nothing else.
    Sessions {
        /// The DEM (same forms as `build`'s inputs).
        #[arg(long, required = true, num_args = 1..)]
        dem: Vec<String>,
        /// Sessions updated in turn.
        #[arg(long, default_value_t = 100, value_parser = clap::value_parser!(u64).range(1..=100_000))]
        sessions: u64,
        /// Poses each session flies, at 10 Hz (its first update, the whole initial cut, is
        /// timed apart).
        #[arg(long, default_value_t = 100, value_parser = clap::value_parser!(u64).range(2..=600))]
        poses: u64,
        /// Seed of the first session's path (session `i` flies seed + i, as `relief-client
        /// load --path random --seed`).
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Screen-space error threshold in pixels.
        #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
        tau: f32,
        /// Print one JSON object instead of a table.
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        dem_args: DemArgs,
    },
    /// Time the query library on one core: rays from the standard path's cameras,
    /// half grazing (1-5 degrees down), half steep, cast by the max-mip pyramid and by the
    /// brute-force march in the same run (every answer must agree; the command fails if one
    /// does not), and heights, HAT/HOT and lines of sight per second.
    Query {
        /// The DEM (same forms as `build`'s inputs).
        #[arg(long, required = true, num_args = 1..)]
        dem: Vec<String>,
        /// Rays cast by each method.
        #[arg(long, default_value_t = 20_000)]
        rays: usize,
        /// Height queries timed.
        #[arg(long, default_value_t = 2_000_000)]
        heights: usize,
        /// Consecutive rays from one camera pose (1: every ray from a random pose, cold
        /// caches; more: a sensor sweeping from one place).
        #[arg(long, default_value_t = 1)]
        rays_per_camera: usize,
        /// Print one JSON object instead of a table.
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        dem_args: DemArgs,
    },
}

/// A tile mesh kind on the command line.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum TileMeshArg {
    /// Every vertex of the tile's lattice.
    Grid,
    /// Paper 002's restricted quadtree.
    Rqt,
    /// Paper 003's greedy-insertion Delaunay TIN.
    Tin,
}

impl From<TileMeshArg> for relief_proto::tile::body::MeshKind {
    fn from(a: TileMeshArg) -> Self {
        match a {
            TileMeshArg::Grid => Self::Grid,
            TileMeshArg::Rqt => Self::Rqt,
            TileMeshArg::Tin => Self::Tin,
        }
    }
}

/// What both benchmarks take.
#[derive(clap::Args)]
struct BenchArgs {
    /// The DEM to fly over (same forms as `build`'s inputs; several files after --dem make a
    /// mosaic, as for `build`).
    #[arg(long, required = true, num_args = 1..)]
    dem: Vec<String>,
    /// Which path: `standard` (60 s loop, 100-300 m above ground) or `stress` (faster, lower).
    #[arg(long, default_value = "standard")]
    path: PathKind,
    /// Screen-space error threshold in pixels.
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    tau: f32,
    /// Measure pixel error on every k-th frame [default: every frame on small grids, fewer
    /// on large ones, never fewer than 60 frames].
    #[arg(long)]
    px_every: Option<usize>,
    /// Fly only the path's first N poses, e.g. for a profile [default: all].
    #[arg(long, value_parser = clap::value_parser!(u64).range(2..))]
    poses: Option<u64>,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    dem_args: DemArgs,
}

impl BenchArgs {
    /// Checks tau and loads the DEM.
    fn load(&self) -> anyhow::Result<crate::dem::Dem> {
        crate::serve::validate::params(&relief_proto::view::Lens::STANDARD.into(), self.tau, None)
            .map_err(anyhow::Error::msg)?;
        self.dem_args.load(&self.dem).context("cannot load the DEM")
    }
}

/// Crack strategies on the command line.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum Crack {
    /// Precomputed crack patches (paper 001).
    Patches,
    /// Skirts hanging from every tile edge (Cesium's baseline).
    Skirts,
    /// Nothing (cracks stay open).
    None,
}

impl From<Crack> for relief_proto::msg::CrackMode {
    fn from(c: Crack) -> Self {
        match c {
            Crack::Patches => Self::Patches,
            Crack::Skirts => Self::Skirts,
            Crack::None => Self::None,
        }
    }
}

/// Prints a benchmark report: one JSON line with `json`, else a two-column table.
/// `--tile-size` of `bench formats`: 256 or 512.
fn png_tile_size(s: &str) -> Result<u32, String> {
    match s.parse::<u32>() {
        Ok(n) if crate::formats::raster::TILE_SIZES.contains(&n) => Ok(n),
        _ => Err(format!("{s:?} is not a served tile size: use 256 or 512")),
    }
}

/// The formats report as a Markdown table.
fn print_formats(r: &crate::bench::formats::FormatsReport) {
    let b = r.bounds;
    println!(
        "bounds {:.4},{:.4},{:.4},{:.4}; Cesium levels 0-{}, Web Mercator levels 0-{}\n",
        b[0], b[1], b[2], b[3], r.cesium_max_level, r.raster_max_level
    );
    println!(
        "| tiles | count | triangles | bytes mean | bytes p99 | gzip mean | gzip p99 | make ms median | make ms p99 | worst error / tolerance |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for k in &r.kinds {
        println!(
            "| {} | {} | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} | {:.2} | {:.2} | {:.3} |",
            k.kind,
            k.tiles,
            k.triangles_mean,
            k.bytes_mean,
            k.bytes_p99,
            k.gzip_mean,
            k.gzip_p99,
            k.make_ms_median,
            k.make_ms_p99,
            k.worst_error_of_tolerance
        );
    }
}

fn print_report(report: &impl serde::Serialize, json: bool) -> anyhow::Result<()> {
    let v = serde_json::to_value(report)?;
    if json {
        println!("{v}");
        return Ok(());
    }
    if let serde_json::Value::Object(m) = v {
        let width = m.keys().map(String::len).max().unwrap_or(0);
        for (k, v) in m {
            let text = match v {
                serde_json::Value::Number(n) => match n.as_f64() {
                    Some(f) if n.is_f64() => format!("{f:.3}"),
                    _ => n.to_string(),
                },
                serde_json::Value::String(s) => s,
                other => other.to_string(),
            };
            println!("{k:<width$}  {text}");
        }
    }
    Ok(())
}

/// Parses the arguments, runs the command, and turns an error into one line and exit code 1.
pub fn main() -> std::process::ExitCode {
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            // The whole chain on one line, no backtrace: these are input errors, not bugs.
            eprintln!("error: {}", relief_proto::errors::one_line(e.as_ref()));
            std::process::ExitCode::FAILURE
        }
    }
}

fn run() -> anyhow::Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_env("RELIEF_LOG")
                .unwrap_or_else(|_| "info".into()),
        )
        .with_writer(std::io::stderr)
        .with_ansi(relief_proto::errors::log_colour())
        .init();
    match Cli::parse().command {
        Command::Serve(args) => {
            let config = args.resolve().context("bad configuration")?;
            tracing::info!(?config, "starting");
            // LOD updates run on the blocking pool; more threads than cores only add stacks
            // and allocator arenas (resident memory), not throughput.
            let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
            tokio::runtime::Builder::new_multi_thread()
                .enable_all()
                .max_blocking_threads(2 * cores)
                .build()?
                .block_on(crate::serve::run(config))?;
        }
        Command::Build {
            inputs,
            output,
            store,
            dem,
        } => {
            let opts = store.options(!dem.quiet)?;
            let pool = preprocess::thread_pool(store.threads()).map_err(anyhow::Error::msg)?;
            let d = pool
                .install(|| dem.load(&inputs))
                .context("cannot load the DEM")?;
            let rep = pool
                .install(|| preprocess::build_store(&d, &output, &opts))
                .context("cannot build the store")?;
            let samples = d.width as f64 * d.height as f64;
            tracing::info!(
                "wrote {} ({} bytes): {}x{} samples, tree built in {:.2} s ({:.1} M samples/s), tiles in {:.2} s",
                output.display(),
                rep.bytes,
                d.width,
                d.height,
                rep.tree_s,
                samples / rep.tree_s.max(1e-9) / 1e6,
                rep.tiles_s
            );
        }
        Command::Health { url, timeout } => {
            anyhow::ensure!(
                timeout.is_finite() && timeout > 0.0,
                "--timeout must be a positive number of seconds"
            );
            let status = health::get_status(&url, std::time::Duration::from_secs_f64(timeout))?;
            if status != 200 {
                anyhow::bail!("{url} answered {status}");
            }
        }
        Command::Info {
            store,
            fractal,
            flat,
            rough,
        } => {
            // Thresholds first: a bad pair is refused before a large store is read.
            let params = fractal
                .then(|| info::fractal_params(flat, rough))
                .transpose()?;
            let s = crate::store::Store::open(&store).context("cannot open the store")?;
            let mut out = info::store_info(&store, &s);
            if let Some(p) = params {
                let report = info::fractal_report(&s, &p, true)
                    .context("cannot build the fractal region tree")?;
                out["fractal"] = serde_json::to_value(report)?;
            }
            println!("{}", serde_json::to_string_pretty(&out)?);
        }
        Command::Bench {
            which:
                BenchCommand::Build {
                    dem,
                    store,
                    output,
                    json,
                    dem_args,
                },
        } => {
            let opts = crate::bench::build::BuildBenchOptions {
                inputs: dem,
                build: store.options(!dem_args.quiet)?,
                dem: dem_args,
                threads: store.threads(),
                output,
            };
            let report = crate::bench::build::run(&opts)?;
            if json {
                println!("{}", serde_json::to_string(&report)?);
            } else {
                crate::bench::build::print(&report);
            }
        }
        Command::Bench {
            which:
                BenchCommand::Formats {
                    dem,
                    max_per_level,
                    tile_size,
                    json,
                    dem_args,
                },
        } => {
            let d = dem_args.load(&dem).context("cannot load the DEM")?;
            let dir = tempfile::tempdir()?;
            let path = dir.path().join("bench.relief");
            crate::preprocess::build_store(&d, &path, &Default::default())?;
            let store = crate::store::Store::open(&path)?;
            let opts = crate::bench::formats::FormatsBenchOptions {
                max_per_level: max_per_level.max(1),
                tile_size,
                progress: !dem_args.quiet,
            };
            let report = crate::bench::formats::run(&store, &opts)?;
            if json {
                println!("{}", serde_json::to_string(&report)?);
            } else {
                print_formats(&report);
            }
        }
        Command::Bench {
            which:
                BenchCommand::Query {
                    dem,
                    rays,
                    heights,
                    rays_per_camera,
                    json,
                    dem_args,
                },
        } => {
            let d = dem_args.load(&dem).context("cannot load the DEM")?;
            let opts = crate::bench::query::QueryBenchOptions {
                rays,
                heights,
                rays_per_camera,
                ..Default::default()
            };
            let report = crate::bench::query::run(&d, &opts)?;
            print_report(&report, json)?;
            if report.mismatches > 0 {
                anyhow::bail!(
                    "{} of {} rays: the max-mip cast and the brute-force march disagree",
                    report.mismatches,
                    report.rays
                );
            }
        }
        Command::Bench {
            which:
                BenchCommand::Sessions {
                    dem,
                    sessions,
                    poses,
                    seed,
                    tau,
                    json,
                    dem_args,
                },
        } => {
            crate::serve::validate::params(&relief_proto::view::Lens::STANDARD.into(), tau, None)
                .map_err(anyhow::Error::msg)?;
            let d = dem_args.load(&dem).context("cannot load the DEM")?;
            let opts = crate::bench::sessions::SessionsBenchOptions {
                sessions: sessions as usize,
                poses: poses as usize,
                seed,
                params: LodParams {
                    tau,
                    ..LodParams::default()
                },
                progress: !dem_args.quiet,
                ..Default::default()
            };
            print_report(&crate::bench::sessions::run(&d, &opts)?, json)?;
        }
        Command::Bench {
            which: BenchCommand::Lod { run },
        } => {
            let d = run.load()?;
            let opts = LodBenchOptions {
                path: run.path,
                params: LodParams {
                    tau: run.tau,
                    ..LodParams::default()
                },
                px_every: run.px_every,
                poses: run.poses.map(|n| n as usize),
                progress: !run.dem_args.quiet,
                ..LodBenchOptions::default()
            };
            print_report(&lod::run(&d, &opts)?, run.json)?;
        }
        Command::Bench {
            which:
                BenchCommand::Tiles {
                    run,
                    crack,
                    tile_size,
                    tile_mesh,
                },
        } => {
            relief_proto::tile::TileShape::new(2, 2, tile_size)?;
            let d = run.load()?;
            let opts = crate::bench::tiles::TileBenchOptions {
                path: run.path,
                tau: run.tau,
                crack: crack.into(),
                tile_size,
                tile_mesh: tile_mesh.into(),
                px_every: run.px_every,
                poses: run.poses.map(|n| n as usize),
                progress: !run.dem_args.quiet,
                ..Default::default()
            };
            print_report(&crate::bench::tiles::run(&d, &opts)?, run.json)?;
        }
        Command::Bench {
            which:
                BenchCommand::Compare {
                    run,
                    target_px,
                    within,
                    levels,
                    tries,
                    tile_size,
                    only,
                    plot,
                },
        } => {
            relief_proto::tile::TileShape::new(2, 2, tile_size)?;
            if !(target_px.is_finite() && target_px > 0.0) {
                anyhow::bail!("--target-px must be a positive number of pixels, not {target_px}");
            }
            if !(within.is_finite() && within > 0.0 && within < 1.0) {
                anyhow::bail!("--within must lie between 0 and 1, not {within}");
            }
            if let Some(l) = levels.iter().find(|l| !(l.is_finite() && **l > 0.0)) {
                anyhow::bail!("--levels must be positive multiples of the target, not {l}");
            }
            let d = run.load()?;
            let opts = crate::bench::compare::CompareOptions {
                path: run.path,
                target_px,
                within,
                levels,
                tries,
                tile_size,
                px_every: run.px_every,
                poses: run.poses.map(|n| n as usize),
                only,
                progress: !run.dem_args.quiet,
            };
            let r = crate::bench::compare::run(&d, &opts)?;
            if let Some(p) = plot {
                std::fs::write(&p, crate::bench::compare::svg(&r))
                    .with_context(|| format!("cannot write {}", p.display()))?;
            }
            if run.json {
                println!("{}", serde_json::to_string(&r)?);
            } else {
                print!("{}", crate::bench::compare::markdown(&r));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::serve::config::TerrainSource;

    #[test]
    fn serve_and_build_take_the_same_dem_arguments() {
        let dem = [
            "--dem",
            "heights.png",
            "--png-offset",
            "-17",
            "--spacing-x",
            "30",
            "--spacing-y",
            "25",
        ];
        let serve = Cli::try_parse_from(["relief-server", "serve"].iter().chain(&dem)).unwrap();
        let Command::Serve(args) = serve.command else {
            panic!("not serve")
        };
        let TerrainSource::Dem(spec, opts) = args.resolve().unwrap().source else {
            panic!("not a DEM")
        };
        assert_eq!(spec, ["heights.png"]);
        assert_eq!(
            (opts.spacing_x, opts.spacing_y, opts.png.offset),
            (Some(30.0), Some(25.0), -17.0)
        );
        let build = ["relief-server", "build", "heights.png", "-o", "x.relief"];
        let build = Cli::try_parse_from(build.iter().chain(&dem[2..])).unwrap();
        let Command::Build { dem: a, .. } = build.command else {
            panic!("not build")
        };
        assert_eq!(a.options(), opts);
    }

    #[test]
    fn build_takes_several_inputs_and_tile_options() {
        use crate::formats::terrain_rgb::Encoding;
        use crate::geo::mercator::TileId;
        let cli = Cli::try_parse_from([
            "relief-server",
            "build",
            "N35E138.hgt",
            "N35E139.hgt",
            "-o",
            "x.relief",
        ])
        .unwrap();
        let Command::Build { inputs, .. } = cli.command else {
            panic!("not build")
        };
        assert_eq!(inputs, ["N35E138.hgt", "N35E139.hgt"]);
        let cli = Cli::try_parse_from([
            "relief-server",
            "build",
            "t.png",
            "--encoding",
            "mapbox",
            "--tile",
            "12/3629/1617",
            "-o",
            "x.relief",
        ])
        .unwrap();
        let Command::Build { dem, .. } = cli.command else {
            panic!("not build")
        };
        let o = dem.options();
        assert_eq!(o.encoding, Some(Encoding::TerrainRgb));
        assert_eq!(o.tile, TileId::new(12, 3629, 1617).ok());
        // No input, a bad encoding, a tile off the map: refused by the parser.
        for bad in [
            &["build", "-o", "x.relief"][..],
            &["build", "t.png", "--encoding", "rgb", "-o", "x"],
            &["build", "t.png", "--tile", "2/4/0", "-o", "x"],
        ] {
            let e = Cli::try_parse_from(["relief-server"].iter().chain(bad)).err();
            assert!(e.is_some(), "{bad:?}");
        }
        let e = Cli::try_parse_from(["relief-server", "build", "t.png", "--tile", "2/4/0"])
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("not on the map"), "{e}");
        // Bench and serve take several files after --dem.
        let cli = Cli::try_parse_from([
            "relief-server",
            "bench",
            "lod",
            "--dem",
            "a.hgt",
            "b.hgt",
            "--json",
        ])
        .unwrap();
        let Command::Bench {
            which: BenchCommand::Lod { run },
        } = cli.command
        else {
            panic!("not bench lod")
        };
        assert_eq!(run.dem, ["a.hgt", "b.hgt"]);
        let cli =
            Cli::try_parse_from(["relief-server", "serve", "--dem", "a.hgt", "b.hgt"]).unwrap();
        let Command::Serve(args) = cli.command else {
            panic!("not serve")
        };
        let TerrainSource::Dem(specs, _) = args.resolve().unwrap().source else {
            panic!("not a DEM")
        };
        assert_eq!(specs, ["a.hgt", "b.hgt"]);
    }

    #[test]
    fn bench_query_takes_rays_heights_and_json() {
        let cli = Cli::try_parse_from([
            "relief-server",
            "bench",
            "query",
            "--dem",
            "synthetic:65",
            "--rays",
            "10",
            "--json",
        ])
        .unwrap();
        let Command::Bench {
            which:
                BenchCommand::Query {
                    dem,
                    rays,
                    heights,
                    json,
                    ..
                },
        } = cli.command
        else {
            panic!("not bench query")
        };
        assert_eq!(
            (dem, rays, heights, json),
            (vec!["synthetic:65".to_string()], 10, 2_000_000, true)
        );
        // The benchmark itself on a small terrain: every ray agrees.
        let d = crate::dem::DemArgs::default()
            .load(&["synthetic:65"])
            .unwrap();
        let opts = crate::bench::query::QueryBenchOptions {
            rays: 200,
            heights: 1000,
            seed: 1,
            rays_per_camera: 10,
        };
        let r = crate::bench::query::run(&d, &opts).unwrap();
        assert_eq!((r.rays, r.mismatches), (200, 0));
        assert!(r.hits > 0);
    }

    /// `(fractal, flat, rough)` of an `info` command line.
    fn info(args: &[&str]) -> Result<(bool, f32, f32), clap::Error> {
        let cli = Cli::try_parse_from(["relief-server", "info", "t.relief"].iter().chain(args))?;
        let Command::Info {
            fractal,
            flat,
            rough,
            ..
        } = cli.command
        else {
            panic!("not info")
        };
        Ok((fractal, flat, rough))
    }

    #[test]
    fn info_fractal_takes_checked_thresholds() {
        let d = FractalParams::default();
        assert_eq!(info(&[]).unwrap(), (false, d.flat, d.rough));
        assert_eq!(info(&["--fractal"]).unwrap(), (true, d.flat, d.rough));
        assert_eq!(
            info(&["--fractal", "--flat", "2.0", "--rough", "2.3"]).unwrap(),
            (true, 2.0, 2.3)
        );
        // Thresholds without --fractal would do nothing: refused.
        assert!(info(&["--flat", "2.02"]).is_err());
        for bad in ["NaN", "inf", "-1", "1.5", "3.01", "x"] {
            let e = info(&["--fractal", "--rough", bad]).unwrap_err();
            assert_eq!(e.kind(), clap::error::ErrorKind::ValueValidation, "{bad}");
        }
        // Each one valid, the pair not: refused when the command runs, before the store opens.
        let (_, flat, rough) = info(&["--fractal", "--flat", "2.05", "--rough", "2.04"]).unwrap();
        let e = info::fractal_params(flat, rough).unwrap_err().to_string();
        assert!(e.contains("must not exceed"), "{e}");
    }
}
