//! DEM input: read a height grid from a GeoTIFF, a 16-bit PNG or a synthetic generator, check it,
//! and fill its voids (DESIGN.md section 2).
//!
//! - [`geotiff`]: int16, uint16, int32, float32 and float64 GeoTIFFs, with GDAL_NODATA and the
//!   GeoTIFF spacing tags (geographic grids get metre spacing from their latitude on WGS 84),
//!   read tile by tile or strip by strip through [`cog::TiffWindows`], so that tiled and
//!   Cloud-Optimized GeoTIFFs (deflate, LZW, zstd; predictors 2 and 3) are never decoded whole.
//! - [`http_range`]: an `http://` or `https://` input, a GeoTIFF read by HTTP range requests (as
//!   S3, GCS, MinIO and nginx serve files), fetching only the bytes the reader needs.
//! - [`png`]: 16-bit grayscale PNGs with scale, offset, no-data value and spacing given by flags.
//! - [`rgb_tile`]: terrain-RGB and Terrarium PNG tiles (`--encoding`), placed in Web Mercator by
//!   their z/x/y (from the path or `--tile`).
//! - SRTM `.hgt` files, placed by their names (`crate::formats::hgt`).
//! - [`mosaic`]: several adjacent inputs on one grid joined into one ([`load_all`]); a folder
//!   stands for the `.tif` and `.tiff` files in it, in name order (as GDAL's VRTs join COGs).
//! - [`synthetic`]: `synthetic:SIZE[:SEED]`, a deterministic fractal terrain, 10 m spacing.
//! - [`fill`]: smooth (harmonic) void filling; the [`VoidMask`] keeps where the voids were.
//!
//! [`load`] dispatches on the spec, refuses unusable input with a [`DemError`] naming the problem
//! and the input, and fills voids; the void mask is kept in the [`Dem`]. [`load_all`] does the
//! same for one input or a mosaic of several, and is what every command calls. [`embedded_default`]
//! is the Mt Fuji crop shipped in `server/data/`.
//!
//! What [`finish`] refuses, after a reader has decoded the samples:
//! - fewer than 2 x 2 samples, or more than [`LoadOptions::max_samples`] (readers check the size
//!   from the header, before allocating);
//! - NaN samples, unless the file's GDAL_NODATA tag is `nan`: then NaN marks voids. An undeclared
//!   NaN is more likely a broken export than a survey gap, so it is reported (with a count and the
//!   first position) rather than silently filled;
//! - infinite heights and heights beyond +-[`ABSURD_HEIGHT_M`]: wrong units, or an undeclared
//!   no-data value such as -32768 or -3.4e38. (An undeclared -9999 passes as a deep trench: it is
//!   a plausible ocean depth, so Relief does not guess.)
//! - grids where every sample is void;
//! - a missing or non-positive ground spacing.

pub mod args;
pub mod cog;
mod error;
pub mod fill;
pub mod geotiff;
pub mod http_range;
mod mask;
pub mod mosaic;
mod noise;
pub mod png;
pub mod rgb_tile;
pub mod synthetic;

pub use args::DemArgs;
pub use error::DemError;
pub use mask::VoidMask;

use crate::formats::terrain_rgb::Encoding;
use crate::geo::mercator::TileId;
use crate::geo::{GeoTransform, Georef};
use std::io::{BufRead, BufReader, Seek, SeekFrom};
use std::path::Path;

/// Peak resident bytes a sample of a build with `grid` or `rqt` tiles, which holds the grid's
/// heights in memory while the tree streams its records to the file and the pyramid keeps only
/// its blobs (and for `rqt`, each tile's sides). Measured by `relief-server bench build`: 6.1
/// on synthetic:16385, 6.8 on an 8193 x 8193 float32 COG, 7.0 (`grid`) and 6.7 (`rqt`) on
/// synthetic:4097. Reading holds more for a while: void filling's pyramid (a quarter of the
/// grid, 2 bytes a sample) and a mosaic's pieces beside the whole, hence the margin.
pub const BUILD_BYTES_PER_SAMPLE: u64 = 12;

