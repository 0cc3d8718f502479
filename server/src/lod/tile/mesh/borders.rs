//! Shared border points for `tin` tiles (paper 003, section 4, "multi-resolution
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
//! - every tile corner on the line is a vertex of every tile along it, so a side of a level-`k`
//!   tile carries at least the `s_k + 1` multiples of `T` in its range (the corners of the
//!   finest tiles): a *comb*, whatever the tolerance;
//! - the coarsest tile along a line carries the border the finest one needs there. Its points
//!   must therefore be allowed off its own lattice ([`super::tin::tin_span`] takes fixed points
//!   anywhere in the window), or fine tiles inherit a border as coarse as that lattice (tried:
//!   up to 180 times their tolerance on Mt Fuji).
//!
//! **Relief's rule** ([`tile_borders`]). The points on a line are its multiples of `T` and its
//! ends, plus, between each two consecutive ones, the full-resolution samples that 1D greedy
//! insertion ([`edge_points`]) keeps to the line's tolerance. Every tile along the line takes
//! the points inside its side. The multiples of `T` cut the line into pieces that every side
//! along it starts and ends on, so a side's points depend only on its own samples: both tiles
//! compute them alike, and no one needs the whole line. The line's tolerance is the caller's,
//! given the line's *home level* `k0`, the coarsest level whose tiles meet on it:
//! - the finest level's tolerance keeps every tile within its own tolerance; coarse tiles pay
//!   for the fine borders;
//! - the home level's tolerance costs coarse tiles nothing beyond the comb; a level-`k` tile
//!   along the line may then be off by up to `tol(k0)` on that side.
//!
//! Sides on the grid's outer border have no neighbour and stay free. Within one level nothing
//! more is needed: a plain `tin` already picks each side's points by the same 1D insertion
//! ([`super::tin`], "sides first"), so same-level neighbours agree; the rule is for levels.
//!
//! **Cost.** Per side: one 1D insertion over its `T * s_k + 1` samples (`O(n log n)` typical,
//! `O(n^2)` at worst), done by each of the two tiles, cheaper than storing it. In triangles,
//! measured by `examples/tin_figures.rs pyramid` (T = 64, tolerances doubling per level up from
//! the finest, four real DEMs): with lines at the finest tolerance, every tile stays within its
//! own, and the finest and root levels pay nothing, level 1 pays 1-10%, level 2 up to 7%,
//! level 3 up to 3%; with lines at their home level's tolerance, at most 5% anywhere, but a
//! level-`k` tile along a line of home `k0` is off by up to `2^(k - k0)` times its tolerance.

use super::tin::tin_span;
use super::{HeightGrid, TriMesh};
use relief_proto::tile::{EDGES, Edge, TileId, TileShape};

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

/// The shared points on each side of tile `t` (north, east, south, west, as [`EDGES`]), as
/// sample offsets from the side's first sample (west to east, north to south); `None` for a
/// side on the grid's outer border, which has no neighbour and stays free. `grid` is the whole
/// grid's heights; `line_tolerance(k0)` is the tolerance, metres, of a line whose home level is
/// `k0` (see the module docs).
pub fn tile_borders(
    shape: &TileShape,
    t: TileId,
    grid: &HeightGrid<'_>,
    line_tolerance: &dyn Fn(u8) -> f32,
) -> [Option<Vec<u32>>; 4] {
    let span = shape.span(t);
    let (c, r, tile) = (span.cols, span.rows, shape.tile_size());
    let (w1, h1) = (shape.width() - 1, shape.height() - 1);
    EDGES.map(|edge| {
        // The line (a column when `on_col`), where the side lies on it, and the grid's last
        // line that way.
        let (on_col, line, (first, last), outer) = match edge {
            Edge::North => (false, r.0, c, h1),
            Edge::South => (false, r.1, c, h1),
            Edge::West => (true, c.0, r, w1),
            Edge::East => (true, c.1, r, w1),
        };
        if line == 0 || line == outer {
            return None;
        }
        let home = (0..=shape.depth())
            .find(|&k| line.is_multiple_of(tile * shape.stride(k)))
            .unwrap_or(t.level);
        let pos: Vec<u32> = (first..=last).collect();
        let z: Vec<f32> = pos
            .iter()
            .map(|&p| {
                if on_col {
                    grid.at(line, p)
                } else {
                    grid.at(p, line)
                }
            })
            .collect();
        let forced: Vec<usize> = (0..pos.len())
            .filter(|&i| pos[i].is_multiple_of(tile))
            .collect();
        let keep = edge_points(&pos, &z, line_tolerance(home), &forced);
        Some(keep.into_iter().map(|i| i as u32).collect())
    })
}

/// Tile `t`'s `tin` mesh at `tolerance` metres, over its lattice of `grid` (the whole grid),
/// vertices relative to its first sample: with shared borders when `line_tolerance` is given
/// ([`tile_borders`]), plain otherwise.
pub fn tile_tin(
    shape: &TileShape,
    t: TileId,
    grid: &HeightGrid<'_>,
    tolerance: f32,
    line_tolerance: Option<&dyn Fn(u8) -> f32>,
) -> TriMesh {
    let span = shape.span(t);
    let Some(lt) = line_tolerance else {
        return tin_span(grid, &span, tolerance, &[], [false; 4]);
    };
    let (w, h) = (span.cols.1 - span.cols.0, span.rows.1 - span.rows.0);
    let sides = tile_borders(shape, t, grid, lt);
    let mut fixed = Vec::new();
    let mut locked = [false; 4];
    for ((edge, side), lock) in EDGES.into_iter().zip(&sides).zip(&mut locked) {
        let Some(points) = side else { continue };
        *lock = true;
        fixed.extend(points.iter().map(|&i| match edge {
            Edge::North => [i, 0],
            Edge::South => [i, h],
            Edge::West => [0, i],
            Edge::East => [w, i],
        }));
    }
    tin_span(grid, &span, tolerance, &fixed, locked)
}

#[cfg(test)]
mod tests;
