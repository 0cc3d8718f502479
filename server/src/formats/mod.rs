//! Standard terrain tile formats Relief can serve besides its own stream.
//!
//! - [`quantized_mesh`]: Cesium's `quantized-mesh-1.0` (`.terrain`) encoder and decoder.

pub mod quantized_mesh;
