//! A streaming session with a Relief server (protocol: `docs/protocol.md`).
//!
//! [`Session`] connects, says hello, sends poses, and applies each delta: for the vertex stream
//! to a [`Mirror`] of the cut and to the [`FanMesh`] built from it, for the tile stream to a
//! [`TileMirror`](relief_proto::tile::mirror::TileMirror) of the held tiles
//! (`session/stream.rs`; the rest of the flow is shared). It checks every delta's digest and
//! acknowledges it.
//! When the connection drops, or the server asks it to reconnect (a drain), it reconnects with
//! exponential backoff and resumes from a snapshot of its own cut, then sends its latest pose
//! again: the caller sees one continuous stream. A digest mismatch is counted as a desync and
//! repaired by starting again from scratch.
//!
//! Its configuration, errors, counters and link state are in `session/types.rs`; dialling,
//! the handshake, backoff and the reconnect in `session/connect.rs`.

use connect::{Ws, idle_of, tile_params};
pub(crate) use connect::{closed, decode, open_query};
use futures_util::{SinkExt, StreamExt};
use relief_proto::codec;
use relief_proto::mesh::FanMesh;
use relief_proto::mirror::Mirror;
use relief_proto::msg::{ClientMsg, ServerMsg, TerrainInfo, WireCamera};
use relief_proto::terrain::TerrainGeometry;
use relief_proto::view::{Camera, Lens};
use std::time::{Duration, Instant};
use tokio_tungstenite::tungstenite::Message;

mod connect;
pub(crate) use connect::Ws as Socket;
mod stream;
mod types;
pub use relief_proto::mirror::Change;
pub use stream::{StreamState, TileState, VertexState};
pub use types::{Applied, ClientError, Counters, Link, SessionConfig};

/// A live session: the connection and the mirrored state of its stream.
pub struct Session {
    /// Where and how to connect.
    config: SessionConfig,
    /// The connection; `None` between a drop and the reconnect.
    ws: Option<Ws>,
    /// The terrain, from the first welcome.
    info: TerrainInfo,
    /// Its geometry.
    geom: TerrainGeometry,
    /// The mirrored cut and its fans, or the held tiles.
    stream: StreamState,
    /// The last pose sent and its sequence number, sent again after a reconnect.
    last_pose: Option<(u64, Camera)>,
    /// The next pose sequence number; grows across reconnects.
    next_pose_seq: u64,
    /// The server's window of unacknowledged deltas.
    max_in_flight: u32,
    /// The server's idle timeout: the session pings after half of it without traffic.
    idle_timeout: Duration,
    /// Counters.
    counters: Counters,
    /// Bumped whenever the mirror starts again from scratch, so that a renderer rebuilds.
    generation: u64,
    /// Connected or not, shared.
    link: std::sync::Arc<Link>,
    /// How long each reconnection took, from noticing the drop to the new welcome,
    /// milliseconds.
    gaps_ms: Vec<f64>,
}

impl Session {
    /// Connects and opens a session from the root (retrying within the reconnect deadline).
    pub async fn connect(config: SessionConfig) -> Result<Session, ClientError> {
        let link = std::sync::Arc::new(Link::default());
        let (ws, welcome, bytes) = Self::establish(&config, None, &link).await?;
        let info = welcome.terrain.clone();
        let geom = info
            .geometry()
            .map_err(|e| ClientError::Protocol(format!("bad terrain in welcome: {e}")))?;
        let stream = StreamState::fresh(&welcome, &geom, tile_params(&config), config.mesh)?;
        Ok(Session {
            config,
            ws: Some(ws),
            info,
            geom,
            stream,
            last_pose: None,
            next_pose_seq: 1,
            max_in_flight: welcome.max_in_flight,
            idle_timeout: idle_of(&welcome),
            counters: Counters {
                bytes_in: bytes as u64,
                ..Counters::default()
            },
            generation: 0,
            gaps_ms: Vec::new(),
            link,
        })
    }

    async fn send(&mut self, msg: &ClientMsg) -> bool {
        let Some(ws) = self.ws.as_mut() else {
            return false;
        };
        ws.send(Message::Binary(codec::encode(msg).into()))
            .await
            .is_ok()
    }

