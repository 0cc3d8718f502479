//! Tests of the `rqt` mesh: restriction, coverage, the error bound by brute force, minimality
//! against martini's midpoint errors, budgets and stitched tile edges.

use super::*;
use proptest::prelude::*;
use relief_proto::tile::Edge;
use std::collections::{HashMap, HashSet};

/// A `(2^k + 1)^2` grid of heights from a seed: rolling hills, a few cliffs and plateaus
/// (exact ties and flat stretches), and noise of `rough` metres.
fn terrain(k: u32, seed: u64, rough: f32) -> Vec<f32> {
    let n = (1usize << k) + 1;
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut rnd = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f32 / (1u64 << 53) as f32
    };
    let (fx, fy, ph) = (rnd() * 0.6, rnd() * 0.6, rnd() * 6.0);
    (0..n * n)
        .map(|i| {
            let (c, r) = ((i % n) as f32, (i / n) as f32);
            let hill = 30.0 * (fx * c + ph).sin() * (fy * r).cos() + 0.8 * c - 0.3 * r;
            let cliff = if c + 0.5 * r > n as f32 * 0.7 {
                25.0
            } else {
                0.0
            };
            let plateau = if rnd() < 0.3 { 0.0 } else { rough * rnd() };
            (hill + cliff + plateau).max(5.0).round()
        })
        .collect()
}

/// The mesh's edges, undirected, with the twice-areas of the triangles on each side.
fn edges(m: &TriMesh) -> HashMap<(Pos, Pos), Vec<i64>> {
    let mut e: HashMap<(Pos, Pos), Vec<i64>> = HashMap::new();
    for t in &m.triangles {
        let v = t.map(|i| m.vertices[i as usize]);
        let a2 = area2(v[0], v[1], v[2]);
        for k in 0..3 {
            let (p, q) = (v[k], v[(k + 1) % 3]);
            e.entry((p.min(q), p.max(q))).or_default().push(a2);
        }
    }
    e
}

/// Checks everything a mesh of `grid` at `tol` must satisfy; panics with the reason.
fn check_mesh(grid: &HeightGrid<'_>, e: &RqtErrors, tol: f32) {
    let m = e.mesh(tol);
    let n = grid.width;
    assert!(m.covers(n, n), "not a cover at {tol}");
    let err = m.max_error(grid);
    assert!(err <= tol.max(0.0), "error {err} above tolerance {tol}");
    assert_eq!(m.triangles.len(), e.triangle_count(tol));
    // Conforming: no vertex lies inside another triangle's edge (no T-junction), so every
    // inner edge has exactly two triangles, and their levels differ by at most one.
    let verts: HashSet<Pos> = m.vertices.iter().copied().collect();
    for ((p, q), areas) in edges(&m) {
        let d = [q[0] as i64 - p[0] as i64, q[1] as i64 - p[1] as i64];
        let steps = d[0].abs().max(d[1].abs());
        for j in 1..steps {
            let r = [
                p[0] as i64 + d[0] / steps * j,
                p[1] as i64 + d[1] / steps * j,
            ];
            assert!(!verts.contains(&r.map(|v| v as u32)), "T-junction at {r:?}");
        }
        let border = (p[0] == q[0] && (p[0] == 0 || p[0] as usize == n - 1))
            || (p[1] == q[1] && (p[1] == 0 || p[1] as usize == n - 1));
        assert_eq!(areas.len(), if border { 1 } else { 2 }, "edge {p:?}-{q:?}");
        if let [a, b] = areas[..] {
            assert!(
                a == b || a == 2 * b || b == 2 * a,
                "levels differ by more than one"
            );
        }
    }
}

/// The paper's RQ rule in blocks: when the centre of a block is active, the centres of its
/// parent's neighbours across the block's two outer edges are active too.
fn check_restricted_blocks(e: &RqtErrors, tol: f32) {
    let s = e.side() as i64;
    let active = |p: [i64; 2]| e.threshold(p.map(|v| v as u32)) > tol;
    let mut h = 1;
    while 4 * h <= s {
        for y in (h..s).step_by(2 * h as usize) {
            for x in (h..s).step_by(2 * h as usize) {
                if !active([x, y]) {
                    continue;
                }
                // The parent block (4h wide) holding this block, and its centre.
                let (px, py) = (x - x % (4 * h) + 2 * h, y - y % (4 * h) + 2 * h);
                let (ox, oy) = ((x - px).signum(), (y - py).signum());
                for q in [[px + ox * 4 * h, py], [px, py + oy * 4 * h]] {
                    if (0..=s).contains(&q[0]) && (0..=s).contains(&q[1]) {
                        assert!(active(q), "block {x},{y} split but neighbour {q:?} not");
                    }
                }
            }
        }
        h *= 2;
    }
}

