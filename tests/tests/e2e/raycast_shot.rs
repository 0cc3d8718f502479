//! `GET /v1/raycast.png` against `relief-client shot` of the same camera: the
//! ray-cast picture of the exact surface and the rendered LOD mesh must agree within a stated
//! tolerance, and a camera turned away must not. The shot is drawn on whatever adapter wgpu
//! finds (Mesa's software Vulkan, lavapipe, in CI), as in `render_gpu.rs`.
//!
//! `RELIEF_DOCS_IMG=1` writes both pictures to `docs/img/raycast.png` and
//! `docs/img/raycast-shot.png`.

use glam::Vec3;
use relief_client::render::Gpu;
use relief_client::render::frame::SKY_RGB8;
use relief_client::render::shot::{ShotPose, draw, frame_params, stream_to};
use relief_client::session::SessionConfig;
use relief_proto::view::{Camera, Lens};
use relief_server::query::view;
use relief_server::serve::config::Limits;
use relief_tests::TestServer;
use relief_tests::http::{get, header};
use std::path::PathBuf;
use std::time::Instant;

/// The compared view: from 2 km south of the crop, 4.2 km up, looking north and 14 degrees down, so
/// that the picture holds Fuji's slopes, the terrain's far edge and sky.
const CAMERA: [f32; 5] = [9700.0, -2000.0, 4200.0, 80.0, -14.0];

/// The compared image size.
const SIZE: (u32, u32) = (640, 360);

/// Levels (0 to 255) by which a pixel's channel may differ before the pixel counts as off.
const OFF_LEVELS: u8 = 24;

/// Tolerance: the mean absolute difference over all channels, levels.
const MAX_MEAN: f64 = 2.0;

/// Tolerance: the share of pixels off by more than [`OFF_LEVELS`] in some channel (the LOD
/// mesh's silhouettes and ridges move by up to about tau pixels, so edges differ).
const MAX_OFF_SHARE: f64 = 0.01;

/// The mean absolute difference per channel and the share of pixels off by more than
/// [`OFF_LEVELS`] in some channel.
fn difference(a: &image::RgbaImage, b: &image::RgbaImage) -> (f64, f64) {
    assert_eq!(a.dimensions(), b.dimensions(), "image sizes differ");
    let (mut sum, mut off) = (0u64, 0usize);
    for (p, q) in a.pixels().zip(b.pixels()) {
        let d = [0, 1, 2].map(|i| p[i].abs_diff(q[i]));
        sum += d.iter().map(|&v| u64::from(v)).sum::<u64>();
        off += usize::from(d.iter().any(|&v| v > OFF_LEVELS));
    }
    let n = a.pixels().len();
    (sum as f64 / (3 * n) as f64, off as f64 / n as f64)
}

/// Whether two pictures agree within the tolerance.
fn agree((mean, off): (f64, f64)) -> bool {
    mean <= MAX_MEAN && off <= MAX_OFF_SHARE
}

/// The query of a ray-cast of `cam` (x, y, z, yaw and pitch in degrees).
fn raycast_path(cam: [f32; 5]) -> String {
    let [x, y, z, yaw, pitch] = cam;
    format!(
        "/v1/raycast.png?camera={x},{y},{z},{yaw},{pitch}&size={}x{}&fov=60",
        SIZE.0, SIZE.1
    )
}

/// The ray-cast PNG of `cam`, decoded.
async fn raycast(server: &TestServer, cam: [f32; 5]) -> image::RgbaImage {
    let (status, hs, body) = get(server, &raycast_path(cam), &[]).await;
    assert_eq!(status, 200, "{}", String::from_utf8_lossy(&body));
    assert_eq!(header(&hs, "content-type"), Some("image/png"));
    image::load_from_memory(&body).unwrap().to_rgba8()
}