    /// Sends a camera pose; returns its sequence number. Reconnects if the connection is gone.
    pub async fn send_pose(&mut self, camera: Camera) -> Result<u64, ClientError> {
        let seq = self.next_pose_seq;
        self.next_pose_seq += 1;
        self.last_pose = Some((seq, camera));
        let msg = ClientMsg::Pose {
            seq,
            camera: WireCamera::from(camera),
        };
        if !self.send(&msg).await {
            // The reconnect sends the pose again.
            Box::pin(self.reconnect(false)).await?;
        }
        Ok(seq)
    }

    /// Waits for the next delta, applies it to the mirror and mesh, checks its digest and
    /// acknowledges it. Drops, drains and desyncs are handled here: the wait goes on.
    pub async fn next_delta(&mut self) -> Result<Applied, ClientError> {
        loop {
            let Some(ws) = self.ws.as_mut() else {
                self.reconnect(false).await?;
                continue;
            };
            // Keep a session at rest alive: ping after half the server's idle timeout.
            let next = match tokio::time::timeout(self.idle_timeout / 2, ws.next()).await {
                Ok(n) => n,
                Err(_) => {
                    if ws.send(Message::Ping(Vec::new().into())).await.is_err() {
                        self.reconnect(false).await?;
                    }
                    continue;
                }
            };
            let msg = match next {
                Some(Ok(Message::Binary(b))) => b,
                Some(Ok(Message::Close(frame))) => {
                    let (code, text) = frame
                        .map(|f| (u16::from(f.code), f.reason.to_string()))
                        .unwrap_or((1005, String::new()));
                    closed(code, text)?;
                    self.reconnect(false).await?;
                    continue;
                }
                Some(Ok(_)) => continue,
                Some(Err(_)) | None => {
                    self.reconnect(false).await?;
                    continue;
                }
            };
            let bytes = msg.len();
            self.counters.bytes_in += bytes as u64;
            let d = match decode(&msg)? {
                ServerMsg::Delta(d) => d,
                ServerMsg::Reconnect { after_ms } => {
                    tokio::time::sleep(Duration::from_millis(u64::from(after_ms))).await;
                    self.reconnect(false).await?;
                    continue;
                }
                ServerMsg::Welcome(_) => {
                    return Err(ClientError::Protocol("a second welcome".into()));
                }
                ServerMsg::Answers(_) | ServerMsg::Refused(_) => {
                    return Err(ClientError::Protocol(
                        "query answers on a stream session".into(),
                    ));
                }
            };
            let started = Instant::now();
            let applied = self.stream.apply(
                &self.geom,
                &d.delta,
                self.config.mesh,
                self.config.record_changes,
            );
            let applied = match applied {
                Ok(a) => a,
                Err(e) => {
                    self.counters.desyncs += 1;
                    tracing::warn!("desync after delta {} ({e}): starting again", d.delta.seq);
                    self.reconnect(true).await?;
                    continue;
                }
            };
            let apply_us = started.elapsed().as_secs_f64() * 1e6;
            self.counters.deltas += 1;
            self.counters.tiles_sent += applied.tiles_sent as u64;
            self.counters.tiles_from_cache += applied.tiles_cached as u64;
            self.send(&ClientMsg::Ack { seq: d.delta.seq }).await;
            return Ok(Applied {
                seq: d.delta.seq,
                pose_seq: d.pose_seq,
                complete: d.complete,
                bytes,
                changes: applied.changes,
                tiles_sent: applied.tiles_sent,
                tiles_cached: applied.tiles_cached,
                apply_us,
            });
        }
    }

    /// Waits until a complete delta reflects pose `seq` (or a newer one).
    pub async fn wait_for_pose(&mut self, seq: u64) -> Result<Vec<Applied>, ClientError> {
        let mut got = Vec::new();
        loop {
            let a = self.next_delta().await?;
            got.push(a);
            if a.pose_seq >= seq && a.complete {
                return Ok(got);
            }
        }
    }

    /// Drops the connection without a close handshake, as a network failure would (for tests of
    /// resume). The next call reconnects.
    pub fn drop_connection(&mut self) {
        self.ws = None;
    }

