//! `relief-wasm`: the browser page's stream session, `relief-proto` compiled to WebAssembly so
//! that the page and the server share one codec. A session carries either stream:
//! tiles (the default), or the vertex stream (`?stream=vertex`), whose mirror, incremental fans
//! and GPU records ([`Scene`]) are the wgpu client's own.
//!
//! It is sans IO: the page owns the WebSocket, the timers and WebGL; this crate turns the
//! page's intentions into message bytes ([`TileSession::hello`], [`TileSession::pose`],
//! [`TileSession::ack`]) and server messages into a [`TileMirror`] checked by digest
//! ([`TileSession::receive`]), and hands each held tile's triangles to the page as typed arrays
//! ([`TileSession::geometry`]): world positions with their morph targets, smooth normals and
//! indices, mesh first, then its crack patches (or skirts), exactly what the wgpu client draws
//! (`relief_proto::tile::draw::TileMesh`), and which added tiles morph in
//! ([`TileSession::split_added`]).
//!
//! The session follows `docs/protocol.md` sections 4, 9, 10, 13 and 15: poses are numbered
//! from 1 across reconnects, deltas must arrive in sequence and match their digest, a resumed
//! welcome keeps the active tiles (and drops the cached ones, as the server does), any other
//! welcome starts from an empty mirror.
//!
//! **Vertex stream.** Each delta is applied to the [`Mirror`] (digest checked), the fan mesh
//! follows change by change, and the [`Scene`]'s node and cell records follow the fans; the page
//! uploads the rows of records that changed ([`TileSession::take_node_rows`],
//! [`TileSession::take_cell_rows`]) into two textures and draws every cell's two triangles,
//! geomorphing each corner in the vertex shader from its ancestors' screen errors
//! ([`TileSession::morph_block`] gives the view's planes and focal length for that).

use relief_proto::close::CloseReason;
use relief_proto::codec::{HARD_LIMIT, decode, encode};
use relief_proto::delta::{BodyModels, Known};
use relief_proto::mesh::scene::{Pool, Scene};
use relief_proto::mesh::{FanMesh, MorphRule};
use relief_proto::mirror::{Change, Mirror};
use relief_proto::msg::{
    ClientMsg, CrackMode, Hello, PROTOCOL_VERSION, Resume, ServerMsg, StreamKind, TerrainInfo,
    TileStreamParams, Welcome, WireCamera, WireLens,
};
use relief_proto::path::{PathKind, camera_path};
use relief_proto::snapshot::Snapshot;
use relief_proto::terrain::TerrainGeometry;
use relief_proto::tile::TileSetInfo;
use relief_proto::tile::draw::{TileMesh, arrived_by_split};
use relief_proto::tile::mirror::TileMirror;
use relief_proto::view::{Camera, ViewState};
use std::cell::RefCell;
use wasm_bindgen::prelude::*;

/// What a session holds once welcomed.
struct Welcomed {
    /// The terrain, as the welcome described it.
    terrain: TerrainInfo,
    /// Grid to world metres, and the height quantum.
    geom: TerrainGeometry,
    /// The stream's own state.
    stream: Stream,
}

/// A stream's client state.
enum Stream {
    /// The tile pyramid and the held tiles.
    Tiles {
        info: TileSetInfo,
        mirror: TileMirror,
    },
    /// The mirrored cut, its fans and their GPU records; `changes` is a buffer kept between
    /// deltas; `models` are the connection's delta-body models (protocol section 5.2), fresh
    /// with every welcome.
    Vertex {
        mirror: Box<Mirror>,
        mesh: Box<FanMesh>,
        scene: Box<Scene>,
        changes: Vec<Change>,
        models: Box<BodyModels>,
    },
}

impl Welcomed {
    fn tiles(&self) -> Option<(&TileSetInfo, &TileMirror)> {
        match &self.stream {
            Stream::Tiles { info, mirror } => Some((info, mirror)),
            Stream::Vertex { .. } => None,
        }
    }

