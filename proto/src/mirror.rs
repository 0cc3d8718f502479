//! The client's mirror of a session's cut: applies deltas, rebuilds node heights from the Haar
//! details, and checks each delta's digest so that a desync is detected, never silent.
//!
//! It is pure and lives in `proto` so that the server's benchmarks replay deltas exactly as a
//! client does.

use crate::cut::{Cut, CutError};
use crate::delta::{Delta, Parents, quad_details};
use crate::haar::inverse;
use crate::paged::Paged;
use crate::terrain::TerrainGeometry;
use crate::tree::{NodeId, TreeShape};

/// What the mirror knows of a node it holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NodeData {
    /// Height in z quanta.
    pub z: i32,
    /// Static-error code; known once the node has split (0 until then).
    pub err_code: u8,
}

/// One split or merge the mirror applied, reported in the order it was applied.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Change {
    /// The node split: its children are now held.
    Split(NodeId),
    /// The node merged: its children are gone.
    Merge(NodeId),
}

impl Change {
    /// The node that split or merged.
    pub fn node(self) -> NodeId {
        match self {
            Change::Split(n) | Change::Merge(n) => n,
        }
    }
}

/// A delta the mirror could not apply.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum MirrorError {
    /// A merge or split is not allowed by the current cut.
    #[error(transparent)]
    Cut(#[from] CutError),
    /// The cut after the delta differs from the server's.
    #[error("desync after delta {seq}: digest {ours:#018x}, server says {theirs:#018x}")]
    Desync {
        /// The delta's sequence number.
        seq: u64,
        /// Our digest.
        ours: u64,
        /// The delta's.
        theirs: u64,
    },
}

/// The client-side cut with node heights.
#[derive(Clone, Debug)]
pub struct Mirror {
    /// The active and interior nodes.
    cut: Cut,
    /// The tree's shape, to list the held nodes by dense index.
    shape: TreeShape,
    /// Height and error code of the root, which is always held.
    root: NodeData,
    /// Heights and error codes of the children of every interior node, by the node's level
    /// and position. Children are held exactly while their parent is interior, so a split
    /// inserts one record and a merge removes one, whatever the number of children; and
    /// nodes that split or merge one after another (a delta lists them in Morton order) are
    /// neighbours in their level's grid, so they share its pages.
    children: Vec<Paged<Children>>,
}

/// What the mirror knows of the children of one interior node, by child index (0 = NW, 1 = NE,
/// 2 = SW, 3 = SE; a child the shape does not have is never read).
#[derive(Clone, Copy, Debug, Default)]
struct Children {
    /// Heights in z quanta.
    z: [i32; 4],
    /// Static-error codes, 0 until the child has split.
    err_code: [u8; 4],
}

/// Which child of its parent `node` is (0 = NW, 1 = NE, 2 = SW, 3 = SE).
fn child_index(node: NodeId) -> usize {
    ((node.x & 1) | (node.y & 1) << 1) as usize
}

impl Mirror {
    /// A mirror holding the root alone, whose height is `root_z` quanta.
    pub fn new(geom: &TerrainGeometry, root_z: i32) -> Mirror {
        Mirror {
            cut: Cut::root(&geom.shape),
            shape: geom.shape.clone(),
            root: NodeData {
                z: root_z,
                err_code: 0,
            },
            children: (0..geom.shape.depth())
                .map(|l| {
                    let (w, h) = geom.shape.level_dims(l);
                    Paged::new(w, h)
                })
                .collect(),
        }
    }

    /// The mirrored cut.
    pub fn cut(&self) -> &Cut {
        &self.cut
    }

    /// Height and error code of a node the mirror holds.
    pub fn node(&self, geom: &TerrainGeometry, node: NodeId) -> Option<NodeData> {
        let Some(parent) = node.parent() else {
            return Some(self.root);
        };
        if !geom.shape.contains(node) {
            return None;
        }
        let c = self.children[parent.level as usize].get(parent.x, parent.y)?;
        let k = child_index(node);
        Some(NodeData {
            z: c.z[k],
            err_code: c.err_code[k],
        })
    }

