//! WGS84 geometry for the quantized-mesh header: geodetic to ECEF, the bounding sphere and the
//! horizon occlusion point.
//!
//! The horizon occlusion point follows Cesium's `EllipsoidalOccluder`
//! (`computeHorizonCullingPointFromVerticesPossiblyUnderEllipsoid`): in the space where the
//! ellipsoid is the unit sphere, the point lies along the direction to the bounding sphere's
//! centre, just far enough out that whenever it is below the horizon every vertex is too. When
//! the minimum height is negative the ellipsoid is first shrunk by it, as Cesium does when it
//! tests the point (`isScaledSpacePointVisiblePossiblyUnderEllipsoid` with the tile's minimum
//! height); for tiles at or above the ellipsoid this is the plain computation.

pub use crate::geo::ellipsoid::{WGS84_A, WGS84_B, WGS84_E2, to_ecef};

/// The outward unit normal of the ellipsoid at a geodetic position (the "up" of that place).
pub fn geodetic_normal(lon_deg: f64, lat_deg: f64) -> [f64; 3] {
    let (sin_lon, cos_lon) = lon_deg.to_radians().sin_cos();
    let (sin_lat, cos_lat) = lat_deg.to_radians().sin_cos();
    [cos_lat * cos_lon, cos_lat * sin_lon, sin_lat]
}

/// A sphere in ECEF.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sphere {
    /// Centre, metres.
    pub center: [f64; 3],
    /// Radius, metres.
    pub radius: f64,
}

pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub(crate) fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

fn max_distance(points: &[[f64; 3]], center: [f64; 3]) -> f64 {
    points
        .iter()
        .map(|&p| norm(sub(p, center)))
        .fold(0.0, f64::max)
}

/// A sphere holding every point: the smaller of the box-centred sphere and Ritter's sphere, as
/// Cesium's `BoundingSphere.fromPoints` chooses. The radius is the largest distance from the
/// chosen centre, measured again at the end, so every point is inside. An empty slice gives a
/// zero sphere at the origin.
pub fn bounding_sphere(points: &[[f64; 3]]) -> Sphere {
    let Some(&first) = points.first() else {
        return Sphere {
            center: [0.0; 3],
            radius: 0.0,
        };
    };
    // The extreme points along each axis, for the box and for Ritter's first guess.
    let mut lo = [first; 3];
    let mut hi = [first; 3];
    for &p in points {
        for axis in 0..3 {
            if p[axis] < lo[axis][axis] {
                lo[axis] = p;
            }
            if p[axis] > hi[axis][axis] {
                hi[axis] = p;
            }
        }
    }
    let box_center = [
        0.5 * (lo[0][0] + hi[0][0]),
        0.5 * (lo[1][1] + hi[1][1]),
        0.5 * (lo[2][2] + hi[2][2]),
    ];
    let naive = Sphere {
        center: box_center,
        radius: max_distance(points, box_center),
    };

    // Ritter: start from the widest of the three axis-extreme pairs, grow to take in every point.
    let widest = (0..3)
        .max_by(|&a, &b| {
            let da = norm(sub(hi[a], lo[a]));
            let db = norm(sub(hi[b], lo[b]));
            da.total_cmp(&db)
        })
        .unwrap_or(0);
    let (a, b) = (lo[widest], hi[widest]);
    let mut center = [
        0.5 * (a[0] + b[0]),
        0.5 * (a[1] + b[1]),
        0.5 * (a[2] + b[2]),
    ];
    let mut radius = 0.5 * norm(sub(b, a));
    for &p in points {
        let d = sub(p, center);
        let dist = norm(d);
        if dist > radius {
            let grown = 0.5 * (radius + dist);
            let shift = (dist - grown) / dist;
            center = [
                center[0] + shift * d[0],
                center[1] + shift * d[1],
                center[2] + shift * d[2],
            ];
            radius = grown;
        }
    }
    let ritter = Sphere {
        center,
        radius: max_distance(points, center),
    };
    if ritter.radius < naive.radius {
        ritter
    } else {
        naive
    }
}

/// The radii of the ellipsoid the horizon occlusion point is computed against: WGS84, shrunk by
/// `min_height` where that is negative (and smaller than the polar radius), as Cesium shrinks it.
pub fn occluder_radii(min_height: f64) -> [f64; 3] {
    if min_height < 0.0 && -min_height < WGS84_B {
        [
            WGS84_A + min_height,
            WGS84_A + min_height,
            WGS84_B + min_height,
        ]
    } else {
        [WGS84_A, WGS84_A, WGS84_B]
    }
}

/// Cesium's horizon occlusion point of `points` (ECEF) along `direction` (need not be unit),
/// expressed in the space scaled by [`occluder_radii`]`(min_height)`, in which the occluder is
/// the unit sphere.
///
/// `None` where Cesium's computation gives none: no points, a point facing away from
/// `direction` by 90 degrees or more (a tile spanning a hemisphere, as the two root tiles of the
/// geographic pyramid do), or a non-finite result.
pub fn horizon_occlusion_point(
    points: &[[f64; 3]],
    direction: [f64; 3],
    min_height: f64,
) -> Option<[f64; 3]> {
    let radii = occluder_radii(min_height);
    let scale = |p: [f64; 3]| [p[0] / radii[0], p[1] / radii[1], p[2] / radii[2]];
    let d = scale(direction);
    let d_len = norm(d);
    let d = [d[0] / d_len, d[1] / d_len, d[2] / d_len];
    let mut magnitude: f64 = 0.0;
    for &p in points {
        let s = scale(p);
        let mag_sq = dot(s, s);
        let mag = mag_sq.sqrt();
        let dir = [s[0] / mag, s[1] / mag, s[2] / mag];
        // Points below the ellipsoid count as on it.
        let mag_sq = mag_sq.max(1.0);
        let mag = mag.max(1.0);
        let cos_alpha = dot(dir, d);
        let sin_alpha = norm(cross(dir, d));
        let cos_beta = 1.0 / mag;
        let sin_beta = (mag_sq - 1.0).sqrt() * cos_beta;
        let candidate = 1.0 / (cos_alpha * cos_beta - sin_alpha * sin_beta);
        // Negative (facing away) or NaN: no point exists.
        if candidate.is_nan() || candidate < 0.0 {
            return None;
        }
        magnitude = magnitude.max(candidate);
    }
    if magnitude > 0.0 && magnitude.is_finite() {
        Some([d[0] * magnitude, d[1] * magnitude, d[2] * magnitude])
    } else {
        None
    }
}
