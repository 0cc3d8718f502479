//! A held tile's triangles in world metres: its mesh, then its crack patches (a grid tile's
//! dropped and raised patches, an `rqt` tile's curtains) or skirts. This is
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

use super::body::IrregularMesh;
use super::body::curtain::CurtainPoint;
use super::body::{cell_height, grid_height, grid_triangles, skirt_triangle_count};
use super::mirror::TileData;
use super::{EDGES, Edge};
use crate::tree::WorldFrame;
use rustc_hash::FxHashMap;

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
    let place = |c: u32, r: u32, zq: i32| {
        let (x, y) = frame.to_world(c as f32, r as f32);
        [x, y, zq as f32 * z_quantum]
    };
    let mut positions: Vec<[f32; 3]> = (0..tile.z.len() as u32)
        .map(|v| {
            let (c, r) = tile.vertex_pos(v);
            place(c, r, tile.z[v as usize])
        })
        .collect();
    let mut patches = Vec::with_capacity(tile.patches.triangle_count());
    for d in &tile.patches.dropped {
        positions.push(place(d.at.0, d.at.1, d.z));
        patches.push([d.a, positions.len() as u32 - 1, d.c]);
    }
    patches.extend(tile.patches.raised.iter().copied());
    // Curtain points are shared by the fan triangles of a segment: one position each.
    let mut below: FxHashMap<CurtainPoint, u32> = FxHashMap::default();
    for tri in &tile.patches.curtains {
        patches.push(tri.map(|p| match p {
            CurtainPoint::Vertex(v) => v,
            CurtainPoint::Below { at, z } => *below.entry(p).or_insert_with(|| {
                positions.push(place(at.0, at.1, z));
                positions.len() as u32 - 1
            }),
        }));
    }
    let mut skirts = Vec::new();
    if let Some(depth) = skirt {
        skirts.reserve(tile.skirt_triangle_count());
        for e in EDGES {
            let vs = tile.edge_vertices(e);
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
        mesh: tile.triangles(),
        patches,
        skirts,
    }
}

impl TileData {
    /// Grid position (column, row) of vertex `v`.
    pub fn vertex_pos(&self, v: u32) -> (u32, u32) {
        match &self.irregular {
            None => self.span.vertex_pos(v),
            Some(m) => {
                let p = m.at[v as usize];
                (self.span.cols.0 + p[0], self.span.rows.0 + p[1])
            }
        }
    }

    /// The mesh's triangles, counter-clockwise seen from above.
    pub fn triangles(&self) -> Vec<[u32; 3]> {
        match &self.irregular {
            None => grid_triangles(&self.span),
            Some(m) => m.triangles.clone(),
        }
    }

    /// The mesh's triangle count.
    pub fn triangle_count(&self) -> usize {
        match &self.irregular {
            None => 2 * (self.span.nx() as usize - 1) * (self.span.ny() as usize - 1),
            Some(m) => m.triangles.len(),
        }
    }

    /// The vertices on `edge`, in its direction (west to east, north to south).
    pub fn edge_vertices(&self, edge: Edge) -> Vec<u32> {
        let Some(m) = &self.irregular else {
            return self.span.edge_vertices(edge);
        };
        let (w, h) = (
            self.span.cols.1 - self.span.cols.0,
            self.span.rows.1 - self.span.rows.0,
        );
        // (whether a vertex is on the edge, its position along it)
        let on = |p: [u32; 2]| match edge {
            Edge::North => (p[1] == 0, p[0]),
            Edge::South => (p[1] == h, p[0]),
            Edge::West => (p[0] == 0, p[1]),
            Edge::East => (p[0] == w, p[1]),
        };
        let mut vs: Vec<(u32, u32)> = (0..m.at.len() as u32)
            .filter_map(|v| {
                let (yes, along) = on(m.at[v as usize]);
                yes.then_some((along, v))
            })
            .collect();
        vs.sort_unstable();
        vs.into_iter().map(|(_, v)| v).collect()
    }

    /// Skirt triangles: two per edge segment on all four edges.
    pub fn skirt_triangle_count(&self) -> usize {
        match &self.irregular {
            None => skirt_triangle_count(&self.span),
            Some(_) => EDGES
                .iter()
                .map(|&e| 2 * self.edge_vertices(e).len().saturating_sub(1))
                .sum(),
        }
    }

    /// Height of the mesh, z quanta, at grid position `(col, row)`; `None` outside the tile.
    /// On an irregular mesh this tests the triangles one by one.
    pub fn height_at(&self, col: f32, row: f32) -> Option<f32> {
        let s = &self.span;
        let inside = (s.cols.0 as f32..=s.cols.1 as f32).contains(&col)
            && (s.rows.0 as f32..=s.rows.1 as f32).contains(&row);
        if !inside {
            return None;
        }
        let Some(m) = &self.irregular else {
            let z: Vec<f32> = self.z.iter().map(|&q| q as f32).collect();
            return Some(grid_height(s, &z, col, row));
        };
        let p = [
            f64::from(col) - f64::from(s.cols.0),
            f64::from(row) - f64::from(s.rows.0),
        ];
        m.triangles.iter().find_map(|t| self.on_triangle(m, t, p))
    }

