//! GeoTIFF reader: int16, uint16, int32, float32 and float64 single-band grids (striped or tiled,
//! Cloud-Optimized or not; deflate, LZW, zstd or any other compression the `tiff` crate decodes;
//! predictors 2 and 3), the GDAL_NODATA no-data value, and the ground spacing from the GeoTIFF
//! tags. The samples are read chunk by chunk through [`super::cog::TiffWindows`], from a file
//! or from a URL by HTTP range requests ([`read_url`]); the tags are read here ([`GeoTags`]).
//!
//! Spacing:
//! - ModelPixelScaleTag (33550) gives the pixel size; ModelTransformationTag (34264) is read
//!   instead when there is no pixel scale (the length of its column vectors).
//! - The grid is geographic (sizes in degrees) when GeoKeyDirectoryTag (34735) says
//!   GTModelTypeGeoKey = 2. Without a model type, a pixel size under 0.1 whose bounds lie within
//!   longitude and latitude ranges is taken as degrees. Otherwise the sizes are metres.
//! - A geographic grid's metre spacing comes from the latitude of its centre (the origin from
//!   ModelTiepointTag 33922, or the transformation): metres per degree along the meridian and
//!   along the parallel on the WGS 84 ellipsoid, from its radii of curvature
//!   ([`metres_per_degree`]). Across a 1-degree tile this varies by about 1% in x; Relief uses
//!   one spacing per grid.

use super::cog::{Source, TiffWindows};
use super::http_range::RangeReader;
use super::{DemError, LoadOptions, RawGrid, VoidMask};
use crate::geo::Georef;
use crate::geo::ellipsoid::metres_per_degree;
use std::io::{Read, Seek};
use tiff::decoder::{Decoder, DecodingResult};
use tiff::tags::Tag;

/// GeoKey GTModelTypeGeoKey and its value for geographic (lat/lon) models.
const GT_MODEL_TYPE: u16 = 1024;
const MODEL_TYPE_GEOGRAPHIC: u16 = 2;
/// GeoKey GeographicTypeGeoKey and ProjectedCSTypeGeoKey, for the CRS name.
const GEOGRAPHIC_TYPE: u16 = 2048;
const PROJECTED_CS_TYPE: u16 = 3072;
/// GeoKey GTRasterTypeGeoKey and its value for pixels that are points (the default, 1, makes
/// them areas, so that the tie point is a pixel's corner).
const GT_RASTER_TYPE: u16 = 1025;
const RASTER_PIXEL_IS_POINT: u16 = 2;
/// The GeoKey value meaning "user-defined", which names no EPSG code.
const USER_DEFINED: u16 = 32767;

/// Reads a GeoTIFF from `reader`; `name` is used in messages. The grid is read chunk by chunk
/// ([`TiffWindows`]), one window over the whole image.
pub fn read<R: Source>(name: &str, reader: R, opts: &LoadOptions) -> Result<RawGrid, DemError> {
    let mut tiff = TiffWindows::open(name, reader, opts)?;
    let (w, h) = (tiff.width(), tiff.height());
    let mut heights = vec![0.0f32; w as usize * h as usize];
    tiff.read_window(0, 0, w, h, &mut heights)?;
    let nodata = tiff.nodata();
    let mut voids = VoidMask::new(heights.len());
    let nan_is_void = nodata.is_some_and(f64::is_nan);
    if let Some(nd) = nodata.filter(|v| !v.is_nan()) {
        // Samples were widened to f32 exactly as the no-data value is narrowed here.
        let nd = nd as f32;
        for (i, v) in heights.iter().enumerate() {
            if *v == nd {
                voids.set(i);
            }
        }
    }
    Ok(RawGrid {
        width: w,
        height: h,
        heights,
        voids,
        spacing: tiff.spacing(),
        crs: tiff.crs(),
        georef: tiff.georef(),
        nan_is_void,
        io: tiff.io(),
    })
}

