//! What a session is configured with and reports: its configuration, errors, per-delta and
//! lifetime counters, and its shared link state.

use relief_proto::msg::StreamKind;
use relief_proto::view::Lens;
use std::time::Duration;

/// How a session connects and what it asks for.
#[derive(Clone, Debug)]
pub struct SessionConfig {
    /// The stream's URL, e.g. `ws://127.0.0.1:8080/v1/stream`.
    pub url: String,
    /// The viewport.
    pub lens: Lens,
    /// Screen-space error threshold, pixels.
    pub tau: f32,
    /// Bandwidth budget, bytes per second; `None` for unlimited.
    pub budget: Option<u32>,
    /// Which stream the hello asks for: the vertex stream, or tiles with a cache limit and a
    /// crack mode.
    pub stream: StreamKind,
    /// First wait before reconnecting; doubles on each failed attempt.
    pub backoff_initial: Duration,
    /// Longest wait between attempts.
    pub backoff_max: Duration,
    /// Give up after this long without a connection.
    pub reconnect_deadline: Duration,
    /// Keep the fan mesh up to date (a viewer needs it; a load generator may skip it, and
    /// [`Session::mesh`] then stays at the root's). A tile session without it keeps a light
    /// tile mirror: every tile and digest is decoded and checked, but no tile data is kept
    /// (nothing to draw, no triangle count, no heights), so thousands of sessions fit in memory.
    pub mesh: bool,
    /// Record every split and merge for [`Session::take_changes`] (a renderer mirrors them into
    /// GPU buffers; nobody else should pay for the list).
    pub record_changes: bool,
}

impl SessionConfig {
    /// Defaults for `url`: the vertex stream, the standard lens, tau 1, no budget, backoff 50 ms
    /// to 2 s, 30 s deadline.
    pub fn new(url: &str) -> SessionConfig {
        SessionConfig {
            url: url.to_string(),
            lens: Lens::STANDARD,
            tau: 1.0,
            budget: None,
            stream: StreamKind::Vertex,
            backoff_initial: Duration::from_millis(50),
            backoff_max: Duration::from_secs(2),
            reconnect_deadline: Duration::from_secs(30),
            mesh: true,
            record_changes: false,
        }
    }
}

/// A session that cannot go on.
#[derive(Debug, thiserror::Error)]
pub enum ClientError {
    /// No connection could be made within the reconnect deadline.
    #[error("cannot connect to {url}: {last}")]
    Connect {
        /// The URL.
        url: String,
        /// The last attempt's error.
        last: String,
    },
    /// The server closed the session for a reason that reconnecting cannot fix.
    #[error("the server closed the session ({code}): {text}")]
    Closed {
        /// The close code.
        code: u16,
        /// The close reason's text.
        text: String,
    },
    /// The server broke the protocol.
    #[error("protocol error: {0}")]
    Protocol(String),
}

/// What one applied delta did.
#[derive(Clone, Copy, Debug)]
pub struct Applied {
    /// The delta's sequence number on its connection.
    pub seq: u64,
    /// The newest pose the delta reflects.
    pub pose_seq: u64,
    /// Whether the cut meets tau for that pose (false while a budget holds splits back).
    pub complete: bool,
    /// Bytes of the message.
    pub bytes: usize,
    /// Merges and splits applied, or tiles removed and added.
    pub changes: usize,
    /// Tiles added with their body (tile stream).
    pub tiles_sent: usize,
    /// Tiles added from the client's cache, without a body (tile stream).
    pub tiles_cached: usize,
    /// Time spent decoding the delta, applying it to the mirror and updating the fans (or
    /// decoding the tiles), microseconds (not waiting for it).
    pub apply_us: f64,
}

/// Counters over the session's life.
#[derive(Clone, Copy, Debug, Default)]
pub struct Counters {
    /// Deltas applied.
    pub deltas: u64,
    /// Bytes of server messages received (welcomes and deltas; payloads, without the
    /// WebSocket framing), as the server's `relief_bytes_out_total` counts them.
    pub bytes_in: u64,
    /// Deltas whose digest did not match the mirror.
    pub desyncs: u64,
    /// Connections made after the first.
    pub reconnects: u64,
    /// Reconnections the server resumed from the snapshot.
    pub resumes: u64,
    /// Tiles received with their body (tile stream).
    pub tiles_sent: u64,
    /// Tiles activated from the client's cache (tile stream).
    pub tiles_from_cache: u64,
}

/// Whether a session is connected, readable from other threads while the session itself is
/// busy reconnecting (a viewer's window shows it).
#[derive(Debug, Default)]
pub struct Link {
    /// Why the session is not connected now; `None` while it is.
    down: std::sync::Mutex<Option<String>>,
}

impl Link {
    /// Why the session is not connected now, or `None` while it is.
    pub fn down(&self) -> Option<String> {
        self.down.lock().map(|d| d.clone()).unwrap_or(None)
    }

    pub(super) fn set(&self, why: Option<String>) {
        if let Ok(mut d) = self.down.lock() {
            *d = why;
        }
    }
}
