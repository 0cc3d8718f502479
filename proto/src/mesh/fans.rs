//! The output-sensitive, incremental form of the reconstruction rule (paper 000, section 3.5.2).
//!
//! A cell yields a triangle only when its four corners fall in at least three different active
//! blocks, and then the cell's centre is a corner of some active block (three or four blocks
//! meeting at a point cannot all pass straight through it). So the mesh is the union, over the
//! corners of active blocks, of the triangles of the cell centred there: the *junction cells*.
//! Around an active node these are its fan, which the paper builds from its neighbours.
//!
//! [`FanMesh`] keeps every junction cell as one compact record: the levels of its four corners'
//! active ancestors (a corner's active node is its ancestor at that level, so four levels say
//! which nodes the cell joins, in 16 bits) and which of its two triangles exist. A split or merge
//! of a node changes which active node the samples inside its block map to, so the only cells
//! that can change are the junction cells centred on that block's closure: the corners of the
//! node and of its children, and the corners of the active neighbours that lie on its edges.
//! [`ring`] walks the active neighbours just outside the block once, edge by edge; every
//! corner of those cells is then either inside the block (the node, or its children after a
//! split) or on that ring, so an update costs one ancestor lookup per neighbour, whatever the
//! node's size, and no allocation.

mod grid;
mod ring;

use super::{Tri, cell_triangles};
use crate::cut::Cut;
use crate::tree::{NodeId, TreeShape};
use grid::CellGrid;
use ring::Ring;

/// The triangles of every junction cell of a cut.
#[derive(Clone, Debug)]
pub struct FanMesh {
    /// Grid width in samples, to tell cells that exist.
    width: u32,
    /// Grid height in samples.
    height: u32,
    /// Level of the leaves, to turn a corner's level back into its node.
    depth: u8,
    /// Junction cells: the levels of the active ancestors of the NW, NE, SW and SE corners, 4
    /// bits each from the low end. Only non-empty cells are held, so the root is interior and
    /// no corner is at level 0: a 0 for SW says the first triangle (NW, SW, SE) is missing, a 0
    /// for NE the second (NW, SE, NE), and a 0 record an empty cell.
    cells: CellGrid,
    /// Triangles over all cells, kept so that counting costs nothing.
    count: usize,
    /// Whether changed cells are marked for [`FanMesh::take_dirty`]: only a consumer that
    /// takes them (a renderer) should pay for the marks and hold emptied pages until then.
    track: bool,
    /// Cells recomputed since creation: the work done, to show it is output-sensitive.
    work: u64,
    /// The active neighbours around the block being updated, kept to reuse its buffers.
    ring: Ring,
}

impl FanMesh {
    /// The mesh of `cut`, built around each of its active nodes. Changed cells are not marked
    /// (see [`FanMesh::track_dirty`]).
    pub fn new(shape: &TreeShape, cut: &Cut) -> FanMesh {
        let (w, h) = (shape.width(), shape.height());
        let mut m = FanMesh {
            width: w,
            height: h,
            depth: shape.depth(),
            cells: CellGrid::new(w - 1, h - 1),
            count: 0,
            track: false,
            work: 0,
            ring: Ring::default(),
        };
        for n in cut.active_nodes(shape) {
            m.refresh(shape, cut, n, n.level, false);
        }
        m
    }

    /// Brings the mesh up to date after `node` has split or merged in `cut`. It must be called
    /// after each split or merge, before the next one: it takes the node's block to be covered
    /// by the node (merged) or by its children (split).
    pub fn update_around(&mut self, shape: &TreeShape, cut: &Cut, node: NodeId) {
        let inner = node.level + u8::from(cut.is_interior(shape, node));
        self.refresh(shape, cut, node, inner, true);
    }

    /// Starts (or stops) marking the cells that change, for [`FanMesh::take_dirty`].
    pub fn track_dirty(&mut self, on: bool) {
        if !on {
            self.cells.take_dirty(&mut Vec::new());
        }
        self.track = on;
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.count
    }

    /// All triangles, canonical and sorted (comparable with [`super::oracle`]).
    pub fn triangles(&self) -> Vec<Tri> {
        let mut v: Vec<Tri> = Vec::with_capacity(self.count);
        self.cells
            .for_each(|c, r, rec| v.extend(self.decode(c, r, rec).into_iter().flatten()));
        v.sort_unstable();
        v
    }

    /// The triangles of cell `(c, r)`.
    pub fn cell(&self, (c, r): (u32, u32)) -> [Option<Tri>; 2] {
        if c + 1 >= self.width || r + 1 >= self.height {
            return [None, None];
        }
        self.decode(c, r, self.cells.get(c, r))
    }

