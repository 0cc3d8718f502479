//! The first hit of a ray on the surface, by paper 004's multi-level ray tracing (section
//! "Визуализация", figures 5 and 6) over the max-mip pyramid, and by a brute-force
//! cell-by-cell march that checks it.
//!
//! **What a hit is.** A ray is `origin + t * unit(dir)` for `t` in `[0, max_dist]` metres. Its
//! first hit is the smallest `t` at which the ray is on or below the surface
//! ([`super::surface`]) over the terrain: so a ray whose origin is on or under the ground hits
//! at distance 0, a ray that enters the terrain's extent from the side below the surface hits
//! where it enters, and outside the extent there is no ground to hit. Horizontal and vertical
//! rays, rays along cell edges and through vertices need no special case: every cell whose
//! closed square the ray touches is a candidate, each answers the smallest `t` at which the
//! ray meets its patch (a quadratic in `t`, solved in closed form), and the first hit is the
//! smallest answer, ties going to the southmost, then westmost cell. Both traversals below
//! evaluate the same per-cell function, each on every cell that could hold the first hit, so
//! they return identical hits.
//!
//! **The traversal** ([`Terrain::cast`]) is the paper's multi-level tracing (figure 5) done
//! without a stack, as in maximum-mipmap relief rendering: it holds one node of the pyramid
//! (its shift `l`, integer coordinates `(x, y)`) and the distance `t` at which the ray enters
//! it, and steps along the ray. The ray leaves the node where it crosses the node's east or
//! west side (`tx`), its north or south side (`ty`), or leaves the grid or reaches
//! `max_dist`, whichever comes first (`te`); the sides are integers times `2^l`, turned into
//! distances with the ray's precomputed inverse direction. Then:
//!
//! - if the ray's lower end over `[t, te]` (the ray being straight) stays above the node's
//!   max by [`SKIP_MARGIN`], the node is cleared: `t` moves to `te`, the node steps to its
//!   neighbour across the side the ray leaves by (both neighbours' common one through a
//!   corner), and the walk goes up a level when that neighbour lies in another parent;
//! - otherwise, above shift 0, the walk goes down to the child the ray is in just after `t`,
//!   found by comparing `t` with where the ray crosses the node's middle lines, computed by
//!   the same expression as the sides, so that a step and a later descent always agree on
//!   which node the ray is in;
//! - at shift 0 (single cells, bounded by their four corner samples, which the pyramid does
//!   not store), a cell the ray is not clear of is tried with the per-cell solution.
//!
//! The walk starts where the ray enters the grid, at the level the paper's figure 6 suggests:
//! the cells the ray crosses while it falls by its height above the sample under that point,
//! as a power of two, one level lower ([`START_BELOW`]), at most the root. It stops at the end
//! of the ray, or as soon as the next stretch begins after the best hit so far.
//!
//! **Why it returns the march's hit.** The stretches the walk steps through cover the ray
//! within the grid, each closed. A cleared stretch lies in its node's closed square, where
//! every cell's patch stays at or under the node's max (a node holds every corner sample of
//! its cells, border samples included, [`super::pyramid`]), while the ray stays above it by
//! [`SKIP_MARGIN`], far more than any rounding: no cell has its hit there. So the first hit
//! lies on a stretch through a cell that was tried, on that cell or on another cell whose
//! closed square the stretch touches. A straight stretch inside a cell touches other cells
//! only at its ends, or all along where it runs along a grid line. The walk therefore also
//! tries every cell whose square holds an end of the stretch, within [`NEAR`] of it (two
//! cells on an edge, four at a vertex), where the stretch on the other side of that end was
//! tried too, at the ray's first and last stretch, and at both ends of a stretch along a grid
//! line; where the stretch on the other side was cleared, no cell has its hit at that end.
//! Every cell is tried with the same function the march uses, and the best hit is chosen by
//! the same order, so that both return the same hit, bit for bit. Exact ties between cells
//! meeting at a vertex rest on the rounding tolerances above rather than on a proof: the
//! property tests check both traversals exactly against trying every cell of the grid on
//! rays through vertices, and the benchmark counts any difference.
//!
//! **The brute force** ([`Terrain::march`]) visits every cell the ray's segment crosses,
//! column by column in ray order (a DDA over the closed cells, widened by [`NEAR`], so that
//! cells touched along an edge or at a vertex are visited too, even where rounding puts the
//! ray a hair off the vertex), and stops at the first hit likewise. It is the
//! baseline the traversal is measured against (`relief-server bench query`).

