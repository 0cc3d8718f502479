//! Heights as the colours of 8-bit RGB PNG tiles: Mapbox terrain-RGB and Mapzen/AWS Terrarium,
//! the two encodings MapLibre GL's `raster-dem` sources read.
//!
//! Each pixel's red, green and blue bytes make a 24-bit code `c = R * 65536 + G * 256 + B`:
//!
//! | encoding | height (m) | step | range (m) |
//! |---|---|---|---|
//! | [`Encoding::TerrainRgb`] (`terrain-rgb`, MapLibre's `mapbox`) | `-10000 + c * 0.1` | 0.1 m | -10000 ..= 1667721.5 |
//! | [`Encoding::Terrarium`] (`terrarium`) | `R * 256 + G + B / 256 - 32768` = `c / 256 - 32768` | 1/256 m | -32768 ..= 32767.996 |
//!
//! # Rounding
//!
//! [`Encoding::encode`] rounds to the **nearest** code, so [`Encoding::decode`] gives back every
//! height in range within half a step (exactly, in real numbers: the only further error is
//! the f32 the decoded height is stored in, under 0.001 m below 8192 m). Heights outside the
//! range clamp to its ends; NaN encodes as 0 m.
//!
//! The known failure of `rio-rgbify` and of many hand-written encoders is float arithmetic
//! followed by truncation (a `floor`, or an integer cast of a fraction times 256 when the code
//! is split into bytes) where rounding is due. Since 0.1 has no exact binary form,
//! `(h + 10000) / 0.1` lands just below the whole number for many heights that lie exactly on a
//! step (0.7 m as f32 gives 100006.99..), and truncating drops them one code: neighbouring
//! pixels of a smooth slope then jump by two steps or none, a visible terracing in hillshades.
//! Here the code is `round((h + 10000) * 10)` in f64 (the product's rounding is far below the
//! half step), the bytes are split from the whole-number code by shifts, and the decode divides
//! the whole-number offset `c - 100000` by 10, the most accurate height the code stands for.
//! The tests check, for every code of the terrain range, that decoding and encoding again gives
//! the same code, and that every decimal height `k / 10` m lands on its own code.
//!
//! # Voids and places outside the terrain
//!
//! The codecs carry heights only. Relief's store has no voids left: the DEM reader filled them
//! harmonically (smoothly from their surroundings, `crate::dem::fill`) before the store was
//! built, so tiles made from the store show the filled heights. Where a tile reaches past the
//! DEM's extent Relief writes 0 m, the sea-level convention of terrain tiles. When reading tiles
//! as a DEM, a fully transparent pixel (alpha 0, in an RGBA tile) means no data: [`read_png`]
//! decodes it as NaN and the DEM reader makes it a void, filled like any other.

use image::codecs::png::{CompressionType, FilterType, PngDecoder, PngEncoder};
use image::{ColorType, ExtendedColorType, ImageDecoder, ImageEncoder};
use std::io::{BufRead, Cursor, Seek};

/// Why a terrain PNG could not be read, or an encoding name not understood.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum FormatError {
    /// Not a readable PNG.
    #[error("not a readable PNG (truncated or corrupt): {0}")]
    Png(String),
    /// A PNG whose pixels are not 8-bit colour (or grey).
    #[error(
        "{0:?} pixels; terrain-RGB and Terrarium tiles are 8-bit RGB (or RGBA, where alpha 0 means no data)"
    )]
    Pixels(ColorType),
    /// More pixels than the caller allows.
    #[error("{width}x{height} pixels is more than the limit of {limit}")]
    TooLarge {
        /// Columns.
        width: u32,
        /// Rows.
        height: u32,
        /// The limit on their product.
        limit: u64,
    },
    /// An encoding name that is none of [`Encoding::ALL`] (nor `mapbox`).
    #[error("unknown height encoding {0:?}; use terrain-rgb (alias mapbox) or terrarium")]
    UnknownEncoding(String),
}

