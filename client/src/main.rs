//! `relief-client`: talk to a Relief server from the command line.
//! Thin: parse the arguments, set up tracing, call into the library.

use anyhow::Context;
use clap::{Parser, Subcommand};
use relief_client::fly::{self, FlyOptions};
use relief_client::load::soak::{self, SoakOptions};
use relief_client::load::{self, LoadOptions, LoadPath};
use relief_client::render::MorphStage;
use relief_client::render::bench::{self, RenderBenchOptions};
use relief_client::render::shot::{self, ShotOptions, ShotPose};
use relief_client::session::SessionConfig;
use relief_client::viewer::{self, ViewerOptions};
use relief_proto::msg::{CrackMode, StreamKind, TileStreamParams};
use relief_proto::path::PathKind;
use relief_proto::view::Lens;
use std::path::PathBuf;
use std::time::Duration;

#[derive(Parser)]
#[command(
    name = "relief-client",
    version,
    about = "Relief terrain LOD streaming client"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// Which stream a session asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum StreamArg {
    /// The vertex stream (paper 000): splits and merges, fans, geomorphs.
    Vertex,
    /// The tile stream (paper 001): tiles with crack patches or skirts.
    Tiles,
}

/// How a tile session closes cracks.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum CrackArg {
    /// Precomputed crack patches, dropped and raised, sent with the tiles.
    Patches,
    /// Skirts hung from every tile edge, 5x the largest error of the level above deep
    /// (Cesium's rule).
    Skirts,
    /// Nothing (cracks show).
    None,
    /// Diagnostic: patches are sent, but only the dropped ones are drawn (paper 001's rule).
    Dropped,
}

/// Tiles a tile session caches by default, active ones included.
const DEFAULT_CACHE_TILES: u32 = 512;

/// Parses `--cache-tiles`: a number of tiles, or `unlimited`.
fn parse_cache(s: &str) -> Result<u32, String> {
    if s == "unlimited" {
        return Ok(u32::MAX);
    }
    s.parse::<u32>()
        .map_err(|_| format!("{s:?} is not a number of tiles or `unlimited`"))
}

/// The server, the stream and the error threshold: what every command that opens a session
/// names.
#[derive(clap::Args)]
struct ServerArgs {
    /// The server: ws://HOST:PORT or http://HOST:PORT, with or without the stream's path
    /// /v1/stream (a bare HOST:PORT works too).
    #[arg(
        long,
        env = "RELIEF_SERVER",
        default_value = "ws://127.0.0.1:8080/v1/stream"
    )]
    server: String,
    /// Screen-space error threshold in pixels.
    #[arg(long, allow_negative_numbers = true, default_value_t = 1.0)]
    tau: f32,
    /// Which stream: `vertex` (splits and merges) or `tiles` (tiles with crack patches).
    #[arg(long, value_enum, default_value = "vertex")]
    stream: StreamArg,
    /// Tile stream: how cracks are closed: `patches`, `skirts`, `none`, or `dropped` (patches
    /// sent, only the dropped ones drawn: a diagnostic) [default: patches].
    #[arg(long, value_enum)]
    crack: Option<CrackArg>,
    /// Tile stream: the most tiles the client keeps, active and cached together, or
    /// `unlimited` [default: 512].
    #[arg(long, value_parser = parse_cache)]
    cache_tiles: Option<u32>,
}

