//! LOD engines: pure modules, no async, unit-testable and benchmarkable.
//!
//! - [`vertex`]: the vertex stream (paper 000): screen errors, the initial cut, coherent and
//!   event-driven session updates, the bandwidth-budgeted update, cut diffs.
//! - [`tile`]: the tile stream (paper 001): the tile pyramid's build, the restricted
//!   screen-space-error selection, and a session's budgeted, cache-aware tile deltas.
//! - [`measure`]: the measured pixel error of a mesh for a camera (DESIGN.md section 7).
pub mod measure;
pub mod tile;
pub mod vertex;
