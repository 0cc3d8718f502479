//! Property tests of the vertex engine: deltas replayed by a mirror rebuild the server's cut,
//! the digest catches dropped and reordered deltas, the top-down initial cut equals the paper's
//! bottom-up pass, and a camera at rest yields empty deltas.

use super::{LodParams, UpdateStats, VertexEngine};
use crate::store::{Store, StoreInput, StoreMeta, write_store};
use glam::Vec3;
use proptest::prelude::*;
use relief_proto::cut::Cut;
use relief_proto::delta::{BodyModels, Delta, Known};
use relief_proto::mirror::{Mirror, MirrorError};
use relief_proto::msg::WireDelta;
use relief_proto::tree::NodeId;
use relief_proto::view::{Camera, Lens, ViewState};

/// A store over a rough random terrain (shared with the other engine tests) of `w` x `h` samples, 10 m apart.
pub(crate) fn store(dir: &std::path::Path, w: u32, h: u32, seed: u64) -> Store {
    let mut s = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
    let mut rnd = move || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 33) as f32 / (1u64 << 31) as f32
    };
    let heights: Vec<f32> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            (x * 0.3).sin() * 30.0 + (y * 0.17).cos() * 50.0 + rnd() * 8.0
        })
        .collect();
    let voids = crate::dem::VoidMask::new(heights.len());
    let path = dir.join(format!("{w}x{h}-{seed}.relief"));
    let input = StoreInput {
        width: w,
        height: h,
        spacing_x: 10.0,
        spacing_y: 10.0,
        z_quantum: 0.1,
        heights: &heights,
        voids: &voids,
        tile_size: 8,
        meta: StoreMeta::default(),
    };
    write_store(&path, &input, |_| {}).unwrap();
    Store::open(&path).unwrap()
}

pub(crate) fn camera(w: u32, h: u32, t: (f32, f32, f32, f32, f32)) -> Camera {
    Camera {
        eye: Vec3::new(
            t.0 * w as f32 * 10.0,
            t.1 * h as f32 * 10.0,
            20.0 + t.2 * 300.0,
        ),
        yaw: t.3 * std::f32::consts::TAU,
        pitch: -0.1 - t.4 * 1.2,
    }
}

pub(crate) fn lens() -> Lens {
    Lens {
        width: 640,
        height: 480,
        ..Lens::STANDARD
    }
}

fn active_set(cut: &Cut, shape: &relief_proto::tree::TreeShape) -> Vec<NodeId> {
    let mut v = cut.active_nodes(shape);
    v.sort();
    v
}

/// The paper's `NonRecursiveDetermineNullSubTrees`, over every node: the test oracle.
fn bottom_up(engine: &VertexEngine<'_>, view: &ViewState, tau: f32) -> Vec<NodeId> {
    let shape = &engine.geometry().shape;
    let mut root_of_null = vec![true; shape.node_count() as usize];
    for level in (0..shape.depth()).rev() {
        let (w, h) = shape.level_dims(level);
        for y in 0..h {
            for x in 0..w {
                let n = NodeId { level, x, y };
                let kids_roots = shape
                    .children(n)
                    .all(|(_, c)| root_of_null[shape.index(c) as usize]);
                root_of_null[shape.index(n) as usize] =
                    kids_roots && engine.screen_error(view, n) <= tau;
            }
        }
    }
    // Active = a null-subtree root whose parent is not one.
    let mut out: Vec<NodeId> = (0..shape.node_count())
        .filter_map(|i| shape.node(i))
        .filter(|&n| {
            root_of_null[shape.index(n) as usize]
                && n.parent()
                    .is_none_or(|p| !root_of_null[shape.index(p) as usize])
        })
        .collect();
    out.sort();
    out
}

/// A camera pose as five fractions (position, height, heading, pitch) for [`camera`].
pub(crate) type Pose = (f32, f32, f32, f32, f32);

