//! Tests of shared borders: the 1D insertion, and tiles of the same and adjacent levels meeting
//! vertex for vertex over a whole pyramid.

use super::*;
use crate::lod::tile::mesh::tin::lattice_error;
use crate::lod::tile::mesh::tin::tests::assert_delaunay;
use proptest::prelude::*;
use relief_proto::tile::TileSpan;

/// A deterministic rough terrain over `w x h` samples.
fn terrain(w: u32, h: u32, seed: u32) -> Vec<f32> {
    (0..w * h)
        .map(|i| {
            let (c, r) = ((i % w) as f32, (i / w) as f32);
            let n = (i ^ seed).wrapping_mul(2_654_435_761) >> 22;
            (c * 0.21).sin() * 40.0 + (r * 0.13 - c * 0.07).cos() * 25.0 + n as f32 * 0.01
        })
        .collect()
}

/// Largest vertical distance from the chords between kept points, over every sample.
fn chord_error(pos: &[u32], z: &[f32], keep: &[usize]) -> f64 {
    let mut worst = 0.0f64;
    for w in keep.windows(2) {
        let (i, j) = (w[0], w[1]);
        for k in i..=j {
            let f = f64::from(pos[k] - pos[i]) / f64::from(pos[j] - pos[i]);
            let m = f64::from(z[i]) * (1.0 - f) + f64::from(z[j]) * f;
            worst = worst.max((m - f64::from(z[k])).abs());
        }
    }
    worst
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// The ends and forced points are kept, every sample is within the tolerance of the
    /// chords, and a larger tolerance keeps a subset.
    #[test]
    fn edge_points_bound_the_error_and_nest(
        z in proptest::collection::vec(-20i16..20, 2..70),
        narrow in 0u32..2,
        tol in 0.0f32..6.0,
        forced in proptest::collection::vec(0usize..70, 0..4),
    ) {
        let z: Vec<f32> = z.into_iter().map(|v| f32::from(v) * 0.5).collect();
        let n = z.len();
        // A narrower last cell, as on a grid whose size is not a tile multiple.
        let mut pos: Vec<u32> = (0..n as u32).map(|i| 2 * i).collect();
        pos[n - 1] -= narrow;
        let keep = edge_points(&pos, &z, tol, &forced);
        prop_assert_eq!(keep.first(), Some(&0));
        prop_assert_eq!(keep.last(), Some(&(n - 1)));
        for f in forced.iter().filter(|&&f| f < n) {
            prop_assert!(keep.contains(f));
        }
        prop_assert!(chord_error(&pos, &z, &keep) <= f64::from(tol) + 1e-9);
        let coarse = edge_points(&pos, &z, tol * 2.0 + 1.0, &forced);
        prop_assert!(coarse.iter().all(|i| keep.contains(i)), "{coarse:?} not in {keep:?}");
    }
}

/// Tile `t`'s mesh vertices in grid samples.
fn global(shape: &TileShape, t: TileId, m: &TriMesh) -> Vec<[u32; 2]> {
    let span = shape.span(t);
    m.vertices
        .iter()
        .map(|v| [span.cols.0 + v[0], span.rows.0 + v[1]])
        .collect()
}

/// The sides two tiles share, when they share a segment of positive length: the segment's
/// samples as a predicate.
fn shared(a: &TileSpan, b: &TileSpan) -> Option<impl Fn(&[u32; 2]) -> bool + use<>> {
    let overlap = |x: (u32, u32), y: (u32, u32)| (x.0.max(y.0), x.1.min(y.1));
    let touch = |x: (u32, u32), y: (u32, u32)| (x.1 == y.0 || x.0 == y.1).then_some(x.1.min(y.1));
    let on_col = touch(a.cols, b.cols).map(|c| (0, c, overlap(a.rows, b.rows)));
    let on_row = touch(a.rows, b.rows).map(|r| (1, r, overlap(a.cols, b.cols)));
    let (axis, at, (lo, hi)) = on_col
        .filter(|s| s.2.0 < s.2.1)
        .or(on_row.filter(|s| s.2.0 < s.2.1))?;
    Some(move |p: &[u32; 2]| p[axis] == at && (lo..=hi).contains(&p[1 - axis]))
}

/// Pairs of tiles whose levels differ by `gaps` that share a segment, and how many of them
/// have different vertices on it, for the meshes `mesh` makes.
fn mismatches(
    shape: &TileShape,
    gaps: std::ops::RangeInclusive<u8>,
    mesh: impl Fn(TileId) -> TriMesh,
) -> (usize, usize) {
    let tiles: Vec<TileId> = (0..shape.tile_count())
        .filter_map(|i| shape.tile(i))
        .collect();
    let verts: Vec<Vec<[u32; 2]>> = tiles.iter().map(|&t| global(shape, t, &mesh(t))).collect();
    let (mut pairs, mut bad) = (0, 0);
    for (i, &a) in tiles.iter().enumerate() {
        for (j, &b) in tiles.iter().enumerate().skip(i + 1) {
            if !gaps.contains(&(b.level - a.level)) {
                continue;
            }
            let Some(on) = shared(&shape.span(a), &shape.span(b)) else {
                continue;
            };
            let side = |v: &[[u32; 2]]| {
                let mut s: Vec<[u32; 2]> = v.iter().copied().filter(|p| on(p)).collect();
                s.sort_unstable();
                s
            };
            pairs += 1;
            bad += usize::from(side(&verts[i]) != side(&verts[j]));
        }
    }
    (pairs, bad)
}

