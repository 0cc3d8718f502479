//! Server configuration: command-line flags, then `RELIEF_*` environment variables, then an
//! optional TOML file, then the defaults, in that order of precedence.
//!
//! Every option is an `Option` in [`ServeArgs`] (clap fills it from a flag or its variable) and
//! in [`FileConfig`] (serde fills it from the file); [`ServeArgs::resolve`] takes the first one
//! set and falls back to [`Limits::default`] and the other defaults documented on each flag.

use serde::Deserialize;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The default listening address.
pub const DEFAULT_ADDR: &str = "127.0.0.1:8080";

/// The default folder of the pages' npm libraries: `web/node_modules` in the repository the
/// server was built from, where `npm ci --prefix web` installs them.
pub const DEFAULT_WEB_LIB: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../web/node_modules");

/// `relief-server serve` options. Each help text states the default.
#[derive(Clone, Debug, Default, clap::Args)]
pub struct ServeArgs {
    /// A store built by `relief-server build` [default: the embedded terrain].
    #[arg(long, env = "RELIEF_STORE", conflicts_with = "dem")]
    pub store: Option<PathBuf>,
    /// A DEM to build a store from on start (cached), in any form `build` reads (GeoTIFF, PNG,
    /// SRTM .hgt, terrain-RGB or Terrarium tiles with --encoding, `synthetic:SIZE[:SEED]`);
    /// several files after --dem make a mosaic, as for `build` (RELIEF_DEM holds one spec; the
    /// TOML file's `dem` one or a list) [default: the embedded terrain, a 257x193 crop of Mount
    /// Fuji].
    #[arg(long, env = "RELIEF_DEM", num_args = 1..)]
    pub dem: Vec<String>,
    /// How to read `--dem` (the same options as `build`; flags only, not in the TOML file).
    #[command(flatten)]
    pub dem_args: crate::dem::DemArgs,
    /// Address to listen on, `HOST:PORT` with a host name or an IP address (e.g.
    /// `localhost:8080`, `0.0.0.0:8080`, `[::1]:8080`) [default: 127.0.0.1:8080].
    #[arg(long, env = "RELIEF_ADDR")]
    pub addr: Option<String>,
    /// Where built stores are cached [default: $XDG_CACHE_HOME/relief, else ~/.cache/relief].
    #[arg(long, env = "RELIEF_CACHE_DIR")]
    pub cache_dir: Option<PathBuf>,
    /// A TOML file with any of these options, named as here with underscores
    /// (e.g. `max_sessions = 100`). Flags and environment variables override it.
    #[arg(long, env = "RELIEF_CONFIG")]
    pub config: Option<PathBuf>,
    /// Largest message a client may send, bytes [default: 1048576].
    #[arg(long, env = "RELIEF_MAX_MESSAGE_BYTES")]
    pub max_message_bytes: Option<u32>,
    /// Most sessions at once [default: 10000].
    #[arg(long, env = "RELIEF_MAX_SESSIONS")]
    pub max_sessions: Option<u32>,
    /// Most sessions at once from one IP address [default: 1000].
    #[arg(long, env = "RELIEF_MAX_SESSIONS_PER_IP")]
    pub max_sessions_per_ip: Option<u32>,
    /// Close a session after this many seconds without a message from its client [default: 60].
    #[arg(long, env = "RELIEF_IDLE_TIMEOUT_S")]
    pub idle_timeout_s: Option<f64>,
    /// Drop a connection whose request headers take longer than this, seconds (against
    /// slowloris) [default: 10].
    #[arg(long, env = "RELIEF_HEADER_TIMEOUT_S")]
    pub header_timeout_s: Option<f64>,
    /// New connections per second allowed from one IP address, with a burst of twice as many
    /// [default: 100].
    #[arg(long, env = "RELIEF_CONN_RATE_PER_IP")]
    pub conn_rate_per_ip: Option<f64>,
    /// Deltas a session may have unacknowledged [default: 4].
    #[arg(long, env = "RELIEF_MAX_IN_FLIGHT")]
    pub max_in_flight: Option<u32>,
    /// Most interior nodes in a session's cut or in a resume or base snapshot; a session whose
    /// cut reaches it is closed (raise tau or shrink the viewport) [default: 8000000].
    #[arg(long, env = "RELIEF_MAX_CUT_NODES")]
    pub max_cut_nodes: Option<u32>,
    /// On SIGTERM or Ctrl-C, seconds to wait for sessions to close before exiting [default: 5].
    #[arg(long, env = "RELIEF_DRAIN_TIMEOUT_S")]
    pub drain_timeout_s: Option<f64>,
    /// Answer 408 to a request whose body has not fully arrived this many seconds after its
    /// headers (against slow bodies) [default: 10].
    #[arg(long, env = "RELIEF_BODY_TIMEOUT_S")]
    pub body_timeout_s: Option<f64>,
    /// Most open connections (HTTP and WebSocket); lowered to fit the process's open-file
    /// limit. Past it, `/healthz` and `/readyz` still answer and everything else gets 503
    /// [default: 16384, or max_sessions + 1000 if more].
    #[arg(long, env = "RELIEF_MAX_CONNECTIONS")]
    pub max_connections: Option<u32>,
    /// Most open connections from one IP address [default: max_sessions_per_ip + 100].
    #[arg(long, env = "RELIEF_MAX_CONNECTIONS_PER_IP")]
    pub max_connections_per_ip: Option<u32>,
    /// Large resumes (over 100,000 interior nodes) opened at once, each until its first delta
    /// has examined the whole resumed cut; more wait their turn [default: half the cores, at
    /// least 1].
    #[arg(long, env = "RELIEF_MAX_OPENINGS")]
    pub max_openings: Option<u32>,
    /// Resume work one IP address may ask for, in interior nodes of resumed cuts per second
    /// (bursts of twice as many); a resume over it waits, or is refused when the wait would
    /// pass 10 s [default: 1000000].
    #[arg(long, env = "RELIEF_RESUME_NODES_PER_S_PER_IP")]
    pub resume_nodes_per_s_per_ip: Option<f64>,
    /// Close an HTTP connection whose client has read nothing of its response for this many
    /// seconds, and free the response (sessions close such a client as a slow reader after
    /// `idle_timeout_s` instead) [default: 20].
    #[arg(long, env = "RELIEF_WRITE_TIMEOUT_S")]
    pub write_timeout_s: Option<f64>,
    /// Memory all sessions together may hold, MiB: their LOD state, their query answers
    /// waiting to be sent, their buffers. A session that would take more is refused or closed
    /// with `server_full` (1013, retry later), a query batch answered with an error [default: a
    /// quarter of the machine's memory, or of the cgroup's limit].
    #[arg(long, env = "RELIEF_MEMORY_BUDGET_MB")]
    pub memory_budget_mb: Option<u64>,
    /// A secret that operators send as `Authorization: Bearer <token>` to see each session's
    /// address in `GET /v1/sessions`; without it the addresses are left out [default: none,
    /// addresses never shown].
    #[arg(long, env = "RELIEF_OPERATOR_TOKEN", hide_env_values = true)]
    pub operator_token: Option<String>,
    /// The URL clients reach the server at, as `SCHEME://HOST[:PORT]` (e.g.
    /// `https://terrain.example.com`), written into the tile URLs of the TileJSONs. Set it
    /// behind a proxy or cache [default: none: the request's Host header, checked to be a host
    /// name, with `Vary: Host`].
    #[arg(long, env = "RELIEF_PUBLIC_URL")]
    pub public_url: Option<String>,
    /// The npm packages of the `/cesium/` and `/maplibre/` pages, as `npm ci --prefix web`
    /// installs them: `/lib/cesium/` serves its `cesium/Build/Cesium` and `/lib/maplibre-gl/`
    /// its `maplibre-gl/dist` [default: web/node_modules in the repository the server was built
    /// from].
    #[arg(long, env = "RELIEF_WEB_LIB")]
    pub web_lib: Option<PathBuf>,
}

