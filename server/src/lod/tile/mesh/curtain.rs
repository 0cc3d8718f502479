//! Crack curtains for adaptive tiles (`rqt+patches`): paper 001's
//! patches generalised to tiles whose border vertices differ from their neighbours'.
//!
//! Along one side of a tile, in the vertical plane of that side, the tile's border is a polyline
//! `own`; each neighbour the selection may put across it (the same level, one coarser, the finer
//! ones) has its own polyline over part of the side. A crack is where they differ. Each tile
//! hangs a *curtain* below its own polyline, down to the lower envelope of every polyline that
//! can meet it there: then wherever two neighbours' borders differ, the higher one's curtain
//! reaches the lower one, and no crack shows whatever the selection, as with paper 001's patches
//! (which this is, when the polylines nest as a grid's do).
//!
//! **Bottom.** At every breakpoint `x` of any polyline inside the side (and the side's ends),
//! `b(x) = floor(min over polylines covering x of p(x))`. Between two breakpoints every polyline
//! is linear, so `b` (linear there too) lies at or below all of them: the curtain reaches every
//! neighbour. Positions are whole samples, heights whole quanta.
//!
//! **Triangles.** For each own segment `a-c`, the polygon `a, c, b(x_m), ..., b(x_0)` over the
//! breakpoints `x_0 = a < ... < x_m = c` is fanned from `a`. A fan triangle may reach below the
//! bottom where the bottom is not convex; it stays below `own`, in the side's plane, where the
//! terrain across hides it as it hides a skirt.
//!
//! **T-junctions.** A segment with no bottom point left inside and whose bottom equals it at
//! both ends has no curtain; one with a bottom point inside keeps its curtain even where that
//! has no depth: the flat triangles through the neighbour's vertex there close the pixel-wide
//! holes a rasterizer leaves along a T-junction (the tile meshes' crack test in images found two
//! such pixels in 120 frames at tau 1 without them).
//!
//! **Pruning.** A bottom point strictly below `own` goes where the fan triangle from `a` over
//! its two neighbours already covers it, when no polyline has it as a vertex or it lies
//! strictly inside that triangle: the fan covers at least what it did, with one triangle less,
//! and no drawn vertex is left on a curtain edge to form a T-junction. On synthetic:1025 this
//! takes the curtains from 0.354 to 0.289 times the skirts' triangles
//! (`examples/curtain_ratio.rs`).

pub use relief_proto::tile::body::curtain::{CurtainVertex, Polyline, SideCurtain, fan};
use relief_proto::tile::{Edge, TileId, TileShape, TileSpan};

/// The curtains under `own` against `others` (see the module docs): for each own segment, its
/// bottom points (ends included), or `None` where nothing lies below it.
pub fn side_curtain(own: &Polyline, others: &[Polyline]) -> SideCurtain {
    (0..own.pos.len().saturating_sub(1))
        .map(|s| {
            let (a, c) = (own.pos[s], own.pos[s + 1]);
            let mut xs: Vec<u32> = others
                .iter()
                .flat_map(|o| o.pos.iter().copied())
                .filter(|&x| x > a && x < c)
                .chain([a, c])
                .collect();
            xs.sort_unstable();
            xs.dedup();
            let mut bottom: Vec<(u32, i32)> = xs
                .iter()
                .map(|&x| {
                    let low = others
                        .iter()
                        .filter_map(|o| o.at(x))
                        .chain(own.at(x))
                        .fold(f64::INFINITY, f64::min);
                    (x, low.floor() as i32)
                })
                .collect();
            let top = |x: u32| own.at(x).unwrap_or(f64::NEG_INFINITY);
            // Points strictly below the own line go where the fan from `a` covers them anyway,
            // unless a polyline's vertex would be left on a curtain edge.
            let vertex = |(x, z): (u32, i32)| {
                others
                    .iter()
                    .any(|o| o.pos.iter().zip(&o.z).any(|(&p, &pz)| p == x && pz == z))
            };
            prune((a, own.z[s]), &mut bottom, |p, inside| {
                f64::from(p.1) < top(p.0) && (inside || !vertex(p))
            });
            // A neighbour's vertex inside the segment is a T-junction: the curtain stays even
            // where it has no depth (see `fan`).
            (bottom.len() > 2 || bottom.iter().any(|&(x, z)| f64::from(z) < top(x)))
                .then_some(bottom)
        })
        .collect()
}

