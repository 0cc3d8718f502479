//! Deterministic 2D gradient noise (Perlin's, with a quintic fade) on an integer-hashed lattice,
//! evaluated a grid row at a time: the building block of [`super::synthetic`].
//!
//! [`Field::at`] is the definition, one sample at a time. [`RowSampler`] gives bit-identical
//! values for a whole row at a fraction of the cost: along a row the lattice row is fixed, so the
//! corner gradients are hashed once per lattice cell (and kept while rows stay in the same cell),
//! the vertical interpolation is done once per lattice column, and each sample costs a few
//! multiply-adds in a loop the compiler vectorises.
//!
//! Values lie in about [-0.7, 0.7], are 0 on lattice points, and average 0. Only integer hashing
//! and f32 arithmetic in a fixed order are used (no transcendental functions), so the values are
//! the same on every machine.

use std::f32::consts::FRAC_1_SQRT_2;

/// 16 unit gradient directions, 22.5 degrees apart.
const GRADIENTS: [(f32, f32); 16] = [
    (1.0, 0.0),
    (0.923_879_5, 0.382_683_43),
    (FRAC_1_SQRT_2, FRAC_1_SQRT_2),
    (0.382_683_43, 0.923_879_5),
    (0.0, 1.0),
    (-0.382_683_43, 0.923_879_5),
    (-FRAC_1_SQRT_2, FRAC_1_SQRT_2),
    (-0.923_879_5, 0.382_683_43),
    (-1.0, 0.0),
    (-0.923_879_5, -0.382_683_43),
    (-FRAC_1_SQRT_2, -FRAC_1_SQRT_2),
    (-0.382_683_43, -0.923_879_5),
    (0.0, -1.0),
    (0.382_683_43, -0.923_879_5),
    (FRAC_1_SQRT_2, -FRAC_1_SQRT_2),
    (0.923_879_5, -0.382_683_43),
];

/// A noise field sampled at lattice coordinates `(x * scale + off_x, y * scale + off_y)` for grid
/// sample (`x`, `y`).
#[derive(Clone, Copy, Debug)]
pub struct Field {
    /// Lattice cells per sample: the field's frequency.
    pub scale: f32,
    /// Lattice offset along x, so that fields do not share lattice lines.
    pub off_x: f32,
    /// Lattice offset along y.
    pub off_y: f32,
    /// Hash seed: each field gets its own gradients.
    pub seed: u32,
}

impl Field {
    /// The field at grid sample (`x`, `y`).
    pub fn at(&self, x: f32, y: f32) -> f32 {
        let (ix, fx, sx) = cell(x * self.scale + self.off_x);
        let (iy, fy, sy) = cell(y * self.scale + self.off_y);
        let (a0, b0) = column(self.seed, ix, iy, fy, sy);
        let (a1, b1) = column(self.seed, ix + 1, iy, fy, sy);
        blend(a0, b0, a1, b1, fx, sx)
    }
}

/// A lattice coordinate's cell, fraction within it, and faded fraction.
fn cell(c: f32) -> (i32, f32, f32) {
    let f = c.floor();
    let t = c - f;
    (f as i32, t, t * t * t * (t * (t * 6.0 - 15.0) + 10.0))
}

/// The gradient at lattice point (`x`, `y`): a hash (murmur3's finaliser) picks a direction.
fn gradient(seed: u32, x: i32, y: i32) -> (f32, f32) {
    let mut h = (x as u32).wrapping_mul(0x27D4_EB2D)
        ^ (y as u32).wrapping_mul(0x1656_67B1)
        ^ seed.wrapping_mul(0x9E37_79B9);
    h ^= h >> 15;
    h = h.wrapping_mul(0x85EB_CA6B);
    h ^= h >> 13;
    h = h.wrapping_mul(0xC2B2_AE35);
    h ^= h >> 16;
    GRADIENTS[(h >> 28) as usize]
}

/// Lattice column `ix` interpolated down to fraction `fy` (faded `sy`) of row `iy`: the noise
/// contribution of that column at horizontal offset `dx` is `a * dx + b`.
fn column(seed: u32, ix: i32, iy: i32, fy: f32, sy: f32) -> (f32, f32) {
    let (g0, g1) = (gradient(seed, ix, iy), gradient(seed, ix, iy + 1));
    lerp_column(g0, g1, fy, sy)
}

fn lerp_column(g0: (f32, f32), g1: (f32, f32), fy: f32, sy: f32) -> (f32, f32) {
    let a = g0.0 + (g1.0 - g0.0) * sy;
    let (d0, d1) = (g0.1 * fy, g1.1 * (fy - 1.0));
    (a, d0 + (d1 - d0) * sy)
}

/// The noise between lattice columns (`a0`, `b0`) and (`a1`, `b1`) at fraction `fx` (faded `sx`).
fn blend(a0: f32, b0: f32, a1: f32, b1: f32, fx: f32, sx: f32) -> f32 {
    let l = a0 * fx + b0;
    let r = a1 * (fx - 1.0) + b1;
    l + (r - l) * sx
}

