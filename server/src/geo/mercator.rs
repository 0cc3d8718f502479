//! Web Mercator (EPSG:3857) and its XYZ tile scheme, the scheme of web map tiles: terrain-RGB
//! and Terrarium PNGs are read (and served) in it.
//!
//! The projection is spherical (radius [`WGS84_A`]) over WGS 84 longitude/latitude: x runs east
//! from -[`HALF_WORLD`] at 180 W to +[`HALF_WORLD`] at 180 E, y north over the same range, which
//! cuts the map at about 85.05 degrees north and south. At zoom `z` the square map is 2^z x 2^z
//! tiles; tile (x, y) is column x from the west and row y from the **north** (y = 0 at the top,
//! the "XYZ" or "slippy map" scheme; TMS counts rows from the south).
//!
//! A tile's pixels are areas: pixel (0, 0) covers the tile's north-west corner, and its sample
//! lies at the pixel's centre, half a pixel in ([`TileId::pixel_georef`]).

use super::ellipsoid::WGS84_A;
use super::georef::{GeoError, Georef};

/// The EPSG code of Web Mercator.
pub const EPSG_WEB_MERCATOR: u32 = 3857;
/// Half the width of the Web Mercator map in metres: pi times the WGS 84 semi-major axis.
pub const HALF_WORLD: f64 = 20_037_508.342_789_244;
/// The deepest zoom accepted: 2^30 tiles a side (millimetre pixels), far past any real pyramid.
pub const MAX_ZOOM: u32 = 30;

/// The latitude in degrees of Web Mercator northing `y` (metres).
pub fn lat_of(y: f64) -> f64 {
    (y / WGS84_A).sinh().atan().to_degrees()
}

/// The Web Mercator northing (metres) of latitude `lat` (degrees).
pub fn y_of(lat: f64) -> f64 {
    WGS84_A * lat.to_radians().tan().asinh()
}

/// A tile of the XYZ scheme: zoom `z`, column `x` from the west, row `y` from the north.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct TileId {
    /// Zoom level: the map is 2^z tiles a side.
    pub z: u32,
    /// Column, 0 at 180 W.
    pub x: u32,
    /// Row, 0 at the north edge of the map.
    pub y: u32,
}

impl TileId {
    /// The tile, or why it is not on the map (`x` or `y` not below 2^z, `z` over [`MAX_ZOOM`]).
    pub fn new(z: u32, x: u32, y: u32) -> Result<TileId, GeoError> {
        if z > MAX_ZOOM || x >= 1 << z || y >= 1 << z {
            return Err(GeoError::Tile(z, x, y));
        }
        Ok(TileId { z, x, y })
    }

    /// The tile's width in Web Mercator metres.
    pub fn size_m(&self) -> f64 {
        2.0 * HALF_WORLD / (1u64 << self.z) as f64
    }

    /// The Web Mercator coordinates of the tile's north-west corner.
    pub fn north_west(&self) -> [f64; 2] {
        let s = self.size_m();
        [
            -HALF_WORLD + self.x as f64 * s,
            HALF_WORLD - self.y as f64 * s,
        ]
    }

    /// Where the samples of a `tile_px` x `tile_px` image of this tile lie: each pixel an area,
    /// its sample at its centre, so the first sample is half a pixel in from the north-west
    /// corner and the step is 2 * [`HALF_WORLD`] / (2^z * `tile_px`) metres.
    pub fn pixel_georef(&self, tile_px: u32) -> Georef {
        let step = self.size_m() / tile_px as f64;
        let [x0, y0] = self.north_west();
        Georef {
            epsg: EPSG_WEB_MERCATOR,
            first: [x0 + step / 2.0, y0 - step / 2.0],
            step: [step, step],
        }
    }

