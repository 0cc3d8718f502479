//! Shared border points for `tin` tiles (issue 13; paper 003, section 4, "multi-resolution
//! modelling"): neighbouring tiles take the same vertices on the edge they share, so their
//! meshes meet vertex for vertex with no crack, no patch and no skirt.
//!
//! **The paper's rule.** The terrain is cut into sectors; each sector has several LODs (one per
//! tolerance); on every edge two sectors share, "a number of points equal for all levels of
//! detail" is inserted and put in the set `I` of points that every LOD keeps. Its 41 x 41
//! example grows from 475 to 636 triangles at tolerance 50 with them.
//!
//! **Why Relief's pyramid needs a per-line rule.** Relief's tiles nest: a level-`k` tile holds
//! `T` cells at stride `s_k = 2^(depth - k)` and meets, across any edge, a tile of level `k - 1`,
//! `k` or `k + 1` (the selection keeps neighbours within one level). One body per tile must
//! match all three. So a level-`k` tile's points on a half of a level-`(k - 1)` edge are exactly
//! that edge's points there, and the level-`(k + 1)` tiles' points on its own halves are exactly
//! its own: by induction, every tile along a *line* of the pyramid (a column or row of samples
//! on which tiles meet) takes the same points on it, whatever its level. Per-level point sets
//! on one edge cannot work. Two consequences, both forced:
//! - every tile corner on the line is a vertex of every tile along it, so a tile side of level
//!   `k` carries at least the `s_k + 1` multiples of `T` in its range (the corners of the finest
//!   tiles): a *comb* that grows coarser tiles' meshes, whatever the tolerance;
//! - the points must be vertices of the coarsest tiles along the line, so they lie on that
//!   level's lattice: a fine tile along a coarse line has a border as coarse as that lattice.
//!
//! **Relief's rule** ([`tile_borders`]). A line's *home level* `k0` is the coarsest level whose
//! tiles meet on it; its *home segments* are the sides of the level-`k0` tiles along it. Each
//! home segment's points are chosen once, from the samples on that segment at stride `s_k0`
//! (plus the line's last sample), by 1D greedy insertion ([`edge_points`]) to the tolerance
//! the caller gives the home level, starting from the segment's ends and every multiple of `T`
//! on it. Every tile along the line takes the points inside its side; both sides of the line
//! compute them from the same samples, so they get the same answer. Sides on the grid's outer
//! border have no neighbour and stay free. The rule needs the finest corners on every home
//! lattice, `s_k0 <= T` for the coarsest inner line (`k0 = 1`): `depth <= log2(T) + 1`, grids
//! up to 8193 samples a side for `T = 64` ([`BorderError::TooDeep`] beyond).
//!
//! **Cost.** Per side: one 1D insertion over at most `T + 1` samples, `O(T log T)`, recomputed
//! by each of the two tiles (cheaper than storing it). In triangles: the comb plus the points
//! the line's tolerance wants; `crate::lod::tile::mesh` figures (`examples/tin_figures.rs`)
//! measure it on real DEMs.

use super::tin::tin_locked;
use super::{HeightGrid, TriMesh};
use relief_proto::tile::{EDGES, Edge, TileId, TileShape, TileSpan};

/// Why shared borders cannot be formed.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum BorderError {
    /// A line's home lattice is coarser than the finest tiles' corners on it.
    #[error(
        "shared borders need depth <= log2(tile size) + 1: a line of level {home} has stride \
         {stride}, wider than the tile size {tile}"
    )]
    TooDeep {
        /// The line's home level.
        home: u8,
        /// Samples between vertices at that level.
        stride: u32,
        /// Cells per tile side.
        tile: u32,
    },
}

/// The points 1D greedy insertion keeps along a line of samples at positions `pos`
/// (increasing) with heights `z`: the ends, the `forced` indices, and, within each segment
/// between two kept points, the sample farthest (vertically) from the segment's chord while
/// that distance exceeds `tolerance` (ties: the smallest index). Returns indices into `pos`,
/// increasing. The order insertions happen in does not change the result (segments are
/// independent), so this is paper 003's greedy insertion restricted to a line, and a larger
/// tolerance keeps a subset of a smaller one's points.
pub fn edge_points(pos: &[u32], z: &[f32], tolerance: f32, forced: &[usize]) -> Vec<usize> {
    assert_eq!(pos.len(), z.len(), "one height per position");
    let n = pos.len();
    if n == 0 {
        return Vec::new();
    }
    let mut keep: Vec<usize> = forced.iter().copied().filter(|&i| i < n).collect();
    keep.extend([0, n - 1]);
    keep.sort_unstable();
    keep.dedup();
    let mut stack: Vec<(usize, usize)> = keep.windows(2).map(|w| (w[0], w[1])).collect();
    let tol = f64::from(tolerance);
    while let Some((i, j)) = stack.pop() {
        let (pi, pj) = (f64::from(pos[i]), f64::from(pos[j]));
        let (zi, zj) = (f64::from(z[i]), f64::from(z[j]));
        let mut best: Option<(f64, usize)> = None;
        for k in i + 1..j {
            let (pk, zk) = (f64::from(pos[k]), f64::from(z[k]));
            let err = ((pj - pk) * (zi - zk) + (pk - pi) * (zj - zk)).abs() / (pj - pi);
            if best.is_none_or(|b| err > b.0) {
                best = Some((err, k));
            }
        }
        if let Some((_, k)) = best.filter(|b| b.0 > tol) {
            keep.push(k);
            stack.extend([(i, k), (k, j)]);
        }
    }
    keep.sort_unstable();
    keep
}

