//! The preprocessed store: the vertex quadtree and the tile pyramid of one DEM, written once,
//! memory-mapped by the server and shared by every session.
//!
//! - [`build`]: heights to the tree's arrays (Haar pyramid, z-bounds, saturated errors).
//! - [`tiles`]: heights to the tile pyramid (meshes, crack patches, errors, bounds).
//! - [`format`]: the versioned, checksummed file layout.
//! - [`mmap`]: the one unsafe call, mapping the file.
//! - [`private`]: the server's private copy of a store, which nothing outside can change.
//! - [`tmp_build`]: the temporary file a build writes, and its cleaning up.
//!
//! [`write_store`] builds and writes a store; [`Store::open`] maps and checks one, and
//! [`Store::open_private`] maps a private copy.

pub mod build;
pub mod format;
pub mod layout;
mod mmap;
pub mod private;
pub mod record_file;
pub mod tiles;
pub mod tmp_build;

use crate::geo::{Georef, LonLatBounds};
use format::{HEADER_LEN, Header, META, NODES, TILE_DATA, TILES, VOIDS};
use layout::{QuadLayout, rec_code, rec_z};
use memmap2::Mmap;
use relief_proto::terrain::TerrainGeometry;
use relief_proto::tile::body::MeshKind;
use relief_proto::tile::{TileSetInfo, TileShape};
use relief_proto::tree::NodeId;
use serde::{Deserialize, Serialize};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;
use tiles::TileRecord;

/// Why a store could not be written or opened.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// The file could not be read or written.
    #[error("{path}: cannot read or write the file")]
    Io {
        /// The file.
        path: String,
        /// What the OS said.
        source: std::io::Error,
    },
    /// The file does not start with the store magic.
    #[error("not a Relief store (bad magic); build one with `relief-server build`")]
    NotAStore,
    /// The file was written by another format version.
    #[error(
        "store format version {found}, but this build reads version {supported}; rebuild it with `relief-server build`"
    )]
    Version {
        /// Version in the file.
        found: u32,
        /// Version this build reads.
        supported: u32,
    },
    /// The file is shorter than its header says.
    #[error("store is truncated: {actual} bytes, at least {expected} expected")]
    Truncated {
        /// Bytes needed.
        expected: u64,
        /// Bytes present.
        actual: u64,
    },
    /// A checksum or a consistency check failed.
    #[error("store is corrupt: {0}")]
    Corrupt(String),
    /// The input cannot be stored as asked; the message says why and what to change.
    #[error("{0}")]
    Input(String),
    /// This machine cannot read the format in place.
    #[error("stores are little-endian; this machine is not")]
    Endianness,
    /// The private copy could not be made (a full disk, most often): the store itself may be
    /// sound.
    #[error("cannot copy the store into the scratch folder {scratch}: {source}")]
    Copy {
        /// The folder the copy was being made in.
        scratch: String,
        /// Why.
        source: std::io::Error,
    },
}

/// Descriptive metadata kept in the store as JSON.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct StoreMeta {
    /// Where the heights came from (file name or synthetic spec).
    pub source: String,
    /// Coordinate reference system of the source, when known.
    pub crs: Option<String>,
    /// Lowest height, metres.
    pub height_min: f64,
    /// Highest height, metres.
    pub height_max: f64,
    /// Samples that were voids in the source and were filled.
    pub void_count: u64,
    /// For a store the server built into its cache: the key of what it was built from (the
    /// DEM, how it was read, the format version), checked when the cache entry is opened so
    /// that a store copied over the entry's name is not served as that DEM.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cache_key: Option<String>,
    /// The tile pyramid's mesh kind: `grid` (the default, and what stores without the field
    /// hold), `rqt` or `tin`.
    #[serde(default = "grid_name")]
    pub tile_mesh: String,
    /// Where the samples lie on the Earth, when the DEM says (GeoTIFF tags, `--origin`):
    /// what the standard formats resample through. Stores without it serve none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub georef: Option<Georef>,
    /// The samples' longitude/latitude box (WGS 84), from the georeference.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bounds: Option<LonLatBounds>,
}

fn grid_name() -> String {
    MeshKind::Grid.name().into()
}

impl Default for StoreMeta {
    /// Empty, with `grid` tiles.
    fn default() -> Self {
        StoreMeta {
            source: String::new(),
            crs: None,
            height_min: 0.0,
            height_max: 0.0,
            void_count: 0,
            cache_key: None,
            tile_mesh: grid_name(),
            georef: None,
            bounds: None,
        }
    }
}

