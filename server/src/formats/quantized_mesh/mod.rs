//! Cesium's `quantized-mesh-1.0` terrain tiles (`.terrain`): an encoder, and a full decoder for
//! tests and tools. Pure functions on bytes; no I/O.
//!
//! The layout (spec: the `CesiumGS/quantized-mesh` README), all little-endian:
//! 1. an 88-byte header: the tile's centre (ECEF, `f64` x3), minimum and maximum height (`f32`
//!    x2), bounding sphere (`f64` x4), horizon occlusion point (`f64` x3, ellipsoid-scaled);
//! 2. `vertexCount: u32`, then all u, all v, all heights, each `u16` delta-coded and zig-zagged
//!    (u and v 0..=32767 west to east and south to north, height 0..=32767 from the minimum to
//!    the maximum height);
//! 3. padding to 2 (16-bit indices) or 4 bytes (32-bit, when there are more than 65536
//!    vertices), `triangleCount: u32` and the high-water-mark coded indices;
//! 4. the west, south, east and north edge lists (`u32` count, then plain indices);
//! 5. extensions, each `id: u8`, `length: u32`, data: `octvertexnormals` (1) and `metadata` (4).
//!
//! Modules:
//! - [`ellipsoid`]: WGS84 geodetic to ECEF, bounding sphere, horizon occlusion point;
//! - [`normals`]: area-weighted vertex normals and their oct encoding;
//! - [`extensions`]: the extensions an `Accept` header asks for; availability metadata JSON;
//! - `encode` and `decode`: [`encode`] a [`QmMesh`], [`decode`] bytes into a [`QmTile`].
//!
//! The encoder renumbers the vertices in the order the triangles first use them (the
//! high-water-mark code needs it); [`vertex_order`] tells that order.

mod decode;
pub mod ellipsoid;
mod encode;
pub mod extensions;
pub mod normals;
#[cfg(test)]
mod tests;

pub use crate::geo::tiling::TileRange;
pub use decode::{QmHeader, QmTile, decode, hwm_decode, zigzag_decode};
pub use encode::{encode, hwm_encode, vertex_order, zigzag_encode};
pub use extensions::{RequestedExtensions, availability_metadata, extensions_from_accept};

/// The largest quantized u, v or height (the east and north edges, the maximum height).
pub const QUANT_MAX: u16 = 32767;
/// Up to this many vertices the indices are 16-bit; above it, 32-bit.
pub const MAX_VERTICES_16: usize = 65536;
/// The bytes of the header.
pub const HEADER_LEN: usize = 88;
/// The extension id of oct-encoded per-vertex normals (`octvertexnormals`).
pub const EXT_OCT_NORMALS: u8 = 1;
/// The extension id of the water mask (`watermask`; decoded as unknown, never written).
pub const EXT_WATER_MASK: u8 = 2;
/// The extension id of the JSON metadata (`metadata`).
pub const EXT_METADATA: u8 = 4;

/// The value of a quantized `q` (0..=32767) between `lo` and `hi`, as decoders compute it.
pub fn dequantize(q: u16, lo: f64, hi: f64) -> f64 {
    lo + f64::from(q) / f64::from(QUANT_MAX) * (hi - lo)
}

/// A triangle mesh over one tile, in geographic coordinates (EPSG:4326, WGS84).
#[derive(Debug, Clone, PartialEq)]
pub struct QmMesh {
    /// Western edge, degrees of longitude.
    pub west: f64,
    /// Southern edge, degrees of latitude.
    pub south: f64,
    /// Eastern edge, degrees of longitude.
    pub east: f64,
    /// Northern edge, degrees of latitude.
    pub north: f64,
    /// `[lon, lat, height]`: degrees, degrees, metres above the ellipsoid. Longitude and
    /// latitude lie within the bounds; the encoder rounds them to the 32767-step grid.
    pub vertices: Vec<[f64; 3]>,
    /// Vertex indices, counter-clockwise seen from above.
    pub triangles: Vec<[u32; 3]>,
}

/// The extensions to write after the mesh, in the order of their ids.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct QmExtensions {
    /// Write `octvertexnormals` (id 1).
    pub normals: bool,
    /// Write `metadata` (id 4) with this JSON (see [`availability_metadata`]).
    pub metadata: Option<String>,
}

/// Why a mesh could not be encoded or bytes could not be decoded.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum QmError {
    /// No vertices or no triangles.
    #[error("the mesh is empty ({vertices} vertices, {triangles} triangles); a tile needs both")]
    Empty {
        /// Vertices given.
        vertices: usize,
        /// Triangles given.
        triangles: usize,
    },
    /// More vertices or triangles than a `u32` count holds.
    #[error("{count} {what} do not fit the format's 32-bit count")]
    TooMany {
        /// `"vertices"` or `"triangles"`.
        what: &'static str,
        /// How many were given.
        count: usize,
    },
    /// A triangle names a vertex that does not exist.
    #[error("triangle {triangle} uses vertex {index}, but the mesh has {vertices} vertices")]
    IndexOutOfRange {
        /// The triangle.
        triangle: usize,
        /// The index it holds.
        index: u32,
        /// Vertices in the mesh.
        vertices: usize,
    },
    /// A NaN or infinite input, or a height beyond `f32`.
    #[error("{what} is not a finite number (or too large for the format)")]
    NonFinite {
        /// Which input.
        what: String,
    },
    /// The bounds are empty, inverted or outside -180..=180, -90..=90.
    #[error(
        "bounds west {west}, south {south}, east {east}, north {north} are not a tile (need -180 <= west < east <= 180, -90 <= south < north <= 90)"
    )]
    BadBounds {
        /// Western edge.
        west: f64,
        /// Southern edge.
        south: f64,
        /// Eastern edge.
        east: f64,
        /// Northern edge.
        north: f64,
    },
    /// A vertex lies outside the tile.
    #[error("vertex {index} at lon {lon}, lat {lat} lies outside the tile's bounds")]
    OutsideBounds {
        /// The vertex.
        index: usize,
        /// Its longitude.
        lon: f64,
        /// Its latitude.
        lat: f64,
    },
    /// The metadata JSON is longer than an extension can hold.
    #[error("the metadata JSON is {len} bytes; an extension holds at most 2^32 - 5")]
    MetadataTooLong {
        /// Its length in bytes.
        len: usize,
    },
    /// The bytes end before a field does.
    #[error("truncated: {what} at byte {at} needs {need} bytes, {left} are left")]
    Truncated {
        /// The field.
        what: &'static str,
        /// Where it starts.
        at: usize,
        /// Bytes it needs.
        need: u64,
        /// Bytes left.
        left: usize,
    },
    /// A field holds a value the format does not allow.
    #[error("invalid tile at byte {at}: {why}")]
    Invalid {
        /// Where the field starts.
        at: usize,
        /// What is wrong.
        why: String,
    },
}
