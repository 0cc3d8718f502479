//! A tile's body: its mesh and its crack patches (paper 001, section 2.2), bit-packed with the
//! Exp-Golomb codes of [`crate::bits`]. `docs/protocol.md` specifies every bit.
//!
//! **Mesh** (kind `grid`): the tile's vertices are the samples of its [`TileSpan`], heights in
//! the store's z quanta. The blob holds a 2-bit mesh kind (0 = grid), the lowest height as 32
//! bits (two's complement), a 4-bit Exp-Golomb order `k`, then one signed residual per vertex in
//! row-major order: the height above the lowest, minus the planar prediction `left + up -
//! up_left` (only `left` on the first row, only `up` in the first column, 0 for the first
//! vertex). Cells are split along the north-west to south-east diagonal.
//!
//! **Patches.** Wherever two tiles one level apart share an edge, the finer tile has one vertex
//! `B` inside each coarse segment `A-C`, and a crack opens when `B` is off the segment. Paper 001
//! patches only *dropped* cracks (`B` below `A-C`), with the triangle `A-B-C` stored with the
//! coarse tile, and argues that *raised* cracks are hidden because the finer tile is the nearer.
//! That holds for its distance rule, not for a screen-space-error rule, where a rough far tile
//! can be finer than a flat near one; so Relief patches both, and every patch hangs *below* the
//! tile that owns it, which keeps it hidden when the neighbour is at the same level:
//! - a *dropped* patch belongs to the coarse tile: `A` and `C` are its vertices, `B` the finer
//!   level's sample inside the segment, below the segment;
//! - a *raised* patch belongs to the fine tile: `A`, `B` and `C` are its own vertices, `B` above
//!   the coarser level's segment `A-C` (so the triangle lies below its own edge), or exactly on
//!   it. There the triangle is degenerate, but the junction is a T: after rounding to screen
//!   space `B` falls a hair to one side of the coarse edge and a rasterizer may leave isolated
//!   pixels uncovered; the triangle shares its edges with both tiles' and covers that sliver.
//!
//! Edges on the terrain's border have no neighbour and no patches. The patch blob holds a 4-bit
//! order `k`, then for each edge in [`EDGES`] order that has a neighbour: one code per own
//! segment that holds a finer sample (tiles above the finest level) — `0` for no patch, else
//! `g + 1`, order-`k` Exp-Golomb, where `g = floor(line) - z_B >= 0` and `line` is the segment's
//! height at `B` — then one bit per coarser-level segment that holds an own vertex (tiles below
//! level 0): 1 for a raised patch.

pub mod curtain;
pub mod irregular;
pub mod rqt;

use super::{EDGES, Edge, TileId, TileShape, TileSpan};
use crate::bits::{BitReader, BitWriter, best_order};
pub use irregular::{IrregularMesh, encode_irregular};

/// A body that does not decode for its tile.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum TileBodyError {
    /// The bits end early.
    #[error("tile body is truncated")]
    Truncated,
    /// An unknown mesh kind.
    #[error("tile mesh kind {0} is unknown")]
    MeshKind(u32),
    /// A height outside the 32-bit range.
    #[error("tile height out of range")]
    Range,
    /// Whole bytes remain after the body.
    #[error("tile body has {0} bytes after its end")]
    Trailing(usize),
    /// An irregular mesh's vertex or triangle count is impossible for its tile.
    #[error("tile mesh has an impossible count: {0} vertices, {1} triangles")]
    Counts(u64, u64),
    /// An irregular mesh's vertex lies outside its tile.
    #[error("tile mesh vertex outside the tile")]
    Outside,
    /// An irregular mesh's triangle names a vertex out of order or out of range, or leaves a
    /// vertex unused.
    #[error("tile mesh triangle index out of order or range")]
    Index,
    /// Patches asked for against heights that are not the tile's grid (`got` heights, `want`
    /// expected): an irregular mesh, or a mesh of another tile.
    #[error("tile patches need {1} grid heights, got {0}")]
    Heights(usize, usize),
    /// A patch blob where the mesh kind carries none (or the session asked for none).
    #[error("tile mesh kind {0} carries no patch blob")]
    PatchesUnexpected(u32),
}

