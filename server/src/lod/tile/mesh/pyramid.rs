//! One tile of the store's pyramid meshed by kind (`build --tile-mesh grid|rqt|tin`).
//!
//! **Tolerances** ([`Tolerances`]). Each adaptive tile is meshed to the tile's own `grid` error
//! (its largest distance to the full-resolution samples at its level's stride): "the tile's error
//! budget". It is then never less faithful than the `grid` tile it replaces, so the selection
//! and the errors it works from stay alike, and it never needs more vertices than the lattice
//! (an `rqt` mesh at that tolerance is a subset of it). Tried first: one tolerance per level,
//! the median of the level's `grid` errors. Every sample of an adaptive tile then sat near the
//! tolerance while a `grid` tile's p99 lies far below its maximum, so at equal *measured* p99
//! error the adaptive streams needed a lower tau and more bytes than `grid` (synthetic:1025:
//! `rqt` 730 kB against `grid`'s 595 kB). `tin`'s shared border lines take the finest level's
//! median (half a quantum: exact), so that every tile along a line stays within its own
//! tolerance ([`super::borders`]).
//!
//! **Kinds.**
//! - `grid`: every vertex of the tile's lattice.
//! - `rqt`: paper 002's restricted quadtree over the tile's lattice ([`super::rqt`]). It needs
//!   a square lattice of `2^k + 1` vertices a side; a tile clipped by the grid's east or south
//!   border is not, and stays a `grid` tile (the body says which kind each tile is). Such a tile
//!   closes its cracks with paper 001's patches, which only meet a neighbour's border where it
//!   has every lattice vertex of its level: so every side of an `rqt` tile that a selection can
//!   put against a `grid` tile ([`meets_grid`]) keeps all its lattice vertices (raised to be
//!   always active, [`RqtErrors::raise`], which keeps the mesh restricted). Its curtains close
//!   the cracks where it stands higher, the grid tile's patches those where it stands higher.
//! - `tin`: paper 003's greedy insertion over the tile's lattice, with the shared border points
//!   anywhere on the full-resolution samples of its sides ([`super::borders::tile_tin`]).
//!
//! Each tile's error is then measured, not assumed: the largest distance between its mesh
//! (quantised heights) and every original sample it covers.

use super::borders::tile_tin;
use super::curtain::across;
use super::rqt::RqtErrors;
use super::{HeightGrid, TriMesh};
use relief_proto::tile::body::rqt::{encode_rqt, rqt_side};
use relief_proto::tile::body::{IrregularMesh, MeshKind, encode_irregular, encode_mesh};
use relief_proto::tile::{EDGES, Edge, TileId, TileShape};

/// The vertical tolerances, metres, of the adaptive meshes.
#[derive(Clone, Debug, PartialEq)]
pub struct Tolerances {
    /// By level, coarsest first: the median `grid` error (for `tin`'s border lines).
    pub per_level: Vec<f32>,
    /// By tile (dense index): its own `grid` error.
    pub per_tile: Vec<f32>,
}

impl Tolerances {
    /// From each tile's `grid` error (by dense index): each tile's own, and the median of each
    /// level's.
    pub fn from_grid_errors(shape: &TileShape, grid_errors: &[f32]) -> Tolerances {
        let depth = shape.depth();
        let per_level: Vec<f32> = (0..=depth)
            .map(|level| {
                let (nx, ny) = shape.level_dims(level);
                let mut e: Vec<f32> = (0..ny)
                    .flat_map(|y| (0..nx).map(move |x| TileId { level, x, y }))
                    .map(|t| grid_errors[shape.index(t) as usize])
                    .collect();
                e.sort_by(f32::total_cmp);
                e[e.len() / 2]
            })
            .collect();
        Tolerances {
            per_level,
            per_tile: grid_errors.to_vec(),
        }
    }

    /// Level `level`'s tolerance.
    pub fn level(&self, level: u8) -> f32 {
        self.per_level[level as usize]
    }

    /// Tile `index`'s tolerance.
    pub fn tile(&self, index: u32) -> f32 {
        self.per_tile[index as usize]
    }

    /// The finest level's tolerance.
    pub fn finest(&self) -> f32 {
        self.per_level.last().copied().unwrap_or(0.0)
    }
}

