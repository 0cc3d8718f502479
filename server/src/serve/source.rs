//! The terrain a server holds: a store file as given, or a DEM (the embedded crop by default)
//! built into the cache folder on first start and mapped from there afterwards.
//!
//! Cache entries are named after what they were built from (the DEM spec, the file's size and
//! modification time, the store format version), so a changed DEM is built again and an
//! unchanged one is not. The key is also recorded inside the store, and an entry whose
//! recorded key differs (another store copied over its name) is built again, not served.
//! Builds go through a temporary file and a rename, so two servers starting at once never map
//! a half-written store.
//!
//! Whatever the source, the server maps a private copy of the store
//! ([`Store::open_private`]), made in the cache folder: the file it was given may be
//! replaced, truncated or deleted while it serves.

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

/// The key of a cache entry: what the DEM was (each file of a mosaic, in order, by its name,
/// size and CRC-32 of its contents) and every load option that changes the heights, the spacing or the
/// georeference.
pub fn cache_key<S: AsRef<str>>(specs: &[S], opts: &LoadOptions) -> u64 {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    specs.len().hash(&mut h);
    // A folder stands for the GeoTIFFs in it (as `build` reads it): each file counts, so that
    // a file added, removed or changed there builds a new store.
    let specs: Vec<String> = specs
        .iter()
        .flat_map(|s| {
            let s = s.as_ref();
            match Path::new(s).is_dir() {
                true => crate::dem::mosaic::folder_tiffs(s).unwrap_or_else(|_| vec![s.into()]),
                false => vec![s.to_string()],
            }
        })
        .collect();
    for spec in &specs {
        let spec = spec.as_str();
        if crate::dem::is_url(spec) {
            url_identity(spec).hash(&mut h);
            continue;
        }
        match file_digest(spec) {
            // A file by its name and contents, not its folder or its time: replicas that
            // fetched the same DEM into different places, at different times, build the
            // same store (and so serve the same terrain id, and resume each other's
            // sessions).
            Some((name, len, crc)) => (name, len, crc).hash(&mut h),
            None => spec.hash(&mut h),
        }
    }
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
    opts.origin
        .map(|(x, y)| (x.to_bits(), y.to_bits()))
        .hash(&mut h);
    opts.encoding.map(|e| e.name()).hash(&mut h);
    opts.tile.map(|t| (t.z, t.x, t.y)).hash(&mut h);
    crate::store::format::VERSION.hash(&mut h);
    h.finish()
}

/// The cache file for a DEM (or a mosaic: named after its first file and the count of the
/// others) read with `opts`.
pub fn cached_store_path<S: AsRef<str>>(
    cache_dir: &Path,
    specs: &[S],
    opts: &LoadOptions,
) -> PathBuf {
    let spec = specs.first().map_or("none", |s| s.as_ref());
    let mut stem: String = spec
        .rsplit('/')
        .next()
        .unwrap_or(spec)
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .take(40)
        .collect();
    if specs.len() > 1 {
        stem.push_str(&format!("+{}", specs.len() - 1));
    }
    cache_dir.join(format!("{stem}-{:016x}.relief", cache_key(specs, opts)))
}

/// A URL's identity as a store's key: the URL without its query string (a presigned URL's
/// signature changes with every signing, the object does not), the object's size and its
/// version (`ETag` or `Last-Modified`), as its first block's answer gives them, so that a
/// replaced object builds a new store. An object the server names no version of is known by
/// its URL and size alone. Where the URL cannot be read, by its URL: the load that follows
/// reports why.
fn url_identity(url: &str) -> (String, Option<u64>, Option<String>) {
    let shown = crate::dem::http_range::without_query(url).to_string();
    match crate::dem::http_range::RangeReader::open(url) {
        Ok(r) => (shown, Some(r.size()), r.version().map(str::to_string)),
        Err(_) => (shown, None, None),
    }
}

