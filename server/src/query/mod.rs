//! Terrain queries for simulator back ends (DESIGN.md section 5, paper 004): heights and
//! normals at points, first hits of rays, lines of sight, and CIGI's height of terrain (HOT)
//! and height above terrain (HAT), all exact against one full-resolution surface. Pure: no
//! async, no I/O, so that the HTTP and WebSocket edges, the benchmarks and the tests call the
//! same code.
//!
//! - [`surface`]: the surface itself (the bilinear patch over each cell), heights and normals
//!   at world points, bilinear or bicubic.
//! - [`pyramid`]: the max-mip and min-mip pyramids over the cells (paper 004, figure 4).
//! - [`ray`]: the first hit of a ray by a stackless traversal of the max-mip pyramid (paper
//!   004's multi-level tracing, figures 5 and 6), and the brute-force cell-by-cell march it
//!   is checked against.
//! - [`los`]: line of sight between two points with a clearance.
//! - [`hat`]: HAT/HOT for many entities.
//! - [`batch`]: the wire's query batches ([`relief_proto::query`]) answered item by item.
//! - [`view`]: a picture of a camera's view, one ray per pixel, shaded like the client's
//!   renderer (`GET /v1/raycast.png`).
//!
//! **Frame.** Queries take and give world metres in the project's frame (DESIGN.md section 2,
//! [`relief_proto::tree::WorldFrame`]): x east from the westmost column, y north from the
//! southmost row, z up. Sample `(col, row)` (row 0 north) lies at
//! `(col * dx, (height - 1 - row) * dy)`. The terrain covers `[0, (width-1) dx] x
//! [0, (height-1) dy]`; a point outside it has no height ([`QueryError::Outside`]), and a ray
//! meets no ground outside it.
//!
//! **Voids** hold their filled heights, as everywhere else in the store: a query over a void
//! answers the filled ground.
//!
//! **Pyramids are built when a [`Terrain`] is made, not stored.** They derive from the
//! heights in one pass (about 0.2 s on one core and 45 MB for a 4097 x 4097 grid, `bench
//! query` reports both), while the heights themselves must be copied out of the store's quadtree records
//! anyway ([`crate::store::Store::heights`]); keeping them in the file would grow every store
//! and change its format for no faster start.

pub mod batch;
pub mod hat;
pub mod los;
pub mod pyramid;
pub mod ray;
pub mod surface;
pub mod view;

#[cfg(test)]
mod tests;

use glam::DVec3;
pub use hat::HatHot;
pub use los::Sight;
pub use pyramid::Pyramid;
pub use ray::{Hit, Ray};
pub use surface::{Interp, SurfacePoint};