/// A tile's mesh: its vertex heights, and its vertices and triangles unless it is a grid.
#[derive(Clone, Debug, PartialEq)]
pub struct PyramidMesh {
    /// Vertex heights, z quanta (row-major over the lattice for a grid).
    pub z: Vec<i32>,
    /// An `rqt` or `tin` mesh; `None` for a grid.
    pub irregular: Option<IrregularMesh>,
    /// The mesh blob as it goes on the wire ([`relief_proto::tile::body`]).
    pub blob: Vec<u8>,
}

/// The whole grid's heights as the store keeps them, in z quanta: each sample's metres
/// quantised when it is read ([`crate::store::layout::quantise`]), so that a build holds no
/// second copy of the grid; and in metres for `tin` meshes, which triangulate a height grid
/// (the other kinds take a sample's metres as its quanta times the quantum, the same `f32`).
pub struct Quantised<'a> {
    /// Heights in metres, row-major, voids filled.
    heights: &'a [f32],
    /// Samples a row.
    width: usize,
    /// Metres a quantum.
    pub quantum: f32,
    /// One over the quantum.
    inv: f32,
    /// The quantised heights in metres as a grid, where `tin` meshes are made.
    pub metres: Option<HeightGrid<'a>>,
}

impl<'a> Quantised<'a> {
    /// `heights` (row-major, `width` a row) at `quantum` metres a quantum, with the grid in
    /// metres for `tin` meshes.
    pub fn new(
        heights: &'a [f32],
        width: u32,
        quantum: f32,
        metres: Option<HeightGrid<'a>>,
    ) -> Quantised<'a> {
        Quantised {
            heights,
            width: width as usize,
            quantum,
            inv: 1.0 / quantum,
            metres,
        }
    }

    /// Sample `(c, r)` in z quanta.
    #[inline]
    pub fn at(&self, c: u32, r: u32) -> i32 {
        let h = self.heights[r as usize * self.width + c as usize];
        crate::store::layout::quantise(h, self.inv)
    }
}

/// Tile `t`'s mesh of `kind` at its tolerance in `tol`, over the grid's quantised heights `q`.
///
/// # Panics
/// If `kind` is `tin` and `q` holds no grid in metres.
pub fn mesh_tile(
    kind: MeshKind,
    shape: &TileShape,
    t: TileId,
    q: &Quantised<'_>,
    tol: &Tolerances,
) -> PyramidMesh {
    let span = shape.span(t);
    let at = |c: u32, r: u32| q.at(c, r);
    let grid = || {
        let z = span.map_vertices(at);
        PyramidMesh {
            blob: encode_mesh(&span, &z),
            z,
            irregular: None,
        }
    };
    // An adaptive mesh (vertices as sample offsets) and its blob.
    let irregular = |m: TriMesh, kind: MeshKind, blob: Option<Vec<u8>>| {
        let z: Vec<i32> = m
            .vertices
            .iter()
            .map(|p| at(span.cols.0 + p[0], span.rows.0 + p[1]))
            .collect();
        let mesh = IrregularMesh {
            kind,
            at: m.vertices,
            triangles: m.triangles,
        };
        PyramidMesh {
            blob: blob.unwrap_or_else(|| encode_irregular(&mesh, &z)),
            z,
            irregular: Some(mesh),
        }
    };
    match kind {
        MeshKind::Grid => grid(),
        MeshKind::Rqt => {
            let (nx, ny) = (span.nx(), span.ny());
            let s = span.stride;
            let lattice = span.map_vertices(|c, r| at(c, r) as f32 * q.quantum);
            let errors = HeightGrid::new(nx as usize, ny as usize, &lattice)
                .filter(|_| rqt_side(&span).is_some())
                .and_then(|g| RqtErrors::new(&g).ok());
            let Some(mut errors) = errors else {
                return grid();
            };
            // Every lattice vertex on a side that can meet a `grid` tile: that tile's patches
            // need them (see the module docs).
            let full = EDGES
                .into_iter()
                .filter(|&e| meets_grid(shape, t, e))
                .flat_map(|e| errors.edge(e))
                .map(|p| (p, f32::MAX))
                .collect::<Vec<_>>();
            errors.raise(full);
            let tolerance = tol.tile(shape.index(t));
            let blob = encode_rqt(
                &span,
                |p| errors.active(p, tolerance),
                |p| at(span.cols.0 + p[0] * s, span.rows.0 + p[1] * s),
            );
            let Some(blob) = blob else {
                return grid();
            };
            let mut m = errors.mesh(tolerance);
            for p in &mut m.vertices {
                *p = p.map(|v| v * s);
            }
            irregular(m, MeshKind::Rqt, Some(blob))
        }
        MeshKind::Tin => {
            let line = |_: u8| tol.finest();
            let Some(quantised) = &q.metres else {
                panic!("tin meshes are made from the quantised heights in metres");
            };
            let m = tile_tin(shape, t, quantised, tol.tile(shape.index(t)), Some(&line));
            irregular(m, MeshKind::Tin, None)
        }
    }
}