    /// The tile a path names: `.../Z/X/Y.png` (the usual folder layout) or a file named
    /// `Z-X-Y.png`; `None` if it names none or one not on the map.
    pub fn from_path(path: &str) -> Option<TileId> {
        let p = std::path::Path::new(path);
        let stem = p.file_stem()?.to_str()?;
        let parts: Vec<&str> = stem.split('-').collect();
        if parts.len() == 3 {
            let n: Vec<u32> = parts
                .iter()
                .map(|p| p.parse().ok())
                .collect::<Option<_>>()?;
            return TileId::new(n[0], n[1], n[2]).ok();
        }
        let y: u32 = stem.parse().ok()?;
        let x_dir = p.parent()?;
        let x: u32 = x_dir.file_name()?.to_str()?.parse().ok()?;
        let z: u32 = x_dir.parent()?.file_name()?.to_str()?.parse().ok()?;
        TileId::new(z, x, y).ok()
    }
}

impl std::fmt::Display for TileId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}/{}", self.z, self.x, self.y)
    }
}

impl std::str::FromStr for TileId {
    type Err = String;

    /// Parses `Z/X/Y`.
    fn from_str(s: &str) -> Result<TileId, String> {
        let bad = || format!("expected Z/X/Y, whole numbers as in 12/3639/1612; got {s:?}");
        let v: Vec<u32> = s
            .split('/')
            .map(|p| p.trim().parse().map_err(|_| bad()))
            .collect::<Result<_, _>>()?;
        let [z, x, y] = v[..] else {
            return Err(bad());
        };
        TileId::new(z, x, y).map_err(|e| e.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geo::GeoTransform;

    /// The usual slippy-map formulas, independent of proj4rs: the longitude and latitude of
    /// tile corner (x, y) at zoom z.
    fn corner(z: u32, x: f64, y: f64) -> [f64; 2] {
        let n = (1u64 << z) as f64;
        let lat = (std::f64::consts::PI * (1.0 - 2.0 * y / n))
            .sinh()
            .atan()
            .to_degrees();
        [x / n * 360.0 - 180.0, lat]
    }

    #[test]
    fn tiles_lie_where_the_slippy_map_formulas_put_them() {
        for (z, x, y) in [(0, 0, 0), (3, 2, 5), (12, 3639, 1612), (15, 29_103, 12_903)] {
            let t = TileId::new(z, x, y).unwrap();
            let px = 256;
            let g = t.pixel_georef(px);
            let tr = GeoTransform::new(&g).unwrap();
            // Pixel corners are half a sample out from the samples.
            for (c, r) in [(-0.5, -0.5), (px as f64 - 0.5, px as f64 - 0.5)] {
                let [lon, lat] = tr.lonlat(c, r).unwrap();
                let [elon, elat] = corner(z, x as f64 + (c + 0.5) / px as f64, {
                    y as f64 + (r + 0.5) / px as f64
                });
                // 180 E and 180 W are one meridian.
                let dlon = (lon - elon + 540.0).rem_euclid(360.0) - 180.0;
                assert!(dlon.abs() < 1e-9, "{t}: {lon} {elon}");
                assert!((lat - elat).abs() < 1e-9, "{t}: {lat} {elat}");
            }
            let [_, lat] = tr.lonlat(0.0, 0.0).unwrap();
            assert!((lat_of(g.first[1]) - lat).abs() < 1e-9);
            assert!((y_of(lat) - g.first[1]).abs() < 1e-6);
        }
    }

    #[test]
    fn tile_ids_parse_from_flags_and_paths() {
        assert_eq!(
            "12/3639/1612".parse(),
            Ok(TileId {
                z: 12,
                x: 3639,
                y: 1612
            })
        );
        for bad in ["12/3639", "1/2/3/4", "a/b/c", "2/4/0", "31/0/0", ""] {
            assert!(bad.parse::<TileId>().is_err(), "{bad}");
        }
        let t = |z, x, y| Some(TileId { z, x, y });
        assert_eq!(
            TileId::from_path("tiles/12/3639/1612.png"),
            t(12, 3639, 1612)
        );
        assert_eq!(
            TileId::from_path("/a/b/12-3639-1612.png"),
            t(12, 3639, 1612)
        );
        assert_eq!(TileId::from_path("3/2/5.png"), t(3, 2, 5));
        assert_eq!(TileId::from_path("heights.png"), None);
        assert_eq!(TileId::from_path("x/2/5.png"), None);
        // Off the map at its zoom.
        assert_eq!(TileId::from_path("2/4/0.png"), None);
        assert_eq!(TileId::from_path("2-1-9.png"), None);
    }
}
