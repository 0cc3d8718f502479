//! The `tin` tile mesh (paper 003, section 3, "the point-selection method"): a
//! Delaunay triangulation of a subset of the grid's samples, built by greedy insertion until
//! every sample lies within a vertical tolerance of the mesh.
//!
//! The paper's algorithm, step by step:
//! 1. `T_0` triangulates the set `I u H`: the grid's four corners (the convex hull `H`) and the
//!    points of particular interest `I`, which the paper says include the points of the
//!    domain's boundary and of edges shared with neighbours. Here: the caller's fixed points
//!    (shared border points, [`super::borders`]), and on each free side the points 1D greedy
//!    insertion keeps along it to the tolerance ([`super::borders::edge_points`]);
//! 2. each triangle finds the sample inside it with the largest vertical deviation from its
//!    plane (the paper measures the distance to the plane along z: `|F_k(x, y) - F(x, y)|`);
//! 3. the largest deviation over all triangles is `Delta_k`;
//! 4. while `Delta_k` exceeds the tolerance, that sample is inserted (4a), the triangulation is
//!    made Delaunay again by Lawson flips (`delaunay`), and only the triangles the
//!    insertion created are scanned again (4b).
//!
//! **Sides first.** A sample on a side is interpolated from that side's vertices alone, so
//! plain greedy insertion ends with exactly the 1D greedy points on every side (ties go the
//! same way); choosing them first changes only the interior. It also means two meshes of the
//! same samples on a side, at the same tolerance and stride, meet vertex for vertex there
//! without further ado.
//!
//! **Thinning** (not in the paper). Greedy insertion never takes a point back, and many of its
//! early points turn out redundant once later ones sit around them. After step 4, every
//! interior point it inserted is tried once, newest first: it is removed
//! ([`super::delaunay::Removal`]) if the Delaunay triangles of the hole it leaves keep every
//! lattice sample within the tolerance. Fixed and side points stay, so shared borders are
//! untouched. Over 40 sets of crops of four real DEMs (`server/tools/pydelatin_compare.py`,
//! `docs/tin.md`) this leaves 11 % fewer triangles than pydelatin (hmm's greedy insertion) at
//! the same tolerance, fewer in every set (without it: 0.3 % fewer, but more in 6 of 40), for
//! 1.3x the time without it. A second and third pass would remove another 1.8 % for 1.45x more
//! time.
//!
//! **Cost.** Each triangle's worst sample sits in an indexed max-heap (`queue`; an
//! entry is updated in place when its triangle is rewritten), so an insertion costs the area of
//! the triangles it changes plus `O(log n)`, as in Garland and Heckbert's "Fast polygonal
//! approximation of terrains and height fields" (1995) and in mapbox's delatin.
//!
//! **Determinism.** The same grid, tolerance and fixed points give the same mesh. Within a
//! triangle the worst sample wins ties by the smallest `(row, col)`; across triangles the heap
//! orders by error, then position, then triangle slot.
//!
//! **Lattices.** [`tin_span`] meshes a window of a larger grid (a tile's samples) and takes as
//! candidates only its lattice: every `stride`-th sample plus the window's last column and row,
//! as a [`TileSpan`] lays out a tile's vertices. Fixed points may lie anywhere in the window,
//! on the lattice or not; vertices are window-relative sample positions (so a coarse tile can
//! carry fine border points, [`super::borders`]). The tolerance is checked at the lattice.
//!
//! **Locked sides.** A locked side takes no points but the fixed points on it. This is how
//! neighbouring tiles meet vertex for vertex when both take the same border points; the
//! tolerance then holds on that side only as far as those points were chosen for it.

use super::delaunay::{NONE, Removal, Triangulation};
use super::queue::Queue;
use super::{HeightGrid, TriMesh, area2};
use relief_proto::tile::TileSpan;

/// The greedy insertion's state.
struct Greedy<'g> {
    /// The heights, of the whole grid the window lies in.
    grid: HeightGrid<'g>,
    /// The window and its lattice of candidates.
    span: TileSpan,
    /// Lattice columns and rows.
    n: (u32, u32),
    /// The triangulation so far, in window-relative positions.
    mesh: Triangulation,
    /// Whether each lattice sample (row-major) is a vertex already, never a candidate again.
    is_vertex: Vec<bool>,
    /// Worst sample of each triangle whose error exceeds the tolerance.
    queue: Queue,
    /// The triangles an insertion rewrote, buffer reused from one insertion to the next.
    dirty: Vec<u32>,
    /// The vertical tolerance, metres.
    tolerance: f64,
}