/// Whether a restricted selection can put a `grid` tile across side `e` of tile `t` in an
/// `rqt` store: a tile the grid's east or south border clips ([`rqt_side`]), at `t`'s level or
/// one apart ([`across`]).
pub fn meets_grid(shape: &TileShape, t: TileId, e: Edge) -> bool {
    across(shape, t, e)
        .iter()
        .any(|&(u, _)| rqt_side(&shape.span(u)).is_none())
}

/// The largest distance, metres, between tile `t`'s irregular mesh (heights `z` in quanta of
/// `quantum`) and the original samples `heights` it covers.
pub fn irregular_error(
    shape: &TileShape,
    t: TileId,
    mesh: &IrregularMesh,
    z: &[i32],
    quantum: f32,
    heights: &HeightGrid<'_>,
) -> f32 {
    let span = shape.span(t);
    let tri = TriMesh {
        vertices: mesh.at.clone(),
        triangles: mesh.triangles.clone(),
    };
    let vz: Vec<f32> = z.iter().map(|&q| q as f32 * quantum).collect();
    tri.error_against(&vz, heights, [span.cols.0, span.rows.0])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rough(w: u32, h: u32) -> Vec<f32> {
        (0..w * h)
            .map(|i| {
                let (c, r) = ((i % w) as f32, (i / w) as f32);
                (c * 0.37).sin() * 30.0 + (r * 0.21).cos() * 20.0 + ((c * r) * 0.013).sin() * 9.0
            })
            .collect()
    }

    /// Every kind covers every tile exactly once, vertices inside the tile, and its measured
    /// error is what the store records; adaptive kinds stay near their tolerance.
    #[test]
    fn every_kind_covers_each_tile_and_measures_its_error() {
        let (w, h) = (129u32, 100u32);
        let heights = rough(w, h);
        let q = 0.1f32;
        let zf: Vec<f32> = heights
            .iter()
            .map(|&v| crate::store::layout::quantise(v, 1.0 / q) as f32 * q)
            .collect();
        let shape = TileShape::new(w, h, 16).unwrap();
        let orig = HeightGrid::new(w as usize, h as usize, &heights).unwrap();
        let quantised = HeightGrid::new(w as usize, h as usize, &zf).unwrap();
        let errs: Vec<f32> = (0..shape.tile_count())
            .map(|i| 8.0 / (1 << shape.tile(i).unwrap().level) as f32)
            .collect();
        let tol = Tolerances::from_grid_errors(&shape, &errs);
        assert_eq!(tol.finest(), 8.0 / (1 << shape.depth()) as f32);
        for kind in [MeshKind::Rqt, MeshKind::Tin] {
            let mut irregular = 0;
            for i in 0..shape.tile_count() {
                let t = shape.tile(i).unwrap();
                let span = shape.span(t);
                let qg = Quantised::new(&heights, w, q, Some(quantised));
                let m = mesh_tile(kind, &shape, t, &qg, &tol);
                let Some(mesh) = &m.irregular else {
                    // Only a clipped tile falls back to a grid, and only for rqt.
                    assert_eq!(kind, MeshKind::Rqt);
                    assert!(span.nx() != span.ny() || !(span.nx() - 1).is_power_of_two());
                    assert_eq!(m.z.len(), span.vertex_count());
                    continue;
                };
                irregular += 1;
                assert_eq!(mesh.kind, kind);
                assert_eq!(m.z.len(), mesh.at.len());
                let tri = TriMesh {
                    vertices: mesh.at.clone(),
                    triangles: mesh.triangles.clone(),
                };
                let (tw, th) = (span.cols.1 - span.cols.0 + 1, span.rows.1 - span.rows.0 + 1);
                assert!(tri.covers(tw as usize, th as usize), "{kind:?} {t:?}");
                let e = irregular_error(&shape, t, mesh, &m.z, q, &orig);
                // The tolerance holds on the lattice; off it, and for quantisation, a margin.
                assert!(e.is_finite() && e >= 0.0);
                if span.stride == 1 {
                    assert!(e <= tol.tile(i) + q, "{kind:?} {t:?}: {e}");
                }
            }
            assert!(irregular > 0, "{kind:?}");
        }
    }
}
