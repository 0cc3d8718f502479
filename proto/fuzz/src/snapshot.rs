//! Target `snapshot`: a [`Header`] (grid size; the parameter picks the tile size, 2 to 256)
//! and then a [`Snapshot`] as bincode puts it on the wire (in a hello's or a `/v1/lod`
//! request's resume), decoded with [`codec::decode`] and round-tripped like a message.
//!
//! The snapshot is then read as a cut of the vertex tree ([`Snapshot::to_cut`]) and as an
//! active set of the tile pyramid ([`active_of`]), as a resuming server does. A wrong digest
//! is what the fuzzer cannot guess, so when only the digest is refused the bits are read again
//! with the digest they give. Whatever is accepted must give back the same bits and digest
//! ([`Snapshot::of`], [`snapshot_of`]); a cut must have the digest of its active nodes and be
//! refused with one interior node less allowed; the active tiles must cover every cell once.

use crate::{Header, LIMIT};
use relief_proto::codec;
use relief_proto::cut::{Cut, node_hash};
use relief_proto::snapshot::{Snapshot, SnapshotError};
use relief_proto::tile::TileShape;
use relief_proto::tile::snapshot::{active_of, snapshot_of};
use relief_proto::tree::{NodeId, TreeShape};

/// The most interior nodes or active tiles accepted (inputs are far too short to reach it).
const MAX_NODES: usize = 1 << 20;

/// Decodes, round-trips and rebuilds one input; true if the snapshot decoded.
pub fn check(data: &[u8]) -> bool {
    let Some((header, frame)) = Header::split(data) else {
        return false;
    };
    let Ok(snap) = codec::decode::<Snapshot>(frame, LIMIT) else {
        return false;
    };
    let bytes = codec::encode(&snap);
    crate::assert_canonical(frame, &bytes);
    assert_eq!(
        codec::decode::<Snapshot>(&bytes, LIMIT).ok(),
        Some(snap.clone())
    );
    if let Ok(shape) = TreeShape::new(header.width, header.height) {
        vertex(&shape, &snap);
    }
    let tile = 2 << (header.param % 8);
    if let Ok(shape) = TileShape::new(header.width, header.height, tile) {
        tiles(&shape, &snap);
    }
    true
}

/// `snap` with the digest that its bits give, when that alone was wrong.
fn with_own_digest<T>(snap: &Snapshot, r: Result<T, SnapshotError>) -> Option<Snapshot> {
    match r {
        Err(SnapshotError::Digest { ours, theirs }) => {
            assert_eq!(theirs, snap.digest);
            Some(Snapshot {
                digest: ours,
                bits: snap.bits.clone(),
            })
        }
        _ => None,
    }
}

/// Reads `snap` as a cut of `shape` and checks it.
fn vertex(shape: &TreeShape, snap: &Snapshot) {
    let first = snap.to_cut(shape, MAX_NODES);
    let (snap, cut) = match first {
        Ok(cut) => (snap.clone(), cut),
        Err(_) => {
            let Some(fixed) = with_own_digest(snap, first) else {
                return;
            };
            let cut = fixed
                .to_cut(shape, MAX_NODES)
                .expect("only the digest was wrong");
            (fixed, cut)
        }
    };
    assert_eq!(Snapshot::of(shape, &cut), snap);
    let active = cut.active_nodes(shape);
    assert_eq!(active.len() as u64, cut.active_count());
    let sum = active
        .iter()
        .fold(0u64, |a, &n| a.wrapping_add(node_hash(shape.index(n))));
    assert_eq!(sum, cut.digest());
    assert!(active.iter().all(|&n| cut.is_active(shape, n)));
    if let Some(fewer) = cut.interior_count().checked_sub(1) {
        assert_eq!(
            snap.to_cut(shape, fewer).map(|c| c.digest()),
            Err(SnapshotError::TooLarge(fewer))
        );
    } else {
        assert_eq!(cut.digest(), Cut::root(shape).digest());
    }
}

/// Reads `snap` as an active tile set of `shape` and checks it.
fn tiles(shape: &TileShape, snap: &Snapshot) {
    let first = active_of(shape, snap, MAX_NODES);
    let (snap, active) = match first {
        Ok(active) => (snap.clone(), active),
        Err(_) => {
            let Some(fixed) = with_own_digest(snap, first) else {
                return;
            };
            let active = active_of(shape, &fixed, MAX_NODES).expect("only the digest was wrong");
            (fixed, active)
        }
    };
    assert!(active.windows(2).all(|w| w[0] < w[1]));
    assert_eq!(snapshot_of(shape, &active), snap);
    let cells: u64 = active
        .iter()
        .map(|&i| {
            let span = shape.span(shape.tile(i).expect("an active tile exists"));
            u64::from(span.cols.1 - span.cols.0) * u64::from(span.rows.1 - span.rows.0)
        })
        .sum();
    let all = u64::from(shape.width() - 1) * u64::from(shape.height() - 1);
    assert_eq!(cells, all, "the active tiles cover the grid once");
}

/// Snapshots of a few cuts and tile sets, on small grids.
pub fn seeds() -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    for (w, h, n) in [(5, 3, 2), (33, 20, 7), (65, 65, 30)] {
        let shape = TreeShape::new(w, h).expect("a small grid");
        // Split the first `n` nodes of a depth-first walk that always takes the last child.
        let mut cut = Cut::root(&shape);
        let mut stack = vec![NodeId::ROOT];
        let mut split = 0;
        while let Some(node) = stack.pop() {
            if split < n && cut.split(&shape, node).is_ok() {
                split += 1;
                stack.extend(shape.children(node).map(|(_, c)| c));
            }
        }
        let header = Header {
            width: w,
            height: h,
            param: 1,
        };
        let bytes = codec::encode(&Snapshot::of(&shape, &cut));
        out.push((format!("cut_{w}x{h}_{n}"), header.with(&bytes)));
    }
    // The root tile split, and its first child too, on a pyramid of 16-cell tiles.
    let shape = TileShape::new(300, 200, 16).expect("a small pyramid");
    let root = NodeId::ROOT;
    let first = root.child(0);
    let mut active: Vec<u32> = shape.children(first).map(|t| shape.index(t)).collect();
    active.extend(shape.children(root).skip(1).map(|t| shape.index(t)));
    active.sort_unstable();
    let header = Header {
        width: 300,
        height: 200,
        param: 3,
    };
    let bytes = codec::encode(&snapshot_of(&shape, &active));
    out.push(("tiles_300x200".into(), header.with(&bytes)));
    out
}