fn docs_img(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../docs/img")
        .join(name)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn raycast_agrees_with_the_rendered_shot() {
    let server = TestServer::start(Limits::default()).await;
    let started = Instant::now();
    let cast = raycast(&server, CAMERA).await;
    let http_s = started.elapsed().as_secs_f64();

    let [x, y, z, yaw, pitch] = CAMERA;
    let cam = Camera {
        eye: Vec3::new(x, y, z),
        yaw: yaw.to_radians(),
        pitch: pitch.to_radians(),
    };
    let lens = Lens {
        width: SIZE.0,
        height: SIZE.1,
        fov_y_deg: 60.0,
        near: 1.0,
    };
    let gpu = Gpu::headless().unwrap_or_else(|e| panic!("{e}"));
    let config = SessionConfig {
        lens,
        ..SessionConfig::new(&server.url())
    };
    let mut s = stream_to(config, ShotPose::Camera(cam)).await.unwrap();
    let params = frame_params(&s, lens, false, SKY_RGB8);
    let shot = draw(&gpu, &mut s, &params).unwrap();

    if std::env::var_os("RELIEF_DOCS_IMG").is_some() {
        cast.save(docs_img("raycast.png")).unwrap();
        shot.save(docs_img("raycast-shot.png")).unwrap();
    }
    let sky = |img: &image::RgbaImage| {
        let n = img.pixels().filter(|p| p.0[..3] == SKY_RGB8).count();
        n as f64 / img.pixels().len() as f64
    };
    let figures = difference(&cast, &shot);
    eprintln!(
        "ray-cast {}x{} over HTTP in {http_s:.2} s ({:.1}% sky; shot {:.1}% sky, adapter {}): \
         mean absolute difference {:.2} levels (at most {MAX_MEAN}), {:.2}% of pixels off by \
         more than {OFF_LEVELS} levels (at most {:.1}%)",
        SIZE.0,
        SIZE.1,
        100.0 * sky(&cast),
        100.0 * sky(&shot),
        gpu.describe(),
        figures.0,
        100.0 * figures.1,
        100.0 * MAX_OFF_SHARE,
    );
    // The view shows both terrain and sky.
    assert!(
        (0.05..0.6).contains(&sky(&cast)),
        "sky share {}",
        sky(&cast)
    );
    if !agree(figures) {
        let dir = std::env::temp_dir();
        cast.save(dir.join("relief-raycast.png")).unwrap();
        shot.save(dir.join("relief-raycast-shot.png")).unwrap();
    }
    assert!(
        agree(figures),
        "the ray-cast and the shot differ: {figures:?} (both saved in {})",
        std::env::temp_dir().display()
    );

    // The comparison can fail: the same camera turned 10 degrees, or 200 m higher, is outside it.
    for (what, wrong) in [
        ("turned 10 degrees", [x, y, z, yaw + 10.0, pitch]),
        ("raised 200 m", [x, y, z + 200.0, yaw, pitch]),
    ] {
        let other = difference(&raycast(&server, wrong).await, &shot);
        eprintln!(
            "camera {what}: mean {:.2} levels, {:.2}% off",
            other.0,
            100.0 * other.1
        );
        assert!(!agree(other), "the tolerance cannot tell a camera {what}");
    }

    // The picture on one thread and on several, timed (the same picture either way).
    let t = server.state.terrain().unwrap();
    let terrain = t.query.as_ref().unwrap();
    let fog = relief_client::render::fog_distance(s.session.geometry());
    assert_eq!(view::fog_distance(terrain), fog, "the haze's fog distance");
    let mut pictures = Vec::new();
    for threads in [1, 2, 4] {
        let started = Instant::now();
        pictures.push(view::render(terrain, &cam, &lens, threads).unwrap());
        eprintln!(
            "ray-cast {}x{} on {threads} thread(s): {:.3} s",
            SIZE.0,
            SIZE.1,
            started.elapsed().as_secs_f64()
        );
    }
    assert!(pictures.iter().all(|p| *p == cast));

    s.session.close().await;
    server.stop().await;
}

#[tokio::test]
async fn bad_requests_are_refused_with_a_reason() {
    let server = TestServer::start(Limits::default()).await;
    for (query, says) in [
        ("", "camera is missing"),
        ("?camera=1,2,3", "five numbers"),
        ("?camera=1,2,3,0,95", "pitch within (-90, 90) degrees"),
        ("?camera=1e9,0,100,0,-10", "away from the terrain"),
        ("?camera=0,0,9000,0,-10&size=4096x4096", "size"),
        ("?camera=0,0,9000,0,-10&size=640", "size"),
        ("?camera=0,0,9000,0,-10&fov=0", "fov"),
    ] {
        let (status, hs, body) = get(&server, &format!("/v1/raycast.png{query}"), &[]).await;
        let text = String::from_utf8_lossy(&body);
        assert_eq!(status, 400, "{query}: {text}");
        assert_eq!(header(&hs, "content-type"), Some("application/json"));
        let v: serde_json::Value = serde_json::from_slice(&body).unwrap();
        let e = v["error"].as_str().unwrap();
        assert!(e.contains(says), "{query}: {e}");
    }
    // The default size and fov.
    let (status, _, body) = get(
        &server,
        "/v1/raycast.png?camera=9700,-6000,5000,90,-12",
        &[],
    )
    .await;
    assert_eq!(status, 200);
    let img = image::load_from_memory(&body).unwrap();
    assert_eq!((img.width(), img.height()), (640, 360));
    server.stop().await;
}

/// The ray-cast's shading constants are the renderer's: the ramp's stops and the sun and haze
/// are literals in the client's WGSL and Rust, duplicated in `relief_server::query::view`.
#[test]
fn shading_constants_match_the_renderer() {
    let client = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../client/src/render");
    let wgsl = std::fs::read_to_string(client.join("shade.wgsl")).unwrap();
    for [h, r, g, b] in view::RAMP {
        let stop = format!("vec4<f32>({h:.1}, {r:.2}, {g:.2}, {b:.2})");
        assert!(wgsl.contains(&stop), "shade.wgsl has no stop {stop}");
    }
    assert!(wgsl.contains(&format!("array<vec4<f32>, {}>", view::RAMP.len())));
    assert!(wgsl.contains("base * (0.30 + 0.95 * lambert)"));
    assert!(wgsl.contains("mix(c, frame.haze.rgb, 0.45 * fog)"));
    assert!(wgsl.contains("pow(c, vec3<f32>(1.0 / 2.2))"));
    let frame = std::fs::read_to_string(client.join("frame.rs")).unwrap();
    let [sx, sy, sz] = view::SUN;
    assert!(frame.contains(&format!("Vec3::new({sx:.2}, {sy:.2}, {sz:.2})")));
    let [hr, hg, hb] = view::HAZE;
    assert!(frame.contains(&format!("[{hr:.2}, {hg:.2}, {hb:.2}, f.fog_distance")));
    assert_eq!(view::SKY_RGB8, SKY_RGB8);
}
