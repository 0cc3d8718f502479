//! The two global tile schemes of the standard formats.
//!
//! - [`Scheme::Geographic`]: Cesium's geographic tiling of WGS 84 longitude/latitude (EPSG:4326)
//!   for quantized-mesh: two root tiles side by side at level 0, each level splitting a tile in
//!   four, `y` counted from the south (TMS).
//! - [`Scheme::Mercator`]: the Web Mercator (EPSG:3857) XYZ tiling of MapLibre and every web
//!   map: one root tile, `y` counted from the north, latitudes to about +-85.05.

use super::georef::LonLatBounds;
use super::mercator::{HALF_WORLD, lat_of, y_of};
use std::f64::consts::PI;

/// The deepest level either scheme serves: a Web Mercator tile at 24 is 2.4 m wide at the
/// equator, finer than any DEM Relief reads; deeper requests are refused.
pub const MAX_LEVEL: u8 = 24;

/// A global tile scheme.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scheme {
    /// Cesium's geographic scheme: 2 x 1 roots, TMS `y` (0 south).
    Geographic,
    /// Web Mercator XYZ: 1 root, `y` 0 north.
    Mercator,
}

/// A tile in a scheme: level, column, row.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct TileXyz {
    /// Level (zoom).
    pub z: u8,
    /// Column from the west.
    pub x: u32,
    /// Row: from the south ([`Scheme::Geographic`]) or from the north ([`Scheme::Mercator`]).
    pub y: u32,
}

/// An inclusive range of tiles of one level, in the field names of Cesium's `layer.json`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "camelCase")]
pub struct TileRange {
    /// Westmost column.
    pub start_x: u32,
    /// First row.
    pub start_y: u32,
    /// Eastmost column.
    pub end_x: u32,
    /// Last row.
    pub end_y: u32,
}

impl TileRange {
    /// Whether the range holds column `x`, row `y`.
    pub fn contains(&self, x: u32, y: u32) -> bool {
        (self.start_x..=self.end_x).contains(&x) && (self.start_y..=self.end_y).contains(&y)
    }
}

/// Web Mercator's latitude limit, where the square map ends (about 85.05 degrees).
pub fn mercator_max_lat() -> f64 {
    lat_of(HALF_WORLD)
}

impl Scheme {
    /// Tiles across and down at level `z`.
    pub fn dims(self, z: u8) -> (u32, u32) {
        match self {
            Scheme::Geographic => (2 << z, 1 << z),
            Scheme::Mercator => (1 << z, 1 << z),
        }
    }

    /// Whether `t` exists in the scheme.
    pub fn contains(self, t: TileXyz) -> bool {
        let (nx, ny) = self.dims(t.z.min(MAX_LEVEL));
        t.z <= MAX_LEVEL && t.x < nx && t.y < ny
    }

    /// The longitude of the west edge of column `x` at level `z` (may be fractional).
    fn lon(self, z: u8, x: f64) -> f64 {
        x / self.dims(z).0 as f64 * 360.0 - 180.0
    }

    /// The latitude of row edge `y` at level `z` (may be fractional): for the geographic
    /// scheme, counted from the south; for Mercator, from the north.
    fn lat(self, z: u8, y: f64) -> f64 {
        let n = self.dims(z).1 as f64;
        match self {
            Scheme::Geographic => y / n * 180.0 - 90.0,
            Scheme::Mercator => lat_of(HALF_WORLD * (1.0 - 2.0 * y / n)),
        }
    }

    /// The longitude and latitude of the point at fraction (`fx` east, `fy` down from the
    /// north edge) across tile `t`; Mercator tiles are uniform in projected metres, so their
    /// latitudes are not linear in `fy`.
    pub fn point(self, t: TileXyz, fx: f64, fy: f64) -> [f64; 2] {
        let lon = self.lon(t.z, t.x as f64 + fx);
        let lat = match self {
            Scheme::Geographic => self.lat(t.z, t.y as f64 + 1.0 - fy),
            Scheme::Mercator => self.lat(t.z, t.y as f64 + fy),
        };
        [lon, lat]
    }

    /// The tile's longitude/latitude box.
    pub fn bounds(self, t: TileXyz) -> LonLatBounds {
        let [west, north] = self.point(t, 0.0, 0.0);
        let [east, south] = self.point(t, 1.0, 1.0);
        LonLatBounds {
            west,
            south,
            east,
            north,
        }
    }

    /// The tiles of level `z` that overlap `b` with a positive area, if any.
    pub fn range(self, b: &LonLatBounds, z: u8) -> Option<TileRange> {
        let (nx, ny) = self.dims(z);
        // Fractional column, and row counted as the scheme counts rows.
        let col = |lon: f64| (lon + 180.0) / 360.0 * nx as f64;
        let row = |lat: f64| match self {
            Scheme::Geographic => (lat + 90.0) / 180.0 * ny as f64,
            Scheme::Mercator => {
                let y = y_of(lat.clamp(-mercator_max_lat(), mercator_max_lat()));
                (1.0 - y / HALF_WORLD) / 2.0 * ny as f64
            }
        };
        let span = |a: f64, b: f64, n: u32| {
            let (lo, hi) = (a.min(b).max(0.0), a.max(b).min(n as f64));
            let (first, last) = (lo.floor(), hi.ceil() - 1.0);
            (first <= last && lo < hi).then_some((first as u32, last as u32))
        };
        let (start_x, end_x) = span(col(b.west), col(b.east), nx)?;
        let (start_y, end_y) = span(row(b.south), row(b.north), ny)?;
        Some(TileRange {
            start_x,
            start_y,
            end_x,
            end_y,
        })
    }

