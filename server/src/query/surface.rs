//! The full-resolution surface every query is exact against: over each cell, the **bilinear
//! patch** of its four corner samples,
//! `h(a, b) = h00 + (h10 - h00) a + (h01 - h00) b + (h00 - h10 - h01 + h11) a b`
//! for `a, b` in `[0, 1]` across the cell (a east, b north).
//!
//! Why the bilinear patch rather than the two triangles of a fixed diagonal: it is what paper
//! 004 interpolates the height map with, it has no preferred diagonal (so a query answers the
//! same on a mirrored terrain), it is continuous across cell edges (each edge is the straight
//! line between its two samples in both cells), it stays within its corners' range (so the
//! max-mip pyramid bounds it, [`super::pyramid`]), and a ray meets it where a quadratic in the
//! ray's distance vanishes, solved in closed form ([`super::ray`]). Normals are the patch's:
//! continuous inside a cell, with a crease at cell edges.
//!
//! Heights may also be asked bicubically ([`Interp::Bicubic`], Catmull-Rom through the 4 x 4
//! samples around the cell, clamped at the borders): smoother, through the samples too, but
//! not the surface rays and lines of sight meet.

use super::{QueryError, Terrain};
use glam::DVec3;

/// How heights between samples are interpolated.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Interp {
    /// The bilinear patch: the surface rays meet.
    #[default]
    Bilinear,
    /// Catmull-Rom bicubic through the 4 x 4 nearest samples.
    Bicubic,
}

/// The surface at a point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    /// Height, metres.
    pub height: f64,
    /// Unit upward normal of the bilinear patch.
    pub normal: DVec3,
}

/// A point located on the grid: its cell (counted from the south-west) and where in it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Located {
    /// Cell column.
    pub i: u32,
    /// Cell row, from the south.
    pub j: u32,
    /// Fraction across the cell eastwards, 0..=1.
    pub a: f64,
    /// Fraction across the cell northwards, 0..=1.
    pub b: f64,
}

/// The four corner heights of a cell: south-west, south-east, north-west, north-east.
pub(crate) type Corners = [f64; 4];

/// Height of the bilinear patch over `c` at `(a, b)`.
#[inline]
pub(crate) fn patch_height(c: &Corners, a: f64, b: f64) -> f64 {
    let [h00, h10, h01, h11] = *c;
    h00 + (h10 - h00) * a + (h01 - h00) * b + (h00 - h10 - h01 + h11) * a * b
}

/// The patch's slope in world units: `(dh/dx, dh/dy)` at `(a, b)` for spacing `dx`, `dy`.
#[inline]
pub(crate) fn patch_normal(c: &Corners, a: f64, b: f64, dx: f64, dy: f64) -> DVec3 {
    let [h00, h10, h01, h11] = *c;
    let e3 = h00 - h10 - h01 + h11;
    let ha = (h10 - h00) + e3 * b;
    let hb = (h01 - h00) + e3 * a;
    DVec3::new(-ha / dx, -hb / dy, 1.0).normalize()
}

impl Terrain {
    /// Corner heights of cell `(i, j)` (row from the south).
    #[inline]
    pub(crate) fn corners(&self, i: u32, j: u32) -> Corners {
        let w = self.width as usize;
        let k = j as usize * w + i as usize;
        let (s, n) = (&self.z[k..k + 2], &self.z[k + w..k + w + 2]);
        [
            f64::from(s[0]),
            f64::from(s[1]),
            f64::from(n[0]),
            f64::from(n[1]),
        ]
    }

    /// The cell holding world point `(x, y)` and where in it. Points on a cell edge belong to
    /// the cell east (north) of it, except on the terrain's east (north) border.
    pub(crate) fn locate(&self, x: f64, y: f64) -> Result<Located, QueryError> {
        if !(x.is_finite() && y.is_finite()) {
            return Err(QueryError::NotFinite);
        }
        let (cx, cy) = self.cells();
        let (u, v) = (x / self.dx, y / self.dy);
        // A point on the border whose division rounded a hair outside is still on it.
        let slack = |n: u32| 1e-9 * f64::from(n);
        if u < -slack(cx) || u > f64::from(cx) + slack(cx) {
            return Err(QueryError::Outside { x, y });
        }
        if v < -slack(cy) || v > f64::from(cy) + slack(cy) {
            return Err(QueryError::Outside { x, y });
        }
        let (u, v) = (u.clamp(0.0, f64::from(cx)), v.clamp(0.0, f64::from(cy)));
        // Truncation is the floor here: both are at least 0.
        let i = (u as u32).min(cx - 1);
        let j = (v as u32).min(cy - 1);
        Ok(Located {
            i,
            j,
            a: u - f64::from(i),
            b: v - f64::from(j),
        })
    }

    /// Height of the surface at world `(x, y)`, metres.
    pub fn height(&self, x: f64, y: f64) -> Result<f64, QueryError> {
        let p = self.locate(x, y)?;
        Ok(patch_height(&self.corners(p.i, p.j), p.a, p.b))
    }

    /// Height at world `(x, y)` interpolated as `interp` says, metres.
    pub fn height_with(&self, x: f64, y: f64, interp: Interp) -> Result<f64, QueryError> {
        match interp {
            Interp::Bilinear => self.height(x, y),
            Interp::Bicubic => {
                let p = self.locate(x, y)?;
                Ok(self.bicubic(p))
            }
        }
    }

    /// Height and normal of the surface at world `(x, y)`.
    pub fn surface(&self, x: f64, y: f64) -> Result<SurfacePoint, QueryError> {
        let p = self.locate(x, y)?;
        let c = self.corners(p.i, p.j);
        Ok(SurfacePoint {
            height: patch_height(&c, p.a, p.b),
            normal: patch_normal(&c, p.a, p.b, self.dx, self.dy),
        })
    }

    /// Heights at many world points, one answer per point, into `out` (cleared first).
    pub fn heights(
        &self,
        points: &[[f64; 2]],
        interp: Interp,
        out: &mut Vec<Result<f64, QueryError>>,
    ) {
        out.clear();
        out.extend(points.iter().map(|&[x, y]| self.height_with(x, y, interp)));
    }

    /// Catmull-Rom through the 4 x 4 samples around `p`'s cell, indices clamped at the borders.
    fn bicubic(&self, p: Located) -> f64 {
        let (w, h) = (self.width as i64, self.height as i64);
        let sample = |i: i64, j: i64| self.at(i.clamp(0, w - 1) as u32, j.clamp(0, h - 1) as u32);
        let (i, j) = (i64::from(p.i), i64::from(p.j));
        let mut rows = [0.0; 4];
        for (k, r) in rows.iter_mut().enumerate() {
            let jj = j - 1 + k as i64;
            *r = catmull_rom(
                [
                    sample(i - 1, jj),
                    sample(i, jj),
                    sample(i + 1, jj),
                    sample(i + 2, jj),
                ],
                p.a,
            );
        }
        catmull_rom(rows, p.b)
    }
}

/// The Catmull-Rom spline through `p[1]` (t = 0) and `p[2]` (t = 1).
#[inline]
fn catmull_rom(p: [f64; 4], t: f64) -> f64 {
    let [p0, p1, p2, p3] = p;
    p1 + 0.5
        * t
        * (p2 - p0 + t * (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3 + t * (3.0 * (p1 - p2) + p3 - p0)))
}
