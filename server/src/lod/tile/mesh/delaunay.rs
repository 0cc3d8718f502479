//! An incremental Delaunay triangulation of grid samples inside a rectangle, for the `tin`
//! mesh ([`super::tin`]; paper 003, section 3): points are inserted one at a time into the
//! triangle (or onto the edge) that holds them, and Lawson flips restore the empty-circle
//! condition after each insertion (the region R of the paper's figure 1, retriangulated from
//! the new point).
//!
//! Half-edge layout: triangle `t` owns half-edges `3t`, `3t + 1`, `3t + 2`, counter-clockwise
//! seen from above (world axes x = col, y = -row; [`area2`] > 0). Half-edge `e` starts at vertex
//! `start[e]` and ends where the next half-edge of its triangle starts; `twin[e]` is the same
//! edge seen from the other triangle, or [`NONE`] on the rectangle's border. Every predicate is
//! exact: coordinates are small integers, orientation is [`area2`] in `i64` and the in-circle
//! test is evaluated in `i128`.

use super::area2;

mod remove;
pub use remove::Removal;

/// No half-edge: the twin of a border edge.
pub const NONE: u32 = u32::MAX;

/// Where a point lies relative to a triangle that holds it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Spot {
    /// Strictly inside.
    Inside,
    /// On the relative interior of this half-edge.
    Edge(u32),
}

/// A Delaunay triangulation of a rectangle's corners plus inserted samples.
#[derive(Clone, Debug)]
pub struct Triangulation {
    /// Vertex positions `[col, row]`, in insertion order (the four corners first).
    pub points: Vec<[u32; 2]>,
    /// The vertex each half-edge starts at.
    pub start: Vec<u32>,
    /// Each half-edge's opposite half-edge, or [`NONE`] on the border, to walk across edges.
    pub twin: Vec<u32>,
    /// Triangles written since the last [`Triangulation::take_dirty`], so that the caller
    /// rescans only what an insertion changed.
    dirty: Vec<u32>,
    /// Whether each triangle is already in `dirty` (no duplicates).
    is_dirty: Vec<bool>,
    /// The edges left to check after an insertion, kept to reuse its allocation.
    stack: Vec<u32>,
}

/// The next half-edge around the same triangle.
#[inline]
pub fn next(e: u32) -> u32 {
    if e % 3 == 2 { e - 2 } else { e + 1 }
}

/// The previous half-edge around the same triangle.
#[inline]
pub fn prev(e: u32) -> u32 {
    if e.is_multiple_of(3) { e + 2 } else { e - 1 }
}

/// Positive when `d` lies strictly inside the circumcircle of the counter-clockwise triangle
/// `a b c`, zero when on it (world axes, exact).
pub fn incircle(a: [u32; 2], b: [u32; 2], c: [u32; 2], d: [u32; 2]) -> i128 {
    let w = |p: [u32; 2]| (i128::from(p[0]), -i128::from(p[1]));
    let (dx, dy) = w(d);
    let rel = |p: [u32; 2]| {
        let (x, y) = w(p);
        (x - dx, y - dy, (x - dx) * (x - dx) + (y - dy) * (y - dy))
    };
    let (ax, ay, a2) = rel(a);
    let (bx, by, b2) = rel(b);
    let (cx, cy, c2) = rel(c);
    ax * (by * c2 - b2 * cy) - ay * (bx * c2 - b2 * cx) + a2 * (bx * cy - by * cx)
}

impl Triangulation {
    /// The two triangles of a `width x height` rectangle's corners, split along the NW-SE
    /// diagonal (the four corners are cocircular: either diagonal is Delaunay).
    pub fn rectangle(width: u32, height: u32) -> Triangulation {
        assert!(width >= 2 && height >= 2, "a rectangle needs 2 x 2 samples");
        let (e, s) = (width - 1, height - 1);
        let mut d = Triangulation {
            points: vec![[0, 0], [e, 0], [0, s], [e, s]],
            start: Vec::new(),
            twin: Vec::new(),
            dirty: Vec::new(),
            is_dirty: Vec::new(),
            stack: Vec::new(),
        };
        // NW SW SE, then NW SE NE; half-edge 2 (SE -> NW) is the twin of half-edge 3.
        d.set(0, [0, 2, 3], [NONE, NONE, NONE]);
        d.set(1, [0, 3, 1], [2, NONE, NONE]);
        d
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.start.len() / 3
    }