#[test]
fn tiles_of_the_same_and_adjacent_levels_meet_vertex_for_vertex() {
    // 121 x 90 with 8-cell tiles: depth 4, narrower last cells east and south. 65 x 65 with
    // 4-cell tiles: depth 4, and the midlines' level-1 lattice (stride 8) is wider than a tile.
    for (w, h, tile) in [(121u32, 90u32, 8u32), (65, 65, 4)] {
        let z = terrain(w, h, 5);
        let grid = HeightGrid::new(w as usize, h as usize, &z).unwrap();
        let shape = TileShape::new(w, h, tile).unwrap();
        let depth = shape.depth();
        assert_eq!(depth, 4);
        let tol = |k: u8| 0.5 * f32::from(1u8 << (depth - k));
        let finest = |_: u8| tol(depth);
        for line in [&tol as &dyn Fn(u8) -> f32, &finest] {
            let mesh = |t: TileId| {
                let m = tile_tin(&shape, t, &grid, tol(t.level), Some(line));
                let sp = shape.span(t);
                let (w, h) = (sp.cols.1 - sp.cols.0 + 1, sp.rows.1 - sp.rows.0 + 1);
                assert_delaunay(&m, w as usize, h as usize);
                m
            };
            let (pairs, bad) = mismatches(&shape, 0..=1, mesh);
            assert!(pairs > 500, "{pairs} pairs");
            assert_eq!(bad, 0, "{w} x {h}: {bad} of {pairs} shared sides differ");
        }
        // Plain tins choose each side's points alike at one level (same samples, tolerance
        // and stride), but not across levels: the check is not vacuous.
        let plain = |t: TileId| tile_tin(&shape, t, &grid, tol(t.level), None);
        assert_eq!(mismatches(&shape, 0..=0, plain).1, 0);
        let (pairs, bad) = mismatches(&shape, 1..=1, plain);
        assert!(bad > pairs / 2, "{bad} of {pairs}");
    }
}

#[test]
fn lines_at_the_finest_tolerance_keep_every_tile_within_its_own() {
    let (w, h) = (97u32, 65u32);
    let z = terrain(w, h, 9);
    let grid = HeightGrid::new(w as usize, h as usize, &z).unwrap();
    let shape = TileShape::new(w, h, 16).unwrap();
    let depth = shape.depth();
    let tol = |k: u8| 0.3 * f32::from(1u8 << (depth - k));
    for t in (0..shape.tile_count()).filter_map(|i| shape.tile(i)) {
        let m = tile_tin(&shape, t, &grid, tol(t.level), Some(&|_| tol(depth)));
        let e = lattice_error(&m, &grid, &shape.span(t));
        assert!(e <= tol(t.level), "{t:?}: {e} > {}", tol(t.level));
    }
}

#[test]
fn the_comb_holds_every_finest_corner() {
    let (w, h) = (65u32, 65u32);
    let z = vec![1.0f32; (w * h) as usize];
    let grid = HeightGrid::new(w as usize, h as usize, &z).unwrap();
    let shape = TileShape::new(w, h, 16).unwrap();
    assert_eq!(shape.depth(), 2);
    // A flat level-1 tile: its inner sides keep only the finest tiles' corners (every 16
    // samples); its outer sides stay free.
    let t = TileId {
        level: 1,
        x: 0,
        y: 0,
    };
    let b = tile_borders(&shape, t, &grid, &|_| 1.0);
    assert_eq!(
        b,
        [None, Some(vec![0, 16, 32]), Some(vec![0, 16, 32]), None]
    );
    // Corners and two comb points, all on the border: 2n - b - 2 = 4 triangles.
    let m = tile_tin(&shape, t, &grid, 1.0, Some(&|_| 1.0));
    assert_eq!((m.vertices.len(), m.triangles.len()), (6, 4));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// Any grid size, tile size and heights: shared borders meet across the same and adjacent
    /// levels, and every mesh is Delaunay and covers its tile.
    #[test]
    fn shared_borders_meet_on_any_pyramid(
        w in 3u32..40,
        h in 3u32..40,
        tile in prop_oneof![Just(2u32), Just(4), Just(8)],
        seed in 0u32..1000,
        base in 0.0f32..2.0,
    ) {
        let z: Vec<f32> = terrain(w, h, seed).iter().map(|v| (v * 2.0).round() * 0.5).collect();
        let grid = HeightGrid::new(w as usize, h as usize, &z).unwrap();
        let shape = TileShape::new(w, h, tile).unwrap();
        let depth = shape.depth();
        let tol = |k: u8| base * (1u32 << (depth - k)) as f32;
        let mesh = |t: TileId| {
            let m = tile_tin(&shape, t, &grid, tol(t.level), Some(&tol));
            let sp = shape.span(t);
            assert_delaunay(&m, (sp.cols.1 - sp.cols.0 + 1) as usize, (sp.rows.1 - sp.rows.0 + 1) as usize);
            m
        };
        prop_assert_eq!(mismatches(&shape, 0..=1, mesh).1, 0);
    }
}