/// Drops the interior bottom points `may_go` allows whose fan triangles the fan from `apex`
/// (the segment's start) over their neighbours already covers: a point inside the triangle
/// from the apex to its two neighbours, or on the line from the apex to the next one. The fan
/// then covers at least what it covered, with one triangle less per point. `may_go` is also
/// told whether the point lies strictly inside that triangle (not on its edges).
fn prune(
    apex: (u32, i32),
    bottom: &mut Vec<(u32, i32)>,
    may_go: impl Fn((u32, i32), bool) -> bool,
) {
    let p = |q: (u32, i32)| (i64::from(q.0), i64::from(q.1));
    let cross = |a: (i64, i64), b: (i64, i64), c: (i64, i64)| {
        (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0)
    };
    let a = p(apex);
    let mut i = 1;
    while i + 1 < bottom.len() {
        let (l, m, r) = (p(bottom[i - 1]), p(bottom[i]), p(bottom[i + 1]));
        let (covered, inside) = if cross(a, l, r) == 0 {
            // No area: the point must lie on the line from the apex to the next one, with
            // the previous one at the apex.
            let on = l == a && cross(a, m, r) == 0 && (a.0..=r.0).contains(&m.0);
            (on, false)
        } else {
            let d = [cross(a, l, m), cross(l, r, m), cross(r, a, m)];
            let covered = d.iter().all(|&v| v >= 0) || d.iter().all(|&v| v <= 0);
            (covered, covered && d.iter().all(|&v| v != 0))
        };
        if covered && may_go(bottom[i], inside) {
            bottom.remove(i);
            i = i.saturating_sub(1).max(1);
        } else {
            i += 1;
        }
    }
}

/// The curtain triangles under `own` against `others`.
pub fn curtain(own: &Polyline, others: &[Polyline]) -> Vec<[CurtainVertex; 3]> {
    side_curtain(own, others)
        .iter()
        .enumerate()
        .filter_map(|(s, b)| b.as_ref().map(|b| fan(own, s, b)))
        .flatten()
        .collect()
}

/// The polyline of a tile's border along side `e`: its vertices there, by absolute position
/// along the line (columns for north and south, rows for east and west). `vertex(v)` gives
/// vertex `v`'s sample position and height; `n` vertices.
pub fn side_polyline(
    span: &TileSpan,
    e: Edge,
    n: usize,
    vertex: impl Fn(usize) -> ([u32; 2], i32),
) -> Polyline {
    let mut pts: Vec<(u32, i32)> = (0..n)
        .filter_map(|v| {
            let ([c, r], z) = vertex(v);
            let on = match e {
                Edge::North => (r == span.rows.0).then_some(c),
                Edge::South => (r == span.rows.1).then_some(c),
                Edge::West => (c == span.cols.0).then_some(r),
                Edge::East => (c == span.cols.1).then_some(r),
            };
            on.map(|x| (x, z))
        })
        .collect();
    pts.sort_unstable();
    pts.dedup_by_key(|p| p.0);
    Polyline {
        pos: pts.iter().map(|p| p.0).collect(),
        z: pts.iter().map(|p| p.1).collect(),
    }
}

/// The side facing back across `e`.
pub fn opposite(e: Edge) -> Edge {
    match e {
        Edge::North => Edge::South,
        Edge::South => Edge::North,
        Edge::East => Edge::West,
        Edge::West => Edge::East,
    }
}