    /// The three vertices of triangle `t`.
    #[inline]
    pub fn corners(&self, t: u32) -> [u32; 3] {
        let e = 3 * t as usize;
        [self.start[e], self.start[e + 1], self.start[e + 2]]
    }

    /// The three vertex positions of triangle `t`.
    #[inline]
    pub fn positions(&self, t: u32) -> [[u32; 2]; 3] {
        self.corners(t).map(|v| self.points[v as usize])
    }

    /// Moves the triangles written since the last call into `out` (cleared first), each once,
    /// in the order first written.
    pub fn take_dirty(&mut self, out: &mut Vec<u32>) {
        for &t in &self.dirty {
            self.is_dirty[t as usize] = false;
        }
        out.clear();
        std::mem::swap(out, &mut self.dirty);
    }

    /// Writes triangle `t` (a new slot when `t == len()`) with vertices `v` and the twins
    /// `h` of its half-edges `v0 v1`, `v1 v2`, `v2 v0`, linking both ways.
    fn set(&mut self, t: u32, v: [u32; 3], h: [u32; 3]) {
        let e = 3 * t as usize;
        if e == self.start.len() {
            self.start.extend_from_slice(&[0; 3]);
            self.twin.extend_from_slice(&[NONE; 3]);
            self.is_dirty.push(false);
        }
        for i in 0..3 {
            self.start[e + i] = v[i];
            self.twin[e + i] = h[i];
            if h[i] != NONE {
                self.twin[h[i] as usize] = (e + i) as u32;
            }
        }
        if !self.is_dirty[t as usize] {
            self.is_dirty[t as usize] = true;
            self.dirty.push(t);
        }
    }

    /// Where `p` lies in triangle `t`: `None` when outside it or on one of its vertices.
    fn spot(&self, t: u32, p: [u32; 2]) -> Option<Spot> {
        let [a, b, c] = self.positions(t);
        let s = [area2(a, b, p), area2(b, c, p), area2(c, a, p)];
        if s.iter().any(|&x| x < 0) {
            return None;
        }
        match s.iter().filter(|&&x| x == 0).count() {
            0 => Some(Spot::Inside),
            1 => {
                let i = s.iter().position(|&x| x == 0).unwrap_or(0) as u32;
                Some(Spot::Edge(3 * t + i))
            }
            _ => None,
        }
    }