/// The same for `tin` tiles, which triangulate a second copy of the grid (in quantised metres)
/// and whose blobs are larger: 16.1 measured on synthetic:4097, with a margin. A `tin` build
/// over the memory it would need is warned about, not refused ([`BUILD_BYTES_PER_SAMPLE`] sets
/// the default limit).
pub const TIN_BUILD_BYTES_PER_SAMPLE: u64 = 24;

/// Samples accepted by default: as many as a build fits in the memory this process may use
/// ([`crate::sysmem::usable_memory`], at [`BUILD_BYTES_PER_SAMPLE`]), or 16385 x 16385 where
/// that cannot be read. `--max-samples` changes it.
pub fn default_max_samples() -> u64 {
    crate::sysmem::usable_memory().map_or(16385 * 16385, |m| m / BUILD_BYTES_PER_SAMPLE)
}
/// Heights beyond this many metres from sea level are refused as absurd.
pub const ABSURD_HEIGHT_M: f32 = 20_000.0;

/// A height grid in metres, voids filled, with its void mask.
#[derive(Clone, Debug)]
pub struct Dem {
    /// Samples per row: the grid's extent east-west.
    pub width: u32,
    /// Rows, row 0 north: the grid's extent north-south.
    pub height: u32,
    /// Ground metres between columns, to place samples in world space.
    pub spacing_x: f64,
    /// Ground metres between rows (differs from `spacing_x` on geographic grids).
    pub spacing_y: f64,
    /// Row-major heights in metres, the terrain itself; voids hold filled values, so every
    /// sample is usable by the LOD engines.
    pub heights: Vec<f32>,
    /// Which samples were voids in the source, so that stores and queries can tell measured
    /// ground from filled ground.
    pub voids: VoidMask,
    /// What the heights came from (path, `synthetic:` spec), for messages and store metadata.
    pub source: String,
    /// Coordinate reference system of the source (as `EPSG:n`), when known, for metadata.
    pub crs: Option<String>,
    /// Where the grid lies on the Earth: from the GeoTIFF's tags, or `--origin` for synthetic
    /// and PNG input. The standard formats (quantized-mesh, terrain-RGB) need it.
    pub georef: Option<Georef>,
    /// What reading the input cost, for benchmarks of remote and tiled input.
    pub io: IoStats,
}

/// What reading an input cost: bytes read from the source (the file, or the bodies of HTTP
/// range requests) against the source's size. A mosaic sums its inputs; a synthetic terrain
/// reads nothing. Only the GeoTIFF reader counts (files and URLs); the others leave it zero.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct IoStats {
    /// Bytes read from the source, to tell how much of a remote file a read fetched.
    pub bytes_read: u64,
    /// The source's size in bytes, what reading it whole would have cost.
    pub source_bytes: u64,
}

impl std::ops::AddAssign for IoStats {
    fn add_assign(&mut self, other: IoStats) {
        self.bytes_read += other.bytes_read;
        self.source_bytes += other.source_bytes;
    }
}

impl Dem {
    /// Whether sample `i` (row-major) was a void in the source.
    pub fn is_void(&self, i: usize) -> bool {
        self.voids.get(i)
    }

    /// The height at column `x`, row `y`.
    ///
    /// # Panics
    /// If (`x`, `y`) is outside the grid.
    pub fn at(&self, x: u32, y: u32) -> f32 {
        assert!(
            x < self.width && y < self.height,
            "({x}, {y}) outside the grid"
        );
        self.heights[y as usize * self.width as usize + x as usize]
    }

    /// Lowest and highest height over the samples that were not voids.
    pub fn valid_range(&self) -> (f32, f32) {
        self.heights
            .iter()
            .enumerate()
            .filter(|&(i, _)| !self.voids.get(i))
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), (_, &h)| {
                (lo.min(h), hi.max(h))
            })
    }
}