impl ServerArgs {
    fn session(&self) -> anyhow::Result<SessionConfig> {
        anyhow::ensure!(
            self.tau.is_finite() && self.tau > 0.0,
            "--tau must be a positive number of pixels"
        );
        let stream = match self.stream {
            StreamArg::Vertex => {
                anyhow::ensure!(
                    self.crack.is_none() && self.cache_tiles.is_none(),
                    "--crack and --cache-tiles need --stream tiles"
                );
                StreamKind::Vertex
            }
            StreamArg::Tiles => StreamKind::Tiles(TileStreamParams {
                cache_tiles: self.cache_tiles.unwrap_or(DEFAULT_CACHE_TILES),
                crack: match self.crack.unwrap_or(CrackArg::Patches) {
                    CrackArg::Patches | CrackArg::Dropped => CrackMode::Patches,
                    CrackArg::Skirts => CrackMode::Skirts,
                    CrackArg::None => CrackMode::None,
                },
            }),
        };
        let url = relief_client::server_url::ServerUrl::parse(&self.server)?;
        Ok(SessionConfig {
            tau: self.tau,
            stream,
            ..SessionConfig::new(&url.stream())
        })
    }

    /// Whether only the dropped crack patches are drawn.
    fn dropped_only(&self) -> bool {
        self.crack == Some(CrackArg::Dropped)
    }
}

/// What every streaming command asks of the server.
#[derive(clap::Args)]
struct StreamArgs {
    #[command(flatten)]
    target: ServerArgs,
    /// Bandwidth budget per session in bytes per second [default: none].
    #[arg(long, allow_negative_numbers = true)]
    budget: Option<u32>,
    /// Poses per second per session; 0 sends each pose as soon as the previous one is answered.
    #[arg(long, allow_negative_numbers = true, default_value_t = fly::DEFAULT_RATE_HZ)]
    rate: f64,
}

impl StreamArgs {
    fn session(&self) -> anyhow::Result<SessionConfig> {
        anyhow::ensure!(
            self.rate.is_finite() && self.rate >= 0.0,
            "--rate must be 0 or more"
        );
        Ok(SessionConfig {
            budget: self.budget,
            ..self.target.session()?
        })
    }
}

/// What every drawing command asks for.
#[derive(clap::Args)]
struct ViewArgs {
    #[command(flatten)]
    target: ServerArgs,
    /// Image or window size, WxH.
    #[arg(long, default_value = "1280x720", value_parser = shot::parse_size)]
    size: (u32, u32),
    /// Vertical field of view, degrees.
    #[arg(long, allow_negative_numbers = true, default_value_t = 60.0)]
    fov: f32,
    /// Draw triangle edges over the shading.
    #[arg(long)]
    wireframe: bool,
    /// Where the geomorph runs: `compute` (once per node in a compute pass before the draw) or
    /// `vertex` (in the vertex shader, per triangle corner). Same image; `compute` is cheaper on big cuts.
    #[arg(long, value_enum, default_value = "compute")]
    morph: MorphStage,
}

impl ViewArgs {
    fn session(&self) -> anyhow::Result<SessionConfig> {
        anyhow::ensure!(
            self.fov.is_finite() && (1.0..=170.0).contains(&self.fov),
            "--fov must be 1 to 170 degrees"
        );
        Ok(SessionConfig {
            lens: Lens {
                width: self.size.0,
                height: self.size.1,
                fov_y_deg: self.fov,
                near: 1.0,
            },
            ..self.target.session()?
        })
    }
}

