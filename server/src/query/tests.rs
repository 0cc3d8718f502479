//! The queries against brute force on random small DEMs, and their edge cases.

use super::ray::GridRay;
use super::*;
use glam::DVec3;
use proptest::prelude::*;

/// A `w` x `h` terrain (row 0 north) spaced `dx`, `dy`.
fn terrain(w: u32, h: u32, dx: f64, dy: f64, z: &[f32]) -> Terrain {
    Terrain::new(w, h, dx, dy, z).unwrap()
}

/// A flat terrain at height `z0` with one sample raised to `peak` at `(col, row)`.
fn peak(w: u32, h: u32, z0: f32, col: u32, row: u32, peak: f32) -> Terrain {
    let mut z = vec![z0; (w * h) as usize];
    z[(row * w + col) as usize] = peak;
    terrain(w, h, 1.0, 1.0, &z)
}

/// Bilinear interpolation written the textbook way (lerp of lerps), from the north-first
/// heights: the reference the surface is checked against.
fn reference_height(w: u32, h: u32, dx: f64, dy: f64, z: &[f32], x: f64, y: f64) -> f64 {
    let (u, v) = (x / dx, f64::from(h - 1) - y / dy);
    let c = (u.floor() as u32).min(w - 2);
    let r = (v.floor() as u32).min(h - 2);
    let (fu, fv) = (u - f64::from(c), v - f64::from(r));
    let s = |c: u32, r: u32| f64::from(z[(r * w + c) as usize]);
    let top = s(c, r) * (1.0 - fu) + s(c + 1, r) * fu;
    let bottom = s(c, r + 1) * (1.0 - fu) + s(c + 1, r + 1) * fu;
    top * (1.0 - fv) + bottom * fv
}

/// A random small DEM: size, spacing and heights (some of them equal, to make flats).
fn dem() -> impl Strategy<Value = (u32, u32, f64, f64, Vec<f32>)> {
    dem_up_to(12)
}

/// A random DEM of fewer than `n` samples a side.
fn dem_up_to(n: u32) -> impl Strategy<Value = (u32, u32, f64, f64, Vec<f32>)> {
    (
        2u32..n,
        2u32..n,
        prop_oneof![Just(1.0), 0.5..30.0],
        0.5..30.0f64,
    )
        .prop_flat_map(|(w, h, dx, dy)| {
            let n = (w * h) as usize;
            let z = proptest::collection::vec(
                prop_oneof![(-5i32..6).prop_map(|v| v as f32), -5.0f32..6.0],
                n,
            );
            (Just(w), Just(h), Just(dx), Just(dy), z)
        })
}

/// A random ray around a terrain of extent `ex` x `ey`: sometimes with a zero component, and
/// sometimes from a grid vertex, to hit edges and vertices exactly.
fn ray_in(ex: f64, ey: f64) -> impl Strategy<Value = Ray> {
    let coord = |e: f64| prop_oneof![-0.3 * e..1.3 * e, (0u32..12).prop_map(f64::from)];
    let comp = || prop_oneof![3 => -1.0..1.0f64, 1 => Just(0.0), 1 => Just(1.0), 1 => Just(-1.0)];
    (
        coord(ex),
        coord(ey),
        -7.0..12.0f64,
        comp(),
        comp(),
        comp(),
        prop_oneof![0.0..3.0 * (ex + ey + 10.0), Just(f64::INFINITY)],
    )
        .prop_filter("non-zero direction", |r| (r.3, r.4, r.5) != (0.0, 0.0, 0.0))
        .prop_map(|(x, y, z, a, b, c, max_dist)| Ray {
            origin: DVec3::new(x, y, z),
            dir: DVec3::new(a, b, c),
            max_dist,
        })
}

