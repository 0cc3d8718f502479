//! GeoTIFF reader: integer and float samples, the GDAL_NODATA no-data value, and the ground
//! spacing from ModelPixelScale (with ModelTiepoint and the GeoKey model type for geographic
//! grids, whose metre spacing follows from the latitude of the grid's centre on WGS 84).

use super::{DemError, LoadOptions, RawGrid, VoidMask, check_size};
use std::io::Cursor;
use tiff::decoder::{Decoder, DecodingResult, Limits};
use tiff::tags::Tag;

/// GeoKey ModelTypeGeoKey and its value for geographic (lat/lon) models.
const GT_MODEL_TYPE: u16 = 1024;
const MODEL_TYPE_GEOGRAPHIC: u16 = 2;
/// GeoKey GeographicTypeGeoKey and ProjectedCSTypeGeoKey, for the CRS name.
const GEOGRAPHIC_TYPE: u16 = 2048;
const PROJECTED_CS_TYPE: u16 = 3072;

/// Reads a GeoTIFF held in `bytes`; `name` is used in messages.
pub fn read(name: &str, bytes: &[u8], opts: &LoadOptions) -> Result<RawGrid, DemError> {
    let corrupt = |e: tiff::TiffError| DemError::Corrupt {
        path: name.into(),
        kind: "GeoTIFF",
        detail: e.to_string(),
    };
    let mut dec = Decoder::new(Cursor::new(bytes)).map_err(corrupt)?;
    let (w, h) = dec.dimensions().map_err(corrupt)?;
    check_size(name, w, h, opts)?;
    dec = dec.with_limits(Limits::unlimited());
    let nodata: Option<f64> = dec
        .get_tag_ascii_string(Tag::GdalNodata)
        .ok()
        .and_then(|s| s.trim().trim_end_matches('\0').parse().ok());
    let keys = dec.get_tag_u16_vec(Tag::GeoKeyDirectoryTag).ok();
    let scale = dec.get_tag_f64_vec(Tag::ModelPixelScaleTag).ok();
    let tie = dec.get_tag_f64_vec(Tag::ModelTiepointTag).ok();
    let image = dec.read_image().map_err(corrupt)?;
    let n = w as usize * h as usize;
    let heights: Vec<f32> = match image {
        DecodingResult::I16(v) => v.into_iter().map(f32::from).collect(),
        DecodingResult::U16(v) => v.into_iter().map(f32::from).collect(),
        DecodingResult::I32(v) => v.into_iter().map(|x| x as f32).collect(),
        DecodingResult::F32(v) => v,
        DecodingResult::F64(v) => v.into_iter().map(|x| x as f32).collect(),
        other => {
            return Err(DemError::Unsupported {
                path: name.into(),
                detail: format!(
                    "{} samples; Relief reads int16, uint16, int32, float32 and float64",
                    kind(&other)
                ),
            });
        }
    };
    if heights.len() != n {
        return Err(DemError::Unsupported {
            path: name.into(),
            detail: format!(
                "{} samples for {w}x{h} pixels: only single-band grids are read",
                heights.len()
            ),
        });
    }
    let mut voids = VoidMask::new(n);
    let nan_is_void = nodata.is_some_and(f64::is_nan);
    if let Some(nd) = nodata.filter(|v| !v.is_nan()) {
        let nd = nd as f32;
        for (i, v) in heights.iter().enumerate() {
            if *v == nd {
                voids.set(i);
            }
        }
    }
    let geographic = keys
        .as_deref()
        .and_then(|k| geokey(k, GT_MODEL_TYPE))
        .map(|t| t == MODEL_TYPE_GEOGRAPHIC);
    let crs = keys.as_deref().and_then(|k| {
        geokey(k, PROJECTED_CS_TYPE)
            .or_else(|| geokey(k, GEOGRAPHIC_TYPE))
            .filter(|&c| c != 0 && c != 32767)
            .map(|c| format!("EPSG:{c}"))
    });
    let spacing = scale.and_then(|s| {
        let (sx, sy) = (*s.first()?, *s.get(1)?);
        // Without a model type, tiny pixel sizes within a degree-like range mean degrees.
        let degrees = geographic.unwrap_or(sx < 0.1 && sy < 0.1);
        if degrees {
            let top = tie.as_ref().and_then(|t| t.get(4).copied())?;
            let lat = top - sy * h as f64 / 2.0;
            let (mx, my) = metres_per_degree(lat);
            Some((sx * mx, sy * my))
        } else {
            Some((sx, sy))
        }
    });
    Ok(RawGrid {
        width: w,
        height: h,
        heights,
        voids,
        spacing,
        crs,
        nan_is_void,
    })
}

/// The value of GeoKey `id` stored inline in the key directory, if present.
fn geokey(keys: &[u16], id: u16) -> Option<u16> {
    let count = *keys.get(3)? as usize;
    (0..count)
        .filter_map(|i| keys.get(4 + 4 * i..8 + 4 * i))
        .find(|k| k[0] == id && k[1] == 0)
        .map(|k| k[3])
}

/// Metres per degree of longitude and of latitude at latitude `lat` (degrees) on WGS 84.
pub fn metres_per_degree(lat: f64) -> (f64, f64) {
    let p = lat.to_radians();
    let lon = 111_412.84 * p.cos() - 93.5 * (3.0 * p).cos() + 0.118 * (5.0 * p).cos();
    let lat_m =
        111_132.92 - 559.82 * (2.0 * p).cos() + 1.175 * (4.0 * p).cos() - 0.0023 * (6.0 * p).cos();
    (lon, lat_m)
}

fn kind(r: &DecodingResult) -> &'static str {
    match r {
        DecodingResult::U8(_) => "uint8",
        DecodingResult::U32(_) => "uint32",
        DecodingResult::U64(_) => "uint64",
        DecodingResult::I8(_) => "int8",
        DecodingResult::I64(_) => "int64",
        DecodingResult::F16(_) => "float16",
        _ => "these",
    }
}
