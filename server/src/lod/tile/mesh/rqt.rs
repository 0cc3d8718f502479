//! The `rqt` tile mesh: paper 002's restricted-quadtree triangulation (section 2.2, vertex
//! errors saturated through their dependencies; section 2.3.2, the recursive triangulation of
//! figure 6), over a square grid of `2^k + 1` samples a side (a 65 x 65 tile, a 257 or 513 crop).
//!
//! **Hierarchy.** A block's centre splits the block's diagonal and each edge midpoint splits
//! its edge (figure 4); seen as triangles this is the right-triangle bisection hierarchy that
//! figure 6 draws (as in Lindstrom 1996, Pajarola 1998, and mapbox's martini): the two root
//! triangles share the grid's NW-SE diagonal, and a triangle splits at its hypotenuse's
//! midpoint `m` into two with their right angle at `m`. A vertex `m` is *active* when the two
//! triangles that share its hypotenuse are split. It depends (figure 3) on the two triangles'
//! apexes: a block centre on two of its parent's edge midpoints, an edge midpoint on the
//! centres of the two blocks that share the edge.
//!
//! **Errors.** The paper's `E_0` of a vertex is its distance to the line it would be
//! interpolated from; that misses the errors that pile up inside a triangle over several
//! levels. Here `E_0` is honest: the error of a triangle `T` is the largest vertical distance
//! between `T`'s plane and any sample inside or on `T` (computed exactly as
//! [`TriMesh::max_error`] does), and the triangle is kept only if that is within tolerance.
//! The saturation `E_A = max(E_A, E_0, E_B1..E_Bk)` is the paper's, with one refinement that
//! makes it exact at every tolerance: a triangle can only need splitting if it exists, that
//! is if its apex is active, so it asks its midpoint for `min(t(apex), err(T))`, not
//! `err(T)`. The thresholds are the least solution of
//!
//! ```text
//! t(m) >= min(t(apex(T)), err(T))   for both triangles T split at m (roots: err(T))
//! t(apex(T)) >= t(m)                the dependencies (figure 3)
//! ```
//!
//! found as widest paths by a Dijkstra-like sweep (largest first). Corners are always active.
//!
//! **Mesh.** At tolerance `tau` the active vertices are those with `t > tau`; figure 6's
//! recursion splits each triangle whose midpoint is active. Then:
//! - *restricted*: the active set is closed under dependencies (second inequality), so the
//!   mesh is conforming (no T-junctions) and neighbouring blocks differ by at most one level;
//! - *bounded*: a leaf `T` exists, so its apex has `t > tau`; its midpoint has `t <= tau`; by
//!   the first inequality `err(T) <= tau`, hence [`TriMesh::max_error`] `<= tau`;
//! - *minimal*: every active vertex is forced (a chain of triangles that exist and exceed
//!   `tau`, and dependencies), so no conforming mesh of this hierarchy within `tau` has fewer
//!   triangles; in particular not martini's, whose midpoint errors may exceed its tolerance.
//!
//! **Tile edges.** A vertex on the grid's border has one triangle inside, so its threshold
//! depends on interior samples too: two tiles meshed alone do not agree along their shared
//! edge. [`stitch`] raises each shared border vertex to the larger of its two thresholds
//! and re-saturates, until nothing changes; tiles stitched together then meet vertex for
//! vertex at any one tolerance. Tiles of different levels (or at different tolerances) never
//! do; patches or skirts close those cracks, as for `grid`.

use super::{HeightGrid, TriMesh, area2};
use relief_proto::tile::body::rqt::rqt_triangles;
use std::collections::BinaryHeap;

mod stitch;
#[cfg(test)]
mod tests;

pub use stitch::stitch;

/// Why a grid cannot be meshed by `rqt`.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum RqtError {
    /// The grid is not square with `2^k + 1` samples a side.
    #[error("rqt needs a square grid of 2^k+1 samples a side, not {0}x{1}")]
    Shape(usize, usize),
}