use super::surface::{Corners, patch_height, patch_normal};
use super::{QueryError, Terrain};
use glam::DVec3;

/// A ray: where it starts, where it goes, and how far it is followed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Start, world metres.
    pub origin: DVec3,
    /// Direction, any non-zero length.
    pub dir: DVec3,
    /// How far along the ray to look, metres (`f64::INFINITY`: to the terrain's end).
    pub max_dist: f64,
}

/// Where a ray first meets the ground.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// The hit point, world metres.
    pub point: DVec3,
    /// Distance from the ray's origin, metres.
    pub distance: f64,
    /// The surface's unit upward normal there.
    pub normal: DVec3,
    /// The cell hit, as `[col, row]` of its north-west corner sample (row 0 north).
    pub cell: [u32; 2],
}

/// How far above a node's max the ray must stay to skip it, metres: far more than the
/// rounding of the per-cell solution, far less than any terrain detail.
const SKIP_MARGIN: f64 = 1e-6;

/// Levels below the one the ray's height above the ground suggests that the traversal
/// starts at.
const START_BELOW: u32 = 1;

/// Cells remembered as tried, so that the cells around the point where two stretches of the
/// ray meet are not tried twice.
const RECENT: usize = 4;

/// How near a grid line, relative to the coordinates' size, a point of the ray counts as on
/// it: far more than their rounding, so that no cell the ray may touch there is missed.
const NEAR: f64 = 1e-9;

/// A ray in grid units: `u = x / dx`, `v = y / dy` (rows from the south), `z` in metres, all
/// against the distance `t` in metres along the unit direction.
#[derive(Clone, Copy, Debug)]
pub(crate) struct GridRay {
    /// Origin `(u, v, z)`; `z` lowered by the clearance for lines of sight.
    o: [f64; 3],
    /// Change of `(u, v, z)` per metre along the ray; `u` or `v` 0 when it does not change.
    d: [f64; 3],
    /// `1 / d[0]` and `1 / d[1]` (unused where `d` is 0).
    inv: [f64; 2],
    /// The ray's length, metres.
    tmax: f64,
    /// Origin in world metres, for the hit point.
    origin: DVec3,
    /// Unit direction in world metres, for the hit point.
    unit: DVec3,
}

/// A hit on one cell.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct CellHit {
    /// Distance along the ray, metres.
    pub t: f64,
    /// Cell column.
    pub i: u32,
    /// Cell row from the south.
    pub j: u32,
}

impl CellHit {
    /// Whether `self` comes before `other`: nearer, or as near and southmost, then westmost.
    #[inline]
    fn before(&self, other: &Option<CellHit>) -> bool {
        match other {
            None => true,
            Some(o) => (self.t, self.j, self.i) < (o.t, o.j, o.i),
        }
    }
}

impl GridRay {
    /// `ray` on `terrain`'s grid, its height lowered by `lower` metres.
    pub(crate) fn new(terrain: &Terrain, ray: &Ray, lower: f64) -> Result<GridRay, QueryError> {
        if !(ray.origin.is_finite() && ray.dir.is_finite()) || ray.max_dist.is_nan() {
            return Err(QueryError::NotFinite);
        }
        if ray.max_dist < 0.0 {
            return Err(QueryError::Negative(ray.max_dist));
        }
        terrain.check_reach(ray.origin, "the ray's origin")?;
        let big = ray.dir.abs().max_element();
        if big == 0.0 {
            return Err(QueryError::ZeroDirection);
        }
        let unit = (ray.dir / big).normalize();
        let (mut du, mut dv) = (unit.x / terrain.dx, unit.y / terrain.dy);
        let (mut iu, mut iv) = (1.0 / du, 1.0 / dv);
        if !iu.is_finite() {
            (du, iu) = (0.0, 0.0);
        }
        if !iv.is_finite() {
            (dv, iv) = (0.0, 0.0);
        }
        Ok(GridRay {
            o: [
                ray.origin.x / terrain.dx,
                ray.origin.y / terrain.dy,
                ray.origin.z - lower,
            ],
            d: [du, dv, unit.z],
            inv: [iu, iv],
            tmax: ray.max_dist,
            origin: ray.origin,
            unit,
        })
    }

