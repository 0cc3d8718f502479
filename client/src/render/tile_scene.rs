//! The tile stream's scene, CPU side: each active tile's triangles in world metres (mesh, then
//! dropped patches, raised patches and skirts, `relief_proto::tile::geometry`), kept in step
//! with a session's [`TileMirror`](relief_proto::tile::mirror::TileMirror). The GPU side
//! (`tiles.rs`) uploads a tile once when it first becomes active and keeps its buffers while the
//! mirror holds it (active or cached), so only tiles new to the client cost an upload.
//!
//! **Morph** (the pop at a tile switch measured 1.8 px on synthetic:4097 and 3.8 px
//! on fuji_srtm3). Every vertex also carries its morph target
//! ([`morph_targets`](relief_proto::tile::geometry::morph_targets): its height on the parent's
//! mesh inside the tile, its own height on the tile's boundary, so seams, patches and skirts
//! never move). A tile that became active as the child of a split (an ancestor of it was
//! active before) is stamped with its arrival time, and the shader draws its vertices at
//! `mix(target, own, alpha)`, alpha growing from 0 to 1 over the geomorph's growth duration
//! (0.25 s, the vertex stream's growth cap). Tiles that arrive by a merge, and the first tiles
//! of a session (or of a fresh start), are drawn as they are.

use crate::session::{Session, TileState};
use relief_proto::terrain::TerrainGeometry;
pub use relief_proto::tile::draw::TileMesh;
use relief_proto::tile::draw::arrived_by_split;
use relief_proto::tile::mirror::TileData;
use rustc_hash::{FxHashMap, FxHashSet};
use std::sync::Arc;

/// The arrival time of a tile drawn as it is, with no morph: long ago.
pub const SETTLED: f32 = -1.0e30;

/// The active tiles' triangles and what left the client since the GPU side last looked.
#[derive(Default)]
pub struct TileScene {
    /// Bumped when the session starts again from scratch: GPU buffers of an older epoch go.
    pub epoch: u64,
    /// The session generation the scene belongs to.
    generation: u64,
    /// Active tiles, ascending dense index.
    pub active: Vec<u32>,
    /// Triangles of each active tile (built when the tile becomes active).
    pub meshes: FxHashMap<u32, Arc<TileMesh>>,
    /// When each active tile became active, on the clock of `sync`'s `now`, if it arrived by a
    /// split (it morphs from then on); [`SETTLED`] otherwise.
    pub arrived: FxHashMap<u32, f32>,
    /// Tiles whose meshes were handed out and that the mirror still holds.
    known: FxHashSet<u32>,
    /// Tiles the mirror no longer holds (evicted from its cache) since [`TileScene::take_gone`].
    gone: Vec<u32>,
}

impl TileScene {
    /// The scene of what `session` (a tile session) holds now (drawn as it is: no morph).
    pub fn new(session: &Session) -> TileScene {
        let mut s = TileScene {
            generation: session.generation(),
            ..TileScene::default()
        };
        s.sync(session, 0.0);
        s
    }

    /// Follows `session`: builds the triangles of newly active tiles, stamps those that arrived
    /// by a split with `now` (seconds on the clock frames are drawn with), drops those of tiles
    /// no longer active, and notes the evicted ones. Returns the tiles built.
    pub fn sync(&mut self, session: &Session, now: f32) -> usize {
        let Some(tiles) = session.tiles() else {
            return 0;
        };
        if session.generation() != self.generation {
            self.generation = session.generation();
            self.epoch += 1;
            self.meshes.clear();
            self.arrived.clear();
            self.known.clear();
            self.gone.clear();
            self.active.clear();
        }
        let mirror = tiles.mirror();
        let before: FxHashSet<u32> = std::mem::take(&mut self.active).into_iter().collect();
        self.active = mirror.active();
        let active: FxHashSet<u32> = self.active.iter().copied().collect();
        self.meshes.retain(|i, _| active.contains(i));
        self.arrived.retain(|i, _| active.contains(i));
        let mut built = 0;
        for &i in &self.active {
            if !before.contains(&i) {
                let split = arrived_by_split(mirror.shape(), i, |p| before.contains(&p));
                self.arrived.insert(i, if split { now } else { SETTLED });
            }
            if self.meshes.contains_key(&i) {
                continue;
            }
            let Some(t) = mirror.tile(i) else { continue };
            self.meshes
                .insert(i, Arc::new(mesh_of(session.geometry(), tiles, t)));
            self.known.insert(i);
            built += 1;
        }
        let gone = &mut self.gone;
        self.known.retain(|i| {
            let held = mirror.tile(*i).is_some();
            if !held {
                gone.push(*i);
            }
            held
        });
        built
    }

    /// When active tile `i` arrived, if it morphs ([`SETTLED`] if not).
    pub fn arrival(&self, i: u32) -> f32 {
        self.arrived.get(&i).copied().unwrap_or(SETTLED)
    }

    /// Tiles evicted since the last call: their GPU buffers can go.
    pub fn take_gone(&mut self) -> Vec<u32> {
        std::mem::take(&mut self.gone)
    }

    /// Triangles drawn over the active tiles.
    pub fn triangles(&self, dropped_only: bool) -> usize {
        self.meshes
            .values()
            .map(|m| m.drawn(dropped_only) as usize)
            .sum()
    }
}

/// Tile `t`'s triangles as `tiles`' session draws them.
fn mesh_of(geom: &TerrainGeometry, tiles: &TileState, t: &TileData) -> TileMesh {
    TileMesh::of(geom, t, tiles.skirt_depth(t.tile.level))
}
