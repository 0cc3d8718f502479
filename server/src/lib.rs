//! `relief-server`: preprocessing, LOD engines and benchmarks of the Relief terrain server.
//!
//! - [`dem`]: DEM readers (GeoTIFF, PNG, synthetic) and void filling.
//! - [`formats`]: the standard formats (Cesium quantized-mesh, terrain-RGB, Terrarium, hgt).
//! - [`geo`]: the georeference (CRS, lon/lat conversion, proj4rs) and the WGS 84 ellipsoid.
//! - [`store`]: the preprocessed vertex-quadtree store: build, file format, memory-mapped reader.
//! - [`preprocess`]: a DEM in, a store out.
//! - [`lod`]: the LOD engines (vertex stream today) and pixel-error measurement.
//! - [`query`]: terrain queries (paper 004): heights, normals, rays, lines of sight, HAT/HOT.
//! - [`bench`]: in-process benchmarks.
//! - [`cli`]: the `relief-server` command line.
//! - [`serve`]: the streaming server: WebSocket sessions, HTTP API, limits, metrics, drain.
//! - [`sysmem`]: the memory this process may use (cgroup or machine).
/// jemalloc instead of the system allocator, for every program that links the server (the
/// `relief-server` binary, the tests' child server): under session churn glibc malloc keeps the
/// memory sessions free (a 2-minute soak of 500 cycling sessions: RSS +8 % while live data was
/// flat; 108 MiB held with 1.6 MB in use after the last session closed), jemalloc gives it back
/// (the same soak: flat within 3.5 %, 25 % less). See `docs/soak/summary.md`.
#[cfg(not(target_env = "msvc"))]
#[global_allocator]
static GLOBAL: tikv_jemallocator::Jemalloc = tikv_jemallocator::Jemalloc;

/// Starts jemalloc's background threads, which give freed memory back to the system about 10 s
/// after it is freed. Without them jemalloc purges an arena only when it is used again, so a
/// server that goes quiet after a burst (answers cut off by the write timeout, sessions closed
/// over the memory budget) would keep the burst's peak resident for good: 1.0 GB held a minute
/// after 60 clients' 10 MB answers were dropped, against 0.23 GB with them. Where the
/// allocator cannot (or is not jemalloc), nothing changes.
pub fn return_freed_memory() {
    #[cfg(not(target_env = "msvc"))]
    if let Err(e) = tikv_jemalloc_ctl::background_thread::write(true) {
        tracing::debug!("jemalloc keeps freed memory until reuse: {e}");
    }
}

pub mod bench;
pub mod cli;
pub mod dem;
pub mod formats;
pub mod geo;
pub mod lod;
pub mod preprocess;
pub mod query;
pub mod serve;
pub mod store;
pub mod sysmem;
