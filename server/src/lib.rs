//! `relief-server`: preprocessing, LOD engines and benchmarks of the Relief terrain server.
//!
//! - [`store`]: the preprocessed vertex-quadtree store: build, file format, memory-mapped reader.
//! - [`lod`]: the LOD engines (vertex stream today), camera paths and pixel-error measurement.
pub mod lod;
pub mod store;