/// The TOML file: the same options as the flags.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FileConfig {
    /// See [`ServeArgs::store`].
    pub store: Option<PathBuf>,
    /// See [`ServeArgs::dem`]: one DEM, or a list of files for a mosaic.
    pub dem: Option<DemSpecs>,
    /// See [`ServeArgs::addr`].
    pub addr: Option<String>,
    /// See [`ServeArgs::cache_dir`].
    pub cache_dir: Option<PathBuf>,
    /// See [`ServeArgs::max_message_bytes`].
    pub max_message_bytes: Option<u32>,
    /// See [`ServeArgs::max_sessions`].
    pub max_sessions: Option<u32>,
    /// See [`ServeArgs::max_sessions_per_ip`].
    pub max_sessions_per_ip: Option<u32>,
    /// See [`ServeArgs::idle_timeout_s`].
    pub idle_timeout_s: Option<f64>,
    /// See [`ServeArgs::header_timeout_s`].
    pub header_timeout_s: Option<f64>,
    /// See [`ServeArgs::conn_rate_per_ip`].
    pub conn_rate_per_ip: Option<f64>,
    /// See [`ServeArgs::max_in_flight`].
    pub max_in_flight: Option<u32>,
    /// See [`ServeArgs::max_cut_nodes`].
    pub max_cut_nodes: Option<u32>,
    /// See [`ServeArgs::drain_timeout_s`].
    pub drain_timeout_s: Option<f64>,
    /// See [`ServeArgs::body_timeout_s`].
    pub body_timeout_s: Option<f64>,
    /// See [`ServeArgs::max_connections`].
    pub max_connections: Option<u32>,
    /// See [`ServeArgs::max_connections_per_ip`].
    pub max_connections_per_ip: Option<u32>,
    /// See [`ServeArgs::max_openings`].
    pub max_openings: Option<u32>,
    /// See [`ServeArgs::resume_nodes_per_s_per_ip`].
    pub resume_nodes_per_s_per_ip: Option<f64>,
    /// See [`ServeArgs::write_timeout_s`].
    pub write_timeout_s: Option<f64>,
    /// See [`ServeArgs::memory_budget_mb`].
    pub memory_budget_mb: Option<u64>,
    /// See [`ServeArgs::operator_token`].
    pub operator_token: Option<String>,
    /// See [`ServeArgs::public_url`].
    pub public_url: Option<String>,
    /// See [`ServeArgs::web_lib`].
    pub web_lib: Option<PathBuf>,
}

