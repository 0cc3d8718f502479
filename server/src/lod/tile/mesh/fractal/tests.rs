//! Tests of the box-counting dimension and the region tree.

use super::*;

/// A deterministic uniform number in [0, 1) per index.
fn hash01(i: u64) -> f64 {
    let mut s = i.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0xD1B5_4A32_D192_ED03;
    s ^= s >> 31;
    s = s.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    s ^= s >> 29;
    (s >> 11) as f64 / (1u64 << 53) as f64
}

/// Fractional Brownian relief on an `n x n` grid by midpoint displacement (`n = 2^k + 1`):
/// displacements shrink by `2^-hurst` per halving, starting at `amp` metres.
fn fbm(n: usize, hurst: f64, amp: f64, seed: u64) -> Vec<f32> {
    let mut z = vec![0.0f64; n * n];
    let mut step = n - 1;
    let mut a = amp;
    let mut k = seed * 1_000_003;
    let mut rnd = || {
        k += 1;
        hash01(k) * 2.0 - 1.0
    };
    while step > 1 {
        let h = step / 2;
        for y in (h..n).step_by(step) {
            for x in (h..n).step_by(step) {
                let c = [
                    (x - h, y - h),
                    (x + h, y - h),
                    (x - h, y + h),
                    (x + h, y + h),
                ];
                z[y * n + x] = c.iter().map(|&(i, j)| z[j * n + i]).sum::<f64>() / 4.0 + a * rnd();
            }
        }
        for y in (0..n).step_by(h) {
            for x in ((y / h + 1) % 2 * h..n).step_by(step) {
                let mut s = 0.0;
                let mut m = 0.0;
                for (dx, dy) in [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)] {
                    let (i, j) = (x as i64 + dx * h as i64, y as i64 + dy * h as i64);
                    if (0..n as i64).contains(&i) && (0..n as i64).contains(&j) {
                        s += z[j as usize * n + i as usize];
                        m += 1.0;
                    }
                }
                z[y * n + x] = s / m + a * rnd();
            }
        }
        step = h;
        a *= 0.5f64.powf(hurst);
    }
    z.into_iter().map(|v| v as f32).collect()
}

fn dim(z: &[f32], n: usize, spacing: f64) -> f32 {
    let g = HeightGrid::new(n, n, z).unwrap();
    let last = n as u32 - 1;
    box_dimension(&g, [spacing, spacing], (0, last), (0, last), 5).unwrap()
}

#[test]
fn a_plane_has_dimension_two_tilted_or_not() {
    let n = 65;
    for (sx, sy) in [(0.0f32, 0.0f32), (0.3, -0.2), (2.0, 1.5)] {
        let z: Vec<f32> = (0..n * n)
            .map(|i| 500.0 + sx * 30.0 * (i % n) as f32 + sy * 30.0 * (i / n) as f32)
            .collect();
        let d = dim(&z, n, 30.0);
        assert!((d - 2.0).abs() < 0.03, "slope ({sx}, {sy}): D = {d}");
    }
}

#[test]
fn tall_noise_is_near_three_and_fbm_falls_between() {
    let n = 65;
    let noise: Vec<f32> = (0..n * n)
        .map(|i| (hash01(i as u64) * 5000.0) as f32)
        .collect();
    let d_noise = dim(&noise, n, 30.0);
    assert!(d_noise > 2.7, "noise: {d_noise}");
    let rough = dim(&fbm(n, 0.3, 2000.0, 1), n, 30.0);
    let smooth = dim(&fbm(n, 0.9, 2000.0, 1), n, 30.0);
    assert!(
        2.0 < smooth && smooth < rough && rough < d_noise,
        "{smooth} {rough}"
    );
}

#[test]
fn small_regions_have_no_dimension() {
    let z = vec![0.0f32; 17 * 17];
    let g = HeightGrid::new(17, 17, &z).unwrap();
    assert!(box_dimension(&g, [1.0, 1.0], (0, 16), (0, 16), 5).is_some());
    assert!(box_dimension(&g, [1.0, 1.0], (0, 15), (0, 16), 5).is_none());
    assert!(box_dimension(&g, [1.0, 1.0], (0, 16), (0, 16), 2).is_none());
}

