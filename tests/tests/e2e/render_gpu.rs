//! The wgpu client against the real server, offscreen on whatever adapter wgpu finds (Mesa's
//! software Vulkan, lavapipe, in CI): a golden image, a crack test in images and a no-pop test
//! of the geomorph at every split and merge.

use glam::Vec3;
use relief_client::render::frame::rgb8;
use relief_client::render::offscreen::{FORMAT, Offscreen, enclosed_background};
use relief_client::render::shot::{ShotPose, draw, frame_params, stream_to};
use relief_client::render::{Follower, FrameParams, Gpu, MorphStage, Renderer};
use relief_client::session::{Session, SessionConfig};
use relief_proto::mesh::MorphRule;
use relief_proto::path::PATH_HZ;
use relief_proto::tree::NodeId;
use relief_proto::view::{Camera, Lens};
use relief_server::serve::config::Limits;
use relief_tests::{TestServer, path};
use std::collections::{HashMap, HashSet};
use std::path::PathBuf;

fn gpu() -> Gpu {
    Gpu::headless().unwrap_or_else(|e| panic!("{e}"))
}

fn lens(width: u32, height: u32) -> Lens {
    Lens {
        width,
        height,
        fov_y_deg: 60.0,
        near: 1.0,
    }
}

fn golden_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("golden/fuji_crop_320x180.png")
}

/// Pixels whose channels differ by more than 8 levels, and the mean absolute difference.
fn difference(a: &image::RgbaImage, b: &image::RgbaImage) -> (usize, f64) {
    assert_eq!(a.dimensions(), b.dimensions(), "image sizes differ");
    let mut far = 0;
    let mut sum = 0u64;
    for (p, q) in a.pixels().zip(b.pixels()) {
        let d = (0..3).map(|i| p[i].abs_diff(q[i])).max().unwrap_or(0);
        far += usize::from(d > 8);
        sum += (0..3).map(|i| u64::from(p[i].abs_diff(q[i]))).sum::<u64>();
    }
    (far, sum as f64 / (a.len() as f64 * 0.75))
}

