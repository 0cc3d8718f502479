//! The tile stream drawn by the wgpu client against the real server, offscreen (lavapipe in
//! CI): the crack test in images along the standard path (issue 10), looking ahead, down and
//! grazing, on a magenta background. With crack patches, and with skirts, no background shows
//! through the terrain; with nothing against cracks it does (so the test can fail). It also
//! prints what paper 001's rule alone (dropped patches, no raised ones) would leave.

use relief_client::render::frame::rgb8;
use relief_client::render::offscreen::{FORMAT, Offscreen, enclosed_background};
use relief_client::render::{FrameParams, Gpu, TileRenderer, TileScene};
use relief_client::session::{Session, SessionConfig};
use relief_proto::msg::{CrackMode, StreamKind, TileStreamParams};
use relief_proto::view::{Camera, Lens};
use relief_server::serve::config::Limits;
use relief_tests::{TestServer, path};

/// Magenta: no terrain colour comes near it.
const BG: [u8; 3] = [255, 0, 255];

fn lens() -> Lens {
    Lens {
        width: 480,
        height: 270,
        fov_y_deg: 60.0,
        near: 1.0,
    }
}

/// What one flight saw.
#[derive(Debug, Default)]
struct Holes {
    /// Frames checked.
    frames: usize,
    /// Enclosed background pixels over all frames.
    pixels: usize,
    /// (pose, pitch in degrees, pixels) of the frames with holes, and where the first is saved.
    at: Vec<(usize, f32, usize)>,
    /// Patch triangles drawn in the checked frames (to show the patches are exercised).
    patch_triangles: usize,
}

/// Flies 160 poses of the standard path with a tile session in `crack` mode at `tau` and counts
/// the enclosed background pixels every eighth pose, looking ahead, down (-80 degrees) and
/// grazing (-3 degrees). Returns the counts drawn with every patch, and with the dropped ones
/// alone.
async fn fly(gpu: &Gpu, url: &str, crack: CrackMode, tau: f32) -> (Holes, Holes) {
    let config = SessionConfig {
        lens: lens(),
        tau,
        stream: StreamKind::Tiles(TileStreamParams {
            cache_tiles: 256,
            crack,
        }),
        ..SessionConfig::new(url)
    };
    let mut session = Session::connect(config).await.unwrap();
    let mut scene = TileScene::new(&session);
    let mut renderer = TileRenderer::new(gpu, FORMAT, &mut scene);
    let target = Offscreen::new(gpu, lens().width, lens().height);
    let (mut all, mut dropped) = (Holes::default(), Holes::default());
    for (k, cam) in path(0, 160).iter().enumerate() {
        let seq = session.send_pose(*cam).await.unwrap();
        session.wait_for_pose(seq).await.unwrap();
        scene.sync(&session);
        renderer.upload(gpu, &mut scene);
        if k % 8 != 7 {
            continue;
        }
        let down = Camera {
            pitch: -80f32.to_radians(),
            ..*cam
        };
        let grazing = Camera {
            pitch: -3f32.to_radians(),
            ..*cam
        };
        for c in [*cam, down, grazing] {
            for (dropped_only, holes) in [(false, &mut all), (true, &mut dropped)] {
                let p = FrameParams {
                    background: rgb8(BG),
                    dropped_only,
                    ..FrameParams::offscreen(&session, c, lens(), 0.0)
                };
                renderer.render(gpu, &target.view, &p);
                let img = target.read(gpu).unwrap();
                let n = enclosed_background(&img, BG);
                if n > 0 {
                    if holes.at.is_empty() {
                        let name = format!("relief-tile-crack-{crack:?}-{tau}-{dropped_only}.png");
                        img.save(std::env::temp_dir().join(name)).unwrap();
                    }
                    holes.at.push((k, c.pitch.to_degrees().round(), n));
                }
                if c == down && !dropped_only && crack != CrackMode::None {
                    let total = img.pixels().filter(|p| [p[0], p[1], p[2]] == BG).count();
                    assert_eq!(total, 0, "pose {k}: looking down, the tiles fill the frame");
                }
                holes.pixels += n;
                holes.frames += 1;
                holes.patch_triangles += scene
                    .meshes
                    .values()
                    .map(|m| {
                        let [_, d, r, _] = m.counts;
                        (d + if dropped_only { 0 } else { r }) as usize
                    })
                    .sum::<usize>();
            }
        }
    }
    let c = session.counters();
    assert_eq!(c.desyncs, 0, "tile digests all matched");
    assert!(c.tiles_sent > 0, "{c:?}");
    session.close().await;
    (all, dropped)
}

/// The standard path at tau 1 and at tau 8. On the committed crop (three tile levels) tau 1
/// keeps the tiles near the path at the finest level, so the level seams that open cracks are
/// few; tau 8 gives many.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn tiles_show_no_cracks_with_patches_or_skirts_and_cracks_without() {
    let server = TestServer::start(Limits::default()).await;
    let gpu = Gpu::headless().unwrap_or_else(|e| panic!("{e}"));
    let url = server.url();
    let mut none_total = 0;
    for tau in [1.0, 8.0] {
        let (patches, dropped_only) = fly(&gpu, &url, CrackMode::Patches, tau).await;
        let (skirts, _) = fly(&gpu, &url, CrackMode::Skirts, tau).await;
        let (none, _) = fly(&gpu, &url, CrackMode::None, tau).await;
        eprintln!(
            "tau {tau}: enclosed background pixels over {} frames: patches {} ({} patch \
             triangles drawn), skirts {}, none {} (in {} frames), dropped patches only {} \
             (in {} frames: {:?})",
            patches.frames,
            patches.pixels,
            patches.patch_triangles,
            skirts.pixels,
            none.pixels,
            none.at.len(),
            dropped_only.pixels,
            dropped_only.at.len(),
            dropped_only.at,
        );
        assert!(patches.frames >= 60, "{} frames checked", patches.frames);
        assert!(
            patches.patch_triangles > 0,
            "no patch was drawn: not a test of them"
        );
        assert_eq!(
            patches.pixels, 0,
            "tau {tau}: cracks with patches: {:?}",
            patches.at
        );
        assert_eq!(
            skirts.pixels, 0,
            "tau {tau}: cracks with skirts: {:?}",
            skirts.at
        );
        none_total += none.pixels;
    }
    assert!(
        none_total > 0,
        "without patches or skirts no crack shows: the test cannot see cracks"
    );
    server.stop().await;
}