    /// Every non-empty junction cell, in no set order.
    pub fn cells(&self) -> Vec<(u32, u32)> {
        let mut v = Vec::new();
        self.cells.for_each(|c, r, _| v.push((c, r)));
        v
    }

    /// Replaces `out` with the cells whose triangles changed since the last call, each once, in
    /// no set order (none unless [`FanMesh::track_dirty`] is on).
    pub fn take_dirty(&mut self, out: &mut Vec<(u32, u32)>) {
        out.clear();
        self.cells.take_dirty(out);
    }

    /// Cells recomputed since creation.
    pub fn work(&self) -> u64 {
        self.work
    }

    /// Recomputes the junction cells centred on the closure of `node`'s block, whose samples
    /// all map to active nodes at level `inner` (the node, or its children). `settled` says
    /// that every record is up to date for the cut before the block changed.
    fn refresh(&mut self, shape: &TreeShape, cut: &Cut, node: NodeId, inner: u8, settled: bool) {
        // Borrowed field by field (the ring is read while the cells change), not moved out
        // and back: the ring is a few hundred bytes, copied twice per change.
        let FanMesh {
            ring,
            cells,
            count,
            work,
            track,
            depth,
            ..
        } = self;
        ring.walk(shape, cut, node, inner, settled.then_some(&*cells));
        ring.for_each_cell(shape, |c, r, levels| {
            // Cell (c, r) from its corners' active levels (NW, NE, SW, SE).
            *work += 1;
            let rec = record(*depth, c, r, levels);
            if let Some(old) = cells.set(c, r, rec, *track) {
                *count = *count + triangles(rec) - triangles(old);
            }
        });
    }

    /// The triangles of cell `(c, r)` with record `rec`.
    fn decode(&self, c: u32, r: u32, rec: u16) -> [Option<Tri>; 2] {
        if rec == 0 {
            return [None, None];
        }
        let l = |shift: u16| ((rec >> shift) & 15) as u8;
        let at = |cc: u32, rr: u32, shift: u16| corner_node(self.depth, cc, rr, l(shift));
        let (nw, ne, sw, se) = (
            at(c, r, 0),
            at(c + 1, r, 4),
            at(c, r + 1, 8),
            at(c + 1, r + 1, 12),
        );
        let [a, b] = cell_triangles(nw, ne, sw, se);
        [a.filter(|_| l(8) != 0), b.filter(|_| l(4) != 0)]
    }
}

/// The record of cell `(c, r)` whose corners' active nodes are at `levels` (NW, NE, SW, SE), in
/// a tree of depth `depth`.
///
/// Two corners have the same active node when their levels are equal and no block boundary of
/// that level runs between them. Between columns `c` and `c + 1` the boundaries are those of
/// the levels whose block size divides `c + 1`.
fn record(depth: u8, c: u32, r: u32, [lnw, lne, lsw, lse]: [u8; 4]) -> u16 {
    // A block boundary of level `l` runs between columns `c` and `c + 1` when the block size
    // `2^(depth - l)` divides `c + 1`: the levels from `depth - tz(c + 1)` down are cut there,
    // and two corners on either side share a node only at a level above that.
    let below = |v: u32| i32::from(depth) - v.trailing_zeros() as i32;
    let (kx, ky) = (below(c + 1), below(r + 1));
    // Non-short-circuit `&` and `|` throughout: the levels vary from cell to cell, so branches
    // on them mispredict; this way the record is straight-line code.
    let same = |la: u8, lb: u8, k: i32| (la == lb) & (i32::from(la) < k);
    let diagonal = same(lnw, lse, kx.min(ky));
    let a = !diagonal & !same(lnw, lsw, ky) & !same(lsw, lse, kx);
    let b = !diagonal & !same(lnw, lne, kx) & !same(lne, lse, ky);
    // A corner only a missing triangle uses is stored as 0, and an empty cell is 0.
    let used = |l: u8, used: bool| u16::from(l) * u16::from(used);
    (u16::from(lnw) | used(lne, b) << 4 | used(lsw, a) << 8 | u16::from(lse) << 12)
        * u16::from(a | b)
}

/// Triangles in a cell record: one per corner level it uses besides NW and SE.
fn triangles(rec: u16) -> usize {
    usize::from(rec & 0x0f00 != 0) + usize::from(rec & 0x00f0 != 0)
}

/// The ancestor at `level` of sample `(c, r)` in a tree of depth `depth`.
fn corner_node(depth: u8, c: u32, r: u32, level: u8) -> NodeId {
    let s = depth - level;
    NodeId {
        level,
        x: c >> s,
        y: r >> s,
    }
}
