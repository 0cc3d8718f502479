//! What a session mirrors, by stream kind: the only part of a session that differs between the
//! vertex stream (a [`Mirror`] of the cut and its [`FanMesh`]) and the tile stream (a
//! [`TileMirror`] of the active and cached tiles). The connection, backoff, resume, pings and
//! acknowledgements in `session.rs` are the same for both.

use super::types::ClientError;
use relief_proto::delta::{BodyModels, Known};
use relief_proto::mesh::FanMesh;
use relief_proto::mirror::{Change, Mirror};
use relief_proto::msg::{CrackMode, TileStreamParams, Welcome, WireDelta};
use relief_proto::snapshot::Snapshot;
use relief_proto::terrain::TerrainGeometry;
use relief_proto::tile::TileSetInfo;
use relief_proto::tile::mirror::{TileData, TileMirror};
use rustc_hash::FxHashMap;

/// The vertex stream's client state.
pub struct VertexState {
    /// The mirrored cut with heights.
    pub(super) mirror: Mirror,
    /// Triangles of the mirrored cut.
    pub(super) mesh: FanMesh,
    /// Changes applied since the last `take_changes` (with `record_changes`).
    pub(super) changes: Vec<Change>,
    /// The connection's delta-body models (docs/protocol.md section 5.2): fresh with every
    /// welcome, resumed or not.
    pub(super) models: Box<BodyModels>,
}

/// The tile stream's client state.
pub struct TileState {
    /// The pyramid as the welcome described it (skirt heights come from its level errors).
    info: TileSetInfo,
    /// What the hello asked for (cache limit, crack mode).
    params: TileStreamParams,
    /// The held tiles, decoded and checked by digest.
    mirror: TileMirror,
    /// Triangles each active tile draws (mesh plus patches or skirts), by dense index, so that
    /// the total follows each delta without walking the active set.
    drawn: FxHashMap<u32, u32>,
    /// Sum of `drawn`.
    triangles: usize,
}

/// What one delta did to the mirrored state.
#[derive(Clone, Copy, Debug, Default)]
pub struct StreamApplied {
    /// Splits and merges, or tiles removed and added.
    pub changes: usize,
    /// Tiles added with a body.
    pub tiles_sent: usize,
    /// Tiles added from the client's cache.
    pub tiles_cached: usize,
}

/// A session's mirrored state.
// One per session, made once and never moved in a hot path: the variants' sizes do not matter.
#[allow(clippy::large_enum_variant)]
pub enum StreamState {
    /// The vertex stream (paper 000).
    Vertex(VertexState),
    /// The tile stream (paper 001).
    Tiles(TileState),
}

impl StreamState {
    /// Fresh state for a session the server welcomed from scratch. A tile session that does not
    /// `keep` its tiles gets a light mirror: every tile and digest is still decoded and
    /// checked, but no tile data is kept (a load generator's thousands of sessions), so it
    /// counts no triangles and has no heights.
    pub(super) fn fresh(
        w: &Welcome,
        geom: &TerrainGeometry,
        tiles: Option<TileStreamParams>,
        keep: bool,
    ) -> Result<StreamState, ClientError> {
        match (tiles, &w.tiles) {
            (None, _) => {
                let mirror = Mirror::new(geom, w.terrain.root_z);
                let mesh = FanMesh::new(&geom.shape, mirror.cut());
                Ok(StreamState::Vertex(VertexState {
                    mirror,
                    mesh,
                    changes: Vec::new(),
                    models: Box::default(),
                }))
            }
            (Some(params), Some(info)) => {
                let shape = info
                    .shape(w.terrain.width, w.terrain.height)
                    .map_err(|e| ClientError::Protocol(format!("bad tile pyramid: {e}")))?;
                Ok(StreamState::Tiles(TileState {
                    info: info.clone(),
                    params,
                    mirror: if keep {
                        TileMirror::new(shape, params)
                    } else {
                        TileMirror::light(shape, params)
                    },
                    drawn: FxHashMap::default(),
                    triangles: 0,
                }))
            }
            (Some(_), None) => Err(ClientError::Protocol(
                "a tile session's welcome has no tile pyramid".into(),
            )),
        }
    }

    /// Applies one delta (`geom` for vertex bodies; `record` keeps the vertex changes).
    /// `Err` is a desync: a body that does not apply or a digest mismatch.
    pub(super) fn apply(
        &mut self,
        geom: &TerrainGeometry,
        wire: &WireDelta,
        build_mesh: bool,
        record: bool,
    ) -> Result<StreamApplied, String> {
        match self {
            StreamState::Vertex(v) => {
                let delta = wire
                    .unpack_in(
                        &geom.shape,
                        geom.z_quantum,
                        &mut v.models,
                        Known::mirror(&v.mirror),
                    )
                    .map_err(|e| format!("bad delta: {e}"))?;
                let shape = &geom.shape;
                let (mesh, changes) = (&mut v.mesh, &mut v.changes);
                v.mirror
                    .apply(geom, &delta, |c, change| {
                        if build_mesh {
                            mesh.update_around(shape, c, change.node());
                        }
                        if record {
                            changes.push(change);
                        }
                    })
                    .map_err(|e| e.to_string())?;
                Ok(StreamApplied {
                    changes: delta.merges.len() + delta.splits.len(),
                    ..StreamApplied::default()
                })
            }
            StreamState::Tiles(t) => t.apply(wire),
        }
    }