    /// The resume snapshot, if there is anything to resume.
    fn snapshot(&self) -> Option<Snapshot> {
        match &self.stream {
            Stream::Tiles { mirror, .. } => {
                (!mirror.active().is_empty()).then(|| mirror.snapshot())
            }
            Stream::Vertex { mirror, .. } => Some(Snapshot::of(&self.geom.shape, mirror.cut())),
        }
    }

    fn digest(&self) -> u64 {
        match &self.stream {
            Stream::Tiles { mirror, .. } => mirror.digest(),
            Stream::Vertex { mirror, .. } => mirror.cut().digest(),
        }
    }
}

/// Texels per row of the node texture (RGBA32UI, three texels a record: 256 records a row).
const NODE_ROW_TEXELS: usize = 768;
/// Texels per row of the cell texture (R32UI, one node slot a texel).
const CELL_ROW_TEXELS: usize = 4096;

/// The rows of `pool`'s words (as a texture of `row_words` words a row) that changed since the
/// last call: `[rows in all, then for each run: first row, row count, its words...]`; every row
/// when the pool grew (the texture must be made anew at the new height).
fn row_updates(pool: &mut Pool, row_words: usize) -> Vec<u32> {
    let rows = pool.words().len().div_ceil(row_words);
    let grown = pool.grown();
    let runs = pool.take_dirty();
    let mut ranges: Vec<(usize, usize)> = Vec::new();
    if grown {
        ranges.push((0, rows));
    } else {
        for (first, count) in runs {
            let (a, b) = (first / row_words, (first + count).div_ceil(row_words));
            match ranges.last_mut() {
                Some((_, end)) if *end >= a => *end = (*end).max(b),
                _ => ranges.push((a, b)),
            }
        }
    }
    let words = pool.words();
    let mut out = vec![rows as u32];
    for (a, b) in ranges {
        out.extend([a as u32, (b - a) as u32]);
        let end = (b * row_words).min(words.len());
        out.extend_from_slice(&words[a * row_words..end]);
        // The last row of a pool that does not fill it.
        out.extend(std::iter::repeat_n(u32::MAX, b * row_words - end));
    }
    out
}

/// A tile session's state, without the socket.
#[wasm_bindgen]
pub struct TileSession {
    lens: WireLens,
    tau: f32,
    /// The tile stream's parameters; `None` for the vertex stream.
    params: Option<TileStreamParams>,
    state: Option<Welcomed>,
    /// The last pose's sequence number (poses are numbered from 1, across reconnects).
    pose_seq: u64,
    /// The newest delta applied on this connection.
    applied: u64,
    /// The newest answered pose and whether its delta was complete.
    answered: (u64, bool),
    session_id: u64,
    max_in_flight: u32,
    idle_timeout_ms: u32,
    reconnect_after_ms: u32,
    removed: Vec<u32>,
    added: Vec<u32>,
    evicted: Vec<u32>,
    sent: u32,
}

/// A held tile's triangles in world metres.
#[wasm_bindgen]
pub struct TileGeometry {
    mesh: TileMesh,
    level: u8,
}

#[wasm_bindgen]
impl TileGeometry {
    /// Vertices, four floats each: `x, y, z` world metres (x east, y north, z up), then the
    /// morph target's `z` (the height on the parent's mesh; `z` itself where the vertex never
    /// moves).
    pub fn positions(&self) -> Vec<f32> {
        self.mesh.positions.clone()
    }

    /// Smooth normals, four floats a vertex: `x, y` of the unit upward normal of the tile's own
    /// mesh, then of the morph target's (`z` follows, as they point up); `0, 0` on the
    /// vertices of patches and skirts alone.
    pub fn normals(&self) -> Vec<f32> {
        self.mesh.normals.clone()
    }

    /// Triangle indices: the mesh's, then the crack patches' (or skirts'), three per triangle.
    pub fn indices(&self) -> Vec<u32> {
        self.mesh.indices.clone()
    }

    /// Triangles of the tile's own surface (the first `3 * mesh_triangles` indices).
    #[wasm_bindgen(getter)]
    pub fn mesh_triangles(&self) -> u32 {
        self.mesh.counts[0]
    }

