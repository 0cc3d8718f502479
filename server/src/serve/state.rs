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
    /// Bytes the session's LOD state holds.
    pub memory_bytes: AtomicU64,
}

/// One session as `GET /v1/sessions` lists it.
#[derive(Debug, Serialize)]
pub struct SessionReport {
    /// Session id, as in the welcome, in hex (a JSON number would lose bits in JavaScript).
    pub id: String,
    /// Client address.
    pub peer: String,
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
    /// Bytes of LOD state.
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
    /// Turns true when the server starts draining: sessions tell their clients to reconnect.
    pub draining: watch::Receiver<bool>,
    /// One-shot computations at once: waiting requests hold no body in memory (it stays in
    /// the socket until their turn), so a flood of them cannot grow the server.
    pub one_shots: tokio::sync::Semaphore,
    /// Where the pages' npm libraries are (`web/node_modules`; see [`super::pages`]).
    pub web_lib: std::path::PathBuf,
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
            draining,
            one_shots: tokio::sync::Semaphore::new(
                2 * std::thread::available_parallelism().map_or(2, |n| n.get()),
            ),
            web_lib: super::config::DEFAULT_WEB_LIB.into(),
        }
    }

    /// The state with the pages' libraries in `dir` instead of the default.
    pub fn with_web_lib(mut self, dir: std::path::PathBuf) -> AppState {
        self.web_lib = dir;
        self
    }

    /// The terrain, once ready.
    pub fn terrain(&self) -> Option<Arc<Terrain>> {
        self.terrain.get().cloned()
    }

    /// Registers a new session and returns its id and stats.
    pub fn register(&self, peer: SocketAddr) -> (u64, Arc<SessionStats>) {
        let id = self.next_id.fetch_add(1, Relaxed);
        let stats = Arc::new(SessionStats {
            peer,
            started: Instant::now(),
            deltas: AtomicU64::new(0),
            acked: AtomicU64::new(0),
            bytes_out: AtomicU64::new(0),
            active_nodes: AtomicU64::new(0),
            memory_bytes: AtomicU64::new(super::session::SOCKET_BYTES),
        });
        self.registry
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .insert(id, stats.clone());
        (id, stats)
    }

    /// Removes a session from the registry.
    pub fn unregister(&self, id: u64) {
        self.registry
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .remove(&id);
    }

    /// Every open session.
    pub fn session_reports(&self) -> Vec<SessionReport> {
        let reg = self.registry.lock().unwrap_or_else(|e| e.into_inner());
        let mut v: Vec<SessionReport> = reg
            .iter()
            .map(|(&id, s)| {
                let deltas = s.deltas.load(Relaxed);
                SessionReport {
                    id: format!("{id:016x}"),
                    peer: s.peer.to_string(),
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
