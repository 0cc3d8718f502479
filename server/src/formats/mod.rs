//! The standard formats Relief speaks besides its own streams (DESIGN.md section 6b), each
//! resampled from the store through its georeference.
//!
//! - [`cesium`]: Cesium terrain: the layer (availability, `layer.json`) and tile meshes.
//! - [`sampler`]: the store's heights at longitudes and latitudes of a tile scheme.

pub mod cesium;
pub mod sampler;