/// The mesh kind named `name` (`grid`, `rqt` or `tin`).
pub fn mesh_kind(name: &str) -> Option<MeshKind> {
    [MeshKind::Grid, MeshKind::Rqt, MeshKind::Tin]
        .into_iter()
        .find(|k| k.name() == name)
}

/// The input to [`write_store`].
pub struct StoreInput<'a> {
    /// Grid width in samples.
    pub width: u32,
    /// Grid height in samples.
    pub height: u32,
    /// Ground metres between columns.
    pub spacing_x: f64,
    /// Ground metres between rows.
    pub spacing_y: f64,
    /// Metres per height quantum.
    pub z_quantum: f64,
    /// Row-major heights in metres, voids filled.
    pub heights: &'a [f32],
    /// Which samples had no data in the source.
    pub voids: &'a crate::dem::VoidMask,
    /// Cells per side of the tile pyramid's tiles.
    pub tile_size: u32,
    /// Descriptive metadata.
    pub meta: StoreMeta,
}

/// Default tile size in cells (65 x 65 vertices, as Cesium's terrain tiles).
pub const DEFAULT_TILE_SIZE: u32 = 64;

/// The share of a build's progress the vertex tree takes (the tile pyramid takes the rest), as
/// the two took of the time in `bench build` on synthetic:16385 (3.8 s, writing its records
/// included, and 13.5 s on one thread), so that a progress bar's rate and time left hold
/// through both.
pub const TREE_SHARE: f64 = 0.2;

/// Leaf samples the tree takes at a time (a band of whole rows, 16 to 1024 of them): the
/// tree's memory is a few bands, whatever the grid's height.
const TREE_BAND_SAMPLES: usize = 1 << 20;

/// Builds the tree and the tile pyramid for `input` and writes them to `path` (through a
/// temporary file and a rename, so that a mapped store is never overwritten in place).
/// `progress` receives the fraction done (the tree [`TREE_SHARE`] of it, the tiles the rest).
/// Returns the file size and the seconds the tree build and the tile build took.
pub fn write_store(
    path: &Path,
    input: &StoreInput<'_>,
    mut progress: impl FnMut(f64),
) -> Result<(u64, f64, f64), StoreError> {
    let geom = geometry(
        input.width,
        input.height,
        input.spacing_x,
        input.spacing_y,
        input.z_quantum,
    )?;
    let tshape = TileShape::new(input.width, input.height, input.tile_size)
        .map_err(|e| StoreError::Corrupt(e.to_string()))?;
    let kind = mesh_kind(&input.meta.tile_mesh).ok_or_else(|| {
        StoreError::Input(format!(
            "tile mesh `{}` is unknown: use grid, rqt or tin",
            input.meta.tile_mesh
        ))
    })?;
    if input.voids.len() != input.heights.len() {
        return Err(StoreError::Input(format!(
            "{} void flags for {} heights",
            input.voids.len(),
            input.heights.len()
        )));
    }
    let voids = input.voids.to_le_bytes();
    let meta = serde_json::to_vec(&input.meta).map_err(|e| StoreError::Corrupt(e.to_string()))?;
    let header = Header {
        width: input.width,
        height: input.height,
        spacing_x: input.spacing_x,
        spacing_y: input.spacing_y,
        z_quantum: input.z_quantum,
        tile_size: input.tile_size,
        sections: [(0, 0); format::SECTION_COUNT],
        body_crc: 0,
    };
    let io = |source| StoreError::Io {
        path: path.display().to_string(),
        source,
    };
    tmp_build::remove_stale(path);
    let tmp = tmp_build::TmpBuild(tmp_build::path_for(path, std::process::id()));
    let tmp_io = |source| StoreError::Io {
        path: tmp.0.display().to_string(),
        source,
    };
    let file = File::create(&tmp.0).map_err(tmp_io)?;
    let mut w = format::SectionWriter::new(BufWriter::with_capacity(1 << 20, file), header)
        .map_err(tmp_io)?;
    let t0 = std::time::Instant::now();
    // The tree streams its records into the file, the rows a band at a time.
    let layout = QuadLayout::new(&geom.shape);
    let nodes_crc = {
        let tmp_name = tmp.0.display().to_string();
        let at = w.position();
        let mut sink = record_file::RecordFile::new(w.get_mut().get_ref(), &tmp_name, at, &layout);
        let mut tree = build::TreeBuilder::new(&geom);
        let width = input.width as usize;
        let band = (TREE_BAND_SAMPLES / width).clamp(16, 1024) * width;
        for rows in input.heights.chunks(band) {
            tree.push_rows(rows, &mut sink)?;
            progress(TREE_SHARE * f64::from(tree.rows_in()) / f64::from(input.height));
        }
        tree.finish()?;
        sink.finish()?
    };
    w.section_written(4 * layout.len(), &nodes_crc)
        .map_err(tmp_io)?;
    let build_s = t0.elapsed().as_secs_f64();
    // The small sections are written, and everything so far synced, on a thread of their own
    // while the tile pyramid is built: syncing is the disk's time, which would otherwise follow
    // the pyramid.
    let (pyramid, tiles_s, first) = std::thread::scope(|scope| {
        let writer = scope.spawn(move || -> std::io::Result<_> {
            w.section(&voids)?;
            w.section(&meta)?;
            w.get_mut().flush()?;
            w.get_mut().get_ref().sync_data()?;
            Ok(w)
        });
        let t1 = std::time::Instant::now();
        let pyramid =
            tiles::build_pyramid(&tshape, input.heights, input.z_quantum as f32, kind, |f| {
                progress(TREE_SHARE + f * (1.0 - TREE_SHARE))
            });
        let tiles_s = t1.elapsed().as_secs_f64();
        let first = writer
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        (pyramid, tiles_s, first)
    });
    let mut w = first.map_err(tmp_io)?;
    w.section(bytemuck::cast_slice(&pyramid.records))
        .and_then(|()| w.section_parts(pyramid.blobs.iter().map(Vec::as_slice)))
        .map_err(tmp_io)?;
    let (file, size) = w.finish().map_err(tmp_io)?;
    let file = file.into_inner().map_err(|e| tmp_io(e.into_error()))?;
    file.sync_all().map_err(tmp_io)?;
    std::fs::rename(&tmp.0, path).map_err(io)?;
    std::mem::forget(tmp);
    Ok((size, build_s, tiles_s))
}