/// Mesh kinds a body can hold.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum MeshKind {
    /// A regular grid of the tile's samples with a fixed index pattern.
    #[default]
    Grid = 0,
    /// Paper 002's restricted-quadtree mesh ([`rqt`] encoding).
    Rqt = 1,
    /// Paper 003's greedy-insertion Delaunay TIN ([`irregular`] encoding).
    Tin = 2,
}

impl MeshKind {
    /// The kind with wire code `code`.
    pub fn from_code(code: u32) -> Option<MeshKind> {
        [MeshKind::Grid, MeshKind::Rqt, MeshKind::Tin]
            .into_iter()
            .find(|k| *k as u32 == code)
    }

    /// Its name, as in `build --tile-mesh` and `/v1/terrain`.
    pub fn name(self) -> &'static str {
        match self {
            MeshKind::Grid => "grid",
            MeshKind::Rqt => "rqt",
            MeshKind::Tin => "tin",
        }
    }
}

/// A decoded mesh blob: the vertex heights, and for an irregular mesh its vertices and
/// triangles.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct DecodedMesh {
    /// Vertex heights, z quanta: row-major over the span for a grid, else one per vertex of
    /// `irregular`.
    pub z: Vec<i32>,
    /// The vertices and triangles of an irregular mesh (`None` for a grid).
    pub irregular: Option<IrregularMesh>,
}

/// A dropped patch: the triangle from two of the tile's edge vertices down to a finer sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Dropped {
    /// The tile's vertex at the segment's start.
    pub a: u32,
    /// The tile's vertex at the segment's end.
    pub c: u32,
    /// The finer sample between them: grid column and row.
    pub at: (u32, u32),
    /// Its height, z quanta.
    pub z: i32,
}

/// A tile's crack patches.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Patches {
    /// Patches for finer neighbours' dropped vertices.
    pub dropped: Vec<Dropped>,
    /// Patches under the tile's own raised edge vertices: `[A, B, C]` vertex indices.
    pub raised: Vec<[u32; 3]>,
    /// An `rqt` tile's crack curtains ([`curtain`]): the patches of a mesh whose border
    /// vertices differ from its neighbours' (empty for a grid tile).
    pub curtains: Vec<[curtain::CurtainPoint; 3]>,
}

impl Patches {
    /// Triangles the patches draw.
    pub fn triangle_count(&self) -> usize {
        self.dropped.len() + self.raised.len() + self.curtains.len()
    }
}

/// One segment of a tile edge that may hold a patch.
struct Segment {
    /// Vertex indices of the segment's ends.
    a: u32,
    /// End vertex.
    c: u32,
    /// Positions along the edge, samples: start, the inner point, end.
    pos: (u32, u32, u32),
    /// Grid column and row of the inner point.
    at: (u32, u32),
    /// For a raised candidate: the tile's own vertex at the inner point.
    b: Option<u32>,
}

/// Along-edge sample position of vertex `v` and the grid position of an along-edge point.
fn along(span: &TileSpan, edge: Edge, v: u32) -> u32 {
    let (c, r) = span.vertex_pos(v);
    match edge {
        Edge::North | Edge::South => c,
        Edge::East | Edge::West => r,
    }
}

fn grid_at(span: &TileSpan, edge: Edge, p: u32) -> (u32, u32) {
    match edge {
        Edge::North => (p, span.rows.0),
        Edge::South => (p, span.rows.1),
        Edge::West => (span.cols.0, p),
        Edge::East => (span.cols.1, p),
    }
}

