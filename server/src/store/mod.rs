//! The preprocessed store: the vertex quadtree of one DEM, written once, memory-mapped by the
//! server and shared by every session.
//!
//! - [`build`]: heights to the tree's arrays (Haar pyramid, z-bounds, saturated errors).
//! - [`format`]: the versioned, checksummed file layout.
//! - [`mmap`]: the one unsafe call, mapping the file.
//!
//! [`write_store`] builds and writes a store; [`Store::open`] maps and checks one.

pub mod build;
pub mod format;
mod mmap;

use format::{HEADER_LEN, Header};
use memmap2::Mmap;
use relief_proto::terrain::TerrainGeometry;
use relief_proto::tree::NodeId;
use serde::{Deserialize, Serialize};
use std::fs::File;
use std::path::Path;

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
    /// This machine cannot read the format in place.
    #[error("stores are little-endian; this machine is not")]
    Endianness,
}

/// Descriptive metadata kept in the store as JSON.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
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
    /// Row-major void flags (true = no data in the source).
    pub voids: &'a [bool],
    /// Descriptive metadata.
    pub meta: StoreMeta,
}

/// Builds the tree for `input` and writes it to `path` (through a temporary file and a rename,
/// so that a mapped store is never overwritten in place). Returns the file size and the seconds
/// the tree build itself took.
pub fn write_store(
    path: &Path,
    input: &StoreInput<'_>,
    progress: impl FnMut(f64),
) -> Result<(u64, f64), StoreError> {
    let geom = geometry(
        input.width,
        input.height,
        input.spacing_x,
        input.spacing_y,
        input.z_quantum,
    )?;
    let t0 = std::time::Instant::now();
    let arrays = build::build_arrays(&geom, input.heights, progress);
    let build_s = t0.elapsed().as_secs_f64();
    let mut voids = vec![0u8; input.voids.len().div_ceil(8)];
    for (i, _) in input.voids.iter().enumerate().filter(|(_, v)| **v) {
        voids[i / 8] |= 1 << (i % 8);
    }
    let meta = serde_json::to_vec(&input.meta).map_err(|e| StoreError::Corrupt(e.to_string()))?;
    let header = Header {
        width: input.width,
        height: input.height,
        spacing_x: input.spacing_x,
        spacing_y: input.spacing_y,
        z_quantum: input.z_quantum,
        sections: [(0, 0); 6],
        body_crc: 0,
    };
    let io = |source| StoreError::Io {
        path: path.display().to_string(),
        source,
    };
    let tmp = path.with_extension("tmp-build");
    let mut file = std::io::BufWriter::new(File::create(&tmp).map_err(io)?);
    let size = format::write_sections(
        &mut file,
        header,
        [
            bytemuck::cast_slice(&arrays.z),
            &arrays.err,
            bytemuck::cast_slice(&arrays.zmin),
            bytemuck::cast_slice(&arrays.zmax),
            &voids,
            &meta,
        ],
    )
    .map_err(io)?;
    let file = file.into_inner().map_err(|e| io(e.into_error()))?;
    file.sync_all().map_err(io)?;
    std::fs::rename(&tmp, path).map_err(io)?;
    Ok((size, build_s))
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
}

impl Store {
    /// Maps `path` and checks it completely (header, section sizes, checksums).
    pub fn open(path: &Path) -> Result<Store, StoreError> {
        if cfg!(target_endian = "big") {
            return Err(StoreError::Endianness);
        }
        let io = |source| StoreError::Io {
            path: path.display().to_string(),
            source,
        };
        let file = File::open(path).map_err(io)?;
        let map = mmap::map(&file).map_err(io)?;
        let header = Header::parse(&map[..HEADER_LEN.min(map.len())], map.len() as u64)?;
        let geom = geometry(
            header.width,
            header.height,
            header.spacing_x,
            header.spacing_y,
            header.z_quantum,
        )?;
        let nodes = geom.shape.node_count();
        let inner = geom.shape.level_offset(geom.shape.depth());
        let samples = header.width as u64 * header.height as u64;
        let expect = [nodes * 4, inner, inner * 4, inner * 4, samples.div_ceil(8)];
        for (i, &len) in expect.iter().enumerate() {
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
        let (off, len) = header.sections[5];
        let meta = serde_json::from_slice(&map[off as usize..(off + len) as usize])
            .map_err(|e| StoreError::Corrupt(format!("metadata: {e}")))?;
        Ok(Store {
            map,
            header,
            geom,
            meta,
        })
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

    /// Heights of all nodes, z quanta, by dense index.
    pub fn z(&self) -> &[i32] {
        // Sections are 8-byte aligned in a page-aligned map and their lengths were checked.
        bytemuck::try_cast_slice(self.section(0)).unwrap_or(&[])
    }

    /// Static-error codes of inner nodes, by dense index.
    pub fn err(&self) -> &[u8] {
        self.section(1)
    }

    /// Lowest subtree height of inner nodes, z quanta.
    pub fn zmin(&self) -> &[i32] {
        bytemuck::try_cast_slice(self.section(2)).unwrap_or(&[])
    }

    /// Highest subtree height of inner nodes, z quanta.
    pub fn zmax(&self) -> &[i32] {
        bytemuck::try_cast_slice(self.section(3)).unwrap_or(&[])
    }

    /// Whether sample `(col, row)` was a void in the source.
    pub fn is_void(&self, col: u32, row: u32) -> bool {
        let i = row as usize * self.header.width as usize + col as usize;
        self.section(4)[i / 8] & (1 << (i % 8)) != 0
    }

    /// Error code of `node` (0 for leaves).
    pub fn err_code(&self, node: NodeId) -> u8 {
        let i = self.geom.shape.index(node) as usize;
        self.err().get(i).copied().unwrap_or(0)
    }

    /// Size of the mapped file in bytes.
    pub fn file_len(&self) -> usize {
        self.map.len()
    }
}

#[cfg(test)]
mod tests;
