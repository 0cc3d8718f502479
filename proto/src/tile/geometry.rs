//! A held tile's triangles in world metres: its mesh, then its crack patches or skirts. This is
//! all the drawing a thin client does; patches and skirts are vertical and must be drawn
//! without back-face culling.

use super::EDGES;
use super::body::{grid_triangles, skirt_triangle_count};
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