/// The tiles a restricted selection may put across side `e` of `t`, each with its side that
/// faces `t`: the same level's neighbour, the coarser tile across (when `t` lies on its
/// parent's side `e`) and the neighbour's children on that side.
pub fn across(shape: &TileShape, t: TileId, e: Edge) -> Vec<(TileId, Edge)> {
    let back = opposite(e);
    let mut out = Vec::new();
    let Some(n) = shape.neighbour(t, e) else {
        return out;
    };
    out.push((n, back));
    // `t` lies on its parent's side `e` exactly when its neighbour has another parent, which
    // is then the coarser tile across.
    if let Some(np) = n.parent()
        && Some(np) != t.parent()
    {
        out.push((np, back));
    }
    let ns = shape.span(n);
    for c in shape.children(n) {
        let cs = shape.span(c);
        let touches = match back {
            Edge::North => cs.rows.0 == ns.rows.0,
            Edge::South => cs.rows.1 == ns.rows.1,
            Edge::West => cs.cols.0 == ns.cols.0,
            Edge::East => cs.cols.1 == ns.cols.1,
        };
        if touches {
            out.push((c, back));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn point(own: &Polyline, v: CurtainVertex) -> (f64, f64) {
        match v {
            CurtainVertex::Own(i) => (f64::from(own.pos[i]), f64::from(own.z[i])),
            CurtainVertex::Bottom(x, z) => (f64::from(x), f64::from(z)),
        }
    }

    fn inside(t: [(f64, f64); 3], p: (f64, f64)) -> bool {
        let cross =
            |a: (f64, f64), b: (f64, f64)| (b.0 - a.0) * (p.1 - a.1) - (b.1 - a.1) * (p.0 - a.0);
        let d = [cross(t[0], t[1]), cross(t[1], t[2]), cross(t[2], t[0])];
        // A flat triangle (kept for T-junctions) covers nothing.
        let area = (t[1].0 - t[0].0) * (t[2].1 - t[0].1) - (t[1].1 - t[0].1) * (t[2].0 - t[0].0);
        area != 0.0 && (d.iter().all(|&v| v >= -1e-9) || d.iter().all(|&v| v <= 1e-9))
    }

    fn polyline(len: u32, seed: u64, step: u32) -> Polyline {
        let mut x = seed | 1;
        let mut pos = vec![0];
        while *pos.last().unwrap() < len {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            pos.push((pos.last().unwrap() + 1 + (x % u64::from(step)) as u32).min(len));
        }
        let z = pos
            .iter()
            .map(|&p| ((p * 7919 + seed as u32 % 97) % 41) as i32 - 20)
            .collect();
        Polyline { pos, z }
    }

    proptest! {
        /// Wherever another polyline lies below the own one, the whole vertical gap between them
        /// is covered by the curtain (sampled at every whole position and a few heights).
        #[test]
        fn the_curtain_closes_every_gap_below(seed in any::<u64>(), n in 1usize..4) {
            let len = 64;
            let own = polyline(len, seed, 16);
            let others: Vec<Polyline> = (0..n).map(|k| polyline(len, seed.wrapping_add(k as u64 * 977), 8)).collect();
            let tris = curtain(&own, &others);
            for x in 0..=len {
                let top = own.at(x).unwrap();
                let low = others.iter().filter_map(|o| o.at(x)).fold(top, f64::min);
                for k in 0..=4 {
                    let z = low + (top - low) * f64::from(k) / 4.0;
                    if top - z < 1e-9 { continue; }
                    let covered = tris.iter().any(|t| inside(t.map(|v| point(&own, v)), (f64::from(x), z)));
                    prop_assert!(covered, "x {} z {} (own {} low {}) not covered", x, z, top, low);
                }
            }
        }
    }

    /// A bottom point that is some polyline's vertex stays; one that only lies on the bottom
    /// where the fan covers it goes.
    #[test]
    fn pruning_keeps_vertices_and_drops_covered_points() {
        let own = Polyline {
            pos: vec![0, 10],
            z: vec![10, 10],
        };
        let flat = Polyline {
            pos: vec![0, 4, 10],
            z: vec![0, 0, 0],
        };
        let dip = Polyline {
            pos: vec![0, 5, 10],
            z: vec![8, 3, 8],
        };
        let c = side_curtain(&own, &[flat, dip]);
        assert_eq!(c, vec![Some(vec![(0, 0), (4, 0), (10, 0)])]);
    }

    #[test]
    fn a_neighbour_on_the_same_vertices_needs_no_curtain() {
        let own = Polyline {
            pos: vec![0, 8, 16],
            z: vec![5, 9, 2],
        };
        assert!(curtain(&own, std::slice::from_ref(&own)).is_empty());
    }
}