/// The TOML file's `dem`: one spec, or a list of files for a mosaic.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum DemSpecs {
    /// `dem = "N35E138.hgt"`.
    One(String),
    /// `dem = ["N35E138.hgt", "N35E139.hgt"]`.
    Many(Vec<String>),
}

impl DemSpecs {
    /// The specs as a list.
    pub fn into_vec(self) -> Vec<String> {
        match self {
            DemSpecs::One(s) => vec![s],
            DemSpecs::Many(v) => v,
        }
    }
}

/// Which terrain to serve.
#[derive(Clone, Debug, PartialEq)]
pub enum TerrainSource {
    /// The crop committed to the repository, built into the cache on first start.
    Embedded,
    /// A store file, mapped as it is.
    Store(PathBuf),
    /// A DEM (or the files of a mosaic) and how to read it, built into the cache on first
    /// start.
    Dem(Vec<String>, crate::dem::LoadOptions),
}

/// The limits that protect the server from its clients.
#[derive(Clone, Debug, PartialEq)]
pub struct Limits {
    /// Largest client message, bytes.
    pub max_message_bytes: u32,
    /// Most sessions at once.
    pub max_sessions: u32,
    /// Most sessions at once per IP address.
    pub max_sessions_per_ip: u32,
    /// Longest silence from a client before its session closes.
    pub idle_timeout: Duration,
    /// Longest time a connection may take to send its request headers.
    pub header_timeout: Duration,
    /// Connections per second per IP address (burst: twice this).
    pub conn_rate_per_ip: f64,
    /// Unacknowledged deltas per session.
    pub max_in_flight: u32,
    /// Interior nodes a session's cut or a snapshot may hold.
    pub max_cut_nodes: u32,
    /// Longest wait for sessions to end on shutdown.
    pub drain_timeout: Duration,
    /// Longest time a request body may take to arrive after the headers.
    pub body_timeout: Duration,
    /// Most open connections (before the open-file limit lowers it).
    pub max_connections: u32,
    /// Most open connections per IP address.
    pub max_connections_per_ip: u32,
    /// Large resumes opened at once (each until its first delta).
    pub max_openings: u32,
    /// Interior nodes of resumed cuts per second per IP address.
    pub resume_nodes_per_s_per_ip: f64,
    /// Longest an HTTP response may wait for its client to read any of it.
    pub write_timeout: Duration,
    /// Bytes all sessions together may hold.
    pub memory_budget: u64,
    /// What shows `GET /v1/sessions`'s addresses, if anything.
    pub operator_token: Option<Secret>,
}

