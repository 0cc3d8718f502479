//! LOD engines: pure modules, no async, unit-testable and benchmarkable.
//!
//! - [`vertex`]: the vertex stream (paper 000): screen errors, initial cut, coherent updates.
//! - [`session`]: one session's cut with event-driven updates that re-examine only the nodes
//!   whose decision can have changed.
//! - [`measure`]: the measured pixel error of a mesh for a camera (DESIGN.md section 7).
pub mod measure;
pub mod session;
pub mod vertex;

#[cfg(test)]
mod tests;
