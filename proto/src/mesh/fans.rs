//! The output-sensitive, incremental form of the reconstruction rule (paper 000, section 3.5.2).
//!
//! A cell yields a triangle only when its four corners fall in at least three different active
//! blocks, and then the cell's centre is a corner of some active block (three or four blocks
//! meeting at a point cannot all pass straight through it). So the mesh is the union, over the
//! corners of active blocks, of the triangles of the cell centred there: the *junction cells*.
//! Around an active node these are its fan, which the paper builds from its neighbours.
//!
//! [`FanMesh`] keeps the triangles of every junction cell. A split or merge of a node changes
//! which active node the samples inside its block map to, so the only cells that can change are
//! the junction cells centred on that block's closure: the corners of the node and of its
//! children, and the corners of the active neighbours that lie on its edges. Those are found by
//! walking each edge from neighbour to neighbour, so an update costs a number of ancestor lookups
//! proportional to the node's neighbours, whatever its size.

use super::{Tri, cell_triangles};
use crate::cut::Cut;
use crate::tree::{NodeId, TreeShape};
use rustc_hash::FxHashMap;

/// The triangles of every junction cell of a cut.
#[derive(Clone, Debug, Default)]
pub struct FanMesh {
    /// Non-empty junction cells, keyed by cell (column, row), with their one or two triangles.
    cells: FxHashMap<(u32, u32), [Option<Tri>; 2]>,
    /// Triangles over all cells, kept so that counting costs nothing.
    count: usize,
    /// Cells whose triangles changed since the last [`FanMesh::take_dirty`], for buffer uploads.
    dirty: Vec<(u32, u32)>,
    /// Cells recomputed since creation: the work done, to show it is output-sensitive.
    work: u64,
}

impl FanMesh {
    /// The mesh of `cut`, built from the corners of its active nodes.
    pub fn new(shape: &TreeShape, cut: &Cut) -> FanMesh {
        let mut m = FanMesh::default();
        for n in cut.active_nodes(shape) {
            for cell in corner_cells(shape, n) {
                m.recompute(shape, cut, cell);
            }
        }
        m.dirty.clear();
        m
    }

    /// Brings the mesh up to date after `node` has split or merged in `cut`.
    pub fn update_around(&mut self, shape: &TreeShape, cut: &Cut, node: NodeId) {
        let mut cells: Vec<(u32, u32)> = corner_cells(shape, node).collect();
        for (_, c) in shape.children(node) {
            cells.extend(corner_cells(shape, c));
        }
        neighbour_corner_cells(shape, cut, node, &mut cells);
        cells.sort_unstable();
        cells.dedup();
        for cell in cells {
            self.recompute(shape, cut, cell);
        }
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.count
    }

    /// All triangles, canonical and sorted (comparable with [`super::oracle`]).
    pub fn triangles(&self) -> Vec<Tri> {
        let mut v: Vec<Tri> = self.cells.values().flatten().flatten().copied().collect();
        v.sort_unstable();
        v
    }

    /// The triangles of cell `(c, r)`.
    pub fn cell(&self, cell: (u32, u32)) -> [Option<Tri>; 2] {
        self.cells.get(&cell).copied().unwrap_or([None, None])
    }

    /// Every non-empty junction cell, in no set order.
    pub fn cells(&self) -> Vec<(u32, u32)> {
        self.cells.keys().copied().collect()
    }

    /// The cells whose triangles changed since the last call, each once.
    pub fn take_dirty(&mut self) -> Vec<(u32, u32)> {
        let mut d = std::mem::take(&mut self.dirty);
        d.sort_unstable();
        d.dedup();
        d
    }

    /// Cells recomputed since creation.
    pub fn work(&self) -> u64 {
        self.work
    }

    fn recompute(&mut self, shape: &TreeShape, cut: &Cut, (c, r): (u32, u32)) {
        self.work += 1;
        let at = |cc, rr| cut.active_ancestor(shape, cc, rr);
        let tris = cell_triangles(at(c, r), at(c + 1, r), at(c, r + 1), at(c + 1, r + 1));
        let new = tris.iter().flatten().count();
        let old = self.cells.get(&(c, r)).copied().unwrap_or([None, None]);
        if old == tris {
            return;
        }
        self.count = self.count + new - old.iter().flatten().count();
        if new == 0 {
            self.cells.remove(&(c, r));
        } else {
            self.cells.insert((c, r), tris);
        }
        self.dirty.push((c, r));
    }
}

/// The cells centred on the four corners of `node`'s block that exist in the grid.
fn corner_cells(shape: &TreeShape, node: NodeId) -> impl Iterator<Item = (u32, u32)> {
    let (c0, r0, c1, r1) = shape.block(node);
    let (w, h) = (shape.width(), shape.height());
    // A corner between samples (c - 1, c) and (r - 1, r) is the cell (c - 1, r - 1).
    [(c0, r0), (c1 + 1, r0), (c0, r1 + 1), (c1 + 1, r1 + 1)]
        .into_iter()
        .filter(move |&(c, r)| c >= 1 && r >= 1 && c < w && r < h)
        .map(|(c, r)| (c - 1, r - 1))
}

/// Adds the cells centred on `node`'s block boundary at the corners of the active nodes just
/// outside each edge. Those neighbours are disjoint from the block, so the corners on their side
/// facing the block lie exactly on the block's edge line.
fn neighbour_corner_cells(shape: &TreeShape, cut: &Cut, node: NodeId, out: &mut Vec<(u32, u32)>) {
    let (c0, r0, c1, r1) = shape.block(node);
    let (w, h) = (shape.width(), shape.height());
    // A cell (c, r) exists when its four samples do: c + 1 < w and r + 1 < h.
    let mut push = |c: i64, r: i64| {
        if c >= 0 && r >= 0 && c + 1 < w as i64 && r + 1 < h as i64 {
            out.push((c as u32, r as u32));
        }
    };
    // West and east edges: walk the column just outside, neighbour by neighbour.
    for (col, west) in [(c0 as i64 - 1, true), (c1 as i64 + 1, false)] {
        if col < 0 || col >= w as i64 {
            continue;
        }
        let mut r = r0;
        while r <= r1 {
            let (nc0, nr0, nc1, nr1) = shape.block(cut.active_ancestor(shape, col as u32, r));
            let c = if west { nc1 as i64 } else { nc0 as i64 - 1 };
            push(c, nr0 as i64 - 1);
            push(c, nr1 as i64);
            r = nr1 + 1;
        }
    }
    // North and south edges: the row just outside.
    for (row, north) in [(r0 as i64 - 1, true), (r1 as i64 + 1, false)] {
        if row < 0 || row >= h as i64 {
            continue;
        }
        let mut c = c0;
        while c <= c1 {
            let (nc0, nr0, nc1, nr1) = shape.block(cut.active_ancestor(shape, c, row as u32));
            let r = if north { nr1 as i64 } else { nr0 as i64 - 1 };
            push(nc0 as i64 - 1, r);
            push(nc1 as i64, r);
            c = nc1 + 1;
        }
    }
}
