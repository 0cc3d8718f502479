//! Either stream's scene and renderer behind one face, so that `shot`, `render-bench` and
//! `view` draw a vertex session ([`Follower`] and [`Renderer`]) or a tile session
//! ([`TileScene`] and [`TileRenderer`]) with the same calls.

use super::follow::Follower;
use super::frame::FrameParams;
use super::gpu::Gpu;
use super::renderer::Renderer;
use super::tile_scene::TileScene;
use super::tiles::TileRenderer;
use crate::session::Session;

/// A session's scene, CPU side.
pub enum StreamScene {
    /// The vertex stream's node and cell records.
    Vertex(Follower),
    /// The tile stream's active tiles.
    Tiles(TileScene),
}

impl StreamScene {
    /// The scene of what `session` holds now. A vertex session must record its changes
    /// (`SessionConfig::record_changes`).
    pub fn new(session: &mut Session) -> StreamScene {
        if session.is_tiles() {
            StreamScene::Tiles(TileScene::new(session))
        } else {
            StreamScene::Vertex(Follower::new(session))
        }
    }

    /// Follows what `session` changed since the last call (new splits, or tiles arrived by a
    /// split, stamped with `now`);
    /// returns the splits and merges applied, or the tiles built.
    pub fn sync(&mut self, session: &mut Session, now: f32) -> usize {
        match self {
            StreamScene::Vertex(f) if !session.is_tiles() => f.sync(session, now),
            StreamScene::Tiles(t) if session.is_tiles() => t.sync(session, now),
            _ => {
                *self = StreamScene::new(session);
                0
            }
        }
    }
}

/// The GPU side of either scene.
enum Inner {
    /// Vertex stream.
    Vertex(Renderer),
    /// Tile stream.
    Tiles(TileRenderer),
}

/// Draws a [`StreamScene`].
pub struct StreamRenderer {
    /// The target format, to remake the inner renderer for a scene of the other kind.
    format: wgpu::TextureFormat,
    /// The renderer of the scene's kind.
    inner: Inner,
}

impl StreamRenderer {
    /// A renderer drawing into `format` targets, with `scene` uploaded.
    pub fn new(gpu: &Gpu, format: wgpu::TextureFormat, scene: &mut StreamScene) -> Self {
        let inner = match scene {
            StreamScene::Vertex(f) => Inner::Vertex(Renderer::new(gpu, format, &mut f.scene)),
            StreamScene::Tiles(t) => Inner::Tiles(TileRenderer::new(gpu, format, t)),
        };
        StreamRenderer { format, inner }
    }

    /// Uploads what `scene` changed; returns the bytes sent.
    pub fn upload(&mut self, gpu: &Gpu, scene: &mut StreamScene) -> usize {
        match (&mut self.inner, &mut *scene) {
            (Inner::Vertex(r), StreamScene::Vertex(f)) => r.upload(gpu, &mut f.scene),
            (Inner::Tiles(r), StreamScene::Tiles(t)) => r.upload(gpu, t),
            _ => {
                *self = StreamRenderer::new(gpu, self.format, scene);
                0
            }
        }
    }

    /// Draws into `target` (of the lens's size).
    pub fn render(&mut self, gpu: &Gpu, target: &wgpu::TextureView, f: &FrameParams) {
        match &mut self.inner {
            Inner::Vertex(r) => r.render(gpu, target, f),
            Inner::Tiles(r) => r.render(gpu, target, f),
        }
    }

    /// The vertex renderer, if that is what this draws (for tests that read back geomorphs).
    pub fn vertex(&mut self) -> Option<&mut Renderer> {
        match &mut self.inner {
            Inner::Vertex(r) => Some(r),
            Inner::Tiles(_) => None,
        }
    }
}
