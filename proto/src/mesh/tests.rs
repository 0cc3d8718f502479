//! The incremental fans against the brute-force rule, and the rule's validity.

use super::*;
use crate::cut::Cut;
use crate::tree::NodeId;
use crate::tree::TreeShape;
use proptest::prelude::*;

fn valid(shape: &TreeShape, tris: &[Tri]) -> MeshReport {
    let r = check_mesh(shape, |n| shape.grid_pos(n), tris);
    assert_eq!(r.cracks, 0, "{r:?}");
    assert_eq!(r.folds, 0, "{r:?}");
    assert_eq!(r.non_manifold_edges, 0, "{r:?}");
    r
}

/// The dirty cells, sorted.
fn dirty(mesh: &mut FanMesh) -> Vec<(u32, u32)> {
    let mut d = Vec::new();
    mesh.take_dirty(&mut d);
    d.sort_unstable();
    d
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
    mesh.track_dirty(true);
    cut.split(&shape, crate::tree::NodeId::ROOT).unwrap();
    mesh.update_around(&shape, &cut, crate::tree::NodeId::ROOT);
    assert_eq!(oracle(&shape, &cut).len(), 2);
    assert_eq!(mesh.triangles(), oracle(&shape, &cut));
    assert_eq!(dirty(&mut mesh), vec![(3, 3)]);
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
        mesh.track_dirty(true);
        // What a renderer holds: the cells as last reported dirty.
        let mut shadow = std::collections::BTreeMap::new();
        let mut taken = Vec::new();
        let mut failure = None;
        random_ops(&shape, &picks, |cut, node| {
            if failure.is_some() { return; }
            mesh.update_around(&shape, cut, node);
            let truth = oracle(&shape, cut);
            if node.x % 2 == 0 {
                // Take the dirty cells after some changes only, so that they pile up in between.
                mesh.take_dirty(&mut taken);
                let before = taken.len();
                taken.sort_unstable();
                taken.dedup();
                if taken.len() != before {
                    failure = Some(format!("a dirty cell listed twice after {node:?}"));
                }
                for &cell in &taken {
                    shadow.insert(cell, mesh.cell(cell));
                }
                let mut drawn: Vec<Tri> = shadow.values().flatten().flatten().copied().collect();
                drawn.sort_unstable();
                if drawn != truth {
                    failure = Some(format!("dirty cells miss a change after {node:?}"));
                }
            }
            if failure.is_some() {
            } else if mesh.triangles() != truth {
                failure = Some(format!("incremental differs after {node:?}"));
            } else if mesh.triangle_count() != truth.len() {
                failure = Some(format!("triangle count differs after {node:?}"));
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

fn leaf(shape: &TreeShape, c: u32, r: u32) -> NodeId {
    shape.leaf(c, r)
}

#[test]
fn two_by_two_split_is_the_cell_itself() {
    let shape = TreeShape::new(2, 2).unwrap();
    let mut cut = Cut::root(&shape);
    assert!(oracle(&shape, &cut).is_empty());
    cut.split(&shape, NodeId::ROOT).unwrap();
    let (a, b, d, e) = (
        leaf(&shape, 0, 0),
        leaf(&shape, 1, 0),
        leaf(&shape, 0, 1),
        leaf(&shape, 1, 1),
    );
    let mut expect = vec![Tri::new(a, d, e).unwrap(), Tri::new(a, e, b).unwrap()];
    expect.sort_unstable();
    assert_eq!(oracle(&shape, &cut), expect);
    assert_eq!(FanMesh::new(&shape, &cut).triangles(), expect);
    valid(&shape, &expect);
}

#[test]
fn three_by_three_root_split_meets_at_one_junction() {
    // Children of the root: NW 2x2, NE 1x2 strip, SW 2x1 strip, SE single sample; they meet
    // only at the centre of cell (1, 1), which therefore holds the whole mesh.
    let shape = TreeShape::new(3, 3).unwrap();
    let mut cut = Cut::root(&shape);
    let mut mesh = FanMesh::new(&shape, &cut);
    mesh.track_dirty(true);
    cut.split(&shape, NodeId::ROOT).unwrap();
    mesh.update_around(&shape, &cut, NodeId::ROOT);
    let [nw, ne, sw, se] = [0, 1, 2, 3].map(|k| NodeId::ROOT.child(k));
    let mut expect = vec![Tri::new(nw, sw, se).unwrap(), Tri::new(nw, se, ne).unwrap()];
    expect.sort_unstable();
    assert_eq!(oracle(&shape, &cut), expect);
    assert_eq!(mesh.triangles(), expect);
    assert_eq!(dirty(&mut mesh), vec![(1, 1)]);
    valid(&shape, &expect);
}

#[test]
fn levels_three_apart_stay_closed() {
    // 16 x 16: refine towards the grid's centre inside the NW quadrant only, so leaves (level 4)
    // touch the three other level-1 quadrants.
    let shape = TreeShape::new(16, 16).unwrap();
    let mut cut = Cut::root(&shape);
    let mut mesh = FanMesh::new(&shape, &cut);
    let mut n = NodeId::ROOT;
    for k in [0, 3, 3, 3] {
        cut.split(&shape, n).unwrap();
        mesh.update_around(&shape, &cut, n);
        n = n.child(k);
    }
    let truth = oracle(&shape, &cut);
    assert_eq!(mesh.triangles(), truth);
    assert_eq!(mesh.triangle_count(), truth.len());
    assert_eq!(FanMesh::new(&shape, &cut).triangles(), truth);
    valid(&shape, &truth);
    // The corner cell where the finest leaf meets three level-1 quadrants.
    let (l, e, s, se) = (
        leaf(&shape, 7, 7),
        NodeId::ROOT.child(1),
        NodeId::ROOT.child(2),
        NodeId::ROOT.child(3),
    );
    assert_eq!(mesh.cell((7, 7)), [Tri::new(l, s, se), Tri::new(l, se, e)]);
    // Merging back up restores the single-split mesh.
    for p in [
        NodeId {
            level: 3,
            x: 3,
            y: 3,
        },
        NodeId {
            level: 2,
            x: 1,
            y: 1,
        },
        NodeId {
            level: 1,
            x: 0,
            y: 0,
        },
    ] {
        cut.merge(&shape, p).unwrap();
        mesh.update_around(&shape, &cut, p);
        assert_eq!(mesh.triangles(), oracle(&shape, &cut));
    }
    assert_eq!(mesh.triangle_count(), 2);
}

#[test]
fn clipped_block_centres_would_fold_a_border_strip() {
    // The smallest grid (by sample count, searched exhaustively over all cuts of every grid up to
    // 45 samples and every grid up to 8 x 8) on which clipped-block centres fold; nominal
    // centres, which the tree uses, do not.
    let shape = TreeShape::new(5, 9).unwrap();
    let mut cut = Cut::root(&shape);
    for n in [
        NodeId::ROOT,
        NodeId {
            level: 1,
            x: 0,
            y: 0,
        },
        NodeId {
            level: 2,
            x: 0,
            y: 1,
        },
        NodeId {
            level: 3,
            x: 1,
            y: 3,
        },
    ] {
        cut.split(&shape, n).unwrap();
    }
    let tris = oracle(&shape, &cut);
    valid(&shape, &tris);
    let clipped = |n: NodeId| {
        let (c0, r0, c1, r1) = shape.block(n);
        ((c0 + c1) as f32 / 2.0, (r0 + r1) as f32 / 2.0)
    };
    let r = check_mesh(&shape, clipped, &tris);
    assert_eq!(r.folds, 1, "{r:?}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Whole deltas in wire order applied through the mirror, chains of splits and merges
    /// among them: the mesh, its count and its dirty cells stay those of the rule.
    #[test]
    fn whole_deltas_keep_the_rule(w in 2u32..70, h in 2u32..70, seed in any::<u64>(),
                                      chain in 0.0f64..0.9) {
        use crate::mirror::Mirror;
        use crate::terrain::TerrainGeometry;
        let geom = TerrainGeometry::new(w, h, 10.0, 10.0, 1.0).unwrap();
        let shape = &geom.shape;
        let mut rng = crate::rng::Rng::new(seed);
        let mut shadow = Cut::root(shape);
        let mut mirror = Mirror::new(&geom, 0);
        let mut mesh = FanMesh::new(shape, mirror.cut());
        mesh.track_dirty(true);
        let mut drawn = std::collections::BTreeMap::new();
        let mut taken = Vec::new();
        for _ in 0..25 {
            let delta = crate::delta::tests::random_delta(shape, &mut shadow, &mut rng, chain);
            mirror.apply(&geom, &delta, |c, ch| mesh.update_around(shape, c, ch.node())).unwrap();
            let truth = oracle(shape, mirror.cut());
            prop_assert_eq!(mesh.triangles(), truth.clone());
            prop_assert_eq!(mesh.triangle_count(), truth.len());
            mesh.take_dirty(&mut taken);
            for &cell in &taken {
                drawn.insert(cell, mesh.cell(cell));
            }
            let mut shown: Vec<Tri> = drawn.values().flatten().flatten().copied().collect();
            shown.sort_unstable();
            prop_assert_eq!(shown, truth, "the dirty cells miss a change");
        }
    }
}