/// How to read PNG input: a PNG carries 16-bit values, not metres, and no geo tags.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PngOptions {
    /// Metres per 16-bit value (`metres = offset + value * scale`), since PNG has no height unit.
    pub scale: f64,
    /// Metres added to every value, so that values can encode heights below 0 m.
    pub offset: f64,
    /// The value that means "no data", if any (default 0, the convention of the shared test
    /// PNGs); such samples become voids.
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
    /// Refuse grids with more samples than this (`--max-samples`), checked from the header
    /// before anything is allocated, so that a hostile or mistaken input cannot exhaust memory.
    pub max_samples: u64,
    /// Ground metres between columns, overriding the file's; required where the file has none
    /// (PNG, or a GeoTIFF without geo tags).
    pub spacing_x: Option<f64>,
    /// Ground metres between rows, overriding the file's; required where the file has none.
    pub spacing_y: Option<f64>,
    /// How to turn PNG values into metres.
    pub png: PngOptions,
    /// Longitude and latitude (degrees) of the north-west sample, for input that carries no
    /// georeference (synthetic, PNG); the grid is then WGS 84 degrees at the ground spacing.
    pub origin: Option<(f64, f64)>,
    /// Read PNGs as terrain-RGB or Terrarium tiles in this encoding (`--encoding`) rather than
    /// as 16-bit grayscale heights.
    pub encoding: Option<Encoding>,
    /// The web map tile a terrain-RGB or Terrarium PNG is (`--tile`), where its path does not
    /// say; one input only.
    pub tile: Option<TileId>,
    /// Show progress bars on long work (synthetic generation, void filling of big grids); tests
    /// and servers turn it off.
    pub progress: bool,
}

impl Default for LoadOptions {
    fn default() -> Self {
        LoadOptions {
            max_samples: default_max_samples(),
            spacing_x: None,
            spacing_y: None,
            png: PngOptions::default(),
            origin: None,
            encoding: None,
            tile: None,
            progress: false,
        }
    }
}

/// Raw samples from a reader, before checks and void filling.
pub struct RawGrid {
    /// Samples per row.
    pub width: u32,
    /// Rows, row 0 north.
    pub height: u32,
    /// Row-major heights in metres; voids may hold anything.
    pub heights: Vec<f32>,
    /// Samples the file marked as no-data.
    pub voids: VoidMask,
    /// Ground spacing (x, y) in metres from the file, or why the file gives none (completed
    /// into an error message unless the caller overrides the spacing).
    pub spacing: Result<(f64, f64), String>,
    /// CRS from the file, if known.
    pub crs: Option<String>,
    /// The georeference from the file, if it has a complete one.
    pub georef: Option<Georef>,
    /// Whether NaN samples count as voids (the file declared NaN as no-data).
    pub nan_is_void: bool,
    /// What reading the input cost (zero where the reader does not count).
    pub io: IoStats,
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

/// File formats [`load`] reads.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Format {
    Tiff,
    Png,
    Hgt,
}

/// The format of a file: by its first bytes when they are a TIFF or PNG signature (so that a
/// misnamed file still loads), else by extension (an `.hgt` file has no signature).
fn sniff(path: &str, head: &[u8]) -> Option<Format> {
    if head.starts_with(b"\x89PNG\r\n\x1a\n") {
        return Some(Format::Png);
    }
    if head.starts_with(b"II*\0") || head.starts_with(b"MM\0*") {
        return Some(Format::Tiff);
    }
    // BigTIFF (version 43) is a TIFF too; the decoder reads it.
    if head.starts_with(b"II+\0") || head.starts_with(b"MM\0+") {
        return Some(Format::Tiff);
    }
    let ext = std::path::Path::new(path)
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("png") => Some(Format::Png),
        Some("tif" | "tiff" | "gtiff") => Some(Format::Tiff),
        Some("hgt") => Some(Format::Hgt),
        _ => None,
    }
}

