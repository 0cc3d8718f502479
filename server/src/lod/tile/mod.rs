//! The tile-stream LOD engine (DESIGN.md section 4; paper 001): screen errors of tiles and the
//! restricted selection. Pure: no I/O, no async.
//!
//! - this file: [`TileEngine`], a tile's box and screen error (Cesium's rule);
//! - [`bits`]: sets of tiles as bitsets over the pyramid;
//! - [`select`]: the selection for a camera: refine while the screen error exceeds tau, then
//!   refine coarser neighbours until no two edge-adjacent tiles differ by more than one level;
//! - [`session`]: one session's active tiles and client cache, and the budgeted, cache-aware
//!   tile delta from one selection to the next.
//!
//! **Screen error.** Cesium's screen-space-error rule: a tile's geometric error (metres, honest
//! and saturated: `store::tiles`) times the focal length in pixels, over the distance from the
//! eye to the nearest point of the tile's box (its samples' extent and height range). A tile
//! whose box lies outside the view frustum has screen error 0: it is kept, coarse, so that the
//! selection always covers the whole terrain once.

pub mod bits;
pub mod select;
pub mod session;
#[cfg(test)]
mod tests;

use crate::store::Store;
use crate::store::tiles::TileRecord;
use glam::Vec3;
use relief_proto::tile::{TileId, TileShape};
use relief_proto::tree::WorldFrame;
use relief_proto::view::{Aabb, ViewState};

/// The engine over one store's tile pyramid; cheap to create, shared by all sessions.
pub struct TileEngine<'a> {
    /// The store, for tile blobs.
    store: &'a Store,
    /// The pyramid's shape.
    shape: &'a TileShape,
    /// Tile records by dense index.
    records: &'a [TileRecord],
    /// Grid-to-world mapping.
    frame: WorldFrame,
    /// Metres per height quantum.
    quantum: f32,
}

impl<'a> TileEngine<'a> {
    /// The engine over `store`.
    pub fn new(store: &'a Store) -> TileEngine<'a> {
        let g = store.geometry();
        TileEngine {
            store,
            shape: store.tile_shape(),
            records: store.tile_records(),
            frame: g.frame,
            quantum: g.z_quantum,
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

    /// The box of tile `t` (dense index `index`): its samples' extent and height range.
    pub fn tile_box(&self, t: TileId, index: u32) -> Aabb {
        let sp = self.shape.span(t);
        let r = self.record(index);
        let (x0, y1) = self.frame.to_world(sp.cols.0 as f32, sp.rows.0 as f32);
        let (x1, y0) = self.frame.to_world(sp.cols.1 as f32, sp.rows.1 as f32);
        Aabb {
            min: Vec3::new(x0, y0, r.zmin as f32 * self.quantum),
            max: Vec3::new(x1, y1, r.zmax as f32 * self.quantum),
        }
    }

    /// Ground metres across tile `t`'s longer side.
    pub fn tile_size_m(&self, t: TileId) -> f32 {
        let sp = self.shape.span(t);
        ((sp.cols.1 - sp.cols.0) as f32 * self.frame.dx)
            .max((sp.rows.1 - sp.rows.0) as f32 * self.frame.dy)
    }

    /// Distance from the eye to the nearest point of `b`, at least the near plane.
    pub fn distance(view: &ViewState, b: &Aabb) -> f32 {
        let e = view.eye();
        (e.clamp(b.min, b.max) - e).length().max(view.near())
    }

    /// Screen-space error of tile `t` in pixels: Cesium's rule, 0 outside the frustum.
    pub fn screen_error(&self, view: &ViewState, t: TileId, index: u32) -> f32 {
        let err = self.record(index).error;
        if err <= 0.0 {
            return 0.0;
        }
        let b = self.tile_box(t, index);
        if !view.intersects(&b) {
            return 0.0;
        }
        err * view.focal() / Self::distance(view, &b)
    }
}
