//! `relief-proto`: the contract that the Relief server and client agree on bit for bit.
//!
//! It is pure: no async runtime, no GPU, no I/O.
//!
//! - [`tree`]: node addressing of the vertex quadtree (level, x, y), dense indices, node
//!   positions, and the world frame (origin and axes), stated once here.
//! - [`cut`]: the set of active nodes, split and merge, and the digest of the active set.
//! - [`fan`]: the mesh reconstruction rule (paper 000, section 3.5): the brute-force oracle and the
//!   output-sensitive incremental builder the client uses.
pub mod cut;
pub mod fan;
pub mod tree;