/// Reads the GeoTIFF at the `http://` or `https://` URL `url` by HTTP range requests
/// ([`RangeReader`]): a Cloud-Optimized GeoTIFF costs its directory and its tiles, nothing
/// else is fetched twice.
pub fn read_url(url: &str, opts: &LoadOptions) -> Result<RawGrid, DemError> {
    let mut reader = RangeReader::open(url)?;
    let mut head = [0u8; 4];
    let n = reader.read(&mut head).map_err(|e| source_error(url, e))?;
    reader
        .seek(std::io::SeekFrom::Start(0))
        .map_err(|e| source_error(url, e))?;
    let tiff = [*b"II*\0", *b"MM\0*", *b"II+\0", *b"MM\0+"];
    if !tiff.iter().any(|t| head[..n] == t[..]) {
        return Err(DemError::Unsupported {
            path: reader.shown_url().into(),
            detail: format!(
                "a URL is read as a GeoTIFF, and this file does not start like one (its first \
                 bytes are {:?})",
                String::from_utf8_lossy(&head[..n])
            ),
        });
    }
    read(url, reader, opts)
}

/// The error `e` of a source read as a [`DemError`]: the source's own where it gave one (a
/// [`RangeReader`]'s HTTP errors travel inside `std::io::Error`), else an I/O error.
fn source_error(name: &str, e: std::io::Error) -> DemError {
    match take_dem_error(e) {
        Ok(d) => d,
        Err(source) => DemError::Io {
            path: name.into(),
            source,
        },
    }
}

/// The [`DemError`] inside `e`, if a source put one there; `e` otherwise.
fn take_dem_error(e: std::io::Error) -> Result<DemError, std::io::Error> {
    if !e.get_ref().is_some_and(|r| r.is::<DemError>()) {
        return Err(e);
    }
    match e.into_inner() {
        Some(inner) => inner
            .downcast::<DemError>()
            .map(|d| *d)
            .map_err(std::io::Error::other),
        None => Err(std::io::Error::other("unknown I/O error")),
    }
}

/// The decoder's error as a [`DemError`]: a source's own error (HTTP) as it is, features the
/// decoder lacks as [`DemError::Unsupported`], the rest [`DemError::Corrupt`], in plain words
/// where they help.
pub(super) fn corrupt(name: &str, e: tiff::TiffError) -> DemError {
    use tiff::TiffError;
    let e = match e {
        TiffError::IoError(io) => match take_dem_error(io) {
            Ok(d) => return d,
            Err(io) => TiffError::IoError(io),
        },
        e => e,
    };
    let detail = match &e {
        TiffError::UnsupportedError(u) => {
            return DemError::Unsupported {
                path: name.into(),
                detail: u.to_string(),
            };
        }
        TiffError::IoError(io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            "the file ends before its data does".to_string()
        }
        TiffError::LimitsExceeded => {
            "its data is larger than --max-samples allows for its size".to_string()
        }
        _ => e.to_string(),
    };
    DemError::Corrupt {
        path: name.into(),
        kind: "GeoTIFF",
        detail,
    }
}

/// The GeoTIFF tags that place the grid on the ground.
pub(super) struct GeoTags {
    /// GeoKeyDirectoryTag: model type and CRS codes.
    keys: Option<Vec<u16>>,
    /// ModelPixelScaleTag: pixel size (x, y, z) in model units.
    scale: Option<Vec<f64>>,
    /// ModelTiepointTag: (i, j, k, x, y, z) raster point to model point, for the origin.
    tie: Option<Vec<f64>>,
    /// ModelTransformationTag: a 4x4 row-major raster-to-model matrix, the alternative to the
    /// two tags above.
    matrix: Option<Vec<f64>>,
}

impl GeoTags {
    /// The tags of the decoder's current image; absent or unreadable ones are `None`.
    pub(super) fn read<R: Read + Seek>(dec: &mut Decoder<R>) -> GeoTags {
        GeoTags {
            keys: dec.get_tag_u16_vec(Tag::GeoKeyDirectoryTag).ok(),
            scale: dec.get_tag_f64_vec(Tag::ModelPixelScaleTag).ok(),
            tie: dec.get_tag_f64_vec(Tag::ModelTiepointTag).ok(),
            matrix: dec.get_tag_f64_vec(Tag::ModelTransformationTag).ok(),
        }
    }

