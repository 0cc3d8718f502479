//! The header's geometry against independent checks (bounding sphere, centre, horizon
//! occlusion point seen from random cameras) and the normals (area weighting, oct encoding).

use super::*;

fn ecef(p: [f64; 3]) -> [f64; 3] {
    to_ecef(p[0], p[1], p[2])
}

#[test]
fn header_sphere_and_centre_hold_every_vertex() {
    let cases = [
        grid(ALPS, 65, 65, sine_terrain),
        irregular(7),
        // Polar cap, up to the pole.
        grid([-180.0, 67.5, -135.0, 90.0], 33, 33, |lon, lat| {
            1500.0 + 1000.0 * (lon / 10.0).sin() * (lat / 3.0).cos()
        }),
        // Below the ellipsoid.
        grid([35.15625, 30.9375, 36.5625, 32.34375], 20, 30, |lon, _| {
            -430.0 + 200.0 * (lon - 35.15625)
        }),
        // A small level-18 tile next to the antimeridian.
        grid([179.99931, -0.00069, 180.0, 0.0], 9, 9, |lon, _| lon),
    ];
    for mesh in &cases {
        let bytes = encode(mesh, &QmExtensions::default()).unwrap();
        let tile = decode(&bytes).unwrap();
        let h = tile.header;
        let (w, s, e, n) = bounds(mesh);
        let mid = 0.5 * (f64::from(h.min_height) + f64::from(h.max_height));
        let center = to_ecef(0.5 * (w + e), 0.5 * (s + n), mid);
        assert!(norm(sub(h.center, center)) < 1e-6);
        let r = h.sphere_radius;
        assert!(norm(sub(h.center, h.sphere_center)) <= r);
        let decoded: Vec<[f64; 3]> = tile.positions(w, s, e, n).into_iter().map(ecef).collect();
        let mut diameter: f64 = 0.0;
        for &p in &decoded {
            assert!(norm(sub(p, h.sphere_center)) <= r * (1.0 + 1e-12));
            for &q in &decoded {
                diameter = diameter.max(norm(sub(p, q)));
            }
        }
        assert!(
            r >= 0.5 * diameter && r <= diameter,
            "radius {r}, diameter {diameter}"
        );
        // The original vertices too, give or take their quantization error.
        for (i, &v) in vertex_order(mesh).unwrap().iter().enumerate() {
            let p = ecef(mesh.vertices[v as usize]);
            assert!(norm(sub(p, h.sphere_center)) <= r + norm(sub(p, decoded[i])) + 1e-6);
        }
    }
    // The sphere of four points around a known centre.
    let sphere = bounding_sphere(&[
        [1.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
    ]);
    assert!(norm(sphere.center) < 1e-12 && (sphere.radius - 1.0).abs() < 1e-12);
}

/// Cesium's horizon test, written from the Horizon-culling article: is a scaled-space point `p`
/// occluded by the unit sphere, seen from `c`?
fn point_occluded(c: [f64; 3], p: [f64; 3]) -> bool {
    let vt = sub(p, c);
    let vt_dot_vc = -dot(vt, c);
    let vh_sq = dot(c, c) - 1.0;
    vt_dot_vc > vh_sq && vt_dot_vc * vt_dot_vc / dot(vt, vt) > vh_sq
}

/// Exactly: does the segment from `c` to `p` pass through the unit ball before reaching `p`?
fn segment_hidden(c: [f64; 3], p: [f64; 3]) -> bool {
    let d = sub(p, c);
    let t = (-dot(c, d) / dot(d, d)).clamp(0.0, 1.0);
    let closest = [c[0] + t * d[0], c[1] + t * d[1], c[2] + t * d[2]];
    dot(closest, closest) < 1.0 - 1e-12
}

/// Checks a tile's horizon occlusion point: outside the (possibly shrunk) unit sphere, and from
/// random cameras near the tile, whenever it is occluded every decoded vertex is hidden.
fn check_horizon_point(mesh: &QmMesh, seed: u64) {
    let bytes = encode(mesh, &QmExtensions::default()).unwrap();
    let tile = decode(&bytes).unwrap();
    let hop = tile.header.horizon_occlusion_point;
    let radii = occluder_radii(f64::from(tile.header.min_height));
    let scale = |p: [f64; 3]| [p[0] / radii[0], p[1] / radii[1], p[2] / radii[2]];
    assert!(norm(hop) > 1.0, "the point {hop:?} is outside the occluder");
    let (w, s, e, n) = bounds(mesh);
    let vertices: Vec<[f64; 3]> = tile
        .positions(w, s, e, n)
        .into_iter()
        .map(|p| scale(ecef(p)))
        .collect();
    // Not absurdly far out: within the magnitude a cap of the tile's angular size needs.
    let cap = (e - w).max(n - s).to_radians();
    assert!(norm(hop) < 1.0 / cap.cos() + 1e-3, "{}", norm(hop));

    let mut rng = Rng(seed);
    let (mut occluded, mut visible) = (0, 0);
    for _ in 0..4000 {
        let lon = rng.range(w - 40.0, e + 40.0);
        let lat = rng.range(s - 40.0, n + 40.0).clamp(-90.0, 90.0);
        let height = 10f64.powf(rng.range(1.0, 7.0));
        let cam = scale(to_ecef(lon, lat, height));
        if !point_occluded(cam, hop) {
            visible += 1;
            continue;
        }
        occluded += 1;
        for (i, &v) in vertices.iter().enumerate() {
            assert!(
                segment_hidden(cam, v),
                "the point is occluded from lon {lon} lat {lat} h {height}, vertex {i} is not"
            );
        }
    }
    assert!(
        occluded > 100 && visible > 100,
        "{occluded} occluded, {visible} visible"
    );
}

#[test]
fn horizon_point_of_flat_tile_hides_every_vertex_it_hides() {
    // Level 7 tiles at height 0: on the ellipsoid itself.
    check_horizon_point(
        &grid([8.4375, 46.40625, 9.84375, 47.8125], 17, 17, |_, _| 0.0),
        1,
    );
    check_horizon_point(
        &grid([-45.0, -1.40625, -43.59375, 0.0], 9, 9, |_, _| 0.0),
        2,
    );
    // Level 3, and with relief.
    check_horizon_point(&grid([0.0, 45.0, 22.5, 67.5], 33, 33, |_, _| 0.0), 3);
    check_horizon_point(&grid(ALPS, 65, 65, sine_terrain), 4);
}

#[test]
fn horizon_point_below_the_ellipsoid_uses_the_shrunk_one() {
    let mesh = grid([35.15625, 30.9375, 36.5625, 32.34375], 20, 30, |lon, _| {
        -430.0 + 200.0 * (lon - 35.15625)
    });
    check_horizon_point(&mesh, 5);
    let radii = occluder_radii(-430.0);
    assert_eq!(radii, [WGS84_A - 430.0, WGS84_A - 430.0, WGS84_B - 430.0]);
}

#[test]
fn horizon_point_of_a_hemisphere_is_nan() {
    // A root tile of the geographic pyramid has no horizon occlusion point.
    let root = grid([-180.0, -90.0, 0.0, 90.0], 9, 9, |_, _| 0.0);
    let tile = decode(&encode(&root, &QmExtensions::default()).unwrap()).unwrap();
    assert!(
        tile.header
            .horizon_occlusion_point
            .iter()
            .all(|c| c.is_nan())
    );
    // A NaN point is never occluded by Cesium's test.
    assert!(!point_occluded([0.0, 0.0, 2.0], [f64::NAN; 3]));
    // Level 1 tiles have one.
    let level1 = grid([-90.0, 0.0, 0.0, 90.0], 9, 9, |_, _| 0.0);
    let tile = decode(&encode(&level1, &QmExtensions::default()).unwrap()).unwrap();
    assert!(
        tile.header
            .horizon_occlusion_point
            .iter()
            .all(|c| c.is_finite())
    );
}

fn angle_deg(a: [f64; 3], b: [f64; 3]) -> f64 {
    (dot(a, b) / (norm(a) * norm(b)))
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}

#[test]
fn oct_normals_round_trip_within_0_7_degrees() {
    let mut dirs = vec![
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
        [1.0, 0.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [1.0, 1.0, 1.0],
        [-1.0, 1.0, -1.0],
        [1e-9, -1e-9, -1.0],
    ];
    // A Fibonacci sphere.
    let count = 50_000;
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    for i in 0..count {
        let z = 1.0 - 2.0 * (f64::from(i) + 0.5) / f64::from(count);
        let r = (1.0 - z * z).sqrt();
        let phi = golden * f64::from(i);
        dirs.push([r * phi.cos(), r * phi.sin(), z]);
    }
    let mut worst: f64 = 0.0;
    for d in dirs {
        let back = oct_decode(oct_encode(d));
        assert!((norm(back) - 1.0).abs() < 1e-12);
        worst = worst.max(angle_deg(d, back));
    }
    // 0.62 for the precise encoding; plain rounding would reach 0.94.
    assert!(worst < 0.7, "worst error {worst} degrees");
    // Bytes as Cesium reads them: 0 is -1, 255 is +1.
    assert!(angle_deg(oct_decode([255, 255]), [0.0, 0.0, -1.0]) < 1e-9);
    assert!(angle_deg(oct_decode([0, 0]), [0.0, 0.0, -1.0]) < 1e-9);
    assert!(angle_deg(oct_decode([255, 128]), [1.0, 0.0, 0.0]) < 0.5);
    assert!(angle_deg(oct_decode([128, 0]), [0.0, -1.0, 0.0]) < 0.5);
    assert!(angle_deg(oct_decode(oct_encode([0.0, 0.0, 1.0])), [0.0, 0.0, 1.0]) < 0.5);
    assert_eq!(oct_encode([0.0, 0.0, 0.0]), oct_encode([0.0, 0.0, 1.0]));
}

#[test]
fn vertex_normals_weigh_triangles_by_area() {
    // Vertex 0 is shared by a triangle of area 2 facing +z and one of area 1 facing +x.
    let p = [
        [0.0, 0.0, 0.0],
        [2.0, 0.0, 0.0],
        [0.0, 2.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 2.0],
        [5.0, 5.0, 5.0],
    ];
    let n = vertex_normals(&p, &[[0, 1, 2], [0, 3, 4]], |_| [0.0, 1.0, 0.0]);
    let k = 1.0 / 20f64.sqrt();
    for (got, want) in n[0].iter().zip([2.0 * k, 0.0, 4.0 * k]) {
        assert!((got - want).abs() < 1e-12);
    }
    assert_eq!(n[1], [0.0, 0.0, 1.0]);
    assert_eq!(n[5], [0.0, 1.0, 0.0], "unused: the fallback");
}

#[test]
fn tile_normals_point_up_and_follow_the_slope() {
    // Flat: every normal within a fraction of a degree of the ellipsoid's.
    let flat = grid([9.0, 47.0, 9.01, 47.01], 11, 11, |_, _| 500.0);
    let (_, tile) = round_trip(
        &flat,
        &QmExtensions {
            normals: true,
            metadata: None,
        },
    );
    let pos = tile.positions(9.0, 47.0, 9.01, 47.01);
    for (p, n) in pos.iter().zip(tile.unit_normals().unwrap()) {
        assert!(angle_deg(n, geodetic_normal(p[0], p[1])) < 1.0);
    }
    // A ramp rising 1 m a metre eastwards: normals 45 degrees from up, leaning west.
    let m_per_deg = WGS84_A * 47f64.to_radians().cos() * std::f64::consts::PI / 180.0;
    let ramp = grid([9.0, 47.0, 9.01, 47.01], 11, 11, |lon, _| {
        (lon - 9.0) * m_per_deg
    });
    let (_, tile) = round_trip(
        &ramp,
        &QmExtensions {
            normals: true,
            metadata: None,
        },
    );
    let east = [-(9f64.to_radians().sin()), 9f64.to_radians().cos(), 0.0];
    for (p, n) in pos.iter().zip(tile.unit_normals().unwrap()) {
        assert!((angle_deg(n, geodetic_normal(p[0], p[1])) - 45.0).abs() < 1.5);
        assert!(dot(n, east) < -0.6);
    }
}
