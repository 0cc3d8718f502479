//! Target `delta`: a [`Header`] (grid size; the parameter picks the z quantum) and then a vertex
//! delta body, decoded with [`Delta::unpack_body`] as a client does.
//!
//! A body that decodes against a mirror of the root (which has no merges, since a merge is a
//! rank among the receiver's interior nodes) must list its splits in strict wire order;
//! re-packed it must be no longer than the input and unpack to the same delta, and re-packing
//! that gives the same bytes. The body is also decoded against a cut whose nodes down to level
//! 3 are all interior, where merges decode: a delta that applies there must round-trip through
//! the cut after it.
//!
//! The delta is then applied to a [`Mirror`] holding the root, with the digest of a shadow
//! [`Cut`] that made the same splits and merges: the mirror must accept it exactly when the
//! shadow did. When it does, the mirror must hold exactly the root and the children of its
//! interior nodes, each split node with the delta's error code and its children with the
//! heights [`inverse`] gives; the cut's digest must be the sum over its active nodes, its
//! snapshot must rebuild it, and the delta that merges everything back, sent through the wire
//! format too, must return the mirror to the root.

use crate::Header;
use relief_proto::cut::{Cut, node_hash};
use relief_proto::delta::{Delta, Known, NoParents, Split, predicted_code, wire_key};
use relief_proto::haar::inverse;
use relief_proto::mirror::Mirror;
use relief_proto::snapshot::Snapshot;
use relief_proto::terrain::TerrainGeometry;
use relief_proto::tree::{NodeId, TreeShape};

/// The z quanta the header's parameter picks from, metres.
const QUANTA: [f32; 4] = [0.01, 0.1, 0.25, 1.0];

/// The root's height in quanta.
const ROOT_Z: i32 = 1000;

/// The sequence number the body is unpacked with.
const SEQ: u64 = 7;

/// Decodes, round-trips and applies one input; true if the body decoded.
pub fn check(data: &[u8]) -> bool {
    let Some((header, body)) = Header::split(data) else {
        return false;
    };
    let quantum = QUANTA[header.param as usize % QUANTA.len()];
    let Ok(geom) = TerrainGeometry::new(header.width, header.height, 1.0, 1.0, quantum) else {
        return false;
    };
    let shape = &geom.shape;
    let deeper = against_a_deeper_cut(shape, quantum, body);
    // A client at its session's start: its mirror holds the root alone, which predicts nothing
    // (splits are predicted from parents in the body) and has no interior node to merge.
    let parents = Mirror::new(&geom, ROOT_Z);
    let known = Known::mirror(&parents);
    let Ok(delta) = Delta::unpack_body(shape, quantum, SEQ, 0, body, known) else {
        return deeper;
    };
    let in_order = |keys: Vec<u64>| keys.windows(2).all(|w| w[0] < w[1]);
    assert!(in_order(
        delta.merges.iter().map(|&n| wire_key(n)).collect()
    ));
    assert!(in_order(
        delta.splits.iter().map(|s| wire_key(s.node)).collect()
    ));
    // Only merges read the cut, and none decodes against the root alone: the cut before
    // serves as the cut after for packing again.
    assert!(delta.merges.is_empty());
    let packed = delta.pack_body(shape, quantum, known);
    assert!(
        packed.len() <= body.len(),
        "re-packing grew {} bytes to {}",
        body.len(),
        packed.len()
    );
    let again = Delta::unpack_body(shape, quantum, SEQ, 0, &packed, known).expect("a packed body");
    assert_eq!(again, delta);
    assert_eq!(again.pack_body(shape, quantum, known), packed);
    apply(&geom, quantum, delta);
    true
}

/// Decodes `body` against a cut whose nodes down to level 3 are all interior, where merges
/// decode too (they are ranks among the receiver's interior nodes); a delta that applies to
/// that cut packs, against the cut after it, into a body that decodes to it again. True if the
/// body decoded.
fn against_a_deeper_cut(shape: &TreeShape, quantum: f32, body: &[u8]) -> bool {
    let before = deeper_cut(shape);
    let known = Known {
        parents: &NoParents,
        cut: &before,
    };
    let Ok(delta) = Delta::unpack_body(shape, quantum, SEQ, 0, body, known) else {
        return false;
    };
    let mut after = before.clone();
    if !applies(shape, &mut after, &delta) {
        return true;
    }
    let packed = delta.pack_body(
        shape,
        quantum,
        Known {
            parents: &NoParents,
            cut: &after,
        },
    );
    let again = Delta::unpack_body(shape, quantum, SEQ, 0, &packed, known).expect("a packed body");
    assert_eq!(again, delta);
    true
}

/// Makes `delta`'s merges (deepest first) and splits on `cut`; whether all of them could be
/// made.
fn applies(shape: &TreeShape, cut: &mut Cut, delta: &Delta) -> bool {
    delta
        .merges
        .iter()
        .rev()
        .all(|&m| cut.merge(shape, m).is_ok())
        && delta
            .splits
            .iter()
            .all(|s| cut.split(shape, s.node).is_ok())
}

/// The cut whose inner nodes down to level 3 are all interior.
fn deeper_cut(shape: &TreeShape) -> Cut {
    let mut cut = Cut::root(shape);
    let mut stack = vec![NodeId::ROOT];
    while let Some(n) = stack.pop() {
        if n.level <= 3 && !shape.is_leaf(n) {
            cut.split(shape, n).expect("an active inner node splits");
            stack.extend(shape.children(n).map(|(_, c)| c));
        }
    }
    cut
}