/// How heights become colours.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Encoding {
    /// Mapbox terrain-RGB: `-10000 + (R * 65536 + G * 256 + B) * 0.1` metres.
    TerrainRgb,
    /// Mapzen/AWS Terrarium: `R * 256 + G + B / 256 - 32768` metres.
    Terrarium,
}

/// The largest 24-bit code.
const MAX_CODE: u32 = 0xFF_FFFF;

impl Encoding {
    /// Both encodings.
    pub const ALL: [Encoding; 2] = [Encoding::TerrainRgb, Encoding::Terrarium];

    /// The encoding's name in Relief's URLs and flags: `terrain-rgb` or `terrarium`.
    pub fn name(self) -> &'static str {
        match self {
            Encoding::TerrainRgb => "terrain-rgb",
            Encoding::Terrarium => "terrarium",
        }
    }

    /// The name MapLibre GL's `raster-dem` source gives the encoding (its `encoding` property):
    /// `mapbox` or `terrarium`.
    pub fn maplibre_name(self) -> &'static str {
        match self {
            Encoding::TerrainRgb => "mapbox",
            Encoding::Terrarium => "terrarium",
        }
    }

    /// Metres between neighbouring codes: 0.1 or 1/256.
    pub fn step(self) -> f64 {
        match self {
            Encoding::TerrainRgb => 0.1,
            Encoding::Terrarium => 1.0 / 256.0,
        }
    }

    /// The lowest and highest heights the encoding holds (codes 0 and 2^24 - 1), metres.
    pub fn range(self) -> (f64, f64) {
        (self.height(0), self.height(MAX_CODE))
    }

    /// The code nearest height `h` (metres), clamped to the range; NaN gives the code of 0 m.
    pub fn code(self, h: f64) -> u32 {
        let h = if h.is_nan() { 0.0 } else { h };
        let c = match self {
            // Times 10 rather than over 0.1: 10 is exact, 0.1 is not.
            Encoding::TerrainRgb => ((h + 10_000.0) * 10.0).round(),
            // Times 256 is exact.
            Encoding::Terrarium => ((h + 32_768.0) * 256.0).round(),
        };
        c.clamp(0.0, MAX_CODE as f64) as u32
    }

    /// The height code `c` stands for, metres (the nearest f64).
    pub fn height(self, c: u32) -> f64 {
        match self {
            // A whole number over 10 is correctly rounded; c * 0.1 - 10000 would round twice.
            Encoding::TerrainRgb => (c as f64 - 100_000.0) / 10.0,
            Encoding::Terrarium => c as f64 / 256.0 - 32_768.0,
        }
    }

    /// The colour of height `h` (metres): the nearest code's red, green and blue bytes.
    pub fn encode(self, h: f32) -> [u8; 3] {
        let c = self.code(h as f64);
        [(c >> 16) as u8, (c >> 8) as u8, c as u8]
    }

    /// The height (metres) of colour `rgb`.
    pub fn decode(self, rgb: [u8; 3]) -> f32 {
        let [r, g, b] = rgb.map(u32::from);
        self.height(r << 16 | g << 8 | b) as f32
    }
}

impl std::fmt::Display for Encoding {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Encoding {
    type Err = FormatError;

