//! `relief-server build`: a DEM in, a store out.

use crate::dem::Dem;
use crate::geo::GeoTransform;
use crate::store::{StoreError, StoreInput, StoreMeta, write_store};
use relief_proto::tile::body::MeshKind;
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
    use rayon::prelude::*;
    let integral = dem
        .heights
        .par_iter()
        .enumerate()
        .filter(|&(i, _)| !dem.is_void(i))
        .all(|(_, h)| h.fract() == 0.0);
    if integral { 1.0 } else { 0.1 }
}

/// Checks that heights from `lo` to `hi` metres keep their relief under a z quantum of `q`
/// metres: every height fits the store's 24-bit integers, and the range does not round to
/// nothing. Heights are stored as whole quanta, so an out-of-range quantum would otherwise
/// corrupt every height silently (clamped to the integer range, or all rounded to zero).
pub fn check_quantum(q: f64, lo: f64, hi: f64) -> Result<(), String> {
    if !(q.is_finite() && q > 0.0) {
        return Err(format!(
            "the z quantum must be a positive number of metres, got {q}"
        ));
    }
    let reach = lo.abs().max(hi.abs());
    let limit = f64::from(crate::store::layout::Z_LIMIT);
    if reach / q > limit {
        return Err(format!(
            "a z quantum of {q} m cannot hold heights from {lo} to {hi} m in the store's 24-bit              integers; use at least {:.3e} m",
            reach / limit
        ));
    }
    if hi > lo && q > hi - lo {
        return Err(format!(
            "a z quantum of {q} m is larger than the terrain's height range ({lo} to {hi} m):              every height would round to nearly the same value; use at most {} m",
            hi - lo
        ));
    }
    Ok(())
}

/// How to build a store.
#[derive(Clone, Copy, Debug)]
pub struct BuildOptions {
    /// Metres per stored height unit (`None`: [`default_quantum`]).
    pub quantum: Option<f64>,
    /// Cells per side of the tile pyramid's tiles.
    pub tile_size: u32,
    /// The tile pyramid's mesh kind.
    pub tile_mesh: MeshKind,
    /// Show a progress bar.
    pub progress: bool,
}

impl Default for BuildOptions {
    /// The default quantum, 64-cell grid tiles, no progress bar.
    fn default() -> Self {
        BuildOptions {
            quantum: None,
            tile_size: crate::store::DEFAULT_TILE_SIZE,
            tile_mesh: MeshKind::Grid,
            progress: false,
        }
    }
}

/// The pool a build runs on (every parallel step of reading and building uses rayon's pool):
/// `threads` threads, or one per core.
pub fn thread_pool(threads: Option<usize>) -> Result<rayon::ThreadPool, String> {
    let threads =
        threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    if threads == 0 {
        return Err("--threads must be at least 1".into());
    }
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| format!("cannot start {threads} build threads: {e}"))
}

/// Builds the store of `dem` (the vertex quadtree and the tile pyramid) at `path`.
pub fn build_store(dem: &Dem, path: &Path, opts: &BuildOptions) -> Result<BuildReport, StoreError> {
    build(dem, path, opts, None)
}

/// Builds the store of `dem` at `path` for the server's cache, recording `cache_key` (see
/// [`crate::store::StoreMeta::cache_key`]); default quantum, tile size and mesh.
pub fn build_cached_store(
    dem: &Dem,
    path: &Path,
    cache_key: &str,
) -> Result<BuildReport, StoreError> {
    let opts = BuildOptions {
        progress: true,
        ..BuildOptions::default()
    };
    build(dem, path, &opts, Some(cache_key.to_string()))
}

/// The source as a store records it: each input by its file name, without its folder, so
/// that the same DEM built from different places gives byte-identical stores (and one terrain
/// id across replicas). A URL is recorded by its last path segment, without the query string
/// (which may hold a presigned URL's credentials and changes with each signature). Mosaics
/// join their inputs with " + ".
fn recorded_source(source: &str) -> String {
    source
        .split(" + ")
        .map(|part| {
            if crate::dem::is_url(part) {
                let path = crate::dem::http_range::without_query(part);
                return match path.rsplit('/').next() {
                    Some(name) if !name.is_empty() => name.to_string(),
                    _ => path.to_string(),
                };
            }
            let p = Path::new(part);
            match p.file_name() {
                Some(name) if p.parent().is_some_and(|d| !d.as_os_str().is_empty()) => {
                    name.to_string_lossy().to_string()
                }
                _ => part.to_string(),
            }
        })
        .collect::<Vec<_>>()
        .join(" + ")
}

