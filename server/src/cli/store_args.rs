//! What `build` and `bench build` both take: how the store is made, and on how many threads.

use super::TileMeshArg;
use crate::preprocess::BuildOptions;

/// The store's quantum, tile size and mesh kind, and the build's threads.
#[derive(clap::Args)]
pub(super) struct StoreArgs {
    /// Metres per stored height unit [default: 1 for whole-metre DEMs, else 0.1].
    #[arg(long)]
    z_quantum: Option<f64>,
    /// Cells per side of the tile stream's tiles: a power of two from 2 to 256 (64 gives
    /// Cesium's 65 x 65-vertex tiles).
    #[arg(long, default_value_t = crate::store::DEFAULT_TILE_SIZE)]
    tile_size: u32,
    /// How the tile stream's tiles are meshed: `grid` (every lattice vertex; crack
    /// patches or skirts), `rqt` (paper 002's restricted quadtree; crack curtains or
    /// skirts) or `tin` (paper 003's greedy Delaunay TIN with shared borders, or skirts).
    /// See docs/streams.md.
    #[arg(long, value_enum, default_value = "grid")]
    tile_mesh: TileMeshArg,
    /// Threads to read and build on [default: one per core]. The store is the same bytes
    /// whatever the number.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    threads: Option<u32>,
}

impl StoreArgs {
    /// The build options these arguments give, once the tile size is checked.
    pub(super) fn options(&self, progress: bool) -> anyhow::Result<BuildOptions> {
        relief_proto::tile::TileShape::new(2, 2, self.tile_size)?;
        Ok(BuildOptions {
            quantum: self.z_quantum,
            tile_size: self.tile_size,
            tile_mesh: self.tile_mesh.into(),
            progress,
        })
    }

    /// `--threads`, if given.
    pub(super) fn threads(&self) -> Option<usize> {
        self.threads.map(|t| t as usize)
    }
}
