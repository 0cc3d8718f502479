//! Node addressing of the vertex quadtree (paper 000, section 3.1) and the world frame.
//!
//! The leaves are the W x H samples of the DEM grid. A node at level `l`, position `(x, y)` covers
//! the block of samples `[x * 2^s, (x + 1) * 2^s) x [y * 2^s, (y + 1) * 2^s)` clipped to the grid,
//! with `s = depth - l`. Level 0 is the root (one node), level `depth` the samples themselves.
//! Sizes that are not powers of two need no padded data: a node on the east or south border simply
//! has one or two children instead of four. Every node's position is the centre of its *nominal*
//! block `[x * 2^s, (x + 1) * 2^s)`, which for full blocks is the mean of its children's positions
//! (the Haar low-pass). For a border node whose block is clipped, the nominal centre may lie up to
//! half a block beyond the grid's edge: its vertex is placed as if the grid had been padded to a
//! power of two. That keeps the reconstruction rule fold-free (paper 000's argument holds on the
//! padded grid, and Relief's mesh is a subset of that mesh), where the clipped block's own centre
//! folds thin border strips over their neighbours. The height is the mean of the real samples.
//!
//! **World frame.** Metres, x east, y north, z up. The origin is the south-west sample of the grid
//! (column 0, row H-1), so that every coordinate of the terrain is non-negative. Row 0 is north:
//! sample `(col, row)` lies at `x = col * dx`, `y = (H - 1 - row) * dy`.

/// The deepest tree the format allows: 32768 samples a side, so that every dense index fits in
/// 32 bits (the cut keys nodes by `u32`).
pub const MAX_DEPTH: u8 = 15;

/// A node of the vertex quadtree: its level (0 = root) and its position within that level.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct NodeId {
    /// Level in the tree; 0 is the root, `TreeShape::depth()` the full-resolution samples.
    pub level: u8,
    /// Column of the node within its level.
    pub x: u32,
    /// Row of the node within its level (0 = north).
    pub y: u32,
}

impl NodeId {
    /// The root node.
    pub const ROOT: NodeId = NodeId {
        level: 0,
        x: 0,
        y: 0,
    };

    /// The parent, or `None` for the root.
    pub fn parent(self) -> Option<NodeId> {
        (self.level > 0).then(|| NodeId {
            level: self.level - 1,
            x: self.x >> 1,
            y: self.y >> 1,
        })
    }

    /// The ancestor of this node at `level` (which must not be deeper than the node).
    pub fn ancestor_at(self, level: u8) -> NodeId {
        let s = self.level - level;
        NodeId {
            level,
            x: self.x >> s,
            y: self.y >> s,
        }
    }

    /// Child `k` (0 = NW, 1 = NE, 2 = SW, 3 = SE), whether or not it exists in a given shape.
    pub fn child(self, k: usize) -> NodeId {
        NodeId {
            level: self.level + 1,
            x: (self.x << 1) | (k as u32 & 1),
            y: (self.y << 1) | ((k as u32 >> 1) & 1),
        }
    }
}

/// The shape of a vertex quadtree over a W x H grid: which nodes exist, their dense indices and
/// their positions. Client and server derive it from the same two numbers, so it never travels.
#[derive(Clone, Debug, PartialEq)]
pub struct TreeShape {
    /// Grid width in samples (columns).
    width: u32,
    /// Grid height in samples (rows).
    height: u32,
    /// Level of the leaves: the smallest `n` with `2^n >= max(width, height)`.
    depth: u8,
    /// Nodes per row and per column at each level, so that existence checks are two compares.
    dims: Vec<(u32, u32)>,
    /// Dense index of the first node of each level, plus the total node count at the end.
    offsets: Vec<u64>,
}

/// A grid size the tree cannot represent.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ShapeError {
    /// Fewer than 2 samples in a direction: no triangle can be formed.
    #[error("grid of {0}x{1} samples is too small: at least 2x2 is needed")]
    TooSmall(u32, u32),
    /// More samples than the addressing supports.
    #[error("grid of {0}x{1} samples is too large: at most 32768 a side")]
    TooLarge(u32, u32),
}

