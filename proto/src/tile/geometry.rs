//! A held tile's triangles in world metres: its mesh, then its crack patches or skirts. This is
//! all the drawing a thin client does; patches and skirts are vertical and must be drawn
//! without back-face culling.
//!
//! **Morph.** A tile that replaces its parent would pop by up to its parent's error. Each
//! interior vertex therefore also has a *morph target*, its height on the parent's mesh (the
//! tile's own vertices on the parent's grid, split along the same diagonal), and a client
//! blends from the target to the vertex's own height over the first moments after the tile
//! arrives ([`morph_targets`]). Boundary vertices never move: they are shared with neighbours
//! (which may not be morphing) and the crack patches were computed for them, so morphing them
//! could open cracks that no patch closes.

use super::EDGES;
use super::body::{cell_height, grid_triangles, skirt_triangle_count};
use super::mirror::TileData;
use crate::tree::WorldFrame;

/// A tile's triangles.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TileTriangles {
    /// Vertex positions, world metres: the tile's vertices, then the patches' and skirts' extra
    /// vertices.
    pub positions: Vec<[f32; 3]>,
    /// Triangles of the tile's surface, counter-clockwise seen from above.
    pub mesh: Vec<[u32; 3]>,
    /// Crack patch triangles.
    pub patches: Vec<[u32; 3]>,
    /// Skirt triangles.
    pub skirts: Vec<[u32; 3]>,
}

/// The triangles of `tile`; `skirt` hangs skirts this many metres deep (`None` for none).
pub fn tile_triangles(
    frame: &WorldFrame,
    z_quantum: f32,
    tile: &TileData,
    skirt: Option<f32>,
) -> TileTriangles {
    let span = &tile.span;
    let place = |c: u32, r: u32, zq: i32| {
        let (x, y) = frame.to_world(c as f32, r as f32);
        [x, y, zq as f32 * z_quantum]
    };
    let mut positions: Vec<[f32; 3]> = (0..span.vertex_count() as u32)
        .map(|v| {
            let (c, r) = span.vertex_pos(v);
            place(c, r, tile.z[v as usize])
        })
        .collect();
    let mut patches = Vec::with_capacity(tile.patches.triangle_count());
    for d in &tile.patches.dropped {
        positions.push(place(d.at.0, d.at.1, d.z));
        patches.push([d.a, positions.len() as u32 - 1, d.c]);
    }
    patches.extend(tile.patches.raised.iter().copied());
    let mut skirts = Vec::new();
    if let Some(depth) = skirt {
        skirts.reserve(skirt_triangle_count(span));
        for e in EDGES {
            let vs = span.edge_vertices(e);
            let base = positions.len() as u32;
            for &v in &vs {
                let p = positions[v as usize];
                positions.push([p[0], p[1], p[2] - depth]);
            }
            for (i, w) in vs.windows(2).enumerate() {
                let (a, b) = (w[0], w[1]);
                let (a2, b2) = (base + i as u32, base + i as u32 + 1);
                skirts.push([a, a2, b2]);
                skirts.push([a, b2, b]);
            }
        }
    }
    TileTriangles {
        positions,
        mesh: grid_triangles(span),
        patches,
        skirts,
    }
}

/// The morph target of every vertex of `tile`, z quanta: the parent's mesh height for interior
/// vertices, the vertex's own height on the tile's boundary (and everywhere on the root tile).
pub fn morph_targets(tile: &TileData) -> Vec<f32> {
    let span = &tile.span;
    let (nx, ny) = (span.nx() as usize, span.ny() as usize);
    let own: Vec<f32> = tile.z.iter().map(|&z| z as f32).collect();
    if tile.tile.level == 0 {
        return own;
    }
    // The parent's grid lines among the tile's: every other one, and the last.
    let lines = |n: usize| -> Vec<usize> {
        let mut v: Vec<usize> = (0..n).step_by(2).collect();
        if v.last() != Some(&(n - 1)) {
            v.push(n - 1);
        }
        v
    };
    let (px, py) = (lines(nx), lines(ny));
    // The parent's lines around index `i` of `lines`, and where `i` lies between them (0..1).
    let bracket = |lines: &[usize], i: usize, pos: &dyn Fn(usize) -> f32| {
        let k = lines.partition_point(|&l| l <= i) - 1;
        let (a, b) = (lines[k], lines[(k + 1).min(lines.len() - 1)]);
        let t = if b > a {
            (pos(i) - pos(a)) / (pos(b) - pos(a))
        } else {
            0.0
        };
        (a, b, t)
    };
    let col = |i: usize| span.col(i as u32) as f32;
    let row = |j: usize| span.row(j as u32) as f32;
    let mut out = own.clone();
    for j in 1..ny - 1 {
        let (j0, j1, v) = bracket(&py, j, &row);
        for i in 1..nx - 1 {
            let (i0, i1, u) = bracket(&px, i, &col);
            let at = |ii: usize, jj: usize| own[jj * nx + ii];
            out[j * nx + i] = cell_height([at(i0, j0), at(i1, j0), at(i0, j1), at(i1, j1)], u, v);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tile::body::{Patches, grid_height};
    use crate::tile::{TileId, TileShape};

    #[test]
    fn morph_targets_lie_on_the_parent_mesh_and_edges_stay() {
        let shape = TileShape::new(300, 70, 16).unwrap();
        let h = |c: u32, r: u32| ((c * 7919 + r * 104729) % 997) as i32;
        for i in 1..shape.tile_count() {
            let t = shape.tile(i).unwrap();
            let span = shape.span(t);
            let z: Vec<i32> = (0..span.vertex_count() as u32)
                .map(|v| {
                    let (c, r) = span.vertex_pos(v);
                    h(c, r)
                })
                .collect();
            let data = TileData {
                tile: t,
                span,
                z: z.clone(),
                patches: Patches::default(),
            };
            let m = morph_targets(&data);
            let parent = shape.span(t.parent().unwrap_or(TileId::ROOT));
            let pz: Vec<f32> = (0..parent.vertex_count() as u32)
                .map(|v| {
                    let (c, r) = parent.vertex_pos(v);
                    h(c, r) as f32
                })
                .collect();
            let (nx, ny) = (span.nx(), span.ny());
            for v in 0..span.vertex_count() as u32 {
                let (c, r) = span.vertex_pos(v);
                let edge = v % nx == 0 || v / nx == 0 || v % nx == nx - 1 || v / nx == ny - 1;
                let want = if edge {
                    z[v as usize] as f32
                } else {
                    grid_height(&parent, &pz, c as f32, r as f32)
                };
                assert!(
                    (m[v as usize] - want).abs() < 1e-2,
                    "tile {t:?} vertex {v}: {} vs {want}",
                    m[v as usize]
                );
            }
        }
    }
}