/// The `tin` mesh of `grid` within `tolerance` metres: the grid's corners, the `fixed` sample
/// positions `[col, row]` (duplicates ignored), each side's 1D greedy points, and whatever
/// samples greedy insertion needs inside.
///
/// Panics if a fixed point lies outside the grid or the tolerance is negative or NaN.
pub fn tin(grid: &HeightGrid<'_>, tolerance: f32, fixed: &[[u32; 2]]) -> TriMesh {
    tin_span(grid, &whole(grid), tolerance, fixed, [false; 4])
}

/// The window of all of `grid`'s samples at stride 1.
pub fn whole(grid: &HeightGrid<'_>) -> TileSpan {
    TileSpan {
        cols: (0, grid.width as u32 - 1),
        rows: (0, grid.height as u32 - 1),
        stride: 1,
    }
}

/// The `tin` mesh of the window `span` of `grid`, with candidates on its lattice and `fixed`
/// points given relative to the window's first sample. The sides marked in `locked` (north,
/// east, south, west, as [`relief_proto::tile::EDGES`]) take no vertices but the corners and
/// the fixed points on them, so that the mesh meets any other mesh built from the same points
/// there vertex for vertex; the other sides take their fixed points plus the 1D greedy points
/// of their lattice samples. Vertices are window-relative. The tolerance holds at every
/// lattice sample off the locked sides; on them it holds only where the fixed points were
/// chosen to it ([`super::borders::edge_points`]).
///
/// Panics if the window leaves the grid, a fixed point leaves the window, or the tolerance is
/// negative or NaN.
pub fn tin_span(
    grid: &HeightGrid<'_>,
    span: &TileSpan,
    tolerance: f32,
    fixed: &[[u32; 2]],
    locked: [bool; 4],
) -> TriMesh {
    assert!(tolerance >= 0.0, "tolerance must be >= 0, not {tolerance}");
    assert!(
        span.cols.1 < grid.width as u32 && span.rows.1 < grid.height as u32 && span.stride > 0,
        "window {span:?} outside {} x {}",
        grid.width,
        grid.height
    );
    let (w, h) = (span.cols.1 - span.cols.0, span.rows.1 - span.rows.0);
    let n = (span.nx(), span.ny());
    let mut g = Greedy {
        grid: *grid,
        span: *span,
        n,
        mesh: Triangulation::rectangle(w + 1, h + 1),
        is_vertex: vec![false; n.0 as usize * n.1 as usize],
        queue: Queue::default(),
        dirty: Vec::new(),
        tolerance: f64::from(tolerance),
    };
    for i in [0, n.0 - 1] {
        for j in [0, n.1 - 1] {
            g.is_vertex[(j * n.0 + i) as usize] = true;
        }
    }
    let mut fixed = fixed.to_vec();
    fixed.extend(free_side_points(grid, span, tolerance, &fixed, locked));
    fixed.sort_unstable_by_key(|p| (p[1], p[0]));
    fixed.dedup();
    for p in fixed {
        assert!(
            p[0] <= w && p[1] <= h,
            "fixed point {p:?} outside {w} x {h} cells"
        );
        if let Some(t) = g.mesh.locate(p) {
            g.mesh.insert(p, t);
            if let Some(k) = g.lattice_index(p) {
                g.is_vertex[k] = true;
            }
        }
    }
    g.mesh.take_dirty(&mut g.dirty);
    for t in 0..g.mesh.len() as u32 {
        g.scan(t);
    }
    let first_greedy = g.mesh.points.len();
    g.run();
    g.thin(first_greedy);
    let mut m = g.mesh;
    m.compact();
    TriMesh {
        triangles: (0..m.len() as u32).map(|t| m.corners(t)).collect(),
        vertices: m.points,
    }
}