/// Loads the DEM named by `spec`: a `synthetic:SIZE[:SEED]` spec, the path of a GeoTIFF, a
/// PNG (16-bit grayscale, or a terrain-RGB or Terrarium tile with [`LoadOptions::encoding`])
/// or an SRTM `.hgt` file (recognised by its first bytes, else by extension), the `http://` or
/// `https://` URL of a GeoTIFF, or a folder of GeoTIFFs (their mosaic, [`load_all`]), and
/// fills its voids.
pub fn load(spec: &str, opts: &LoadOptions) -> Result<Dem, DemError> {
    if spec == "embedded" || spec == EMBEDDED_SPEC {
        check_tile_options(spec, "the embedded terrain", opts)?;
        return embedded_default();
    }
    if let Some(rest) = spec.strip_prefix("synthetic:") {
        check_tile_options(spec, "a synthetic terrain", opts)?;
        return synthetic::load(spec, rest, opts);
    }
    if !is_url(spec) && Path::new(spec).is_dir() {
        return load_all(&[spec], opts);
    }
    let raw = read_file(spec, opts)?;
    finish(&shown_source(spec), raw, opts)
}

/// `source` (inputs joined by " + ") as messages and the [`Dem`] name it: URLs without their
/// query strings ([`http_range::without_query`]), files as given.
fn shown_source(source: &str) -> String {
    source
        .split(" + ")
        .map(|part| match is_url(part) {
            true => http_range::without_query(part),
            false => part,
        })
        .collect::<Vec<_>>()
        .join(" + ")
}

/// Loads one DEM ([`load`]) or, given several inputs, the mosaic of them ([`mosaic`]): what
/// every command that reads a DEM calls. A folder stands for the GeoTIFFs in it
/// ([`mosaic::folder_tiffs`]).
pub fn load_all<S: AsRef<str>>(specs: &[S], opts: &LoadOptions) -> Result<Dem, DemError> {
    let mut expanded = Vec::with_capacity(specs.len());
    for spec in specs {
        let spec = spec.as_ref();
        if !is_url(spec) && Path::new(spec).is_dir() {
            expanded.extend(mosaic::folder_tiffs(spec)?);
        } else {
            expanded.push(spec.to_string());
        }
    }
    match expanded.as_slice() {
        [] => Err(DemError::BadOptions {
            input: "the command line".into(),
            detail: "no DEM given".into(),
        }),
        [one] => load(one, opts),
        many => {
            let specs: Vec<&str> = many.iter().map(String::as_str).collect();
            let (source, raw) = mosaic::join(&specs, opts)?;
            finish(&shown_source(&source), raw, opts)
        }
    }
}

/// Whether `spec` names a remote file, read by HTTP range requests.
pub fn is_url(spec: &str) -> bool {
    let lower = spec.get(..8).unwrap_or(spec).to_ascii_lowercase();
    lower.starts_with("http://") || lower.starts_with("https://")
}