/// A secret: compared, never printed (the configuration is logged at start).
#[derive(Clone, PartialEq, Eq)]
pub struct Secret(pub String);

impl std::fmt::Debug for Secret {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Secret(..)")
    }
}

/// The default memory budget: a quarter of the memory this process may use (the cgroup's
/// limit where there is one, else the machine's; [`crate::sysmem::usable_memory`]), or 1 GiB
/// where neither can be read.
pub fn default_memory_budget() -> u64 {
    crate::sysmem::usable_memory().map_or(1 << 30, |m| m / 4)
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_message_bytes: 1 << 20,
            max_sessions: 10_000,
            max_sessions_per_ip: 1000,
            idle_timeout: Duration::from_secs(60),
            header_timeout: Duration::from_secs(10),
            conn_rate_per_ip: 100.0,
            max_in_flight: 4,
            max_cut_nodes: 8_000_000,
            drain_timeout: Duration::from_secs(5),
            body_timeout: Duration::from_secs(10),
            max_connections: 16_384,
            max_connections_per_ip: 1100,
            max_openings: std::thread::available_parallelism()
                .map_or(1, |n| (n.get() as u32 / 2).max(1)),
            resume_nodes_per_s_per_ip: 1.0e6,
            write_timeout: Duration::from_secs(20),
            memory_budget: default_memory_budget(),
            operator_token: None,
        }
    }
}

/// The resolved configuration.
#[derive(Clone, Debug, PartialEq)]
pub struct ServeConfig {
    /// The terrain.
    pub source: TerrainSource,
    /// Where to listen.
    pub addr: SocketAddr,
    /// Where built stores are cached.
    pub cache_dir: PathBuf,
    /// The limits.
    pub limits: Limits,
    /// Where the pages' npm libraries are (`web/node_modules`).
    pub web_lib: PathBuf,
    /// See [`ServeArgs::public_url`].
    pub public_url: Option<String>,
}

/// A configuration that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The TOML file cannot be read.
    #[error("cannot read the config file {path}: {source}")]
    Read {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// The TOML file does not parse or names an unknown option.
    #[error("config file {path}: {message}")]
    Parse {
        /// The file.
        path: String,
        /// The parser's message.
        message: String,
    },
    /// An option is out of range.
    #[error("{0}")]
    Invalid(String),
}

/// The first socket address `HOST:PORT` resolves to (host names included).
fn resolve_addr(a: &str) -> Result<SocketAddr, ConfigError> {
    use std::net::ToSocketAddrs;
    let hint = "give HOST:PORT, e.g. 127.0.0.1:8080, localhost:8080 or 0.0.0.0:8080";
    match a.to_socket_addrs() {
        Ok(mut addrs) => addrs.next().ok_or_else(|| {
            ConfigError::Invalid(format!("address {a:?} resolves to nothing; {hint}"))
        }),
        Err(e) => Err(ConfigError::Invalid(format!("address {a:?}: {e}; {hint}"))),
    }
}

