//! What one frame is drawn with, and the uniform block the shaders read it from (`Frame` in
//! `terrain.wgsl`): camera-relative view-projection, the view's planes and focal length for
//! the screen error, the geomorph's parameters, shading.

use crate::session::Session;
use glam::{Mat4, Vec3, Vec4};
use relief_proto::mesh::MorphRule;
use relief_proto::view::{Camera, Lens, ViewState};

/// Bytes of the uniform block (see `Frame` in `terrain.wgsl`).
pub(crate) const FRAME_BYTES: usize = 60 * 4;

/// Where the geomorph is evaluated. Both run the same WGSL function and draw the same image
/// (the golden-image test checks both).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum MorphStage {
    /// Once per node in a compute pass before the draw; the vertex shader reads the result.
    /// Each node is shared by about six triangle corners, so this does less work on big cuts
    /// (lavapipe, 1280x720, fuji_srtm3's standard path: 214 against 343 ms a frame; on the
    /// embedded crop 30 against 33 ms).
    #[default]
    Compute,
    /// In the vertex shader, per triangle corner.
    Vertex,
}

/// What one frame is drawn with.
#[derive(Clone, Copy, Debug)]
pub struct FrameParams {
    /// The camera.
    pub camera: Camera,
    /// The lens; its width and height are the target's.
    pub lens: Lens,
    /// The geomorph.
    pub rule: MorphRule,
    /// Now, seconds on the clock the scene's split times use.
    pub now: f32,
    /// Draw triangle edges over the shading.
    pub wireframe: bool,
    /// The terrain's lowest and highest heights, metres (in the uniform block for shaders that
    /// want a relative ramp; the default hypsometric ramp in `shade.wgsl` is in absolute metres).
    pub z_range: (f32, f32),
    /// Encode sRGB in the shader (for targets that do not encode it themselves).
    pub encode_srgb: bool,
    /// Clear colour, 0..1 as stored in the target.
    pub background: [f64; 3],
    /// Distance at which the haze reaches about two thirds of its strength, metres.
    pub fog_distance: f32,
    /// Where the geomorph is evaluated.
    pub morph: MorphStage,
    /// Tile stream only: leave out the raised crack patches and draw the dropped ones alone
    /// (paper 001's original rule), to see whether raised cracks show. A diagnostic.
    pub dropped_only: bool,
}

impl FrameParams {
    /// An offscreen frame of `session`'s terrain (either stream) from `camera` through `lens`
    /// at `now`: the session's tau with the default geomorph (in a compute pass), no wireframe, sRGB encoded
    /// in the shader, the default sky, haze scaled to the terrain.
    pub fn offscreen(session: &Session, camera: Camera, lens: Lens, now: f32) -> FrameParams {
        FrameParams {
            camera,
            lens,
            rule: MorphRule::new(session.tau()),
            now,
            wireframe: false,
            z_range: super::height_range(session.terrain()),
            encode_srgb: true,
            background: rgb8(SKY_RGB8),
            fog_distance: super::fog_distance(session.geometry()),
            morph: MorphStage::default(),
            dropped_only: false,
        }
    }
}

/// The default sky, 8-bit sRGB (`--background`'s default, `#9eb3cc`).
pub const SKY_RGB8: [u8; 3] = [158, 179, 204];

/// An 8-bit colour as a clear colour (0..1 as stored in the target).
pub fn rgb8(c: [u8; 3]) -> [f64; 3] {
    c.map(|v| f64::from(v) / 255.0)
}

/// Right-handed perspective with an infinite far plane and reversed depth (1 at the near plane,
/// 0 at infinity), for wgpu's 0..1 clip depth: the best depth precision far away.
fn projection(fov_y: f32, aspect: f32, near: f32) -> Mat4 {
    let f = 1.0 / (fov_y / 2.0).tan();
    Mat4::from_cols(
        Vec4::new(f / aspect, 0.0, 0.0, 0.0),
        Vec4::new(0.0, f, 0.0, 0.0),
        Vec4::new(0.0, 0.0, 0.0, -1.0),
        Vec4::new(0.0, 0.0, near, 0.0),
    )
}

/// View rotation from the eye looking along `dir` with z up (the eye is the origin: positions
/// reach the shader relative to it).
fn look_to(dir: Vec3) -> Mat4 {
    let f = dir.normalize();
    let s = f.cross(Vec3::Z).normalize_or(Vec3::X);
    let u = s.cross(f);
    Mat4::from_cols(
        Vec4::new(s.x, u.x, -f.x, 0.0),
        Vec4::new(s.y, u.y, -f.y, 0.0),
        Vec4::new(s.z, u.z, -f.z, 0.0),
        Vec4::W,
    )
}

/// The uniform block of `Frame` in `terrain.wgsl`.
pub(crate) fn frame_block(f: &FrameParams) -> [f32; FRAME_BYTES / 4] {
    let view = ViewState::new(&f.camera, &f.lens);
    let forward = f.camera.forward();
    let aspect = f.lens.width.max(1) as f32 / f.lens.height.max(1) as f32;
    let proj = projection(f.lens.fov_y_deg.to_radians(), aspect, f.lens.near);
    let look = look_to(forward);
    let mut b = [0.0f32; FRAME_BYTES / 4];
    b[0..16].copy_from_slice(&(proj * look).to_cols_array());
    b[16..20].copy_from_slice(&[f.camera.eye.x, f.camera.eye.y, f.camera.eye.z, f.now]);
    b[20..24].copy_from_slice(&[forward.x, forward.y, forward.z, view.focal()]);
    for (i, n) in view.planes().iter().enumerate() {
        let offset = if i == 4 { view.near() } else { 0.0 };
        b[24 + 4 * i..28 + 4 * i].copy_from_slice(&[n.x, n.y, n.z, offset]);
    }
    b[44..48].copy_from_slice(&[f.rule.tau, f.rule.lambda, f.rule.duration, view.off_axis()]);
    b[48..52].copy_from_slice(&[
        view.near(),
        f.z_range.0,
        f.z_range.1,
        if f.wireframe { 1.0 } else { 0.0 },
    ]);
    let sun = Vec3::new(-0.55, 0.45, 0.70).normalize();
    let srgb = if f.encode_srgb { 1.0 } else { 0.0 };
    b[52..56].copy_from_slice(&[sun.x, sun.y, sun.z, srgb]);
    b[56..60].copy_from_slice(&[0.62, 0.70, 0.80, f.fog_distance.max(1.0)]);
    b
}