/// A sample position `[col, row]`.
type Pos = [u32; 2];

/// A vertex's place in the hierarchy, from its position.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    /// One of the grid's four corners: always in the mesh.
    Corner,
    /// The centre of a block `2h` cells wide: it splits one of the block's diagonals.
    Centre(u32),
    /// The midpoint of a horizontal edge `2h` cells long.
    EdgeH(u32),
    /// The midpoint of a vertical edge `2h` cells long.
    EdgeV(u32),
}

/// Saturated vertex thresholds of one grid: build once, then mesh at any tolerance.
#[derive(Clone, Debug)]
pub struct RqtErrors {
    /// Cells per side, a power of two (the grid has `side + 1` samples a side).
    side: u32,
    /// For each vertex, the errors of the two triangles split at it (in the order of
    /// [`RqtErrors::apexes`]; 0 where a triangle would lie outside the grid): the honest `E_0`.
    tri: Vec<[f32; 2]>,
    /// For each vertex, its saturated threshold: active when above the tolerance
    /// (infinite at the corners).
    thr: Vec<f32>,
}

/// `t` in canonical order: apex first, then the other two so that the triangle is
/// counter-clockwise seen from above; mesh and error computation share it.
fn ccw(c: Pos, a: Pos, b: Pos) -> [Pos; 3] {
    if area2(c, a, b) > 0 {
        [c, a, b]
    } else {
        [c, b, a]
    }
}

/// Largest vertical distance between the plane of `t` and the samples in or on it, as
/// [`TriMesh::max_error`] computes it, rounded up to `f32`.
fn triangle_error(grid: &HeightGrid<'_>, t: [Pos; 3]) -> f32 {
    let z = t.map(|p| f64::from(grid.at(p[0], p[1])));
    let d = area2(t[0], t[1], t[2]) as f64;
    let (c0, c1) = (t.iter().map(|p| p[0]).min(), t.iter().map(|p| p[0]).max());
    let (r0, r1) = (t.iter().map(|p| p[1]).min(), t.iter().map(|p| p[1]).max());
    let (Some(c0), Some(c1), Some(r0), Some(r1)) = (c0, c1, r0, r1) else {
        return 0.0;
    };
    let mut worst = 0.0f64;
    for r in r0..=r1 {
        for c in c0..=c1 {
            let p = [c, r];
            let w0 = area2(t[1], t[2], p) as f64 / d;
            let w1 = area2(t[2], t[0], p) as f64 / d;
            let w2 = area2(t[0], t[1], p) as f64 / d;
            if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                continue;
            }
            let m = w0 * z[0] + w1 * z[1] + w2 * z[2];
            worst = worst.max((m - f64::from(grid.at(c, r))).abs());
        }
    }
    let e = worst as f32;
    if f64::from(e) < worst {
        f32::from_bits(e.to_bits() + 1)
    } else {
        e
    }
}

impl RqtErrors {
    /// The thresholds of `grid`, which must be square with `2^k + 1` samples a side.
    pub fn new(grid: &HeightGrid<'_>) -> Result<RqtErrors, RqtError> {
        let n = grid.width;
        if grid.height != n || !(n - 1).is_power_of_two() || n - 1 > 1 << 15 {
            return Err(RqtError::Shape(grid.width, grid.height));
        }
        let side = (n - 1) as u32;
        let mut e = RqtErrors {
            side,
            tri: vec![[0.0; 2]; n * n],
            thr: vec![0.0; n * n],
        };
        for y in 0..=side {
            for x in 0..=side {
                let v = e.index([x, y]);
                if e.kind([x, y]) == Kind::Corner {
                    e.thr[v] = f32::INFINITY;
                    continue;
                }
                let [h0, h1] = e.hypotenuse([x, y]);
                for (k, apex) in e.apexes([x, y]).into_iter().enumerate() {
                    if let Some(c) = apex {
                        e.tri[v][k] = triangle_error(grid, ccw(c, h0, h1));
                    }
                }
            }
        }
        let mut heap = BinaryHeap::new();
        if side >= 2 {
            // The root triangles exist unconditionally (their apexes are corners).
            let c = e.index([side / 2, side / 2]);
            e.thr[c] = e.tri[c][0].max(e.tri[c][1]);
            heap.push((e.thr[c].to_bits(), c as u32));
        }
        e.saturate(heap);
        Ok(e)
    }