    /// Every node the mirror holds (active and interior), by dense index, in no set order.
    pub fn held(&self) -> impl Iterator<Item = (u64, NodeData)> + '_ {
        let shape = &self.shape;
        let root = (shape.index(NodeId::ROOT), self.root);
        let mut held = vec![root];
        for (level, grid) in self.children.iter().enumerate() {
            grid.for_each(|x, y, c| {
                let level = level as u8;
                for (k, n) in shape.children(NodeId { level, x, y }) {
                    let d = NodeData {
                        z: c.z[k],
                        err_code: c.err_code[k],
                    };
                    held.push((shape.index(n), d));
                }
            });
        }
        held.into_iter()
    }

    /// Applies `delta` and checks its digest: first the merges deepest first (in reverse of their
    /// canonical order, so that when a node and its child both merge the child goes first and
    /// every merging node's children are active), then the splits in order (parents first).
    /// `on_change` is called after each merge or split with the change, for incremental mesh
    /// and GPU-buffer updates. On error the mirror may hold part of the delta: the caller must resynchronise.
    pub fn apply(
        &mut self,
        geom: &TerrainGeometry,
        delta: &Delta,
        mut on_change: impl FnMut(&Cut, Change),
    ) -> Result<(), MirrorError> {
        let shape = &geom.shape;
        for &m in delta.merges.iter().rev() {
            self.cut.merge(shape, m)?;
            self.children[m.level as usize].remove(m.x, m.y);
            on_change(&self.cut, Change::Merge(m));
        }
        for s in &delta.splits {
            self.cut.split(shape, s.node)?;
            // The node was active, so it is held: the root, or a child of an interior node.
            let z = match s.node.parent() {
                None => {
                    self.root.err_code = s.err_code;
                    self.root.z
                }
                Some(p) => {
                    let c = self.children[p.level as usize]
                        .get_mut(p.x, p.y)
                        .ok_or(CutError::NotSplittable(s.node))?;
                    let k = child_index(s.node);
                    c.err_code[k] = s.err_code;
                    c.z[k]
                }
            };
            let c = Children {
                z: inverse(z, s.details),
                err_code: [0; 4],
            };
            self.children[s.node.level as usize].insert(s.node.x, s.node.y, c);
            on_change(&self.cut, Change::Split(s.node));
        }
        if self.cut.digest() != delta.digest {
            return Err(MirrorError::Desync {
                seq: delta.seq,
                ours: self.cut.digest(),
                theirs: delta.digest,
            });
        }
        Ok(())
    }
}

/// A body's splits are predicted from the mirror's parents (docs/protocol.md section 5.4): an
/// interior node's details come back from its children's heights.
impl Parents for Mirror {
    fn details(&self, node: NodeId) -> Option<[i32; 3]> {
        if !self.shape.contains(node) {
            return None;
        }
        let c = self
            .children
            .get(node.level as usize)?
            .get(node.x, node.y)?;
        Some(quad_details(&self.shape, node, c.z))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::delta::Split;

    fn split(node: NodeId, err_code: u8, details: [i32; 3]) -> Split {
        Split {
            node,
            err_code,
            details,
        }
    }

    #[test]
    fn holds_the_children_of_interior_nodes_with_their_heights() {
        // 5 x 3: the root's east and south children are clipped, so some nodes have fewer
        // than four children.
        let geom = TerrainGeometry::new(5, 3, 1.0, 1.0, 1.0).unwrap();
        let shape = &geom.shape;
        let mut m = Mirror::new(&geom, 100);
        let (root, nw, ne) = (NodeId::ROOT, NodeId::ROOT.child(0), NodeId::ROOT.child(1));
        let mut shadow = Cut::root(shape);
        shadow.split(shape, root).unwrap();
        shadow.split(shape, ne).unwrap();
        let delta = Delta {
            seq: 1,
            digest: shadow.digest(),
            merges: vec![],
            splits: vec![split(root, 7, [4, -2, 1]), split(ne, 3, [0, 6, 0])],
        };
        let mut seen = Vec::new();
        m.apply(&geom, &delta, |_, c| seen.push(c)).unwrap();
        assert_eq!(seen, vec![Change::Split(root), Change::Split(ne)]);
        let quad = inverse(100, [4, -2, 1]);
        assert_eq!(m.node(&geom, root).unwrap().err_code, 7);
        assert_eq!(
            m.node(&geom, nw).unwrap(),
            NodeData {
                z: quad[0],
                err_code: 0
            }
        );
        assert_eq!(
            m.node(&geom, ne).unwrap(),
            NodeData {
                z: quad[1],
                err_code: 3
            }
        );
        let ne_kids = inverse(quad[1], [0, 6, 0]);
        assert_eq!(m.node(&geom, ne.child(0)).unwrap().z, ne_kids[0]);
        assert_eq!(m.node(&geom, nw.child(0)), None, "not held");
        // Held: the root, its children that exist, and ne's children that exist.
        let mut held: Vec<u64> = m.held().map(|(i, _)| i).collect();
        held.sort_unstable();
        let mut want: Vec<u64> = std::iter::once(root)
            .chain(shape.children(root).map(|(_, c)| c))
            .chain(shape.children(ne).map(|(_, c)| c))
            .map(|n| shape.index(n))
            .collect();
        want.sort_unstable();
        assert_eq!(held, want);
        for (i, d) in m.held() {
            assert_eq!(m.node(&geom, shape.node(i).unwrap()), Some(d));
        }
        // Merging drops the children; the merged node keeps its height and error code.
        shadow.merge(shape, ne).unwrap();
        let delta = Delta {
            seq: 2,
            digest: shadow.digest(),
            merges: vec![ne],
            splits: vec![],
        };
        m.apply(&geom, &delta, |_, _| {}).unwrap();
        assert_eq!(m.node(&geom, ne.child(0)), None);
        assert_eq!(
            m.node(&geom, ne).unwrap(),
            NodeData {
                z: quad[1],
                err_code: 3
            }
        );
        assert_eq!(m.held().count(), 1 + shape.children(root).count());
        // A wrong digest is a desync.
        let bad = Delta {
            seq: 3,
            digest: 0,
            merges: vec![],
            splits: vec![],
        };
        assert!(matches!(
            m.apply(&geom, &bad, |_, _| {}),
            Err(MirrorError::Desync { seq: 3, .. })
        ));
    }
}
