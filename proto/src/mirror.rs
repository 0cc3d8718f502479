//! The client's mirror of a session's cut: applies deltas, rebuilds node heights from the Haar
//! details, and checks each delta's digest so that a desync is detected, never silent.
//!
//! It is pure and lives in `proto` so that the server's benchmarks replay deltas exactly as a
//! client does.

use crate::cut::{Cut, CutError};
use crate::delta::Delta;
use crate::haar::inverse;
use crate::terrain::TerrainGeometry;
use crate::tree::NodeId;
use rustc_hash::FxHashMap;

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
    /// Heights and error codes of the nodes the cut holds (active and interior), by dense index.
    nodes: FxHashMap<u64, NodeData>,
}

impl Mirror {
    /// A mirror holding the root alone, whose height is `root_z` quanta.
    pub fn new(geom: &TerrainGeometry, root_z: i32) -> Mirror {
        let mut nodes = FxHashMap::default();
        nodes.insert(
            geom.shape.index(NodeId::ROOT),
            NodeData {
                z: root_z,
                err_code: 0,
            },
        );
        Mirror {
            cut: Cut::root(&geom.shape),
            nodes,
        }
    }

    /// The mirrored cut.
    pub fn cut(&self) -> &Cut {
        &self.cut
    }

    /// Height and error code of a node the mirror holds.
    pub fn node(&self, geom: &TerrainGeometry, node: NodeId) -> Option<NodeData> {
        self.nodes.get(&geom.shape.index(node)).copied()
    }

    /// Every node the mirror holds (active and interior), by dense index, in no set order.
    pub fn held(&self) -> impl Iterator<Item = (u64, NodeData)> + '_ {
        self.nodes.iter().map(|(&k, &v)| (k, v))
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
            for (_, c) in shape.children(m) {
                self.nodes.remove(&shape.index(c));
            }
            on_change(&self.cut, Change::Merge(m));
        }
        for s in &delta.splits {
            self.cut.split(shape, s.node)?;
            let pi = shape.index(s.node);
            let parent = self
                .nodes
                .get_mut(&pi)
                .ok_or(CutError::NotSplittable(s.node))?;
            parent.err_code = s.err_code;
            let quad = inverse(parent.z, s.details);
            for (k, c) in shape.children(s.node) {
                let data = NodeData {
                    z: quad[k],
                    err_code: 0,
                };
                self.nodes.insert(shape.index(c), data);
            }
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
