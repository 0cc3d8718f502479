//! The active nodes just outside a block, and the junction cells a change of the block can
//! touch, for [`super::FanMesh`].
//!
//! Every such cell is centred on the block's boundary (at the block's corners, its children's
//! corners and its neighbours' corners) or on its children's common corner, so each of its four
//! samples lies inside the block or in the one-sample ring around it. The ring is found by
//! walking each edge from neighbour to neighbour, one ancestor lookup per neighbour; the
//! column walks reach one sample past each end, so they cover the diagonal corners too.

use super::grid::CellGrid;
use crate::cut::Cut;
use crate::tree::{NodeId, TreeShape};

/// The ring around one block: for each side, the active nodes along it in order, and the
/// levels of the four diagonal neighbours.
#[derive(Clone, Debug, Default)]
pub(super) struct Ring {
    /// The block's first and last column and row, inclusive.
    block: (u32, u32, u32, u32),
    /// Level of the active nodes inside the block.
    inner: u8,
    /// Nominal half-size of the block: its children's boundaries lie this far from its origin.
    half: u32,
    /// Column `c0 - 1`, rows `r0 ..= r1`; empty on the west border.
    west: Side,
    /// Column `c1 + 1`, rows as `west`; empty on the east border.
    east: Side,
    /// Row `r0 - 1`, columns `c0 ..= c1`; empty on the north border.
    north: Side,
    /// Row `r1 + 1`, columns as `north`; empty on the south border.
    south: Side,
    /// Levels of the active nodes of the samples diagonally off the block's NW, NE, SW and SE
    /// corners, where they exist.
    diagonal: [u8; 4],
}

/// The active nodes along one side of a block.
#[derive(Clone, Debug, Default)]
struct Side {
    /// Where the first node's block begins along the side (possibly before the block's).
    start: u32,
    /// The nodes in order, as (last sample of its block along the side, level).
    runs: Vec<(u32, u8)>,
}

impl Side {
    /// Whether the side exists (the block is not on that border of the grid).
    fn is_empty(&self) -> bool {
        self.runs.is_empty()
    }

    /// The first node's level, if its block reaches `at` or before.
    fn first_reaching(&self, at: u32) -> Option<u8> {
        let &(_, level) = self.runs.first()?;
        (self.start <= at).then_some(level)
    }

    /// The last node's level, if its block reaches `at` or beyond.
    fn last_reaching(&self, at: u32) -> Option<u8> {
        let &(last, level) = self.runs.last()?;
        (last >= at).then_some(level)
    }
}

/// The active ancestor of sample `(c, r)`, searched from level `hint` (an active neighbour's
/// level is usually within one of the block's): up while the parent is not interior, else down
/// while the node is interior. Levels below `floor` are known to be interior.
fn active_near(shape: &TreeShape, cut: &Cut, (c, r): (u32, u32), hint: u8, floor: u8) -> NodeId {
    let leaf = shape.leaf(c, r);
    let mut l = hint.max(floor).min(shape.depth());
    if cut.is_interior(shape, leaf.ancestor_at(l)) {
        // Leaves are never interior, so this stops at the depth at the latest.
        l += 1;
        while cut.is_interior(shape, leaf.ancestor_at(l)) {
            l += 1;
        }
    } else {
        while l > floor && !cut.is_interior(shape, leaf.ancestor_at(l - 1)) {
            l -= 1;
        }
    }
    leaf.ancestor_at(l)
}

impl Ring {
    /// Walks the ring of `node`'s block, whose samples map to active nodes at level `inner`.
    /// With the mesh's `records` up to date for the cut before the block changed, a diagonal
    /// neighbour that no side's node reaches is read from the corner cell, which it shares with
    /// two other nodes (so it is used by a triangle there and its level is stored) instead of
    /// searched.
    pub(super) fn walk(
        &mut self,
        shape: &TreeShape,
        cut: &Cut,
        node: NodeId,
        inner: u8,
        records: Option<&CellGrid>,
    ) {
        let (c0, r0, c1, r1) = shape.block(node);
        let (w, h) = (shape.width(), shape.height());
        self.block = (c0, r0, c1, r1);
        self.inner = inner;
        self.half = (1u32 << (shape.depth() - node.level)) >> 1;
        let find = |(c, r): (u32, u32), hint: u8| {
            // The node's ancestors are interior (it is active or has just split), and so are
            // the sample's ancestors it shares: those above the highest bit in which the
            // sample's column or row differs from the block's origin.
            let differ = (c ^ c0) | (r ^ r0);
            let floor = shape.depth() - (31 - differ.leading_zeros()) as u8;
            active_near(shape, cut, (c, r), hint, floor)
        };
        let walk = |out: &mut Side, fixed: u32, from: u32, to: u32, column: bool| {
            out.runs.clear();
            let mut at = from;
            let mut hint = node.level;
            while at <= to {
                let n = find(if column { (fixed, at) } else { (at, fixed) }, hint);
                let (nc0, nr0, nc1, nr1) = shape.block(n);
                if at == from {
                    out.start = if column { nr0 } else { nc0 };
                }
                let last = if column { nr1 } else { nc1 };
                out.runs.push((last, n.level));
                hint = n.level;
                at = last + 1;
            }
        };
        let (west, east, north, south) = (c0 > 0, c1 + 1 < w, r0 > 0, r1 + 1 < h);
        self.west.runs.clear();
        if west {
            walk(&mut self.west, c0 - 1, r0, r1, true);
        }
        self.east.runs.clear();
        if east {
            walk(&mut self.east, c1 + 1, r0, r1, true);
        }
        self.north.runs.clear();
        if north {
            walk(&mut self.north, r0 - 1, c0, c1, false);
        }
        self.south.runs.clear();
        if south {
            walk(&mut self.south, r1 + 1, c0, c1, false);
        }
        // Each diagonal sample, the corner cell that holds it and its corner's shift there
        // (wrapping where the sample lies off the grid: then it is skipped).
        let (w0, n0) = (c0.wrapping_sub(1), r0.wrapping_sub(1));
        let corners = [
            (west && north, (w0, n0), (w0, n0), 0),
            (east && north, (c1 + 1, n0), (c1, n0), 4),
            (west && south, (w0, r1 + 1), (w0, r1), 8),
            (east && south, (c1 + 1, r1 + 1), (c1, r1), 12),
        ];
        // Each diagonal's level where a side's node reaches it (read for all four at once, not
        // by a match per corner: its jump mispredicted; a missing side reaches nothing, and an
        // off-grid sample is skipped below).
        let alongs = [
            (self.west.first_reaching(n0)).or(self.north.first_reaching(w0)),
            (self.east.first_reaching(n0)).or(self.north.last_reaching(c1 + 1)),
            (self.west.last_reaching(r1 + 1)).or(self.south.first_reaching(w0)),
            (self.east.last_reaching(r1 + 1)).or(self.south.last_reaching(c1 + 1)),
        ];
        for (k, (exists, sample, cell, shift)) in corners.into_iter().enumerate() {
            if !exists {
                continue;
            }
            self.diagonal[k] = alongs[k].unwrap_or_else(|| match records {
                Some(g) => {
                    let level = (g.get(cell.0, cell.1) >> shift & 15) as u8;
                    debug_assert!(level > 0, "corner cell {cell:?} does not hold {sample:?}");
                    level
                }
                None => find(sample, node.level).level,
            });
        }
    }