/// Applies `delta` to a mirror of the root and checks the result (see the module docs).
fn apply(geom: &TerrainGeometry, quantum: f32, delta: Delta) {
    let shape = &geom.shape;
    let mut shadow = Cut::root(shape);
    let fits = applies(shape, &mut shadow, &delta);
    let delta = Delta {
        digest: shadow.digest(),
        ..delta
    };
    let mut mirror = Mirror::new(geom, ROOT_Z);
    let mut changes = 0;
    let applied = mirror.apply(geom, &delta, |_, _| changes += 1);
    assert_eq!(applied.is_ok(), fits, "{applied:?}");
    if !fits {
        return;
    }
    assert_eq!(changes, delta.merges.len() + delta.splits.len());
    let cut = mirror.cut();
    let active = cut.active_nodes(shape);
    assert_eq!(active.len() as u64, cut.active_count());
    let sum = active
        .iter()
        .fold(0u64, |a, &n| a.wrapping_add(node_hash(shape.index(n))));
    assert_eq!(sum, cut.digest());

    let root = mirror.node(geom, NodeId::ROOT).expect("the root is held");
    assert_eq!(root.z, ROOT_Z);
    for s in &delta.splits {
        let node = mirror.node(geom, s.node).expect("a split node is held");
        assert_eq!(node.err_code, s.err_code);
        let quad = inverse(node.z, s.details);
        for (k, c) in shape.children(s.node) {
            assert_eq!(mirror.node(geom, c).map(|d| d.z), Some(quad[k]));
        }
    }
    let held: usize = 1 + cut
        .interior_nodes()
        .map(|n| shape.children(n).count())
        .sum::<usize>();
    assert_eq!(mirror.held().count(), held);
    for (i, data) in mirror.held() {
        let node = shape.node(i).expect("a held node exists");
        assert_eq!(mirror.node(geom, node), Some(data));
    }

    let snap = Snapshot::of(shape, cut);
    let back = snap.to_cut(shape, usize::MAX).expect("a cut's snapshot");
    assert_eq!(back.digest(), cut.digest());
    assert_eq!(back.interior_count(), cut.interior_count());

    let undo = Delta {
        seq: SEQ + 1,
        digest: Cut::root(shape).digest(),
        merges: delta.splits.iter().map(|s| s.node).collect(),
        splits: Vec::new(),
    };
    let root = Cut::root(shape);
    let after = Known {
        parents: &NoParents,
        cut: &root,
    };
    let body = undo.pack_body(shape, quantum, after);
    let wire = Delta::unpack_body(
        shape,
        quantum,
        undo.seq,
        undo.digest,
        &body,
        Known::mirror(&mirror),
    );
    assert_eq!(wire.as_ref(), Ok(&undo));
    mirror
        .apply(geom, &undo, |_, _| {})
        .expect("merging every split returns to the root");
    assert_eq!(mirror.held().count(), 1);
    assert_eq!(mirror.cut().interior_count(), 0);
}

/// A delta from the root of `shape`: the first `n` nodes that a breadth-first walk splits,
/// with made-up details.
fn splits_from_root(shape: &TreeShape, quantum: f32, n: usize) -> Delta {
    let mut cut = Cut::root(shape);
    let mut queue = std::collections::VecDeque::from([NodeId::ROOT]);
    let mut delta = Delta::default();
    while let Some(node) = queue.pop_front() {
        if delta.splits.len() == n || cut.split(shape, node).is_err() {
            continue;
        }
        let i = delta.splits.len() as i32;
        let details = [(i * 7) % 11 - 5, (i * 13) % 9 - 4, i % 3 - 1];
        delta.splits.push(Split {
            node,
            err_code: predicted_code(details, quantum).saturating_add((i % 2) as u8),
            details,
        });
        queue.extend(shape.children(node).map(|(_, c)| c));
    }
    delta.digest = cut.digest();
    delta.canonicalize();
    delta
}

/// Deltas from the root on a few small grids, the empty delta, and merges of a cut whose nodes
/// down to level 3 are all interior (the cut the merges decode against).
pub fn seeds() -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    for (w, h, param, n) in [(5, 3, 3, 3), (33, 20, 1, 9), (65, 65, 2, 21), (9, 6, 0, 0)] {
        let header = Header {
            width: w,
            height: h,
            param,
        };
        let quantum = QUANTA[param as usize];
        let shape = TreeShape::new(w, h).expect("a small grid");
        let delta = splits_from_root(&shape, quantum, n);
        let name = format!("splits_{w}x{h}_{n}");
        // No merges: the cut is not read.
        let known = Known {
            parents: &NoParents,
            cut: &Cut::root(&shape),
        };
        out.push((name, header.with(&delta.pack_body(&shape, quantum, known))));
    }
    let shape = TreeShape::new(33, 20).expect("a small grid");
    let mut after = deeper_cut(&shape);
    let merges: Vec<NodeId> = after
        .interior_nodes()
        .filter(|n| n.level == 3 && (n.x + n.y) % 3 == 0)
        .collect();
    for &m in &merges {
        after
            .merge(&shape, m)
            .expect("a level-3 node with active children merges");
    }
    let mut delta = Delta {
        digest: after.digest(),
        merges,
        ..Delta::default()
    };
    delta.canonicalize();
    let header = Header {
        width: 33,
        height: 20,
        param: 1,
    };
    let known = Known {
        parents: &NoParents,
        cut: &after,
    };
    out.push((
        "merges_33x20".into(),
        header.with(&delta.pack_body(&shape, 0.1, known)),
    ));
    out
}
