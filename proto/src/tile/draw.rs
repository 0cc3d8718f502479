//! What a client uploads for one held tile, shared by the wgpu client and the browser page's
//! WebAssembly: the tile's triangles ([`tile_triangles`]) as flat vertex and index arrays, each
//! vertex with its morph target ([`morph_targets`]) and smooth normals of both, and the rule for
//! which newly active tiles morph ([`arrived_by_split`]).
//!
//! **Morph on arrival.** A tile that became active as the child of a split (an ancestor of it
//! was active before) is drawn at `mix(target, own, alpha)`, alpha growing from 0 to 1 over the
//! growth duration; tiles that arrive by a merge, and the first tiles of a session, are drawn as
//! they are. Boundary vertices, patches and skirts never move.

use super::TileShape;
use super::geometry::{morph_targets, tile_triangles};
use super::mirror::TileData;
use crate::terrain::TerrainGeometry;

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
    /// Triangles of the mesh, dropped patches, raised patches (an `rqt` tile's curtains) and
    /// skirts, in that order.
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

/// Whether tile `i`, newly active, replaced a coarser tile: one of its ancestors was active
/// before (`was_active`, by dense index). The active set covers the terrain once, so otherwise
/// finer tiles were (a merge), or none (a fresh start).
pub fn arrived_by_split(shape: &TileShape, i: u32, was_active: impl Fn(u32) -> bool) -> bool {
    let mut t = shape.tile(i).and_then(|t| t.parent());
    while let Some(p) = t {
        if was_active(shape.index(p)) {
            return true;
        }
        t = p.parent();
    }
    false
}

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tile::TileId;
    use crate::tile::body::{Dropped, Patches};
    use std::collections::HashSet;

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
        let before: HashSet<u32> = [index(1, 0, 0), index(2, 2, 0)].into_iter().collect();
        let split_child =
            |before: &HashSet<u32>, i| arrived_by_split(&shape, i, |p| before.contains(&p));
        assert!(split_child(&before, index(2, 1, 1)));
        assert!(split_child(&before, index(3, 0, 0)));
        assert!(!split_child(&before, index(2, 3, 0)));
        assert!(!split_child(&before, index(1, 1, 0)), "a merge");
        assert!(!split_child(&HashSet::new(), index(2, 0, 0)));
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
