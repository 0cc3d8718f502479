//! Standard terrain formats, so that Relief plugs into the tools users already have:
//!
//! - [`terrain_rgb`]: Mapbox terrain-RGB and Mapzen/AWS Terrarium, heights as the colours of
//!   8-bit RGB PNG tiles (MapLibre GL's `raster-dem` sources), with exact rounding. Read as DEM
//!   input by `crate::dem::rgb_tile` (`--encoding`).
//! - [`hgt`]: SRTM `.hgt` files, big-endian 16-bit grids placed by their names; read as DEM
//!   input by `crate::dem::load`.
//!
//! The codecs here are pure: bytes and heights in, bytes and heights out. Where the samples lie
//! on the Earth is `crate::geo`'s business (Web Mercator tiles: `crate::geo::mercator`).

pub mod hgt;
pub mod terrain_rgb;