/// Where side `edge` of a tile lies: whether its line is a column, the line's column (row),
/// the last column (row) of the grid, the side's first and last sample along the line, and
/// the line's last sample.
fn side_line(shape: &TileShape, span: &TileSpan, edge: Edge) -> (bool, u32, u32, u32, u32, u32) {
    let (w1, h1) = (shape.width() - 1, shape.height() - 1);
    let (c, r) = (span.cols, span.rows);
    match edge {
        Edge::North => (false, r.0, h1, c.0, c.1, w1),
        Edge::South => (false, r.1, h1, c.0, c.1, w1),
        Edge::West => (true, c.0, w1, r.0, r.1, h1),
        Edge::East => (true, c.1, w1, r.0, r.1, h1),
    }
}

/// The shared points on each side of tile `t` (north, east, south, west, as [`EDGES`]), as
/// vertex offsets along the side (west to east, north to south); `None` for a side on the
/// grid's outer border, which has no neighbour and stays free. `heights` are the full grid's
/// (row-major metres); `line_tolerance(k0)` is the tolerance, metres, of a line whose home
/// level is `k0` (see the module docs).
pub fn tile_borders(
    shape: &TileShape,
    t: TileId,
    heights: &[f32],
    line_tolerance: &dyn Fn(u8) -> f32,
) -> Result<[Option<Vec<u32>>; 4], BorderError> {
    let span = shape.span(t);
    let (w, tile) = (shape.width(), shape.tile_size());
    let mut out: [Option<Vec<u32>>; 4] = Default::default();
    for (slot, edge) in out.iter_mut().zip(EDGES) {
        let (on_cols, coord, outer, first, last, end) = side_line(shape, &span, edge);
        if coord == 0 || coord == outer {
            continue;
        }
        let home = (0..=shape.depth())
            .find(|&k| coord.is_multiple_of(tile * shape.stride(k)))
            .unwrap_or(t.level);
        let s = shape.stride(home);
        if s > tile {
            return Err(BorderError::TooDeep {
                home,
                stride: s,
                tile,
            });
        }
        let ext = tile * s;
        let a = first / ext * ext;
        let b = (a + ext).min(end);
        let mut pos: Vec<u32> = (a..b).step_by(s as usize).collect();
        pos.push(b);
        let forced: Vec<usize> = (0..pos.len())
            .filter(|&i| pos[i].is_multiple_of(tile) || i + 1 == pos.len())
            .collect();
        let z: Vec<f32> = pos
            .iter()
            .map(|&p| {
                let (c, r) = if on_cols { (coord, p) } else { (p, coord) };
                heights[(r * w + c) as usize]
            })
            .collect();
        let keep = edge_points(&pos, &z, line_tolerance(home), &forced);
        let stride = span.stride;
        let along = |p: u32| {
            if p == last {
                (last - first).div_ceil(stride)
            } else {
                (p - first) / stride
            }
        };
        *slot = Some(
            keep.into_iter()
                .map(|i| pos[i])
                .filter(|&p| p >= first && p <= last)
                .map(along)
                .collect(),
        );
    }
    Ok(out)
}

/// Tile `t`'s vertex heights, row-major over its `nx x ny` vertices (the grid `tin` meshes).
pub fn tile_heights(shape: &TileShape, t: TileId, heights: &[f32]) -> Vec<f32> {
    let span = shape.span(t);
    let w = shape.width();
    (0..span.vertex_count() as u32)
        .map(|v| {
            let (c, r) = span.vertex_pos(v);
            heights[(r * w + c) as usize]
        })
        .collect()
}

/// Tile `t`'s `tin` mesh (in tile vertex coordinates) at `tolerance` metres: with shared
/// borders when `line_tolerance` is given ([`tile_borders`]), plain otherwise.
pub fn tile_tin(
    shape: &TileShape,
    t: TileId,
    heights: &[f32],
    tolerance: f32,
    line_tolerance: Option<&dyn Fn(u8) -> f32>,
) -> Result<TriMesh, BorderError> {
    let span = shape.span(t);
    let (nx, ny) = (span.nx(), span.ny());
    let z = tile_heights(shape, t, heights);
    let grid = HeightGrid {
        width: nx as usize,
        height: ny as usize,
        z: &z,
    };
    let Some(lt) = line_tolerance else {
        return Ok(super::tin::tin(&grid, tolerance, &[]));
    };
    let sides = tile_borders(shape, t, heights, lt)?;
    let mut fixed = Vec::new();
    let mut locked = [false; 4];
    for ((edge, side), lock) in EDGES.into_iter().zip(&sides).zip(&mut locked) {
        let Some(points) = side else { continue };
        *lock = true;
        fixed.extend(points.iter().map(|&i| match edge {
            Edge::North => [i, 0],
            Edge::South => [i, ny - 1],
            Edge::West => [0, i],
            Edge::East => [nx - 1, i],
        }));
    }
    Ok(tin_locked(&grid, tolerance, &fixed, locked))
}

#[cfg(test)]
mod tests;
