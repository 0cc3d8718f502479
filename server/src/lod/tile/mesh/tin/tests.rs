//! Tests of the greedy-insertion TIN: Delaunay, coverage, the tolerance (by brute force), fixed
//! points, locked sides and determinism, on small random DEMs.

use super::*;
use crate::lod::tile::mesh::delaunay::incircle;
use proptest::prelude::*;

/// Every triangle is counter-clockwise, the triangles cover the grid once, and no vertex lies
/// strictly inside any triangle's circumcircle (exact integer test).
pub(crate) fn assert_delaunay(m: &TriMesh, w: usize, h: usize) {
    assert!(m.covers(w, h), "mesh does not cover {w} x {h}");
    for t in &m.triangles {
        let [a, b, c] = t.map(|i| m.vertices[i as usize]);
        for &q in &m.vertices {
            assert!(
                incircle(a, b, c, q) <= 0,
                "{q:?} inside circle of {a:?} {b:?} {c:?}"
            );
        }
    }
}

/// A deterministic rough terrain: two waves plus hashed noise.
fn terrain(w: usize, h: usize, seed: u32) -> Vec<f32> {
    (0..w * h)
        .map(|i| {
            let (c, r) = ((i % w) as f32, (i / w) as f32);
            let n = (i as u32 ^ seed).wrapping_mul(2_654_435_761) >> 24;
            (c * 0.37).sin() * 30.0 + (r * 0.23 + c * 0.05).cos() * 20.0 + n as f32 * 0.05
        })
        .collect()
}

#[test]
fn a_plane_needs_only_its_corners() {
    let (w, h) = (17usize, 11usize);
    let z: Vec<f32> = (0..w * h)
        .map(|i| 3.0 * (i % w) as f32 - 2.0 * (i / w) as f32)
        .collect();
    let g = HeightGrid::new(w, h, &z).unwrap();
    let m = tin(&g, 0.0, &[]);
    assert_eq!((m.vertices.len(), m.triangles.len()), (4, 2));
    assert_eq!(m.max_error(&g), 0.0);
}

#[test]
fn tolerance_zero_reproduces_the_grid_and_a_bump_is_one_vertex() {
    let (w, h) = (33usize, 33usize);
    let z = terrain(w, h, 7);
    let g = HeightGrid::new(w, h, &z).unwrap();
    let m = tin(&g, 0.0, &[]);
    assert_delaunay(&m, w, h);
    assert_eq!(m.max_error(&g), 0.0);
    // A single 4 m spike on a flat grid, tolerance under 4 m: the corners plus the spike (its
    // neighbours then lie at most 0.95 * 4 m above the plane).
    let mut flat = vec![5.0f32; w * h];
    flat[10 * w + 20] = 9.0;
    let g = HeightGrid::new(w, h, &flat).unwrap();
    let m = tin(&g, 3.9, &[]);
    assert_eq!(
        m.vertices,
        vec![[0, 0], [32, 0], [0, 32], [32, 32], [20, 10]]
    );
    assert_eq!(m.triangles.len(), 4);
}

#[test]
fn larger_tolerances_need_fewer_triangles() {
    let (w, h) = (65usize, 65usize);
    let z = terrain(w, h, 3);
    let g = HeightGrid::new(w, h, &z).unwrap();
    let mut last = usize::MAX;
    for tol in [0.5f32, 1.0, 2.0, 5.0, 10.0, 20.0] {
        let m = tin(&g, tol, &[]);
        assert_delaunay(&m, w, h);
        assert!(m.max_error(&g) <= tol);
        assert!(m.triangles.len() < last, "{tol}: {}", m.triangles.len());
        last = m.triangles.len();
    }
}