    /// The closed interval of `t` in `[0, tmax]` over which the ray lies in the square
    /// `[u0, u1] x [v0, v1]`, if any.
    #[inline]
    fn slab(&self, u0: f64, u1: f64, v0: f64, v1: f64) -> Option<(f64, f64)> {
        let (a0, a1) = axis(self.o[0], self.d[0], self.inv[0], u0, u1);
        let (b0, b1) = axis(self.o[1], self.d[1], self.inv[1], v0, v1);
        let ta = a0.max(b0).max(0.0);
        let tb = a1.min(b1).min(self.tmax);
        (ta <= tb).then_some((ta, tb))
    }

    /// Whether the ray's stretch over `[ta, tb]` runs along a grid line, within rounding:
    /// both ends on the same line of constant `u` or `v`.
    #[inline]
    fn along_line(&self, ta: f64, tb: f64) -> bool {
        (0..2).any(|a| {
            let (p, q) = (self.o[a] + self.d[a] * ta, self.o[a] + self.d[a] * tb);
            let k = p.round();
            let tol = NEAR * (1.0 + self.o[a].abs() + (self.d[a] * tb).abs());
            (p - k).abs() <= tol && (q - k).abs() <= tol
        })
    }

    /// The ray's height at `t`.
    #[inline]
    fn z(&self, t: f64) -> f64 {
        self.o[2] + self.d[2] * t
    }
}

/// The interval of `t` over which `o + d t` lies in `[lo, hi]` (everything or nothing when `d`
/// is 0).
#[inline]
fn axis(o: f64, d: f64, inv: f64, lo: f64, hi: f64) -> (f64, f64) {
    if d != 0.0 {
        let (a, b) = ((lo - o) * inv, (hi - o) * inv);
        if a <= b { (a, b) } else { (b, a) }
    } else if o >= lo && o <= hi {
        (f64::NEG_INFINITY, f64::INFINITY)
    } else {
        (f64::INFINITY, f64::NEG_INFINITY)
    }
}

/// The node after node `(x, y)` at shift `l` along the ray, which leaves it eastwards or
/// westwards (`across_x`, step `sx`) and northwards or southwards (`across_y`, step `sy`), both at
/// a corner; a level up (below `top`) when that node lies in another parent.
#[inline]
fn next_node(
    (x, y, l): (i64, i64, u32),
    across_x: bool,
    across_y: bool,
    (sx, sy): (i64, i64),
    top: u32,
) -> (i64, i64, u32) {
    let (px, py) = (x >> 1, y >> 1);
    let nx = if across_x { x + sx } else { x };
    let ny = if across_y { y + sy } else { y };
    if l < top && (nx >> 1 != px || ny >> 1 != py) {
        (nx >> 1, ny >> 1, l + 1)
    } else {
        (nx, ny, l)
    }
}

/// `ceil(x) - 1`, at least 0: the first of the closed unit intervals `[k, k+1]` holding `x`.
#[inline]
fn ceil_minus_one(x: f64) -> u32 {
    let t = x.max(0.0) as u32;
    if f64::from(t) < x {
        t
    } else {
        t.saturating_sub(1)
    }
}

/// The smallest `s` in `[0, l]` at which `a s^2 + b s + c <= 0`, if any.
#[inline]
fn first_root(a: f64, b: f64, c: f64, l: f64) -> Option<f64> {
    if c <= 0.0 {
        return Some(0.0);
    }
    let disc = b * b - 4.0 * a * c;
    if disc >= 0.0 {
        // The stable pair of roots: no cancellation whatever the signs.
        let q = -0.5 * (b + b.signum() * disc.sqrt());
        let (r1, r2) = (q / a, c / q);
        let lo = r1.min(r2);
        let hi = r1.max(r2);
        for r in [lo, hi] {
            if r.is_finite() && (0.0..=l).contains(&r) {
                return Some(r);
            }
        }
    }
    // The root lies at the span's end but rounded a hair past it.
    (l.is_finite() && (a * l + b) * l + c <= 0.0).then_some(l)
}

impl Terrain {
    /// The first hit of `ray` by the paper's hierarchical traversal of the max-mip pyramid.
    pub fn cast(&self, ray: &Ray) -> Result<Option<Hit>, QueryError> {
        let r = GridRay::new(self, ray, 0.0)?;
        Ok(self.cast_grid(&r).map(|h| self.hit(&r, h)))
    }

    /// The first hit of `ray` by the brute-force march over every cell it crosses: the
    /// reference [`Terrain::cast`] is checked against, and the baseline it is measured with.
    pub fn march(&self, ray: &Ray) -> Result<Option<Hit>, QueryError> {
        let r = GridRay::new(self, ray, 0.0)?;
        Ok(self.march_grid(&r).map(|h| self.hit(&r, h)))
    }