#[test]
fn flat_regions_stop_early_and_rough_ones_reach_the_finest_tiles() {
    // West half a gentle plane, east half rough relief: 257 x 257, 64-cell tiles, depth 2.
    let n = 257;
    let rough = fbm(n, 0.2, 3000.0, 3);
    let z: Vec<f32> = (0..n * n)
        .map(|i| {
            let (c, r) = (i % n, i / n);
            if c <= 128 {
                100.0 + 0.1 * c as f32 + 0.05 * r as f32
            } else {
                rough[i]
            }
        })
        .collect();
    let g = HeightGrid::new(n, n, &z).unwrap();
    let shape = TileShape::new(n as u32, n as u32, 64).unwrap();
    let params = FractalParams {
        flat: 2.05,
        rough: 2.2,
        scales: 5,
    };
    let leaves = fractal_leaves(&g, [30.0, 30.0], &shape, &params);
    // The leaves cover the grid once.
    let area: u64 = leaves
        .iter()
        .map(|l| {
            let s = shape.span(l.tile);
            u64::from(s.cols.1 - s.cols.0) * u64::from(s.rows.1 - s.rows.0)
        })
        .sum();
    assert_eq!(area, 256 * 256);
    let west: Vec<_> = leaves
        .iter()
        .filter(|l| shape.span(l.tile).cols.1 <= 128)
        .collect();
    let east: Vec<_> = leaves
        .iter()
        .filter(|l| shape.span(l.tile).cols.0 >= 128)
        .collect();
    assert_eq!(west.len() + east.len(), leaves.len());
    assert!(west.iter().all(|l| l.tile.level == 1), "{west:?}");
    assert!(east.iter().all(|l| l.tile.level == 2), "{east:?}");
    assert!(east.iter().all(|l| l.dimension.unwrap() > 2.2));
    // All flat: the root alone.
    let flat = vec![10.0f32; n * n];
    let g = HeightGrid::new(n, n, &flat).unwrap();
    let leaves = fractal_leaves(&g, [30.0, 30.0], &shape, &params);
    assert_eq!(leaves.len(), 1);
}

#[test]
fn the_split_rule_is_log_linear_between_the_thresholds() {
    let p = FractalParams {
        flat: 2.0,
        rough: 2.4,
        scales: 5,
    };
    assert!(!subdivides(&p, Some(2.0), 0, 4));
    assert!(subdivides(&p, Some(2.4), 3, 4));
    assert!(!subdivides(&p, Some(2.4), 4, 4));
    // Halfway: leaves from level 2 on.
    assert!(subdivides(&p, Some(2.2), 1, 4));
    assert!(!subdivides(&p, Some(2.2), 2, 4));
    assert!(!subdivides(&p, None, 0, 4));
}

#[test]
fn leaf_level_agrees_with_the_split_rule() {
    for p in [
        FractalParams::default(),
        FractalParams {
            flat: 2.0,
            rough: 2.4,
            scales: 5,
        },
        // Equal thresholds: a step from the whole grid to the finest tiles.
        FractalParams {
            flat: 2.02,
            rough: 2.02,
            scales: 5,
        },
    ] {
        for depth in 0..=6u8 {
            for k in 0..=400 {
                let d = 1.99 + 0.001 * k as f32;
                let ll = leaf_level(&p, d, depth);
                assert!(ll <= depth);
                for level in 0..=depth {
                    assert_eq!(
                        subdivides(&p, Some(d), level, depth),
                        level < ll,
                        "{p:?} d {d} level {level} depth {depth}"
                    );
                }
            }
        }
    }
    let p = FractalParams::default();
    assert_eq!(leaf_level(&p, 2.0, 5), 0);
    assert_eq!(leaf_level(&p, 2.5, 5), 5);
    assert_eq!(leaf_level(&p, f32::NAN, 5), 0);
}

#[test]
fn leaves_say_why_they_stopped() {
    let p = FractalParams::default();
    let leaf = |level, d| FractalLeaf {
        tile: TileId { level, x: 0, y: 0 },
        dimension: d,
    };
    assert_eq!(LeafStop::of(&p, &leaf(3, None), 3), LeafStop::NoDimension);
    assert_eq!(LeafStop::of(&p, &leaf(0, Some(2.005)), 3), LeafStop::Flat);
    assert_eq!(LeafStop::of(&p, &leaf(3, Some(2.005)), 3), LeafStop::Flat);
    assert_eq!(LeafStop::of(&p, &leaf(3, Some(2.2)), 3), LeafStop::Finest);
    // Between the thresholds: a third of the way allows level 1 leaves.
    assert_eq!(leaf_level(&p, 2.02, 3), 1);
    assert_eq!(LeafStop::of(&p, &leaf(1, Some(2.02)), 3), LeafStop::Sized);
    assert_eq!(LeafStop::of(&p, &leaf(3, Some(2.02)), 3), LeafStop::Sized);
    // Close enough below rough that only the finest tiles are allowed.
    assert_eq!(leaf_level(&p, 2.039, 3), 3);
    assert_eq!(LeafStop::of(&p, &leaf(3, Some(2.039)), 3), LeafStop::Finest);
}

#[test]
fn progress_reaches_one_and_never_goes_back() {
    let n = 257;
    let z = fbm(n, 0.5, 1000.0, 7);
    let g = HeightGrid::new(n, n, &z).unwrap();
    let shape = TileShape::new(n as u32, n as u32, 32).unwrap();
    let mut seen = Vec::new();
    let leaves =
        fractal_leaves_with_progress(&g, [30.0, 30.0], &shape, &FractalParams::default(), |f| {
            seen.push(f)
        });
    assert_eq!(seen.len(), leaves.len());
    assert!(seen.windows(2).all(|w| w[0] < w[1]), "{seen:?}");
    assert!((seen.last().unwrap() - 1.0).abs() < 1e-12);
    assert_eq!(
        leaves,
        fractal_leaves(&g, [30.0, 30.0], &shape, &FractalParams::default())
    );
}