/// Why a query has no answer (each item of a batch gets its own).
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum QueryError {
    /// A coordinate, direction, distance or clearance is NaN or infinite.
    #[error("a coordinate is not a finite number")]
    NotFinite,
    /// The point lies outside the terrain's extent.
    #[error("point ({}, {}) lies outside the terrain", Short(*x), Short(*y))]
    Outside {
        /// World x, metres.
        x: f64,
        /// World y, metres.
        y: f64,
    },
    /// A ray's or sight line's direction is zero.
    #[error("the ray's direction is zero")]
    ZeroDirection,
    /// A maximum distance or a clearance is negative.
    #[error("distance or clearance {} m is negative", Short(*.0))]
    Negative(f64),
    /// A ray's origin or a sight line's end lies farther from the terrain than
    /// [`QUERY_REACH_M`], where `f64` can no longer place it to the metre.
    #[error("{0} lies more than 1e6 m from the terrain")]
    OutOfReach(&'static str),
    /// The grid cannot be queried: fewer than 2 x 2 samples, a non-positive spacing, a height
    /// that is not finite, or heights that do not match the size.
    #[error("cannot query this grid: {0}")]
    BadGrid(&'static str),
}

/// How far beyond the terrain's extent, and above or below its highest or lowest point, a ray's
/// origin or a sight line's end may be, metres: as far as a session's camera may be. Farther,
/// the grid coordinates lose the precision the answers need (at 1e16 m a ray's hit was 1.1 m
/// off; at 1e100 every coordinate rounds to one value).
pub const QUERY_REACH_M: f64 = 1.0e6;

/// A number in a message: as written when it is of ordinary size, in scientific notation when
/// not, so that a message stays short whatever the client sent (an `f64` written out in full
/// can take 300 digits).
pub struct Short(pub f64);

impl std::fmt::Display for Short {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let a = self.0.abs();
        if a == 0.0 || (1e-6..1e9).contains(&a) || !a.is_finite() {
            write!(f, "{}", self.0)
        } else {
            write!(f, "{:e}", self.0)
        }
    }
}

/// A terrain ready for queries: its heights and its pyramids.
#[derive(Clone, Debug)]
pub struct Terrain {
    /// Samples per row (east-west).
    width: u32,
    /// Rows (north-south).
    height: u32,
    /// Ground metres between columns, to turn world x into grid units.
    dx: f64,
    /// Ground metres between rows, to turn world y into grid units.
    dy: f64,
    /// Heights in metres, row-major **from the south** (the store's rows flipped), so that
    /// `y / dy` indexes rows directly.
    z: Vec<f32>,
    /// The max-mip and min-mip pyramids over the cells.
    pyramid: Pyramid,
    /// The largest absolute height, metres: the vertical reach is measured from it.
    z_abs_max: f64,
}

impl Terrain {
    /// A terrain of `width` x `height` samples spaced `dx`, `dy` metres, from row-major
    /// `heights` in metres with row 0 north (as [`crate::store::Store::heights`] and
    /// [`crate::dem::Dem`] hold them). Builds the pyramids.
    pub fn new(
        width: u32,
        height: u32,
        dx: f64,
        dy: f64,
        heights: &[f32],
    ) -> Result<Terrain, QueryError> {
        if heights.len() != width as usize * height as usize {
            return Err(QueryError::BadGrid("heights do not match the size"));
        }
        let w = (width as usize).max(1);
        let z: Vec<f32> = heights.chunks_exact(w).rev().flatten().copied().collect();
        Terrain::from_south_rows(width, height, dx, dy, z)
    }

    /// A terrain from `z`, row-major from the south (as [`Terrain`] keeps it). Builds the
    /// pyramids.
    fn from_south_rows(
        width: u32,
        height: u32,
        dx: f64,
        dy: f64,
        z: Vec<f32>,
    ) -> Result<Terrain, QueryError> {
        if width < 2 || height < 2 {
            return Err(QueryError::BadGrid("fewer than 2 x 2 samples"));
        }
        if !(dx.is_finite() && dy.is_finite() && dx > 0.0 && dy > 0.0) {
            return Err(QueryError::BadGrid("the spacing must be positive"));
        }
        if z.len() != width as usize * height as usize {
            return Err(QueryError::BadGrid("heights do not match the size"));
        }
        if z.iter().any(|h| !h.is_finite()) {
            return Err(QueryError::BadGrid("a height is not finite"));
        }
        let pyramid = Pyramid::build(&z, width, height);
        let z_abs_max = f64::from(z.iter().fold(0f32, |m, h| m.max(h.abs())));
        Ok(Terrain {
            width,
            height,
            dx,
            dy,
            z,
            pyramid,
            z_abs_max,
        })
    }

    /// Checks that `p` (a ray's origin, a sight line's end, named `what`) lies within
    /// [`QUERY_REACH_M`] of the terrain.
    pub fn check_reach(&self, p: DVec3, what: &'static str) -> Result<(), QueryError> {
        let (w, h) = self.extent();
        let r = QUERY_REACH_M;
        let inside = (-r..=w + r).contains(&p.x)
            && (-r..=h + r).contains(&p.y)
            && p.z.abs() <= self.z_abs_max + r;
        if inside {
            Ok(())
        } else {
            Err(QueryError::OutOfReach(what))
        }
    }

    /// The terrain of a store: its heights as stored (within half a z quantum of the source).
    pub fn from_store(store: &crate::store::Store) -> Result<Terrain, QueryError> {
        use rayon::prelude::*;
        let g = store.geometry();
        let (w, h) = (g.shape.width(), g.shape.height());
        let q = g.z_quantum;
        // The rows from the south straight from the store's records, with no copy of the grid
        // in the store's order between (on a large terrain, gigabytes at the server's start).
        let mut z = vec![0f32; w as usize * h as usize];
        z.par_chunks_mut(w as usize)
            .enumerate()
            .for_each(|(i, row)| {
                let r = h - 1 - i as u32;
                for (c, v) in row.iter_mut().enumerate() {
                    *v = store.sample_z(c as u32, r) as f32 * q;
                }
            });
        Terrain::from_south_rows(w, h, f64::from(g.frame.dx), f64::from(g.frame.dy), z)
    }

    /// Samples per row and rows.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Ground metres between columns and between rows.
    pub fn spacing(&self) -> (f64, f64) {
        (self.dx, self.dy)
    }

    /// World extent east and north, metres.
    pub fn extent(&self) -> (f64, f64) {
        (
            f64::from(self.width - 1) * self.dx,
            f64::from(self.height - 1) * self.dy,
        )
    }

    /// The pyramids.
    pub fn pyramid(&self) -> &Pyramid {
        &self.pyramid
    }

    /// Bytes held: heights plus pyramids.
    pub fn bytes(&self) -> usize {
        self.z.len() * 4 + self.pyramid.bytes()
    }

    /// Height of grid sample `(i, j)`, `j` counted from the south, metres.
    #[inline]
    fn at(&self, i: u32, j: u32) -> f64 {
        f64::from(self.z[j as usize * self.width as usize + i as usize])
    }

    /// Cells per row and per column.
    #[inline]
    fn cells(&self) -> (u32, u32) {
        (self.width - 1, self.height - 1)
    }
}
