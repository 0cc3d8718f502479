//! The delta between two arbitrary cuts: what the stateless HTTP one-shot (DESIGN.md section 6,
//! "HTTP") returns, turning the client's base cut into the cut computed from scratch for its
//! camera (paper 000, section 3.4, [`VertexEngine::initial_cut`]).
//!
//! Unlike a coherent update, the two cuts may be far apart: a node and its children may all merge
//! in one delta. The merges are the nodes interior in `from` but not in `to`, the splits those
//! interior in `to` but not in `from`. The interior sets of both cuts are closed under taking
//! parents, so:
//! - a merged node's interior children are merged too, and [`relief_proto::mirror::Mirror`]
//!   applies merges deepest first, so every node's children are active when it merges;
//! - after the merges the cut is the intersection of the two interior sets, itself a cut, and a
//!   split node's parent is interior there or split before it (splits go parents first).
//!
//! Pure: no I/O, no async. The cost is proportional to the two cuts' interior counts.

use super::VertexEngine;
use relief_proto::cut::Cut;
use relief_proto::delta::Delta;

/// The delta that turns cut `from` into cut `to`, canonicalized, with `to`'s digest.
///
/// Both cuts must belong to the engine's terrain.
pub fn diff_delta(engine: &VertexEngine<'_>, from: &Cut, to: &Cut, seq: u64) -> Delta {
    let shape = &engine.geometry().shape;
    let mut delta = Delta {
        seq,
        digest: to.digest(),
        merges: from
            .interior_nodes()
            .filter(|&n| !to.is_interior(shape, n))
            .collect(),
        splits: to
            .interior_nodes()
            .filter(|&n| !from.is_interior(shape, n))
            .map(|n| engine.split_payload(n))
            .collect(),
    };
    // Ascending levels: splits parents first; the mirror takes merges in reverse, deepest first.
    delta.canonicalize();
    delta
}

#[cfg(test)]
pub(super) mod tests {
    //! Also the synthetic store, lens and cameras that the other LOD modules' tests share.
    use super::*;
    use crate::lod::vertex::{LodParams, UpdateStats};
    use crate::store::Store;
    use proptest::prelude::*;
    use relief_proto::delta::Known;
    use relief_proto::mirror::Mirror;
    use relief_proto::msg::WireDelta;
    use relief_proto::path::{PathKind, camera_path};
    use relief_proto::tree::NodeId;
    use relief_proto::view::ViewState;

    use crate::lod::vertex::tests::{Pose, camera, lens, pose, store};

    fn sorted_active(cut: &Cut, s: &Store) -> Vec<NodeId> {
        let mut v = cut.active_nodes(&s.geometry().shape);
        v.sort();
        v
    }

    /// A mirror at `from` (via its full delta) takes the wire-packed diff to `to` and then holds
    /// `to`'s active set, with every height rebuilt exactly. Returns the diff.
    fn check_diff(s: &Store, from: &Cut, to: &Cut) -> Delta {
        let engine = VertexEngine::new(s);
        let geom = engine.geometry();
        let mut mirror = Mirror::new(geom, s.root_z());
        mirror
            .apply(geom, &engine.full_delta(from, 0), |_, _| {})
            .unwrap();
        // Tags on the server's side must not matter.
        let d = diff_delta(&engine, &from.tagged(&geom.shape), to, 1);
        let known = Known {
            parents: &engine,
            cut: to,
        };
        let back = WireDelta::pack(&d, &geom.shape, geom.z_quantum, known)
            .unpack(&geom.shape, geom.z_quantum, Known::mirror(&mirror))
            .unwrap();
        assert_eq!(back, d);
        mirror.apply(geom, &back, |_, _| {}).unwrap();
        assert_eq!(mirror.cut().digest(), to.digest());
        assert_eq!(sorted_active(mirror.cut(), s), sorted_active(to, s));
        for n in sorted_active(to, s) {
            let z = mirror.node(geom, n).map(|d| d.z);
            assert_eq!(z, Some(s.node_z(n)));
        }
        d
    }