    /// The value of GeoKey `id` stored inline in the key directory, if present.
    fn key(&self, id: u16) -> Option<u16> {
        let keys = self.keys.as_deref()?;
        let count = *keys.get(3)? as usize;
        (0..count)
            .filter_map(|i| keys.get(4 + 4 * i..8 + 4 * i))
            .find(|k| k[0] == id && k[1] == 0)
            .map(|k| k[3])
    }

    /// `EPSG:n` from the projected or geographic CRS key, if it names one.
    pub(super) fn crs(&self) -> Option<String> {
        self.key(PROJECTED_CS_TYPE)
            .or_else(|| self.key(GEOGRAPHIC_TYPE))
            .filter(|&c| c != 0 && c != USER_DEFINED)
            .map(|c| format!("EPSG:{c}"))
    }

    /// Where the samples lie, when the file names an EPSG CRS and places the grid north-up
    /// without rotation; `None` otherwise (the terrain then serves no standard formats).
    pub(super) fn georef(&self) -> Option<Georef> {
        let epsg = self.crs()?.strip_prefix("EPSG:")?.parse().ok()?;
        if let Some(m) = self.matrix.as_deref().filter(|_| self.scale.is_none()) {
            // Rotated, sheared or south-up grids are not regular in their CRS's axes.
            if m.len() < 16 || m[1] != 0.0 || m[4] != 0.0 || m[5] >= 0.0 || m[0] <= 0.0 {
                return None;
            }
        }
        let Affine {
            size: (sx, sy),
            origin: Some((x, y)),
        } = self.affine()?
        else {
            return None;
        };
        // A pixel that is an area has its sample at its centre, half a pixel in from the
        // corner the tie point names.
        let half = if self.key(GT_RASTER_TYPE) == Some(RASTER_PIXEL_IS_POINT) {
            0.0
        } else {
            0.5
        };
        Some(Georef {
            epsg,
            first: [x + half * sx, y - half * sy],
            step: [sx, sy],
        })
    }

    /// Pixel size and origin from ModelPixelScale and ModelTiepoint, or else from
    /// ModelTransformation.
    fn affine(&self) -> Option<Affine> {
        if let Some(s) = self.scale.as_deref() {
            let size = (s.first()?.abs(), s.get(1)?.abs());
            let origin = self.tie.as_deref().and_then(|t| {
                let (i, j, x, y) = (*t.first()?, *t.get(1)?, *t.get(3)?, *t.get(4)?);
                // Rows go south: y decreases by the pixel size per row.
                Some((x - i * size.0, y + j * size.1))
            });
            return Some(Affine { size, origin });
        }
        let m = self.matrix.as_deref().filter(|m| m.len() >= 16)?;
        Some(Affine {
            size: (m[0].hypot(m[4]), m[1].hypot(m[5])),
            origin: Some((m[3], m[7])),
        })
    }

    /// Ground spacing in metres, or why there is none.
    pub(super) fn spacing(&self, w: u32, h: u32) -> Result<(f64, f64), String> {
        let Some(Affine {
            size: (sx, sy),
            origin,
        }) = self.affine()
        else {
            return Err("the file has no ModelPixelScale or ModelTransformation tag".into());
        };
        let geographic = match self.key(GT_MODEL_TYPE) {
            Some(t) => t == MODEL_TYPE_GEOGRAPHIC,
            // No model type: degrees if the pixels are tiny and the bounds fit the globe.
            None => {
                sx < 0.1
                    && sy < 0.1
                    && origin.is_some_and(|(x, y)| {
                        let (x1, y1) = (x + sx * w as f64, y - sy * h as f64);
                        x >= -180.0 && x1 <= 360.0 && y <= 90.0 && y1 >= -90.0
                    })
            }
        };
        if !geographic {
            return Ok((sx, sy));
        }
        let Some((_, top)) = origin else {
            return Err(
                "a geographic grid without a ModelTiepoint, so its latitude is unknown".into(),
            );
        };
        let centre = (top - sy * h as f64 / 2.0).clamp(-90.0, 90.0);
        let (mx, my) = metres_per_degree(centre);
        Ok((sx * mx, sy * my))
    }
}