    /// The world hit of cell hit `h` on `r`: the point on the ray (not lowered).
    pub(crate) fn hit(&self, r: &GridRay, h: CellHit) -> Hit {
        let (u, v) = (r.o[0] + r.d[0] * h.t, r.o[1] + r.d[1] * h.t);
        let a = (u - f64::from(h.i)).clamp(0.0, 1.0);
        let b = (v - f64::from(h.j)).clamp(0.0, 1.0);
        let c = self.corners(h.i, h.j);
        Hit {
            point: r.origin + r.unit * h.t,
            distance: h.t,
            normal: patch_normal(&c, a, b, self.dx, self.dy),
            cell: [h.i, self.height - 2 - h.j],
        }
    }

    /// Where `r` first meets the patch of cell `(i, j)`, if it does: a pure function of the
    /// ray and the cell, so that every traversal gets the same answer from the same cell.
    #[inline]
    pub(crate) fn cell_hit(&self, r: &GridRay, i: u32, j: u32) -> Option<CellHit> {
        let (fi, fj) = (f64::from(i), f64::from(j));
        let (ta, tb) = r.slab(fi, fi + 1.0, fj, fj + 1.0)?;
        let c: Corners = self.corners(i, j);
        let top = c[0].max(c[1]).max(c[2]).max(c[3]);
        let (z0, z1) = (r.z(ta), r.z(tb));
        if z0.min(z1) > top + SKIP_MARGIN {
            return None;
        }
        let a0 = (r.o[0] + r.d[0] * ta - fi).clamp(0.0, 1.0);
        let b0 = (r.o[1] + r.d[1] * ta - fj).clamp(0.0, 1.0);
        let [h00, h10, h01, h11] = c;
        let (e1, e2, e3) = (h10 - h00, h01 - h00, h00 - h10 - h01 + h11);
        let [du, dv, dz] = r.d;
        // f(s) = ray height - patch height at t = ta + s: a quadratic in s.
        let qc = z0 - patch_height(&c, a0, b0);
        let qb = dz - e1 * du - e2 * dv - e3 * (a0 * dv + b0 * du);
        let qa = -e3 * du * dv;
        let s = first_root(qa, qb, qc, tb - ta)?;
        Some(CellHit { t: ta + s, i, j })
    }