    /// `terrain-rgb` (or `mapbox`, MapLibre's name for it) or `terrarium`, in any case.
    fn from_str(s: &str) -> Result<Encoding, FormatError> {
        match s.to_ascii_lowercase().as_str() {
            "terrain-rgb" | "mapbox" => Ok(Encoding::TerrainRgb),
            "terrarium" => Ok(Encoding::Terrarium),
            _ => Err(FormatError::UnknownEncoding(s.into())),
        }
    }
}

/// An RGB8 PNG of a `width` x `height` grid of heights (row-major, row 0 at the top) in `enc`.
///
/// # Panics
/// If `heights` does not hold `width * height` values.
pub fn encode_png(width: u32, height: u32, heights: &[f32], enc: Encoding) -> Vec<u8> {
    assert_eq!(
        heights.len() as u64,
        width as u64 * height as u64,
        "{} heights for a {width}x{height} image",
        heights.len()
    );
    let rgb: Vec<u8> = heights.iter().flat_map(|&h| enc.encode(h)).collect();
    let mut out = Vec::new();
    // Adaptive filtering suits these images: the low byte changes from pixel to pixel, the high
    // ones slowly.
    PngEncoder::new_with_quality(&mut out, CompressionType::Default, FilterType::Adaptive)
        .write_image(&rgb, width, height, ExtendedColorType::Rgb8)
        .expect("encoding a PNG into memory");
    out
}

/// The width, height and heights (row-major) of a terrain PNG in `enc`.
pub fn decode_png(bytes: &[u8], enc: Encoding) -> Result<(u32, u32, Vec<f32>), FormatError> {
    read_png(Cursor::new(bytes), enc, u64::MAX)
}

/// [`decode_png`] from a reader, refusing images of more than `max_pixels` pixels before
/// decoding them. RGB8 is the format; RGBA8 is read too (alpha 0 decodes as NaN, no data, any
/// other alpha is ignored), and 8-bit grey (as a PNG optimiser may store an image whose
/// pixels all have R = G = B) counts as R = G = B.
pub fn read_png<R: BufRead + Seek>(
    reader: R,
    enc: Encoding,
    max_pixels: u64,
) -> Result<(u32, u32, Vec<f32>), FormatError> {
    let png = |e: image::ImageError| FormatError::Png(e.to_string());
    let dec = PngDecoder::new(reader).map_err(png)?;
    let (w, h) = dec.dimensions();
    if w as u64 * h as u64 > max_pixels {
        return Err(FormatError::TooLarge {
            width: w,
            height: h,
            limit: max_pixels,
        });
    }
    let colour = dec.color_type();
    let channels = match colour {
        ColorType::L8 => 1,
        ColorType::La8 => 2,
        ColorType::Rgb8 => 3,
        ColorType::Rgba8 => 4,
        other => return Err(FormatError::Pixels(other)),
    };
    let mut buf = vec![0u8; dec.total_bytes() as usize];
    dec.read_image(&mut buf).map_err(png)?;
    let heights = buf
        .chunks_exact(channels)
        .map(|p| {
            let (rgb, alpha) = match *p {
                [v] => ([v; 3], 255),
                [v, a] => ([v; 3], a),
                [r, g, b] => ([r, g, b], 255),
                [r, g, b, a] => ([r, g, b], a),
                _ => unreachable!("chunks of {channels} bytes"),
            };
            if alpha == 0 {
                f32::NAN
            } else {
                enc.decode(rgb)
            }
        })
        .collect();
    Ok((w, h, heights))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Codes whose heights f32 holds to better than half a step: terrain-RGB up to 2^20 m
    /// (2^20 - 1 m and the f32 spacing there is 1/16 m), all of Terrarium's.
    fn exact_codes(enc: Encoding) -> std::ops::RangeInclusive<u32> {
        match enc {
            Encoding::TerrainRgb => 0..=enc.code((1u32 << 20) as f64) - 1,
            Encoding::Terrarium => 0..=MAX_CODE,
        }
    }

    #[test]
    fn every_code_decodes_and_encodes_to_itself() {
        for enc in Encoding::ALL {
            let mut n = 0u64;
            for c in exact_codes(enc) {
                let rgb = [(c >> 16) as u8, (c >> 8) as u8, c as u8];
                let h = enc.decode(rgb);
                assert_eq!(enc.encode(h), rgb, "{enc}: code {c}, height {h}");
                n += 1;
            }
            // Terrain-RGB: every code from -10000 m to 2^20 m, 10.6 million; Terrarium: all
            // 16.8 million.
            assert!(n > 10_000_000, "{enc}: {n}");
        }
    }

    #[test]
    fn decimal_heights_land_on_their_own_codes() {
        // The truncation bug: floor((h + 10000) / 0.1) puts 0.7 m on code 100006, not 100007.
        assert_eq!(Encoding::TerrainRgb.code(0.7f32 as f64), 100_007);
        assert_eq!(((0.7f32 as f64 + 10_000.0) / 0.1).floor(), 100_006.0);
        for k in -100_000i32..=300_000 {
            let h = k as f32 / 10.0;
            let c = Encoding::TerrainRgb.code(h as f64);
            assert_eq!(c as i64, k as i64 + 100_000, "{h}");
        }
        // Terrarium: every whole metre and every 1/256 of the range.
        for k in -32_768 * 256..32_768 * 256 {
            let h = k as f32 / 256.0;
            assert_eq!(
                Encoding::Terrarium.code(h as f64) as i64,
                k as i64 + 32_768 * 256
            );
        }
    }

    #[test]
    fn neighbouring_heights_step_by_one_code() {
        // A smooth ramp of one step per sample: each code exactly one above the last, never
        // two or none (the terracing of truncating encoders).
        for enc in Encoding::ALL {
            let mut last = enc.code(-500.0);
            for k in 1..20_000 {
                let h = (-500.0 + k as f64 * enc.step()) as f32;
                let c = enc.code(h as f64);
                assert_eq!(c, last + 1, "{enc}: {h}");
                last = c;
            }
        }
    }

    #[test]
    fn out_of_range_heights_clamp_and_nan_is_sea_level() {
        for enc in Encoding::ALL {
            let (lo, hi) = enc.range();
            assert_eq!(enc.encode(f32::NEG_INFINITY), [0, 0, 0]);
            assert_eq!(enc.encode((lo - 1000.0) as f32), [0, 0, 0]);
            assert_eq!(enc.encode(f32::INFINITY), [255, 255, 255]);
            assert_eq!(enc.encode(1e9), [255, 255, 255]);
            assert_eq!(enc.decode([0, 0, 0]) as f64, lo);
            assert_eq!(enc.decode([255, 255, 255]) as f64, hi);
            assert_eq!(enc.encode(f32::NAN), enc.encode(0.0));
            assert_eq!(enc.decode(enc.encode(0.0)), 0.0);
        }
        assert_eq!(Encoding::TerrainRgb.range(), (-10_000.0, 1_667_721.5));
        assert_eq!(
            Encoding::Terrarium.range(),
            (-32_768.0, 32_768.0 - 1.0 / 256.0)
        );
        // The published examples: 0 m.
        assert_eq!(Encoding::TerrainRgb.encode(0.0), [1, 134, 160]);
        assert_eq!(Encoding::Terrarium.encode(0.0), [128, 0, 0]);
        assert_eq!(Encoding::Terrarium.decode([128, 1, 128]), 1.5);
    }

    #[test]
    fn names_parse_back() {
        for enc in Encoding::ALL {
            assert_eq!(enc.name().parse::<Encoding>(), Ok(enc));
            assert_eq!(enc.maplibre_name().parse::<Encoding>(), Ok(enc));
            assert_eq!(enc.to_string(), enc.name());
        }
        assert_eq!("Mapbox".parse::<Encoding>(), Ok(Encoding::TerrainRgb));
        let e = "rgb".parse::<Encoding>().unwrap_err().to_string();
        assert!(e.contains("terrain-rgb") && e.contains("terrarium"), "{e}");
    }

    #[test]
    fn pngs_of_every_kind_decode() {
        let enc = Encoding::Terrarium;
        let heights = [0.0f32, 1.5, -20.25, 3776.0, 100.0, 8848.5];
        let png = encode_png(3, 2, &heights, enc);
        assert_eq!(decode_png(&png, enc).unwrap(), (3, 2, heights.to_vec()));
        // RGBA: alpha 0 is no data.
        let mut rgba = image::RgbaImage::new(2, 1);
        rgba.put_pixel(0, 0, image::Rgba([128, 1, 128, 255]));
        rgba.put_pixel(1, 0, image::Rgba([128, 1, 128, 0]));
        let mut bytes = Cursor::new(Vec::new());
        rgba.write_to(&mut bytes, image::ImageFormat::Png).unwrap();
        let (w, h, v) = decode_png(bytes.get_ref(), enc).unwrap();
        assert_eq!((w, h, v[0]), (2, 1, 1.5));
        assert!(v[1].is_nan());
        // Grey: R = G = B.
        let grey = image::GrayImage::from_raw(2, 1, vec![128, 7]).unwrap();
        let mut bytes = Cursor::new(Vec::new());
        grey.write_to(&mut bytes, image::ImageFormat::Png).unwrap();
        let (_, _, v) = decode_png(bytes.get_ref(), enc).unwrap();
        assert_eq!(v, vec![enc.decode([128; 3]), enc.decode([7; 3])]);
        // 16-bit grey is a height PNG, not a terrain tile.
        let l16 = image::ImageBuffer::<image::Luma<u16>, _>::from_raw(2, 1, vec![1u16, 2]).unwrap();
        let mut bytes = Cursor::new(Vec::new());
        l16.write_to(&mut bytes, image::ImageFormat::Png).unwrap();
        let e = decode_png(bytes.get_ref(), enc).unwrap_err();
        assert_eq!(e, FormatError::Pixels(ColorType::L16));
        assert!(e.to_string().contains("8-bit RGB"), "{e}");
        // Limits and garbage.
        let e = read_png(Cursor::new(&png), enc, 5).unwrap_err();
        assert!(matches!(e, FormatError::TooLarge { limit: 5, .. }), "{e}");
        assert!(matches!(
            decode_png(&png[..png.len() / 2], enc),
            Err(FormatError::Png(_))
        ));
        assert!(matches!(
            decode_png(b"not a png", enc),
            Err(FormatError::Png(_))
        ));
    }

    /// The f32 spacing at `h`: what storing a decoded height as f32 may add to its error.
    fn f32_ulp(h: f64) -> f64 {
        let h = h.abs() as f32;
        (f32::from_bits(h.to_bits() + 1) - h) as f64
    }

    proptest! {
        #[test]
        fn decoding_an_encoding_is_within_half_a_step(
            h in -12_000.0f32..40_000.0,
            terrarium in any::<bool>(),
        ) {
            let enc = if terrarium { Encoding::Terrarium } else { Encoding::TerrainRgb };
            let (lo, hi) = enc.range();
            let c = enc.code(h as f64);
            let clamped = (h as f64).clamp(lo, hi);
            // Exactly, in f64 (up to f64 rounding far below a step)...
            prop_assert!((enc.height(c) - clamped).abs() <= enc.step() / 2.0 + 1e-9);
            // ... and through the bytes and f32.
            let back = enc.decode(enc.encode(h)) as f64;
            prop_assert!(
                (back - clamped).abs() <= enc.step() / 2.0 + f32_ulp(clamped),
                "{} -> {}", h, back
            );
            // Encoding what was decoded changes nothing.
            prop_assert_eq!(enc.encode(enc.decode(enc.encode(h))), enc.encode(h));
        }

        #[test]
        fn encoding_keeps_order(a in -10_000.0f32..30_000.0, b in -10_000.0f32..30_000.0) {
            for enc in Encoding::ALL {
                let (ca, cb) = (enc.code(a as f64), enc.code(b as f64));
                if a <= b {
                    prop_assert!(ca <= cb);
                }
            }
        }

        #[test]
        fn pngs_round_trip_within_half_a_step(
            w in 1u32..20,
            h in 1u32..20,
            seed in any::<u64>(),
            terrarium in any::<bool>(),
        ) {
            let enc = if terrarium { Encoding::Terrarium } else { Encoding::TerrainRgb };
            let n = (w * h) as u64;
            let heights: Vec<f32> = (0..n)
                .map(|i| {
                    let x = (seed ^ i.wrapping_mul(0x9E37_79B9_7F4A_7C15)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
                    -400.0 + (x >> 40) as f32 / (1u64 << 24) as f32 * 9_000.0
                })
                .collect();
            let png = encode_png(w, h, &heights, enc);
            let (dw, dh, back) = decode_png(&png, enc).unwrap();
            prop_assert_eq!((dw, dh), (w, h));
            for (a, b) in heights.iter().zip(&back) {
                prop_assert!(((a - b).abs() as f64) <= enc.step() / 2.0 + f32_ulp(*a as f64));
            }
        }
    }
}
