//! DEM input: read a height grid from a GeoTIFF, a 16-bit PNG or a synthetic generator, check it,
//! and fill its voids (DESIGN.md section 2).
//!
//! - [`geotiff`]: int16, uint16, int32, float32 and float64 GeoTIFFs, with GDAL_NODATA and the
//!   GeoTIFF spacing tags (geographic grids get metre spacing from their latitude).
//! - [`png`]: 16-bit grayscale PNGs with scale, offset, no-data value and spacing given by flags.
//! - [`synthetic`]: `synthetic:SIZE[:SEED]`, a deterministic fractal terrain.
//! - [`fill`]: smooth void filling.
//!
//! [`load`] dispatches on the spec, refuses absurd input with a [`DemError`] naming the problem,
//! and fills voids. The void mask is kept in the [`Dem`].

pub mod fill;
pub mod geotiff;
pub mod png;
pub mod synthetic;

use std::path::Path;

/// Samples accepted by default: a little over 16385 x 16385.
pub const DEFAULT_MAX_SAMPLES: u64 = 16385 * 16385;
/// Heights beyond this many metres from sea level are refused as absurd.
pub const ABSURD_HEIGHT_M: f32 = 20_000.0;

/// A height grid in metres, voids filled, with its void mask.
#[derive(Clone, Debug)]
pub struct Dem {
    /// Samples per row.
    pub width: u32,
    /// Rows; row 0 is north.
    pub height: u32,
    /// Ground metres between columns.
    pub spacing_x: f64,
    /// Ground metres between rows.
    pub spacing_y: f64,
    /// Row-major heights in metres; voids hold filled values.
    pub heights: Vec<f32>,
    /// Which samples were voids in the source.
    pub voids: VoidMask,
    /// What the heights came from, for messages and store metadata.
    pub source: String,
    /// Coordinate reference system of the source, when known.
    pub crs: Option<String>,
}

impl Dem {
    /// Whether sample `i` (row-major) was a void in the source.
    pub fn is_void(&self, i: usize) -> bool {
        self.voids.get(i)
    }
}

/// One bit per sample: set where the source had no data.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VoidMask {
    /// The bits, 64 samples a word, row-major.
    bits: Vec<u64>,
    /// Set bits, kept for reports.
    count: u64,
}

impl VoidMask {
    /// A mask of `n` samples, none void.
    pub fn new(n: usize) -> VoidMask {
        VoidMask {
            bits: vec![0; n.div_ceil(64)],
            count: 0,
        }
    }

    /// Marks sample `i` void.
    pub fn set(&mut self, i: usize) {
        let (w, b) = (i / 64, 1u64 << (i % 64));
        if self.bits[w] & b == 0 {
            self.bits[w] |= b;
            self.count += 1;
        }
    }

    /// Whether sample `i` is void.
    pub fn get(&self, i: usize) -> bool {
        self.bits
            .get(i / 64)
            .is_some_and(|w| w & (1 << (i % 64)) != 0)
    }

    /// Number of void samples.
    pub fn count(&self) -> u64 {
        self.count
    }
}

/// How to read PNG input.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PngOptions {
    /// Metres per 16-bit value.
    pub scale: f64,
    /// Metres added to every value.
    pub offset: f64,
    /// The value that means "no data", if any.
    pub nodata_value: Option<u16>,
}

impl Default for PngOptions {
    fn default() -> Self {
        PngOptions {
            scale: 1.0,
            offset: 0.0,
            nodata_value: Some(0),
        }
    }
}

/// Options of [`load`].
#[derive(Clone, Debug, PartialEq)]
pub struct LoadOptions {
    /// Refuse grids with more samples than this.
    pub max_samples: u64,
    /// Ground metres between columns, overriding the file's (required for PNG).
    pub spacing_x: Option<f64>,
    /// Ground metres between rows, overriding the file's (required for PNG).
    pub spacing_y: Option<f64>,
    /// PNG decoding.
    pub png: PngOptions,
    /// Show progress bars on long work.
    pub progress: bool,
}

