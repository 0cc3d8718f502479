use super::*;
use crate::cut::Cut;
use crate::delta::{Delta, Split};
use crate::mesh::Tri;
use std::collections::BTreeSet;

use crate::rng::Rng;

/// A random delta from `shadow`'s cut: a few merges of nodes whose children are all active, or
/// a few splits of active nodes; `shadow` is moved to the cut after it.
fn random_delta(geom: &TerrainGeometry, shadow: &mut Cut, rng: &mut Rng, seq: u64) -> Delta {
    let shape = &geom.shape;
    let mut merges = Vec::new();
    let mut splits = Vec::new();
    if rng.below(3) == 0 {
        let mut candidates: Vec<NodeId> = shadow
            .interior_indices()
            .filter_map(|i| shape.node(i))
            .filter(|&n| {
                shape
                    .children(n)
                    .all(|(_, c)| !shadow.is_interior(shape, c))
            })
            .collect();
        candidates.sort_unstable_by_key(|&n| shape.index(n));
        for _ in 0..3 {
            if candidates.is_empty() {
                break;
            }
            let n = candidates.swap_remove(rng.below(candidates.len()));
            shadow.merge(shape, n).unwrap();
            merges.push(n);
        }
    } else {
        let mut candidates: Vec<NodeId> = shadow
            .active_nodes(shape)
            .into_iter()
            .filter(|&n| !shape.is_leaf(n))
            .collect();
        for _ in 0..6 {
            if candidates.is_empty() {
                break;
            }
            let n = candidates.swap_remove(rng.below(candidates.len()));
            shadow.split(shape, n).unwrap();
            let d = |r: &mut Rng| r.below(41) as i32 - 20;
            splits.push(Split {
                node: n,
                err_code: 1 + rng.below(200) as u8,
                details: [d(rng), d(rng), d(rng)],
            });
        }
    }
    merges.sort_unstable_by_key(|&n| shape.index(n));
    Delta {
        seq,
        digest: shadow.digest(),
        merges,
        splits,
    }
}

/// The triangles the cell records draw, as canonical triangles of nodes.
fn drawn(scene: &Scene, geom: &TerrainGeometry, mirror: &Mirror) -> BTreeSet<Tri> {
    let node_of: FxHashMap<u32, NodeId> = mirror
        .held()
        .map(|(i, _)| geom.shape.node(i).unwrap())
        .map(|n| (scene.slot_of(geom, n).unwrap(), n))
        .collect();
    let mut out = BTreeSet::new();
    for s in 0..scene.cells.capacity() as u32 {
        let r = scene.cells.record(s);
        for t in [&r[0..3], &r[3..6]] {
            if t[0] == NONE {
                assert!(t.iter().all(|&v| v == NONE), "a half-written triangle");
                continue;
            }
            let [a, b, c] = [t[0], t[1], t[2]].map(|v| node_of[&v]);
            assert!(out.insert(Tri::new(a, b, c).unwrap()), "a triangle twice");
        }
    }
    out
}

fn check(scene: &Scene, geom: &TerrainGeometry, mirror: &Mirror, mesh: &FanMesh) {
    let want: BTreeSet<Tri> = mesh.triangles().into_iter().collect();
    assert_eq!(drawn(scene, geom, mirror), want);
    assert_eq!(scene.held_count(), mirror.held().count());
    let slots: std::collections::HashSet<u32> = mirror
        .held()
        .filter_map(|(i, _)| scene.slot_of(geom, geom.shape.node(i).unwrap()))
        .collect();
    assert_eq!(slots.len(), scene.held_count(), "two nodes share a slot");
    for (i, d) in mirror.held() {
        let n = geom.shape.node(i).unwrap();
        let slot = scene.slot_of(geom, n).expect("every held node has a slot");
        let r = scene.nodes.record(slot);
        let want_parent = n.parent().map_or(NONE, |p| scene.slot_of(geom, p).unwrap());
        assert_eq!(r[3], want_parent, "{n:?}'s parent slot");
        assert_eq!(f32::from_bits(r[2]), geom.world_pos(n, d.z).z);
    }
}

/// A `w` x `h` terrain held at its root, with its mesh and scene.
fn start(w: u32, h: u32, root_z: i32) -> (TerrainGeometry, Mirror, FanMesh, Scene) {
    let geom = TerrainGeometry::new(w, h, 10.0, 12.0, 0.25).unwrap();
    let mirror = Mirror::new(&geom, root_z);
    let mut mesh = FanMesh::new(&geom.shape, mirror.cut());
    let scene = Scene::build(&geom, &mirror, &mut mesh);
    (geom, mirror, mesh, scene)
}

#[test]
fn records_follow_random_splits_and_merges() {
    let (geom, mut mirror, mut mesh, mut scene) = start(37, 29, 400);
    let mut shadow = Cut::root(&geom.shape);
    let mut rng = Rng::new(0x5eed_1234_abcd);
    let mut changes = Vec::new();
    for seq in 1..=400u64 {
        let delta = random_delta(&geom, &mut shadow, &mut rng, seq);
        changes.clear();
        mirror
            .apply(&geom, &delta, |c, change| {
                mesh.update_around(&geom.shape, c, change.node());
                changes.push(change);
            })
            .unwrap();
        scene.apply(&geom, &mirror, &mut mesh, &changes, seq as f32);
        check(&scene, &geom, &mirror, &mesh);
    }
    assert!(mesh.triangle_count() > 100, "the walk reached a real mesh");
    // A scene built from scratch draws the same triangles.
    let mut fresh_mesh = FanMesh::new(&geom.shape, mirror.cut());
    let fresh = Scene::build(&geom, &mirror, &mut fresh_mesh);
    assert_eq!(drawn(&fresh, &geom, &mirror), drawn(&scene, &geom, &mirror));
}

#[test]
fn splits_are_stamped_and_pages_marked() {
    let (geom, mut mirror, mut mesh, mut scene) = start(17, 17, 0);
    assert!(scene.nodes.grown());
    let _ = scene.nodes.take_dirty();
    let _ = scene.cells.take_dirty();
    assert!(
        scene.nodes.take_dirty().is_empty(),
        "nothing written, nothing to upload"
    );
    let root = NodeId::ROOT;
    let mut shadow = Cut::root(&geom.shape);
    shadow.split(&geom.shape, root).unwrap();
    let delta = Delta {
        seq: 1,
        digest: shadow.digest(),
        merges: vec![],
        splits: vec![Split {
            node: root,
            err_code: 9,
            details: [1, 2, 3],
        }],
    };
    mirror
        .apply(&geom, &delta, |c, ch| {
            mesh.update_around(&geom.shape, c, ch.node())
        })
        .unwrap();
    scene.apply(&geom, &mirror, &mut mesh, &[Change::Split(root)], 42.5);
    let r = scene.nodes.record(scene.slot_of(&geom, root).unwrap());
    assert_eq!(f32::from_bits(r[11]), 42.5, "the split time");
    assert!(f32::from_bits(r[7]) > 0.0, "the static error arrived");
    let child = scene.slot_of(&geom, root.child(0)).unwrap();
    assert_eq!(f32::from_bits(scene.nodes.record(child)[11]), LONG_AGO);
    let runs = scene.nodes.take_dirty();
    assert_eq!(
        runs,
        vec![(0, PAGE_RECORDS * NODE_WORDS)],
        "one page, not the pool"
    );
    assert_eq!(
        mesh.triangle_count(),
        2,
        "four active children make one quad"
    );
}