/// Random poses.
pub(crate) fn pose() -> impl Strategy<Value = Pose> {
    (
        0.0f32..1.0,
        0.0f32..1.0,
        0.0f32..1.0,
        0.0f32..1.0,
        0.0f32..1.0,
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    #[test]
    fn replayed_deltas_rebuild_the_cut(w in 5u32..70, h in 5u32..70, seed in any::<u64>(),
                                       poses in proptest::collection::vec(pose(), 1..12)) {
        let dir = tempfile::tempdir().unwrap();
        let s = store(dir.path(), w, h, seed);
        let engine = VertexEngine::new(&s);
        let geom = engine.geometry();
        let p = LodParams { tau: 2.0, ..LodParams::default() };
        let mut st = UpdateStats::default();
        let v0 = ViewState::new(&camera(w, h, poses[0]), &lens());
        let mut cut = engine.initial_cut(&v0, &p, &mut st);
        prop_assert_eq!(active_set(&cut, &geom.shape), bottom_up(&engine, &v0, p.tau));
        let mut mirror = Mirror::new(geom, s.root_z());
        // One connection: the body models carry from delta to delta on both ends.
        let (mut server, mut client) = (BodyModels::new(), BodyModels::new());
        let first = WireDelta::pack_in(&engine.full_delta(&cut, 0), &geom.shape, &mut server, geom.z_quantum,
                                       Known { parents: &engine, cut: &cut });
        let first = first.unpack_in(&geom.shape, geom.z_quantum, &mut client, Known::mirror(&mirror)).unwrap();
        mirror.apply(geom, &first, |_, _| {}).unwrap();
        for (i, t) in poses.iter().enumerate() {
            let view = ViewState::new(&camera(w, h, *t), &lens());
            let d = engine.update(&mut cut, &view, &p, i as u64 + 1, &mut st);
            let wire = WireDelta::pack_in(&d, &geom.shape, &mut server, geom.z_quantum,
                                          Known { parents: &engine, cut: &cut });
            let back = wire.unpack_in(&geom.shape, geom.z_quantum, &mut client, Known::mirror(&mirror)).unwrap();
            prop_assert_eq!(&back, &d);
            mirror.apply(geom, &back, |_, _| {}).unwrap();
            prop_assert_eq!(active_set(mirror.cut(), &geom.shape), active_set(&cut, &geom.shape));
            // Heights rebuilt from details equal the store's, node for node.
            for n in active_set(&cut, &geom.shape) {
                let z = mirror.node(geom, n).unwrap().z;
                prop_assert_eq!(z, s.node_z(n));
            }
        }
    }

    #[test]
    fn dropped_or_reordered_deltas_are_detected(seed in any::<u64>(), a in pose(), b in pose(), c in pose()) {
        let (w, h) = (40, 33);
        let dir = tempfile::tempdir().unwrap();
        let s = store(dir.path(), w, h, seed);
        let engine = VertexEngine::new(&s);
        let geom = engine.geometry();
        let p = LodParams::default();
        let mut st = UpdateStats::default();
        let mut cut = engine.initial_cut(&ViewState::new(&camera(w, h, a), &lens()), &p, &mut st);
        let base = Mirror::new(geom, s.root_z());
        let mut m = base.clone();
        m.apply(geom, &engine.full_delta(&cut, 0), |_, _| {}).unwrap();
        let d1 = engine.update(&mut cut, &ViewState::new(&camera(w, h, b), &lens()), &p, 1, &mut st);
        let d2 = engine.update(&mut cut, &ViewState::new(&camera(w, h, c), &lens()), &p, 2, &mut st);
        prop_assume!(!d1.is_empty() && !d2.is_empty());
        // Dropping d1: applying d2 alone must fail (either an illegal op or a digest mismatch).
        let mut dropped = m.clone();
        let r = dropped.apply(geom, &d2, |_, _| {});
        prop_assert!(r.is_err());
        // Reordering: d2 before d1.
        let mut reordered = m.clone();
        let r = reordered.apply(geom, &d2, |_, _| {}).and_then(|_| reordered.apply(geom, &d1, |_, _| {}));
        prop_assert!(r.is_err());
        m.apply(geom, &d1, |_, _| {}).unwrap();
        m.apply(geom, &d2, |_, _| {}).unwrap();
    }
}

#[test]
fn camera_at_rest_converges_to_empty_deltas() {
    let (w, h) = (129, 97);
    let dir = tempfile::tempdir().unwrap();
    let s = store(dir.path(), w, h, 5);
    let engine = VertexEngine::new(&s);
    let p = LodParams::default();
    let cam = camera(w, h, (0.3, 0.2, 0.1, 0.15, 0.2));
    let view = ViewState::new(&cam, &lens());
    let mut st = UpdateStats::default();
    let mut cut = Cut::root(&engine.geometry().shape);
    let mut rounds = 0;
    while !engine
        .update(&mut cut, &view, &p, rounds, &mut st)
        .is_empty()
    {
        rounds += 1;
        assert!(rounds < 40, "no convergence");
    }
    // Converged from the root one level per update: same cut as computed directly.
    let direct = engine.initial_cut(&view, &p, &mut st);
    assert_eq!(cut.digest(), direct.digest());
    // Sub-millimetre jitter changes nothing thanks to the hysteresis.
    for k in 0..10 {
        let mut c = cam;
        c.eye.x += (k as f32 * 0.37).sin() * 1e-3;
        c.yaw += (k as f32 * 0.71).cos() * 1e-5;
        let d = engine.update(&mut cut, &ViewState::new(&c, &lens()), &p, 100 + k, &mut st);
        assert!(d.is_empty(), "jitter produced {d:?}");
    }
}

#[test]
fn mirror_refuses_a_forged_digest() {
    let dir = tempfile::tempdir().unwrap();
    let s = store(dir.path(), 33, 33, 1);
    let engine = VertexEngine::new(&s);
    let geom = engine.geometry();
    let view = ViewState::new(&camera(33, 33, (0.5, 0.1, 0.2, 0.25, 0.3)), &lens());
    let cut = engine.initial_cut(&view, &LodParams::default(), &mut UpdateStats::default());
    let mut d: Delta = engine.full_delta(&cut, 0);
    d.digest ^= 1;
    let mut m = Mirror::new(geom, s.root_z());
    assert!(matches!(
        m.apply(geom, &d, |_, _| {}),
        Err(MirrorError::Desync { .. })
    ));
}

/// A smooth random flight: small steps and turns, now and then a fast one.
fn flight(w: u32, h: u32, seed: u64, n: usize) -> Vec<Camera> {
    let mut s = seed | 1;
    let mut rnd = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s % 10_000) as f32 / 10_000.0
    };
    let mut c = camera(w, h, (rnd(), rnd(), rnd() * 0.5, rnd(), rnd()));
    (0..n)
        .map(|_| {
            let fast = if rnd() < 0.1 { 20.0 } else { 1.0 };
            c.eye += Vec3::new(rnd() - 0.5, rnd() - 0.5, (rnd() - 0.5) * 0.3) * 8.0 * fast;
            c.eye.z = c.eye.z.max(15.0);
            c.yaw += (rnd() - 0.5) * 0.05 * fast;
            c.pitch = (c.pitch + (rnd() - 0.5) * 0.03 * fast).clamp(-1.4, -0.05);
            c
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(16))]

    #[test]
    fn event_driven_session_matches_the_full_pass(w in 20u32..120, h in 20u32..120,
                                                  seed in any::<u64>(), tau in 0.5f32..4.0) {
        use super::session::VertexSession;
        let dir = tempfile::tempdir().unwrap();
        let s = store(dir.path(), w, h, seed);
        let engine = VertexEngine::new(&s);
        let p = LodParams { tau, ..LodParams::default() };
        let cams = flight(w, h, seed, 60);
        let v0 = ViewState::new(&cams[0], &lens());
        let mut st = UpdateStats::default();
        let mut full = engine.initial_cut(&v0, &p, &mut st);
        let mut session = VertexSession::new(&engine, &v0, &p);
        let (mut full_visits, mut session_visits) = (0, 0);
        for (i, cam) in cams.iter().enumerate() {
            let view = ViewState::new(cam, &lens());
            let mut a = UpdateStats::default();
            let mut b = UpdateStats::default();
            let d1 = engine.update(&mut full, &view, &p, i as u64, &mut a);
            let d2 = session.update(&engine, &view, &p, i as u64, &mut b);
            prop_assert_eq!(d1, d2, "update {}", i);
            full_visits += a.visited;
            session_visits += b.visited;
        }
        prop_assert!(session_visits <= full_visits);
    }
}

