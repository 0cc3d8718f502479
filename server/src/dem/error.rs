//! [`DemError`]: why a DEM could not be loaded, one variant per problem, each message naming the
//! input and what to do about it where there is something to do.

use super::ABSURD_HEIGHT_M;

/// Why a DEM could not be loaded. Each message names the input and the problem.
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
    /// A remote file could not be read: the server's status, a broken or cut-short answer, or a
    /// connection that failed. `url` leaves out the query string, which may hold credentials.
    #[error("{url}: {detail}")]
    Http {
        /// The URL, without its query string.
        url: String,
        /// What went wrong, in words.
        detail: String,
    },
    /// The server sent the whole file in answer to a range request: reading a large file that
    /// way would download all of it for every few tiles, so Relief refuses.
    #[error(
        "the server at {url} does not support HTTP range requests (it answered 200 to a Range request); serve it from one that does (S3, GCS, nginx) or download it first"
    )]
    NoRanges {
        /// The URL, without its query string.
        url: String,
    },
    /// The file is neither a TIFF nor a PNG by its first bytes, nor named as one of the formats
    /// Relief reads.
    #[error(
        "{path}: unknown file format; Relief reads GeoTIFF (.tif, .tiff), 16-bit grayscale PNG (.png), terrain-RGB and Terrarium PNG tiles (.png with --encoding), SRTM .hgt and synthetic:SIZE[:SEED]"
    )]
    UnknownFormat {
        /// The file.
        path: String,
    },
    /// The file is not a valid image of its kind (truncated or corrupt).
    #[error("{path}: not a readable {kind} (truncated or corrupt): {detail}")]
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
        "{input}: {width}x{height} = {samples} samples exceeds the limit of {limit}; a build \
         holds it in memory, about {gib:.1} GiB here, so the default limit is what fits in this \
         machine's memory; raise it with --max-samples",
        gib = *samples as f64 * super::BUILD_BYTES_PER_SAMPLE as f64 / (1u64 << 30) as f64
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
        "{input}: {count} samples are not plausible terrain heights (limit +-{ABSURD_HEIGHT_M} m), the first {value} m at column {col}, row {row}; is an undeclared no-data value or a wrong unit in play?"
    )]
    Absurd {
        /// The input.
        input: String,
        /// How many samples are absurd.
        count: u64,
        /// The first absurd value.
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
    /// Read options that make no heights or no place (non-finite PNG scale or offset, an
    /// `--origin` off the globe or given to a georeferenced file).
    #[error("{input}: {detail}")]
    BadOptions {
        /// The input.
        input: String,
        /// What is wrong.
        detail: String,
    },
    /// Input whose place on the Earth cannot be told: an `.hgt` file's name, a tile without
    /// z/x/y.
    #[error("{input}: cannot tell where it lies: {detail}")]
    Place {
        /// The input.
        input: String,
        /// What is missing and how to give it.
        detail: String,
    },
    /// An input that does not fit the mosaic of the ones before it (another CRS or grid step,
    /// off their grid, no georeference).
    #[error("{input}: cannot join it to the mosaic: {detail}")]
    Mosaic {
        /// The input.
        input: String,
        /// What does not fit.
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