/// The points 1D greedy insertion picks on each free side of the window: its lattice samples
/// and the fixed points on it (kept) as candidates, to `tolerance`.
fn free_side_points(
    grid: &HeightGrid<'_>,
    span: &TileSpan,
    tolerance: f32,
    fixed: &[[u32; 2]],
    locked: [bool; 4],
) -> Vec<[u32; 2]> {
    let (w, h) = (span.cols.1 - span.cols.0, span.rows.1 - span.rows.0);
    let s = span.stride;
    let lattice = |end: u32| (0..=end).filter(move |&v| v % s == 0 || v == end);
    let mut out = Vec::new();
    for (k, _) in locked.iter().enumerate().filter(|(_, l)| !**l) {
        // The side as (along-axis, fixed coordinate, end along it).
        let (axis, at, end) = match k {
            0 => (0, 0, w),
            1 => (1, w, h),
            2 => (0, h, w),
            _ => (1, 0, h),
        };
        let point = |v: u32| if axis == 0 { [v, at] } else { [at, v] };
        let on: Vec<u32> = fixed
            .iter()
            .filter(|p| p[1 - axis] == at)
            .map(|p| p[axis])
            .collect();
        let mut pos: Vec<u32> = lattice(end).chain(on.iter().copied()).collect();
        pos.sort_unstable();
        pos.dedup();
        let forced: Vec<usize> = (0..pos.len()).filter(|&i| on.contains(&pos[i])).collect();
        let z: Vec<f32> = pos
            .iter()
            .map(|&v| {
                let p = point(v);
                grid.at(span.cols.0 + p[0], span.rows.0 + p[1])
            })
            .collect();
        let keep = super::borders::edge_points(&pos, &z, tolerance, &forced);
        out.extend(keep.into_iter().map(|i| point(pos[i])));
    }
    out
}

impl Greedy<'_> {
    /// Inserts the worst sample until none exceeds the tolerance.
    fn run(&mut self) {
        while let Some((t, k)) = self.queue.peek() {
            let p = [self.x(k % self.n.0), self.y(k / self.n.0)];
            self.mesh.insert(p, t);
            self.is_vertex[k as usize] = true;
            let mut dirty = std::mem::take(&mut self.dirty);
            self.mesh.take_dirty(&mut dirty);
            for &t in &dirty {
                self.scan(t);
            }
            self.dirty = dirty;
        }
    }

    /// Takes back, newest first, each vertex from `first` on (those greedy insertion added)
    /// that the mesh turned out not to need: where the hole it leaves, triangulated again,
    /// keeps every lattice sample within the tolerance. Fixed and side points stay.
    fn thin(&mut self, first: usize) {
        let mut out = self.mesh.out_edges();
        let mut plan = Removal::default();
        for v in (first..self.mesh.points.len()).rev() {
            let e = out[v];
            if e == NONE || !self.mesh.plan_removal(e, &mut plan) {
                continue;
            }
            let Some(k) = self.lattice_index(self.mesh.points[v]) else {
                continue;
            };
            self.is_vertex[k] = false;
            let fits = plan
                .triangles(&self.mesh)
                .all(|t| self.worst(t).is_none_or(|(err, _)| err <= self.tolerance));
            if fits {
                self.mesh.remove(&plan, &mut out);
            } else {
                self.is_vertex[k] = true;
            }
        }
    }

    /// Window-relative column of lattice column `i`.
    fn x(&self, i: u32) -> u32 {
        (i * self.span.stride).min(self.span.cols.1 - self.span.cols.0)
    }

    /// Window-relative row of lattice row `j`.
    fn y(&self, j: u32) -> u32 {
        (j * self.span.stride).min(self.span.rows.1 - self.span.rows.0)
    }

    /// The lattice index of window-relative `p`, if it is a lattice sample.
    fn lattice_index(&self, p: [u32; 2]) -> Option<usize> {
        let s = self.span.stride;
        let (w, h) = (self.x(self.n.0 - 1), self.y(self.n.1 - 1));
        let i = if p[0] == w { self.n.0 - 1 } else { p[0] / s };
        let j = if p[1] == h { self.n.1 - 1 } else { p[1] / s };
        (self.x(i) == p[0] && self.y(j) == p[1]).then_some((j * self.n.0 + i) as usize)
    }

    /// Finds triangle `t`'s worst lattice sample and, when it exceeds the tolerance, queues it.
    fn scan(&mut self, t: u32) {
        let worst = self.worst(self.mesh.positions(t));
        self.queue
            .set(t, worst.filter(|&(err, _)| err > self.tolerance));
    }

    /// The worst lattice sample of the counter-clockwise triangle `v` that is not a vertex
    /// and not on the window's sides: its vertical distance, metres, and lattice index.
    fn worst(&self, v: [[u32; 2]; 3]) -> Option<(f64, u32)> {
        let (c0, r0) = (self.span.cols.0 as usize, self.span.rows.0 as usize);
        let (gw, z_all) = (self.grid.width, self.grid.z);
        let z = v.map(|p| f64::from(z_all[(r0 + p[1] as usize) * gw + c0 + p[0] as usize]));
        let d = area2(v[0], v[1], v[2]);
        let s = self.span.stride;
        let (xe, ye) = (self.x(self.n.0 - 1), self.y(self.n.1 - 1));
        // Sub-triangle areas A_k grow by `step[k]` from one lattice column to the next.
        let edges = [(v[1], v[2]), (v[2], v[0]), (v[0], v[1])];
        // Areas are integers, exact in f64 (below 2^53).
        let step = edges.map(|(a, b)| ((i64::from(b[1]) - i64::from(a[1])) * i64::from(s)) as f64);
        let y0 = v.iter().map(|p| p[1]).min().unwrap_or(0);
        let y1 = v.iter().map(|p| p[1]).max().unwrap_or(0);
        // Largest |sum A_k (z_k - z)| (exact zero on a plane) and its lattice index.
        let mut best: Option<(f64, u32)> = None;
        let mut j = y0.div_ceil(s);
        while j < self.n.1 && self.y(j) <= y1 {
            let r = self.y(j);
            let row = j * self.n.0;
            j += 1;
            if r == 0 || r == ye {
                continue;
            }
            let Some((lo, hi)) = row_span(v, r) else {
                continue;
            };
            let zrow = &z_all[(r0 + r as usize) * gw + c0..];
            let mut i = lo.div_ceil(s);
            let mut a = edges.map(|(p, q)| area2(p, q, [i * s, r]) as f64);
            while i < self.n.0 && self.x(i) <= hi {
                let c = self.x(i);
                if c != i * s {
                    // The narrower last cell.
                    a = edges.map(|(p, q)| area2(p, q, [c, r]) as f64);
                }
                let k = row + i;
                if !self.is_vertex[k as usize] && c != 0 && c != xe {
                    let zs = f64::from(zrow[c as usize]);
                    let num = (a[0] * (z[0] - zs) + a[1] * (z[1] - zs) + a[2] * (z[2] - zs)).abs();
                    if best.is_none_or(|b| num > b.0) {
                        best = Some((num, k));
                    }
                }
                i += 1;
                for (a, st) in a.iter_mut().zip(step) {
                    *a += st;
                }
            }
        }
        best.map(|(num, k)| (num / d as f64, k))
    }
}