/// A camera that turns steadily and barely moves, on a terrain large enough for far boxes: the
/// slacks are then spent by rotation, whose bound (a lever times the chords) the session files
/// each group with. A rotation allowance too large for the screen error's own terms shows here
/// as a delta that differs from the full pass: halving the depth's off-axis lever fails this
/// test, where the property test's gentler flights (16 cases) still pass.
#[test]
fn a_turning_camera_matches_the_full_pass() {
    use super::session::VertexSession;
    let (w, h) = (257, 193);
    let dir = tempfile::tempdir().unwrap();
    let s = store(dir.path(), w, h, 11);
    let engine = VertexEngine::new(&s);
    let mut changes = 0;
    for (k, (turn, tilt, tau)) in [
        (0.02f32, 0.004f32, 1.0f32),
        (0.05, -0.01, 0.7),
        (0.09, 0.0, 2.0),
    ]
    .into_iter()
    .enumerate()
    {
        let p = LodParams {
            tau,
            ..LodParams::default()
        };
        let mut cam = camera(
            w,
            h,
            (0.1 + 0.35 * k as f32, 0.3, 0.2, 0.1 * k as f32, 0.15),
        );
        let v0 = ViewState::new(&cam, &lens());
        let mut full = engine.initial_cut(&v0, &p, &mut UpdateStats::default());
        let mut session = VertexSession::new(&engine, &v0, &p);
        for i in 1..120u64 {
            cam.yaw += turn;
            cam.pitch = (cam.pitch + tilt).clamp(-1.3, -0.08);
            cam.eye += Vec3::new(0.4, -0.3, 0.0);
            let view = ViewState::new(&cam, &lens());
            let (mut a, mut b) = (UpdateStats::default(), UpdateStats::default());
            let d1 = engine.update(&mut full, &view, &p, i, &mut a);
            let d2 = session.update(&engine, &view, &p, i, &mut b);
            assert_eq!(d1, d2, "flight {k}, update {i}");
            changes += d1.splits.len() + d1.merges.len();
        }
    }
    assert!(changes > 2_000, "{changes}");
}