#[derive(Subcommand)]
enum Command {
    /// Fly one session along a camera path and print deltas, bandwidth, latency and desyncs.
    Fly {
        #[command(flatten)]
        stream: StreamArgs,
        /// Which path: `standard` (60 s loop, 100-300 m above ground) or `stress`.
        #[arg(long, default_value = "standard")]
        path: PathKind,
        /// Print one JSON object instead of an indented one.
        #[arg(long)]
        json: bool,
    },
    /// Stream the terrain for one camera and draw it offscreen into a PNG (no window needed; works
    /// on Mesa's software Vulkan).
    Shot {
        #[command(flatten)]
        view: ViewArgs,
        /// A fixed camera: x,y,z,yaw,pitch (metres east and north of the terrain's south-west
        /// sample, metres of height, degrees counter-clockwise from east, degrees of elevation,
        /// negative looks down).
        #[arg(long, conflicts_with_all = ["path", "frame"], allow_hyphen_values = true)]
        camera: Option<String>,
        /// A path to fly from its start up to --frame: `standard` or `stress`.
        #[arg(long, requires = "frame")]
        path: Option<PathKind>,
        /// The path's pose to draw (10 poses a second); the frame is drawn one pose interval
        /// later, with that pose's splits still growing.
        #[arg(long, requires = "path")]
        frame: Option<usize>,
        /// Draw what was streamed for the camera (or path) from this other camera instead,
        /// x,y,z,yaw,pitch[,fov] (fov: vertical, degrees; default --fov): a diagnostic that
        /// shows up close what a selection leaves, e.g. its crack patches (seen from the
        /// selecting camera, a crack is at most about tau pixels; a narrow fov from the same
        /// eye magnifies it).
        #[arg(long, allow_hyphen_values = true)]
        look_from: Option<String>,
        /// Where to write the PNG.
        #[arg(short = 'o', long = "out", default_value = "shot.png")]
        out: PathBuf,
        /// Background colour: #rrggbb or r,g,b.
        #[arg(long, default_value = "#9eb3cc")]
        background: String,
    },
    /// Measure the renderer along a path, offscreen: the client's cost per pose (delta apply,
    /// fan rebuild, record update, upload), median and p99 in microseconds, and frames per
    /// second.
    RenderBench {
        #[command(flatten)]
        view: ViewArgs,
        /// Which path: `standard` or `stress`.
        #[arg(long, default_value = "standard")]
        path: PathKind,
        /// Fly only the path's first this many poses (0: all 600).
        #[arg(long, allow_negative_numbers = true, default_value_t = 0)]
        poses: usize,
        /// Print one JSON object instead of an indented one.
        #[arg(long)]
        json: bool,
    },
    /// Open a window and fly over the streamed terrain. WASD/arrows move, the mouse (held left
    /// button) looks, Q/E or PageDown/PageUp go down/up, Shift is 5x faster, Ctrl 5x slower,
    /// G toggles following the ground, F toggles the wireframe, +/- change tau, Esc quits.
    View {
        #[command(flatten)]
        view: ViewArgs,
        /// Camera poses sent to the server per second.
        #[arg(long, allow_negative_numbers = true, default_value_t = 10.0)]
        rate: f64,
        /// Close by itself after this many seconds (for scripted checks) [default: never].
        #[arg(long, allow_negative_numbers = true)]
        exit_after: Option<f64>,
    },
    /// Run many sessions at once against a server and report bandwidth, latency, errors and the
    /// server's CPU and memory; with --sweep, run stages of growing size and find the knee; with
    /// --soak, cycle sessions for a long, bounded time and judge the server's memory.
    #[command(after_long_help = SOAK_HELP)]
    /// The replica drill (deploy/README.md): sessions, half vertex and half tiles, fly the
    /// standard loop in lock step through a load balancer, and a prober asks POST /v1/query,
    /// while each --action runs when the fleet has flown its fraction of the poses (e.g. kill a
    /// replica, restart it). Prints lost sessions, desyncs, reconnections and their gaps, and
    /// the queries answered; exits non-zero if a session was lost or desynced or started
    /// afresh instead of resuming.
    Chaos {
        /// The load balancer: ws://HOST:PORT or http://HOST:PORT (a bare HOST:PORT works too).
        #[arg(
            long,
            env = "RELIEF_SERVER",
            default_value = "ws://127.0.0.1:8080/v1/stream"
        )]
        server: String,
        /// Sessions: the first half vertex, the rest tiles.
        #[arg(long, default_value_t = 200)]
        sessions: usize,
        /// Poses of the standard loop each session flies.
        #[arg(long, default_value_t = 300)]
        poses: usize,
        /// FRACTION:COMMAND, run with `sh -c` when the fleet has flown that fraction of its
        /// poses, e.g. `0.3:'kubectl delete pod relief-0 --grace-period=0 --force'`. Repeat
        /// for more; they run in order of their fractions.
        #[arg(long, value_parser = parse_action)]
        action: Vec<(f64, String)>,
        /// Milliseconds between the prober's queries (0: no prober).
        #[arg(long, default_value_t = 100)]
        query_every_ms: u64,
        /// Seconds a session may take to reconnect before it counts as lost.
        #[arg(long, default_value_t = 30.0)]
        reconnect_deadline: f64,
        /// Write the report as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
    },
    Load {
        #[command(flatten)]
        stream: StreamArgs,
        /// Concurrent sessions (ignored with --sweep) [default: 10; 500 with --soak].
        #[arg(long, allow_negative_numbers = true)]
        sessions: Option<usize>,
        /// Seconds every session flies once all have started.
        #[arg(long, allow_negative_numbers = true, default_value_t = 30.0)]
        duration: f64,
        /// Soak for this long (e.g. 2m, 1h, 1h30m; at most 7d): every session cycles through
        /// connect, fly, drop, resume, fly, close, and the server's RSS is sampled; exits
        /// non-zero when the RSS after the warm-up spreads more than --rss-tolerance, or on any
        /// desync, error or drop not resumed (see below).
        #[arg(long, value_parser = soak::duration::parse_duration, conflicts_with_all = ["sweep", "duration", "json", "knee_ms"])]
        soak: Option<Duration>,
        /// Soak: how often the server's RSS is sampled (e.g. 60s, 5s).
        #[arg(long, value_parser = soak::duration::parse_duration, default_value = "60s", requires = "soak")]
        sample_every: Duration,
        /// Soak: how long at the start is left out of the verdict [default: 10% of the soak, at
        /// least one sample interval].
        #[arg(long, value_parser = soak::duration::parse_duration, requires = "soak")]
        warmup: Option<Duration>,
        /// Soak: the largest (max - min) / min of the RSS samples after the warm-up that passes.
        #[arg(
            long,
            allow_negative_numbers = true,
            default_value_t = 0.05,
            requires = "soak"
        )]
        rss_tolerance: f64,
        /// Which paths: `standard` or `stress` (phase-shifted per session), or `random`
        /// (a seeded loop per session).
        #[arg(long, default_value = "standard")]
        path: LoadPath,
        /// Seed of the random paths.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Seconds over which sessions start, evenly spread [default: 10% of the duration; with
        /// --soak, 40 sessions a second, at most the warm-up].
        #[arg(long, allow_negative_numbers = true)]
        ramp: Option<f64>,
        /// Rebuild fans as a viewer would (costs client CPU); tile sessions keep their decoded
        /// tiles (without it they keep a light mirror that checks every tile and digest).
        #[arg(long)]
        mesh: bool,
        /// Simulator back ends instead of viewers: each session asks, every tick (--rate per
        /// second; 0: as soon as the last batch is answered), one batch of terrain queries:
        /// `hat` for HAT/HOT of every entity, `ray=N` rays, `sight=N` lines of sight
        /// (e.g. hat,ray=10,sight=10). The report gives queries/s, batch latency and the
        /// server's CPU per query.
        #[arg(long, value_name = "MIX", conflicts_with_all = ["soak", "mesh", "budget", "path"])]
        queries: Option<relief_client::load::query::QueryMix>,
        /// Entities each query back end moves over the terrain.
        #[arg(long, default_value_t = 1000, requires = "queries")]
        entities: usize,
        /// Run these session counts in turn (e.g. 10,100,500) and report the knee.
        #[arg(long, value_delimiter = ',')]
        sweep: Vec<usize>,
        /// The p99 latency in milliseconds above which a sweep stage counts as broken away.
        #[arg(long, allow_negative_numbers = true, default_value_t = 50.0)]
        knee_ms: f64,
        /// Write the JSON report to this file.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Write report.json, summary.md and PNG plots into this folder (with --soak:
        /// soak.json, samples.csv, rss.png and summary.md).
        #[arg(long)]
        report: Option<PathBuf>,
        /// Hide the progress bar.
        #[arg(long)]
        quiet: bool,
    },
}

