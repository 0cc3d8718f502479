//! Taking a vertex back out of the triangulation ([`super::super::tin`]'s thinning pass): the
//! hole its star leaves is triangulated again by Delaunay ears, and the result is Delaunay
//! again (the hole of a deleted vertex is covered by the Delaunay triangles of its link
//! vertices: Devillers, "On deletion in Delaunay triangulations", 1999).
//!
//! A removal is planned first ([`Triangulation::plan_removal`]) and carried out only if the
//! caller accepts the plan ([`Triangulation::remove`]), so that a refused removal changes
//! nothing. Removed triangles leave dead slots and removed vertices unused points until
//! [`Triangulation::compact`].

use super::{NONE, Triangulation, incircle, next, prev};
use crate::lod::tile::mesh::area2;

/// The triangles that would cover the hole of a removed vertex.
#[derive(Clone, Debug, Default)]
pub struct Removal {
    /// The half-edges leaving the vertex, counter-clockwise: one per triangle of its star.
    star: Vec<u32>,
    /// The star's outer vertices, counter-clockwise (`link[i]` starts `star[i]`'s next edge).
    link: Vec<u32>,
    /// The new triangles, as indices into `link`, counter-clockwise.
    pub ears: Vec<[usize; 3]>,
}

impl Removal {
    /// The new triangles' vertex positions, counter-clockwise.
    pub fn triangles<'a>(
        &'a self,
        d: &'a Triangulation,
    ) -> impl Iterator<Item = [[u32; 2]; 3]> + 'a {
        self.ears
            .iter()
            .map(|e| e.map(|i| d.points[self.link[i] as usize]))
    }
}

impl Triangulation {
    /// One half-edge leaving each vertex ([`NONE`] for a vertex no triangle uses), for
    /// [`Triangulation::plan_removal`].
    pub fn out_edges(&self) -> Vec<u32> {
        let mut out = vec![NONE; self.points.len()];
        for (e, &v) in self.start.iter().enumerate() {
            if v != NONE {
                out[v as usize] = e as u32;
            }
        }
        out
    }

    /// How to remove the vertex half-edge `e` leaves: `None` when the vertex lies on the
    /// rectangle's border (its star is open) or its hole has no Delaunay ear (which exact
    /// arithmetic should not allow; refusing is always safe).
    pub fn plan_removal(&self, e: u32, plan: &mut Removal) -> bool {
        plan.star.clear();
        plan.link.clear();
        plan.ears.clear();
        let mut f = e;
        loop {
            plan.star.push(f);
            plan.link.push(self.start[next(f) as usize]);
            let o = self.twin[prev(f) as usize];
            if o == NONE || plan.star.len() > self.start.len() {
                return false;
            }
            f = o;
            if f == e {
                break;
            }
        }
        let pos = |i: usize| self.points[plan.link[i] as usize];
        let k = plan.link.len();
        let mut poly: Vec<usize> = (0..k).collect();
        while poly.len() > 3 {
            let m = poly.len();
            let ear = (0..m).find(|&i| {
                let (a, b, c) = (poly[i], poly[(i + 1) % m], poly[(i + 2) % m]);
                area2(pos(a), pos(b), pos(c)) > 0
                    && (0..k).all(|d| {
                        d == a || d == b || d == c || incircle(pos(a), pos(b), pos(c), pos(d)) <= 0
                    })
            });
            let Some(i) = ear else {
                return false;
            };
            plan.ears
                .push([poly[i], poly[(i + 1) % m], poly[(i + 2) % m]]);
            poly.remove((i + 1) % m);
        }
        if area2(pos(poly[0]), pos(poly[1]), pos(poly[2])) <= 0 {
            return false;
        }
        plan.ears.push([poly[0], poly[1], poly[2]]);
        true
    }

    /// Carries out `plan` (from [`Triangulation::plan_removal`] on this very state): the
    /// star's triangles give way to the ears, two slots die, and `out` (from
    /// [`Triangulation::out_edges`]) follows for the link vertices.
    pub fn remove(&mut self, plan: &Removal, out: &mut [u32]) {
        let k = plan.link.len();
        let outer: Vec<u32> = plan
            .star
            .iter()
            .map(|&f| self.twin[next(f) as usize])
            .collect();
        let slots: Vec<u32> = plan.star.iter().map(|&f| f / 3).collect();
        let v = self.start[plan.star[0] as usize];
        // Inner edges, by their link ends (low, high): the half-edge seen first.
        let mut inner: Vec<((usize, usize), u32)> = Vec::with_capacity(2 * k);
        for (n, ear) in plan.ears.iter().enumerate() {
            let t = slots[n];
            let mut h = [NONE; 3];
            for i in 0..3 {
                let (a, b) = (ear[i], ear[(i + 1) % 3]);
                if b == (a + 1) % k {
                    h[i] = outer[a];
                }
            }
            self.set(t, ear.map(|i| plan.link[i]), h);
            for i in 0..3 {
                let (a, b) = (ear[i], ear[(i + 1) % 3]);
                let e = 3 * t + i as u32;
                out[plan.link[a] as usize] = e;
                if b == (a + 1) % k {
                    continue;
                }
                let key = (a.min(b), a.max(b));
                if let Some(p) = inner.iter().position(|(q, _)| *q == key) {
                    let (_, o) = inner.swap_remove(p);
                    self.twin[e as usize] = o;
                    self.twin[o as usize] = e;
                } else {
                    inner.push((key, e));
                }
            }
        }
        debug_assert!(inner.is_empty(), "every inner edge has two sides");
        for &t in &slots[plan.ears.len()..] {
            let e = 3 * t as usize;
            self.start[e..e + 3].fill(NONE);
            self.twin[e..e + 3].fill(NONE);
        }
        out[v as usize] = NONE;
    }

    /// Drops dead slots and unused points, keeping the order of what is left.
    pub fn compact(&mut self) {
        let mut vmap = vec![NONE; self.points.len()];
        let live: Vec<u32> = (0..self.len() as u32)
            .filter(|&t| self.start[3 * t as usize] != NONE)
            .collect();
        for &t in &live {
            for v in self.corners(t) {
                vmap[v as usize] = 0;
            }
        }
        let mut points = Vec::with_capacity(self.points.len());
        for (v, p) in self.points.iter().enumerate() {
            if vmap[v] == 0 {
                vmap[v] = points.len() as u32;
                points.push(*p);
            }
        }
        let mut tmap = vec![NONE; self.len()];
        for (n, &t) in live.iter().enumerate() {
            tmap[t as usize] = n as u32;
        }
        let edge = |e: u32| {
            if e == NONE {
                NONE
            } else {
                3 * tmap[(e / 3) as usize] + e % 3
            }
        };
        let mut start = Vec::with_capacity(3 * live.len());
        let mut twin = Vec::with_capacity(3 * live.len());
        for &t in &live {
            for i in 0..3 {
                let e = 3 * t as usize + i;
                start.push(vmap[self.start[e] as usize]);
                twin.push(edge(self.twin[e]));
            }
        }
        self.points = points;
        self.start = start;
        self.twin = twin;
        self.dirty.clear();
        self.is_dirty = vec![false; live.len()];
    }
}
