//! The tile stream's contract (DESIGN.md section 4; paper 001): the tile pyramid's shape, tile
//! bodies with their crack patches, tile deltas, the client's tile cache, and resume snapshots of
//! an active tile set.
//!
//! - this file: [`TileId`] and [`TileShape`], which tiles exist and which samples each covers;
//! - [`body`]: a tile's heights and crack patches, bit-packed, and the triangles they make;
//! - [`delta`]: tiles removed and added between two selections, and their byte layout;
//! - [`cache`]: the active set, its digest and the client's tile cache, which both ends keep
//!   with one deterministic eviction rule so that the server never sends a tile twice;
//! - [`snapshot`]: an active tile set in one bit per inner tile, for resume, and the
//!   restriction check;
//! - [`mirror`]: the client's decoded tiles, rebuilt from deltas and checked by digest;
//! - [`geometry`]: a held tile's triangles in world metres, with its patches or skirts.
//!
//! **Pyramid.** Tiles have `T` x `T` cells (T a power of two, 64 by default). The finest level
//! `L` has a vertex every sample; level `k` has one every `s = 2^(L-k)` samples. Tile `(k, x, y)`
//! covers sample columns `[x*T*s, min((x+1)*T*s, W-1)]` and the same for rows (row 0 north), and
//! exists when that range holds at least one cell in both directions. Its vertex columns are the
//! multiples of `s` inside the range plus the range's last column, so a tile on the east or south
//! border of a grid whose size is not `T*2^L+1` ends with one narrower cell: the terrain needs no
//! padding and has no walls at its borders. Level 0 is one tile. A tile's children are the up to
//! four tiles of the next level inside it, in [`crate::tree::NodeId::child`] order.
//!
//! Because every level's vertex columns contain the coarser level's, two neighbouring tiles one
//! level apart agree at every coarse vertex of their shared edge; each coarse edge segment holds
//! at most one vertex of the finer level, and that vertex alone can open a crack (paper 001,
//! section 2.1), which [`body`]'s patches close.

pub mod body;
pub mod cache;
pub mod delta;
pub mod draw;
mod example;
pub mod geometry;
pub mod mirror;
pub mod snapshot;

use crate::codec::{Decode, Encode};
use crate::tree::{MAX_DEPTH, NodeId, ShapeError};

/// A tile: level (0 = the one root tile), column and row within the level (row 0 north).
pub type TileId = NodeId;

/// Smallest and largest tile size in cells.
pub const TILE_SIZE_RANGE: (u32, u32) = (2, 256);

/// Why a tile pyramid cannot be formed.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TileShapeError {
    /// The grid itself is not representable.
    #[error(transparent)]
    Grid(#[from] ShapeError),
    /// The tile size is not a power of two in range.
    #[error("tile size {0} must be a power of two from 2 to 256 cells")]
    TileSize(u32),
}

/// The shape of a tile pyramid over a W x H grid. Both ends derive it from the grid size and
/// the tile size, so it never travels.
#[derive(Clone, Debug, PartialEq)]
pub struct TileShape {
    /// Grid width in samples.
    width: u32,
    /// Grid height in samples.
    height: u32,
    /// Cells per tile side.
    tile: u32,
    /// The finest level, whose vertices are every sample.
    depth: u8,
    /// Tiles per row and per column at each level.
    dims: Vec<(u32, u32)>,
    /// Dense index of each level's first tile, plus the total at the end.
    offsets: Vec<u32>,
}

/// The four edges of a tile, in the order bodies list them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Edge {
    /// The first row, west to east.
    North = 0,
    /// The last column, north to south.
    East = 1,
    /// The last row, west to east.
    South = 2,
    /// The first column, north to south.
    West = 3,
}

/// All edges in body order.
pub const EDGES: [Edge; 4] = [Edge::North, Edge::East, Edge::South, Edge::West];

/// Which samples a tile covers and where its vertices are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TileSpan {
    /// First and last sample column.
    pub cols: (u32, u32),
    /// First and last sample row.
    pub rows: (u32, u32),
    /// Samples between vertices (the last cell may be narrower).
    pub stride: u32,
}

impl TileSpan {
    /// Vertices along x.
    pub fn nx(&self) -> u32 {
        (self.cols.1 - self.cols.0).div_ceil(self.stride) + 1
    }

    /// Vertices along y.
    pub fn ny(&self) -> u32 {
        (self.rows.1 - self.rows.0).div_ceil(self.stride) + 1
    }

    /// Sample column of vertex column `i`.
    pub fn col(&self, i: u32) -> u32 {
        (self.cols.0 + i * self.stride).min(self.cols.1)
    }

    /// Sample row of vertex row `j`.
    pub fn row(&self, j: u32) -> u32 {
        (self.rows.0 + j * self.stride).min(self.rows.1)
    }