fn geometry(w: u32, h: u32, dx: f64, dy: f64, q: f64) -> Result<TerrainGeometry, StoreError> {
    let ok = |v: f64| v.is_finite() && v > 0.0;
    if !(ok(dx) && ok(dy) && ok(q)) {
        return Err(StoreError::Corrupt(format!(
            "spacing {dx} x {dy} m and z quantum {q} m must be positive"
        )));
    }
    TerrainGeometry::new(w, h, dx as f32, dy as f32, q as f32)
        .map_err(|e| StoreError::Corrupt(e.to_string()))
}

/// An opened, checked, memory-mapped store.
pub struct Store {
    /// The mapped file.
    map: Mmap,
    /// The parsed header: section offsets.
    header: Header,
    /// Tree shape and world frame, derived from the header.
    geom: TerrainGeometry,
    /// Descriptive metadata.
    meta: StoreMeta,
    /// Where each node's record lies.
    layout: QuadLayout,
    /// The tile pyramid's shape.
    tiles: TileShape,
    /// What tile clients are told of the pyramid.
    tile_info: TileSetInfo,
    /// Each tile's world box, error and size, by dense index, computed once at open so that a
    /// selection reads one record per tile.
    tile_bounds: Vec<TileBounds>,
}

/// A tile's box, geometric error and size in world metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TileBounds {
    /// Its samples' extent and height range.
    pub aabb: relief_proto::view::Aabb,
    /// Geometric error, metres (saturated).
    pub error: f32,
    /// Ground metres across its longer side.
    pub size: f32,
}

impl Store {
    /// Maps `path` and checks it completely (header, section sizes, checksums). The file must
    /// not change while the store is open (see [`Store::open_private`] for a server).
    pub fn open(path: &Path) -> Result<Store, StoreError> {
        let io = |source| StoreError::Io {
            path: path.display().to_string(),
            source,
        };
        Store::from_file(&File::open(path).map_err(io)?, path)
    }

    /// Copies `path` into an unnamed, read-only file in `scratch` and maps the copy, checked
    /// completely: whatever later happens to `path` (truncated, overwritten, deleted) cannot
    /// reach the open store. See [`private`].
    pub fn open_private(path: &Path, scratch: &Path) -> Result<Store, StoreError> {
        let copy = private::copy(path, scratch).map_err(|source| {
            if source.kind() == std::io::ErrorKind::NotFound && !path.exists() {
                StoreError::Io {
                    path: path.display().to_string(),
                    source,
                }
            } else {
                StoreError::Copy {
                    scratch: scratch.display().to_string(),
                    source,
                }
            }
        })?;
        Store::from_file(&copy, path)
    }

