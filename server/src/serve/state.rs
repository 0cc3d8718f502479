//! The state every handler shares.

use super::config::Limits;
use super::limits::{IpBuckets, SlotLimits};
use super::metrics::Metrics;
use crate::formats::cesium::CesiumLayer;
use crate::formats::raster::{RasterLayer, TILE_SIZES};
use crate::geo::GeoTransform;
use crate::store::Store;
use relief_proto::msg::TerrainInfo;
use serde::Serialize;
use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::Instant;
use tokio::sync::watch;

/// The served terrain: the mapped store and what clients are told of it.
pub struct Terrain {
    /// The mapped store.
    pub store: Store,
    /// The metadata sent in welcomes and by `GET /v1/terrain`.
    pub info: TerrainInfo,
    /// The standard formats' view of the terrain, or why there is none (no georeference, or a
    /// CRS Relief cannot convert): `/cesium` and `/tiles` answer 404 with the reason.
    pub formats: Result<Formats, String>,
    /// The heights and max/min-mip pyramids the queries run on (`/v1/query`, query sessions,
    /// `/v1/raycast.png`), built with the terrain: about 0.15 s and 7 bytes per sample (4097 x 4097: 112 MB).
    pub query: Result<crate::query::Terrain, String>,
}

/// What the standard formats need of a georeferenced terrain, built once when it is loaded.
#[derive(Debug)]
pub struct Formats {
    /// Sample positions to and from longitude/latitude.
    pub geo: GeoTransform,
    /// The Cesium tiles that exist.
    pub cesium: CesiumLayer,
    /// The Web Mercator PNG tiles that exist, at 256 and 512 pixels.
    pub raster: [RasterLayer; 2],
}

impl Formats {
    fn new(store: &Store) -> Result<Formats, String> {
        let g = store.meta().georef.as_ref().ok_or_else(|| {
            "the terrain has no georeference (a PNG or synthetic DEM built without --origin \
             LON,LAT), so it has no place on the globe to serve standard tiles for"
                .to_string()
        })?;
        let geo = GeoTransform::new(g).map_err(|e| e.to_string())?;
        let shape = &store.geometry().shape;
        let cesium =
            CesiumLayer::new(&geo, shape.width(), shape.height()).map_err(|e| e.to_string())?;
        let [a, b] = TILE_SIZES.map(|s| RasterLayer::new(&geo, shape.width(), shape.height(), s));
        let raster = [a.map_err(|e| e.to_string())?, b.map_err(|e| e.to_string())?];
        Ok(Formats {
            geo,
            cesium,
            raster,
        })
    }
}

impl Terrain {
    /// Wraps an opened store.
    pub fn new(store: Store) -> Terrain {
        let g = store.geometry();
        let info = TerrainInfo {
            id: store.terrain_id(),
            width: g.shape.width(),
            height: g.shape.height(),
            spacing_x: g.frame.dx,
            spacing_y: g.frame.dy,
            z_quantum: g.z_quantum,
            root_z: store.root_z(),
            height_range: [
                store.meta().height_min as f32,
                store.meta().height_max as f32,
            ],
        };
        let formats = Formats::new(&store);
        let query = crate::query::Terrain::from_store(&store).map_err(|e| e.to_string());
        Terrain {
            store,
            info,
            formats,
            query,
        }
    }
}

/// What `GET /v1/sessions` reports of one session, updated by the session as it runs.
#[derive(Debug)]
pub struct SessionStats {
    /// The client's address.
    pub peer: SocketAddr,
    /// When the session began.
    pub started: Instant,
    /// Deltas sent.
    pub deltas: AtomicU64,
    /// Newest acknowledged delta.
    pub acked: AtomicU64,
    /// Message bytes sent.
    pub bytes_out: AtomicU64,
    /// Active nodes in the session's cut.
    pub active_nodes: AtomicU64,
    /// Bytes the session holds (see [`AppState::set_session_memory`]), as charged against the
    /// server's memory budget.
    pub memory_bytes: AtomicU64,
    /// The largest message received: the socket's read buffer grew to it and keeps it.
    pub largest_in: AtomicU64,
    /// The largest message sent: the socket's write buffer grew to it and keeps it.
    pub largest_out: AtomicU64,
}