/// `relief-client load --help`'s last section: what a soak does and judges.
const SOAK_HELP: &str = "\
Soak (--soak DURATION):
  Each of --sessions virtual clients (500 by default) cycles until the end: it connects (a new
  session), flies 50 to 200 poses of its path at --rate (10 Hz), drops the connection (the
  socket closes without a close handshake), stays away up to 2 s, resumes (reconnects with a
  snapshot of its cut; the server must answer `resumed`), flies again, and after 1 to 3 drops
  closes and starts again as a new session. Lengths and pauses are drawn from --seed per client.
  The server's /metrics is scraped every --sample-every; samples in the first --warmup are left
  out. The run passes when (max - min) / min of the RSS after the warm-up is at most
  --rss-tolerance, with no desyncs, no client errors, every drop resumed, and at least one cycle
  and one resume. A least-squares slope of the RSS (MiB/h) is reported, with a warning when its
  rise over the window exceeds half the tolerance. --report DIR writes soak.json, samples.csv,
  rss.png and summary.md.

  relief-client load --soak 1h --report soak/                 # 500 sessions, RSS each minute
  relief-client load --soak 3m --sample-every 5s --warmup 1m  # the CI version";

/// Keeps headless commands away from the windowing system.
mod headless_env {
    #![allow(unsafe_code)] // Reason: `std::env::set_var` is unsafe in Rust 2024; it is called once, first thing in `main`, before any thread exists.

