//! The tile stream's scene, CPU side: each active tile's triangles in world metres (mesh, then
//! dropped patches, raised patches and skirts, `relief_proto::tile::geometry`), kept in step
//! with a session's [`TileMirror`](relief_proto::tile::mirror::TileMirror). The GPU side
//! (`tiles.rs`) uploads a tile once when it first becomes active and keeps its buffers while the
//! mirror holds it (active or cached), so only tiles new to the client cost an upload.
//!
//! **Morph** (issue 10; the pop at a tile switch measured 1.8 px on synthetic:4097 and 3.8 px
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
use relief_proto::tile::TileShape;
use relief_proto::tile::geometry::{morph_targets, tile_triangles};
use relief_proto::tile::mirror::TileData;
use rustc_hash::{FxHashMap, FxHashSet};
use std::sync::Arc;

/// One tile's triangles, ready to upload.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TileMesh {
    /// Vertices, world metres, four floats each: x, y, z and the morph target's z (the same z
    /// for the patches' and skirts' extra vertices).
    pub positions: Vec<f32>,
    /// Smooth normals, four floats a vertex: x and y of the unit upward normal of the tile's own
    /// mesh, then of the morph target's (z follows, as the normals point up). The sum of the
    /// unit normals of the mesh triangles around each vertex, so a tile's boundary vertices see
    /// only its own triangles; a vertex of patches or skirts alone has none (0, 0).
    pub normals: Vec<f32>,
    /// Vertex indices, three a triangle: the mesh, the dropped patches, the raised patches,
    /// then the skirts.
    pub indices: Vec<u32>,
    /// Triangles of the mesh, dropped patches, raised patches and skirts, in that order.
    pub counts: [u32; 4],
}

impl TileMesh {
    /// The triangles of `tile`, with skirts `skirt` metres deep if given.
    pub fn of(geom: &TerrainGeometry, tile: &TileData, skirt: Option<f32>) -> TileMesh {
        let t = tile_triangles(&geom.frame, geom.z_quantum, tile, skirt);
        let dropped = tile.patches.dropped.len();
        let counts = [
            t.mesh.len() as u32,
            dropped as u32,
            (t.patches.len() - dropped) as u32,
            t.skirts.len() as u32,
        ];
        let indices = [&t.mesh, &t.patches, &t.skirts]
            .into_iter()
            .flat_map(|tris| tris.iter().flatten().copied())
            .collect();
        let targets = morph_targets(tile);
        let positions: Vec<f32> = t
            .positions
            .iter()
            .enumerate()
            .flat_map(|(v, p)| {
                let target = targets.get(v).map_or(p[2], |q| q * geom.z_quantum);
                [p[0], p[1], p[2], target]
            })
            .collect();
        let normals = smooth_normals(&positions, &t.mesh);
        TileMesh {
            positions,
            normals,
            indices,
            counts,
        }
    }

    /// Triangles drawn: all of them, or without the raised patches (`dropped_only`).
    pub fn drawn(&self, dropped_only: bool) -> u32 {
        let [m, d, r, s] = self.counts;
        if dropped_only {
            m + d + s
        } else {
            m + d + r + s
        }
    }
}

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
                let split = split_child(mirror.shape(), &before, i);
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

/// Whether tile `i`, newly active, replaced a coarser tile: one of its ancestors was active
/// `before` (the active set covers the terrain once, so otherwise finer tiles were, or none).
/// [`TileMesh::normals`] of `positions` (x, y, z, target z) under the triangles `mesh`.
fn smooth_normals(positions: &[f32], mesh: &[[u32; 3]]) -> Vec<f32> {
    let n = positions.len() / 4;
    let mut sums = vec![[glam::Vec3::ZERO; 2]; n];
    let at = |v: u32, k: usize| {
        let p = &positions[4 * v as usize..4 * v as usize + 4];
        glam::Vec3::new(p[0], p[1], p[2 + k])
    };
    for tri in mesh {
        let face = |k: usize| {
            let [a, b, c] = tri.map(|v| at(v, k));
            let f = (b - a).cross(c - a).normalize_or_zero();
            if f.z < 0.0 { -f } else { f }
        };
        let (own, target) = (face(0), face(1));
        for &v in tri {
            let s = &mut sums[v as usize];
            s[0] += own;
            s[1] += target;
        }
    }
    sums.iter()
        .flat_map(|[own, target]| {
            let (o, t) = (own.normalize_or_zero(), target.normalize_or_zero());
            [o.x, o.y, t.x, t.y]
        })
        .collect()
}

fn split_child(shape: &TileShape, before: &FxHashSet<u32>, i: u32) -> bool {
    let mut t = shape.tile(i).and_then(|t| t.parent());
    while let Some(p) = t {
        if before.contains(&shape.index(p)) {
            return true;
        }
        t = p.parent();
    }
    false
}

