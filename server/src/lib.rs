//! `relief-server`: preprocessing, LOD engines and benchmarks of the Relief terrain server.
//!
//! - [`dem`]: DEM readers (GeoTIFF, PNG, synthetic) and void filling.
//! - [`store`]: the preprocessed vertex-quadtree store: build, file format, memory-mapped reader.
//! - [`preprocess`]: a DEM in, a store out.
//! - [`lod`]: the LOD engines (vertex stream today) and pixel-error measurement.
//! - [`bench`]: in-process benchmarks.
//! - [`cli`]: the `relief-server` command line.
//! - [`serve`]: the streaming server: WebSocket sessions, HTTP API, limits, metrics, drain.
pub mod bench;
pub mod cli;
pub mod dem;
pub mod lod;
pub mod preprocess;
pub mod serve;
pub mod store;