    /// Turns off Mesa's implicit Vulkan layer `VK_LAYER_MESA_device_select` for a command that
    /// draws offscreen. When an instance enables the Wayland surface extension (wgpu enables every
    /// surface extension the driver has), the layer calls `wl_display_connect` while enumerating
    /// GPUs, and libwayland prints `error: XDG_RUNTIME_DIR is invalid or not set in the
    /// environment.` on a machine with no session (ssh, containers, CI). The layer only orders GPUs
    /// by the display's default; wgpu picks the adapter by power preference anyway. A user who
    /// chose a GPU with `MESA_VK_DEVICE_SELECT`, or set `NODEVICE_SELECT`, is left alone.
    ///
    /// Must be called before any thread is started (the tokio runtime, wgpu).
    pub fn quiet_vulkan_layers() {
        if std::env::var_os("MESA_VK_DEVICE_SELECT").is_some()
            || std::env::var_os("NODEVICE_SELECT").is_some()
        {
            return;
        }
        // SAFETY: called from `main` before the tokio runtime or any other thread exists, so
        // nothing reads the environment concurrently.
        unsafe { std::env::set_var("NODEVICE_SELECT", "1") };
    }
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    if matches!(
        cli.command,
        Command::Shot { .. } | Command::RenderBench { .. }
    ) {
        headless_env::quiet_vulkan_layers();
    }
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_env("RELIEF_LOG")
                .unwrap_or_else(|_| "warn".into()),
        )
        .with_writer(std::io::stderr)
        .with_ansi(relief_proto::errors::log_colour())
        .init();
    match run(cli) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", relief_proto::errors::one_line(e.as_ref()));
            std::process::ExitCode::FAILURE
        }
    }
}

/// Prints `report` as one line of JSON (`compact`) or indented.
fn print_json(report: &impl serde::Serialize, compact: bool) -> anyhow::Result<()> {
    if compact {
        println!("{}", serde_json::to_string(report)?);
    } else {
        println!("{}", serde_json::to_string_pretty(report)?);
    }
    Ok(())
}

