//! The standard formats Relief speaks besides its own streams (DESIGN.md section 6b), each
//! resampled from the store through its georeference, and the ones it reads.
//!
//! - [`sampler`]: the store's heights at longitudes and latitudes of a tile scheme.
//! - [`quantized_mesh`]: Cesium's `quantized-mesh-1.0` (`.terrain`) encoder and decoder.
//! - [`cesium`]: Cesium terrain: the layer (availability, `layer.json`) and tile meshes.
//! - [`terrain_rgb`]: the terrain-RGB and Terrarium height encodings, and their PNGs.
//! - [`raster`]: Web Mercator PNG elevation tiles for MapLibre, and their TileJSON.
//! - [`hgt`]: the SRTM `.hgt` reader.

pub mod cesium;
pub mod hgt;
pub mod quantized_mesh;
pub mod raster;
pub mod sampler;
pub mod terrain_rgb;
