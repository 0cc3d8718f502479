//! The incremental fans against the brute-force rule, and the rule's validity.

use super::*;
use crate::cut::Cut;
use crate::tree::TreeShape;
use proptest::prelude::*;

fn valid(shape: &TreeShape, tris: &[Tri]) -> MeshReport {
    let r = check_mesh(shape, |n| shape.grid_pos(n), tris);
    assert_eq!(r.cracks, 0, "{r:?}");
    assert_eq!(r.folds, 0, "{r:?}");
    assert_eq!(r.non_manifold_edges, 0, "{r:?}");
    r
}

#[test]
fn full_resolution_is_the_grid() {
    let shape = TreeShape::new(5, 4).unwrap();
    let mut cut = Cut::root(&shape);
    let mut stack = vec![crate::tree::NodeId::ROOT];
    while let Some(n) = stack.pop() {
        if !shape.is_leaf(n) {
            cut.split(&shape, n).unwrap();
            stack.extend(shape.children(n).map(|(_, c)| c));
        }
    }
    let tris = oracle(&shape, &cut);
    assert_eq!(tris.len(), 2 * 4 * 3);
    assert_eq!(valid(&shape, &tris).triangles, 24);
    assert_eq!(FanMesh::new(&shape, &cut).triangles(), tris);
}

#[test]
fn root_alone_draws_nothing_and_one_split_draws_two() {
    let shape = TreeShape::new(8, 8).unwrap();
    let mut cut = Cut::root(&shape);
    assert!(oracle(&shape, &cut).is_empty());
    let mut mesh = FanMesh::new(&shape, &cut);
    cut.split(&shape, crate::tree::NodeId::ROOT).unwrap();
    mesh.update_around(&shape, &cut, crate::tree::NodeId::ROOT);
    assert_eq!(oracle(&shape, &cut).len(), 2);
    assert_eq!(mesh.triangles(), oracle(&shape, &cut));
    assert_eq!(mesh.take_dirty(), vec![(3, 3)]);
}

/// A random walk of splits and merges: `ops` picks, each step, a node to split or merge.
fn random_ops(shape: &TreeShape, picks: &[(bool, u32)], mut each: impl FnMut(&Cut, NodeIdArg)) {
    let mut cut = Cut::root(shape);
    for &(split, k) in picks {
        let active = cut.active_nodes(shape);
        let splittable: Vec<_> = active.iter().filter(|n| !shape.is_leaf(**n)).collect();
        let mergeable: Vec<_> = cut
            .interior_indices()
            .filter_map(|i| shape.node(i))
            .filter(|&n| shape.children(n).all(|(_, c)| !cut.is_interior(shape, c)))
            .collect();
        let node = if (split || mergeable.is_empty()) && !splittable.is_empty() {
            let n = *splittable[k as usize % splittable.len()];
            cut.split(shape, n).unwrap();
            n
        } else if !mergeable.is_empty() {
            let n = mergeable[k as usize % mergeable.len()];
            cut.merge(shape, n).unwrap();
            n
        } else {
            continue;
        };
        each(&cut, node);
    }
}

type NodeIdArg = crate::tree::NodeId;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn incremental_fans_equal_the_rule(w in 2u32..40, h in 2u32..40,
                                        picks in proptest::collection::vec((prop::bool::weighted(0.7), any::<u32>()), 0..150)) {
        let shape = TreeShape::new(w, h).unwrap();
        let mut mesh = FanMesh::new(&shape, &Cut::root(&shape));
        let mut failure = None;
        random_ops(&shape, &picks, |cut, node| {
            if failure.is_some() { return; }
            mesh.update_around(&shape, cut, node);
            let truth = oracle(&shape, cut);
            if mesh.triangles() != truth {
                failure = Some(format!("incremental differs after {node:?}"));
            } else if FanMesh::new(&shape, cut).triangles() != truth {
                failure = Some(format!("from-scratch differs after {node:?}"));
            } else {
                let r = check_mesh(&shape, |n| shape.grid_pos(n), &truth);
                if r.cracks + r.folds + r.non_manifold_edges > 0 {
                    failure = Some(format!("invalid mesh after {node:?}: {r:?}"));
                }
            }
        });
        prop_assert!(failure.is_none(), "{}", failure.unwrap_or_default());
    }
}

#[test]
fn update_work_does_not_grow_with_block_size() {
    // Splitting the root of a large grid touches the same few cells as on a small one.
    let mut works = Vec::new();
    for side in [33u32, 1025] {
        let shape = TreeShape::new(side, side).unwrap();
        let mut cut = Cut::root(&shape);
        let mut mesh = FanMesh::new(&shape, &cut);
        let before = mesh.work();
        cut.split(&shape, crate::tree::NodeId::ROOT).unwrap();
        mesh.update_around(&shape, &cut, crate::tree::NodeId::ROOT);
        let child = crate::tree::NodeId::ROOT.child(3);
        cut.split(&shape, child).unwrap();
        mesh.update_around(&shape, &cut, child);
        works.push(mesh.work() - before);
    }
    assert_eq!(works[0], works[1], "{works:?}");
    assert!(works[0] < 40, "{works:?}");
}

#[test]
fn a_missing_triangle_is_a_crack_and_a_flipped_one_a_fold() {
    let shape = TreeShape::new(6, 6).unwrap();
    let mut cut = Cut::root(&shape);
    cut.split(&shape, crate::tree::NodeId::ROOT).unwrap();
    for k in 0..4 {
        cut.split(&shape, crate::tree::NodeId::ROOT.child(k))
            .unwrap();
    }
    let mut tris = oracle(&shape, &cut);
    valid(&shape, &tris);
    let t = tris.remove(tris.len() / 2);
    let r = check_mesh(&shape, |n| shape.grid_pos(n), &tris);
    assert!(r.cracks > 0, "{r:?}");
    let [a, b, c] = t.0;
    tris.push(Tri::new(a, c, b).unwrap());
    let r = check_mesh(&shape, |n| shape.grid_pos(n), &tris);
    assert!(r.folds > 0, "{r:?}");
}
