//! A DEM's georeference: its CRS and where its sample grid lies in it, and the conversion
//! between sample positions and WGS 84 longitude/latitude.
//!
//! Samples are points: [`Georef::first`] is the position of sample (0, 0) itself (a GeoTIFF
//! whose pixels are areas has its tie point half a pixel further out; the reader accounts for
//! it). Columns go east by `step[0]`, rows go south by `step[1]`, in the CRS's units: degrees
//! for a geographic CRS, metres (or the CRS's unit) for a projected one.
//!
//! [`GeoTransform`] does the conversions. A grid in EPSG:4326 needs none. Any other EPSG code is
//! looked up in `proj4rs`'s built-in definitions, and positions go through PROJ.4's inverse and
//! forward projections with a datum shift to WGS 84 where the definition has one.

use crate::geo::ellipsoid::metres_per_degree;
use proj4rs::proj::Proj;
use serde::{Deserialize, Serialize};

/// The EPSG code of WGS 84 longitude/latitude.
pub const EPSG_WGS84: u32 = 4326;

/// Where a DEM's sample grid lies: a CRS and an axis-aligned regular grid in it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Georef {
    /// The EPSG code of the CRS the grid is regular in (4326 for WGS 84 longitude/latitude).
    pub epsg: u32,
    /// CRS coordinates (x east, y north) of sample (0, 0), the north-west corner sample.
    pub first: [f64; 2],
    /// CRS units between columns (eastward) and between rows (southward); both positive.
    pub step: [f64; 2],
}

impl Georef {
    /// A WGS 84 longitude/latitude grid whose north-west sample lies at `origin` (lon, lat in
    /// degrees) with `spacing` ground metres between columns and rows, at the origin's latitude:
    /// how `--origin` places a synthetic terrain or a PNG.
    pub fn around(origin: (f64, f64), spacing: (f64, f64)) -> Result<Georef, GeoError> {
        let (lon, lat) = origin;
        if !((-180.0..=180.0).contains(&lon) && (-85.0..=85.0).contains(&lat)) {
            return Err(GeoError::Origin(lon, lat));
        }
        let (mx, my) = metres_per_degree(lat);
        Ok(Georef {
            epsg: EPSG_WGS84,
            first: [lon, lat],
            step: [spacing.0 / mx, spacing.1 / my],
        })
    }

    /// CRS coordinates of the (fractional) sample position `col`, `row`.
    pub fn model(&self, col: f64, row: f64) -> [f64; 2] {
        [
            self.first[0] + col * self.step[0],
            self.first[1] - row * self.step[1],
        ]
    }

    /// The fractional sample position of CRS coordinates `x`, `y`.
    pub fn sample(&self, x: f64, y: f64) -> [f64; 2] {
        [
            (x - self.first[0]) / self.step[0],
            (self.first[1] - y) / self.step[1],
        ]
    }

    /// The CRS as `EPSG:n`.
    pub fn crs(&self) -> String {
        format!("EPSG:{}", self.epsg)
    }

    /// Ground metres between columns and between rows of a grid of `rows` rows, at the latitude
    /// of its centre, where the CRS's units are not metres on the ground: WGS 84 degrees
    /// ([`metres_per_degree`] on the ellipsoid) and Web Mercator (its metres times the cosine of
    /// the latitude, the sphere's scale factor). `None` for other CRSs, whose units are taken
    /// to be ground metres by their readers.
    pub fn ground_spacing(&self, rows: u32) -> Option<(f64, f64)> {
        let centre_y = self.first[1] - self.step[1] * rows.saturating_sub(1) as f64 / 2.0;
        match self.epsg {
            EPSG_WGS84 => {
                let (mx, my) = metres_per_degree(centre_y.clamp(-90.0, 90.0));
                Some((self.step[0] * mx, self.step[1] * my))
            }
            super::mercator::EPSG_WEB_MERCATOR => {
                let k = super::mercator::lat_of(centre_y).to_radians().cos();
                Some((self.step[0] * k, self.step[1] * k))
            }
            _ => None,
        }
    }
}

/// A longitude/latitude box in degrees (WGS 84).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LonLatBounds {
    /// Westmost longitude.
    pub west: f64,
    /// Southmost latitude.
    pub south: f64,
    /// Eastmost longitude.
    pub east: f64,
    /// Northmost latitude.
    pub north: f64,
}

impl LonLatBounds {
    /// Whether the two boxes overlap with a positive area.
    pub fn overlaps(&self, o: &LonLatBounds) -> bool {
        self.west < o.east && o.west < self.east && self.south < o.north && o.south < self.north
    }