    /// Vertex count.
    pub fn vertex_count(&self) -> usize {
        self.nx() as usize * self.ny() as usize
    }

    /// The vertices along `edge` in its direction, as vertex indices (row-major).
    pub fn edge_vertices(&self, edge: Edge) -> Vec<u32> {
        let (nx, ny) = (self.nx(), self.ny());
        match edge {
            Edge::North => (0..nx).collect(),
            Edge::South => (0..nx).map(|i| (ny - 1) * nx + i).collect(),
            Edge::West => (0..ny).map(|j| j * nx).collect(),
            Edge::East => (0..ny).map(|j| j * nx + nx - 1).collect(),
        }
    }

    /// Grid position (column, row) of vertex index `v`.
    pub fn vertex_pos(&self, v: u32) -> (u32, u32) {
        let nx = self.nx();
        (self.col(v % nx), self.row(v / nx))
    }

    /// `f(col, row)` at every vertex's sample, in vertex order: `f` of [`TileSpan::vertex_pos`]
    /// of `0, 1, ...`, without a division per vertex.
    pub fn map_vertices<T>(&self, mut f: impl FnMut(u32, u32) -> T) -> Vec<T> {
        let mut out = Vec::with_capacity(self.vertex_count());
        for j in 0..self.ny() {
            let r = self.row(j);
            for i in 0..self.nx() {
                out.push(f(self.col(i), r));
            }
        }
        out
    }
}

impl TileShape {
    /// The pyramid over a `width` x `height` grid with tiles of `tile` cells.
    pub fn new(width: u32, height: u32, tile: u32) -> Result<TileShape, TileShapeError> {
        if width < 2 || height < 2 {
            return Err(ShapeError::TooSmall(width, height).into());
        }
        if width > 1 << MAX_DEPTH || height > 1 << MAX_DEPTH {
            return Err(ShapeError::TooLarge(width, height).into());
        }
        if !tile.is_power_of_two() || !(TILE_SIZE_RANGE.0..=TILE_SIZE_RANGE.1).contains(&tile) {
            return Err(TileShapeError::TileSize(tile));
        }
        let cells = (width - 1).max(height - 1);
        let mut depth = 0u8;
        while (tile as u64) << depth < cells as u64 {
            depth += 1;
        }
        let mut dims = Vec::new();
        let mut offsets = vec![0u32];
        for k in 0..=depth {
            let ext = (tile as u64) << (depth - k);
            let d = (
                ((width - 1) as u64).div_ceil(ext) as u32,
                ((height - 1) as u64).div_ceil(ext) as u32,
            );
            dims.push(d);
            let last = *offsets.last().unwrap_or(&0);
            offsets.push(last + d.0 * d.1);
        }
        Ok(TileShape {
            width,
            height,
            tile,
            depth,
            dims,
            offsets,
        })
    }

    /// Grid width in samples.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Grid height in samples.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Cells per tile side.
    pub fn tile_size(&self) -> u32 {
        self.tile
    }

    /// The finest level.
    pub fn depth(&self) -> u8 {
        self.depth
    }

    /// Tiles per row and column at `level`.
    pub fn level_dims(&self, level: u8) -> (u32, u32) {
        self.dims[level as usize]
    }

    /// Number of tiles in the pyramid.
    pub fn tile_count(&self) -> u32 {
        *self.offsets.last().unwrap_or(&0)
    }

    /// Whether `t` is a tile of this pyramid.
    pub fn contains(&self, t: TileId) -> bool {
        t.level <= self.depth && {
            let (w, h) = self.dims[t.level as usize];
            t.x < w && t.y < h
        }
    }

    /// Dense index of `t` (level by level, row-major): below [`TileShape::tile_count`].
    pub fn index(&self, t: TileId) -> u32 {
        let (w, _) = self.dims[t.level as usize];
        self.offsets[t.level as usize] + t.y * w + t.x
    }

    /// The tile with dense index `i`, if any.
    pub fn tile(&self, i: u32) -> Option<TileId> {
        if i >= self.tile_count() {
            return None;
        }
        let level = self.offsets.partition_point(|&o| o <= i) - 1;
        let (w, _) = self.dims[level];
        let r = i - self.offsets[level];
        Some(TileId {
            level: level as u8,
            x: r % w,
            y: r / w,
        })
    }

    /// Whether `t` lies at the finest level.
    pub fn is_leaf(&self, t: TileId) -> bool {
        t.level == self.depth
    }