#[test]
fn a_node_just_split_is_not_evaluated_again_for_its_merge_check() {
    // Found by the property test above: on this small terrain the session examined 1,245
    // nodes to the full pass's 1,228, since each node it split was evaluated a second time for
    // its own merge check, when the split had just evaluated it.
    use super::session::VertexSession;
    let (w, h, seed, tau) = (82u32, 20u32, 9_872_809_616_889_327_660u64, 0.5f32);
    let dir = tempfile::tempdir().unwrap();
    let s = store(dir.path(), w, h, seed);
    let engine = VertexEngine::new(&s);
    let p = LodParams {
        tau,
        ..LodParams::default()
    };
    let cams = flight(w, h, seed, 60);
    let v0 = ViewState::new(&cams[0], &lens());
    let mut full = engine.initial_cut(&v0, &p, &mut UpdateStats::default());
    let mut session = VertexSession::new(&engine, &v0, &p);
    let (mut full_visits, mut session_visits, mut changes) = (0, 0, 0);
    for (i, cam) in cams.iter().enumerate() {
        let view = ViewState::new(cam, &lens());
        let (mut a, mut b) = (UpdateStats::default(), UpdateStats::default());
        let d1 = engine.update(&mut full, &view, &p, i as u64, &mut a);
        let d2 = session.update(&engine, &view, &p, i as u64, &mut b);
        assert_eq!(d1, d2, "update {i}");
        changes += d1.splits.len() + d1.merges.len();
        full_visits += a.visited;
        session_visits += b.visited;
    }
    assert!(changes > 200, "{changes}");
    assert!(
        session_visits <= full_visits,
        "session {session_visits} full pass {full_visits}"
    );
}

#[test]
fn prefetching_any_node_reads_nothing_out_of_bounds() {
    // The update prefetches the cut's page and the children's records of groups ahead of
    // their examination: on a grid with odd borders, for every node of every level
    // (leaves and nodes outside the grid included), in an empty cut and a deep one.
    let (w, h) = (37u32, 23u32);
    let dir = tempfile::tempdir().unwrap();
    let s = store(dir.path(), w, h, 5);
    let engine = VertexEngine::new(&s);
    let shape = &engine.geometry().shape;
    let view = ViewState::new(&camera(w, h, (0.5, 0.5, 0.1, 0.2, 0.3)), &lens());
    let deep = engine.initial_cut(
        &view,
        &LodParams {
            tau: 0.1,
            ..LodParams::default()
        },
        &mut UpdateStats::default(),
    );
    // Pages on every inner level.
    assert!(
        deep.interior_nodes().any(|n| n.level + 2 == shape.depth()),
        "{} interior nodes",
        deep.interior_nodes().count()
    );
    // Tagged as a session's cut is (its tags are prefetched too), and untagged.
    let root = Cut::root(shape);
    for cut in [root.tagged(shape), deep.tagged(shape), root, deep] {
        for level in 0..=shape.depth() {
            let (cw, ch) = shape.level_dims(level.min(shape.depth() - 1));
            for y in 0..=ch {
                for x in 0..=cw {
                    let n = NodeId { level, x, y };
                    engine.prefetch_children(n);
                    cut.prefetch_tag(n);
                }
            }
        }
    }
}