    /// Calls `f(c, r, levels)` once for each cell that the block's change can touch, with the
    /// levels of its NW, NE, SW and SE samples' active nodes.
    pub(super) fn for_each_cell(&self, shape: &TreeShape, mut f: impl FnMut(u32, u32, [u8; 4])) {
        let (c0, r0, c1, r1) = self.block;
        let (w, h) = (shape.width(), shape.height());
        let inner = self.inner;
        // The cell centred on the corner between samples (x - 1, x) and (y - 1, y) is cell
        // (x - 1, y - 1); it exists when 1 <= x < w and 1 <= y < h. Its samples off the block
        // lie on the ring; the ends of an edge reach the ring's neighbouring sides (which exist
        // where the cell does).
        let exists = |x: u32, y: u32| x >= 1 && y >= 1 && x < w && y < h;
        let (cm, rm) = (c0 + self.half, r0 + self.half);
        if !self.west.is_empty() {
            let mut west = Cursor::new(&self.west.runs);
            points(&self.west.runs, r0, r1, rm, true, |y| {
                if exists(c0, y) {
                    let nw = if y == r0 {
                        self.diagonal[0]
                    } else {
                        west.at(y - 1)
                    };
                    let sw = if y > r1 { self.diagonal[2] } else { west.at(y) };
                    let ne = if y == r0 { self.north.runs[0].1 } else { inner };
                    let se = if y > r1 { self.south.runs[0].1 } else { inner };
                    f(c0 - 1, y - 1, [nw, ne, sw, se]);
                }
            });
        }
        if !self.east.is_empty() {
            let mut east = Cursor::new(&self.east.runs);
            let x = c1 + 1;
            points(&self.east.runs, r0, r1, rm, true, |y| {
                if exists(x, y) {
                    let ne = if y == r0 {
                        self.diagonal[1]
                    } else {
                        east.at(y - 1)
                    };
                    let se = if y > r1 { self.diagonal[3] } else { east.at(y) };
                    let nw = if y == r0 {
                        last(&self.north.runs)
                    } else {
                        inner
                    };
                    let sw = if y > r1 {
                        last(&self.south.runs)
                    } else {
                        inner
                    };
                    f(c1, y - 1, [nw, ne, sw, se]);
                }
            });
        }
        if !self.north.is_empty() {
            let mut north = Cursor::new(&self.north.runs);
            points(&self.north.runs, c0, c1, cm, false, |x| {
                if exists(x, r0) {
                    let (nw, ne) = (north.at(x - 1), north.at(x));
                    f(x - 1, r0 - 1, [nw, ne, inner, inner]);
                }
            });
        }
        if !self.south.is_empty() {
            let mut south = Cursor::new(&self.south.runs);
            let y = r1 + 1;
            points(&self.south.runs, c0, c1, cm, false, |x| {
                if exists(x, y) {
                    let (sw, se) = (south.at(x - 1), south.at(x));
                    f(x - 1, r1, [inner, inner, sw, se]);
                }
            });
        }
        // The children's common corner (a leaf has no children: half 0).
        if self.half > 0 && cm <= c1 && rm <= r1 {
            f(cm - 1, rm - 1, [inner; 4]);
        }
    }
}

/// The level of the last run of a side.
fn last(side: &[(u32, u8)]) -> u8 {
    side[side.len() - 1].1
}

/// Reads the runs of one side at increasing positions.
struct Cursor<'a> {
    /// The runs, as (last position, level).
    side: &'a [(u32, u8)],
    /// The run that held the last position asked for.
    at: usize,
}

impl<'a> Cursor<'a> {
    fn new(side: &'a [(u32, u8)]) -> Cursor<'a> {
        Cursor { side, at: 0 }
    }

    /// The level of the run holding `pos`, which is no smaller than the last one asked for.
    fn at(&mut self, pos: u32) -> u8 {
        while self.side[self.at].0 < pos {
            self.at += 1;
        }
        self.side[self.at].1
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
