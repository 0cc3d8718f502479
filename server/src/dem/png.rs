//! 16-bit grayscale PNG reader: `metres = offset + value * scale`, one value meaning no data
//! ([`super::PngOptions`]). A PNG has no geo tags, so the ground spacing must be given
//! (`--spacing-x`, `--spacing-y`); [`super::finish`] says so when it is missing.
//!
//! Only 16-bit grayscale is read: 8 bits (256 levels) are too coarse for terrain, and a colour PNG
//! is an image of terrain, not heights, unless it is a terrain-RGB or Terrarium tile: those are
//! read by [`super::rgb_tile`] when `--encoding` says which.

use super::{DemError, LoadOptions, RawGrid, VoidMask, check_size};
use image::{ColorType, ImageDecoder, codecs::png::PngDecoder};
use std::io::{BufRead, Seek};

/// Reads a PNG from `reader`; `name` is used in messages.
pub fn read<R: BufRead + Seek>(
    name: &str,
    reader: R,
    opts: &LoadOptions,
) -> Result<RawGrid, DemError> {
    let p = opts.png;
    if !(p.scale.is_finite() && p.offset.is_finite()) || p.scale == 0.0 {
        return Err(DemError::BadOptions {
            input: name.into(),
            detail: format!(
                "PNG scale {} and offset {} must be finite, and the scale not 0",
                p.scale, p.offset
            ),
        });
    }
    let corrupt = |e: image::ImageError| DemError::Corrupt {
        path: name.into(),
        kind: "PNG",
        detail: e.to_string(),
    };
    let dec = PngDecoder::new(reader).map_err(corrupt)?;
    let (w, h) = dec.dimensions();
    check_size(name, w, h, opts)?;
    if dec.color_type() != ColorType::L16 {
        let tile = match dec.color_type() {
            ColorType::Rgb8 | ColorType::Rgba8 => {
                "; if it is a terrain-RGB or Terrarium tile, say which with --encoding \
                 terrain-rgb or --encoding terrarium"
            }
            _ => "",
        };
        return Err(DemError::Unsupported {
            path: name.into(),
            detail: format!(
                "{:?} pixels; heights must be a 16-bit grayscale PNG{tile}",
                dec.color_type()
            ),
        });
    }
    let mut buf = vec![0u8; dec.total_bytes() as usize];
    dec.read_image(&mut buf).map_err(corrupt)?;
    let n = w as usize * h as usize;
    let mut voids = VoidMask::new(n);
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
        spacing: Err("a PNG carries no ground spacing".into()),
        crs: None,
        georef: None,
        nan_is_void: false,
        io: Default::default(),
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::super::{DemError, LoadOptions, PngOptions, load};
    use image::{ImageBuffer, ImageFormat, Luma, Rgb};

    /// Encodes a 16-bit grayscale PNG.
    pub(crate) fn png16(w: u32, h: u32, v: &[u16]) -> Vec<u8> {
        let img: ImageBuffer<Luma<u16>, Vec<u16>> =
            ImageBuffer::from_raw(w, h, v.to_vec()).expect("buffer size");
        let mut out = std::io::Cursor::new(Vec::new());
        img.write_to(&mut out, ImageFormat::Png).expect("encode");
        out.into_inner()
    }

    fn with_spacing(png: PngOptions, x: f64, y: f64) -> LoadOptions {
        LoadOptions {
            spacing_x: Some(x),
            spacing_y: Some(y),
            png,
            ..LoadOptions::default()
        }
    }

    #[test]
    fn scale_offset_and_nodata_value_apply() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("h.png");
        std::fs::write(&p, png16(3, 2, &[0, 1, 2, 1000, 30000, 7])).unwrap();
        let png = PngOptions {
            scale: 0.5,
            offset: -100.0,
            nodata_value: Some(7),
        };
        let d = load(p.to_str().unwrap(), &with_spacing(png, 2.0, 3.0)).unwrap();
        assert_eq!(&d.heights[..5], &[-100.0, -99.5, -99.0, 400.0, 14900.0]);
        assert_eq!(d.voids.iter().collect::<Vec<_>>(), vec![5]);

        // No no-data value: 0 is a height like any other.
        let png = PngOptions {
            nodata_value: None,
            ..PngOptions::default()
        };
        let p0 = dir.path().join("zero.png");
        std::fs::write(&p0, png16(2, 2, &[0, 0, 5, 5])).unwrap();
        let d = load(p0.to_str().unwrap(), &with_spacing(png, 1.0, 1.0)).unwrap();
        assert_eq!(
            (d.voids.count(), d.heights.clone()),
            (0, vec![0.0, 0.0, 5.0, 5.0])
        );
        // The default no-data value 0 makes the top row void and fills it from below.
        let d = load(
            p0.to_str().unwrap(),
            &with_spacing(PngOptions::default(), 1.0, 1.0),
        )
        .unwrap();
        assert_eq!((d.voids.count(), d.heights), (2, vec![5.0; 4]));
    }

    #[test]
    fn png_errors_name_the_problem() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("h.png");
        std::fs::write(&p, png16(4, 4, &[100; 16])).unwrap();
        let p = p.to_str().unwrap();
        // No spacing.
        let e = load(p, &LoadOptions::default()).unwrap_err();
        assert!(matches!(e, DemError::Spacing { .. }), "{e}");
        assert!(e.to_string().contains("--spacing-x"), "{e}");
        // Non-finite scale.
        let bad = PngOptions {
            scale: f64::NAN,
            ..PngOptions::default()
        };
        let e = load(p, &with_spacing(bad, 1.0, 1.0)).unwrap_err();
        assert!(matches!(e, DemError::BadOptions { .. }), "{e}");
        // Colour PNG.
        let rgb: ImageBuffer<Rgb<u8>, Vec<u8>> = ImageBuffer::from_raw(2, 2, vec![9; 12]).unwrap();
        let c = dir.path().join("rgb.png");
        rgb.save_with_format(&c, ImageFormat::Png).unwrap();
        let e = load(
            c.to_str().unwrap(),
            &with_spacing(PngOptions::default(), 1.0, 1.0),
        );
        let e = e.unwrap_err();
        assert!(matches!(e, DemError::Unsupported { .. }), "{e}");
        assert!(e.to_string().contains("16-bit grayscale"), "{e}");
    }
}