/// Tile `t`'s triangles as `tiles`' session draws them.
fn mesh_of(geom: &TerrainGeometry, tiles: &TileState, t: &TileData) -> TileMesh {
    TileMesh::of(geom, t, tiles.skirt_depth(t.tile.level))
}

#[cfg(test)]
mod tests {
    use super::*;
    use relief_proto::tile::body::{Dropped, Patches};
    use relief_proto::tile::{TileId, TileShape};

    #[test]
    fn a_tile_mesh_orders_mesh_dropped_raised_skirts() {
        let shape = TileShape::new(9, 9, 4).unwrap();
        let geom = TerrainGeometry::new(9, 9, 10.0, 10.0, 0.5).unwrap();
        let t = TileId {
            level: 1,
            x: 0,
            y: 0,
        };
        let span = shape.span(t);
        let tile = TileData {
            tile: t,
            span,
            z: vec![100; span.vertex_count()],
            irregular: None,
            patches: Patches {
                dropped: vec![Dropped {
                    a: 0,
                    c: 1,
                    at: (1, 0),
                    z: 90,
                }],
                raised: vec![[0, 5, 10]],
                curtains: Vec::new(),
            },
        };
        let m = TileMesh::of(&geom, &tile, None);
        assert_eq!(m.counts, [32, 1, 1, 0]);
        assert_eq!(m.positions.len(), 4 * (25 + 1));
        assert_eq!(m.indices.len(), 3 * 34);
        // The dropped patch's extra vertex, then the raised patch, come after the mesh.
        assert_eq!(&m.indices[96..99], &[0, 25, 1]);
        assert_eq!(&m.indices[99..102], &[0, 5, 10]);
        assert_eq!(m.drawn(true), 33);
        assert_eq!(m.drawn(false), 34);
        let skirted = TileMesh::of(&geom, &tile, Some(3.0));
        assert_eq!(skirted.counts[3], 32);
        // Skirt vertices hang 3 m below their edge vertex.
        let z = |v: usize| skirted.positions[4 * v + 2];
        assert!((z(26) - (z(0) - 3.0)).abs() < 1e-4);
    }

    #[test]
    fn interior_vertices_morph_from_the_parent_mesh_and_the_boundary_stays() {
        let shape = TileShape::new(9, 9, 4).unwrap();
        let geom = TerrainGeometry::new(9, 9, 10.0, 10.0, 0.5).unwrap();
        let t = TileId {
            level: 1,
            x: 1,
            y: 0,
        };
        let span = shape.span(t);
        // A bump at vertex (1, 1) of the tile: off the parent's grid lines.
        let mut z = vec![100; span.vertex_count()];
        z[6] = 140;
        let tile = TileData {
            tile: t,
            span,
            z,
            irregular: None,
            patches: Patches::default(),
        };
        let m = TileMesh::of(&geom, &tile, Some(3.0));
        let own = |v: usize| m.positions[4 * v + 2];
        let target = |v: usize| m.positions[4 * v + 3];
        assert_eq!(own(6), 70.0);
        assert_eq!(target(6), 50.0, "the bump is not on the parent's mesh");
        for v in [0, 1, 2, 3, 4, 5, 9, 10, 14, 15, 19, 20, 24, 25, 30] {
            assert_eq!(
                own(v),
                target(v),
                "vertex {v} is on the boundary or a skirt"
            );
        }
    }

    #[test]
    fn only_children_of_a_split_morph() {
        let shape = TileShape::new(33, 33, 4).unwrap();
        let index = |level, x, y| shape.index(TileId { level, x, y });
        let before: FxHashSet<u32> = [index(1, 0, 0), index(2, 2, 0)].into_iter().collect();
        assert!(split_child(&shape, &before, index(2, 1, 1)));
        assert!(split_child(&shape, &before, index(3, 0, 0)));
        assert!(!split_child(&shape, &before, index(2, 3, 0)));
        assert!(!split_child(&shape, &before, index(1, 1, 0)), "a merge");
        assert!(!split_child(&shape, &FxHashSet::default(), index(2, 0, 0)));
    }

    #[test]
    fn smooth_normals_follow_the_slope_of_each_mesh() {
        // Two triangles of a unit square: the own heights rise with x (z = x), the target's
        // are flat.
        let positions = [
            [0.0, 0.0, 0.0, 5.0],
            [1.0, 0.0, 1.0, 5.0],
            [1.0, 1.0, 1.0, 5.0],
            [0.0, 1.0, 0.0, 5.0],
        ]
        .concat();
        let n = smooth_normals(&positions, &[[0, 1, 2], [0, 2, 3]]);
        let h = std::f32::consts::FRAC_1_SQRT_2;
        for v in 0..4 {
            let [x, y, tx, ty] = [n[4 * v], n[4 * v + 1], n[4 * v + 2], n[4 * v + 3]];
            assert!((x + h).abs() < 1e-5 && y.abs() < 1e-5, "{v}: {x} {y}");
            assert!(tx.abs() < 1e-6 && ty.abs() < 1e-6);
        }
    }
}
