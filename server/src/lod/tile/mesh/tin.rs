//! The `tin` tile mesh (issue 13; paper 003, section 3, "the point-selection method"): a
//! Delaunay triangulation of a subset of the grid's samples, built by greedy insertion until
//! every sample lies within a vertical tolerance of the mesh.
//!
//! The paper's algorithm, step by step:
//! 1. `T_0` triangulates the set `I u H`: the grid's four corners (the convex hull `H`) and the
//!    points of particular interest `I`, here the caller's fixed points (shared border points,
//!    [`super::borders`]), inserted in sorted order;
//! 2. each triangle finds the sample inside it with the largest vertical deviation from its
//!    plane (the paper measures the distance to the plane along z: `|F_k(x, y) - F(x, y)|`);
//! 3. the largest deviation over all triangles is `Delta_k`;
//! 4. while `Delta_k` exceeds the tolerance, that sample is inserted (4a), the triangulation is
//!    made Delaunay again by Lawson flips ([`super::delaunay`]), and only the triangles the
//!    insertion created are scanned again (4b).
//!
//! Each triangle's worst sample sits in a max-heap with lazy deletion (an entry is dropped when
//! its triangle was rewritten since), so an insertion costs the area of the triangles it
//! changes plus `O(log n)`, as in Garland and Heckbert's "Fast polygonal approximation of
//! terrains and height fields" (1995) and in mapbox's delatin.
//!
//! Determinism: the same grid, tolerance and fixed points give the same mesh. Within a triangle
//! the worst sample wins ties by the smallest `(row, col)`; across triangles the heap orders by
//! error, then position, then triangle slot.
//!
//! Sides of the grid may be *locked* ([`tin_locked`]): their samples are never inserted, so the
//! fixed points are the only vertices on them. This is how neighbouring tiles meet vertex for
//! vertex when both take the same border points; it also means the tolerance holds on a locked
//! side only as far as its fixed points were chosen for it.

use super::delaunay::Triangulation;
use super::{HeightGrid, TriMesh, area2};
use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// A heap entry: error bits (non-negative `f64`, so the bits order like the values), the
/// sample's row-major index reversed (smaller wins ties), the triangle slot reversed and the
/// triangle's version when scanned.
type Entry = (u64, Reverse<u64>, Reverse<u32>, u32);

/// The greedy insertion's state.
struct Greedy<'g> {
    /// The heights.
    grid: HeightGrid<'g>,
    /// The triangulation so far.
    mesh: Triangulation,
    /// Whether each sample (row-major) is a vertex already, never a candidate again.
    is_vertex: Vec<bool>,
    /// Locked sides in [`relief_proto::tile::EDGES`] order (north, east, south, west).
    locked: [bool; 4],
    /// Bumped each time a triangle is rescanned, to drop stale heap entries.
    version: Vec<u32>,
    /// Worst sample of each triangle whose error exceeds the tolerance.
    heap: BinaryHeap<Entry>,
    /// The vertical tolerance, metres.
    tolerance: f64,
}

/// The `tin` mesh of `grid` within `tolerance` metres: the grid's corners, the `fixed` sample
/// positions `[col, row]` (duplicates ignored), and whatever samples greedy insertion needs.
/// Every side stays free: border samples are inserted like any other.
///
/// Panics if a fixed point lies outside the grid or the tolerance is negative or NaN.
pub fn tin(grid: &HeightGrid<'_>, tolerance: f32, fixed: &[[u32; 2]]) -> TriMesh {
    tin_locked(grid, tolerance, fixed, [false; 4])
}

/// [`tin`] with the sides marked in `locked` (north, east, south, west, as
/// [`relief_proto::tile::EDGES`]) taking no vertices but the corners and the fixed points on
/// them: the mesh then meets any other mesh built from the same points on that side vertex for
/// vertex. The tolerance holds in the interior; on a locked side it holds only where the fixed
/// points were chosen to that tolerance ([`super::borders::edge_points`]).
pub fn tin_locked(
    grid: &HeightGrid<'_>,
    tolerance: f32,
    fixed: &[[u32; 2]],
    locked: [bool; 4],
) -> TriMesh {
    assert!(tolerance >= 0.0, "tolerance must be >= 0, not {tolerance}");
    let (w, h) = (grid.width as u32, grid.height as u32);
    let mut g = Greedy {
        grid: *grid,
        mesh: Triangulation::rectangle(w, h),
        is_vertex: vec![false; grid.width * grid.height],
        locked,
        version: Vec::new(),
        heap: BinaryHeap::new(),
        tolerance: f64::from(tolerance),
    };
    for &[c, r] in &g.mesh.points {
        g.is_vertex[r as usize * grid.width + c as usize] = true;
    }
    let mut fixed = fixed.to_vec();
    fixed.sort_unstable_by_key(|p| (p[1], p[0]));
    fixed.dedup();
    for p in fixed {
        assert!(p[0] < w && p[1] < h, "fixed point {p:?} outside {w} x {h}");
        let i = p[1] as usize * grid.width + p[0] as usize;
        if !g.is_vertex[i] {
            let t = g.mesh.locate(p).unwrap_or(0);
            g.mesh.insert(p, t);
            g.is_vertex[i] = true;
        }
    }
    g.mesh.take_dirty();
    for t in 0..g.mesh.len() as u32 {
        g.scan(t);
    }
    g.run();
    let m = g.mesh;
    TriMesh {
        triangles: (0..m.len() as u32).map(|t| m.corners(t)).collect(),
        vertices: m.points,
    }
}

