//! The brute-force reconstruction rule: every cell of the grid, every time. The test oracle.

use super::{Tri, cell_triangles};
use crate::cut::Cut;
use crate::tree::TreeShape;

/// All triangles of the rule for `cut`, canonical and sorted.
///
/// It paints each active node's index over its sample block (so each sample's active ancestor is
/// one array read), then emits the two triangles of every cell: O(W x H) time and memory.
pub fn oracle(shape: &TreeShape, cut: &Cut) -> Vec<Tri> {
    let (w, h) = (shape.width() as usize, shape.height() as usize);
    let active = cut.active_nodes(shape);
    let mut owner = vec![0u32; w * h];
    for (k, n) in active.iter().enumerate() {
        let (c0, r0, c1, r1) = shape.block(*n);
        for r in r0 as usize..=r1 as usize {
            owner[r * w + c0 as usize..=r * w + c1 as usize].fill(k as u32);
        }
    }
    let mut out = Vec::new();
    for r in 0..h - 1 {
        for c in 0..w - 1 {
            let at = |cc: usize, rr: usize| active[owner[rr * w + cc] as usize];
            let tris = cell_triangles(at(c, r), at(c + 1, r), at(c, r + 1), at(c + 1, r + 1));
            out.extend(tris.into_iter().flatten());
        }
    }
    out.sort_unstable();
    out
}
