//! The active nodes just outside a block, and the junction cells a change of the block can
//! touch, for [`super::FanMesh`].
//!
//! Every such cell is centred on the block's boundary (at the block's corners, its children's
//! corners and its neighbours' corners) or on its children's common corner, so each of its four
//! samples lies inside the block or in the one-sample ring around it. The ring is found by
//! walking each edge from neighbour to neighbour, one ancestor lookup per neighbour; the
//! column walks reach one sample past each end, so they cover the diagonal corners too.

use crate::cut::Cut;
use crate::tree::{NodeId, TreeShape};

/// The ring around one block: for each side, the active nodes along it in order, as (last
/// sample covered along the side, level).
#[derive(Clone, Debug, Default)]
pub(super) struct Ring {
    /// The block's first and last column and row, inclusive.
    block: (u32, u32, u32, u32),
    /// Level of the active nodes inside the block.
    inner: u8,
    /// Nominal half-size of the block: its children's boundaries lie this far from its origin.
    half: u32,
    /// Column `c0 - 1`, rows `r0 - 1 ..= r1 + 1` within the grid; empty on the west border.
    west: Vec<(u32, u8)>,
    /// Column `c1 + 1`, rows as `west`; empty on the east border.
    east: Vec<(u32, u8)>,
    /// Row `r0 - 1`, columns `c0 ..= c1`; empty on the north border.
    north: Vec<(u32, u8)>,
    /// Row `r1 + 1`, columns as `north`; empty on the south border.
    south: Vec<(u32, u8)>,
}

/// The level of the run of `side` that holds position `at`.
fn find(side: &[(u32, u8)], at: u32) -> u8 {
    side[side.partition_point(|&(last, _)| last < at)].1
}

/// The active ancestor of sample `(c, r)`, searched from level `hint` (an active neighbour's
/// level is usually within one of the block's): up while the parent is not interior, else down
/// while the node is interior.
fn active_near<V: Copy + Default>(
    shape: &TreeShape,
    cut: &Cut<V>,
    c: u32,
    r: u32,
    hint: u8,
) -> NodeId {
    let leaf = shape.leaf(c, r);
    let mut l = hint.min(shape.depth());
    if cut.is_interior(shape, leaf.ancestor_at(l)) {
        // Leaves are never interior, so this stops at the depth at the latest.
        l += 1;
        while cut.is_interior(shape, leaf.ancestor_at(l)) {
            l += 1;
        }
    } else {
        while l > 0 && !cut.is_interior(shape, leaf.ancestor_at(l - 1)) {
            l -= 1;
        }
    }
    leaf.ancestor_at(l)
}

impl Ring {
    /// Walks the ring of `node`'s block, whose samples map to active nodes at level `inner`.
    pub(super) fn walk<V: Copy + Default>(
        &mut self,
        shape: &TreeShape,
        cut: &Cut<V>,
        node: NodeId,
        inner: u8,
    ) {
        let (c0, r0, c1, r1) = shape.block(node);
        let (w, h) = (shape.width(), shape.height());
        self.block = (c0, r0, c1, r1);
        self.inner = inner;
        self.half = (1u32 << (shape.depth() - node.level)) >> 1;
        let walk = |out: &mut Vec<(u32, u8)>, fixed: u32, from: u32, to: u32, column: bool| {
            out.clear();
            let mut at = from;
            let mut hint = node.level;
            while at <= to {
                let (c, r) = if column { (fixed, at) } else { (at, fixed) };
                let n = active_near(shape, cut, c, r, hint);
                let (_, _, nc1, nr1) = shape.block(n);
                let last = if column { nr1 } else { nc1 };
                out.push((last, n.level));
                hint = n.level;
                at = last + 1;
            }
        };
        let (top, bottom) = (r0.max(1) - 1, (r1 + 1).min(h - 1));
        self.west.clear();
        if c0 > 0 {
            walk(&mut self.west, c0 - 1, top, bottom, true);
        }
        self.east.clear();
        if c1 + 1 < w {
            walk(&mut self.east, c1 + 1, top, bottom, true);
        }
        self.north.clear();
        if r0 > 0 {
            walk(&mut self.north, r0 - 1, c0, c1, false);
        }
        self.south.clear();
        if r1 + 1 < h {
            walk(&mut self.south, r1 + 1, c0, c1, false);
        }
    }

    /// The level of the active node of sample `(c, r)`, which must lie in the block or on the
    /// ring.
    fn level_at(&self, c: u32, r: u32) -> u8 {
        let (c0, r0, c1, r1) = self.block;
        if (c0..=c1).contains(&c) && (r0..=r1).contains(&r) {
            self.inner
        } else if c + 1 == c0 {
            find(&self.west, r)
        } else if c == c1 + 1 {
            find(&self.east, r)
        } else if r + 1 == r0 {
            find(&self.north, c)
        } else {
            debug_assert_eq!(r, r1 + 1);
            find(&self.south, c)
        }
    }

    /// Calls `f(c, r, levels)` once for each cell that the block's change can touch, with the
    /// levels of its NW, NE, SW and SE samples' active nodes.
    pub(super) fn for_each_cell(&self, shape: &TreeShape, mut f: impl FnMut(u32, u32, [u8; 4])) {
        let (c0, r0, c1, r1) = self.block;
        let (w, h) = (shape.width(), shape.height());
        // The cell centred on the corner between samples (x - 1, x) and (y - 1, y) is cell
        // (x - 1, y - 1); it exists when 1 <= x < w and 1 <= y < h.
        let mut centre = |x: u32, y: u32| {
            if x >= 1 && y >= 1 && x < w && y < h {
                let (c, r) = (x - 1, y - 1);
                let levels = [
                    self.level_at(c, r),
                    self.level_at(x, r),
                    self.level_at(c, y),
                    self.level_at(x, y),
                ];
                f(c, r, levels);
            }
        };
        let (cm, rm) = (c0 + self.half, r0 + self.half);
        // West and east edges, corners included.
        for (x, side) in [(c0, &self.west), (c1 + 1, &self.east)] {
            if !side.is_empty() {
                points(side, r0, r1, rm, true, |y| centre(x, y));
            }
        }
        // North and south edges, corners excluded.
        for (y, side) in [(r0, &self.north), (r1 + 1, &self.south)] {
            if !side.is_empty() {
                points(side, c0, c1, cm, false, |x| centre(x, y));
            }
        }
        // The children's common corner.
        if cm <= c1 && rm <= r1 {
            centre(cm, rm);
        }
    }
}

/// The corner positions along one edge of a block spanning `lo ..= hi`, in increasing order and
/// each once: the block's own corners `lo` and `hi + 1` if `ends`, the children's boundary `mid`,
/// and where each active node of `side` begins.
fn points(side: &[(u32, u8)], lo: u32, hi: u32, mid: u32, ends: bool, mut f: impl FnMut(u32)) {
    let mut mid_left = mid > lo && mid <= hi;
    if ends {
        f(lo);
    }
    for &(last, _) in side {
        let p = last + 1;
        if p <= lo {
            continue;
        }
        if p > hi {
            break;
        }
        if mid_left && mid <= p {
            if mid < p {
                f(mid);
            }
            mid_left = false;
        }
        f(p);
    }
    if mid_left {
        f(mid);
    }
    if ends {
        f(hi + 1);
    }
}
