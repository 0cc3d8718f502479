//! The terrain a server holds: a store file as given, or a DEM (the embedded crop by default)
//! built into the cache folder on first start and mapped from there afterwards.
//!
//! Cache entries are named after what they were built from (the DEM spec, the file's size and
//! modification time, the store format version), so a changed DEM is built again and an
//! unchanged one is not. Builds go through a temporary file and a rename, so two servers
//! starting at once never map a half-written store.

use super::config::TerrainSource;
use crate::dem::{self, LoadOptions};
use crate::preprocess;
use crate::store::Store;
use std::hash::{Hash, Hasher};
use std::path::{Path, PathBuf};

/// Why a terrain could not be opened.
#[derive(Debug, thiserror::Error)]
pub enum SourceError {
    /// The DEM cannot be read.
    #[error("cannot load the DEM: {0}")]
    Dem(#[from] dem::DemError),
    /// The store cannot be built, written or opened.
    #[error("cannot use the store {path}")]
    Store {
        /// The store file.
        path: String,
        /// Why.
        source: crate::store::StoreError,
    },
    /// The store file given does not exist.
    #[error("the store {path} does not exist; build one with `relief-server build DEM -o {path}`")]
    Missing {
        /// The file.
        path: String,
    },
    /// The cache folder cannot be created.
    #[error("cannot create the cache folder {path}: {source}")]
    Cache {
        /// The folder.
        path: String,
        /// Why.
        source: std::io::Error,
    },
}

fn cache_key(spec: &str, opts: &LoadOptions) -> u64 {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    spec.hash(&mut h);
    // What changes the heights or the spacing changes the store.
    for v in [
        opts.png.scale,
        opts.png.offset,
        opts.spacing_x.unwrap_or(-1.0),
        opts.spacing_y.unwrap_or(-1.0),
    ] {
        v.to_bits().hash(&mut h);
    }
    opts.png.nodata_value.hash(&mut h);
    crate::store::format::VERSION.hash(&mut h);
    if let Ok(m) = std::fs::metadata(spec) {
        m.len().hash(&mut h);
        if let Ok(t) = m.modified() {
            t.hash(&mut h);
        }
    }
    h.finish()
}

/// The cache file for a DEM spec read with `opts`.
pub fn cached_store_path(cache_dir: &Path, spec: &str, opts: &LoadOptions) -> PathBuf {
    let stem: String = spec
        .rsplit('/')
        .next()
        .unwrap_or(spec)
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .take(40)
        .collect();
    cache_dir.join(format!("{stem}-{:016x}.relief", cache_key(spec, opts)))
}

/// Fails early, before the server listens, for a store file that is not there.
pub fn check_exists(source: &TerrainSource) -> Result<(), SourceError> {
    match source {
        TerrainSource::Store(p) if !p.exists() => Err(SourceError::Missing {
            path: p.display().to_string(),
        }),
        _ => Ok(()),
    }
}

fn open(path: &Path) -> Result<Store, SourceError> {
    Store::open(path).map_err(|source| SourceError::Store {
        path: path.display().to_string(),
        source,
    })
}

/// Opens the terrain, building and caching it first if needed. Blocking: call it off the
/// async runtime.
pub fn open_terrain(source: &TerrainSource, cache_dir: &Path) -> Result<Store, SourceError> {
    let defaults = LoadOptions::default();
    let (spec, opts) = match source {
        TerrainSource::Store(p) => return open(p),
        TerrainSource::Embedded => (dem::EMBEDDED_SPEC, &defaults),
        TerrainSource::Dem(s, o) => (s.as_str(), o),
    };
    let path = cached_store_path(cache_dir, spec, opts);
    if path.exists() {
        match open(&path) {
            Ok(s) => {
                tracing::info!("using cached store {}", path.display());
                return Ok(s);
            }
            Err(e) => {
                let why = std::error::Error::source(&e).map(|s| s.to_string());
                tracing::warn!(
                    "rebuilding the cached store: {e}: {}",
                    why.unwrap_or_default()
                );
            }
        }
    }
    std::fs::create_dir_all(cache_dir).map_err(|source| SourceError::Cache {
        path: cache_dir.display().to_string(),
        source,
    })?;
    let d = match source {
        TerrainSource::Embedded => dem::embedded_default()?,
        _ => dem::load(spec, opts)?,
    };
    tracing::info!(
        "building the store for {spec} ({}x{} samples) into {}",
        d.width,
        d.height,
        path.display()
    );
    preprocess::build_store(&d, &path, None, crate::store::DEFAULT_TILE_SIZE, true).map_err(
        |source| SourceError::Store {
            path: path.display().to_string(),
            source,
        },
    )?;
    open(&path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_embedded_terrain_is_built_once_then_reused() {
        let dir = tempfile::tempdir().unwrap();
        let a = open_terrain(&TerrainSource::Embedded, dir.path()).unwrap();
        let path = cached_store_path(dir.path(), dem::EMBEDDED_SPEC, &LoadOptions::default());
        let before = std::fs::metadata(&path).unwrap().modified().unwrap();
        let b = open_terrain(&TerrainSource::Embedded, dir.path()).unwrap();
        assert_eq!(a.terrain_id(), b.terrain_id());
        assert_eq!(
            std::fs::metadata(&path).unwrap().modified().unwrap(),
            before
        );
    }

    #[test]
    fn a_corrupt_cache_entry_is_rebuilt() {
        let dir = tempfile::tempdir().unwrap();
        let path = cached_store_path(dir.path(), dem::EMBEDDED_SPEC, &LoadOptions::default());
        std::fs::write(&path, b"not a store").unwrap();
        let s = open_terrain(&TerrainSource::Embedded, dir.path()).unwrap();
        assert_eq!(s.geometry().shape.width(), 257);
    }

    #[test]
    fn a_missing_store_is_named() {
        let e = open_terrain(
            &TerrainSource::Store("/nonexistent/x.relief".into()),
            Path::new("/tmp"),
        )
        .err()
        .unwrap()
        .to_string();
        assert!(e.contains("/nonexistent/x.relief"), "{e}");
        let e = check_exists(&TerrainSource::Store("/nonexistent/x.relief".into()))
            .unwrap_err()
            .to_string();
        assert_eq!(e.matches("/nonexistent/x.relief").count(), 2, "{e}");
        assert!(e.contains("relief-server build"), "{e}");
    }
}
