//! `relief-client shot`: stream the cut (or the tiles) for one camera (or a path up to one
//! frame) and draw it offscreen into a PNG. Works on Mesa's software Vulkan, with no window.
//!
//! With `--path K --frame N` the session flies the path's poses 0..=N in lock step, as a viewer
//! at the path's rate would receive them, each split stamped with its pose's time; the frame is
//! drawn one pose interval after pose N, so the last pose's splits are still growing, as they
//! would be on screen. With `--camera`, one pose is streamed and drawn after every geomorph has
//! settled.

use super::frame::{FrameParams, MorphStage, rgb8};
use super::gpu::{Gpu, RenderError};
use super::offscreen::Offscreen;
use super::stream::{StreamRenderer, StreamScene};
use crate::flight::{PathSpec, extent, server_path};
use crate::http::HttpError;
use crate::session::{ClientError, Session, SessionConfig};
use relief_proto::path::{PATH_HZ, PathKind};
use relief_proto::view::{Camera, Lens};

/// Which camera a shot is taken from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ShotPose {
    /// A fixed camera.
    Camera(Camera),
    /// Pose `frame` of a path, flown from its start.
    Path {
        /// The path.
        kind: PathKind,
        /// The pose index.
        frame: usize,
    },
}

/// What to draw.
#[derive(Clone, Debug)]
pub struct ShotOptions {
    /// The session (its lens's width and height are the image's).
    pub session: SessionConfig,
    /// The camera.
    pub pose: ShotPose,
    /// Draw triangle edges.
    pub wireframe: bool,
    /// Clear colour, 8-bit RGB.
    pub background: [u8; 3],
    /// Where the geomorph is evaluated.
    pub morph: MorphStage,
    /// Tile stream: draw the dropped crack patches alone (a diagnostic).
    pub dropped_only: bool,
    /// Draw from this camera, with this vertical field of view (degrees) if given, instead of
    /// the one streamed for (a diagnostic: the selection seen up close).
    pub look_from: Option<(Camera, Option<f32>)>,
}

/// What a shot drew.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ShotReport {
    /// The adapter used.
    pub adapter: String,
    /// Image width and height.
    pub size: (u32, u32),
    /// Triangles drawn.
    pub triangles: usize,
    /// Active nodes of the cut, or active tiles.
    pub active: u64,
    /// Deltas received.
    pub deltas: u64,
    /// Bytes received.
    pub bytes: u64,
    /// Why the image may show no terrain (empty when it is in view): see [`super::shot_check`].
    pub warnings: Vec<String>,
}