impl SessionStats {
    /// What the session holds besides its LOD state or its answers: the socket's buffers.
    pub fn socket_bytes(&self) -> u64 {
        self.socket_bytes_with(0)
    }

    /// The socket's buffers while a message of `out` bytes waits to be sent.
    pub fn socket_bytes_with(&self, out: u64) -> u64 {
        super::session::SOCKET_BYTES
            + self.largest_in.load(Relaxed)
            + self.largest_out.load(Relaxed).max(out)
    }
}

/// One session as `GET /v1/sessions` lists it.
#[derive(Debug, Serialize)]
pub struct SessionReport {
    /// Session id, as in the welcome, in hex (a JSON number would lose bits in JavaScript).
    pub id: String,
    /// Client address: only for a request that carries the operator token.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peer: Option<String>,
    /// Seconds since the session began.
    pub age_s: f64,
    /// Deltas sent.
    pub deltas: u64,
    /// Deltas sent but not acknowledged.
    pub unacked: u64,
    /// Message bytes sent.
    pub bytes_out: u64,
    /// Active nodes in the cut.
    pub active_nodes: u64,
    /// Bytes the session holds: socket buffers, LOD state, answers waiting to be sent.
    pub memory_bytes: u64,
}

/// Shared server state.
pub struct AppState {
    /// The terrain, set once the store is mapped (`/readyz` turns ready then).
    pub terrain: OnceLock<Arc<Terrain>>,
    /// Limits from the configuration.
    pub limits: Limits,
    /// Counters for `/metrics`.
    pub metrics: Metrics,
    /// Session admission.
    pub sessions: SlotLimits,
    /// Connection admission (sessions are connections too).
    pub connections: SlotLimits,
    /// Resume work per address, in interior nodes of the resumed cuts.
    pub resume_work: IpBuckets,
    /// Large resumes being opened at once, each until its first delta: a flood of them waits
    /// its turn instead of taking every core.
    pub openings: tokio::sync::Semaphore,
    /// Open sessions by id, for `GET /v1/sessions`.
    pub registry: Mutex<HashMap<u64, Arc<SessionStats>>>,
    /// The next session id.
    next_id: AtomicU64,
    /// Bytes all sessions hold together, charged against `limits.memory_budget`.
    memory_used: AtomicU64,
    /// Turns true when the server starts draining: sessions tell their clients to reconnect.
    pub draining: watch::Receiver<bool>,
    /// The long computations (one-shots, query batches, pictures, raster tiles, large JSON,
    /// expensive sessions' updates), on threads of their own at a lower priority, a slot each.
    pub background: super::pool::Pool,
    /// Where the pages' npm libraries are (`web/node_modules`; see [`super::pages`]).
    pub web_lib: std::path::PathBuf,
    /// The scheme and host clients reach the server at (`https://terrain.example.com`), for
    /// the absolute URLs in TileJSON; without it the request's Host header is used.
    pub public_url: Option<String>,
}

impl AppState {
    /// State with `limits`, not yet ready; `draining` turns true on shutdown.
    pub fn new(limits: Limits, draining: watch::Receiver<bool>) -> AppState {
        AppState {
            terrain: OnceLock::new(),
            sessions: SlotLimits::new(limits.max_sessions, limits.max_sessions_per_ip),
            connections: SlotLimits::new(limits.max_connections, limits.max_connections_per_ip),
            resume_work: IpBuckets::new(
                limits.resume_nodes_per_s_per_ip,
                2.0 * limits.resume_nodes_per_s_per_ip,
            ),
            openings: tokio::sync::Semaphore::new(limits.max_openings as usize),
            limits,
            metrics: Metrics::default(),
            registry: Mutex::default(),
            // Ids start at a random-looking point so that two server lives rarely share ids.
            next_id: AtomicU64::new(
                std::time::SystemTime::now()
                    .duration_since(std::time::UNIX_EPOCH)
                    .map(|d| d.as_micros() as u64)
                    .unwrap_or(1)
                    << 8,
            ),
            memory_used: AtomicU64::new(0),
            draining,
            background: super::pool::Pool::new(
                2 * std::thread::available_parallelism().map_or(2, |n| n.get()),
            ),
            web_lib: super::config::DEFAULT_WEB_LIB.into(),
            public_url: None,
        }
    }