    /// Cells per side (the grid has `side + 1` samples a side).
    pub fn side(&self) -> u32 {
        self.side
    }

    /// The threshold of the vertex at `[col, row]`: it is in the mesh at every tolerance
    /// below this.
    pub fn threshold(&self, p: Pos) -> f32 {
        self.thr[self.index(p)]
    }

    /// Row-major index of `p`.
    pub(super) fn index(&self, p: Pos) -> usize {
        p[1] as usize * (self.side as usize + 1) + p[0] as usize
    }

    /// Where `p` sits in the hierarchy.
    fn kind(&self, p: Pos) -> Kind {
        let bits = p[0] | p[1];
        if bits == 0 || bits.trailing_zeros() >= self.side.trailing_zeros() {
            return Kind::Corner;
        }
        let h = 1 << bits.trailing_zeros();
        match ((p[0] / h) & 1, (p[1] / h) & 1) {
            (1, 1) => Kind::Centre(h),
            (1, _) => Kind::EdgeH(h),
            _ => Kind::EdgeV(h),
        }
    }

    /// For a block centre `p` of half-width `h`: its parent block's centre, one of the
    /// block's corners, through which the block's split diagonal runs (the X pattern).
    fn parent_centre(p: Pos, h: u32) -> Pos {
        p.map(|v| {
            if (v - h) % (4 * h) == 2 * h {
                v - h
            } else {
                v + h
            }
        })
    }

    /// The hypotenuse that `p` splits (its two ends).
    fn hypotenuse(&self, p: Pos) -> [Pos; 2] {
        let [x, y] = p;
        match self.kind(p) {
            Kind::Corner => [p, p],
            Kind::EdgeH(h) => [[x - h, y], [x + h, y]],
            Kind::EdgeV(h) => [[x, y - h], [x, y + h]],
            Kind::Centre(h) => {
                let q = Self::parent_centre(p, h);
                [q, [2 * x - q[0], 2 * y - q[1]]]
            }
        }
    }

    /// The apexes of the (up to) two triangles that `p` splits: the vertices `p` depends on.
    fn apexes(&self, p: Pos) -> [Option<Pos>; 2] {
        let [x, y] = p;
        let s = self.side;
        match self.kind(p) {
            Kind::Corner => [None, None],
            Kind::EdgeH(h) => [
                (y >= h).then(|| [x, y - h]),
                (y + h <= s).then(|| [x, y + h]),
            ],
            Kind::EdgeV(h) => [
                (x >= h).then(|| [x - h, y]),
                (x + h <= s).then(|| [x + h, y]),
            ],
            Kind::Centre(h) => {
                let q = Self::parent_centre(p, h);
                [Some([q[0], 2 * y - q[1]]), Some([2 * x - q[0], q[1]])]
            }
        }
    }

    /// The midpoints of the triangles whose apex is `p` (its dependants).
    fn dependants(&self, p: Pos) -> [Option<Pos>; 4] {
        let (steps, h) = match self.kind(p) {
            Kind::Centre(h) => ([(-1, 0), (1, 0), (0, -1), (0, 1)], h),
            Kind::EdgeH(h) | Kind::EdgeV(h) if h >= 2 => {
                ([(-1, -1), (1, -1), (-1, 1), (1, 1)], h / 2)
            }
            _ => return [None; 4],
        };
        let s = i64::from(self.side);
        steps.map(|(dx, dy): (i64, i64)| {
            let q = [
                i64::from(p[0]) + dx * i64::from(h),
                i64::from(p[1]) + dy * i64::from(h),
            ];
            q.iter()
                .all(|v| (0..=s).contains(v))
                .then(|| q.map(|v| v as u32))
        })
    }