    /// Crack patch or skirt triangles (the indices after the mesh's).
    #[wasm_bindgen(getter)]
    pub fn extra_triangles(&self) -> u32 {
        self.mesh.counts[1..].iter().sum()
    }

    /// The tile's level in the pyramid (0 is the root tile).
    #[wasm_bindgen(getter)]
    pub fn level(&self) -> u8 {
        self.level
    }
}

fn crack_mode(s: &str) -> Result<CrackMode, JsError> {
    match s {
        "patches" => Ok(CrackMode::Patches),
        "skirts" => Ok(CrackMode::Skirts),
        "none" => Ok(CrackMode::None),
        _ => Err(JsError::new(&format!(
            "unknown crack mode {s:?}: use patches, skirts or none"
        ))),
    }
}

#[wasm_bindgen]
impl TileSession {
    /// A session for a `width` x `height` pixel viewport with a vertical field of view of
    /// `fov_y_deg` degrees and a near plane `near` metres away, screen error `tau` pixels, on
    /// `stream` `tiles` (then `crack` is one of `patches`, `skirts`, `none`, and at most
    /// `cache_tiles` tiles are kept) or `vertex`.
    #[wasm_bindgen(constructor)]
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        width: u32,
        height: u32,
        fov_y_deg: f32,
        near: f32,
        tau: f32,
        stream: &str,
        crack: &str,
        cache_tiles: u32,
    ) -> Result<TileSession, JsError> {
        let params = match stream {
            "tiles" => Some(TileStreamParams {
                cache_tiles,
                crack: crack_mode(crack)?,
            }),
            "vertex" => None,
            _ => {
                return Err(JsError::new(&format!(
                    "unknown stream {stream:?}: use tiles or vertex"
                )));
            }
        };
        Ok(TileSession {
            lens: WireLens {
                width,
                height,
                fov_y_deg,
                near,
            },
            tau,
            params,
            state: None,
            pose_seq: 0,
            applied: 0,
            answered: (0, false),
            session_id: 0,
            max_in_flight: 1,
            idle_timeout_ms: 60_000,
            reconnect_after_ms: 0,
            removed: Vec::new(),
            added: Vec::new(),
            evicted: Vec::new(),
            sent: 0,
        })
    }

    /// Changes the viewport and tau for the next hello (they are fixed for a connection).
    pub fn set_view(&mut self, width: u32, height: u32, tau: f32) {
        self.lens.width = width;
        self.lens.height = height;
        self.tau = tau;
    }

    /// The hello for a new connection: a resume from the mirror (the active tiles when it holds
    /// any, the cut), else a new session.
    pub fn hello(&self) -> Vec<u8> {
        let resume = self.state.as_ref().and_then(|s| {
            s.snapshot().map(|snapshot| Resume {
                terrain_id: s.terrain.id,
                snapshot,
            })
        });
        encode(&ClientMsg::Hello(Hello {
            version: PROTOCOL_VERSION,
            kind: self.params.map_or(StreamKind::Vertex, StreamKind::Tiles),
            lens: self.lens,
            tau: self.tau,
            budget: None,
            resume,
        }))
    }

    /// Whether the next hello resumes.
    #[wasm_bindgen(getter)]
    pub fn resuming(&self) -> bool {
        self.state.as_ref().is_some_and(|s| s.snapshot().is_some())
    }

    /// Forgets the mirror: the next hello starts a new session (after a desync, or a resume the
    /// server refused).
    pub fn reset(&mut self) {
        self.state = None;
    }

    /// A pose: eye `x, y, z` world metres, `yaw` and `pitch` radians; numbered from 1.
    pub fn pose(&mut self, x: f32, y: f32, z: f32, yaw: f32, pitch: f32) -> Vec<u8> {
        self.pose_seq += 1;
        encode(&ClientMsg::Pose {
            seq: self.pose_seq,
            camera: WireCamera {
                eye: [x, y, z],
                yaw,
                pitch,
            },
        })
    }

    /// The acknowledgement of every delta applied on this connection.
    pub fn ack(&self) -> Vec<u8> {
        encode(&ClientMsg::Ack { seq: self.applied })
    }

    /// Decodes and applies one server message at `now` (seconds on the page's drawing clock:
    /// the split time of the vertex stream's geomorph). Returns `welcome` (a new session: drop
    /// everything drawn), `resumed` (the active tiles or the cut stay; cached tiles are gone),
    /// `delta` (see [`Self::removed`], [`Self::added`], [`Self::evicted`], or the vertex
    /// stream's record rows) or `reconnect` (close, wait [`Self::reconnect_after_ms`],
    /// reconnect). An error is a desync or a protocol fault: close, [`Self::reset`] and
    /// reconnect.
    pub fn receive(&mut self, bytes: &[u8], now: f32) -> Result<String, JsError> {
        let msg: ServerMsg =
            decode(bytes, HARD_LIMIT).map_err(|e| JsError::new(&format!("bad message: {e}")))?;
        match msg {
            ServerMsg::Welcome(w) => self.welcome(w).map(str::to_string),
            ServerMsg::Delta(d) => {
                let state = self
                    .state
                    .as_mut()
                    .ok_or_else(|| JsError::new("a delta before the welcome"))?;
                if d.delta.seq != self.applied + 1 {
                    return Err(JsError::new(&format!(
                        "delta {} after delta {}",
                        d.delta.seq, self.applied
                    )));
                }
                let geom = &state.geom;
                match &mut state.stream {
                    Stream::Tiles { mirror, .. } => {
                        let c = mirror
                            .apply(&d.delta)
                            .map_err(|e| JsError::new(&format!("desync: {e}")))?;
                        self.removed = c.removed;
                        self.added = c.added;
                        self.evicted = c.evicted;
                        self.sent = c.sent as u32;
                    }
                    Stream::Vertex {
                        mirror,
                        mesh,
                        scene,
                        changes,
                        models,
                    } => {
                        let delta = d
                            .delta
                            .unpack_in(&geom.shape, geom.z_quantum, models, Known::mirror(mirror))
                            .map_err(|e| JsError::new(&format!("desync: bad delta: {e}")))?;
                        changes.clear();
                        mirror
                            .apply(geom, &delta, |cut, change| {
                                mesh.update_around(&geom.shape, cut, change.node());
                                changes.push(change);
                            })
                            .map_err(|e| JsError::new(&format!("desync: {e}")))?;
                        scene.apply(geom, mirror, mesh, changes, now);
                        self.sent = changes.len() as u32;
                    }
                }
                self.applied = d.delta.seq;
                self.answered = (d.pose_seq, d.complete);
                Ok("delta".into())
            }
            ServerMsg::Answers(_) | ServerMsg::Refused(_) => {
                Err(JsError::new("query answers on a tile session"))
            }
            ServerMsg::Reconnect { after_ms } => {
                self.reconnect_after_ms = after_ms;
                Ok("reconnect".into())
            }
        }
    }

    fn welcome(&mut self, w: Welcome) -> Result<&'static str, JsError> {
        if w.version != PROTOCOL_VERSION {
            return Err(JsError::new(&format!(
                "the server speaks protocol {}, this page {PROTOCOL_VERSION}",
                w.version
            )));
        }
        let info = match (self.params, w.tiles.clone()) {
            (Some(_), None) => {
                return Err(JsError::new("a tile session's welcome has no tile pyramid"));
            }
            (None, Some(_)) => return Err(JsError::new("a vertex session's welcome has tiles")),
            (_, info) => info,
        };
        self.applied = 0;
        self.session_id = w.session_id;
        self.max_in_flight = w.max_in_flight;
        self.idle_timeout_ms = w.idle_timeout_ms;
        self.removed.clear();
        self.added.clear();
        self.evicted.clear();
        if let Some(s) = self.state.as_mut().filter(|s| {
            w.resumed
                && s.terrain == w.terrain
                && s.tiles().map(|(i, _)| i) == info.as_ref()
                && s.digest() == w.digest
        }) {
            match &mut s.stream {
                Stream::Tiles { mirror, .. } => mirror.keep_active_only(),
                // A new connection: its bodies start from fresh models.
                Stream::Vertex { models, .. } => **models = BodyModels::new(),
            }
            return Ok("resumed");
        }
        let geom = w
            .terrain
            .geometry()
            .map_err(|e| JsError::new(&format!("bad terrain: {e}")))?;
        let stream = match (self.params, info) {
            (Some(params), Some(info)) => {
                let shape = info
                    .shape(w.terrain.width, w.terrain.height)
                    .map_err(|e| JsError::new(&format!("bad tile pyramid: {e}")))?;
                Stream::Tiles {
                    info,
                    mirror: TileMirror::new(shape, params),
                }
            }
            _ => {
                let mirror = Mirror::new(&geom, w.terrain.root_z);
                let mut mesh = FanMesh::new(&geom.shape, mirror.cut());
                let scene = Scene::build(&geom, &mirror, &mut mesh);
                Stream::Vertex {
                    mirror: Box::new(mirror),
                    mesh: Box::new(mesh),
                    scene: Box::new(scene),
                    changes: Vec::new(),
                    models: Box::default(),
                }
            }
        };
        self.state = Some(Welcomed {
            geom,
            terrain: w.terrain,
            stream,
        });
        Ok("welcome")
    }

    /// Tiles the last delta stopped drawing (dense indices).
    pub fn removed(&self) -> Vec<u32> {
        self.removed.clone()
    }

    /// Tiles the last delta started drawing.
    pub fn added(&self) -> Vec<u32> {
        self.added.clone()
    }

    /// The tiles among [`Self::added`] that replaced a coarser tile the same delta removed (an
    /// ancestor): they morph in from their parent's mesh. The others arrived by a merge.
    pub fn split_added(&self) -> Vec<u32> {
        let Some((_, mirror)) = self.state.as_ref().and_then(Welcomed::tiles) else {
            return Vec::new();
        };
        let removed: std::collections::HashSet<u32> = self.removed.iter().copied().collect();
        self.added
            .iter()
            .copied()
            .filter(|&i| arrived_by_split(mirror.shape(), i, |p| removed.contains(&p)))
            .collect()
    }

    /// Tiles the last delta dropped from the cache (their geometry is no longer needed).
    pub fn evicted(&self) -> Vec<u32> {
        self.evicted.clone()
    }

    /// Tiles of the last delta that came with a body (the others came from the cache); on the
    /// vertex stream, the delta's splits and merges.
    #[wasm_bindgen(getter)]
    pub fn sent(&self) -> u32 {
        self.sent
    }

    /// The active tiles, ascending.
    pub fn active(&self) -> Vec<u32> {
        self.state
            .as_ref()
            .and_then(Welcomed::tiles)
            .map_or_else(Vec::new, |(_, m)| m.active())
    }

    /// The triangles of held tile `index`, mesh then patches or skirts; `undefined` for a tile
    /// not held.
    pub fn geometry(&self, index: u32) -> Option<TileGeometry> {
        let s = self.state.as_ref()?;
        let (info, mirror) = s.tiles()?;
        let tile = mirror.tile(index)?;
        let skirts = self.params.is_some_and(|p| p.crack == CrackMode::Skirts);
        let skirt = skirts.then(|| info.skirt_height(tile.tile.level));
        Some(TileGeometry {
            mesh: TileMesh::of(&s.geom, tile, skirt),
            level: tile.tile.level,
        })
    }

    /// Whether the session has been welcomed.
    #[wasm_bindgen(getter)]
    pub fn welcomed(&self) -> bool {
        self.state.is_some()
    }

    /// The welcome's session id, 16 hex digits.
    #[wasm_bindgen(getter)]
    pub fn session_id(&self) -> String {
        format!("{:016x}", self.session_id)
    }

    /// Digest of the active tiles or the cut, 16 hex digits.
    #[wasm_bindgen(getter)]
    pub fn digest(&self) -> String {
        format!("{:016x}", self.state.as_ref().map_or(0, Welcomed::digest))
    }

    /// Deltas the server lets out unacknowledged.
    #[wasm_bindgen(getter)]
    pub fn max_in_flight(&self) -> u32 {
        self.max_in_flight
    }

    /// The server closes a connection silent for this long, milliseconds.
    #[wasm_bindgen(getter)]
    pub fn idle_timeout_ms(&self) -> u32 {
        self.idle_timeout_ms
    }

    /// The wait the last `Reconnect` asked for, milliseconds.
    #[wasm_bindgen(getter)]
    pub fn reconnect_after_ms(&self) -> u32 {
        self.reconnect_after_ms
    }

    /// The last pose's sequence number.
    #[wasm_bindgen(getter)]
    pub fn pose_seq(&self) -> f64 {
        self.pose_seq as f64
    }

    /// The newest pose a delta answered.
    #[wasm_bindgen(getter)]
    pub fn answered_pose(&self) -> f64 {
        self.answered.0 as f64
    }

    /// Whether the newest delta met tau for its pose.
    #[wasm_bindgen(getter)]
    pub fn complete(&self) -> bool {
        self.answered.1
    }

    /// The newest delta applied on this connection.
    #[wasm_bindgen(getter)]
    pub fn applied(&self) -> f64 {
        self.applied as f64
    }

    /// Tiles held, active and cached; on the vertex stream, the nodes held.
    #[wasm_bindgen(getter)]
    pub fn held(&self) -> u32 {
        self.state.as_ref().map_or(0, |s| match &s.stream {
            Stream::Tiles { mirror, .. } => mirror.held_count() as u32,
            Stream::Vertex { scene, .. } => scene.held_count() as u32,
        })
    }

    /// Vertex stream: the triangles of the fans.
    #[wasm_bindgen(getter)]
    pub fn fan_triangles(&self) -> u32 {
        match self.state.as_ref().map(|s| &s.stream) {
            Some(Stream::Vertex { mesh, .. }) => mesh.triangle_count() as u32,
            _ => 0,
        }
    }

    /// Vertex stream: active nodes of the cut.
    #[wasm_bindgen(getter)]
    pub fn active_nodes(&self) -> f64 {
        match self.state.as_ref().map(|s| &s.stream) {
            Some(Stream::Vertex { mirror, .. }) => mirror.cut().active_count() as f64,
            _ => 0.0,
        }
    }

    /// Vertex stream: cell records to draw (each two triangles, six corners, of node slots).
    #[wasm_bindgen(getter)]
    pub fn cell_count(&self) -> u32 {
        match self.state.as_ref().map(|s| &s.stream) {
            Some(Stream::Vertex { scene, .. }) => scene.cells.high_water() as u32,
            _ => 0,
        }
    }

    /// Vertex stream: the node records' rows that changed since the last call, for an RGBA32UI
    /// texture of 768 texels a row (256 records of 12 words, see
    /// `relief_proto::mesh::scene::NODE_WORDS`): `[rows in all, then per run: first row, row
    /// count, the rows' words]`. All rows after a welcome or when the pool grew.
    pub fn take_node_rows(&mut self) -> Vec<u32> {
        match self.state.as_mut().map(|s| &mut s.stream) {
            Some(Stream::Vertex { scene, .. }) => {
                row_updates(&mut scene.nodes, 4 * NODE_ROW_TEXELS)
            }
            _ => Vec::new(),
        }
    }

    /// Vertex stream: the cell records' rows that changed since the last call, for an R32UI
    /// texture of 4096 texels a row (a node slot each, six a cell; `u32::MAX` for a missing
    /// triangle), laid out as [`Self::take_node_rows`].
    pub fn take_cell_rows(&mut self) -> Vec<u32> {
        match self.state.as_mut().map(|s| &mut s.stream) {
            Some(Stream::Vertex { scene, .. }) => row_updates(&mut scene.cells, CELL_ROW_TEXELS),
            _ => Vec::new(),
        }
    }

    /// Vertex stream: what the vertex shader's geomorph needs of the view from eye `x, y, z`
    /// looking along `yaw`, `pitch` (radians) through this session's lens, 32 floats: the unit
    /// view direction and the focal length in pixels; the inward normals of the four side
    /// planes and the near plane, each with its offset; tau, lambda, the growth duration in
    /// seconds and the off-axis bound; the near distance and three zeros. The same
    /// `relief_proto::view::ViewState` as the server's and the wgpu client's (`frame.rs`).
    pub fn morph_block(&self, x: f32, y: f32, z: f32, yaw: f32, pitch: f32) -> Vec<f32> {
        let camera = Camera {
            eye: glam::Vec3::new(x, y, z),
            yaw,
            pitch,
        };
        let view = ViewState::new(&camera, &self.lens.into());
        let rule = MorphRule::new(self.tau);
        let f = camera.forward();
        let mut b = vec![f.x, f.y, f.z, view.focal()];
        for (i, n) in view.planes().iter().enumerate() {
            let offset = if i == 4 { view.near() } else { 0.0 };
            b.extend([n.x, n.y, n.z, offset]);
        }
        b.extend([rule.tau, rule.lambda, rule.duration, view.off_axis()]);
        b.extend([view.near(), 0.0, 0.0, 0.0]);
        b
    }

    /// Lowest and highest terrain height, metres (`[0, 0]` before the welcome).
    pub fn height_range(&self) -> Vec<f32> {
        self.state
            .as_ref()
            .map_or(vec![0.0, 0.0], |s| s.terrain.height_range.to_vec())
    }
}

