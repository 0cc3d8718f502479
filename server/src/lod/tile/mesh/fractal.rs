//! Paper 002, section 2.1: the box-counting fractal dimension of a terrain region, and the
//! adaptive region quadtree it drives (flat regions stop subdividing early).
//!
//! **Box counting (section 2.1.1).** The surface `F` is the region's samples joined linearly
//! (the grid's triangles). Its bounding box is cut into cubes of side `eps`: `b x b` cells
//! across and `eps = b * g` metres tall, where `g = sqrt(dx * dy)` is the ground spacing in
//! metres, so that heights and ground are in one unit and a cube is a cube (exactly so where
//! `dx = dy`). Over each column of `b x b` cells the surface spans the heights between its
//! lowest and highest sample (a linear surface takes its extremes at vertices). The paper
//! stacks the cubes from the bounding box's floor `z0`, so a column meets
//! `floor((zmax - z0) / eps) - floor((zmin - z0) / eps) + 1` of them; that depends on where
//! the floor falls, and with relief comparable to `eps` it biases small regions (whose floor
//! is their own lowest sample) against large ones. Here a column counts the mean of that
//! over the stack's offset, `(zmax - zmin) / eps + 1`; `N(eps)` is the sum over columns (a
//! column cut short by the region's edge counts in proportion to its area).
//!
//! The paper counts at 3 to 5 sizes; here they are `b = 1, 2, 4, ...` cells,
//! [`FractalParams::scales`] of them (5: up to 16 cells), none over a quarter of the region's
//! shorter side, and at least 3. The sizes are the same for every region, so that a large
//! region's dimension is its fine-scale roughness on average, comparable with a small one's
//! (at sizes relative to the region, a large region's columns are so much wider than its
//! relief is tall that every region looks flat from the root). The dimension is minus the
//! least-squares slope of `ln N(eps)` against `ln eps`. A plane gives 2, tilted or not (its
//! cubes per column do not change with scale); white noise much taller than the spacing
//! nearly 3; real terrain lies between (fractional Brownian relief of Hurst exponent `H`
//! tends to `3 - H` at scales where its relief is taller than `eps`).
//!
//! **Region tree (section 2.1.2).** The paper splits regions into four equal quadrants while
//! their dimension is high ("near 2.3": subdivide) and stops where it is near 2.0 (flat). The
//! regions here are the tile pyramid's tiles (their spans, [`TileShape::span`]), so a leaf
//! names the level at which the pyramid may stop refining. A region subdivides while its
//! side is larger than the largest leaf its dimension `D` allows: the whole grid at
//! `D <= flat`, the finest tiles at `D >= rough`, and log-linearly in between. The two
//! thresholds are [`FractalParams`]; `docs/fractal.md` justifies their defaults.

use super::HeightGrid;
use relief_proto::tile::{TileId, TileShape, TileSpan};

/// Thresholds of the region tree.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FractalParams {
    /// Dimension at or below which a region is flat: a leaf, whatever its size.
    pub flat: f32,
    /// Dimension at or above which a region subdivides down to the finest tiles.
    pub rough: f32,
    /// The most box sizes one estimate regresses over (the paper's 3 to 5).
    pub scales: u32,
}

impl Default for FractalParams {
    fn default() -> Self {
        FractalParams {
            flat: 2.01,
            rough: 2.04,
            scales: 5,
        }
    }
}

/// A leaf of the region tree.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FractalLeaf {
    /// The tile whose span the region is.
    pub tile: TileId,
    /// Its box-counting dimension; `None` where the region is under 16 cells across (too few
    /// box sizes for a slope).
    pub dimension: Option<f32>,
}

