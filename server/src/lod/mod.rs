//! LOD engines: pure modules, no async, unit-testable and benchmarkable.
//!
//! - [`vertex`]: the vertex stream (paper 000): screen errors, initial cut, coherent updates.
//! - [`measure`]: the measured pixel error of a mesh for a camera (DESIGN.md section 7).
pub mod measure;
pub mod vertex;

#[cfg(test)]
mod tests;