/// The segments of `t`'s edges that can hold patches, in body order: for each edge with a
/// neighbour, the dropped candidates (own segments holding a finer sample), then the raised
/// candidates (coarser-level segments holding an own vertex).
fn segments(shape: &TileShape, t: TileId) -> Vec<(bool, Segment)> {
    let span = shape.span(t);
    let s = span.stride;
    let mut out = Vec::new();
    for edge in EDGES {
        if shape.neighbour(t, edge).is_none() {
            continue;
        }
        let vs = span.edge_vertices(edge);
        if t.level < shape.depth() {
            for w in vs.windows(2) {
                let (pa, pc) = (along(&span, edge, w[0]), along(&span, edge, w[1]));
                let pb = pa + s / 2;
                if pb < pc {
                    out.push((
                        true,
                        Segment {
                            a: w[0],
                            c: w[1],
                            pos: (pa, pb, pc),
                            at: grid_at(&span, edge, pb),
                            b: None,
                        },
                    ));
                }
            }
        }
        if t.level > 0 {
            let max = match edge {
                Edge::North | Edge::South => shape.width() - 1,
                Edge::East | Edge::West => shape.height() - 1,
            };
            let coarse: Vec<usize> = (0..vs.len())
                .filter(|&i| {
                    let p = along(&span, edge, vs[i]);
                    p.is_multiple_of(2 * s) || p == max
                })
                .collect();
            for w in coarse.windows(2) {
                if w[1] - w[0] == 2 {
                    let (a, b, c) = (vs[w[0]], vs[w[0] + 1], vs[w[1]]);
                    let pb = along(&span, edge, b);
                    out.push((
                        false,
                        Segment {
                            a,
                            c,
                            pos: (along(&span, edge, a), pb, along(&span, edge, c)),
                            at: grid_at(&span, edge, pb),
                            b: Some(b),
                        },
                    ));
                }
            }
        }
    }
    out
}

/// `floor` of the segment's height at its inner point, and whether `zb` lies strictly below
/// (`Less`), on, or above it. Exact integer arithmetic.
fn line(za: i32, zc: i32, pos: (u32, u32, u32), zb: i32) -> (i64, std::cmp::Ordering) {
    let (pa, pb, pc) = (pos.0 as i64, pos.1 as i64, pos.2 as i64);
    let num = za as i64 * (pc - pb) + zc as i64 * (pb - pa);
    let den = pc - pa;
    ((num.div_euclid(den)), (zb as i64 * den).cmp(&num))
}

/// The patches of tile `t` whose vertex heights are `z`, with `sample(col, row)` the
/// full-resolution heights: paper 001's steps 1-4 for dropped cracks, plus raised ones and
/// T-junctions.
pub fn find_patches(
    shape: &TileShape,
    t: TileId,
    z: &[i32],
    sample: impl Fn(u32, u32) -> i32,
) -> Patches {
    let mut p = Patches::default();
    for (dropped, seg) in segments(shape, t) {
        let (za, zc) = (z[seg.a as usize], z[seg.c as usize]);
        if dropped {
            let zb = sample(seg.at.0, seg.at.1);
            if line(za, zc, seg.pos, zb).1.is_lt() {
                p.dropped.push(Dropped {
                    a: seg.a,
                    c: seg.c,
                    at: seg.at,
                    z: zb,
                });
            }
        } else if let Some(b) = seg.b
            && !line(za, zc, seg.pos, z[b as usize]).1.is_lt()
        {
            p.raised.push([seg.a, b, seg.c]);
        }
    }
    p
}

/// Packs `patches` of tile `t` (found by [`find_patches`] for heights `z`).
pub fn encode_patches(shape: &TileShape, t: TileId, z: &[i32], patches: &Patches) -> Vec<u8> {
    let segs = segments(shape, t);
    let mut dropped = patches.dropped.iter().peekable();
    let mut codes = Vec::new();
    let mut raised = Vec::new();
    for (is_dropped, seg) in &segs {
        if *is_dropped {
            let code = match dropped.peek().copied() {
                Some(d) if d.a == seg.a && d.c == seg.c => {
                    let (floor, _) = line(z[seg.a as usize], z[seg.c as usize], seg.pos, d.z);
                    dropped.next();
                    (floor - d.z as i64 + 1) as u64
                }
                _ => 0,
            };
            codes.push(code);
        } else {
            raised.push(
                patches
                    .raised
                    .iter()
                    .any(|r| r[0] == seg.a && r[2] == seg.c),
            );
        }
    }
    let k = best_order(codes.iter().copied(), 15);
    let mut w = BitWriter::new();
    w.put(k, 4);
    let (mut ci, mut ri) = (0, 0);
    for (is_dropped, _) in &segs {
        if *is_dropped {
            w.put_eg(codes[ci], k);
            ci += 1;
        } else {
            w.put(raised[ri] as u32, 1);
            ri += 1;
        }
    }
    w.finish()
}