    /// Digest of the mirrored cut or active tile set.
    pub(crate) fn digest(&self) -> u64 {
        match self {
            StreamState::Vertex(v) => v.mirror.cut().digest(),
            StreamState::Tiles(t) => t.mirror.digest(),
        }
    }

    /// The resume snapshot; `None` when there is nothing to resume (no tile yet).
    pub(super) fn snapshot(&self, geom: &TerrainGeometry) -> Option<Snapshot> {
        match self {
            StreamState::Vertex(v) => Some(Snapshot::of(&geom.shape, v.mirror.cut())),
            StreamState::Tiles(t) if t.active_count() > 0 => Some(t.mirror.snapshot()),
            StreamState::Tiles(_) => None,
        }
    }

    /// After a resumed welcome: a new connection's delta bodies start from fresh models; the
    /// server knows the active set only, so a tile client's cache is cut down to it (both ends'
    /// eviction must agree).
    pub(super) fn resumed(&mut self) {
        match self {
            StreamState::Vertex(v) => *v.models = BodyModels::new(),
            StreamState::Tiles(t) => t.mirror.keep_active_only(),
        }
    }

    /// Whether a welcome's pyramid is the one this state mirrors.
    pub(super) fn same_pyramid(&self, w: &Welcome) -> bool {
        match self {
            StreamState::Vertex(_) => w.tiles.is_none(),
            StreamState::Tiles(t) => w.tiles.as_ref() == Some(&t.info),
        }
    }

    /// Triangles drawn: the fans, or the active tiles' meshes with their patches or skirts.
    pub fn triangle_count(&self) -> usize {
        match self {
            StreamState::Vertex(v) => v.mesh.triangle_count(),
            StreamState::Tiles(t) => t.triangles,
        }
    }

    /// Active nodes of the cut, or active tiles.
    pub fn active_count(&self) -> u64 {
        match self {
            StreamState::Vertex(v) => v.mirror.cut().active_count(),
            StreamState::Tiles(t) => t.active_count() as u64,
        }
    }
}

impl TileState {
    /// The pyramid and its level errors.
    pub fn info(&self) -> &TileSetInfo {
        &self.info
    }

    /// The cache limit and crack mode of the session.
    pub fn params(&self) -> TileStreamParams {
        self.params
    }

    /// The held tiles.
    pub fn mirror(&self) -> &TileMirror {
        &self.mirror
    }

    /// Active tiles.
    pub fn active_count(&self) -> usize {
        self.drawn.len()
    }

    /// How deep skirts hang under a tile of `level`, metres (`None` unless the session draws
    /// skirts): [`TileSetInfo::skirt_height`], Cesium's five times a level's largest error
    /// taken from the level above (the crack test on 16-cell tiles saw holes with the level's
    /// own).
    pub fn skirt_depth(&self, level: u8) -> Option<f32> {
        (self.params.crack == CrackMode::Skirts).then(|| self.info.skirt_height(level))
    }

    /// Height of the active tiles' surface over world `x`, `y`, metres (`None` off them).
    pub fn height_at(&self, geom: &TerrainGeometry, x: f32, y: f32) -> Option<f32> {
        let (c, r) = geom.frame.to_grid(x, y);
        let t = self.drawn.keys().find_map(|i| {
            let t = self.mirror.tile(*i)?;
            let s = &t.span;
            (c >= s.cols.0 as f32
                && c <= s.cols.1 as f32
                && r >= s.rows.0 as f32
                && r <= s.rows.1 as f32)
                .then_some(t)
        })?;
        Some(t.height_at(c, r)? * geom.z_quantum)
    }

    /// Triangles tile `t` draws: its mesh plus its patches or skirts.
    fn triangles_of(&self, t: &TileData) -> usize {
        t.triangle_count()
            + match self.params.crack {
                CrackMode::Patches => t.patches.triangle_count(),
                CrackMode::Skirts => t.skirt_triangle_count(),
                CrackMode::None => 0,
            }
    }

    fn apply(&mut self, wire: &WireDelta) -> Result<StreamApplied, String> {
        let c = self.mirror.apply(wire).map_err(|e| e.to_string())?;
        for r in &c.removed {
            self.triangles -= self.drawn.remove(r).unwrap_or(0) as usize;
        }
        for a in &c.added {
            let n = self.mirror.tile(*a).map_or(0, |t| self.triangles_of(t));
            self.triangles += n;
            self.drawn.insert(*a, n as u32);
        }
        Ok(StreamApplied {
            changes: c.removed.len() + c.added.len(),
            tiles_sent: c.sent,
            tiles_cached: c.added.len() - c.sent,
        })
    }
}

#[cfg(test)]
mod tests;