/// `(eps, N(eps))` for each box size over the samples `cols` x `rows` (first and last,
/// inclusive) of `grid`, finest first; `spacing` is the ground metres between columns and
/// between rows. Empty when the region is under 16 cells across.
pub fn box_counts(
    grid: &HeightGrid<'_>,
    spacing: [f64; 2],
    cols: (u32, u32),
    rows: (u32, u32),
    scales: u32,
) -> Vec<(f64, f64)> {
    let (cw, ch) = ((cols.1 - cols.0) as usize, (rows.1 - rows.0) as usize);
    let short = cw.min(ch);
    if short < 16 {
        return Vec::new();
    }
    let top = ((1usize << short.ilog2()) / 4).min(1 << scales.saturating_sub(1).min(16));
    let g = (spacing[0] * spacing[1]).sqrt();
    let at = |c: usize, r: usize| f64::from(grid.at(cols.0 + c as u32, rows.0 + r as u32));
    // Lowest and highest sample of each cell, then of each b x b block (children merged).
    let (mut w, mut h) = (cw, ch);
    // Cells per column at the current size (short at the region's east and south edges).
    let mut cells = vec![1.0f64; w * h];
    let mut lo = vec![0.0f64; w * h];
    let mut hi = vec![0.0f64; w * h];
    for r in 0..h {
        for c in 0..w {
            let v = [at(c, r), at(c + 1, r), at(c, r + 1), at(c + 1, r + 1)];
            lo[r * w + c] = v.iter().copied().fold(f64::INFINITY, f64::min);
            hi[r * w + c] = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        }
    }
    let mut out = Vec::new();
    let mut b = 1;
    loop {
        let eps = b as f64 * g;
        let full = (b * b) as f64;
        let n: f64 = (0..w * h)
            .map(|i| {
                let cubes = (hi[i] - lo[i]) / eps + 1.0;
                cubes * cells[i] / full
            })
            .sum();
        out.push((eps, n));
        if b >= top {
            return out;
        }
        let (nw, nh) = (w.div_ceil(2), h.div_ceil(2));
        let mut nlo = vec![f64::INFINITY; nw * nh];
        let mut nhi = vec![f64::NEG_INFINITY; nw * nh];
        let mut ncells = vec![0.0f64; nw * nh];
        for r in 0..h {
            for c in 0..w {
                let j = (r / 2) * nw + c / 2;
                nlo[j] = nlo[j].min(lo[r * w + c]);
                nhi[j] = nhi[j].max(hi[r * w + c]);
                ncells[j] += cells[r * w + c];
            }
        }
        (w, h, lo, hi, cells, b) = (nw, nh, nlo, nhi, ncells, 2 * b);
    }
}

/// Minus the least-squares slope of `ln N` against `ln eps`; `None` under 3 points.
pub fn dimension_of(counts: &[(f64, f64)]) -> Option<f32> {
    if counts.len() < 3 {
        return None;
    }
    let n = counts.len() as f64;
    let (mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0);
    for &(eps, count) in counts {
        let (x, y) = (eps.ln(), count.ln());
        (sx, sy, sxx, sxy) = (sx + x, sy + y, sxx + x * x, sxy + x * y);
    }
    Some((-(n * sxy - sx * sy) / (n * sxx - sx * sx)) as f32)
}

/// The box-counting dimension of the region `cols` x `rows` (see the module docs).
pub fn box_dimension(
    grid: &HeightGrid<'_>,
    spacing: [f64; 2],
    cols: (u32, u32),
    rows: (u32, u32),
    scales: u32,
) -> Option<f32> {
    dimension_of(&box_counts(grid, spacing, cols, rows, scales))
}

/// The coarsest pyramid level whose tiles may be leaves for a region of dimension `d`, in a
/// pyramid whose finest level is `depth`: 0 at or below `flat`, `depth` at or above `rough`,
/// log-linearly in between. A region at `level` subdivides exactly when `level` is coarser
/// than this ([`subdivides`]).
pub fn leaf_level(p: &FractalParams, d: f32, depth: u8) -> u8 {
    if d.is_nan() || d <= p.flat {
        return 0;
    }
    let f = ((d - p.flat) / (p.rough - p.flat)).clamp(0.0, 1.0);
    // `subdivides` splits while `level < f * depth - 1e-4`: the first level that does not.
    (f * f32::from(depth) - 1e-4)
        .ceil()
        .clamp(0.0, f32::from(depth)) as u8
}

