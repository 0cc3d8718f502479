//! `relief-client`: talk to a Relief server from the command line.
//! Thin: parse the arguments, set up tracing, call into the library.

use clap::{Parser, Subcommand};
use relief_client::fly::{self, FlyOptions};
use relief_client::session::SessionConfig;
use relief_proto::path::PathKind;

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

#[derive(Subcommand)]
enum Command {
    /// Fly one session along a camera path and print deltas, bandwidth, latency and desyncs.
    Fly {
        /// The stream's URL.
        #[arg(
            long,
            env = "RELIEF_SERVER",
            default_value = "ws://127.0.0.1:8080/v1/stream"
        )]
        server: String,
        /// Which path: `standard` (60 s loop, 100-300 m above ground) or `stress`.
        #[arg(long, default_value = "standard")]
        path: PathKind,
        /// Screen-space error threshold in pixels.
        #[arg(long, default_value_t = 1.0)]
        tau: f32,
        /// Bandwidth budget in bytes per second [default: none].
        #[arg(long)]
        budget: Option<u32>,
        /// Poses per second; 0 sends each pose as soon as the previous one is answered.
        #[arg(long, default_value_t = fly::DEFAULT_RATE_HZ)]
        rate: f64,
        /// Print one JSON object instead of an indented one.
        #[arg(long)]
        json: bool,
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
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn run() -> anyhow::Result<()> {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    match Cli::parse().command {
        Command::Fly {
            server,
            path,
            tau,
            budget,
            rate,
            json,
        } => {
            anyhow::ensure!(rate.is_finite() && rate >= 0.0, "--rate must be 0 or more");
            let opts = FlyOptions {
                session: SessionConfig {
                    tau,
                    budget,
                    ..SessionConfig::new(&server)
                },
                path,
                rate_hz: rate,
            };
            let report = rt.block_on(fly::fly(&opts))?;
            if json {
                println!("{}", serde_json::to_string(&report)?);
            } else {
                println!("{}", serde_json::to_string_pretty(&report)?);
            }
        }
    }
    Ok(())
}