impl Greedy<'_> {
    /// Inserts the worst sample until none exceeds the tolerance.
    fn run(&mut self) {
        while let Some((_, Reverse(i), Reverse(t), ver)) = self.heap.pop() {
            if self.version[t as usize] != ver {
                continue;
            }
            let w = self.grid.width as u64;
            let p = [(i % w) as u32, (i / w) as u32];
            self.mesh.insert(p, t);
            self.is_vertex[i as usize] = true;
            for t in self.mesh.take_dirty() {
                self.scan(t);
            }
        }
    }

    /// Whether the sample at `[c, r]` lies on a locked side.
    fn on_locked_side(&self, c: u32, r: u32) -> bool {
        let (e, s) = (self.grid.width as u32 - 1, self.grid.height as u32 - 1);
        (self.locked[0] && r == 0)
            || (self.locked[1] && c == e)
            || (self.locked[2] && r == s)
            || (self.locked[3] && c == 0)
    }

    /// Finds triangle `t`'s worst sample and, when it exceeds the tolerance, queues it.
    fn scan(&mut self, t: u32) {
        if self.version.len() <= t as usize {
            self.version.resize(t as usize + 1, 0);
        }
        self.version[t as usize] = self.version[t as usize].wrapping_add(1);
        let v = self.mesh.positions(t);
        let z = v.map(|p| f64::from(self.grid.at(p[0], p[1])));
        let d = area2(v[0], v[1], v[2]);
        let r0 = v.iter().map(|p| p[1]).min().unwrap_or(0);
        let r1 = v.iter().map(|p| p[1]).max().unwrap_or(0);
        let mut best: Option<(f64, u32, u32)> = None;
        for r in r0..=r1 {
            let Some((c0, c1)) = row_span(v, r) else {
                continue;
            };
            for c in c0..=c1 {
                let i = r as usize * self.grid.width + c as usize;
                if self.is_vertex[i] || self.on_locked_side(c, r) {
                    continue;
                }
                let zs = f64::from(self.grid.z[i]);
                // Sum of A_k (z_k - z) over the sub-triangle areas A_k: exact zero on a plane.
                let p = [c, r];
                let a = [
                    area2(v[1], v[2], p),
                    area2(v[2], v[0], p),
                    area2(v[0], v[1], p),
                ];
                let num: f64 = (0..3).map(|k| a[k] as f64 * (z[k] - zs)).sum();
                let err = num.abs() / d as f64;
                if best.is_none_or(|b| err > b.0) {
                    best = Some((err, c, r));
                }
            }
        }
        let Some((err, c, r)) = best.filter(|b| b.0 > self.tolerance) else {
            return;
        };
        let i = u64::from(r) * self.grid.width as u64 + u64::from(c);
        let ver = self.version[t as usize];
        self.heap.push((err.to_bits(), Reverse(i), Reverse(t), ver));
    }
}

/// The columns of row `r` inside or on the counter-clockwise triangle `v` (exact integer
/// edge functions), or `None` when the row misses it.
fn row_span(v: [[u32; 2]; 3], r: u32) -> Option<(u32, u32)> {
    let (mut lo, mut hi) = (i64::MIN, i64::MAX);
    for k in 0..3 {
        let (a, b) = (v[k], v[(k + 1) % 3]);
        // area2(a, b, [c, r]) = kc * c + k0 must be >= 0.
        let kc = i64::from(b[1]) - i64::from(a[1]);
        let k0 = area2(a, b, [0, r]);
        if kc > 0 {
            lo = lo.max((-k0).div_euclid(kc) + i64::from((-k0).rem_euclid(kc) != 0));
        } else if kc < 0 {
            hi = hi.min(k0.div_euclid(-kc));
        } else if k0 < 0 {
            return None;
        }
    }
    let lo = lo.max(0);
    (lo <= hi).then_some((lo as u32, hi as u32))
}

#[cfg(test)]
pub(crate) mod tests;