/// Unpacks the patch blob of tile `t` whose vertex heights are `z`.
pub fn decode_patches(
    shape: &TileShape,
    t: TileId,
    z: &[i32],
    bytes: &[u8],
) -> Result<Patches, TileBodyError> {
    let want = shape.span(t).vertex_count();
    if z.len() != want {
        return Err(TileBodyError::Heights(z.len(), want));
    }
    let mut r = BitReader::new(bytes);
    let k = r.get(4).ok_or(TileBodyError::Truncated)?;
    let mut p = Patches::default();
    for (is_dropped, seg) in segments(shape, t) {
        if is_dropped {
            let code = r.get_eg(k).ok_or(TileBodyError::Truncated)?;
            if code > 0 {
                let (floor, _) = line(z[seg.a as usize], z[seg.c as usize], seg.pos, 0);
                let zb = floor - (code as i64 - 1);
                let zb = i32::try_from(zb).map_err(|_| TileBodyError::Range)?;
                p.dropped.push(Dropped {
                    a: seg.a,
                    c: seg.c,
                    at: seg.at,
                    z: zb,
                });
            }
        } else if r.get(1).ok_or(TileBodyError::Truncated)? == 1 {
            p.raised.push([seg.a, seg.b.unwrap_or(seg.a), seg.c]);
        }
    }
    finished(&r)?;
    Ok(p)
}

fn finished(r: &BitReader<'_>) -> Result<(), TileBodyError> {
    let rest = r.remaining();
    if rest >= 8 {
        return Err(TileBodyError::Trailing((rest / 8) as usize));
    }
    Ok(())
}

fn predict(z: &[i64], nx: usize, i: usize, j: usize) -> i64 {
    let at = j * nx + i;
    match (i > 0, j > 0) {
        (true, true) => z[at - 1] + z[at - nx] - z[at - nx - 1],
        (true, false) => z[at - 1],
        (false, true) => z[at - nx],
        (false, false) => 0,
    }
}

/// A mesh blob's start, every kind alike: the 2-bit kind and the lowest height as 32 bits.
fn mesh_header(kind: MeshKind, zmin: i32) -> BitWriter {
    let mut w = BitWriter::new();
    w.put(kind as u32, 2);
    w.put(zmin as u32, 32);
    w
}

/// Packs a grid mesh with vertex heights `z` (row-major over `span`).
pub fn encode_mesh(span: &TileSpan, z: &[i32]) -> Vec<u8> {
    let nx = span.nx() as usize;
    let zmin = z.iter().copied().min().unwrap_or(0);
    let v: Vec<i64> = z.iter().map(|&h| h as i64 - zmin as i64).collect();
    let res: Vec<i64> = (0..v.len())
        .map(|at| v[at] - predict(&v, nx, at % nx, at / nx))
        .collect();
    let k = best_order(res.iter().map(|&r| crate::bits::zigzag(r)), 15);
    let mut w = mesh_header(MeshKind::Grid, zmin);
    w.put(k, 4);
    for r in res {
        w.put_eg_signed(r, k);
    }
    w.finish()
}

/// Unpacks a mesh blob of any kind over `span`.
pub fn decode_mesh(span: &TileSpan, bytes: &[u8]) -> Result<DecodedMesh, TileBodyError> {
    let mut r = BitReader::new(bytes);
    let code = r.get(2).ok_or(TileBodyError::Truncated)?;
    match MeshKind::from_code(code) {
        Some(MeshKind::Grid) => Ok(DecodedMesh {
            z: decode_grid(span, r)?,
            irregular: None,
        }),
        Some(kind) => {
            let (mesh, z) = if kind == MeshKind::Rqt {
                rqt::decode_rqt(span, r)?
            } else {
                irregular::decode_irregular(span, kind, r)?
            };
            Ok(DecodedMesh {
                z,
                irregular: Some(mesh),
            })
        }
        None => Err(TileBodyError::MeshKind(code)),
    }
}

