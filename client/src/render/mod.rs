//! The wgpu renderer: the vertex stream's cut drawn as the paper's fans with GPU geomorphs
//! (paper 000, sections 3.5-3.6), or the tile stream's tiles with their crack patches or skirts
//! (paper 001), in a window or offscreen.
//!
//! - [`scene`]: node and triangle records in slot pools, kept in step with the mirror one split
//!   or merge at a time; dirty pages for upload. Pure CPU.
//! - [`follow`]: a scene that follows a [`crate::Session`].
//! - [`gpu`]: instance, adapter, device and queue, headless or for a window.
//! - [`frame`]: what a frame is drawn with, and its uniform block.
//! - [`renderer`]: GPU buffers, the geomorph and terrain passes (`terrain.wgsl`).
//! - [`tile_scene`]: the tile stream's active tiles as triangles, following a session. Pure CPU.
//! - [`tiles`]: per-tile GPU buffers and the tile pass (`tiles.wgsl`).
//! - [`stream`]: either stream's scene and renderer behind one face.
//! - `pass`: what both passes share: depth buffer, frame buffer, shading (`shade.wgsl`).
//! - [`offscreen`]: a target without a window, and reading GPU memory back.
//! - [`shot`]: `relief-client shot`: one frame to a PNG.
//! - [`shot_check`]: why a shot shows no terrain (under the ground, looking away, too far).
//! - [`bench`]: `relief-client render-bench`: the client's cost per delta and frame rate.

pub mod bench;
pub mod follow;
pub mod frame;
pub mod gpu;
pub mod offscreen;
mod pass;
pub mod renderer;
pub mod shot;
pub mod shot_check;
pub mod stream;
pub mod tile_scene;
pub mod tiles;

pub use follow::Follower;
pub use frame::{FrameParams, MorphStage};
pub use gpu::{Gpu, RenderError};
pub use offscreen::Offscreen;
pub use relief_proto::mesh::scene::Scene;
pub use renderer::Renderer;
pub use stream::{StreamRenderer, StreamScene};
pub use tile_scene::TileScene;
pub use tiles::TileRenderer;

use crate::session::SessionConfig;
use relief_proto::terrain::TerrainGeometry;
use std::time::Duration;

/// `config` as a renderer needs it: fans kept and changes recorded (vertex stream), and at most 5 s of
/// reconnecting before an error, so that a dead server is reported within seconds.
pub fn renderer_config(config: SessionConfig) -> SessionConfig {
    SessionConfig {
        mesh: true,
        record_changes: true,
        reconnect_deadline: config.reconnect_deadline.min(Duration::from_secs(5)),
        ..config
    }
}

/// The fog distance that suits a terrain: its larger side.
pub fn fog_distance(geom: &TerrainGeometry) -> f32 {
    let w = geom.shape.width() as f32 * geom.frame.dx;
    let h = geom.shape.height() as f32 * geom.frame.dy;
    w.max(h)
}

/// The terrain's lowest to highest heights, metres.
pub fn height_range(info: &relief_proto::msg::TerrainInfo) -> (f32, f32) {
    (info.height_range[0], info.height_range[1])
}