fn run(cli: Cli) -> anyhow::Result<()> {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    match cli.command {
        Command::Shot {
            view,
            camera,
            path,
            frame,
            look_from,
            out,
            background,
        } => {
            let pose = match (camera, path, frame) {
                (Some(c), _, _) => {
                    ShotPose::Camera(shot::parse_camera(&c).map_err(anyhow::Error::msg)?)
                }
                (None, Some(kind), Some(frame)) => ShotPose::Path { kind, frame },
                _ => anyhow::bail!("give either --camera x,y,z,yaw,pitch or --path P --frame K"),
            };
            let opts = ShotOptions {
                session: view.session()?,
                pose,
                wireframe: view.wireframe,
                background: shot::parse_colour(&background).map_err(anyhow::Error::msg)?,
                morph: view.morph,
                dropped_only: view.target.dropped_only(),
                look_from: look_from
                    .map(|c| shot::parse_look(&c))
                    .transpose()
                    .map_err(anyhow::Error::msg)?,
            };
            let (img, report) = rt.block_on(shot::shot(&opts))?;
            for w in &report.warnings {
                eprintln!("warning: {w}");
            }
            shot::save_png(img, &out).with_context(|| format!("cannot write {}", out.display()))?;
            eprintln!(
                "wrote {} ({}x{}, {} triangles, {} active, adapter {})",
                out.display(),
                report.size.0,
                report.size.1,
                report.triangles,
                report.active,
                report.adapter
            );
        }
        Command::RenderBench {
            view,
            path,
            poses,
            json,
        } => {
            let opts = RenderBenchOptions {
                session: view.session()?,
                path,
                poses,
                morph: view.morph,
                dropped_only: view.target.dropped_only(),
            };
            let report = rt.block_on(bench::render_bench(&opts))?;
            print_json(&report, json)?;
        }
        Command::View {
            view,
            rate,
            exit_after,
        } => {
            anyhow::ensure!(
                rate.is_finite() && rate > 0.0 && rate <= 120.0,
                "--rate must be above 0 and at most 120 poses a second"
            );
            let opts = ViewerOptions {
                session: view.session()?,
                rate_hz: rate,
                wireframe: view.wireframe,
                exit_after: exit_after.map(Duration::from_secs_f64),
                morph: view.morph,
                dropped_only: view.target.dropped_only(),
            };
            drop(rt);
            viewer::run(opts)?;
        }
        Command::Fly { stream, path, json } => {
            let opts = FlyOptions {
                session: stream.session()?,
                path,
                rate_hz: stream.rate,
            };
            let report = rt.block_on(fly::fly(&opts))?;
            print_json(&report, json)?;
        }
        Command::Chaos {
            server,
            sessions,
            poses,
            action,
            query_every_ms,
            reconnect_deadline,
            json,
        } => {
            anyhow::ensure!(
                reconnect_deadline.is_finite() && reconnect_deadline > 0.0,
                "--reconnect-deadline must be a positive number of seconds"
            );
            let url = relief_client::server_url::ServerUrl::parse(&server)?;
            let opts = relief_client::chaos::ChaosOptions {
                url: url.stream(),
                sessions,
                poses,
                actions: action,
                query_every: (query_every_ms > 0).then(|| Duration::from_millis(query_every_ms)),
                reconnect_deadline: Duration::from_secs_f64(reconnect_deadline),
            };
            let report = rt
                .block_on(relief_client::chaos::run(
                    &opts,
                    &mut relief_client::chaos::ShellDrill,
                ))
                .map_err(anyhow::Error::msg)?;
            if let Some(path) = json {
                std::fs::write(&path, serde_json::to_string_pretty(&report)?)
                    .with_context(|| format!("cannot write {}", path.display()))?;
            }
            println!("{}", relief_client::chaos::summary(&report));
            anyhow::ensure!(
                report.lost == 0 && report.desyncs == 0 && report.resumes == report.reconnects,
                "the drill failed: {} lost, {} desyncs, {} of {} reconnections resumed",
                report.lost,
                report.desyncs,
                report.resumes,
                report.reconnects
            );
        }
        Command::Load {
            stream,
            sessions,
            duration,
            soak,
            sample_every,
            warmup,
            rss_tolerance,
            path,
            seed,
            ramp,
            mesh,
            queries,
            entities,
            sweep,
            knee_ms,
            json,
            report,
            quiet,
        } => {
            if let Some(length) = soak {
                let sessions = sessions.unwrap_or(soak::DEFAULT_SESSIONS);
                let warmup =
                    warmup.unwrap_or_else(|| SoakOptions::default_warmup(length, sample_every));
                let ramp = match ramp {
                    Some(r) => {
                        anyhow::ensure!(
                            r.is_finite() && (0.0..1e6).contains(&r),
                            "--ramp must be 0 or more seconds"
                        );
                        Duration::from_secs_f64(r)
                    }
                    None => SoakOptions::default_ramp(sessions, warmup),
                };
                let session = stream.session()?;
                let opts = SoakOptions {
                    load: LoadOptions {
                        url: session.url,
                        sessions,
                        duration: length,
                        ramp,
                        path,
                        seed,
                        tau: session.tau,
                        budget: session.budget,
                        stream: session.stream,
                        rate_hz: stream.rate,
                        mesh,
                        progress: !quiet,
                        queries: None,
                    },
                    sample_every,
                    warmup,
                    rss_tolerance,
                    shape: soak::cycle::CycleShape::default(),
                };
                let r = rt.block_on(soak::run_soak(&opts))?;
                if let Some(dir) = report {
                    for f in soak::report::write_report(&dir, &r)? {
                        eprintln!("wrote {}", f.display());
                    }
                }
                println!("{}", soak::report::markdown(&r, None));
                anyhow::ensure!(
                    r.verdict.pass,
                    "the soak failed: {}",
                    r.verdict.failures.join("; ")
                );
                return Ok(());
            }
            let sessions = sessions.unwrap_or(10);
            anyhow::ensure!(
                duration.is_finite() && duration > 0.0 && duration < 1e6,
                "--duration must be a positive number of seconds"
            );
            let ramp = ramp.unwrap_or(duration / 10.0);
            anyhow::ensure!(
                ramp.is_finite() && (0.0..1e6).contains(&ramp),
                "--ramp must be 0 or more seconds"
            );
            let session = stream.session()?;
            let opts = LoadOptions {
                url: session.url,
                sessions,
                duration: Duration::from_secs_f64(duration),
                ramp: Duration::from_secs_f64(ramp),
                path,
                seed,
                tau: session.tau,
                budget: session.budget,
                stream: session.stream,
                rate_hz: stream.rate,
                mesh,
                progress: !quiet,
                queries: queries.map(|mix| relief_client::load::query::QueryLoad { mix, entities }),
            };
            let counts = if sweep.is_empty() {
                vec![sessions]
            } else {
                sweep
            };
            let stages = rt.block_on(load::run_sweep(&opts, &counts))?;
            let text = load::report::json(&stages, knee_ms);
            if let Some(path) = json {
                std::fs::write(&path, &text)
                    .with_context(|| format!("cannot write {}", path.display()))?;
            }
            if let Some(dir) = report {
                for f in load::report::write_report(&dir, &stages, knee_ms)? {
                    eprintln!("wrote {}", f.display());
                }
            }
            println!("{}", load::report::markdown(&stages, knee_ms, &[]));
        }
    }
    Ok(())
}

/// Parses `FRACTION:COMMAND`.
fn parse_action(s: &str) -> Result<(f64, String), String> {
    let (at, cmd) = s
        .split_once(':')
        .ok_or_else(|| format!("{s:?} is not FRACTION:COMMAND, e.g. 0.3:'kill -9 1234'"))?;
    let at: f64 = at
        .trim()
        .parse()
        .map_err(|_| format!("{s:?}: {at:?} is not a fraction from 0 to 1"))?;
    if !(0.0..=1.0).contains(&at) || cmd.trim().is_empty() {
        return Err(format!(
            "{s:?}: want a fraction from 0 to 1, then a command"
        ));
    }
    Ok((at, cmd.to_string()))
}