    /// As `[west, south, east, north]`, the order of TileJSON and GeoJSON.
    pub fn to_array(self) -> [f64; 4] {
        [self.west, self.south, self.east, self.north]
    }
}

/// Why a georeference cannot be used.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum GeoError {
    /// An EPSG code `proj4rs` has no definition for.
    #[error("EPSG:{0} is not a CRS Relief knows (proj4rs has no definition for it)")]
    UnknownCrs(u32),
    /// A projection failed for a position.
    #[error("EPSG:{epsg}: {detail}")]
    Projection {
        /// The CRS.
        epsg: u32,
        /// What PROJ.4 said.
        detail: String,
    },
    /// A grid whose step is not positive and finite.
    #[error("grid step {0} x {1} must be positive and finite")]
    Step(f64, f64),
    /// An origin off the globe (or too near a pole for a local grid).
    #[error("origin {0}, {1} must be a longitude in -180..180 and a latitude in -85..85")]
    Origin(f64, f64),
    /// A web map tile that is not on the map.
    #[error(
        "tile {0}/{1}/{2} is not on the map: at zoom Z, X and Y must be below 2^Z, and Z at most {max}",
        max = super::mercator::MAX_ZOOM
    )]
    Tile(u32, u32, u32),
}

/// Converts between a grid's sample positions and WGS 84 longitude/latitude.
#[derive(Clone)]
pub struct GeoTransform {
    georef: Georef,
    /// The grid's CRS and WGS 84, for a CRS other than EPSG:4326.
    proj: Option<(Proj, Proj)>,
}

impl std::fmt::Debug for GeoTransform {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GeoTransform")
            .field("georef", &self.georef)
            .finish_non_exhaustive()
    }
}

impl GeoTransform {
    /// The transform of `georef`, or why its CRS is unusable.
    pub fn new(georef: &Georef) -> Result<GeoTransform, GeoError> {
        let [sx, sy] = georef.step;
        if !(sx.is_finite() && sy.is_finite() && sx > 0.0 && sy > 0.0) {
            return Err(GeoError::Step(sx, sy));
        }
        let proj = if georef.epsg == EPSG_WGS84 {
            None
        } else {
            let code = u16::try_from(georef.epsg).map_err(|_| GeoError::UnknownCrs(georef.epsg))?;
            let src = Proj::from_epsg_code(code).map_err(|_| GeoError::UnknownCrs(georef.epsg))?;
            let wgs = Proj::from_epsg_code(EPSG_WGS84 as u16)
                .map_err(|_| GeoError::UnknownCrs(EPSG_WGS84))?;
            Some((src, wgs))
        };
        Ok(GeoTransform {
            georef: georef.clone(),
            proj,
        })
    }

    /// The georeference.
    pub fn georef(&self) -> &Georef {
        &self.georef
    }

    /// Longitude and latitude (degrees) of the fractional sample position `col`, `row`.
    pub fn lonlat(&self, col: f64, row: f64) -> Result<[f64; 2], GeoError> {
        let [x, y] = self.georef.model(col, row);
        let Some((src, wgs)) = &self.proj else {
            return Ok([x, y]);
        };
        let mut p = if src.is_latlong() {
            (x.to_radians(), y.to_radians(), 0.0)
        } else {
            (x, y, 0.0)
        };
        proj4rs::transform::transform(src, wgs, &mut p).map_err(|e| self.failed(e))?;
        Ok([p.0.to_degrees(), p.1.to_degrees()])
    }

    /// The fractional sample position of longitude `lon`, latitude `lat` (degrees).
    pub fn sample(&self, lon: f64, lat: f64) -> Result<[f64; 2], GeoError> {
        let Some((src, wgs)) = &self.proj else {
            return Ok(self.georef.sample(lon, lat));
        };
        let mut p = (lon.to_radians(), lat.to_radians(), 0.0);
        proj4rs::transform::transform(wgs, src, &mut p).map_err(|e| self.failed(e))?;
        let (x, y) = if src.is_latlong() {
            (p.0.to_degrees(), p.1.to_degrees())
        } else {
            (p.0, p.1)
        };
        Ok(self.georef.sample(x, y))
    }

