//! `relief-wasm`: the browser page's tile session, `relief-proto` compiled to WebAssembly so that
//! the page and the server share one codec (issue 15).
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

use relief_proto::close::CloseReason;
use relief_proto::codec::{HARD_LIMIT, decode, encode};
use relief_proto::msg::{
    ClientMsg, CrackMode, Hello, PROTOCOL_VERSION, Resume, ServerMsg, StreamKind, TerrainInfo,
    TileStreamParams, Welcome, WireCamera, WireLens,
};
use relief_proto::path::{PathKind, camera_path};
use relief_proto::terrain::TerrainGeometry;
use relief_proto::tile::TileSetInfo;
use relief_proto::tile::draw::{TileMesh, arrived_by_split};
use relief_proto::tile::mirror::TileMirror;
use std::cell::RefCell;
use wasm_bindgen::prelude::*;

/// What a tile session holds once welcomed.
struct Welcomed {
    /// The terrain, as the welcome described it.
    terrain: TerrainInfo,
    /// The tile pyramid.
    info: TileSetInfo,
    /// The held tiles.
    mirror: TileMirror,
    /// Grid to world metres, and the height quantum.
    geom: TerrainGeometry,
}

/// A tile session's state, without the socket.
#[wasm_bindgen]
pub struct TileSession {
    lens: WireLens,
    tau: f32,
    params: TileStreamParams,
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
    /// `fov_y_deg` degrees and a near plane `near` metres away, screen error `tau` pixels,
    /// `crack` one of `patches`, `skirts`, `none`, keeping at most `cache_tiles` tiles.
    #[wasm_bindgen(constructor)]
    pub fn new(
        width: u32,
        height: u32,
        fov_y_deg: f32,
        near: f32,
        tau: f32,
        crack: &str,
        cache_tiles: u32,
    ) -> Result<TileSession, JsError> {
        Ok(TileSession {
            lens: WireLens {
                width,
                height,
                fov_y_deg,
                near,
            },
            tau,
            params: TileStreamParams {
                cache_tiles,
                crack: crack_mode(crack)?,
            },
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

    /// The hello for a new connection: a resume from the mirror's active tiles when it holds
    /// any, else a new session.
    pub fn hello(&self) -> Vec<u8> {
        let resume = self.state.as_ref().and_then(|s| {
            (!s.mirror.active().is_empty()).then(|| Resume {
                terrain_id: s.terrain.id,
                snapshot: s.mirror.snapshot(),
            })
        });
        encode(&ClientMsg::Hello(Hello {
            version: PROTOCOL_VERSION,
            kind: StreamKind::Tiles(self.params),
            lens: self.lens,
            tau: self.tau,
            budget: None,
            resume,
        }))
    }

    /// Whether the next hello resumes.
    #[wasm_bindgen(getter)]
    pub fn resuming(&self) -> bool {
        self.state
            .as_ref()
            .is_some_and(|s| !s.mirror.active().is_empty())
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

    /// Decodes and applies one server message. Returns `welcome` (a new session: drop every
    /// tile drawn), `resumed` (the active tiles stay; cached ones are gone), `delta` (see
    /// [`Self::removed`], [`Self::added`], [`Self::evicted`]) or `reconnect` (close, wait
    /// [`Self::reconnect_after_ms`], reconnect). An error is a desync or a protocol fault:
    /// close, [`Self::reset`] and reconnect.
    pub fn receive(&mut self, bytes: &[u8]) -> Result<String, JsError> {
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
                let c = state
                    .mirror
                    .apply(&d.delta)
                    .map_err(|e| JsError::new(&format!("desync: {e}")))?;
                self.applied = d.delta.seq;
                self.answered = (d.pose_seq, d.complete);
                self.removed = c.removed;
                self.added = c.added;
                self.evicted = c.evicted;
                self.sent = c.sent as u32;
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
        let info = w
            .tiles
            .clone()
            .ok_or_else(|| JsError::new("a tile session's welcome has no tile pyramid"))?;
        self.applied = 0;
        self.session_id = w.session_id;
        self.max_in_flight = w.max_in_flight;
        self.idle_timeout_ms = w.idle_timeout_ms;
        self.removed.clear();
        self.added.clear();
        self.evicted.clear();
        if let Some(s) = self.state.as_mut().filter(|s| {
            w.resumed && s.terrain == w.terrain && s.info == info && s.mirror.digest() == w.digest
        }) {
            s.mirror.keep_active_only();
            return Ok("resumed");
        }
        let shape = info
            .shape(w.terrain.width, w.terrain.height)
            .map_err(|e| JsError::new(&format!("bad tile pyramid: {e}")))?;
        let geom = w
            .terrain
            .geometry()
            .map_err(|e| JsError::new(&format!("bad terrain: {e}")))?;
        self.state = Some(Welcomed {
            mirror: TileMirror::new(shape, self.params),
            geom,
            terrain: w.terrain,
            info,
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
        let Some(s) = self.state.as_ref() else {
            return Vec::new();
        };
        let removed: std::collections::HashSet<u32> = self.removed.iter().copied().collect();
        self.added
            .iter()
            .copied()
            .filter(|&i| arrived_by_split(s.mirror.shape(), i, |p| removed.contains(&p)))
            .collect()
    }

    /// Tiles the last delta dropped from the cache (their geometry is no longer needed).
    pub fn evicted(&self) -> Vec<u32> {
        self.evicted.clone()
    }

    /// Tiles of the last delta that came with a body (the others came from the cache).
    #[wasm_bindgen(getter)]
    pub fn sent(&self) -> u32 {
        self.sent
    }

    /// The active tiles, ascending.
    pub fn active(&self) -> Vec<u32> {
        self.state
            .as_ref()
            .map_or_else(Vec::new, |s| s.mirror.active())
    }

    /// The triangles of held tile `index`, mesh then patches or skirts; `undefined` for a tile
    /// not held.
    pub fn geometry(&self, index: u32) -> Option<TileGeometry> {
        let s = self.state.as_ref()?;
        let tile = s.mirror.tile(index)?;
        let skirt =
            (self.params.crack == CrackMode::Skirts).then(|| s.info.skirt_height(tile.tile.level));
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

    /// Digest of the active tiles, 16 hex digits.
    #[wasm_bindgen(getter)]
    pub fn digest(&self) -> String {
        format!(
            "{:016x}",
            self.state.as_ref().map_or(0, |s| s.mirror.digest())
        )
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

    /// Tiles held, active and cached.
    #[wasm_bindgen(getter)]
    pub fn held(&self) -> u32 {
        self.state
            .as_ref()
            .map_or(0, |s| s.mirror.held_count() as u32)
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