    /// Height, z quanta, of irregular triangle `t` at `p` (offsets from the span's first
    /// sample), when `p` lies on it.
    fn on_triangle(&self, m: &IrregularMesh, t: &[u32; 3], p: [f64; 2]) -> Option<f32> {
        // Signed areas in (col, row) axes; triangles are clockwise there.
        let cross = |a: [f64; 2], b: [f64; 2], p: [f64; 2]| {
            (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
        };
        let v = t.map(|i| {
            let q = m.at[i as usize];
            [f64::from(q[0]), f64::from(q[1])]
        });
        let d = cross(v[0], v[1], v[2]);
        if d == 0.0 {
            return None;
        }
        let l = [
            cross(v[1], v[2], p) / d,
            cross(v[2], v[0], p) / d,
            cross(v[0], v[1], p) / d,
        ];
        l.iter().all(|&w| w >= -1e-9).then(|| {
            let z = t.map(|i| f64::from(self.z[i as usize]));
            (l[0] * z[0] + l[1] * z[1] + l[2] * z[2]) as f32
        })
    }
}

/// A tile's surface for many height look-ups: an irregular mesh's triangles bucketed on a
/// coarse grid over the tile, so that a look-up tests a few triangles, not all.
pub struct Surface<'a> {
    tile: &'a TileData,
    /// A grid tile's heights as floats (converted once, not per look-up).
    grid_z: Vec<f32>,
    /// Buckets per side.
    n: usize,
    /// Sample offsets per bucket side.
    cell: [f64; 2],
    /// Triangle indices by bucket, row-major.
    buckets: Vec<Vec<u32>>,
}

impl<'a> Surface<'a> {
    /// The surface of `tile`.
    pub fn new(tile: &'a TileData) -> Surface<'a> {
        let s = &tile.span;
        let size = [
            f64::from(s.cols.1 - s.cols.0).max(1.0),
            f64::from(s.rows.1 - s.rows.0).max(1.0),
        ];
        let n = 16;
        let cell = size.map(|v| v / n as f64);
        let mut buckets = vec![Vec::new(); n * n];
        if let Some(m) = &tile.irregular {
            let bucket = |v: f64, axis: usize| ((v / cell[axis]) as usize).min(n - 1);
            for (k, t) in m.triangles.iter().enumerate() {
                let ps = t.map(|i| m.at[i as usize].map(f64::from));
                let lo =
                    [0, 1].map(|a| bucket(ps.iter().map(|p| p[a]).fold(f64::MAX, f64::min), a));
                let hi =
                    [0, 1].map(|a| bucket(ps.iter().map(|p| p[a]).fold(f64::MIN, f64::max), a));
                for j in lo[1]..=hi[1] {
                    for i in lo[0]..=hi[0] {
                        buckets[j * n + i].push(k as u32);
                    }
                }
            }
        }
        let grid_z = match tile.irregular {
            None => tile.z.iter().map(|&q| q as f32).collect(),
            Some(_) => Vec::new(),
        };
        Surface {
            tile,
            grid_z,
            n,
            cell,
            buckets,
        }
    }

    /// As [`TileData::height_at`].
    pub fn height_at(&self, col: f32, row: f32) -> Option<f32> {
        let s = &self.tile.span;
        let Some(m) = &self.tile.irregular else {
            let inside = (s.cols.0 as f32..=s.cols.1 as f32).contains(&col)
                && (s.rows.0 as f32..=s.rows.1 as f32).contains(&row);
            return inside.then(|| grid_height(s, &self.grid_z, col, row));
        };
        let p = [
            f64::from(col) - f64::from(s.cols.0),
            f64::from(row) - f64::from(s.rows.0),
        ];
        if p[0] < 0.0 || p[1] < 0.0 {
            return None;
        }
        let b = [0, 1].map(|a| ((p[a] / self.cell[a]) as usize).min(self.n - 1));
        self.buckets[b[1] * self.n + b[0]]
            .iter()
            .find_map(|&k| self.tile.on_triangle(m, &m.triangles[k as usize], p))
    }
}

/// The morph target of every vertex of `tile`, z quanta: the parent's mesh height for interior
/// vertices, the vertex's own height on the tile's boundary (and everywhere on the root tile).
/// Irregular meshes do not morph (their targets are their own heights): their parent's mesh is
/// not a subset of their vertices.
pub fn morph_targets(tile: &TileData) -> Vec<f32> {
    let span = &tile.span;
    let (nx, ny) = (span.nx() as usize, span.ny() as usize);
    let own: Vec<f32> = tile.z.iter().map(|&z| z as f32).collect();
    if tile.tile.level == 0 || tile.irregular.is_some() {
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
    use crate::tile::body::Patches;
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
                irregular: None,
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