    /// The longitude/latitude box of a `width` x `height` grid's samples. A projected grid's
    /// edges are curves in longitude/latitude, so the box is taken over 64 points along each
    /// edge.
    pub fn bounds(&self, width: u32, height: u32) -> Result<LonLatBounds, GeoError> {
        let (w, h) = ((width.max(1) - 1) as f64, (height.max(1) - 1) as f64);
        let mut b = LonLatBounds {
            west: f64::INFINITY,
            south: f64::INFINITY,
            east: f64::NEG_INFINITY,
            north: f64::NEG_INFINITY,
        };
        let steps = if self.proj.is_some() { 64 } else { 1 };
        for k in 0..=steps {
            let t = k as f64 / steps as f64;
            for (c, r) in [(t * w, 0.0), (t * w, h), (0.0, t * h), (w, t * h)] {
                let [lon, lat] = self.lonlat(c, r)?;
                b.west = b.west.min(lon);
                b.east = b.east.max(lon);
                b.south = b.south.min(lat);
                b.north = b.north.max(lat);
            }
        }
        Ok(b)
    }

    fn failed(&self, e: proj4rs::errors::Error) -> GeoError {
        GeoError::Projection {
            epsg: self.georef.epsg,
            detail: e.to_string(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// bigtujunga_30m's grid (`../shared/dem/bigtujunga_30m/bigtujunga_30m.json`): UTM 11N,
    /// 30 m pixels, bounds_xy of the pixel areas.
    fn tujunga() -> Georef {
        Georef {
            epsg: 32611,
            first: [376_313.655_454_263_5 + 15.0, 3_807_917.827_628_375_5 - 15.0],
            step: [30.0, 30.0],
        }
    }

    #[test]
    fn wgs84_grids_convert_without_projection() {
        let g = Georef {
            epsg: 4326,
            first: [138.0, 36.0],
            step: [1.0 / 1200.0, 1.0 / 1200.0],
        };
        let t = GeoTransform::new(&g).unwrap();
        assert_eq!(t.lonlat(1200.0, 1200.0).unwrap(), [139.0, 35.0]);
        let s = t.sample(138.5, 35.25).unwrap();
        assert!((s[0] - 600.0).abs() < 1e-9 && (s[1] - 900.0).abs() < 1e-9);
        let b = t.bounds(1201, 1201).unwrap();
        assert_eq!(b.to_array(), [138.0, 35.0, 139.0, 36.0]);
    }

    #[test]
    fn utm_grids_round_trip_through_longitude_and_latitude() {
        let t = GeoTransform::new(&tujunga()).unwrap();
        // The San Gabriel Mountains, north of Los Angeles.
        let [lon, lat] = t.lonlat(0.0, 0.0).unwrap();
        assert!(
            (-118.4..-118.3).contains(&lon) && (34.3..34.5).contains(&lat),
            "{lon} {lat}"
        );
        for (c, r) in [(0.0, 0.0), (1196.0, 642.0), (600.5, 321.25)] {
            let [lon, lat] = t.lonlat(c, r).unwrap();
            let s = t.sample(lon, lat).unwrap();
            assert!((s[0] - c).abs() < 1e-6 && (s[1] - r).abs() < 1e-6, "{s:?}");
        }
        let b = t.bounds(1197, 643).unwrap();
        assert!(b.west < -118.3 && b.east > -118.0 && b.south < 34.24 && b.north > 34.4);
        // 30 m east is about 0.000326 degrees of longitude at 34.3 N.
        let [a, _] = t.lonlat(100.0, 100.0).unwrap();
        let [c, _] = t.lonlat(101.0, 100.0).unwrap();
        assert!(((c - a) - 30.0 / metres_per_degree(34.3).0).abs() < 2e-6);
    }

    #[test]
    fn unknown_codes_and_bad_grids_are_refused() {
        let mut g = tujunga();
        g.epsg = 1;
        assert_eq!(GeoTransform::new(&g).unwrap_err(), GeoError::UnknownCrs(1));
        g.epsg = 99_999_999;
        assert!(GeoTransform::new(&g).is_err());
        let mut g = tujunga();
        g.step = [0.0, 30.0];
        assert!(matches!(GeoTransform::new(&g), Err(GeoError::Step(..))));
        assert!(Georef::around((200.0, 0.0), (10.0, 10.0)).is_err());
        assert!(Georef::around((0.0, f64::NAN), (10.0, 10.0)).is_err());
    }

    #[test]
    fn origins_place_metre_grids_in_degrees() {
        let g = Georef::around((8.5, 47.4), (10.0, 10.0)).unwrap();
        let (mx, my) = metres_per_degree(47.4);
        assert!((g.step[0] * mx - 10.0).abs() < 1e-9 && (g.step[1] * my - 10.0).abs() < 1e-9);
        assert_eq!(g.model(0.0, 0.0), [8.5, 47.4]);
    }
}