impl Default for LoadOptions {
    fn default() -> Self {
        LoadOptions {
            max_samples: DEFAULT_MAX_SAMPLES,
            spacing_x: None,
            spacing_y: None,
            png: PngOptions::default(),
            progress: false,
        }
    }
}

/// Why a DEM could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum DemError {
    /// The file could not be opened or read.
    #[error("{path}: cannot read the file")]
    Io {
        /// The file.
        path: String,
        /// What the OS said.
        source: std::io::Error,
    },
    /// The file is not a valid image of its kind (truncated or corrupt).
    #[error("{path}: not a readable {kind}: {detail}")]
    Corrupt {
        /// The file.
        path: String,
        /// GeoTIFF or PNG.
        kind: &'static str,
        /// The decoder's message.
        detail: String,
    },
    /// The samples are of a kind Relief does not read.
    #[error("{path}: unsupported sample format: {detail}")]
    Unsupported {
        /// The file.
        path: String,
        /// What was found.
        detail: String,
    },
    /// Fewer than 2 x 2 samples.
    #[error("{input}: {width}x{height} samples is too small; at least 2x2 are needed")]
    TooSmall {
        /// The input.
        input: String,
        /// Columns.
        width: u32,
        /// Rows.
        height: u32,
    },
    /// More samples than the configured limit.
    #[error(
        "{input}: {width}x{height} = {samples} samples exceeds the limit of {limit}; raise it with --max-samples"
    )]
    TooLarge {
        /// The input.
        input: String,
        /// Columns.
        width: u32,
        /// Rows.
        height: u32,
        /// Their product.
        samples: u64,
        /// The limit.
        limit: u64,
    },
    /// Every sample is a void.
    #[error("{0}: every sample is no-data; there is no terrain to build")]
    AllVoid(String),
    /// NaN samples that are not declared as no-data.
    #[error(
        "{input}: {count} NaN samples (first at column {col}, row {row}) and no GDAL_NODATA tag declaring NaN as no-data"
    )]
    NaN {
        /// The input.
        input: String,
        /// How many.
        count: u64,
        /// Column of the first.
        col: u32,
        /// Row of the first.
        row: u32,
    },
    /// Infinite or absurd heights.
    #[error(
        "{input}: height {value} m at column {col}, row {row} is not a plausible terrain height (limit +-20000 m)"
    )]
    Absurd {
        /// The input.
        input: String,
        /// The value.
        value: f32,
        /// Its column.
        col: u32,
        /// Its row.
        row: u32,
    },
    /// No usable ground spacing.
    #[error("{input}: {detail}")]
    Spacing {
        /// The input.
        input: String,
        /// What is missing or wrong.
        detail: String,
    },
    /// A `synthetic:` spec that does not parse.
    #[error("bad synthetic spec {spec:?}: {detail}")]
    BadSpec {
        /// The spec.
        spec: String,
        /// What is wrong.
        detail: String,
    },
}

/// Raw samples from a reader, before checks and void filling.
pub struct RawGrid {
    /// Samples per row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Row-major heights; voids may hold anything.
    pub heights: Vec<f32>,
    /// Void samples.
    pub voids: VoidMask,
    /// Spacing from the file, if it has one.
    pub spacing: Option<(f64, f64)>,
    /// CRS from the file, if known.
    pub crs: Option<String>,
    /// Whether NaN samples count as voids (the file declared NaN as no-data).
    pub nan_is_void: bool,
}

/// Checks that a grid of `w` x `h` may be read under `opts`.
pub fn check_size(source: &str, w: u32, h: u32, opts: &LoadOptions) -> Result<(), DemError> {
    if w < 2 || h < 2 {
        return Err(DemError::TooSmall {
            input: source.into(),
            width: w,
            height: h,
        });
    }
    let samples = w as u64 * h as u64;
    if samples > opts.max_samples {
        return Err(DemError::TooLarge {
            input: source.into(),
            width: w,
            height: h,
            samples,
            limit: opts.max_samples,
        });
    }
    Ok(())
}