impl TreeShape {
    /// The tree over a `width` x `height` grid.
    pub fn new(width: u32, height: u32) -> Result<TreeShape, ShapeError> {
        if width < 2 || height < 2 {
            return Err(ShapeError::TooSmall(width, height));
        }
        if width > 1 << MAX_DEPTH || height > 1 << MAX_DEPTH {
            return Err(ShapeError::TooLarge(width, height));
        }
        let side = width.max(height);
        let depth = (32 - (side - 1).leading_zeros()) as u8;
        let mut dims = Vec::with_capacity(depth as usize + 1);
        let mut offsets = Vec::with_capacity(depth as usize + 2);
        let mut total = 0u64;
        for l in 0..=depth {
            let s = depth - l;
            let d = (width.div_ceil(1 << s), height.div_ceil(1 << s));
            offsets.push(total);
            total += d.0 as u64 * d.1 as u64;
            dims.push(d);
        }
        offsets.push(total);
        Ok(TreeShape {
            width,
            height,
            depth,
            dims,
            offsets,
        })
    }

    /// Grid width in samples.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Grid height in samples.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Level of the leaves (the full-resolution samples).
    pub fn depth(&self) -> u8 {
        self.depth
    }

    /// Number of nodes at all levels together.
    pub fn node_count(&self) -> u64 {
        self.offsets[self.depth as usize + 1]
    }

    /// Nodes per row and per column at `level`.
    #[inline]
    pub fn level_dims(&self, level: u8) -> (u32, u32) {
        self.dims[level as usize]
    }

    /// Dense index of the first node of `level`.
    pub fn level_offset(&self, level: u8) -> u64 {
        self.offsets[level as usize]
    }

    /// The dense indices of an inner node's four nominal children (in child order) and which
    /// of them exist (bit `k` for child `k`; child 0 always does), computed for all four
    /// without a branch per child.
    #[inline]
    pub fn children_indices(&self, node: NodeId) -> ([u64; 4], u8) {
        debug_assert!(node.level < self.depth);
        let level = node.level as usize + 1;
        let (w, h) = self.dims[level];
        let (x, y) = (2 * node.x, 2 * node.y);
        let (east, south) = (x + 1 < w, y + 1 < h);
        let exists = 1 | u8::from(east) << 1 | u8::from(south) << 2 | u8::from(east & south) << 3;
        let north = self.offsets[level] + y as u64 * w as u64 + x as u64;
        let south_row = north + w as u64;
        ([north, north + 1, south_row, south_row + 1], exists)
    }

    /// Whether `node` exists in this tree.
    pub fn contains(&self, node: NodeId) -> bool {
        node.level <= self.depth && {
            let (w, h) = self.dims[node.level as usize];
            node.x < w && node.y < h
        }
    }

    /// Whether `node` is a full-resolution sample.
    pub fn is_leaf(&self, node: NodeId) -> bool {
        node.level == self.depth
    }

    /// Dense index of an existing node: levels in order, rows in order within a level.
    /// Parents always have smaller indices than their children.
    #[inline]
    pub fn index(&self, node: NodeId) -> u64 {
        let (w, _) = self.dims[node.level as usize];
        self.offsets[node.level as usize] + node.y as u64 * w as u64 + node.x as u64
    }

    /// The node with dense index `index`, or `None` if the index is out of range.
    pub fn node(&self, index: u64) -> Option<NodeId> {
        if index >= self.node_count() {
            return None;
        }
        let level = self.offsets.partition_point(|&o| o <= index) - 1;
        let (w, _) = self.dims[level];
        let local = index - self.offsets[level];
        Some(NodeId {
            level: level as u8,
            x: (local % w as u64) as u32,
            y: (local / w as u64) as u32,
        })
    }