    /// Maps `file` (read from `path`) and checks it completely.
    fn from_file(file: &File, path: &Path) -> Result<Store, StoreError> {
        if cfg!(target_endian = "big") {
            return Err(StoreError::Endianness);
        }
        let io = |source| StoreError::Io {
            path: path.display().to_string(),
            source,
        };
        let map = mmap::map(file).map_err(io)?;
        let header = Header::parse(&map[..HEADER_LEN.min(map.len())], map.len() as u64)?;
        let geom = geometry(
            header.width,
            header.height,
            header.spacing_x,
            header.spacing_y,
            header.z_quantum,
        )?;
        let layout = QuadLayout::new(&geom.shape);
        let samples = header.width as u64 * header.height as u64;
        let tiles = TileShape::new(header.width, header.height, header.tile_size)
            .map_err(|e| StoreError::Corrupt(e.to_string()))?;
        let n_tiles = u64::from(tiles.tile_count());
        let record_len = std::mem::size_of::<TileRecord>() as u64;
        let expect = [
            (NODES, layout.len() * 4),
            (VOIDS, samples.div_ceil(8)),
            (TILES, n_tiles * record_len),
        ];
        for (i, len) in expect {
            if header.sections[i].1 != len {
                return Err(StoreError::Corrupt(format!(
                    "section {} holds {} bytes, the grid implies {len}",
                    format::SECTIONS[i],
                    header.sections[i].1
                )));
            }
        }
        let mut crc = crc32fast::Hasher::new();
        for (off, len) in header.sections {
            crc.update(&map[off as usize..(off + len) as usize]);
        }
        if crc.finalize() != header.body_crc {
            return Err(StoreError::Corrupt("data checksum mismatch".into()));
        }
        let (off, len) = header.sections[META];
        let meta: StoreMeta = serde_json::from_slice(&map[off as usize..(off + len) as usize])
            .map_err(|e| StoreError::Corrupt(format!("metadata: {e}")))?;
        if mesh_kind(&meta.tile_mesh).is_none() {
            return Err(StoreError::Corrupt(format!(
                "metadata: tile mesh `{}` is unknown",
                meta.tile_mesh
            )));
        }
        let mesh_name = meta.tile_mesh.clone();
        let mut store = Store {
            map,
            header,
            geom,
            meta,
            layout,
            tile_info: TileSetInfo {
                tile_size: tiles.tile_size(),
                depth: tiles.depth(),
                mesh: mesh_name,
                level_errors: vec![0.0; tiles.depth() as usize + 1],
            },
            tiles,
            tile_bounds: Vec::new(),
        };
        let data_len = store.section(TILE_DATA).len() as u64;
        let mut level_errors = vec![0f32; store.tiles.depth() as usize + 1];
        for (i, r) in store.tile_records().iter().enumerate() {
            let end = r.offset + u64::from(r.mesh_len) + u64::from(r.patch_len);
            if end > data_len || r.mesh_len == 0 || !r.error.is_finite() || r.zmin > r.zmax {
                return Err(StoreError::Corrupt(format!(
                    "tile record {i} is inconsistent"
                )));
            }
            let level = store.tiles.tile(i as u32).map_or(0, |t| t.level as usize);
            level_errors[level] = level_errors[level].max(r.error);
        }
        store.tile_info.level_errors = level_errors;
        store.tile_bounds = store.compute_tile_bounds();
        Ok(store)
    }

    fn section(&self, i: usize) -> &[u8] {
        let (off, len) = self.header.sections[i];
        &self.map[off as usize..(off + len) as usize]
    }

    /// An identifier of the store's contents: the body checksum over the header's own. Two
    /// servers holding the same store give the same id, so a resume snapshot taken on one is
    /// accepted by the other and refused by a server holding another terrain.
    pub fn terrain_id(&self) -> u64 {
        let head = crc32fast::hash(&self.map[..HEADER_LEN - 4]);
        (u64::from(head) << 32) | u64::from(self.header.body_crc)
    }

    /// Tree shape, world frame and z quantum.
    pub fn geometry(&self) -> &TerrainGeometry {
        &self.geom
    }

    /// Descriptive metadata.
    pub fn meta(&self) -> &StoreMeta {
        &self.meta
    }