    /// The state with the pages' libraries in `dir` instead of the default.
    pub fn with_web_lib(mut self, dir: std::path::PathBuf) -> AppState {
        self.web_lib = dir;
        self
    }

    /// The state with `url` as the public URL (no trailing slash).
    pub fn with_public_url(mut self, url: Option<String>) -> AppState {
        self.public_url = url.map(|u| u.trim_end_matches('/').to_string());
        self
    }

    /// The terrain, once ready.
    pub fn terrain(&self) -> Option<Arc<Terrain>> {
        self.terrain.get().cloned()
    }

    /// Registers a new session and returns its id and stats, its socket's buffers charged
    /// against the memory budget; or why not, when the budget is spent.
    pub fn register(&self, peer: SocketAddr) -> Result<(u64, Arc<SessionStats>), String> {
        let stats = Arc::new(SessionStats {
            peer,
            started: Instant::now(),
            deltas: AtomicU64::new(0),
            acked: AtomicU64::new(0),
            bytes_out: AtomicU64::new(0),
            active_nodes: AtomicU64::new(0),
            memory_bytes: AtomicU64::new(0),
            largest_in: AtomicU64::new(0),
            largest_out: AtomicU64::new(0),
        });
        self.set_session_memory(&stats, super::session::SOCKET_BYTES)?;
        let id = self.next_id.fetch_add(1, Relaxed);
        self.registry
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .insert(id, stats.clone());
        Ok((id, stats))
    }

    /// Removes a session from the registry and gives its memory back to the budget.
    pub fn unregister(&self, id: u64) {
        let gone = self
            .registry
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .remove(&id);
        if let Some(s) = gone {
            let _ = self.set_session_memory(&s, 0);
        }
    }

    /// Sets what session `stats` holds to `bytes`, charged against the memory budget: growth
    /// that would pass the budget is refused (the session keeps its old figure) with the
    /// reason; shrinking always goes through.
    pub fn set_session_memory(&self, stats: &SessionStats, bytes: u64) -> Result<(), String> {
        let old = stats.memory_bytes.load(Relaxed);
        if bytes > old {
            let grow = bytes - old;
            let budget = self.limits.memory_budget;
            let took = self.memory_used.fetch_update(Relaxed, Relaxed, |used| {
                (used.saturating_add(grow) <= budget).then_some(used + grow)
            });
            if took.is_err() {
                return Err(format!(
                    "the server's memory budget of {} MiB for sessions is spent; retry later",
                    budget >> 20
                ));
            }
        } else {
            self.memory_used.fetch_sub(old - bytes, Relaxed);
        }
        stats.memory_bytes.store(bytes, Relaxed);
        Ok(())
    }

    /// Bytes all sessions hold together.
    pub fn sessions_memory(&self) -> u64 {
        self.memory_used.load(Relaxed)
    }

    /// Every open session, with the clients' addresses when `with_peers`.
    pub fn session_reports(&self, with_peers: bool) -> Vec<SessionReport> {
        let reg = self.registry.lock().unwrap_or_else(|e| e.into_inner());
        let mut v: Vec<SessionReport> = reg
            .iter()
            .map(|(&id, s)| {
                let deltas = s.deltas.load(Relaxed);
                SessionReport {
                    id: format!("{id:016x}"),
                    peer: with_peers.then(|| s.peer.to_string()),
                    age_s: s.started.elapsed().as_secs_f64(),
                    deltas,
                    unacked: deltas.saturating_sub(s.acked.load(Relaxed)),
                    bytes_out: s.bytes_out.load(Relaxed),
                    active_nodes: s.active_nodes.load(Relaxed),
                    memory_bytes: s.memory_bytes.load(Relaxed),
                }
            })
            .collect();
        v.sort_by(|a, b| a.id.cmp(&b.id));
        v
    }
}