/// The largest vertical distance, metres, between `mesh` (vertices relative to the window's
/// first sample) and `grid` at the lattice samples of window `span`: what [`tin_span`]
/// promises to keep within its tolerance. Brute force, as [`TriMesh::max_error`]: each
/// triangle tests the lattice samples of its bounding box.
pub fn lattice_error(mesh: &TriMesh, grid: &HeightGrid<'_>, span: &TileSpan) -> f32 {
    let (c0, r0, s) = (span.cols.0, span.rows.0, span.stride);
    let (w, h) = (span.cols.1 - c0, span.rows.1 - r0);
    let lattice = |lo: u32, hi: u32, end: u32| {
        (lo.div_ceil(s)..=hi / s)
            .map(move |i| i * s)
            .chain((hi == end && !end.is_multiple_of(s)).then_some(end))
    };
    let mut worst = 0.0f64;
    for t in &mesh.triangles {
        let v = t.map(|i| mesh.vertices[i as usize]);
        let z = v.map(|p| f64::from(grid.at(c0 + p[0], r0 + p[1])));
        let d = area2(v[0], v[1], v[2]) as f64;
        let (x0, x1) = (v.iter().map(|p| p[0]).min(), v.iter().map(|p| p[0]).max());
        let (y0, y1) = (v.iter().map(|p| p[1]).min(), v.iter().map(|p| p[1]).max());
        let (Some(x0), Some(x1), Some(y0), Some(y1)) = (x0, x1, y0, y1) else {
            continue;
        };
        for y in lattice(y0, y1, h) {
            for x in lattice(x0, x1, w) {
                let p = [x, y];
                let a = [
                    area2(v[1], v[2], p),
                    area2(v[2], v[0], p),
                    area2(v[0], v[1], p),
                ];
                if a.iter().any(|&a| a < 0) {
                    continue;
                }
                let zs = f64::from(grid.at(c0 + x, r0 + y));
                let m: f64 = (0..3).map(|k| a[k] as f64 * (z[k] - zs)).sum();
                worst = worst.max(m.abs() / d);
            }
        }
    }
    worst as f32
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