/// A DEM file's name, length and CRC-32 of its contents; `None` when `spec` is not a readable
/// file (a synthetic terrain, or a file the loader will report missing).
fn file_digest(spec: &str) -> Option<(String, u64, u32)> {
    use std::io::Read;
    let path = Path::new(spec);
    let mut f = std::fs::File::open(path).ok()?;
    if !f.metadata().ok()?.is_file() {
        return None;
    }
    let mut crc = crc32fast::Hasher::new();
    let mut buf = vec![0u8; 1 << 20];
    let mut len = 0u64;
    loop {
        let n = f.read(&mut buf).ok()?;
        if n == 0 {
            break;
        }
        crc.update(&buf[..n]);
        len += n as u64;
    }
    let name = path.file_name()?.to_string_lossy().to_string();
    Some((name, len, crc.finalize()))
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

/// Opens a private copy of the store at `path`, made in `scratch`.
fn open(path: &Path, scratch: &Path) -> Result<Store, SourceError> {
    Store::open_private(path, scratch).map_err(|source| SourceError::Store {
        path: path.display().to_string(),
        source,
    })
}

/// Opens the cache entry at `path` if it was built for `key`: `Err(Ok(why))` when it must be
/// rebuilt, `Err(Err(e))` when it cannot be opened for a reason a rebuild would not cure (its
/// private copy does not fit on the disk).
fn open_cached(
    path: &Path,
    scratch: &Path,
    key: &str,
) -> Result<Store, Result<String, SourceError>> {
    let store = open(path, scratch).map_err(|e| {
        if let SourceError::Store {
            source: crate::store::StoreError::Copy { .. },
            ..
        } = e
        {
            return Err(e);
        }
        let why = std::error::Error::source(&e).map(|s| s.to_string());
        Ok(format!("{e}: {}", why.unwrap_or_default()))
    })?;
    match store.meta().cache_key.as_deref() {
        Some(k) if k == key => Ok(store),
        other => Err(Ok(format!(
            "it holds a store built for {} (from {:?}), not for this DEM ({key})",
            other.unwrap_or("no cache key"),
            store.meta().source
        ))),
    }
}

/// Opens the terrain, building and caching it first if needed. Blocking: call it off the
/// async runtime.
pub fn open_terrain(source: &TerrainSource, cache_dir: &Path) -> Result<Store, SourceError> {
    let defaults = LoadOptions::default();
    let embedded = [dem::EMBEDDED_SPEC.to_string()];
    let (specs, opts) = match source {
        TerrainSource::Store(p) => return open(p, cache_dir),
        TerrainSource::Embedded => (&embedded[..], &defaults),
        TerrainSource::Dem(s, o) => (&s[..], o),
    };
    let path = cached_store_path(cache_dir, specs, opts);
    let key = format!("{:016x}", cache_key(specs, opts));
    if path.exists() {
        match open_cached(&path, cache_dir, &key) {
            Ok(s) => {
                tracing::info!("using cached store {}", path.display());
                return Ok(s);
            }
            Err(Ok(why)) => {
                tracing::warn!("rebuilding the cached store {}: {why}", path.display())
            }
            Err(Err(e)) => return Err(e),
        }
    }
    std::fs::create_dir_all(cache_dir).map_err(|source| SourceError::Cache {
        path: cache_dir.display().to_string(),
        source,
    })?;
    let d = match source {
        TerrainSource::Embedded => dem::embedded_default()?,
        _ => dem::load_all(specs, opts)?,
    };
    tracing::info!(
        "building the store for {} ({}x{} samples) into {}",
        d.source,
        d.width,
        d.height,
        path.display()
    );
    preprocess::build_cached_store(&d, &path, &key).map_err(|source| SourceError::Store {
        path: path.display().to_string(),
        source,
    })?;
    open(&path, cache_dir)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tiles16() -> preprocess::BuildOptions {
        preprocess::BuildOptions {
            tile_size: 16,
            ..Default::default()
        }
    }

    #[test]
    fn the_embedded_terrain_is_built_once_then_reused() {
        let dir = tempfile::tempdir().unwrap();
        let a = open_terrain(&TerrainSource::Embedded, dir.path()).unwrap();
        let path = cached_store_path(dir.path(), &[dem::EMBEDDED_SPEC], &LoadOptions::default());
        let before = std::fs::metadata(&path).unwrap().modified().unwrap();
        let b = open_terrain(&TerrainSource::Embedded, dir.path()).unwrap();
        assert_eq!(a.terrain_id(), b.terrain_id());
        assert_eq!(
            std::fs::metadata(&path).unwrap().modified().unwrap(),
            before
        );
    }

    #[test]
    fn one_dem_in_two_places_builds_byte_identical_stores() {
        // Deployment: replicas that fetched the same DEM into different folders, at different
        // times, must build the same store and so serve the same terrain id.
        let (a, b) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
        let fa = a.path().join("fuji.tif");
        std::fs::write(&fa, dem::EMBEDDED_FUJI).unwrap();
        std::thread::sleep(std::time::Duration::from_millis(20));
        let fb = b.path().join("sub").join("fuji.tif");
        std::fs::create_dir_all(fb.parent().unwrap()).unwrap();
        std::fs::write(&fb, dem::EMBEDDED_FUJI).unwrap();
        let built = |file: &Path, cache: &Path| {
            let spec = vec![file.to_str().unwrap().to_string()];
            let src = TerrainSource::Dem(spec.clone(), LoadOptions::default());
            let s = open_terrain(&src, cache).unwrap();
            let bytes =
                std::fs::read(cached_store_path(cache, &spec, &LoadOptions::default())).unwrap();
            (s.terrain_id(), s.meta().source.clone(), bytes)
        };
        let (id_a, src_a, bytes_a) = built(&fa, &a.path().join("cache"));
        let (id_b, src_b, bytes_b) = built(&fb, &b.path().join("cache"));
        assert_eq!(src_a, "fuji.tif");
        assert_eq!((id_a, &src_a), (id_b, &src_b));
        assert!(bytes_a == bytes_b, "the two stores differ");
        // The embedded terrain, built twice from scratch, likewise.
        let (c, d) = (tempfile::tempdir().unwrap(), tempfile::tempdir().unwrap());
        let one = open_terrain(&TerrainSource::Embedded, c.path()).unwrap();
        let two = open_terrain(&TerrainSource::Embedded, d.path()).unwrap();
        assert_eq!(one.terrain_id(), two.terrain_id());
        let file = |dir: &Path| {
            std::fs::read(cached_store_path(
                dir,
                &[dem::EMBEDDED_SPEC],
                &LoadOptions::default(),
            ))
            .unwrap()
        };
        assert!(file(c.path()) == file(d.path()));
        // A DEM whose contents differ is another store.
        let mut other = dem::EMBEDDED_FUJI.to_vec();
        let n = other.len();
        other[n - 1] ^= 1;
        std::fs::write(&fb, &other).unwrap();
        let key = |f: &Path| cache_key(&[f.to_str().unwrap()], &LoadOptions::default());
        assert_ne!(key(&fa), key(&fb));
    }

    #[test]
    fn a_corrupt_cache_entry_is_rebuilt() {
        let dir = tempfile::tempdir().unwrap();
        let path = cached_store_path(dir.path(), &[dem::EMBEDDED_SPEC], &LoadOptions::default());
        std::fs::write(&path, b"not a store").unwrap();
        let s = open_terrain(&TerrainSource::Embedded, dir.path()).unwrap();
        assert_eq!(s.geometry().shape.width(), 257);
    }

    #[test]
    fn a_foreign_store_over_a_cache_entry_is_rebuilt_not_served() {
        // Hostile input: a valid store of another terrain, copied over the cached file's name.
        let dir = tempfile::tempdir().unwrap();
        let path = cached_store_path(dir.path(), &[dem::EMBEDDED_SPEC], &LoadOptions::default());
        let other = dem::load("synthetic:65:3", &LoadOptions::default()).unwrap();
        preprocess::build_store(&other, &path, &tiles16()).unwrap();
        let foreign_id = Store::open(&path).unwrap().terrain_id();
        let s = open_terrain(&TerrainSource::Embedded, dir.path()).unwrap();
        assert_ne!(s.terrain_id(), foreign_id);
        assert_eq!(s.geometry().shape.width(), 257);
    }

    #[test]
    fn the_served_store_is_a_private_copy() {
        // Hostile input: truncating or overwriting the store file under the server changes nothing
        // it serves.
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("s.relief");
        let d = dem::load("synthetic:129:5", &LoadOptions::default()).unwrap();
        preprocess::build_store(&d, &file, &tiles16()).unwrap();
        let s = open_terrain(&TerrainSource::Store(file.clone()), dir.path()).unwrap();
        let before: Vec<i32> = (0..129).map(|c| s.sample_z(c, 64)).collect();
        let len = std::fs::metadata(&file).unwrap().len();
        std::fs::OpenOptions::new()
            .write(true)
            .open(&file)
            .unwrap()
            .set_len(len / 3)
            .unwrap();
        let after: Vec<i32> = (0..129).map(|c| s.sample_z(c, 64)).collect();
        assert_eq!(before, after);
        std::fs::write(&file, vec![0x7f; len as usize]).unwrap();
        assert_eq!(s.sample_z(5, 64), before[5]);
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

    #[test]
    fn the_cache_key_covers_every_input_and_option() {
        use crate::formats::terrain_rgb::Encoding;
        use crate::geo::mercator::TileId;
        let d = LoadOptions::default();
        let key = |specs: &[&str], o: &LoadOptions| cache_key(specs, o);
        let base = key(&["a.png"], &d);
        assert_eq!(base, key(&["a.png"], &d));
        let variants = [
            LoadOptions {
                encoding: Some(Encoding::TerrainRgb),
                ..d.clone()
            },
            LoadOptions {
                encoding: Some(Encoding::Terrarium),
                ..d.clone()
            },
            LoadOptions {
                tile: TileId::new(3, 1, 2).ok(),
                ..d.clone()
            },
            LoadOptions {
                tile: TileId::new(3, 2, 1).ok(),
                ..d.clone()
            },
            LoadOptions {
                origin: Some((1.0, 2.0)),
                ..d.clone()
            },
        ];
        let mut keys: Vec<u64> = variants.iter().map(|o| key(&["a.png"], o)).collect();
        keys.push(base);
        keys.push(key(&["a.png", "b.png"], &d));
        keys.push(key(&["b.png", "a.png"], &d));
        keys.push(key(&["a.pngb.png"], &d));
        let n = keys.len();
        keys.sort_unstable();
        keys.dedup();
        assert_eq!(keys.len(), n);
        // A changed file of a mosaic changes the key.
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a"), dir.path().join("b"));
        std::fs::write(&a, b"1").unwrap();
        std::fs::write(&b, b"1").unwrap();
        let specs = [a.to_str().unwrap(), b.to_str().unwrap()];
        let before = key(&specs, &d);
        std::fs::write(&b, b"22").unwrap();
        assert_ne!(key(&specs, &d), before);
        let p = cached_store_path(dir.path(), &specs, &d);
        assert!(
            p.file_name().unwrap().to_str().unwrap().starts_with("a+1-"),
            "{p:?}"
        );
    }
}
