//! `relief-client`: talk to a Relief server from the command line.
//! Thin: parse the arguments, set up tracing, call into the library.

use anyhow::Context;
use clap::{Parser, Subcommand};
use relief_client::fly::{self, FlyOptions};
use relief_client::load::{self, LoadOptions, LoadPath};
use relief_client::session::SessionConfig;
use relief_proto::path::PathKind;
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

/// What every streaming command asks of the server.
#[derive(clap::Args)]
struct StreamArgs {
    /// The stream's URL.
    #[arg(
        long,
        env = "RELIEF_SERVER",
        default_value = "ws://127.0.0.1:8080/v1/stream"
    )]
    server: String,
    /// Screen-space error threshold in pixels.
    #[arg(long, default_value_t = 1.0)]
    tau: f32,
    /// Bandwidth budget per session in bytes per second [default: none].
    #[arg(long)]
    budget: Option<u32>,
    /// Poses per second per session; 0 sends each pose as soon as the previous one is answered.
    #[arg(long, default_value_t = fly::DEFAULT_RATE_HZ)]
    rate: f64,
}

impl StreamArgs {
    fn session(&self) -> anyhow::Result<SessionConfig> {
        anyhow::ensure!(
            self.rate.is_finite() && self.rate >= 0.0,
            "--rate must be 0 or more"
        );
        Ok(SessionConfig {
            tau: self.tau,
            budget: self.budget,
            ..SessionConfig::new(&self.server)
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
    /// Run many sessions at once against a server and report bandwidth, latency, errors and the
    /// server's CPU and memory; with --sweep, run stages of growing size and find the knee.
    Load {
        #[command(flatten)]
        stream: StreamArgs,
        /// Concurrent sessions (ignored with --sweep).
        #[arg(long, default_value_t = 10)]
        sessions: usize,
        /// Seconds every session flies once all have started.
        #[arg(long, default_value_t = 30.0)]
        duration: f64,
        /// Which paths: `standard` or `stress` (phase-shifted per session), or `random`
        /// (a seeded loop per session).
        #[arg(long, default_value = "standard")]
        path: LoadPath,
        /// Seed of the random paths.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Seconds over which sessions start, evenly spread [default: 10% of the duration].
        #[arg(long)]
        ramp: Option<f64>,
        /// Rebuild fans as a viewer would (costs client CPU).
        #[arg(long)]
        mesh: bool,
        /// Run these session counts in turn (e.g. 10,100,500) and report the knee.
        #[arg(long, value_delimiter = ',')]
        sweep: Vec<usize>,
        /// The p99 latency in milliseconds above which a sweep stage counts as broken away.
        #[arg(long, default_value_t = 50.0)]
        knee_ms: f64,
        /// Write the JSON report to this file.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Write report.json, summary.md and PNG plots into this folder.
        #[arg(long)]
        report: Option<PathBuf>,
        /// Hide the progress bar.
        #[arg(long)]
        quiet: bool,
    },
}

fn main() -> std::process::ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_env("RELIEF_LOG")
                .unwrap_or_else(|_| "warn".into()),
        )
        .with_writer(std::io::stderr)
        .init();
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", relief_proto::errors::one_line(e.as_ref()));
            std::process::ExitCode::FAILURE
        }
    }
}

fn run() -> anyhow::Result<()> {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    match Cli::parse().command {
        Command::Fly { stream, path, json } => {
            let opts = FlyOptions {
                session: stream.session()?,
                path,
                rate_hz: stream.rate,
            };
            let report = rt.block_on(fly::fly(&opts))?;
            if json {
                println!("{}", serde_json::to_string(&report)?);
            } else {
                println!("{}", serde_json::to_string_pretty(&report)?);
            }
        }
        Command::Load {
            stream,
            sessions,
            duration,
            path,
            seed,
            ramp,
            mesh,
            sweep,
            knee_ms,
            json,
            report,
            quiet,
        } => {
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
                rate_hz: stream.rate,
                mesh,
                progress: !quiet,
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
