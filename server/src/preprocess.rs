//! `relief-server build`: a DEM in, a store out.

use crate::dem::Dem;
use crate::store::{StoreError, StoreInput, StoreMeta, write_store};
use std::path::Path;

/// What a build produced.
#[derive(Clone, Copy, Debug)]
pub struct BuildReport {
    /// Size of the store file, bytes.
    pub bytes: u64,
    /// Seconds spent building the tree (excluding reading the DEM and writing the file).
    pub tree_s: f64,
    /// Seconds spent building the tile pyramid.
    pub tiles_s: f64,
}

/// The z quantum a DEM gets when none is asked for: 1 m when every valid sample is a whole
/// number of metres (integer DEMs: lossless), else 0.1 m (at most 5 cm of rounding).
pub fn default_quantum(dem: &Dem) -> f64 {
    let integral = dem
        .heights
        .iter()
        .enumerate()
        .filter(|&(i, _)| !dem.is_void(i))
        .all(|(_, h)| h.fract() == 0.0);
    if integral { 1.0 } else { 0.1 }
}

/// Builds the vertex-quadtree store of `dem` at `path`.
pub fn build_store(
    dem: &Dem,
    path: &Path,
    quantum: Option<f64>,
    tile_size: u32,
    progress: bool,
) -> Result<BuildReport, StoreError> {
    let quantum = quantum.unwrap_or_else(|| default_quantum(dem));
    let voids: Vec<bool> = (0..dem.heights.len()).map(|i| dem.is_void(i)).collect();
    let (lo, hi) = dem
        .heights
        .iter()
        .fold((f32::MAX, f32::MIN), |(a, b), &h| (a.min(h), b.max(h)));
    let input = StoreInput {
        width: dem.width,
        height: dem.height,
        spacing_x: dem.spacing_x,
        spacing_y: dem.spacing_y,
        z_quantum: quantum,
        heights: &dem.heights,
        voids: &voids,
        tile_size,
        meta: StoreMeta {
            source: dem.source.clone(),
            crs: dem.crs.clone(),
            height_min: lo as f64,
            height_max: hi as f64,
            void_count: voids.iter().filter(|v| **v).count() as u64,
        },
    };
    let bar = crate::bench::progress_bar(progress, 1000, "tree and tiles");
    let (bytes, tree_s, tiles_s) =
        write_store(path, &input, |f| bar.set_position((f * 1000.0) as u64))?;
    bar.finish_and_clear();
    Ok(BuildReport {
        bytes,
        tree_s,
        tiles_s,
    })
}