fn seconds(name: &str, s: f64) -> Result<Duration, ConfigError> {
    if s.is_finite() && s > 0.0 && s < 1e7 {
        Ok(Duration::from_secs_f64(s))
    } else {
        Err(ConfigError::Invalid(format!(
            "{name} must be a positive number of seconds, got {s}"
        )))
    }
}

fn positive(name: &str, v: u32) -> Result<u32, ConfigError> {
    if v > 0 {
        Ok(v)
    } else {
        Err(ConfigError::Invalid(format!("{name} must be at least 1")))
    }
}

fn rate_of(name: &str, r: f64) -> Result<f64, ConfigError> {
    if r.is_finite() && r > 0.0 {
        Ok(r)
    } else {
        Err(ConfigError::Invalid(format!(
            "{name} must be a positive number, got {r}"
        )))
    }
}

/// The default cache folder.
pub fn default_cache_dir() -> PathBuf {
    if let Some(x) = std::env::var_os("XDG_CACHE_HOME").filter(|x| !x.is_empty()) {
        return PathBuf::from(x).join("relief");
    }
    if let Some(h) = std::env::var_os("HOME").filter(|h| !h.is_empty()) {
        return PathBuf::from(h).join(".cache").join("relief");
    }
    std::env::temp_dir().join("relief-cache")
}

fn read_file(path: &Path) -> Result<FileConfig, ConfigError> {
    let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
        path: path.display().to_string(),
        source,
    })?;
    toml::from_str(&text).map_err(|e| ConfigError::Parse {
        path: path.display().to_string(),
        message: e.message().to_string(),
    })
}