/// Evaluates one [`Field`] along the rows of a grid `width` samples wide.
pub struct RowSampler {
    /// The field.
    field: Field,
    /// Lattice cell of column 0; cells are numbered from it.
    x0: i32,
    /// Runs of columns in one lattice cell: first column, end column, cell (from `x0`).
    runs: Vec<(usize, usize, usize)>,
    /// Each column's fraction within its cell.
    fx: Vec<f32>,
    /// Each column's faded fraction.
    sx: Vec<f32>,
    /// Lattice row whose gradients `g0` and `g1` hold, if any.
    row: Option<i32>,
    /// Gradients along lattice row `row`, lattice columns `x0..`.
    g0: Vec<(f32, f32)>,
    /// Gradients along lattice row `row + 1`.
    g1: Vec<(f32, f32)>,
    /// Each lattice column interpolated down to the current sample row, as `(a, b)`.
    ab: Vec<(f32, f32)>,
}

impl RowSampler {
    /// A sampler of `field` over rows of `width` (at least 1) samples.
    pub fn new(field: Field, width: usize) -> RowSampler {
        let cells: Vec<(i32, f32, f32)> = (0..width)
            .map(|x| cell(x as f32 * field.scale + field.off_x))
            .collect();
        let x0 = cells.first().map_or(0, |c| c.0);
        let mut runs: Vec<(usize, usize, usize)> = Vec::new();
        for (x, c) in cells.iter().enumerate() {
            let k = (c.0 - x0) as usize;
            match runs.last_mut() {
                Some(r) if r.2 == k => r.1 = x + 1,
                _ => runs.push((x, x + 1, k)),
            }
        }
        let span = cells.last().map_or(0, |c| (c.0 - x0) as usize) + 2;
        RowSampler {
            field,
            x0,
            runs,
            fx: cells.iter().map(|c| c.1).collect(),
            sx: cells.iter().map(|c| c.2).collect(),
            row: None,
            g0: vec![(0.0, 0.0); span],
            g1: vec![(0.0, 0.0); span],
            ab: vec![(0.0, 0.0); span],
        }
    }

    /// Writes the field along grid row `y` into `out` (`width` samples).
    pub fn row(&mut self, y: usize, out: &mut [f32]) {
        let f = self.field;
        let (iy, fy, sy) = cell(y as f32 * f.scale + f.off_y);
        if self.row != Some(iy) {
            for (k, (g0, g1)) in self.g0.iter_mut().zip(&mut self.g1).enumerate() {
                let ix = self.x0 + k as i32;
                (*g0, *g1) = (gradient(f.seed, ix, iy), gradient(f.seed, ix, iy + 1));
            }
            self.row = Some(iy);
        }
        for ((ab, &g0), &g1) in self.ab.iter_mut().zip(&self.g0).zip(&self.g1) {
            *ab = lerp_column(g0, g1, fy, sy);
        }
        for &(begin, end, k) in &self.runs {
            let ((a0, b0), (a1, b1)) = (self.ab[k], self.ab[k + 1]);
            let (fx, sx) = (&self.fx[begin..end], &self.sx[begin..end]);
            for ((o, &fx), &sx) in out[begin..end].iter_mut().zip(fx).zip(sx) {
                *o = blend(a0, b0, a1, b1, fx, sx);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_match_the_point_definition_bit_for_bit() {
        let fields = [
            Field {
                scale: 1.0 / 300.0,
                off_x: 0.37,
                off_y: -5.2,
                seed: 1,
            },
            Field {
                scale: 0.25,
                off_x: 17.9,
                off_y: 3.3,
                seed: 99,
            },
            Field {
                scale: 1.7,
                off_x: -2.0,
                off_y: 0.0,
                seed: 7,
            },
        ];
        for f in fields {
            let mut s = RowSampler::new(f, 257);
            let mut row = vec![0.0; 257];
            for y in [0usize, 1, 2, 100, 101, 256] {
                s.row(y, &mut row);
                for (x, v) in row.iter().enumerate() {
                    let p = f.at(x as f32, y as f32);
                    assert_eq!(v.to_bits(), p.to_bits(), "{f:?} at ({x}, {y})");
                }
            }
        }
    }

    #[test]
    fn noise_is_bounded_centred_and_zero_on_the_lattice() {
        let f = Field {
            scale: 0.05,
            off_x: 0.0,
            off_y: 0.0,
            seed: 3,
        };
        let v: Vec<f32> = (0..400 * 400)
            .map(|i| f.at((i % 400) as f32, (i / 400) as f32))
            .collect();
        assert!(v.iter().all(|x| x.abs() < 1.0));
        let mean = v.iter().sum::<f32>() / v.len() as f32;
        assert!(mean.abs() < 0.05, "mean {mean}");
        assert!(v.iter().any(|&x| x > 0.3) && v.iter().any(|&x| x < -0.3));
        assert_eq!(f.at(20.0, 40.0), 0.0);
    }
}