/// Whether a close with `code` is worth reconnecting after (protocol section 10): a network
/// failure, a code that is not the protocol's, or one the protocol marks retry.
#[wasm_bindgen]
pub fn close_retries(code: u16) -> bool {
    CloseReason::from_code(code).is_none_or(CloseReason::retry)
}

/// Whether a close with `code` refused the resume snapshot (reconnect without it).
#[wasm_bindgen]
pub fn close_refused_snapshot(code: u16) -> bool {
    code == CloseReason::BadSnapshot.code()
}

fn path_kind(kind: &str) -> Result<PathKind, JsError> {
    kind.parse().map_err(|e: String| JsError::new(&e))
}

/// The points, `x, y` interleaved, at which the camera path `kind` (`standard` or `stress`)
/// over a terrain of `extent_x` by `extent_y` metres needs the ground's height: ask the server
/// (`POST /v1/heights`), then call [`camera_path_poses`] with the answers in this order.
#[wasm_bindgen]
pub fn camera_path_queries(kind: &str, extent_x: f32, extent_y: f32) -> Result<Vec<f32>, JsError> {
    let points = RefCell::new(Vec::new());
    camera_path(path_kind(kind)?, extent_x, extent_y, |x, y| {
        points.borrow_mut().extend([x, y]);
        0.0
    });
    Ok(points.into_inner())
}

/// The poses of camera path `kind`, five numbers each (`x, y, z, yaw, pitch`), with `heights`
/// the ground's heights at [`camera_path_queries`]' points, in order.
#[wasm_bindgen]
pub fn camera_path_poses(
    kind: &str,
    extent_x: f32,
    extent_y: f32,
    heights: &[f32],
) -> Result<Vec<f32>, JsError> {
    let next = RefCell::new(0usize);
    let cams = camera_path(path_kind(kind)?, extent_x, extent_y, |_, _| {
        let mut i = next.borrow_mut();
        let h = heights.get(*i).copied().unwrap_or(0.0);
        *i += 1;
        h
    });
    Ok(cams
        .iter()
        .flat_map(|c| [c.eye.x, c.eye.y, c.eye.z, c.yaw, c.pitch])
        .collect())
}

/// The protocol version this page speaks.
#[wasm_bindgen]
pub fn protocol_version() -> u32 {
    PROTOCOL_VERSION
}