    /// Every node's record (height and error code, see [`layout`]), by slot.
    pub fn nodes(&self) -> &[u32] {
        // Sections are 8-byte aligned in a page-aligned map and their lengths were checked.
        bytemuck::try_cast_slice(self.section(NODES)).unwrap_or(&[])
    }

    /// Where each node's record lies in [`Store::nodes`].
    pub fn layout(&self) -> &QuadLayout {
        &self.layout
    }

    /// The record of `node`, an existing node.
    #[inline]
    pub fn record(&self, node: NodeId) -> u32 {
        self.nodes()[self.layout.slot(node)]
    }

    /// Height of `node` in z quanta.
    pub fn node_z(&self, node: NodeId) -> i32 {
        rec_z(self.record(node))
    }

    /// Height of the root in z quanta: what a client's mirror starts from.
    pub fn root_z(&self) -> i32 {
        self.node_z(NodeId::ROOT)
    }

    /// Height of sample `(col, row)` in z quanta.
    pub fn sample_z(&self, col: u32, row: u32) -> i32 {
        self.node_z(self.geom.shape.leaf(col, row))
    }

    /// Every sample's height in metres, row by row from the north: the full-resolution grid
    /// the store was built from, as stored (each height rounded to the z quantum, so within
    /// half a quantum of the source; voids hold their filled heights). It allocates
    /// `4 * width * height` bytes.
    pub fn heights(&self) -> Vec<f32> {
        let (w, h) = (self.header.width, self.header.height);
        let q = self.geom.z_quantum;
        let mut out = Vec::with_capacity(w as usize * h as usize);
        for row in 0..h {
            out.extend((0..w).map(|col| self.sample_z(col, row) as f32 * q));
        }
        out
    }

    /// Whether sample `(col, row)` was a void in the source.
    pub fn is_void(&self, col: u32, row: u32) -> bool {
        let i = row as usize * self.header.width as usize + col as usize;
        self.section(VOIDS)[i / 8] & (1 << (i % 8)) != 0
    }

    /// Error code of `node` (0 for leaves).
    pub fn err_code(&self, node: NodeId) -> u8 {
        rec_code(self.record(node))
    }

    fn compute_tile_bounds(&self) -> Vec<TileBounds> {
        let (frame, q) = (self.geom.frame, self.geom.z_quantum);
        self.tile_records()
            .iter()
            .enumerate()
            .map(|(i, r)| {
                let t = self.tiles.tile(i as u32).unwrap_or(NodeId::ROOT);
                let sp = self.tiles.span(t);
                let (x0, y1) = frame.to_world(sp.cols.0 as f32, sp.rows.0 as f32);
                let (x1, y0) = frame.to_world(sp.cols.1 as f32, sp.rows.1 as f32);
                TileBounds {
                    aabb: relief_proto::view::Aabb {
                        min: glam::Vec3::new(x0, y0, r.zmin as f32 * q),
                        max: glam::Vec3::new(x1, y1, r.zmax as f32 * q),
                    },
                    error: r.error,
                    size: (x1 - x0).max(y1 - y0),
                }
            })
            .collect()
    }

    /// Each tile's world box, error and size, by dense index.
    pub fn tile_bounds(&self) -> &[TileBounds] {
        &self.tile_bounds
    }

    /// The tile pyramid's shape.
    pub fn tile_shape(&self) -> &TileShape {
        &self.tiles
    }

    /// The tile pyramid's mesh kind (checked when the store was opened).
    pub fn tile_mesh(&self) -> MeshKind {
        mesh_kind(&self.meta.tile_mesh).unwrap_or_default()
    }

    /// What tile clients are told of the pyramid.
    pub fn tile_info(&self) -> &TileSetInfo {
        &self.tile_info
    }

    /// Tile records by dense index.
    pub fn tile_records(&self) -> &[TileRecord] {
        bytemuck::try_cast_slice(self.section(TILES)).unwrap_or(&[])
    }

    /// The mesh blob and the patch blob of tile `index`.
    pub fn tile_blobs(&self, index: u32) -> (&[u8], &[u8]) {
        let Some(r) = self.tile_records().get(index as usize) else {
            return (&[], &[]);
        };
        let data = self.section(TILE_DATA);
        let (a, m) = (r.offset as usize, r.mesh_len as usize);
        (&data[a..a + m], &data[a + m..a + m + r.patch_len as usize])
    }

    /// Size of the mapped file in bytes.
    pub fn file_len(&self) -> usize {
        self.map.len()
    }
}

#[cfg(test)]
mod tests;