#[test]
fn locked_sides_take_only_their_fixed_points() {
    let (w, h) = (21usize, 13usize);
    let z = terrain(w, h, 11);
    let g = HeightGrid::new(w, h, &z).unwrap();
    let fixed = [[7, 0], [20, 5], [3, 12], [0, 4], [10, 6]];
    let m = tin_span(&g, &whole(&g), 0.1, &fixed, [true; 4]);
    assert_delaunay(&m, w, h);
    let on_side = |p: &[u32; 2]| p[0] == 0 || p[1] == 0 || p[0] == 20 || p[1] == 12;
    let mut side: Vec<[u32; 2]> = m.vertices.iter().copied().filter(on_side).collect();
    side.sort_unstable();
    assert_eq!(
        side,
        vec![
            [0, 0],
            [0, 4],
            [0, 12],
            [3, 12],
            [7, 0],
            [20, 0],
            [20, 5],
            [20, 12]
        ]
    );
    // Free, the same sides take more points at that tolerance.
    let free = tin(&g, 0.1, &fixed);
    assert!(free.vertices.iter().filter(|p| on_side(p)).count() > side.len());
    assert!(free.max_error(&g) <= 0.1);
}

#[test]
fn a_window_meshes_its_lattice_and_takes_fixed_points_off_it() {
    // Columns 3..=26 (last cell 3 wide at stride 4), rows 5..=18 (last cell 1 wide).
    let (w, h) = (30usize, 20usize);
    let z = terrain(w, h, 13);
    let g = HeightGrid::new(w, h, &z).unwrap();
    let span = TileSpan {
        cols: (3, 26),
        rows: (5, 18),
        stride: 4,
    };
    let fixed = [[5, 0], [23, 7], [9, 9]];
    for tol in [0.0f32, 1.0, 4.0] {
        let free = tin_span(&g, &span, tol, &fixed, [false; 4]);
        assert_delaunay(&free, 24, 14);
        assert!(lattice_error(&free, &g, &span) <= tol);
        // Locked north: only the corners and the fixed point there; the tolerance is not
        // promised on that side.
        let m = tin_span(&g, &span, tol, &fixed, [true, false, false, false]);
        assert_delaunay(&m, 24, 14);
        for m in [&free, &m] {
            for p in &m.vertices {
                let on_lattice = |v: u32, end: u32| v.is_multiple_of(4) || v == end;
                assert!(fixed.contains(p) || (on_lattice(p[0], 23) && on_lattice(p[1], 13)));
            }
            for p in &fixed {
                assert!(m.vertices.contains(p));
            }
        }
        assert!(
            m.vertices
                .iter()
                .all(|p| p[1] != 0 || [0, 5, 23].contains(&p[0]))
        );
    }
    // At tolerance 0 every lattice sample is exact.
    let m = tin_span(&g, &span, 0.0, &[], [false; 4]);
    assert_eq!(lattice_error(&m, &g, &span), 0.0);
}

fn dem() -> impl Strategy<Value = (usize, usize, Vec<f32>)> {
    (2usize..18, 2usize..18).prop_flat_map(|(w, h)| {
        // Small integer steps make many exact ties and cocircular points.
        let z = proptest::collection::vec((-8i8..8).prop_map(|v| f32::from(v) * 0.5), w * h);
        (Just(w), Just(h), z)
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// On any small DEM, with any tolerance and fixed points: Delaunay, covering, within the
    /// tolerance by brute force, fixed points kept, and the same mesh twice.
    #[test]
    fn tin_is_delaunay_covering_and_within_tolerance(
        (w, h, z) in dem(),
        tol in prop_oneof![Just(0.0f32), 0.0f32..3.0],
        fixed in proptest::collection::vec((0u32..18, 0u32..18), 0..6),
    ) {
        let g = HeightGrid::new(w, h, &z).unwrap();
        let fixed: Vec<[u32; 2]> = fixed
            .into_iter()
            .map(|(c, r)| [c % w as u32, r % h as u32])
            .collect();
        let m = tin(&g, tol, &fixed);
        assert_delaunay(&m, w, h);
        prop_assert!(m.max_error(&g) <= tol, "error {} > {tol}", m.max_error(&g));
        for p in &fixed {
            prop_assert!(m.vertices.contains(p), "fixed {p:?} missing");
        }
        let mut seen = m.vertices.clone();
        seen.sort_unstable();
        seen.dedup();
        prop_assert_eq!(seen.len(), m.vertices.len(), "a sample inserted twice");
        prop_assert_eq!(&m, &tin(&g, tol, &fixed));
    }
}