/// Reads the samples of the file or URL `path`, by its format, before checks and void filling.
pub fn read_file(path: &str, opts: &LoadOptions) -> Result<RawGrid, DemError> {
    if is_url(path) {
        check_tile_options(path, "a GeoTIFF URL", opts)?;
        return geotiff::read_url(path, opts);
    }
    let io = |source| DemError::Io {
        path: path.into(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    let len = file.metadata().map_err(io)?.len();
    let mut file = BufReader::new(cog::Counting::new(file, len));
    let head = file.fill_buf().map_err(io)?;
    match sniff(path, head) {
        Some(Format::Png) => match opts.encoding {
            Some(enc) => rgb_tile::read(path, file, enc, opts),
            None if opts.tile.is_some() => Err(DemError::BadOptions {
                input: path.into(),
                detail: "--tile places a terrain-RGB or Terrarium tile; say which with \
                         --encoding terrain-rgb or --encoding terrarium"
                    .into(),
            }),
            None => png::read(path, file, opts),
        },
        Some(Format::Tiff) => {
            check_tile_options(path, "a GeoTIFF", opts)?;
            // Unbuffered: the TIFF reader seeks to each chunk (a seek empties a BufReader),
            // and its decompressors buffer for themselves; so the count is what was needed.
            let mut file = file.into_inner();
            file.seek(SeekFrom::Start(0)).map_err(io)?;
            geotiff::read(path, file, opts)
        }
        Some(Format::Hgt) => {
            check_tile_options(path, "an SRTM .hgt file", opts)?;
            crate::formats::hgt::read(path, len, file, opts)
        }
        None => Err(DemError::UnknownFormat { path: path.into() }),
    }
}

/// A file's size and place, without its samples.
#[derive(Clone, Debug)]
pub struct Layout {
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Ground spacing, or why there is none.
    pub spacing: Result<(f64, f64), String>,
    /// Where it lies, if it says.
    pub georef: Option<Georef>,
    /// What finding out read.
    pub io: IoStats,
}

/// A GeoTIFF's layout from its directory.
fn tiff_layout<R: cog::Source>(mut t: cog::TiffWindows<R>) -> Layout {
    Layout {
        width: t.width(),
        height: t.height(),
        spacing: t.spacing(),
        georef: t.georef(),
        io: t.io(),
    }
}

/// The size and place of the file or URL `path`: a GeoTIFF's from its directory alone (no
/// sample decoded; a URL costs its first block), any other format's by reading it whole and
/// letting the samples go. Where a GeoTIFF's directory cannot be read, the whole read says
/// why.
pub fn read_layout(path: &str, opts: &LoadOptions) -> Result<Layout, DemError> {
    let directory = || -> Option<Layout> {
        if is_url(path) {
            let reader = http_range::RangeReader::open(path).ok()?;
            return cog::TiffWindows::open(path, reader, opts)
                .ok()
                .map(tiff_layout);
        }
        let mut file = std::fs::File::open(path).ok()?;
        let len = file.metadata().ok()?.len();
        let mut head = [0u8; 4];
        std::io::Read::read_exact(&mut file, &mut head).ok()?;
        if sniff(path, &head) != Some(Format::Tiff) {
            return None;
        }
        file.seek(SeekFrom::Start(0)).ok()?;
        cog::TiffWindows::open(path, cog::Counting::new(file, len), opts)
            .ok()
            .map(tiff_layout)
    };
    if let Some(layout) = directory() {
        return Ok(layout);
    }
    let raw = read_file(path, opts)?;
    Ok(Layout {
        width: raw.width,
        height: raw.height,
        spacing: raw.spacing,
        georef: raw.georef,
        io: raw.io,
    })
}

/// Refuses `--encoding` and `--tile` for input that is not a terrain tile, rather than
/// ignoring them.
fn check_tile_options(input: &str, what: &str, opts: &LoadOptions) -> Result<(), DemError> {
    let flag = match (opts.encoding, opts.tile) {
        (Some(_), _) => "--encoding",
        (None, Some(_)) => "--tile",
        (None, None) => return Ok(()),
    };
    Err(DemError::BadOptions {
        input: input.into(),
        detail: format!(
            "{flag} reads terrain-RGB and Terrarium PNG tiles, and this is {what}; leave it out"
        ),
    })
}

/// Checks raw samples (see the module docs), applies spacing overrides and fills voids.
pub fn finish(source: &str, mut raw: RawGrid, opts: &LoadOptions) -> Result<Dem, DemError> {
    check_size(source, raw.width, raw.height, opts)?;
    let n = raw.width as usize * raw.height as usize;
    if raw.heights.len() != n || raw.voids.len() != n {
        return Err(DemError::Unsupported {
            path: source.into(),
            detail: format!(
                "{} samples for a {}x{} grid",
                raw.heights.len(),
                raw.width,
                raw.height
            ),
        });
    }
    let at = |i: usize| {
        (
            (i % raw.width as usize) as u32,
            (i / raw.width as usize) as u32,
        )
    };
    let (mut nan, mut first_nan) = (0u64, 0usize);
    let (mut absurd, mut first_absurd) = (0u64, 0usize);
    for (i, h) in raw.heights.iter().enumerate() {
        if h.is_nan() {
            if !raw.voids.get(i) {
                first_nan = if nan == 0 { i } else { first_nan };
                nan += 1;
            }
        } else if h.abs() > ABSURD_HEIGHT_M && !raw.voids.get(i) {
            first_absurd = if absurd == 0 { i } else { first_absurd };
            absurd += 1;
        }
    }
    if nan > 0 && !raw.nan_is_void {
        let (col, row) = at(first_nan);
        return Err(DemError::NaN {
            input: source.into(),
            count: nan,
            col,
            row,
        });
    }
    if absurd > 0 {
        let (col, row) = at(first_absurd);
        return Err(DemError::Absurd {
            input: source.into(),
            count: absurd,
            value: raw.heights[first_absurd],
            col,
            row,
        });
    }
    if nan > 0 {
        for (i, h) in raw.heights.iter().enumerate() {
            if h.is_nan() {
                raw.voids.set(i);
            }
        }
    }
    if raw.voids.count() == n as u64 {
        return Err(DemError::AllVoid(source.into()));
    }
    let spacing = spacing(source, &raw.spacing, opts)?;
    let georef = georef(source, raw.georef.take(), spacing, opts)?;
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
        crs: georef.as_ref().map(Georef::crs).or(raw.crs),
        georef,
        io: raw.io,
    })
}

