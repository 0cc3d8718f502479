//! Terrain geometry: a tree shape plus the metres that turn grid units and z quanta into world
//! coordinates, and the bounding box both ends use for a node's screen error.

use crate::haar::error_value;
use crate::tree::{NodeId, ShapeError, TreeShape, WorldFrame};
use crate::view::{Aabb, QuadBoxes};
use glam::Vec3;

/// Everything needed to place a node in the world: shared by server and client.
#[derive(Clone, Debug, PartialEq)]
pub struct TerrainGeometry {
    /// Which nodes exist and where they sit in the grid.
    pub shape: TreeShape,
    /// Grid-to-world mapping.
    pub frame: WorldFrame,
    /// Metres per integer height unit: heights travel and are stored in these quanta.
    pub z_quantum: f32,
}

impl TerrainGeometry {
    /// Geometry of a `width` x `height` grid with spacing `dx`, `dy` metres and z quantum `q`.
    pub fn new(
        width: u32,
        height: u32,
        dx: f32,
        dy: f32,
        z_quantum: f32,
    ) -> Result<TerrainGeometry, ShapeError> {
        Ok(TerrainGeometry {
            shape: TreeShape::new(width, height)?,
            frame: WorldFrame {
                dx,
                dy,
                rows: height,
            },
            z_quantum,
        })
    }

    /// World position of `node` whose height is `zq` quanta.
    pub fn world_pos(&self, node: NodeId, zq: i32) -> Vec3 {
        let (c, r) = self.shape.grid_pos(node);
        let (x, y) = self.frame.to_world(c, r);
        Vec3::new(x, y, zq as f32 * self.z_quantum)
    }

    /// The box used for `node`'s screen error: its nominal block in x and y (which holds its
    /// samples and every vertex of its subtree, see [`crate::tree`]), and its height plus or minus
    /// its static error in z. The static error bounds how far any sample of the subtree
    /// lies from the node's height, so the box holds the whole subtree; and because it is built
    /// only from what a split carries, the client computes exactly the server's box.
    #[inline]
    pub fn node_box(&self, node: NodeId, zq: i32, err_code: u8) -> Aabb {
        self.node_box_with(node, zq, error_value(err_code))
    }

    /// [`TerrainGeometry::node_box`] for a node whose static error is `e` metres (the value of
    /// its error code), for callers that keep their own table of code values.
    #[inline]
    pub fn node_box_with(&self, node: NodeId, zq: i32, e: f32) -> Aabb {
        let s = self.shape.depth() - node.level;
        let ([x0, x1], [y0, y1]) = self.block_ranges(span(node.x, s), span(node.y, s));
        let z = zq as f32 * self.z_quantum;
        Aabb {
            min: Vec3::new(x0, y0, z - e),
            max: Vec3::new(x1, y1, z + e),
        }
    }

    /// [`TerrainGeometry::node_box_with`] of the four children of `node` (an inner node) at
    /// once, child `k` with height `zq[k]` quanta and static error `e[k]` metres: the same
    /// numbers, each column's x range and each row's y range computed once.
    #[inline]
    pub fn children_boxes_with(&self, node: NodeId, zq: [i32; 4], e: [f32; 4]) -> QuadBoxes {
        let s = self.shape.depth() - node.level - 1;
        let (xw, yn) = self.block_ranges(span(2 * node.x, s), span(2 * node.y, s));
        let (xe, ys) = self.block_ranges(span(2 * node.x + 1, s), span(2 * node.y + 1, s));
        let z = |k: usize| {
            let z = zq[k] as f32 * self.z_quantum;
            [z - e[k], z + e[k]]
        };
        QuadBoxes {
            x: [xw, xe],
            y: [yn, ys],
            z: [z(0), z(1), z(2), z(3)],
        }
    }

    /// The world x and y ranges `[min, max]` of the block spanning columns `c0 ..= c1` and rows
    /// `r0 ..= r1` (row 0 is the north, so the first row gives the largest y).
    #[inline]
    fn block_ranges(&self, (c0, c1): (u32, u32), (r0, r1): (u32, u32)) -> ([f32; 2], [f32; 2]) {
        let (x0, y1) = self.frame.to_world(c0 as f32, r0 as f32);
        let (x1, y0) = self.frame.to_world(c1 as f32, r1 as f32);
        ([x0, x1], [y0, y1])
    }
}

/// The first and last sample of the nominal block of position `v` on a lattice whose blocks
/// are `2^s` samples wide. In u32: the nominal lattice is at most `2^MAX_DEPTH` a side.
#[inline]
fn span(v: u32, s: u8) -> (u32, u32) {
    let lo = v << s;
    (lo, lo + (1u32 << s) - 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_spans_block_and_error() {
        let g = TerrainGeometry::new(5, 3, 10.0, 20.0, 0.5).unwrap();
        let b = g.node_box(NodeId::ROOT, 100, crate::haar::error_code(3.0));
        // The nominal block of the root of a 5x3 grid is 8x8 samples.
        assert_eq!((b.min.x, b.max.x), (0.0, 70.0));
        assert_eq!((b.min.y, b.max.y), (-100.0, 40.0));
        assert!(b.min.z <= 47.0 && b.max.z >= 53.0);
        let p = g.world_pos(NodeId::ROOT, 100);
        assert_eq!(p.z, 50.0);
    }

    #[test]
    fn children_boxes_are_each_childs_box() {
        // Uneven spacing and a grid that is not a power of two plus one, so that border
        // children and every level are covered.
        let g = TerrainGeometry::new(37, 21, 30.5, 29.25, 0.1).unwrap();
        let shape = &g.shape;
        for level in 0..shape.depth() {
            let (w, h) = shape.level_dims(level);
            for (x, y) in (0..h).flat_map(|y| (0..w).map(move |x| (x, y))) {
                let node = NodeId { level, x, y };
                let zq = [10, -3, 250, 7];
                let e = [0.5, 1.25, 0.0, 3.5];
                let q = g.children_boxes_with(node, zq, e);
                for k in 0..4 {
                    let one = g.node_box_with(node.child(k), zq[k], e[k]);
                    assert_eq!(q.aabb(k), one, "{node:?} child {k}");
                }
            }
        }
    }
}