    /// The hierarchical traversal (module docs).
    pub(crate) fn cast_grid(&self, r: &GridRay) -> Option<CellHit> {
        let (cx, cy) = self.cells();
        let (t0, t1) = r.slab(0.0, f64::from(cx), 0.0, f64::from(cy))?;
        let mut best = None;
        let top = self.pyramid.top_shift();
        let (mut t, mut l) = (t0, self.start_shift(r, t0, top));
        let [mut x, mut y] = self.node_at(r, t, l);
        // Which side of a node the ray leaves by: 1 where it goes east (north), else 0.
        let ex = i64::from(r.d[0] > 0.0);
        let ey = i64::from(r.d[1] > 0.0);
        let sx = if r.d[0] >= 0.0 { 1 } else { -1 };
        let sy = if r.d[1] >= 0.0 { 1 } else { -1 };
        // The ray's lowest point over `[ta, tb]`.
        let low = |ta: f64, tb: f64| r.z(if r.d[2] < 0.0 { tb } else { ta });
        // The cells tried last, not to try them again where stretches meet.
        let (mut recent, mut next) = ([u64::MAX; RECENT], 0usize);
        // Whether the stretch before `t` was a cell tried (not a node cleared).
        let mut open = false;
        loop {
            let size = (1u64 << l) as f64;
            // Where the ray leaves node (x, y): by its east or west side at `tx`, by its
            // north or south side at `ty`, or out of the grid (or at its length) at `t1`.
            let tx = if r.d[0] != 0.0 {
                ((x + ex) as f64 * size - r.o[0]) * r.inv[0]
            } else {
                f64::INFINITY
            };
            let ty = if r.d[1] != 0.0 {
                ((y + ey) as f64 * size - r.o[1]) * r.inv[1]
            } else {
                f64::INFINITY
            };
            let te = tx.min(ty).min(t1).max(t);
            let max = if l == 0 {
                let c = self.corners(x as u32, y as u32);
                c[0].max(c[1]).max(c[2]).max(c[3])
            } else {
                f64::from(self.pyramid.max(l, x as u32, y as u32))
            };
            if low(t, te) > max + SKIP_MARGIN {
                // Clear of the node: on to the next one, and a level up where that one lies
                // in another parent.
                open = false;
                if te >= t1 {
                    break;
                }
                (x, y, l) = next_node((x, y, l), tx <= ty, ty <= tx, (sx, sy), top);
                t = te;
            } else if l > 0 {
                // Under the node's max somewhere: down to the child the ray is in at `t`.
                let half = size / 2.0;
                let bit = |o: f64, d: f64, inv: f64, k: i64| -> i64 {
                    let mid = (2 * k + 1) as f64 * half;
                    if d > 0.0 {
                        i64::from(t >= (mid - o) * inv)
                    } else if d < 0.0 {
                        i64::from(t < (mid - o) * inv)
                    } else {
                        i64::from(o >= mid)
                    }
                };
                let (bx, by) = (
                    bit(r.o[0], r.d[0], r.inv[0], x),
                    bit(r.o[1], r.d[1], r.inv[1], y),
                );
                l -= 1;
                let (nw, nh) = self.pyramid.dims(l);
                x = (2 * x + bx).min(i64::from(nw) - 1);
                y = (2 * y + by).min(i64::from(nh) - 1);
            } else {
                // A cell the ray may meet: tried, and with it the cells around the ends of
                // its stretch where a hit there could be theirs (module docs).
                let mut tried = |i: u32, j: u32, best: &mut Option<CellHit>| {
                    let key = u64::from(i) | u64::from(j) << 32;
                    if !recent.contains(&key) {
                        recent[next % RECENT] = key;
                        next += 1;
                        self.try_cell(r, i, j, best);
                    }
                };
                let along = r.along_line(t, te);
                if t == t0 || open || along {
                    self.around(r, t, &mut best, &mut tried);
                }
                tried(x as u32, y as u32, &mut best);
                if te >= t1 || along {
                    self.around(r, te, &mut best, &mut tried);
                }
                open = true;
                if te >= t1 {
                    break;
                }
                (x, y, l) = next_node((x, y, l), tx <= ty, ty <= tx, (sx, sy), top);
                t = te;
            }
            if best.is_some_and(|b| t > b.t) {
                break;
            }
        }
        best
    }

    /// Tries, through `tried`, every cell whose square holds the ray's point at `t` or lies
    /// within rounding of it: one cell inside, two on an edge, four at a vertex.
    #[inline]
    fn around(
        &self,
        r: &GridRay,
        t: f64,
        best: &mut Option<CellHit>,
        tried: &mut impl FnMut(u32, u32, &mut Option<CellHit>),
    ) {
        let (cx, cy) = self.cells();
        let range = |a: usize, n: u32| {
            let p = r.o[a] + r.d[a] * t;
            let tol = NEAR * (1.0 + r.o[a].abs() + (r.d[a] * t).abs());
            let lo = ((p - tol).ceil() - 1.0).max(0.0) as u32;
            let hi = ((p + tol).floor().max(0.0) as u32).min(n - 1);
            (lo.min(n - 1), hi)
        };
        let ((i0, i1), (j0, j1)) = (range(0, cx), range(1, cy));
        for j in j0..=j1 {
            for i in i0..=i1 {
                tried(i, j, best);
            }
        }
    }

    /// The shift to start at (paper 004, figure 6): about the cells the ray crosses while it
    /// falls by its height above the ground where it enters the grid at `t`, up to `top`.
    #[inline]
    fn start_shift(&self, r: &GridRay, t: f64, top: u32) -> u32 {
        if r.d[2] >= 0.0 {
            return top;
        }
        let (cx, cy) = self.cells();
        let u = (r.o[0] + r.d[0] * t).clamp(0.0, f64::from(cx - 1));
        let v = (r.o[1] + r.d[1] * t).clamp(0.0, f64::from(cy - 1));
        let h = r.z(t) - self.at(u as u32, v as u32);
        let cells = h / -r.d[2] * r.d[0].abs().max(r.d[1].abs());
        if cells >= 2.0 {
            ((cells as u64).ilog2() - START_BELOW.min((cells as u64).ilog2())).min(top)
        } else {
            0
        }
    }