/// Whether two first hits agree: both none, or as far within rounding (on the same cell,
/// unless the hit lies where cells meet).
/// The exhaustive first hit of `ray`, after checking that the pyramid's cast and the column
/// march both find it.
fn cast_and_march_agree_with_exhaustive(
    t: &Terrain,
    ray: &Ray,
) -> Result<Option<Hit>, TestCaseError> {
    let r = GridRay::new(t, ray, 0.0).unwrap();
    let all = t.exhaustive_grid(&r).map(|h| t.hit(&r, h));
    same_hit(t.cast(ray).unwrap(), all)?;
    same_hit(t.march(ray).unwrap(), all)?;
    Ok(all)
}

fn same_hit(a: Option<Hit>, b: Option<Hit>) -> Result<(), TestCaseError> {
    match (a, b) {
        (None, None) => Ok(()),
        (Some(a), Some(b)) => {
            let tol = 1e-9 * (1.0 + a.distance.abs());
            prop_assert!((a.distance - b.distance).abs() <= tol, "{a:?} vs {b:?}");
            prop_assert!((a.point - b.point).length() <= 1e-6, "{a:?} vs {b:?}");
            Ok(())
        }
        (a, b) => Err(TestCaseError::fail(format!("{a:?} vs {b:?}"))),
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// The pyramid's cast and the column march give the exhaustive first hit.
    #[test]
    fn first_hit_matches_the_exhaustive_march(
        (t, ray) in dem().prop_flat_map(|(w, h, dx, dy, z)| {
            let t = terrain(w, h, dx, dy, &z);
            let (ex, ey) = t.extent();
            (Just(t), ray_in(ex, ey))
        })
    ) {
        let all = cast_and_march_agree_with_exhaustive(&t, &ray)?;
        // And the hit is where the ray first comes to the ground: on or under the surface
        // there, above it everywhere before (sampled densely).
        let unit = ray.dir.normalize();
        let end = all.map_or(ray.max_dist.min(1e4), |h| h.distance);
        if let Some(h) = all {
            let g = t.height(h.point.x, h.point.y).unwrap();
            prop_assert!(h.point.z <= g + 1e-6, "{h:?} above ground {g}");
        }
        for k in 0..400 {
            let d = end * f64::from(k) / 400.0;
            let p = ray.origin + unit * d;
            if d >= end - 1e-9 * (1.0 + end) {
                break;
            }
            if let Ok(g) = t.height(p.x, p.y) {
                prop_assert!(p.z > g - 1e-6, "ray under the ground at {p} before its hit {all:?}");
            }
        }
    }

    /// The same on larger DEMs, where the pyramid is deeper and rays are long.
    #[test]
    fn first_hit_matches_on_deeper_pyramids(
        (t, ray) in dem_up_to(70).prop_flat_map(|(w, h, dx, dy, z)| {
            let t = terrain(w, h, dx, dy, &z);
            let (ex, ey) = t.extent();
            (Just(t), ray_in(ex, ey))
        })
    ) {
        cast_and_march_agree_with_exhaustive(&t, &ray)?;
    }

    /// Rays from grid vertices along lattice directions (through vertices, along edges),
    /// over integer DEMs (ties everywhere): the pyramid's cast and the march both return
    /// exactly the exhaustive hit, cell included (the march once lost cells that the ray
    /// touches only at a vertex, computed a hair off).
    #[test]
    fn cast_is_the_march_exactly_through_vertices(
        (t, ray) in dem_up_to(40).prop_flat_map(|(w, h, _, _, z)| {
            let z: Vec<f32> = z.iter().map(|v| v.round()).collect();
            let t = terrain(w, h, 1.0, 1.0, &z);
            let ray = (
                0..w + 2,
                0..h + 2,
                -6i32..10,
                -2i32..3,
                -2i32..3,
                prop_oneof![Just(0.0), Just(-1.0), -2.0..1.0f64],
            )
                .prop_filter("non-zero direction", |r| (r.3, r.4, r.5) != (0, 0, 0.0))
                .prop_map(|(x, y, z, a, b, c)| Ray {
                    origin: DVec3::new(f64::from(x) - 1.0, f64::from(y) - 1.0, f64::from(z)),
                    dir: DVec3::new(f64::from(a), f64::from(b), c),
                    max_dist: f64::INFINITY,
                });
            (Just(t), ray)
        })
    ) {
        let cast = t.cast(&ray).unwrap();
        let r = GridRay::new(&t, &ray, 0.0).unwrap();
        prop_assert_eq!(cast, t.exhaustive_grid(&r).map(|h| t.hit(&r, h)));
        prop_assert_eq!(cast, t.march(&ray).unwrap());
    }

    /// A line of sight is blocked exactly where dense sampling of the segment first finds it
    /// within the clearance of the ground.
    #[test]
    fn line_of_sight_agrees_with_dense_sampling(
        (t, a, b, c) in dem().prop_flat_map(|(w, h, dx, dy, z)| {
            let t = terrain(w, h, dx, dy, &z);
            let (ex, ey) = t.extent();
            let p = move || (-0.2 * ex..1.2 * ex, -0.2 * ey..1.2 * ey, -2.0..12.0f64)
                .prop_map(|(x, y, z)| DVec3::new(x, y, z));
            (Just(t), p(), p(), prop_oneof![Just(0.0), 0.0..3.0f64])
        })
    ) {
        let sight = t.line_of_sight(a, b, c).unwrap();
        let len = (b - a).length();
        let n = 2000;
        let mut first_below = None;
        for k in 0..=n {
            let d = len * f64::from(k) / f64::from(n);
            let p = a + (b - a) * (f64::from(k) / f64::from(n));
            if let Ok(g) = t.height(p.x, p.y) {
                if p.z - c < g - 1e-6 && first_below.is_none() {
                    first_below = Some(d);
                }
                if let Sight::Blocked { distance, .. } = sight {
                    // Nothing before the blocking point is within the clearance.
                    if d < distance - 1e-9 * (1.0 + len) {
                        prop_assert!(p.z - c > g - 1e-6, "{p} blocked before {sight:?}");
                    }
                }
            }
        }
        match sight {
            Sight::Visible => prop_assert!(first_below.is_none(), "{first_below:?}"),
            Sight::Blocked { point, distance } => {
                if let Some(d) = first_below {
                    prop_assert!(distance <= d + 1e-9 * (1.0 + len));
                }
                let g = t.height(point.x, point.y).unwrap();
                prop_assert!(point.z - c <= g + 1e-6, "{point} clear of {g}");
            }
        }
    }

    /// Heights are the textbook bilinear interpolation; bicubic goes through the samples.
    #[test]
    fn heights_match_the_reference_interpolation(
        ((w, h, dx, dy, z), fx, fy) in (dem(), 0.0..=1.0f64, 0.0..=1.0f64)
    ) {
        let t = terrain(w, h, dx, dy, &z);
        let (ex, ey) = t.extent();
        let (x, y) = (fx * ex, fy * ey);
        let want = reference_height(w, h, dx, dy, &z, x, y);
        let got = t.height(x, y).unwrap();
        prop_assert!((got - want).abs() <= 1e-9 * (1.0 + want.abs()), "{got} vs {want}");
        prop_assert_eq!(t.surface(x, y).unwrap().height, got);
        let (c, r) = ((fx * f64::from(w - 1)).round() as u32, (fy * f64::from(h - 1)).round() as u32);
        let (sx, sy) = (f64::from(c) * dx, f64::from(h - 1 - r) * dy);
        let cubic = t.height_with(sx, sy, Interp::Bicubic).unwrap();
        let sample = f64::from(z[(r * w + c) as usize]);
        prop_assert!((cubic - sample).abs() <= 1e-9 * (1.0 + sample.abs()), "{cubic} vs {sample}");
    }
}

#[test]
fn bad_grids_and_inputs_are_errors_not_panics() {
    assert!(matches!(
        Terrain::new(1, 5, 1.0, 1.0, &[0.0; 5]),
        Err(QueryError::BadGrid(_))
    ));
    assert!(Terrain::new(2, 2, 1.0, 1.0, &[0.0; 3]).is_err());
    assert!(Terrain::new(2, 2, 0.0, 1.0, &[0.0; 4]).is_err());
    assert!(Terrain::new(2, 2, 1.0, 1.0, &[0.0, f32::NAN, 0.0, 0.0]).is_err());
    let t = peak(4, 4, 0.0, 1, 1, 3.0);
    let ray = |o: DVec3, d: DVec3, m: f64| Ray {
        origin: o,
        dir: d,
        max_dist: m,
    };
    let (o, d) = (DVec3::new(0.5, 0.5, 5.0), DVec3::NEG_Z);
    for (r, e) in [
        (ray(DVec3::NAN, d, 1.0), QueryError::NotFinite),
        (
            ray(o, DVec3::new(0.0, f64::INFINITY, -1.0), 1.0),
            QueryError::NotFinite,
        ),
        (ray(o, d, f64::NAN), QueryError::NotFinite),
        (ray(o, DVec3::ZERO, 1.0), QueryError::ZeroDirection),
        (ray(o, d, -1.0), QueryError::Negative(-1.0)),
    ] {
        assert_eq!(t.cast(&r), Err(e));
        assert_eq!(t.march(&r), Err(e));
    }
    assert_eq!(t.height(f64::NAN, 0.0), Err(QueryError::NotFinite));
    assert_eq!(
        t.height(-0.1, 1.0),
        Err(QueryError::Outside { x: -0.1, y: 1.0 })
    );
    assert!(t.height(3.0001, 1.0).is_err());
    assert!(t.hat_hot(DVec3::new(1.0, 1.0, f64::INFINITY)).is_err());
    assert_eq!(t.line_of_sight(o, o, -1.0), Err(QueryError::Negative(-1.0)));
    assert_eq!(
        t.line_of_sight(o, DVec3::new(f64::NAN, 0.0, 0.0), 1.0),
        Err(QueryError::NotFinite)
    );
    // The border itself is inside.
    assert_eq!(t.height(3.0, 3.0), Ok(0.0));
    assert_eq!(t.height(0.0, 0.0), Ok(0.0));
}

#[test]
fn vertical_rays_on_a_vertex_an_edge_and_inside_a_cell() {
    // Peak at column 1, row 1 (north-first) of a 4 x 4 grid: world (1, 2).
    let t = peak(4, 4, 0.0, 1, 1, 4.0);
    let down = |x: f64, y: f64| {
        let r = Ray {
            origin: DVec3::new(x, y, 10.0),
            dir: DVec3::NEG_Z,
            max_dist: 100.0,
        };
        let (a, b) = (t.cast(&r).unwrap().unwrap(), t.march(&r).unwrap().unwrap());
        assert_eq!(a, b);
        a
    };
    let on_vertex = down(1.0, 2.0);
    assert!((on_vertex.distance - 6.0).abs() < 1e-12, "{on_vertex:?}");
    // On an edge from the peak: halfway down.
    let on_edge = down(1.5, 2.0);
    assert!((on_edge.point.z - 2.0).abs() < 1e-12, "{on_edge:?}");
    // Inside a cell: bilinear.
    let inside = down(1.25, 2.5);
    assert!(
        (inside.point.z - 4.0 * 0.75 * 0.5).abs() < 1e-12,
        "{inside:?}"
    );
    assert_eq!(inside.normal, t.surface(1.25, 2.5).unwrap().normal);
    // Upwards from above the ground: nothing; from under it: at once.
    let up = |z: f64| {
        t.cast(&Ray {
            origin: DVec3::new(1.25, 2.5, z),
            dir: DVec3::Z,
            max_dist: f64::INFINITY,
        })
        .unwrap()
    };
    assert_eq!(up(10.0), None);
    let under = up(-1.0).unwrap();
    assert_eq!((under.distance, under.point.z), (0.0, -1.0));
}

#[test]
fn horizontal_rays_and_rays_along_edges_and_through_vertices() {
    let t = peak(5, 5, 0.0, 2, 2, 4.0);
    let cast = |o: DVec3, d: DVec3| {
        let r = Ray {
            origin: o,
            dir: d,
            max_dist: f64::INFINITY,
        };
        let (a, b) = (t.cast(&r).unwrap(), t.march(&r).unwrap());
        let g = GridRay::new(&t, &r, 0.0).unwrap();
        assert_eq!(a, t.exhaustive_grid(&g).map(|h| t.hit(&g, h)));
        assert_eq!(a, b);
        a
    };
    // Horizontal, exactly along the row of the peak (an edge line), at height 2: meets the
    // peak's slope halfway up, at x = 1.5.
    let h = cast(DVec3::new(-1.0, 2.0, 2.0), DVec3::X).unwrap();
    assert!((h.point.x - 1.5).abs() < 1e-12, "{h:?}");
    // Diagonal through the vertices (0,0), (1,1), (2,2): meets the peak's slope where the
    // bilinear diagonal a*a*4 reaches the ray... from z=3 sloping down 1 per vertex.
    let diag = cast(
        DVec3::new(0.0, 0.0, 3.0),
        DVec3::new(1.0, 1.0, -1.0 / 2f64.sqrt()),
    );
    let p = diag.unwrap().point;
    assert!((p.z - t.height(p.x, p.y).unwrap()).abs() < 1e-9, "{p}");
    // Horizontal at exactly the flat ground's height: touches at once.
    assert_eq!(
        cast(DVec3::new(0.5, 0.5, 0.0), DVec3::Y).unwrap().distance,
        0.0
    );
    // Horizontal above everything: no hit. Outside the terrain, going away: no hit.
    assert_eq!(cast(DVec3::new(-1.0, 2.0, 4.5), DVec3::X), None);
    assert_eq!(cast(DVec3::new(-1.0, 2.0, 1.0), DVec3::NEG_X), None);
    // Entering from the side below the ground's height: hits where it enters.
    let side = peak(3, 3, 5.0, 0, 0, 5.0);
    let r = Ray {
        origin: DVec3::new(-2.0, 1.0, 1.0),
        dir: DVec3::X,
        max_dist: 10.0,
    };
    assert_eq!(side.cast(&r).unwrap().unwrap().distance, 2.0);
    // A zero-length ray: hits only if it starts on or under the ground.
    let zero = |z: f64| {
        t.cast(&Ray {
            origin: DVec3::new(0.5, 0.5, z),
            dir: DVec3::NEG_Z,
            max_dist: 0.0,
        })
        .unwrap()
    };
    assert_eq!(zero(1.0), None);
    assert_eq!(zero(0.0).map(|h| h.distance), Some(0.0));
}

#[test]
fn hit_cells_are_named_by_their_north_west_sample() {
    // 3 x 3 samples, north-first: the peak at column 2, row 2 is the south-east corner.
    let t = peak(3, 3, 0.0, 2, 2, 4.0);
    let r = Ray {
        origin: DVec3::new(1.75, 0.25, 10.0),
        dir: DVec3::NEG_Z,
        max_dist: 20.0,
    };
    assert_eq!(t.cast(&r).unwrap().unwrap().cell, [1, 1]);
}

#[test]
fn line_of_sight_over_a_ridge() {
    // A ridge along column 5 of an 11 x 3 grid, 10 m high.
    let (w, h) = (11, 3);
    let z: Vec<f32> = (0..w * h)
        .map(|i| if i % w == 5 { 10.0 } else { 0.0 })
        .collect();
    let t = terrain(w, h, 1.0, 1.0, &z);
    let (a, b) = (DVec3::new(0.0, 1.0, 2.0), DVec3::new(10.0, 1.0, 2.0));
    let Sight::Blocked { point, distance } = t.line_of_sight(a, b, 0.0).unwrap() else {
        panic!("not blocked")
    };
    // The ridge's west slope rises 10 m over [4, 5]: it reaches 2 m at x = 4.2.
    assert!((point.x - 4.2).abs() < 1e-12 && (distance - 4.2).abs() < 1e-12);
    let over = DVec3::new(10.0, 1.0, 12.0);
    assert!(
        t.line_of_sight(DVec3::new(0.0, 1.0, 12.0), over, 1.0)
            .unwrap()
            .is_visible()
    );
    // The same line with 2.5 m clearance is blocked by the ridge top.
    let s = t
        .line_of_sight(DVec3::new(0.0, 1.0, 12.0), over, 2.5)
        .unwrap();
    assert!(
        matches!(s, Sight::Blocked { distance, .. } if (distance - 4.95).abs() < 1e-12),
        "{s:?}"
    );
    // A point: blocked only within the clearance of the ground.
    assert!(t.line_of_sight(a, a, 1.0).unwrap().is_visible());
    assert!(!t.line_of_sight(a, a, 2.0).unwrap().is_visible());
    // Outside the terrain there is nothing to block.
    let far = DVec3::new(-5.0, 1.0, 0.5);
    assert!(
        t.line_of_sight(far, DVec3::new(-5.0, 9.0, 0.5), 0.0)
            .unwrap()
            .is_visible()
    );
}

#[test]
fn hat_and_hot_on_a_slope() {
    // A plane rising 1 m per 2 m eastwards.
    let (w, h) = (5, 4);
    let z: Vec<f32> = (0..w * h).map(|i| (i % w) as f32).collect();
    let t = terrain(w, h, 2.0, 3.0, &z);
    let mut out = Vec::new();
    t.hat_hot_many(
        &[DVec3::new(3.0, 4.0, 10.0), DVec3::new(100.0, 0.0, 0.0)],
        &mut out,
    );
    let a = out[0].unwrap();
    assert!((a.hot - 1.5).abs() < 1e-12 && (a.hat - 8.5).abs() < 1e-12);
    let n = DVec3::new(-0.5, 0.0, 1.0).normalize();
    assert!((a.normal - n).length() < 1e-12, "{:?}", a.normal);
    assert_eq!(out[1], Err(QueryError::Outside { x: 100.0, y: 0.0 }));
    // Bicubic reproduces the plane away from the borders.
    assert!((t.height_with(3.0, 4.0, Interp::Bicubic).unwrap() - 1.5).abs() < 1e-12);
    let mut hs = Vec::new();
    t.heights(&[[3.0, 4.0], [f64::NAN, 1.0]], Interp::Bilinear, &mut hs);
    assert_eq!(hs, vec![Ok(1.5), Err(QueryError::NotFinite)]);
}

#[test]
fn from_store_reads_the_stored_heights() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.relief");
    let (w, h) = (9u32, 6u32);
    let heights: Vec<f32> = (0..w * h).map(|i| (i % 7) as f32).collect();
    let input = crate::store::StoreInput {
        width: w,
        height: h,
        spacing_x: 10.0,
        spacing_y: 20.0,
        z_quantum: 0.5,
        heights: &heights,
        voids: &crate::dem::VoidMask::new(heights.len()),
        tile_size: 4,
        meta: Default::default(),
    };
    crate::store::write_store(&path, &input, |_| {}).unwrap();
    let s = crate::store::Store::open(&path).unwrap();
    let t = Terrain::from_store(&s).unwrap();
    assert_eq!(t.size(), (w, h));
    // Sample (col 3, row 0) is the north-west-most row: world (30, 100).
    assert_eq!(t.height(30.0, 100.0), Ok(f64::from(heights[3])));
}