/// Golden-image tolerance: at most 1% of pixels off by more than 8 levels, and a mean absolute
/// difference of at most 1.5 levels (rasterisers may differ on edge pixels, not on the picture).
fn matches(a: &image::RgbaImage, b: &image::RgbaImage) -> bool {
    let (far, mean) = difference(a, b);
    far * 100 <= a.len() / 4 && mean <= 1.5
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn golden_image_of_the_committed_crop() {
    let server = TestServer::start(Limits::default()).await;
    let gpu = gpu();
    let l = lens(320, 180);
    let cam = Camera {
        eye: Vec3::new(9700.0, -6000.0, 7000.0),
        yaw: 90f32.to_radians(),
        pitch: -30f32.to_radians(),
    };
    let config = SessionConfig {
        lens: l,
        ..SessionConfig::new(&server.url())
    };
    let mut s = stream_to(config, ShotPose::Camera(cam)).await.unwrap();
    let params = frame_params(&s, l, false, [158, 179, 204]);
    let img = draw(&gpu, &mut s, &params).unwrap();
    let per_vertex = FrameParams {
        morph: MorphStage::Vertex,
        ..params
    };
    let img_vertex = draw(&gpu, &mut s, &per_vertex).unwrap();
    let wire_params = frame_params(&s, l, true, [158, 179, 204]);
    let wire = draw(&gpu, &mut s, &wire_params).unwrap();
    let golden = golden_path();
    if std::env::var_os("RELIEF_BLESS").is_some() {
        img.save(&golden).unwrap();
    }
    let want = image::open(&golden)
        .unwrap_or_else(|e| panic!("{}: {e} (RELIEF_BLESS=1 writes it)", golden.display()))
        .to_rgba8();
    let (far, mean) = difference(&img, &want);
    let actual = std::env::temp_dir().join("relief-golden-actual.png");
    if !matches(&img, &want) {
        img.save(&actual).unwrap();
    }
    assert!(
        matches(&img, &want),
        "{far} pixels off by more than 8 levels, mean difference {mean:.2} (adapter {}); \
         this render is at {}",
        gpu.describe(),
        actual.display()
    );
    // The geomorph in the vertex shader draws the same picture.
    let (far, mean) = difference(&img_vertex, &want);
    assert!(
        matches(&img_vertex, &want),
        "per-vertex geomorph: {far} pixels off, mean {mean:.2}"
    );
    // The comparison can fail: the wireframe overlay of the same view is far outside it.
    assert!(
        !matches(&wire, &want),
        "the tolerance cannot tell a wireframe apart"
    );
    s.session.close().await;
    server.stop().await;
}

/// A session recording its changes, with its scene and a renderer.
struct Rig {
    session: Session,
    follower: Follower,
    renderer: Renderer,
    lens: Lens,
}

impl Rig {
    async fn new(gpu: &Gpu, url: &str, lens: Lens) -> Rig {
        let config = SessionConfig {
            lens,
            record_changes: true,
            ..SessionConfig::new(url)
        };
        let mut session = Session::connect(config).await.unwrap();
        let mut follower = Follower::new(&mut session);
        let renderer = Renderer::new(gpu, FORMAT, &mut follower.scene);
        Rig {
            session,
            follower,
            renderer,
            lens,
        }
    }

    /// Streams `cam`'s delta and brings the scene and the GPU buffers up to date.
    async fn pose(&mut self, gpu: &Gpu, cam: Camera, now: f32) {
        let seq = self.session.send_pose(cam).await.unwrap();
        self.session.wait_for_pose(seq).await.unwrap();
        self.follower.sync(&mut self.session, now);
        self.renderer.upload(gpu, &mut self.follower.scene);
    }

    fn params(&self, camera: Camera, now: f32, rule: MorphRule, bg: [u8; 3]) -> FrameParams {
        FrameParams {
            rule,
            background: rgb8(bg),
            morph: MorphStage::Compute,
            ..FrameParams::offscreen(&self.session, camera, self.lens, now)
        }
    }

    /// Drawn positions of the active nodes for `p` (runs the geomorph pass and reads it back).
    fn drawn(&mut self, gpu: &Gpu, p: &FrameParams) -> HashMap<NodeId, Vec3> {
        self.renderer.morph_only(gpu, p);
        let all = self.renderer.read_drawn(gpu).unwrap();
        let geom = self.session.geometry();
        self.session
            .mirror()
            .cut()
            .active_nodes(&geom.shape)
            .into_iter()
            .map(|n| {
                let slot = self
                    .follower
                    .scene
                    .slot_of(geom, n)
                    .expect("active nodes are held");
                (n, all[slot as usize])
            })
            .collect()
    }

    /// Active nodes drawn away from their rest position: geomorphs in progress.
    fn morphing(&self, drawn: &HashMap<NodeId, Vec3>) -> usize {
        let geom = self.session.geometry();
        drawn
            .iter()
            .filter(|(n, p)| {
                let d = self.session.mirror().node(geom, **n).unwrap();
                geom.world_pos(**n, d.z).distance(**p) > 0.01
            })
            .count()
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn no_background_shows_through_the_terrain() {
    let server = TestServer::start(Limits::default()).await;
    let gpu = gpu();
    let bg = [255, 0, 255];
    let mut rig = Rig::new(&gpu, &server.url(), lens(480, 270)).await;
    let target = Offscreen::new(&gpu, 480, 270);
    let cams = path(0, 160);
    let (mut frames, mut morphing, mut holes) = (0, 0, Vec::new());
    for (k, cam) in cams.iter().enumerate() {
        let t = k as f32 / PATH_HZ;
        rig.pose(&gpu, *cam, t).await;
        if k % 8 != 7 {
            continue;
        }
        // Mid-growth for this pose's splits, and mid-morph for nodes near tau.
        let now = t + 0.1;
        let views = relief_tests::crack_views(*cam);
        for c in views {
            let p = rig.params(c, now, MorphRule::new(1.0), bg);
            let drawn = rig.drawn(&gpu, &p);
            morphing += rig.morphing(&drawn);
            rig.renderer.render(&gpu, &target.view, &p);
            let img = target.read(&gpu).unwrap();
            let n = enclosed_background(&img, bg);
            if n > 0 {
                let f = std::env::temp_dir().join(format!("relief-crack-{k}.png"));
                img.save(&f).unwrap();
                holes.push((k, c.pitch.to_degrees(), n, f));
            }
            if c == views[1] {
                let total = img.pixels().filter(|p| [p[0], p[1], p[2]] == bg).count();
                assert_eq!(total, 0, "pose {k}: looking down, terrain fills the frame");
            }
            frames += 1;
        }
    }
    eprintln!(
        "{frames} frames, {morphing} vertices mid-geomorph, {} with holes",
        holes.len()
    );
    assert!(
        holes.is_empty(),
        "background through the terrain: {holes:?}"
    );
    assert!(frames >= 60, "{frames} frames checked");
    assert!(
        morphing > 100,
        "only {morphing} vertices were mid-geomorph: not a test of it"
    );
    rig.session.close().await;
    server.stop().await;
}

/// Compares the drawn positions before and after one delta, for the same camera and time:
/// every node drawn in both frames stays put, every node a split brings in stands where its
/// ancestor was drawn, and every node a merge removes stood where its ancestor is now drawn.
/// Returns (changed vertices checked, vertices that jumped more than `tol` metres).
fn jumps(
    before: &HashMap<NodeId, Vec3>,
    after: &HashMap<NodeId, Vec3>,
    tol: f32,
) -> (usize, usize) {
    let ancestor_in = |mut n: NodeId, set: &HashMap<NodeId, Vec3>| -> Option<Vec3> {
        while let Some(p) = n.parent() {
            if let Some(v) = set.get(&p) {
                return Some(*v);
            }
            n = p;
        }
        None
    };
    let (mut checked, mut jumped) = (0, 0);
    let mut check = |a: Vec3, b: Vec3| {
        jumped += usize::from(a.distance(b) > tol + 1e-6 * a.length());
    };
    for (n, p) in after {
        match before.get(n) {
            Some(q) => check(*p, *q),
            None => {
                checked += 1;
                if let Some(q) = ancestor_in(*n, before) {
                    check(*p, q);
                }
            }
        }
    }
    let kept: HashSet<&NodeId> = after.keys().collect();
    for (n, q) in before {
        if !kept.contains(n) {
            checked += 1;
            if let Some(p) = ancestor_in(*n, after) {
                check(p, *q);
            }
        }
    }
    (checked, jumped)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn no_vertex_jumps_at_splits_and_merges() {
    let server = TestServer::start(Limits::default()).await;
    let gpu = gpu();
    let mut rig = Rig::new(&gpu, &server.url(), Lens::STANDARD).await;
    let rule = MorphRule::new(1.0);
    // The paper's error-driven alpha alone: splits that arrive late jump.
    let error_only = MorphRule {
        duration: 0.0,
        ..rule
    };
    let (mut checked, mut jumped, mut jumped_error_only) = (0, 0, 0);
    for (k, cam) in path(0, 300).iter().enumerate() {
        let t = k as f32 / PATH_HZ;
        let p = rig.params(*cam, t, rule, [0, 0, 0]);
        let e = rig.params(*cam, t, error_only, [0, 0, 0]);
        let (before, before_e) = (rig.drawn(&gpu, &p), rig.drawn(&gpu, &e));
        rig.pose(&gpu, *cam, t).await;
        let (after, after_e) = (rig.drawn(&gpu, &p), rig.drawn(&gpu, &e));
        let (c, j) = jumps(&before, &after, 1e-3);
        checked += c;
        jumped += j;
        jumped_error_only += jumps(&before_e, &after_e, 1e-3).1;
    }
    eprintln!(
        "{checked} split or merged vertices: {jumped} jumped; {jumped_error_only} without the growth cap"
    );
    assert!(
        checked > 10_000,
        "only {checked} split or merged vertices checked"
    );
    assert_eq!(
        jumped, 0,
        "{jumped} of {checked} vertices jumped at a split or merge"
    );
    assert!(
        jumped_error_only > 0,
        "the check cannot see a jump: without the growth cap, late splits must jump"
    );
    rig.session.close().await;
    server.stop().await;
}