/// The vertex heights of a grid mesh blob over `span`, from `r` (just past the kind).
fn decode_grid(span: &TileSpan, mut r: BitReader<'_>) -> Result<Vec<i32>, TileBodyError> {
    let zmin = r.get(32).ok_or(TileBodyError::Truncated)? as i32 as i64;
    let k = r.get(4).ok_or(TileBodyError::Truncated)?;
    let nx = span.nx() as usize;
    let n = span.vertex_count();
    // Every vertex needs at least one bit: refuse before allocating for a short body.
    if r.remaining() < n as u64 {
        return Err(TileBodyError::Truncated);
    }
    let mut v = vec![0i64; n];
    for at in 0..n {
        let res = r.get_eg_signed(k).ok_or(TileBodyError::Truncated)?;
        v[at] = predict(&v, nx, at % nx, at / nx)
            .checked_add(res)
            .filter(|x| x.abs() < 1 << 40)
            .ok_or(TileBodyError::Range)?;
    }
    finished(&r)?;
    v.into_iter()
        .map(|x| i32::try_from(x + zmin).map_err(|_| TileBodyError::Range))
        .collect()
}

/// The grid mesh's triangles as vertex-index triples, counter-clockwise seen from above.
pub fn grid_triangles(span: &TileSpan) -> Vec<[u32; 3]> {
    let (nx, ny) = (span.nx(), span.ny());
    let mut t = Vec::with_capacity(2 * (nx as usize - 1) * (ny as usize - 1));
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            let v00 = j * nx + i;
            let (v10, v01, v11) = (v00 + 1, v00 + nx, v00 + nx + 1);
            t.push([v00, v01, v11]);
            t.push([v00, v11, v10]);
        }
    }
    t
}

/// Height of the grid mesh over `span` with vertex heights `z` (any unit) at grid position
/// `(col, row)` inside the span, on the triangles of [`grid_triangles`].
pub fn grid_height(span: &TileSpan, z: &[f32], col: f32, row: f32) -> f32 {
    let (nx, ny) = (span.nx(), span.ny());
    let s = span.stride as f32;
    let fi = ((col - span.cols.0 as f32) / s).clamp(0.0, (nx - 1) as f32);
    let fj = ((row - span.rows.0 as f32) / s).clamp(0.0, (ny - 1) as f32);
    let i = (fi as u32).min(nx - 2);
    let j = (fj as u32).min(ny - 2);
    // The cell's corners, which may be narrower than the stride on the border.
    let (c0, c1) = (span.col(i) as f32, span.col(i + 1) as f32);
    let (r0, r1) = (span.row(j) as f32, span.row(j + 1) as f32);
    let u = ((col - c0) / (c1 - c0)).clamp(0.0, 1.0);
    let v = ((row - r0) / (r1 - r0)).clamp(0.0, 1.0);
    let (at, w) = ((j * nx + i) as usize, nx as usize);
    cell_height([z[at], z[at + 1], z[at + w], z[at + w + 1]], u, v)
}

/// Height inside one grid cell with corner heights `[north-west, north-east, south-west,
/// south-east]` at `u` east and `v` south (both 0..1), on the cell's two triangles split along
/// the north-west to south-east diagonal.
pub fn cell_height([z00, z10, z01, z11]: [f32; 4], u: f32, v: f32) -> f32 {
    if u <= v {
        z00 + v * (z01 - z00) + u * (z11 - z01)
    } else {
        z00 + u * (z10 - z00) + v * (z11 - z10)
    }
}

/// Skirt triangles of a tile: two per edge segment on all four edges (Cesium's skirts).
pub fn skirt_triangle_count(span: &TileSpan) -> usize {
    4 * (span.nx() as usize - 1 + span.ny() as usize - 1)
}

#[cfg(test)]
mod tests;
