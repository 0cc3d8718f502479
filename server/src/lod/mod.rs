//! LOD engines: pure modules, no async, unit-testable and benchmarkable.
//!
//! - [`vertex`]: the vertex stream (paper 000): screen errors, initial cut, coherent updates.
//! - [`session`]: one session's cut with event-driven updates that re-examine only the nodes
//!   whose decision can have changed.
//! - [`budget`]: the bandwidth-budgeted update: merges, then the splits that remove the most
//!   screen error per byte, up to a byte budget (DESIGN.md section 6).
//! - [`diff`]: the delta between two arbitrary cuts, for the stateless HTTP one-shot.
//! - [`measure`]: the measured pixel error of a mesh for a camera (DESIGN.md section 7).
pub mod budget;
pub mod diff;
pub mod measure;
pub mod session;
pub mod vertex;

#[cfg(test)]
pub(crate) mod tests;