    /// The node at shift `l` that the ray is in just after `t` (the one it is about to cross,
    /// where `t` falls on a node's side).
    #[inline]
    fn node_at(&self, r: &GridRay, t: f64, l: u32) -> [i64; 2] {
        let (nw, nh) = self.pyramid.dims(l);
        let scale = 1.0 / (1u64 << l) as f64;
        let at = |a: usize, n: u32| {
            let p = (r.o[a] + r.d[a] * t) * scale;
            let k = if r.d[a] < 0.0 {
                p.ceil() - 1.0
            } else {
                p.floor()
            };
            (k.max(0.0) as i64).min(i64::from(n) - 1)
        };
        [at(0, nw), at(1, nh)]
    }

    /// Tries cell `(i, j)`, keeping the better hit in `best`.
    #[inline]
    fn try_cell(&self, r: &GridRay, i: u32, j: u32, best: &mut Option<CellHit>) {
        if let Some(h) = self.cell_hit(r, i, j)
            && h.before(best)
        {
            *best = Some(h);
        }
    }

    /// The brute-force march (module docs).
    pub(crate) fn march_grid(&self, r: &GridRay) -> Option<CellHit> {
        let (cx, cy) = self.cells();
        let span = r.slab(0.0, f64::from(cx), 0.0, f64::from(cy))?;
        let mut best = None;
        self.walk(r, 0, span, &mut best, |t, i, j, best| {
            t.try_cell(r, i, j, best)
        });
        best
    }

    /// Visits in ray order every node at shift `s` (cells for 0) whose closed square the ray
    /// touches over `(t0, t1)` (within the terrain), column by column, calling `visit`, until
    /// the next node's span begins after the hit in `best`.
    fn walk(
        &self,
        r: &GridRay,
        s: u32,
        (t0, t1): (f64, f64),
        best: &mut Option<CellHit>,
        mut visit: impl FnMut(&Self, u32, u32, &mut Option<CellHit>),
    ) {
        let (cx, cy) = self.cells();
        let (nw, nh) = self.pyramid.dims(s);
        let size = (1u64 << s) as f64;
        // The nodes whose closed extent meets `[a, b]` along one axis, or comes within
        // rounding of it ([`NEAR`] times the largest coordinate the ray can have here): a
        // cell that the ray touches only at a vertex, computed a hair off, is still visited.
        let big = r.o[0].abs().max(r.o[1].abs()) + f64::from(cx.max(cy));
        let tol = NEAR * (1.0 + 2.0 * big);
        let span = |a: f64, b: f64, n: u32| {
            let (lo, hi) = ((a.min(b) - tol) / size, (a.max(b) + tol) / size);
            (
                ceil_minus_one(lo).min(n - 1),
                (hi.max(0.0) as u32).min(n - 1),
            )
        };
        let end = |k: u32, n: u32| ((u64::from(k) + 1) << s).min(u64::from(n)) as f64;
        let (ilo, ihi) = span(r.o[0] + r.d[0] * t0, r.o[0] + r.d[0] * t1, nw);
        for k in 0..=ihi.saturating_sub(ilo) {
            let i = if r.d[0] >= 0.0 { ilo + k } else { ihi - k };
            let (a0, a1) = axis(r.o[0], r.d[0], r.inv[0], f64::from(i) * size, end(i, cx));
            let (tc0, tc1) = (a0.max(t0), a1.min(t1));
            if tc0 > tc1 {
                continue;
            }
            if best.is_some_and(|b| tc0 > b.t) {
                break;
            }
            let (va, vb) = (r.o[1] + r.d[1] * tc0, r.o[1] + r.d[1] * tc1);
            let (jlo, jhi) = span(va, vb, nh);
            for k in 0..=jhi.saturating_sub(jlo) {
                let j = if r.d[1] >= 0.0 { jlo + k } else { jhi - k };
                if let Some(b) = best {
                    let (e0, _) = axis(r.o[1], r.d[1], r.inv[1], f64::from(j) * size, end(j, cy));
                    if e0.max(tc0) > b.t {
                        break;
                    }
                }
                visit(self, i, j, best);
            }
        }
    }

    /// Every cell tried, for tests: the exhaustive reference.
    #[cfg(test)]
    pub(crate) fn exhaustive_grid(&self, r: &GridRay) -> Option<CellHit> {
        let (cx, cy) = self.cells();
        let mut best = None;
        for j in 0..cy {
            for i in 0..cx {
                if let Some(h) = self.cell_hit(r, i, j)
                    && h.before(&best)
                {
                    best = Some(h);
                }
            }
        }
        best
    }
}
