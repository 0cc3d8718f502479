//! Where the terrain lies on the Earth: the store's georeference and the WGS 84 ellipsoid.
//!
//! - [`georef`]: [`Georef`], how a DEM's sample grid sits in its CRS, and [`GeoTransform`],
//!   which converts between sample positions and longitude/latitude (projected CRSs through
//!   `proj4rs`, a maintained pure-Rust port of PROJ.4 with the EPSG definitions built in).
//! - [`tiling`]: the global tile schemes of the standard formats: Cesium's geographic one and
//!   Web Mercator XYZ.
//! - [`ellipsoid`]: WGS 84 constants, metres per degree, geodetic to Earth-centred coordinates.
//! - [`mercator`]: Web Mercator (EPSG:3857) and its XYZ tiles, the scheme of web map tiles.
//!
//! The standard formats (`crate::formats`) resample the store onto their tile schemes through
//! these.

pub mod ellipsoid;
pub mod georef;
pub mod mercator;
pub mod tiling;

pub use georef::{GeoError, GeoTransform, Georef, LonLatBounds};