    /// The deepest level worth serving for ground sampled every `step_deg` degrees of
    /// longitude: the first whose tiles of `samples` points a side are at least as fine,
    /// clamped to [`MAX_LEVEL`].
    pub fn level_for(self, step_deg: f64, samples: u32) -> u8 {
        let per_tile = |z: u8| 360.0 / self.dims(z).0 as f64 / (samples.max(2) - 1) as f64;
        (0..=MAX_LEVEL)
            .find(|&z| per_tile(z) <= step_deg * 1.000_001)
            .unwrap_or(MAX_LEVEL)
    }
}

/// Cesium's estimate of a terrain tile's geometric error at level 0 of the geographic scheme,
/// metres: `TerrainProvider.getEstimatedLevelZeroGeometricErrorForAHeightmap` for the WGS 84
/// ellipsoid, 65 samples a side and two root tiles. Each level halves it.
pub fn cesium_level_error(z: u8) -> f64 {
    let level0 = super::ellipsoid::WGS84_A * 2.0 * PI * 0.25 / (65.0 * 2.0);
    level0 / f64::from(1u32 << z.min(31))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn geographic_tiles_have_two_roots_and_count_rows_from_the_south() {
        let g = Scheme::Geographic;
        assert_eq!(g.dims(0), (2, 1));
        let west = g.bounds(TileXyz { z: 0, x: 0, y: 0 });
        assert_eq!(west.to_array(), [-180.0, -90.0, 0.0, 90.0]);
        let ne = g.bounds(TileXyz { z: 1, x: 3, y: 1 });
        assert_eq!(ne.to_array(), [90.0, 0.0, 180.0, 90.0]);
        // Mt Fuji's degree square at level 8: 0.703125-degree tiles.
        let fuji = LonLatBounds {
            west: 138.0,
            south: 35.0,
            east: 139.0,
            north: 36.0,
        };
        let r = g.range(&fuji, 8).unwrap();
        assert_eq!((r.start_x, r.end_x), (452, 453));
        assert_eq!((r.start_y, r.end_y), (177, 179));
        for (x, y) in [(452, 177), (453, 179)] {
            assert!(g.bounds(TileXyz { z: 8, x, y }).overlaps(&fuji));
        }
        assert!(
            !g.bounds(TileXyz {
                z: 8,
                x: 454,
                y: 178
            })
            .overlaps(&fuji)
        );
        assert!(
            !g.bounds(TileXyz {
                z: 8,
                x: 453,
                y: 180
            })
            .overlaps(&fuji)
        );
    }

    #[test]
    fn mercator_tiles_match_the_xyz_convention() {
        let m = Scheme::Mercator;
        let root = m.bounds(TileXyz { z: 0, x: 0, y: 0 });
        assert!((root.north - 85.051_128_779_806_59).abs() < 1e-9);
        assert!((root.south + root.north).abs() < 1e-9);
        // Zoom 1: tile (0, 0) is the north-west quarter.
        let nw = m.bounds(TileXyz { z: 1, x: 0, y: 0 });
        assert_eq!((nw.west, nw.east, nw.south), (-180.0, 0.0, 0.0));
        // Tokyo (139.69 E, 35.69 N) at zoom 10 is tile 909/403, the well-known answer.
        let p = LonLatBounds {
            west: 139.69,
            south: 35.69,
            east: 139.69 + 1e-6,
            north: 35.69 + 1e-6,
        };
        let r = m.range(&p, 10).unwrap();
        assert_eq!(
            (r.start_x, r.start_y, r.end_x, r.end_y),
            (909, 403, 909, 403)
        );
        // Latitude is not linear across a Mercator tile: the middle row lies north of the mean.
        let t = TileXyz { z: 2, x: 1, y: 0 };
        let mid = m.point(t, 0.5, 0.5)[1];
        let b = m.bounds(t);
        assert!(mid < (b.north + b.south) / 2.0 + 20.0 && mid > (b.north + b.south) / 2.0);
    }

    #[test]
    fn ranges_outside_the_scheme_or_touching_an_edge_are_empty() {
        let g = Scheme::Geographic;
        let edge = LonLatBounds {
            west: 0.0,
            south: 0.0,
            east: 0.0,
            north: 0.0,
        };
        assert!(g.range(&edge, 3).is_none());
        assert!(!g.contains(TileXyz { z: 0, x: 2, y: 0 }));
        assert!(!g.contains(TileXyz { z: 30, x: 0, y: 0 }));
        assert!(Scheme::Mercator.contains(TileXyz { z: 3, x: 7, y: 7 }));
    }

    #[test]
    fn levels_and_errors_follow_cesium() {
        assert!((cesium_level_error(0) - 77_067.34).abs() < 0.1);
        assert!((cesium_level_error(12) - 77_067.34 / 4096.0).abs() < 1e-3);
        // 3" SRTM (1/1200 degree) in 65-sample tiles: level 12 tiles have 0.00069-degree steps.
        assert_eq!(Scheme::Geographic.level_for(1.0 / 1200.0, 65), 12);
        assert_eq!(Scheme::Mercator.level_for(1.0 / 1200.0, 257), 11);
    }
}