    /// The children of `node` that exist (1, 2 or 4 of them), as `(k, child)` with `k` as in
    /// [`NodeId::child`]. Leaves have none.
    pub fn children(&self, node: NodeId) -> impl Iterator<Item = (usize, NodeId)> + '_ {
        let inner = node.level < self.depth;
        (0..4)
            .map(move |k| (k, node.child(k)))
            .filter(move |&(_, c)| inner && self.contains(c))
    }

    /// The sample block a node covers: `(col0, row0, col1, row1)`, inclusive.
    pub fn block(&self, node: NodeId) -> (u32, u32, u32, u32) {
        let s = self.depth - node.level;
        let c0 = node.x << s;
        let r0 = node.y << s;
        let c1 = (((node.x + 1) << s) - 1).min(self.width - 1);
        let r1 = (((node.y + 1) << s) - 1).min(self.height - 1);
        (c0, r0, c1, r1)
    }

    /// The leaf-level node of sample `(col, row)`.
    pub fn leaf(&self, col: u32, row: u32) -> NodeId {
        NodeId {
            level: self.depth,
            x: col,
            y: row,
        }
    }

    /// Position of a node in grid units: (column, row) as reals, the centre of its nominal block.
    pub fn grid_pos(&self, node: NodeId) -> (f32, f32) {
        let s = self.depth - node.level;
        let half = ((1u64 << s) - 1) as f32 / 2.0;
        (
            ((node.x as u64) << s) as f32 + half,
            ((node.y as u64) << s) as f32 + half,
        )
    }
}

/// The mapping from grid coordinates to world metres (see the module docs for the frame).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorldFrame {
    /// Ground distance between columns, metres.
    pub dx: f32,
    /// Ground distance between rows, metres.
    pub dy: f32,
    /// Grid height in samples, to flip rows (north first) into y (north up).
    pub rows: u32,
}

impl WorldFrame {
    /// World x, y of a grid position (column, row).
    #[inline]
    pub fn to_world(&self, col: f32, row: f32) -> (f32, f32) {
        (col * self.dx, (self.rows as f32 - 1.0 - row) * self.dy)
    }

    /// Grid position (column, row) of world x, y.
    pub fn to_grid(&self, x: f32, y: f32) -> (f32, f32) {
        (x / self.dx, self.rows as f32 - 1.0 - y / self.dy)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn power_of_two_shape() {
        let t = TreeShape::new(4, 4).unwrap();
        assert_eq!(t.depth(), 2);
        assert_eq!(t.node_count(), 1 + 4 + 16);
        assert_eq!(t.grid_pos(NodeId::ROOT), (1.5, 1.5));
    }

    #[test]
    fn children_indices_are_the_existing_children() {
        for (w, h) in [(5, 3), (4, 4), (17, 9), (2, 33), (65, 40)] {
            let t = TreeShape::new(w, h).unwrap();
            for level in 0..t.depth() {
                let (lw, lh) = t.level_dims(level);
                for (x, y) in (0..lh).flat_map(|y| (0..lw).map(move |x| (x, y))) {
                    let node = NodeId { level, x, y };
                    let (indices, exists) = t.children_indices(node);
                    let mut mask = 0;
                    for (k, c) in t.children(node) {
                        mask |= 1 << k;
                        assert_eq!(indices[k], t.index(c), "{node:?} child {k}");
                    }
                    assert_eq!(exists, mask, "{node:?}");
                }
            }
        }
    }

    #[test]
    fn odd_shape_has_partial_nodes() {
        let t = TreeShape::new(5, 3).unwrap();
        assert_eq!(t.depth(), 3);
        assert_eq!(t.level_dims(2), (3, 2));
        assert_eq!(t.level_dims(0), (1, 1));
        let border = NodeId {
            level: 2,
            x: 2,
            y: 1,
        };
        assert_eq!(t.children(border).count(), 1);
        assert_eq!(t.block(border), (4, 2, 4, 2));
        // Column 4 stands alone at level 2, but its vertex sits at its nominal block's centre.
        assert_eq!(t.grid_pos(border), (4.5, 2.5));
    }

    #[test]
    fn index_round_trips() {
        let t = TreeShape::new(13, 7).unwrap();
        let mut expect = 0;
        for l in 0..=t.depth() {
            let (w, h) = t.level_dims(l);
            for y in 0..h {
                for x in 0..w {
                    let n = NodeId { level: l, x, y };
                    assert_eq!(t.index(n), expect);
                    assert_eq!(t.node(expect), Some(n));
                    expect += 1;
                }
            }
        }
        assert_eq!(t.node(expect), None);
    }

    #[test]
    fn rejects_bad_sizes() {
        assert_eq!(TreeShape::new(1, 5), Err(ShapeError::TooSmall(1, 5)));
        assert!(TreeShape::new(2, 2).is_ok());
        assert!(matches!(
            TreeShape::new(1 << 21, 4),
            Err(ShapeError::TooLarge(..))
        ));
    }
}
