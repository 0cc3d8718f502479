//! The WGS 84 ellipsoid: metres per degree and Earth-centred, Earth-fixed (ECEF) coordinates.

/// WGS 84 semi-major axis, metres.
pub const WGS84_A: f64 = 6_378_137.0;
/// WGS 84 first eccentricity squared.
pub const WGS84_E2: f64 = 6.694_379_990_141_316e-3;
/// WGS 84 semi-minor axis, metres.
pub const WGS84_B: f64 = 6_356_752.314_245_179;

/// Metres per degree of longitude and of latitude at latitude `lat` (degrees) on WGS 84: the
/// parallel's radius N cos(lat) and the meridian's radius of curvature M, times pi/180, where
/// N = a / sqrt(1 - e^2 sin^2 lat) and M = a (1 - e^2) / (1 - e^2 sin^2 lat)^(3/2).
pub fn metres_per_degree(lat: f64) -> (f64, f64) {
    let p = lat.to_radians();
    let w2 = 1.0 - WGS84_E2 * p.sin() * p.sin();
    let n = WGS84_A / w2.sqrt();
    let m = WGS84_A * (1.0 - WGS84_E2) / (w2 * w2.sqrt());
    let rad = std::f64::consts::PI / 180.0;
    (n * p.cos() * rad, m * rad)
}

/// ECEF position (metres) of longitude `lon`, latitude `lat` (degrees) and height `h` (metres
/// above the ellipsoid).
pub fn to_ecef(lon: f64, lat: f64, h: f64) -> [f64; 3] {
    let (lo, la) = (lon.to_radians(), lat.to_radians());
    let n = WGS84_A / (1.0 - WGS84_E2 * la.sin() * la.sin()).sqrt();
    [
        (n + h) * la.cos() * lo.cos(),
        (n + h) * la.cos() * lo.sin(),
        (n * (1.0 - WGS84_E2) + h) * la.sin(),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ecef_of_known_points() {
        let close = |a: [f64; 3], b: [f64; 3]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-6);
        assert!(close(to_ecef(0.0, 0.0, 0.0), [WGS84_A, 0.0, 0.0]));
        assert!(close(to_ecef(90.0, 0.0, 10.0), [0.0, WGS84_A + 10.0, 0.0]));
        let pole = to_ecef(0.0, 90.0, 0.0);
        assert!(pole[0].abs() < 1e-6 && (pole[2] - WGS84_B).abs() < 1e-6);
    }
}