/// Loads the DEM named by `spec`: a `synthetic:SIZE[:SEED]` spec, or a GeoTIFF or PNG path
/// (chosen by extension, else by the file's first bytes).
pub fn load(spec: &str, opts: &LoadOptions) -> Result<Dem, DemError> {
    if let Some(rest) = spec.strip_prefix("synthetic:") {
        return synthetic::load(spec, rest, opts);
    }
    let path = Path::new(spec);
    let io = |source| DemError::Io {
        path: spec.into(),
        source,
    };
    let bytes = std::fs::read(path).map_err(io)?;
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let is_png = match ext.as_deref() {
        Some("png") => true,
        Some("tif" | "tiff") => false,
        _ => bytes.starts_with(b"\x89PNG"),
    };
    let raw = if is_png {
        png::read(spec, &bytes, opts)?
    } else {
        geotiff::read(spec, &bytes, opts)?
    };
    finish(spec, raw, opts)
}

/// Checks raw samples, applies spacing overrides and fills voids.
pub fn finish(source: &str, mut raw: RawGrid, opts: &LoadOptions) -> Result<Dem, DemError> {
    check_size(source, raw.width, raw.height, opts)?;
    let mut nan = (0u64, 0usize);
    for (i, h) in raw.heights.iter().enumerate() {
        if raw.voids.get(i) {
            continue;
        }
        if h.is_nan() {
            if nan.0 == 0 {
                nan.1 = i;
            }
            nan.0 += 1;
        } else if h.is_infinite() || h.abs() > ABSURD_HEIGHT_M {
            return Err(DemError::Absurd {
                input: source.into(),
                value: *h,
                col: (i % raw.width as usize) as u32,
                row: (i / raw.width as usize) as u32,
            });
        }
    }
    if nan.0 > 0 {
        if !raw.nan_is_void {
            return Err(DemError::NaN {
                input: source.into(),
                count: nan.0,
                col: (nan.1 % raw.width as usize) as u32,
                row: (nan.1 / raw.width as usize) as u32,
            });
        }
        for i in 0..raw.heights.len() {
            if raw.heights[i].is_nan() {
                raw.voids.set(i);
            }
        }
    }
    if raw.voids.count() == raw.heights.len() as u64 {
        return Err(DemError::AllVoid(source.into()));
    }
    let spacing = match (opts.spacing_x, opts.spacing_y, raw.spacing) {
        (Some(x), Some(y), _) => (x, y),
        (Some(x), None, Some((_, y))) => (x, y),
        (None, Some(y), Some((x, _))) => (x, y),
        (None, None, Some(s)) => s,
        _ => {
            return Err(DemError::Spacing {
                input: source.into(),
                detail: "no ground spacing: give --spacing-x and --spacing-y in metres".into(),
            });
        }
    };
    if !(spacing.0.is_finite() && spacing.1.is_finite() && spacing.0 > 0.0 && spacing.1 > 0.0) {
        return Err(DemError::Spacing {
            input: source.into(),
            detail: format!("spacing {} x {} m must be positive", spacing.0, spacing.1),
        });
    }
    fill::fill_voids(
        raw.width,
        raw.height,
        &mut raw.heights,
        &raw.voids,
        opts.progress,
    );
    Ok(Dem {
        width: raw.width,
        height: raw.height,
        spacing_x: spacing.0,
        spacing_y: spacing.1,
        heights: raw.heights,
        voids: raw.voids,
        source: source.into(),
        crs: raw.crs,
    })
}

/// The crop of Mt Fuji shipped with the server (see `server/data/README.md`).
pub const EMBEDDED_FUJI: &[u8] = include_bytes!("../../data/fuji_crop.tif");

/// The embedded default terrain: the Mt Fuji crop, decoded and void-filled.
pub fn embedded_default() -> Result<Dem, DemError> {
    let opts = LoadOptions::default();
    let raw = geotiff::read("embedded:fuji_crop.tif", EMBEDDED_FUJI, &opts)?;
    finish("embedded:fuji_crop.tif", raw, &opts)
}

#[cfg(test)]
mod tests;