    /// The existing children of `t`, in [`NodeId::child`] order.
    pub fn children(&self, t: TileId) -> impl Iterator<Item = TileId> + '_ {
        let inner = t.level < self.depth;
        (0..4)
            .filter(move |_| inner)
            .map(move |k| t.child(k))
            .filter(move |c| self.contains(*c))
    }

    /// The tile across `edge` at the same level, if any.
    pub fn neighbour(&self, t: TileId, edge: Edge) -> Option<TileId> {
        let n = match edge {
            Edge::North => TileId {
                y: t.y.checked_sub(1)?,
                ..t
            },
            Edge::South => TileId { y: t.y + 1, ..t },
            Edge::West => TileId {
                x: t.x.checked_sub(1)?,
                ..t
            },
            Edge::East => TileId { x: t.x + 1, ..t },
        };
        self.contains(n).then_some(n)
    }

    /// Samples between vertices at `level`.
    pub fn stride(&self, level: u8) -> u32 {
        1 << (self.depth - level)
    }

    /// The samples `t` covers and its vertex stride.
    pub fn span(&self, t: TileId) -> TileSpan {
        let stride = self.stride(t.level);
        let ext = self.tile * stride;
        let (c0, r0) = (t.x * ext, t.y * ext);
        TileSpan {
            cols: (c0, (c0 + ext).min(self.width - 1)),
            rows: (r0, (r0 + ext).min(self.height - 1)),
            stride,
        }
    }
}

/// What a tile client is told of the pyramid, in the welcome of a tile session and by
/// `GET /v1/tiles.json`.
#[derive(Clone, Debug, PartialEq, Encode, Decode)]
pub struct TileSetInfo {
    /// Cells per tile side.
    pub tile_size: u32,
    /// The finest level.
    pub depth: u8,
    /// The tile meshes' kind (`grid` today).
    pub mesh: String,
    /// Largest geometric error of any tile of each level, metres (level 0 first): skirts hang
    /// five times this far below their level's tiles.
    pub level_errors: Vec<f32>,
}

impl TileSetInfo {
    /// The shape of the pyramid over a `width` x `height` grid.
    pub fn shape(&self, width: u32, height: u32) -> Result<TileShape, TileShapeError> {
        let s = TileShape::new(width, height, self.tile_size)?;
        if s.depth() != self.depth {
            return Err(TileShapeError::TileSize(self.tile_size));
        }
        Ok(s)
    }

    /// How far skirts hang below tiles of `level`, metres: Cesium's rule of five times a
    /// level's largest geometric error, taken from the level above (the coarser neighbour a
    /// tile may meet bounds the gap to it), since the finest level's own error is only the
    /// height quantisation and would hang no skirt at all.
    pub fn skirt_height(&self, level: u8) -> f32 {
        5.0 * self
            .level_errors
            .get(level.saturating_sub(1) as usize)
            .copied()
            .unwrap_or(0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pyramid_covers_any_grid_once_per_level() {
        for &(w, h, t) in &[
            (5, 3, 2),
            (257, 193, 64),
            (65, 65, 64),
            (300, 70, 16),
            (2, 2, 64),
        ] {
            let s = TileShape::new(w, h, t).unwrap();
            assert_eq!(s.level_dims(0), (1, 1), "{w}x{h}");
            assert_eq!(s.stride(s.depth()), 1);
            for k in 0..=s.depth() {
                let (nx, ny) = s.level_dims(k);
                let mut cells = 0u64;
                for y in 0..ny {
                    for x in 0..nx {
                        let t = TileId { level: k, x, y };
                        assert_eq!(s.tile(s.index(t)), Some(t));
                        let sp = s.span(t);
                        assert!(sp.cols.1 > sp.cols.0 && sp.rows.1 > sp.rows.0);
                        cells += (sp.cols.1 - sp.cols.0) as u64 * (sp.rows.1 - sp.rows.0) as u64;
                        assert!(sp.nx() <= t_plus_one(&s) && sp.ny() <= t_plus_one(&s));
                    }
                }
                assert_eq!(cells, (w as u64 - 1) * (h as u64 - 1), "level {k}");
            }
        }
    }

    fn t_plus_one(s: &TileShape) -> u32 {
        s.tile_size() + 1
    }

    #[test]
    fn children_nest_inside_parents_and_coarse_vertices_are_fine_vertices() {
        let s = TileShape::new(300, 70, 16).unwrap();
        for i in 0..s.tile_count() {
            let t = s.tile(i).unwrap();
            let sp = s.span(t);
            let cols: Vec<u32> = (0..sp.nx()).map(|i| sp.col(i)).collect();
            for c in s.children(t) {
                let cs = s.span(c);
                assert!(cs.cols.0 >= sp.cols.0 && cs.cols.1 <= sp.cols.1);
                let ccols: Vec<u32> = (0..cs.nx()).map(|i| cs.col(i)).collect();
                for col in cols.iter().filter(|&&v| v >= cs.cols.0 && v <= cs.cols.1) {
                    assert!(ccols.contains(col));
                }
            }
        }
        assert!(TileShape::new(10, 10, 48).is_err());
    }
}