/// Where the raster lies in model space.
struct Affine {
    /// Pixel size (x, y) in model units (degrees or metres).
    size: (f64, f64),
    /// Model coordinates of the raster's (0, 0) corner, for the latitude, if known.
    origin: Option<(f64, f64)>,
}

/// A sample type's name for messages.
pub(super) fn kind(r: &DecodingResult) -> &'static str {
    match r {
        DecodingResult::U8(_) => "uint8",
        DecodingResult::U16(_) => "uint16",
        DecodingResult::U32(_) => "uint32",
        DecodingResult::U64(_) => "uint64",
        DecodingResult::I8(_) => "int8",
        DecodingResult::I16(_) => "int16",
        DecodingResult::I32(_) => "int32",
        DecodingResult::I64(_) => "int64",
        DecodingResult::F16(_) => "float16",
        DecodingResult::F32(_) => "float32",
        DecodingResult::F64(_) => "float64",
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::{GeoTags, METRES_10, tiff_bytes, write_tmp};
    use super::super::{DemError, LoadOptions, load};
    use super::metres_per_degree;
    use tiff::encoder::colortype;

    fn close(a: f64, b: f64, rel: f64) -> bool {
        (a - b).abs() <= rel * b.abs()
    }

    #[test]
    fn wgs84_metres_per_degree() {
        // Reference values of the WGS 84 ellipsoid.
        for (lat, lon_m, lat_m) in [
            (0.0, 111_319.49, 110_574.28),
            (45.0, 78_846.81, 111_131.75),
            (60.0, 55_799.98, 111_412.24),
            (89.999, 1.95, 111_693.98),
        ] {
            let (x, y) = metres_per_degree(lat);
            assert!((x - lon_m).abs() < 0.05, "lon at {lat}: {x}");
            assert!((y - lat_m).abs() < 0.05, "lat at {lat}: {y}");
        }
    }

    #[test]
    fn sample_types() {
        let dir = tempfile::tempdir().unwrap();
        let t = tiff_bytes::<colortype::Gray16>(2, 2, &[0, 1, 65535, 7], &METRES_10);
        let t = load(&write_tmp(&dir, "u16.tif", &t), &LoadOptions::default());
        assert!(matches!(t, Err(DemError::Absurd { value: 65535.0, .. })));
        let t = tiff_bytes::<colortype::Gray16>(2, 2, &[0, 1, 2000, 7], &METRES_10);
        let d = load(&write_tmp(&dir, "u16.tif", &t), &LoadOptions::default()).unwrap();
        assert_eq!(d.heights, vec![0.0, 1.0, 2000.0, 7.0]);
        let t = tiff_bytes::<colortype::GrayI16>(2, 2, &[-400, 1, 2, 3], &METRES_10);
        let d = load(&write_tmp(&dir, "i16.tif", &t), &LoadOptions::default()).unwrap();
        assert_eq!(d.heights, vec![-400.0, 1.0, 2.0, 3.0]);
        let t = tiff_bytes::<colortype::GrayI32>(2, 2, &[-5, 1, 2, 19_999], &METRES_10);
        let d = load(&write_tmp(&dir, "i32.tif", &t), &LoadOptions::default()).unwrap();
        assert_eq!(d.heights, vec![-5.0, 1.0, 2.0, 19_999.0]);
        let t = tiff_bytes::<colortype::Gray64Float>(2, 2, &[0.25, 1.0, 2.0, 3.0], &METRES_10);
        let d = load(&write_tmp(&dir, "f64.tif", &t), &LoadOptions::default()).unwrap();
        assert_eq!(d.heights, vec![0.25, 1.0, 2.0, 3.0]);
        // Unsupported: 8-bit samples, colour.
        let t = tiff_bytes::<colortype::Gray8>(2, 2, &[1, 2, 3, 4], &METRES_10);
        let e = load(&write_tmp(&dir, "u8.tif", &t), &LoadOptions::default()).unwrap_err();
        assert!(e.to_string().contains("uint8 samples"), "{e}");
        let t = tiff_bytes::<colortype::RGB16>(2, 2, &[1; 12], &METRES_10);
        let e = load(&write_tmp(&dir, "rgb.tif", &t), &LoadOptions::default()).unwrap_err();
        assert!(matches!(e, DemError::Unsupported { .. }), "{e}");
        assert!(e.to_string().contains("single-band"), "{e}");
    }

    #[test]
    fn spacing_from_the_geo_tags() {
        let dir = tempfile::tempdir().unwrap();
        let data = [100.0f32; 16];
        let spacing = |tags: &GeoTags| {
            let t = tiff_bytes::<colortype::Gray32Float>(4, 4, &data, tags);
            load(&write_tmp(&dir, "g.tif", &t), &LoadOptions::default())
                .map(|d| (d.spacing_x, d.spacing_y))
        };
        let deg = 1.0 / 1200.0;
        let at_60n = metres_per_degree(60.0 - 2.0 * deg);
        let geographic = [1u16, 1, 0, 1, 1024, 0, 1, 2];
        // Geographic by model type, with the tiepoint at raster (2, 2).
        let tags = GeoTags {
            scale: Some([deg, deg, 0.0]),
            tie: Some([2.0, 2.0, 0.0, 10.0, 60.0 - 2.0 * deg, 0.0]),
            keys: Some(&geographic),
            ..GeoTags::default()
        };
        let (x, y) = spacing(&tags).unwrap();
        assert!(
            close(x, at_60n.0 * deg, 1e-9) && close(y, at_60n.1 * deg, 1e-9),
            "{x} {y}"
        );
        // No model type: tiny pixels within the globe are degrees...
        let tags = GeoTags { keys: None, ..tags };
        let (x, y) = spacing(&tags).unwrap();
        assert!(
            close(x, at_60n.0 * deg, 1e-9) && close(y, at_60n.1 * deg, 1e-9),
            "{x} {y}"
        );
        // ...but 5 cm pixels at UTM coordinates are metres.
        let tags = GeoTags {
            scale: Some([0.05, 0.05, 0.0]),
            tie: Some([0.0, 0.0, 0.0, 500_000.0, 4_000_000.0, 0.0]),
            ..GeoTags::default()
        };
        assert_eq!(spacing(&tags).unwrap(), (0.05, 0.05));
        // A projected model type keeps metres whatever the size.
        let projected = [1u16, 1, 0, 2, 1024, 0, 1, 1, 3072, 0, 1, 32633];
        let tags = GeoTags {
            scale: Some([0.001, 0.002, 0.0]),
            tie: Some([0.0, 0.0, 0.0, 10.0, 20.0, 0.0]),
            keys: Some(&projected),
            ..GeoTags::default()
        };
        assert_eq!(spacing(&tags).unwrap(), (0.001, 0.002));
        // ModelTransformation instead of pixel scale.
        let mut m = [0.0; 16];
        (m[0], m[3], m[5], m[7], m[15]) = (25.0, 300_000.0, -30.0, 5_000_000.0, 1.0);
        let tags = GeoTags {
            matrix: Some(m),
            ..GeoTags::default()
        };
        assert_eq!(spacing(&tags).unwrap(), (25.0, 30.0));
        // Geographic without a tiepoint, and no tags at all: errors that say what to do.
        let tags = GeoTags {
            scale: Some([deg, deg, 0.0]),
            keys: Some(&geographic),
            ..GeoTags::default()
        };
        let e = spacing(&tags).unwrap_err().to_string();
        assert!(
            e.contains("ModelTiepoint") && e.contains("--spacing-x"),
            "{e}"
        );
        let e = spacing(&GeoTags::default()).unwrap_err().to_string();
        assert!(
            e.contains("ModelPixelScale") && e.contains("--spacing-y"),
            "{e}"
        );
        let t = tiff_bytes::<colortype::Gray32Float>(4, 4, &data, &GeoTags::default());
        let opts = LoadOptions {
            spacing_x: Some(5.0),
            spacing_y: Some(6.0),
            ..LoadOptions::default()
        };
        let d = load(&write_tmp(&dir, "plain.tif", &t), &opts).unwrap();
        assert_eq!((d.spacing_x, d.spacing_y, d.crs), (5.0, 6.0, None));
    }
}