    /// A triangle holding `p` (inside or on an edge); `None` when `p` is a vertex already or
    /// lies outside the rectangle. A visibility walk from the newest triangle (consecutive
    /// fixed points are near each other), which cannot cycle on a Delaunay triangulation;
    /// bounded all the same, with a scan of every triangle behind it.
    pub fn locate(&self, p: [u32; 2]) -> Option<u32> {
        let mut t = self.len() as u32 - 1;
        'walk: for _ in 0..self.len() {
            let v = self.positions(t);
            for i in 0..3 {
                if area2(v[i], v[(i + 1) % 3], p) < 0 {
                    let o = self.twin[3 * t as usize + i];
                    if o == NONE {
                        return None;
                    }
                    t = o / 3;
                    continue 'walk;
                }
            }
            return self.spot(t, p).map(|_| t);
        }
        (0..self.len() as u32).find(|&t| self.spot(t, p).is_some())
    }

    /// Inserts `p`, which lies in triangle `t` (inside or on an edge, not on a vertex), and
    /// restores the Delaunay condition. Returns the new vertex's index.
    pub fn insert(&mut self, p: [u32; 2], t: u32) -> u32 {
        let spot = self.spot(t, p);
        let v = self.points.len() as u32;
        self.points.push(p);
        let mut stack = std::mem::take(&mut self.stack);
        match spot {
            Some(Spot::Inside) => self.split_triangle(t, v, &mut stack),
            Some(Spot::Edge(e)) => self.split_edge(e, v, &mut stack),
            None => panic!("insert: {p:?} is not inside triangle {t} or on its edges"),
        }
        while let Some(e) = stack.pop() {
            self.legalize(e, &mut stack);
        }
        self.stack = stack;
        v
    }

    /// Splits triangle `t = a b c` into `a b p`, `b c p`, `c a p`.
    fn split_triangle(&mut self, t: u32, p: u32, stack: &mut Vec<u32>) {
        let [a, b, c] = self.corners(t);
        let e = 3 * t as usize;
        let [hab, hbc, hca] = [self.twin[e], self.twin[e + 1], self.twin[e + 2]];
        let (t1, t2) = (self.len() as u32, self.len() as u32 + 1);
        // Half-edges: t: ab bp pa; t1: bc cp pb; t2: ca ap pc.
        self.set(t, [a, b, p], [hab, NONE, NONE]);
        self.set(t1, [b, c, p], [hbc, NONE, 3 * t + 1]);
        self.set(t2, [c, a, p], [hca, 3 * t + 2, 3 * t1 + 1]);
        stack.extend([3 * t, 3 * t1, 3 * t2]);
    }

    /// Splits the edge of half-edge `e = a b` (triangle `a b c`, and `b a d` across it when
    /// `e` is not on the border) at `p`.
    fn split_edge(&mut self, e: u32, p: u32, stack: &mut Vec<u32>) {
        let t = e / 3;
        let (a, b, c) = (
            self.start[e as usize],
            self.start[next(e) as usize],
            self.start[prev(e) as usize],
        );
        let (hbc, hca) = (self.twin[next(e) as usize], self.twin[prev(e) as usize]);
        let o = self.twin[e as usize];
        let t1 = self.len() as u32;
        // t: a p c (ap pc ca); t1: p b c (pb bc cp).
        self.set(t, [a, p, c], [NONE, NONE, hca]);
        self.set(t1, [p, b, c], [NONE, hbc, 3 * t + 1]);
        stack.extend([3 * t + 2, 3 * t1 + 1]);
        if o == NONE {
            return;
        }
        let u = o / 3;
        let d = self.start[prev(o) as usize];
        let (had, hdb) = (self.twin[next(o) as usize], self.twin[prev(o) as usize]);
        let u1 = self.len() as u32;
        // u: b p d (bp pd db) twin of t1's pb; u1: p a d (pa ad dp) twin of t's ap.
        self.set(u, [b, p, d], [3 * t1, NONE, hdb]);
        self.set(u1, [p, a, d], [3 * t, had, 3 * u + 1]);
        stack.extend([3 * u + 2, 3 * u1 + 1]);
    }

    /// Lawson's flip for half-edge `e = a b` of triangle `a b p`, whose apex `p` is the point
    /// just inserted: when the apex `q` across the edge lies strictly inside the circle
    /// through `a b p`, edge `a b` becomes `p q`, and the two new edges facing `p` are checked
    /// in turn.
    fn legalize(&mut self, e: u32, stack: &mut Vec<u32>) {
        let o = self.twin[e as usize];
        if o == NONE {
            return;
        }
        let (a, b, p) = (
            self.start[e as usize],
            self.start[next(e) as usize],
            self.start[prev(e) as usize],
        );
        let q = self.start[prev(o) as usize];
        let pos = |v: u32| self.points[v as usize];
        if incircle(pos(a), pos(b), pos(p), pos(q)) <= 0 {
            return;
        }
        let (t, u) = (e / 3, o / 3);
        let (hbp, hpa) = (self.twin[next(e) as usize], self.twin[prev(e) as usize]);
        let (haq, hqb) = (self.twin[next(o) as usize], self.twin[prev(o) as usize]);
        // t: p a q (pa aq qp); u: q b p (qb bp pq).
        self.set(t, [p, a, q], [hpa, haq, NONE]);
        self.set(u, [q, b, p], [hqb, hbp, 3 * t + 2]);
        stack.extend([3 * t + 1, 3 * u]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every half-edge's twin points back and runs the other way; every triangle is
    /// counter-clockwise; no vertex is strictly inside any triangle's circumcircle.
    pub(crate) fn check(d: &Triangulation) {
        for e in 0..d.start.len() as u32 {
            let o = d.twin[e as usize];
            if o != NONE {
                assert_eq!(d.twin[o as usize], e);
                assert_eq!(d.start[o as usize], d.start[next(e) as usize]);
                assert_eq!(d.start[next(o) as usize], d.start[e as usize]);
            }
        }
        for t in 0..d.len() as u32 {
            let [a, b, c] = d.positions(t);
            assert!(area2(a, b, c) > 0, "triangle {t} {:?}", [a, b, c]);
            for &q in &d.points {
                assert!(incircle(a, b, c, q) <= 0, "{q:?} inside circle of {t}");
            }
        }
    }

    #[test]
    fn the_incircle_sign_follows_the_circle() {
        let (a, b, c) = ([0, 0], [0, 2], [2, 2]);
        assert!(area2(a, b, c) > 0);
        assert!(incircle(a, b, c, [1, 1]) > 0);
        assert_eq!(incircle(a, b, c, [2, 0]), 0);
        assert!(incircle(a, b, c, [3, 0]) < 0);
    }

    #[test]
    fn inserting_inside_on_edges_and_on_the_border_keeps_a_delaunay_mesh() {
        let mut d = Triangulation::rectangle(9, 7);
        check(&d);
        // Inside, on the diagonal, on the border, then a dense row of points.
        let mut pts = vec![[2, 5], [4, 3], [0, 3], [8, 1], [6, 6]];
        pts.extend((1..8).map(|c| [c, 2]));
        for p in pts {
            let Some(t) = d.locate(p) else {
                continue;
            };
            d.insert(p, t);
            check(&d);
        }
        // Euler: 2n - b - 2 triangles over a convex region with b border vertices.
        let n = d.points.len();
        let b = d
            .points
            .iter()
            .filter(|p| p[0] % 8 == 0 || p[1] % 6 == 0)
            .count();
        assert_eq!(d.len(), 2 * n - b - 2);
        assert!(
            d.locate([4, 3]).is_none(),
            "a vertex is not a place to insert"
        );
    }

    #[test]
    fn removing_vertices_keeps_a_delaunay_mesh_and_border_vertices_stay() {
        // A dense, degenerate set (many cocircular quadruples on the lattice), then removals
        // in a scrambled order until only the corners and the border points are left.
        let mut d = Triangulation::rectangle(13, 11);
        for k in 0..200u32 {
            let p = [(k * 7919) % 13, (k * 104_729 / 13) % 11];
            if let Some(t) = d.locate(p) {
                d.insert(p, t);
            }
        }
        check(&d);
        let mut plan = Removal::default();
        let mut k = 0u32;
        loop {
            let mut out = d.out_edges();
            let n = d.points.len() as u32;
            let interior = |p: [u32; 2]| !p[0].is_multiple_of(12) && !p[1].is_multiple_of(10);
            let Some(v) = (0..n)
                .map(|i| (i + k * 31) % n)
                .find(|&v| interior(d.points[v as usize]))
            else {
                break;
            };
            k += 1;
            assert!(d.plan_removal(out[v as usize], &mut plan), "vertex {v}");
            let before = d.len();
            d.remove(&plan, &mut out);
            d.compact();
            check(&d);
            assert_eq!(d.len(), before - 2);
            assert_eq!(d.out_edges().iter().filter(|&&e| e == NONE).count(), 0);
        }
        // A border vertex's star is open: it cannot be planned away.
        let out = d.out_edges();
        let b = d.points.iter().position(|&p| p == [0, 5]).unwrap();
        assert!(!d.plan_removal(out[b], &mut plan));
        assert!(k > 50, "{k} removals");
    }
}