/// Martini's errors (mapbox/martini, pymartini): each hypotenuse midpoint's distance to the
/// hypotenuse's interpolation, saturated from the triangles it splits into; the paper's `E_0`.
fn martini_errors(grid: &HeightGrid<'_>) -> RqtErrors {
    let mut e = RqtErrors::new(grid).unwrap();
    let s = e.side;
    let mut mid = vec![0.0f32; e.thr.len()];
    // Finest first: coarse to fine the levels are Centre(s/2), Edge(s/2), Centre(s/4), ...
    let mut order: Vec<Pos> = (0..=s)
        .flat_map(|y| (0..=s).map(move |x| [x, y]))
        .filter(|&p| e.kind(p) != Kind::Corner)
        .collect();
    let half = |k: Kind| match k {
        Kind::Centre(h) => 2 * h + 1,
        Kind::EdgeH(h) | Kind::EdgeV(h) => 2 * h,
        Kind::Corner => u32::MAX,
    };
    order.sort_by_key(|&p| half(e.kind(p)));
    for p in order {
        let [a, b] = e.hypotenuse(p);
        let z = (grid.at(a[0], a[1]) + grid.at(b[0], b[1])) / 2.0;
        let i = e.index(p);
        mid[i] = mid[i].max((z - grid.at(p[0], p[1])).abs());
        for q in e.dependants(p).into_iter().flatten() {
            mid[i] = mid[i].max(mid[e.index(q)]);
        }
    }
    for (i, t) in e.thr.iter_mut().enumerate() {
        if t.is_finite() {
            *t = mid[i];
        }
    }
    e
}

#[test]
fn a_plane_is_two_triangles_and_a_negative_tolerance_the_full_grid() {
    let n = 17usize;
    let z: Vec<f32> = (0..n * n)
        .map(|i| 2.0 * (i % n) as f32 - 0.5 * (i / n) as f32)
        .collect();
    let g = HeightGrid::new(n, n, &z).unwrap();
    let e = RqtErrors::new(&g).unwrap();
    assert_eq!(e.mesh(1e-3).triangles.len(), 2);
    let full = e.mesh(-1.0);
    assert_eq!(full.triangles.len(), 2 * 16 * 16);
    assert!(full.covers(n, n));
}

#[test]
fn a_spike_splits_only_what_it_needs() {
    let n = 65usize;
    let mut z = vec![100.0f32; n * n];
    z[20 * n + 37] = 130.0;
    let g = HeightGrid::new(n, n, &z).unwrap();
    let e = RqtErrors::new(&g).unwrap();
    check_mesh(&g, &e, 1.0);
    check_restricted_blocks(&e, 1.0);
    let m = e.mesh(1.0);
    assert!(m.vertices.contains(&[37, 20]));
    assert!(m.triangles.len() < 100, "{} triangles", m.triangles.len());
    assert_eq!(e.mesh(30.0).triangles.len(), 2);
}

#[test]
fn a_rough_65_tile_meets_every_tolerance() {
    let z = terrain(6, 11, 25.0);
    let g = HeightGrid::new(65, 65, &z).unwrap();
    let e = RqtErrors::new(&g).unwrap();
    let mut last = usize::MAX;
    for tol in [0.0f32, 0.5, 1.0, 3.0, 10.0, 30.0, 100.0] {
        check_mesh(&g, &e, tol);
        check_restricted_blocks(&e, tol);
        let n = e.triangle_count(tol);
        assert!(n <= last, "more triangles at a larger tolerance");
        last = n;
    }
}

