//! `relief-proto`: the contract that the Relief server and client agree on bit for bit.
//!
//! It is pure: no async runtime, no GPU, no I/O.
//!
//! - [`tree`]: node addressing of the vertex quadtree (level, x, y), dense indices, node
//!   positions, and the world frame (origin and axes), stated once here.
//! - [`terrain`]: tree shape plus metres: node world positions and bounding boxes.
//! - [`cut`]: the set of active nodes, split and merge, and the digest of the active set.
//! - [`haar`]: the integer Haar step (parent plus three details) and the static-error code.
//! - [`view`]: cameras, frustum, screen-space error and the geomorph factor.
//! - [`delta`]: merges and splits between two cuts, and their compact range-coded body.
//! - [`range`]: the adaptive binary range coder behind that body; [`bits`]: the bit writer and
//!   reader with Exp-Golomb codes behind the tile bodies.
//! - [`mirror`]: the client-side cut with heights, rebuilt from deltas and checked by digest.
//! - [`msg`]: the wire messages; [`codec`]: their bincode encoding with a decode limit;
//!   [`close`]: the reasons a session ends; [`snapshot`]: a cut in one bit per inner node.
//! - [`errors`]: one-line error reports for the command lines.
//! - [`float`]: minimum and maximum of floats that are never NaN, one instruction each.
//! - [`prefetch`]: the hint that a cache line will be read soon.
//! - [`path`]: the standard and stress camera paths.
//! - [`query`]: terrain query batches and their answers (heights, HAT/HOT, rays, lines of
//!   sight).
//! - [`rng`]: a small seeded generator (splitmix64) for load plans, benchmarks and tests.
//! - [`tile`]: the tile stream (paper 001): the tile pyramid's shape, tile bodies with crack
//!   patches, tile deltas, the tile cache both ends keep, and snapshots of an active tile set.
//! - [`mesh`]: the mesh reconstruction rule (paper 000, section 3.5): the brute-force oracle and the
//!   output-sensitive incremental builder the client uses.
//! - `paged`: a sparse 2D grid of small records in pages, for the fan mesh's cells and the
//!   mirror's heights.
pub mod bits;
pub mod close;
pub mod codec;
pub mod cut;
pub mod delta;
pub mod errors;
pub mod float;
pub mod haar;
pub mod mesh;
pub mod mirror;
pub mod msg;
pub mod nodeset;
mod paged;
pub mod path;
pub mod prefetch;
pub mod query;
pub mod range;
pub mod rng;
pub mod snapshot;
pub mod terrain;
pub mod tile;
pub mod tree;
pub mod view;