    /// Widest-path relaxation from the vertices in `heap` (threshold bits, index), largest
    /// first, until both inequalities of the module docs hold everywhere.
    pub(super) fn saturate(&mut self, mut heap: BinaryHeap<(u32, u32)>) {
        let n = self.side + 1;
        while let Some((bits, v)) = heap.pop() {
            if bits != self.thr[v as usize].to_bits() {
                continue; // superseded by a larger value
            }
            let t = f32::from_bits(bits);
            let p = [v % n, v / n];
            for a in self.apexes(p).into_iter().flatten() {
                let i = self.index(a);
                if t > self.thr[i] {
                    self.thr[i] = t;
                    heap.push((t.to_bits(), i as u32));
                }
            }
            for m in self.dependants(p).into_iter().flatten() {
                let i = self.index(m);
                let k = usize::from(self.apexes(m)[1] == Some(p));
                let cand = t.min(self.tri[i][k]);
                if cand > self.thr[i] {
                    self.thr[i] = cand;
                    heap.push((cand.to_bits(), i as u32));
                }
            }
        }
    }

    /// The mesh at `tolerance` metres (figure 6's recursion): [`TriMesh::max_error`] is at
    /// most `tolerance`. A negative tolerance gives the full grid, an infinite one 2 triangles.
    pub fn mesh(&self, tolerance: f32) -> TriMesh {
        let (vertices, triangles) = rqt_triangles(self.side, |m, _, _| self.active(m, tolerance));
        TriMesh {
            vertices,
            triangles,
        }
    }

    /// Whether vertex `p` is active at `tolerance`.
    pub fn active(&self, p: Pos, tolerance: f32) -> bool {
        self.thr[self.index(p)] > tolerance
    }

    /// Triangles of [`RqtErrors::mesh`] at `tolerance`, counted without building it: each
    /// active vertex splits its one or two triangles.
    pub fn triangle_count(&self, tolerance: f32) -> usize {
        2 + (0..self.thr.len())
            .filter(|&i| self.thr[i] > tolerance && self.thr[i].is_finite())
            .map(|i| self.tri_count(i))
            .sum::<usize>()
    }

    /// The smallest tolerance whose mesh has at most `budget` triangles (at least 2).
    pub fn tolerance_for(&self, budget: usize) -> f32 {
        let mut active: Vec<(f32, usize)> = (0..self.thr.len())
            .filter(|&i| self.thr[i].is_finite() && self.thr[i] > 0.0)
            .map(|i| (self.thr[i], self.tri_count(i)))
            .collect();
        active.sort_by(|a, b| b.0.total_cmp(&a.0));
        // Walk down the distinct thresholds t: at tolerance t, exactly the vertices before
        // t's group are active.
        let (mut count, mut j) = (2, 0);
        while j < active.len() {
            let t = active[j].0;
            let group = active[j..].iter().take_while(|a| a.0 == t);
            let (len, w) = group.fold((0, 0), |(n, w), a| (n + 1, w + a.1));
            if count + w > budget {
                return t;
            }
            count += w;
            j += len;
        }
        0.0
    }

    /// How many triangles vertex `i` splits: 1 on the grid's border, else 2.
    fn tri_count(&self, i: usize) -> usize {
        let n = self.side as usize + 1;
        let p = [(i % n) as u32, (i / n) as u32];
        self.apexes(p).iter().flatten().count()
    }
}

/// The `rqt` mesh of `grid` at `tolerance` metres.
pub fn rqt(grid: &HeightGrid<'_>, tolerance: f32) -> Result<TriMesh, RqtError> {
    Ok(RqtErrors::new(grid)?.mesh(tolerance))
}