#[test]
fn shapes_other_than_two_to_the_k_plus_one_are_refused() {
    let z = vec![0.0f32; 64 * 64];
    let g = HeightGrid::new(64, 64, &z).unwrap();
    assert_eq!(rqt(&g, 1.0).unwrap_err(), RqtError::Shape(64, 64));
    let z = vec![0.0f32; 65 * 33];
    let g = HeightGrid::new(65, 33, &z).unwrap();
    assert!(rqt(&g, 1.0).is_err());
    let z = [1.0, 2.0, 3.0, 5.0];
    let g = HeightGrid::new(2, 2, &z).unwrap();
    assert_eq!(rqt(&g, 0.0).unwrap().triangles.len(), 2);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Restricted, conforming, covering and within tolerance by brute force over every
    /// sample, on random small DEMs at random tolerances.
    #[test]
    fn the_cut_is_restricted_and_the_error_bound_holds(
        k in 1u32..=5, seed in any::<u64>(), rough in 0.0f32..40.0, tol in -0.5f32..30.0,
    ) {
        let z = terrain(k, seed, rough);
        let n = (1usize << k) + 1;
        let g = HeightGrid::new(n, n, &z).unwrap();
        let e = RqtErrors::new(&g).unwrap();
        check_mesh(&g, &e, tol);
        check_restricted_blocks(&e, tol);
        // Dependencies hold: an active vertex's apexes are active.
        for y in 0..n as u32 {
            for x in 0..n as u32 {
                for a in e.apexes([x, y]).into_iter().flatten() {
                    prop_assert!(e.threshold(a) >= e.threshold([x, y]));
                }
            }
        }
    }

    /// No more triangles than martini at martini's measured error: the thresholds are
    /// minimal for the hierarchy, and martini's mesh is one of its conforming meshes.
    #[test]
    fn no_more_triangles_than_martini_at_its_measured_error(
        k in 2u32..=5, seed in any::<u64>(), rough in 0.0f32..40.0, tol in 0.0f32..20.0,
    ) {
        let z = terrain(k, seed, rough);
        let n = (1usize << k) + 1;
        let g = HeightGrid::new(n, n, &z).unwrap();
        let martini = martini_errors(&g).mesh(tol);
        prop_assert!(martini.covers(n, n));
        let measured = martini.max_error(&g);
        let ours = RqtErrors::new(&g).unwrap();
        prop_assert!(ours.triangle_count(measured) <= martini.triangles.len());
    }

    /// A budget's tolerance meets the budget, and the next threshold down would not.
    #[test]
    fn the_tolerance_for_a_budget_is_the_smallest_that_meets_it(
        seed in any::<u64>(), budget in 0usize..600,
    ) {
        let z = terrain(5, seed, 20.0);
        let g = HeightGrid::new(33, 33, &z).unwrap();
        let e = RqtErrors::new(&g).unwrap();
        let t = e.tolerance_for(budget);
        prop_assert!(e.triangle_count(t) <= budget.max(2));
        let below = e.thr.iter().copied().filter(|&v| v < t).fold(0.0f32, f32::max);
        if t > 0.0 {
            prop_assert!(e.triangle_count(below) > budget, "{t} {below}");
        }
    }
}

/// Cuts a `cols x cols` block of `(2^k + 1)`-sample tiles from one terrain, stitches them,
/// and checks every shared edge at several tolerances; returns whether they differed before.
fn check_stitched(seed: u64, cols: usize, k: u32) -> bool {
    let t = (1usize << k) + 1;
    let big_k = (cols * (t - 1)).next_power_of_two().ilog2();
    let n = (1usize << big_k) + 1;
    let big = terrain(big_k, seed, 30.0);
    let zs: Vec<Vec<f32>> = (0..cols * cols)
        .map(|i| {
            let (tx, ty) = (i % cols, i / cols);
            (0..t * t)
                .map(|j| big[(ty * (t - 1) + j / t) * n + tx * (t - 1) + j % t])
                .collect()
        })
        .collect();
    let grids: Vec<HeightGrid<'_>> = zs
        .iter()
        .map(|z| HeightGrid::new(t, t, z).unwrap())
        .collect();
    let mut tiles: Vec<RqtErrors> = grids.iter().map(|g| RqtErrors::new(g).unwrap()).collect();
    let border = |e: &RqtErrors, edge: Edge, tol: f32| -> Vec<bool> {
        e.edge(edge)
            .into_iter()
            .map(|p| e.threshold(p) > tol)
            .collect()
    };
    let mismatched = |tiles: &[RqtErrors], tol: f32| {
        (0..tiles.len()).any(|i| {
            let east = (i + 1) % cols != 0
                && border(&tiles[i], Edge::East, tol) != border(&tiles[i + 1], Edge::West, tol);
            let south = i + cols < tiles.len()
                && border(&tiles[i], Edge::South, tol)
                    != border(&tiles[i + cols], Edge::North, tol);
            east || south
        })
    };
    let tols = [0.5f32, 2.0, 5.0, 10.0];
    let before = tols.iter().any(|&tol| mismatched(&tiles, tol));
    stitch(&mut tiles, cols);
    for tol in tols {
        assert!(!mismatched(&tiles, tol), "stitched tiles differ at {tol}");
        for (g, e) in grids.iter().zip(&tiles) {
            check_mesh(g, e, tol);
        }
    }
    before
}

#[test]
fn stitched_tiles_meet_vertex_for_vertex_at_any_tolerance() {
    // Alone, neighbouring tiles disagree along their edges; stitched, they agree.
    assert!(check_stitched(7, 2, 5));
    check_stitched(8, 3, 4);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(16))]

    /// Stitching converges and agrees on random blocks of tiles.
    #[test]
    fn stitching_agrees_on_random_blocks(seed in any::<u64>(), cols in 1usize..=3, k in 1u32..=4) {
        check_stitched(seed, cols, k);
    }
}