/// Why a shot failed.
#[derive(Debug, thiserror::Error)]
pub enum ShotError {
    /// The session failed.
    #[error(transparent)]
    Session(#[from] ClientError),
    /// Fetching the path's ground heights failed.
    #[error(transparent)]
    Http(#[from] HttpError),
    /// Rendering failed.
    #[error(transparent)]
    Render(#[from] RenderError),
    /// The frame asked for is past the path's end.
    #[error("--frame {frame} is past the path's last pose ({last})")]
    FrameOutOfRange {
        /// Asked.
        frame: usize,
        /// The last pose index.
        last: usize,
    },
}

/// A session streamed to a camera, its scene, and the clock its splits were stamped with.
pub struct Streamed {
    /// The session, with its mirror and mesh (or tiles).
    pub session: Session,
    /// Its records or tiles.
    pub scene: StreamScene,
    /// When the frame should be drawn, seconds on the scene's clock.
    pub now: f32,
    /// The camera to draw from.
    pub camera: Camera,
}

/// Connects and streams the cut (or tiles) for `pose`.
pub async fn stream_to(config: SessionConfig, pose: ShotPose) -> Result<Streamed, ShotError> {
    let config = super::renderer_config(config);
    let mut session = Session::connect(config).await?;
    let mut scene = StreamScene::new(&mut session);
    let (cams, last) = match pose {
        ShotPose::Camera(c) => (vec![c], 0),
        ShotPose::Path { kind, frame } => {
            let ext = extent(session.terrain());
            let url = session.url().to_string();
            let cams = server_path(&url, ext, PathSpec::Kind(kind)).await?;
            if frame >= cams.len() {
                return Err(ShotError::FrameOutOfRange {
                    frame,
                    last: cams.len().saturating_sub(1),
                });
            }
            (cams, frame)
        }
    };
    for (k, cam) in cams.iter().enumerate().take(last + 1) {
        let seq = session.send_pose(*cam).await?;
        session.wait_for_pose(seq).await?;
        scene.sync(&mut session, k as f32 / PATH_HZ);
    }
    let now = match pose {
        ShotPose::Camera(_) => 1.0e3,
        ShotPose::Path { .. } => (last + 1) as f32 / PATH_HZ,
    };
    Ok(Streamed {
        session,
        scene,
        now,
        camera: cams[last],
    })
}

/// The frame parameters a shot of `s` uses.
pub fn frame_params(s: &Streamed, lens: Lens, wireframe: bool, background: [u8; 3]) -> FrameParams {
    FrameParams {
        wireframe,
        background: rgb8(background),
        ..FrameParams::offscreen(&s.session, s.camera, lens, s.now)
    }
}

/// Draws `s` offscreen with `gpu` and returns the image.
pub fn draw(
    gpu: &Gpu,
    s: &mut Streamed,
    params: &FrameParams,
) -> Result<image::RgbaImage, RenderError> {
    let target = Offscreen::new(gpu, params.lens.width, params.lens.height);
    let mut renderer = StreamRenderer::new(gpu, super::offscreen::FORMAT, &mut s.scene);
    renderer.render(gpu, &target.view, params);
    target.read(gpu)
}

/// Takes the shot: streams, draws, returns the image and what was drawn.
pub async fn shot(opts: &ShotOptions) -> Result<(image::RgbaImage, ShotReport), ShotError> {
    let gpu = Gpu::headless()?;
    let lens = opts.session.lens;
    let mut s = stream_to(opts.session.clone(), opts.pose).await?;
    let mut lens = lens;
    if let Some((c, fov)) = opts.look_from {
        s.camera = c;
        lens.fov_y_deg = fov.unwrap_or(lens.fov_y_deg);
    }
    let params = FrameParams {
        morph: opts.morph,
        dropped_only: opts.dropped_only,
        ..frame_params(&s, lens, opts.wireframe, opts.background)
    };
    let img = draw(&gpu, &mut s, &params)?;
    let ground = {
        let e = s.camera.eye;
        super::shot_check::ground_at(s.session.url(), s.session.terrain(), e.x, e.y).await?
    };
    let warnings = super::shot_check::warnings(
        s.session.terrain(),
        &s.camera,
        &lens,
        ground,
        super::shot_check::coverage(&img, opts.background),
    );
    let c = s.session.counters();
    let report = ShotReport {
        adapter: gpu.describe(),
        size: (lens.width, lens.height),
        triangles: match &s.scene {
            StreamScene::Tiles(t) => t.triangles(opts.dropped_only),
            StreamScene::Vertex(_) => s.session.triangle_count(),
        },
        active: s.session.active_count(),
        deltas: c.deltas,
        bytes: c.bytes_in,
        warnings,
    };
    s.session.close().await;
    Ok((img, report))
}

/// Writes `img` as an RGB PNG (its alpha is always opaque) at the best compression, so that
/// wireframe screenshots stay small.
pub fn save_png(img: image::RgbaImage, path: &std::path::Path) -> image::ImageResult<()> {
    use image::codecs::png::{CompressionType, FilterType, PngEncoder};
    let file = std::io::BufWriter::new(std::fs::File::create(path)?);
    let enc = PngEncoder::new_with_quality(file, CompressionType::Best, FilterType::Adaptive);
    image::DynamicImage::ImageRgba8(img)
        .into_rgb8()
        .write_with_encoder(enc)
}

/// Parses `WxH` (each 16 to 8192 pixels).
pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("size {s:?} is not WxH, e.g. 1280x720"))?;
    let dim = |v: &str| -> Result<u32, String> {
        let n: u32 = v
            .trim()
            .parse()
            .map_err(|_| format!("size {s:?}: {v:?} is not a whole number"))?;
        if (16..=8192).contains(&n) {
            Ok(n)
        } else {
            Err(format!("size {s:?}: each side must be 16 to 8192 pixels"))
        }
    };
    Ok((dim(w)?, dim(h)?))
}

pub use relief_proto::view::parse_camera;

/// Parses `x,y,z,yaw,pitch[,fov]`: a camera as [`parse_camera`] reads it, and a vertical field
/// of view in degrees (1 to 120).
pub fn parse_look(s: &str) -> Result<(Camera, Option<f32>), String> {
    let parts: Vec<&str> = s.split(',').collect();
    if parts.len() != 6 {
        return parse_camera(s).map(|c| (c, None));
    }
    let cam = parse_camera(&parts[..5].join(","))?;
    match parts[5].trim().parse::<f32>() {
        Ok(f) if (1.0..=120.0).contains(&f) => Ok((cam, Some(f))),
        _ => Err(format!("{s:?}: the field of view must be 1 to 120 degrees")),
    }
}

/// Parses a colour: `#rrggbb` or `r,g,b` (0-255).
pub fn parse_colour(s: &str) -> Result<[u8; 3], String> {
    let bad = || format!("colour {s:?} is not #rrggbb or r,g,b");
    if let Some(hex) = s.strip_prefix('#') {
        if hex.len() != 6 {
            return Err(bad());
        }
        let c = |i: usize| u8::from_str_radix(&hex[i..i + 2], 16).map_err(|_| bad());
        return Ok([c(0)?, c(2)?, c(4)?]);
    }
    let v: Vec<u8> = s
        .split(',')
        .map(|p| p.trim().parse::<u8>())
        .collect::<Result<_, _>>()
        .map_err(|_| bad())?;
    v.try_into().map_err(|_| bad())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_sizes_cameras_and_colours() {
        assert_eq!(parse_size("1280x720"), Ok((1280, 720)));
        assert!(parse_size("1280").is_err());
        assert!(parse_size("0x720").is_err());
        assert!(parse_size("99999x720").is_err());
        let c = parse_camera("100,200,3000,90,-30").unwrap();
        assert_eq!(c.eye, glam::Vec3::new(100.0, 200.0, 3000.0));
        assert!((c.yaw - std::f32::consts::FRAC_PI_2).abs() < 1e-6);
        assert!(parse_camera("1,2,3,4").is_err());
        assert!(parse_camera("1,2,3,4,95").is_err());
        assert!(parse_camera("1,2,nan,4,5").is_err());
        assert_eq!(parse_look("1,2,3,4,5").unwrap().1, None);
        assert_eq!(parse_look("1,2,3,4,5,10").unwrap().1, Some(10.0));
        assert!(parse_look("1,2,3,4,5,0").is_err());
        assert_eq!(parse_colour("#ff00fe"), Ok([255, 0, 254]));
        assert_eq!(parse_colour("1, 2,3"), Ok([1, 2, 3]));
        assert!(parse_colour("#ff00").is_err());
        assert!(parse_colour("1,2,300").is_err());
    }
}