    /// Closes the session politely.
    pub async fn close(mut self) {
        if let Some(ws) = self.ws.as_mut() {
            let _ = ws.close(None).await;
        }
    }

    /// The session's connection state, shared (it changes while the session reconnects).
    pub fn link(&self) -> std::sync::Arc<Link> {
        self.link.clone()
    }

    /// The stream's URL.
    pub fn url(&self) -> &str {
        &self.config.url
    }

    /// The session's lens (fixed by the hello).
    pub fn lens(&self) -> Lens {
        self.config.lens
    }

    /// The session's screen-space error threshold, pixels.
    pub fn tau(&self) -> f32 {
        self.config.tau
    }

    /// The terrain.
    pub fn terrain(&self) -> &TerrainInfo {
        &self.info
    }

    /// The terrain's geometry.
    pub fn geometry(&self) -> &TerrainGeometry {
        &self.geom
    }

    /// The stream's mirrored state.
    pub fn stream(&self) -> &StreamState {
        &self.stream
    }

    /// The tile stream's state (`None` for a vertex session).
    pub fn tiles(&self) -> Option<&TileState> {
        match &self.stream {
            StreamState::Tiles(t) => Some(t),
            StreamState::Vertex(_) => None,
        }
    }

    /// Whether the session receives the tile stream.
    pub fn is_tiles(&self) -> bool {
        self.tiles().is_some()
    }

    /// Triangles drawn: the fans, or the active tiles with their patches or skirts.
    pub fn triangle_count(&self) -> usize {
        self.stream.triangle_count()
    }

    /// Active nodes of the cut, or active tiles.
    pub fn active_count(&self) -> u64 {
        self.stream.active_count()
    }

    fn vertex(&self) -> &VertexState {
        match &self.stream {
            StreamState::Vertex(v) => v,
            StreamState::Tiles(_) => panic!("a tile session has no vertex mirror or fans"),
        }
    }

    /// The mirrored cut with heights.
    ///
    /// # Panics
    /// On a tile session ([`Session::tiles`] holds its mirror).
    pub fn mirror(&self) -> &Mirror {
        &self.vertex().mirror
    }

    /// The mesh of the mirrored cut.
    ///
    /// # Panics
    /// On a tile session.
    pub fn mesh(&self) -> &FanMesh {
        &self.vertex().mesh
    }

    /// The geometry, the mirror and the mesh at once, for renderers that follow the mesh's
    /// dirty cells while reading the mirror.
    ///
    /// # Panics
    /// On a tile session.
    pub fn parts_mut(&mut self) -> (&TerrainGeometry, &Mirror, &mut FanMesh) {
        match &mut self.stream {
            StreamState::Vertex(v) => (&self.geom, &v.mirror, &mut v.mesh),
            StreamState::Tiles(_) => panic!("a tile session has no vertex mirror or fans"),
        }
    }

    /// Mutable mesh access, for renderers that take its dirty cells.
    ///
    /// # Panics
    /// On a tile session.
    pub fn mesh_mut(&mut self) -> &mut FanMesh {
        self.parts_mut().2
    }

    /// The server's window of unacknowledged deltas.
    pub fn max_in_flight(&self) -> u32 {
        self.max_in_flight
    }

    /// The splits and merges applied since the last call, in order (empty unless the config
    /// asks to record them, and for tile sessions).
    pub fn take_changes(&mut self) -> Vec<Change> {
        match &mut self.stream {
            StreamState::Vertex(v) => std::mem::take(&mut v.changes),
            StreamState::Tiles(_) => Vec::new(),
        }
    }

    /// How many times the mirror has started again from scratch: when this moves, what
    /// [`Session::take_changes`] returned before no longer applies; rebuild from the mirror.
    pub fn generation(&self) -> u64 {
        self.generation
    }

    /// Counters over the session's life.
    pub fn counters(&self) -> Counters {
        self.counters
    }

    /// How long each reconnection took, from noticing the drop to the new welcome,
    /// milliseconds, in order.
    pub fn reconnect_gaps_ms(&self) -> &[f64] {
        &self.gaps_ms
    }

    /// Digest of the mirrored cut (vertex stream) or active tile set (tile stream).
    pub fn digest(&self) -> u64 {
        self.stream.digest()
    }
}
