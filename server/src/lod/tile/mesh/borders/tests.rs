//! Tests of shared borders: the 1D insertion, and tiles of the same and adjacent levels meeting
//! vertex for vertex over a whole pyramid.

use super::*;
use crate::lod::tile::mesh::tin::tests::assert_delaunay;
use proptest::prelude::*;

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
        .map(|v| [span.col(v[0]), span.row(v[1])])
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

/// Every pair of tiles of the same or adjacent levels that share a segment, with the
/// vertices each has on it, for meshes from `mesh`.
fn mismatches(shape: &TileShape, mesh: impl Fn(TileId) -> TriMesh) -> (usize, usize) {
    let tiles: Vec<TileId> = (0..shape.tile_count())
        .filter_map(|i| shape.tile(i))
        .collect();
    let verts: Vec<Vec<[u32; 2]>> = tiles.iter().map(|&t| global(shape, t, &mesh(t))).collect();
    let (mut pairs, mut bad) = (0, 0);
    for (i, &a) in tiles.iter().enumerate() {
        for (j, &b) in tiles.iter().enumerate().skip(i + 1) {
            if b.level > a.level + 1 {
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
    // 121 x 90 with 8-cell tiles: depth 4, narrower last cells east and south.
    let (w, h) = (121u32, 90u32);
    let z = terrain(w, h, 5);
    let shape = TileShape::new(w, h, 8).unwrap();
    assert_eq!(shape.depth(), 4);
    let depth = shape.depth();
    let tol = |k: u8| 0.5 * f32::from(1u8 << (depth - k));
    let shared_mesh = |t: TileId| {
        let m = tile_tin(&shape, t, &z, tol(t.level), Some(&tol)).unwrap();
        let sp = shape.span(t);
        assert_delaunay(&m, sp.nx() as usize, sp.ny() as usize);
        m
    };
    let (pairs, bad) = mismatches(&shape, shared_mesh);
    assert!(pairs > 500, "{pairs} pairs");
    assert_eq!(bad, 0, "{bad} of {pairs} shared sides differ");
    // Plain tins do not meet: the check is not vacuous.
    let plain = |t: TileId| tile_tin(&shape, t, &z, tol(t.level), None).unwrap();
    assert!(mismatches(&shape, plain).1 > pairs / 4);
}

#[test]
fn sectors_of_one_level_keep_the_tolerance() {
    // Depth 1: every inner line is at home on the finest level, at full resolution, so the
    // shared borders cost the tolerance nothing.
    let (w, h) = (33u32, 30u32);
    let z = terrain(w, h, 9);
    let shape = TileShape::new(w, h, 16).unwrap();
    assert_eq!(shape.depth(), 1);
    for tol in [0.0f32, 0.7, 3.0] {
        let (nx, ny) = shape.level_dims(1);
        for (x, y) in (0..nx).flat_map(|x| (0..ny).map(move |y| (x, y))) {
            let t = TileId { level: 1, x, y };
            let m = tile_tin(&shape, t, &z, tol, Some(&|_| tol)).unwrap();
            let zt = tile_heights(&shape, t, &z);
            let sp = shape.span(t);
            let g = HeightGrid::new(sp.nx() as usize, sp.ny() as usize, &zt).unwrap();
            assert!(
                m.max_error(&g) <= tol,
                "{t:?} at {tol}: {}",
                m.max_error(&g)
            );
        }
    }
}

#[test]
fn the_comb_holds_every_finest_corner_and_deep_pyramids_are_refused() {
    let (w, h) = (65u32, 65u32);
    let z = vec![1.0f32; (w * h) as usize];
    let shape = TileShape::new(w, h, 16).unwrap();
    // A flat level-1 tile: its inner sides keep only the finest tiles' corners (every 16
    // samples, every 8 vertices at stride 2); its outer sides stay free.
    let t = TileId {
        level: 1,
        x: 0,
        y: 0,
    };
    let b = tile_borders(&shape, t, &z, &|_| 1.0).unwrap();
    assert_eq!(b, [None, Some(vec![0, 8, 16]), Some(vec![0, 8, 16]), None]);
    // 4-cell tiles over 65 samples: depth 4, the midline's lattice (stride 8) misses corners.
    let deep = TileShape::new(w, h, 4).unwrap();
    assert_eq!(
        tile_borders(
            &deep,
            TileId {
                level: 4,
                x: 7,
                y: 0
            },
            &z,
            &|_| 1.0
        ),
        Err(BorderError::TooDeep {
            home: 1,
            stride: 8,
            tile: 4
        })
    );
}