    /// Whether some merged node's parent merges too.
    fn nested(d: &Delta) -> bool {
        d.merges
            .iter()
            .any(|m| m.parent().is_some_and(|p| d.merges.contains(&p)))
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]

        #[test]
        fn diff_takes_any_cut_to_any_other(w in 5u32..80, h in 5u32..80, seed in any::<u64>(),
                                            a in pose(), b in pose(),
                                            tau_a in 0.3f32..8.0, tau_b in 0.3f32..8.0) {
            let dir = tempfile::tempdir().unwrap();
            let s = store(dir.path(), w, h, seed);
            let engine = VertexEngine::new(&s);
            let mut st = UpdateStats::default();
            let cut = |t: Pose, tau: f32, st: &mut UpdateStats| {
                let view = ViewState::new(&camera(w, h, t), &lens());
                engine.initial_cut(&view, &LodParams { tau, ..LodParams::default() }, st)
            };
            let from = cut(a, tau_a, &mut st);
            let to = cut(b, tau_b, &mut st);
            let d = check_diff(&s, &from, &to);
            // Merges and splits are disjoint, and together they are the symmetric difference.
            prop_assert_eq!(
                d.merges.len() + d.splits.len(),
                from.interior_count() + to.interior_count()
                    - 2 * from.interior_nodes()
                        .filter(|&n| to.is_interior(&s.geometry().shape, n))
                        .count()
            );
            // And back again.
            check_diff(&s, &to, &from);
        }
    }

    #[test]
    fn fine_to_root_merges_nested_and_back() {
        let (w, h) = (97, 65);
        let dir = tempfile::tempdir().unwrap();
        let s = store(dir.path(), w, h, 3);
        let engine = VertexEngine::new(&s);
        let shape = &engine.geometry().shape;
        let view = ViewState::new(&camera(w, h, (0.4, 0.3, 0.0, 0.1, 0.4)), &lens());
        let p = LodParams {
            tau: 0.3,
            ..LodParams::default()
        };
        let fine = engine.initial_cut(&view, &p, &mut UpdateStats::default());
        assert!(fine.interior_count() > 50);
        let root = Cut::root(shape);
        let d = check_diff(&s, &fine, &root);
        assert!(nested(&d));
        assert!(d.merges.contains(&NodeId::ROOT));
        assert_eq!(d.merges.len(), fine.interior_count());
        let up = check_diff(&s, &root, &fine);
        assert!(up.merges.is_empty());
        assert_eq!(up, engine.full_delta(&fine, 1));
        assert!(check_diff(&s, &fine, &fine).is_empty());
    }

    #[test]
    fn along_the_stress_path_with_coarse_and_fine_ends() {
        let (w, h) = (120, 90);
        let dir = tempfile::tempdir().unwrap();
        let s = store(dir.path(), w, h, 11);
        let engine = VertexEngine::new(&s);
        let (ex, ey) = (w as f32 * 10.0, h as f32 * 10.0);
        let poses = camera_path(PathKind::Stress, ex, ey, |_, _| 60.0);
        let mut saw_nested = false;
        for (i, k) in [(0, 1), (0, 40), (57, 150), (120, 7), (299, 0)] {
            let cut = |pose: usize, tau: f32| {
                let view = ViewState::new(&poses[pose], &lens());
                let p = LodParams {
                    tau,
                    ..LodParams::default()
                };
                engine.initial_cut(&view, &p, &mut UpdateStats::default())
            };
            // Fine to coarse (nested merges), coarse to fine, and like to like.
            let fine = cut(i, 0.5);
            let coarse = cut(k, 6.0);
            saw_nested |= nested(&check_diff(&s, &fine, &coarse));
            check_diff(&s, &coarse, &fine);
            check_diff(&s, &cut(i, 1.0), &cut(k, 1.0));
        }
        assert!(saw_nested, "no case exercised nested merges");
    }
}