/// Why a leaf of the region tree stopped subdividing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LeafStop {
    /// Under 16 cells across: too few box sizes for a dimension, so it cannot be judged.
    NoDimension,
    /// Its dimension is at or below `flat`: a leaf whatever its size.
    Flat,
    /// Its dimension asks for the finest tiles (at or above `rough`, or close enough below
    /// it), and it is one: the pyramid has no finer tiles to split it into.
    Finest,
    /// Its dimension lies between the thresholds and the region is no larger than that
    /// dimension allows ([`leaf_level`]), above the finest level or not.
    Sized,
}

impl LeafStop {
    /// The stop of `leaf`, a leaf of the tree built with `p` over a pyramid of `depth` levels.
    pub fn of(p: &FractalParams, leaf: &FractalLeaf, depth: u8) -> LeafStop {
        match leaf.dimension {
            None => LeafStop::NoDimension,
            Some(d) if d.is_nan() || d <= p.flat => LeafStop::Flat,
            Some(d) if leaf.tile.level >= depth && leaf_level(p, d, depth) >= depth => {
                LeafStop::Finest
            }
            Some(_) => LeafStop::Sized,
        }
    }

    /// Its name in reports: `no_dimension`, `flat`, `finest` or `sized`.
    pub fn name(self) -> &'static str {
        match self {
            LeafStop::NoDimension => "no_dimension",
            LeafStop::Flat => "flat",
            LeafStop::Finest => "finest",
            LeafStop::Sized => "sized",
        }
    }
}

/// Whether a region of dimension `d` at `level` subdivides, in a pyramid of `depth` levels.
pub fn subdivides(p: &FractalParams, d: Option<f32>, level: u8, depth: u8) -> bool {
    let Some(d) = d else { return false };
    if level >= depth || d <= p.flat {
        return false;
    }
    let f = ((d - p.flat) / (p.rough - p.flat)).clamp(0.0, 1.0);
    // The coarsest level whose tiles may be leaves: 0 when flat, `depth` when rough.
    f32::from(level) < f * f32::from(depth) - 1e-4
}

/// The leaves of the region tree over `grid` (which `shape` was made for), depth first,
/// children in [`TileId::child`] order: together they cover the grid once.
pub fn fractal_leaves(
    grid: &HeightGrid<'_>,
    spacing: [f64; 2],
    shape: &TileShape,
    params: &FractalParams,
) -> Vec<FractalLeaf> {
    fractal_leaves_with_progress(grid, spacing, shape, params, |_| {})
}

/// [`fractal_leaves`], calling `progress` after each leaf with the fraction of the grid's
/// cells the leaves so far cover (1 after the last; nothing while the root is measured).
pub fn fractal_leaves_with_progress(
    grid: &HeightGrid<'_>,
    spacing: [f64; 2],
    shape: &TileShape,
    params: &FractalParams,
    mut progress: impl FnMut(f64),
) -> Vec<FractalLeaf> {
    let cells = |s: TileSpan| f64::from(s.cols.1 - s.cols.0) * f64::from(s.rows.1 - s.rows.0);
    let total = cells(shape.span(TileId::ROOT)).max(1.0);
    let mut covered = 0.0;
    let mut leaves = Vec::new();
    let mut stack = vec![TileId::ROOT];
    while let Some(t) = stack.pop() {
        let span = shape.span(t);
        let d = box_dimension(grid, spacing, span.cols, span.rows, params.scales);
        if subdivides(params, d, t.level, shape.depth()) {
            let mut kids: Vec<TileId> = shape.children(t).collect();
            kids.reverse();
            stack.extend(kids);
        } else {
            leaves.push(FractalLeaf {
                tile: t,
                dimension: d,
            });
            covered += cells(span);
            progress(covered / total);
        }
    }
    leaves
}

#[cfg(test)]
mod tests;
