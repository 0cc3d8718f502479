//! Validity checks of a triangle list: no cracks, no fold-overs, a manifold surface.

use super::Tri;
use crate::tree::{NodeId, TreeShape};
use rustc_hash::FxHashMap;

/// What [`check_mesh`] found; a valid mesh has every count but `triangles` at 0.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MeshReport {
    /// Triangles checked.
    pub triangles: usize,
    /// Directed edges with no opposite twin that are not on the mesh's outer boundary: holes.
    pub cracks: usize,
    /// Triangles whose orientation seen from above is not counter-clockwise (or is degenerate).
    pub folds: usize,
    /// Directed edges used by more than one triangle.
    pub non_manifold_edges: usize,
}

/// Whether the edge `u -> v` lies on the mesh's outer boundary: both nodes' blocks touch the same
/// side of the grid. The outline of the full-resolution triangulation runs along the grid's
/// border samples, and replacing each by its active ancestor keeps it between border nodes.
fn on_boundary(shape: &TreeShape, u: NodeId, v: NodeId) -> bool {
    let (a, b) = (shape.block(u), shape.block(v));
    let (w, h) = (shape.width() - 1, shape.height() - 1);
    (a.0 == 0 && b.0 == 0)
        || (a.1 == 0 && b.1 == 0)
        || (a.2 == w && b.2 == w)
        || (a.3 == h && b.3 == h)
}

/// Checks `tris`, with `grid_pos` giving each node's (column, row) position.
pub fn check_mesh(
    shape: &TreeShape,
    grid_pos: impl Fn(NodeId) -> (f32, f32),
    tris: &[Tri],
) -> MeshReport {
    let mut edges: FxHashMap<(NodeId, NodeId), u32> = FxHashMap::default();
    let mut report = MeshReport {
        triangles: tris.len(),
        ..MeshReport::default()
    };
    for t in tris {
        let [a, b, c] = t.0;
        let (pa, pb, pc) = (grid_pos(a), grid_pos(b), grid_pos(c));
        // Rows grow southwards, so counter-clockwise in the world is clockwise in (col, row).
        let cross = (pb.0 - pa.0) * (pc.1 - pa.1) - (pc.0 - pa.0) * (pb.1 - pa.1);
        if cross >= 0.0 {
            report.folds += 1;
        }
        for e in [(a, b), (b, c), (c, a)] {
            *edges.entry(e).or_insert(0) += 1;
        }
    }
    for (&(u, v), &n) in &edges {
        if n > 1 {
            report.non_manifold_edges += 1;
        }
        if !edges.contains_key(&(v, u)) && !on_boundary(shape, u, v) {
            report.cracks += 1;
        }
    }
    report
}
