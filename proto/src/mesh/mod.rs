//! The mesh reconstruction rule of paper 000, section 3.5, and the client's incremental fans.
//!
//! **The rule.** Triangulate the full-resolution grid with a fixed diagonal; replace every vertex
//! by its active ancestor; drop the triangles that repeat a vertex. Whatever the level differences
//! between neighbours, the result has no cracks and no fold-overs (section 3.5.3).
//!
//! Cell `(c, r)` is the grid square whose north-west sample is `(c, r)`. With corners
//! `a = (c, r)` (NW), `b = (c+1, r)` (NE), `d = (c, r+1)` (SW) and `e = (c+1, r+1)` (SE), the
//! fixed diagonal runs NW-SE and the two triangles are `(a, d, e)` and `(a, e, b)`, both
//! counter-clockwise seen from above in the world frame (y north).
//!
//! - [`oracle`]: the rule applied to every cell, the test oracle.
//! - [`fans`]: the output-sensitive incremental builder the client uses.
//! - [`check`]: crack, fold and manifold checks of a triangle list.
//! - [`morph`]: where each active node is drawn: the geomorph down the chain of ancestors.
//! - [`scene`]: the node and triangle records a GPU draws the fans and the geomorph from.

pub mod check;
pub mod fans;
pub mod morph;
pub mod oracle;
pub mod scene;

pub use check::{MeshReport, check_mesh};
pub use fans::FanMesh;
pub use morph::{MorphRule, drawn_position};
pub use oracle::oracle;

use crate::tree::NodeId;

/// An oriented triangle of active nodes, rotated (never reflected) so that its smallest node
/// comes first: two triangles are the same oriented triangle exactly when they are equal.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Tri(pub [NodeId; 3]);

impl Tri {
    /// The canonical rotation of `(a, b, c)`, or `None` when a vertex repeats.
    pub fn new(a: NodeId, b: NodeId, c: NodeId) -> Option<Tri> {
        if a == b || b == c || a == c {
            return None;
        }
        Some(if a < b && a < c {
            Tri([a, b, c])
        } else if b < c {
            Tri([b, c, a])
        } else {
            Tri([c, a, b])
        })
    }
}

/// The (up to two) triangles of cell `(c, r)`, given the active node of each of its corners.
pub fn cell_triangles(nw: NodeId, ne: NodeId, sw: NodeId, se: NodeId) -> [Option<Tri>; 2] {
    [Tri::new(nw, sw, se), Tri::new(nw, se, ne)]
}

#[cfg(test)]
mod tests;
