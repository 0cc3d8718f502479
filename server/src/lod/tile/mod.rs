//! The tile-stream LOD engine (DESIGN.md section 4; paper 001): screen errors of tiles and the
//! restricted selection. Pure: no I/O, no async.
//!
//! - this file: [`TileEngine`], a tile's box and screen error (Cesium's rule);
//! - [`bits`]: sets of tiles as bitsets over the pyramid;
//! - [`select`]: the selection for a camera: refine while the screen error exceeds tau, then
//!   refine coarser neighbours until no two edge-adjacent tiles differ by more than one level;
//! - [`session`]: one session's active tiles and client cache, and the budgeted, cache-aware
//!   tile delta from one selection to the next;
//! - [`mesh`]: tile meshes over a grid of samples and their error.
//!
//! **Screen error.** Cesium's screen-space-error rule: a tile's geometric error (metres, honest
//! and saturated: `store::tiles`) times the focal length in pixels, over the distance from the
//! eye to the nearest point of the tile's box (its samples' extent and height range). A tile
//! whose box lies outside the view frustum has screen error 0: it is kept, coarse, so that the
//! selection always covers the whole terrain once.

pub mod bits;
pub mod mesh;
pub mod select;
pub mod session;
#[cfg(test)]
mod tests;

use crate::store::tiles::TileRecord;
use crate::store::{Store, TileBounds};
use relief_proto::tile::TileShape;
use relief_proto::view::{Aabb, ViewState};

/// The engine over one store's tile pyramid; cheap to create, shared by all sessions.
pub struct TileEngine<'a> {
    /// The store, for tile blobs.
    store: &'a Store,
    /// The pyramid's shape.
    shape: &'a TileShape,
    /// Tile records by dense index.
    records: &'a [TileRecord],
    /// Tile boxes, errors and sizes by dense index.
    bounds: &'a [TileBounds],
}

impl<'a> TileEngine<'a> {
    /// The engine over `store`.
    pub fn new(store: &'a Store) -> TileEngine<'a> {
        TileEngine {
            store,
            shape: store.tile_shape(),
            records: store.tile_records(),
            bounds: store.tile_bounds(),
        }
    }

    /// The pyramid's shape.
    pub fn shape(&self) -> &'a TileShape {
        self.shape
    }

    /// The store.
    pub fn store(&self) -> &'a Store {
        self.store
    }

    /// The record of tile `index`.
    pub fn record(&self, index: u32) -> &'a TileRecord {
        &self.records[index as usize]
    }

    /// The box of tile `index`: its samples' extent and height range.
    pub fn tile_box(&self, index: u32) -> Aabb {
        self.bounds[index as usize].aabb
    }

    /// Ground metres across tile `index`'s longer side.
    pub fn tile_size_m(&self, index: u32) -> f32 {
        self.bounds[index as usize].size
    }

    /// Distance from the eye to the nearest point of `b`, at least the near plane.
    pub fn distance(view: &ViewState, b: &Aabb) -> f32 {
        let e = view.eye();
        (e.clamp(b.min, b.max) - e).length().max(view.near())
    }

    /// Screen-space error of tile `index` in pixels: Cesium's rule, 0 outside the frustum.
    pub fn screen_error(&self, view: &ViewState, index: u32) -> f32 {
        let b = &self.bounds[index as usize];
        if b.error <= 0.0 || !view.intersects(&b.aabb) {
            return 0.0;
        }
        b.error * view.focal() / Self::distance(view, &b.aabb)
    }
}
