//! `GET /v1/stream`: the WebSocket upgrade. Admission (readiness, session limits) happens after
//! the upgrade so that a refused client gets a close frame with a reason it can read, which a
//! browser's WebSocket API cannot do with an HTTP status.

use super::limits::Refusal;
use super::listen::ConnSlot;
use super::session;
use super::stall::WriteStall;
use super::state::AppState;
use axum::Extension;
use axum::extract::ws::{CloseFrame, Message, WebSocket, WebSocketUpgrade};
use axum::extract::{ConnectInfo, State};
use axum::response::Response;
use relief_proto::close::CloseReason;
use std::net::SocketAddr;
use std::sync::Arc;

/// Upgrades the connection and runs the session.
pub async fn upgrade(
    State(state): State<Arc<AppState>>,
    ConnectInfo(peer): ConnectInfo<SocketAddr>,
    slot: Option<Extension<ConnSlot>>,
    stall: Option<Extension<WriteStall>>,
    ws: WebSocketUpgrade,
) -> Response {
    // The session bounds its own sends (a slow reader is closed with 4007): the connection's
    // write timeout is for HTTP responses.
    if let Some(Extension(s)) = &stall {
        s.disable();
    }
    let max = state.limits.max_message_bytes as usize;
    // Client messages are small: a 4 KiB read buffer instead of the default 128 KiB is most
    // of a session's memory saved (larger messages still assemble, up to the limit).
    ws.max_message_size(max)
        .max_frame_size(max)
        .read_buffer_size(4096)
        .on_upgrade(move |socket| async move {
            // The connection's slot stays taken for as long as the session runs.
            let _slot = slot;
            admit(socket, state, peer).await
        })
}

async fn admit(mut socket: WebSocket, state: Arc<AppState>, peer: SocketAddr) {
    let refusal = if state.terrain().is_none() {
        Some((
            CloseReason::NotReady,
            "the terrain is not ready yet".to_string(),
        ))
    } else if *state.draining.borrow() {
        Some((
            CloseReason::Draining,
            "the server is shutting down".to_string(),
        ))
    } else {
        match state.sessions.admit(peer.ip()) {
            Ok(permit) => {
                session::run(socket, state, peer, permit).await;
                return;
            }
            Err(Refusal::ServerFull) => Some((
                CloseReason::ServerFull,
                format!(
                    "the server holds its maximum of {} sessions",
                    state.limits.max_sessions
                ),
            )),
            Err(Refusal::PerAddress) => Some((
                CloseReason::TooManyFromAddress,
                format!(
                    "{} already holds the maximum of {} sessions per address",
                    peer.ip(),
                    state.limits.max_sessions_per_ip
                ),
            )),
        }
    };
    if let Some((reason, detail)) = refusal {
        state.metrics.close(reason);
        tracing::info!(%peer, "refused a session: {}", reason.text(&detail));
        let _ = socket
            .send(Message::Close(Some(CloseFrame {
                code: reason.code(),
                reason: reason.text(&detail).into(),
            })))
            .await;
    }
}