impl ServeArgs {
    /// Flags and variables first, then the TOML file, then the defaults.
    pub fn resolve(&self) -> Result<ServeConfig, ConfigError> {
        let file = match &self.config {
            Some(p) => read_file(p)?,
            None => FileConfig::default(),
        };
        let d = Limits::default();
        let store = self.store.clone().or(file.store);
        let dem = match (self.dem.is_empty(), file.dem.map(DemSpecs::into_vec)) {
            (false, _) => Some(self.dem.clone()),
            (true, Some(d)) if d.is_empty() => {
                return Err(ConfigError::Invalid(
                    "dem is an empty list; name a DEM, or leave dem out for the embedded terrain"
                        .into(),
                ));
            }
            (true, d) => d,
        };
        let source = match (store, dem) {
            (Some(_), Some(_)) => {
                return Err(ConfigError::Invalid(
                    "give either a store or a DEM, not both".into(),
                ));
            }
            (Some(s), None) => TerrainSource::Store(s),
            (None, Some(d)) => TerrainSource::Dem(d, self.dem_args.options()),
            (None, None) => TerrainSource::Embedded,
        };
        let rate = rate_of(
            "conn_rate_per_ip",
            self.conn_rate_per_ip
                .or(file.conn_rate_per_ip)
                .unwrap_or(d.conn_rate_per_ip),
        )?;
        let max_message_bytes = positive(
            "max_message_bytes",
            self.max_message_bytes
                .or(file.max_message_bytes)
                .unwrap_or(d.max_message_bytes),
        )?;
        if max_message_bytes < 256 || max_message_bytes as usize > relief_proto::codec::HARD_LIMIT {
            return Err(ConfigError::Invalid(format!(
                "max_message_bytes must be between 256 and {}, got {max_message_bytes}",
                relief_proto::codec::HARD_LIMIT
            )));
        }
        let max_sessions = positive(
            "max_sessions",
            self.max_sessions
                .or(file.max_sessions)
                .unwrap_or(d.max_sessions),
        )?;
        let max_sessions_per_ip = positive(
            "max_sessions_per_ip",
            self.max_sessions_per_ip
                .or(file.max_sessions_per_ip)
                .unwrap_or(d.max_sessions_per_ip),
        )?;
        let limits = Limits {
            max_message_bytes,
            max_sessions,
            max_sessions_per_ip,
            idle_timeout: match self.idle_timeout_s.or(file.idle_timeout_s) {
                Some(s) => seconds("idle_timeout_s", s)?,
                None => d.idle_timeout,
            },
            header_timeout: match self.header_timeout_s.or(file.header_timeout_s) {
                Some(s) => seconds("header_timeout_s", s)?,
                None => d.header_timeout,
            },
            conn_rate_per_ip: rate,
            max_in_flight: positive(
                "max_in_flight",
                self.max_in_flight
                    .or(file.max_in_flight)
                    .unwrap_or(d.max_in_flight),
            )?,
            max_cut_nodes: positive(
                "max_cut_nodes",
                self.max_cut_nodes
                    .or(file.max_cut_nodes)
                    .unwrap_or(d.max_cut_nodes),
            )?,
            drain_timeout: match self.drain_timeout_s.or(file.drain_timeout_s) {
                Some(s) => seconds("drain_timeout_s", s)?,
                None => d.drain_timeout,
            },
            body_timeout: match self.body_timeout_s.or(file.body_timeout_s) {
                Some(s) => seconds("body_timeout_s", s)?,
                None => d.body_timeout,
            },
            max_connections: positive(
                "max_connections",
                self.max_connections
                    .or(file.max_connections)
                    .unwrap_or(d.max_connections.max(max_sessions.saturating_add(1000))),
            )?,
            // Every session is a connection: by default an address may hold its sessions
            // and a hundred HTTP connections besides.
            max_connections_per_ip: positive(
                "max_connections_per_ip",
                self.max_connections_per_ip
                    .or(file.max_connections_per_ip)
                    .unwrap_or(max_sessions_per_ip.saturating_add(100)),
            )?,
            max_openings: positive(
                "max_openings",
                self.max_openings
                    .or(file.max_openings)
                    .unwrap_or(d.max_openings),
            )?,
            resume_nodes_per_s_per_ip: rate_of(
                "resume_nodes_per_s_per_ip",
                self.resume_nodes_per_s_per_ip
                    .or(file.resume_nodes_per_s_per_ip)
                    .unwrap_or(d.resume_nodes_per_s_per_ip),
            )?,
            write_timeout: match self.write_timeout_s.or(file.write_timeout_s) {
                Some(s) => seconds("write_timeout_s", s)?,
                None => d.write_timeout,
            },
            memory_budget: match self.memory_budget_mb.or(file.memory_budget_mb) {
                Some(0) => {
                    return Err(ConfigError::Invalid(
                        "memory_budget_mb must be positive".into(),
                    ));
                }
                Some(mb) => mb.saturating_mul(1 << 20),
                None => d.memory_budget,
            },
            operator_token: match self.operator_token.clone().or(file.operator_token) {
                Some(t) if t.trim().is_empty() => {
                    return Err(ConfigError::Invalid(
                        "operator_token must not be empty".into(),
                    ));
                }
                t => t.map(Secret),
            },
        };
        let addr = resolve_addr(
            self.addr
                .clone()
                .or(file.addr)
                .as_deref()
                .unwrap_or(DEFAULT_ADDR),
        )?;
        Ok(ServeConfig {
            source,
            addr,
            cache_dir: self
                .cache_dir
                .clone()
                .or(file.cache_dir)
                .unwrap_or_else(default_cache_dir),
            limits,
            web_lib: self
                .web_lib
                .clone()
                .or(file.web_lib)
                .unwrap_or_else(|| PathBuf::from(DEFAULT_WEB_LIB)),
            public_url: match self.public_url.clone().or(file.public_url) {
                Some(u) if !(u.starts_with("http://") || u.starts_with("https://")) => {
                    return Err(ConfigError::Invalid(format!(
                        "public_url {u:?} must start with http:// or https://"
                    )));
                }
                u => u,
            },
        })
    }
}

#[cfg(test)]
mod tests;