/// The grid's georeference: the file's, or one placed by `--origin`, which a georeferenced
/// file refuses (its own tags say where it lies). The CRS must be one Relief can convert.
fn georef(
    source: &str,
    file: Option<Georef>,
    spacing: (f64, f64),
    opts: &LoadOptions,
) -> Result<Option<Georef>, DemError> {
    let bad = |detail: String| DemError::BadOptions {
        input: source.into(),
        detail,
    };
    let g = match (file, opts.origin) {
        (Some(g), None) => g,
        (Some(g), Some(_)) => {
            return Err(bad(format!(
                "--origin places input without a georeference, and this file has one ({})",
                g.crs()
            )));
        }
        (None, Some(origin)) => Georef::around(origin, spacing).map_err(|e| bad(e.to_string()))?,
        (None, None) => return Ok(None),
    };
    GeoTransform::new(&g).map_err(|e| bad(e.to_string()))?;
    Ok(Some(g))
}

/// The ground spacing: the caller's overrides, else the file's, checked to be positive.
fn spacing(
    source: &str,
    file: &Result<(f64, f64), String>,
    opts: &LoadOptions,
) -> Result<(f64, f64), DemError> {
    let err = |detail: String| DemError::Spacing {
        input: source.into(),
        detail,
    };
    let s = match (opts.spacing_x, opts.spacing_y, file) {
        (Some(x), Some(y), _) => (x, y),
        (x, y, Ok((fx, fy))) => (x.unwrap_or(*fx), y.unwrap_or(*fy)),
        (_, _, Err(why)) => {
            return Err(err(format!(
                "no ground spacing: {why}; give --spacing-x and --spacing-y in metres"
            )));
        }
    };
    if !(s.0.is_finite() && s.1.is_finite() && s.0 > 0.0 && s.1 > 0.0) {
        return Err(err(format!(
            "ground spacing {} x {} m must be positive and finite",
            s.0, s.1
        )));
    }
    Ok(s)
}

/// The crop of Mt Fuji shipped with the server (see `server/data/README.md`).
pub const EMBEDDED_FUJI: &[u8] = include_bytes!("../../data/fuji_crop.tif");

/// The name the embedded default terrain goes by (its source in store metadata and logs).
pub const EMBEDDED_SPEC: &str = "embedded:fuji_crop.tif";

/// The embedded default terrain: the 257 x 193 Mt Fuji crop, decoded and void-filled.
pub fn embedded_default() -> Result<Dem, DemError> {
    let name = EMBEDDED_SPEC;
    let opts = LoadOptions::default();
    let bytes = std::io::Cursor::new(EMBEDDED_FUJI);
    let raw = geotiff::read(
        name,
        cog::Counting::new(bytes, EMBEDDED_FUJI.len() as u64),
        &opts,
    )?;
    finish(name, raw, &opts)
}

#[cfg(test)]
mod tests;
