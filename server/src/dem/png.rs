//! 16-bit grayscale PNG reader: `metres = offset + value * scale`, one value meaning no data,
//! ground spacing given by the caller (a PNG has no geo tags).

use super::{DemError, LoadOptions, RawGrid, VoidMask, check_size};
use image::{ImageDecoder, ImageFormat, codecs::png::PngDecoder};
use std::io::Cursor;

/// Reads a PNG held in `bytes`; `name` is used in messages.
pub fn read(name: &str, bytes: &[u8], opts: &LoadOptions) -> Result<RawGrid, DemError> {
    let corrupt = |e: image::ImageError| DemError::Corrupt {
        path: name.into(),
        kind: "PNG",
        detail: e.to_string(),
    };
    if image::guess_format(bytes).ok() != Some(ImageFormat::Png) {
        return Err(DemError::Corrupt {
            path: name.into(),
            kind: "PNG",
            detail: "missing PNG signature".into(),
        });
    }
    let dec = PngDecoder::new(Cursor::new(bytes)).map_err(corrupt)?;
    let (w, h) = dec.dimensions();
    check_size(name, w, h, opts)?;
    if dec.color_type() != image::ColorType::L16 {
        return Err(DemError::Unsupported {
            path: name.into(),
            detail: format!(
                "{:?} pixels; heights must be a 16-bit grayscale PNG",
                dec.color_type()
            ),
        });
    }
    let mut buf = vec![0u8; dec.total_bytes() as usize];
    dec.read_image(&mut buf).map_err(corrupt)?;
    let n = w as usize * h as usize;
    let mut voids = VoidMask::new(n);
    let p = opts.png;
    let heights = buf
        .chunks_exact(2)
        .enumerate()
        .map(|(i, b)| {
            // The image crate hands out 16-bit samples in native byte order.
            let v = u16::from_ne_bytes([b[0], b[1]]);
            if p.nodata_value == Some(v) {
                voids.set(i);
            }
            (p.offset + v as f64 * p.scale) as f32
        })
        .collect();
    Ok(RawGrid {
        width: w,
        height: h,
        heights,
        voids,
        spacing: None,
        crs: None,
        nan_is_void: false,
    })
}