fn build(
    dem: &Dem,
    path: &Path,
    opts: &BuildOptions,
    cache_key: Option<String>,
) -> Result<BuildReport, StoreError> {
    let (quantum, tile_size, progress) = (opts.quantum, opts.tile_size, opts.progress);
    let quantum = quantum.unwrap_or_else(|| default_quantum(dem));
    use rayon::prelude::*;
    let (lo, hi) = dem
        .heights
        .par_iter()
        .fold(|| (f32::MAX, f32::MIN), |(a, b), &h| (a.min(h), b.max(h)))
        .reduce(|| (f32::MAX, f32::MIN), |x, y| (x.0.min(y.0), x.1.max(y.1)));
    check_quantum(quantum, f64::from(lo), f64::from(hi)).map_err(StoreError::Input)?;
    let bounds = match &dem.georef {
        Some(g) => Some(
            GeoTransform::new(g)
                .and_then(|t| t.bounds(dem.width, dem.height))
                .map_err(|e| StoreError::Input(e.to_string()))?,
        ),
        None => None,
    };
    let input = StoreInput {
        width: dem.width,
        height: dem.height,
        spacing_x: dem.spacing_x,
        spacing_y: dem.spacing_y,
        z_quantum: quantum,
        heights: &dem.heights,
        voids: &dem.voids,
        tile_size,
        meta: StoreMeta {
            source: recorded_source(&dem.source),
            crs: dem.crs.clone(),
            height_min: lo as f64,
            height_max: hi as f64,
            void_count: dem.voids.count(),
            cache_key,
            tile_mesh: opts.tile_mesh.name().into(),
            georef: dem.georef.clone(),
            bounds,
        },
    };
    let samples = u64::from(dem.width) * u64::from(dem.height);
    if opts.tile_mesh == MeshKind::Tin {
        let need = samples * crate::dem::TIN_BUILD_BYTES_PER_SAMPLE;
        if let Some(have) = crate::sysmem::usable_memory().filter(|&m| need > m) {
            tracing::warn!(
                "tin tiles triangulate a second copy of the grid: about {:.1} GiB for {samples} \
                 samples, more than the {:.1} GiB this process may use; `grid` and `rqt` tiles \
                 need about half of that",
                need as f64 / (1u64 << 30) as f64,
                have as f64 / (1u64 << 30) as f64
            );
        }
    }
    let bar = crate::bench::build_progress_bar(progress, samples);
    let (bytes, tree_s, tiles_s) = write_store(path, &input, |f| {
        let tree = f < crate::store::TREE_SHARE;
        bar.set_message(if tree { "vertex tree" } else { "tile pyramid" });
        bar.set_position((f * samples as f64) as u64)
    })?;
    bar.finish_and_clear();
    Ok(BuildReport {
        bytes,
        tree_s,
        tiles_s,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn opts(quantum: Option<f64>) -> BuildOptions {
        BuildOptions {
            quantum,
            ..BuildOptions::default()
        }
    }

    #[test]
    fn a_quantum_that_would_corrupt_heights_is_refused() {
        // Hostile input: at 1e-9 m every height became 2.147 m (clamped), at 1e9 m 0 m.
        let d = crate::dem::embedded_default().unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("q.relief");
        for (q, needle) in [(1e-9, "24-bit"), (1e9, "height range"), (-1.0, "positive")] {
            let e = build_store(&d, &path, &opts(Some(q)))
                .unwrap_err()
                .to_string();
            assert!(e.contains(needle), "{q}: {e}");
            assert!(!path.exists());
        }
        assert!(build_store(&d, &path, &opts(Some(0.01))).is_ok());
        assert!(
            check_quantum(1.0, 5.0, 5.0).is_ok(),
            "a flat terrain takes any quantum"
        );
        assert!(check_quantum(1e-4, -800.0, 800.0).is_ok());
        assert!(check_quantum(1e-4, -900.0, 800.0).is_err());
    }

    #[test]
    fn recorded_sources_keep_file_names_only() {
        for (source, recorded) in [
            ("/data/dem/N35E138.hgt", "N35E138.hgt"),
            ("fuji.tif", "fuji.tif"),
            ("a/x.tif + /b/y.tif", "x.tif + y.tif"),
            (
                "https://b.s3.amazonaws.com/dem/fuji.tif?X-Amz-Signature=abc",
                "fuji.tif",
            ),
            ("HTTP://127.0.0.1:8080/cog/fuji.tif#frag", "fuji.tif"),
            ("http://host/a.tif + /local/b.tif", "a.tif + b.tif"),
            ("http://host/", "http://host/"),
        ] {
            assert_eq!(recorded_source(source), recorded, "{source}");
        }
    }
}
