//! `relief-client view`: a window over the streamed terrain.
//!
//! - [`controls`]: the fly camera (keys, mouse drags, follow-ground).
//! - [`net`]: the network thread: the session, its deltas applied to the shared scene,
//!   reconnects with a message while the server is away.
//! - [`app`]: the winit window: surface, renderer, input, the title line as HUD.
//!
//! The window thread only reads the shared scene, uploads its dirty pages and draws; all network
//! work and delta application happen on the network thread, so a slow delta never stalls a
//! frame for longer than the upload of what it changed.

pub mod app;
pub mod controls;
pub mod net;

use crate::session::SessionConfig;
use std::time::Duration;

/// How the viewer runs.
#[derive(Clone, Debug)]
pub struct ViewerOptions {
    /// The session; its lens's size is the window's first size.
    pub session: SessionConfig,
    /// Poses sent per second.
    pub rate_hz: f64,
    /// Start with the wireframe overlay.
    pub wireframe: bool,
    /// Close by itself after this long.
    pub exit_after: Option<Duration>,
    /// Where the geomorph is evaluated.
    pub morph: crate::render::MorphStage,
    /// Tile stream: draw the dropped crack patches alone (a diagnostic).
    pub dropped_only: bool,
}

/// Why the viewer could not run.
#[derive(Debug, thiserror::Error)]
pub enum ViewerError {
    /// No display, or the window system refused.
    #[error("cannot open a window: {0} (is there a display? try `relief-client shot` headless)")]
    Window(String),
    /// The GPU side failed.
    #[error(transparent)]
    Render(#[from] crate::render::RenderError),
}

/// Opens the window and runs until it is closed.
pub fn run(opts: ViewerOptions) -> Result<(), ViewerError> {
    app::run(opts)
}
