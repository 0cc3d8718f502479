//! One message in or out of a session: the idle timeout on both, decoding with the size limit,
//! and the close reason for each way it can fail.

use crate::serve::state::{AppState, SessionStats};
use axum::extract::ws::Message;
use futures_util::{Sink, SinkExt, Stream, StreamExt};
use relief_proto::close::CloseReason;
use relief_proto::codec;
use relief_proto::msg::{ClientMsg, ServerMsg};
use std::error::Error as StdError;
use std::sync::atomic::Ordering::Relaxed;

/// How a session ended.
pub(super) type Ended = Result<(), (CloseReason, String)>;

pub(super) fn fail<T>(
    reason: CloseReason,
    detail: impl Into<String>,
) -> Result<T, (CloseReason, String)> {
    Err((reason, detail.into()))
}

/// The close for a socket error the client caused: a message over the size limit (1009), a
/// text frame that is not UTF-8 (1007), or a frame that breaks RFC 6455 (1002). `None` for a
/// connection that is simply gone (reset, or ended without a close frame), which nobody is left
/// to tell.
fn client_fault(e: &(dyn StdError + 'static), state: &AppState) -> Option<(CloseReason, String)> {
    use tungstenite::Error as W;
    let mut cur = Some(e);
    while let Some(err) = cur {
        if let Some(t) = err.downcast_ref::<W>() {
            return match t {
                W::Capacity(_) => Some((
                    CloseReason::TooLarge,
                    format!(
                        "message exceeds the limit of {} bytes",
                        state.limits.max_message_bytes
                    ),
                )),
                W::Utf8(_) => Some((
                    CloseReason::Malformed,
                    "a text frame is not valid UTF-8".into(),
                )),
                // A peer whose connection ends without a close frame has gone, as one whose
                // socket reset has: a network failure (`docs/protocol.md`, section 10), not a
                // frame that breaks RFC 6455.
                W::Protocol(tungstenite::error::ProtocolError::ResetWithoutClosingHandshake) => {
                    None
                }
                W::Protocol(p) => Some((CloseReason::Protocol, format!("{p}"))),
                _ => None,
            };
        }
        cur = err.source();
    }
    None
}

/// Receives the next message within the idle timeout. `None`: the client closed.
pub(super) async fn receive<S, E>(
    socket: &mut S,
    state: &AppState,
    stats: &SessionStats,
) -> Result<Option<ClientMsg>, (CloseReason, String)>
where
    S: Stream<Item = Result<Message, E>> + Unpin,
    E: StdError + 'static,
{
    loop {
        let next = tokio::time::timeout(state.limits.idle_timeout, socket.next()).await;
        let msg = match next {
            Err(_) => {
                return fail(
                    CloseReason::Idle,
                    format!(
                        "no message for {:.0} s",
                        state.limits.idle_timeout.as_secs_f64()
                    ),
                );
            }
            Ok(None) => return Ok(None),
            Ok(Some(Err(e))) => {
                return match client_fault(&e, state) {
                    Some(why) => Err(why),
                    None => Ok(None),
                };
            }
            Ok(Some(Ok(m))) => m,
        };
        match msg {
            Message::Binary(bytes) => {
                state
                    .metrics
                    .bytes_in_total
                    .fetch_add(bytes.len() as u64, Relaxed);
                stats.largest_in.fetch_max(bytes.len() as u64, Relaxed);
                return match codec::decode::<ClientMsg>(
                    &bytes,
                    state.limits.max_message_bytes as usize,
                ) {
                    Ok(m) => Ok(Some(m)),
                    Err(e) => fail(CloseReason::Malformed, e.to_string()),
                };
            }
            Message::Text(_) => {
                return fail(
                    CloseReason::Malformed,
                    "text frames are not part of the protocol; send binary frames",
                );
            }
            Message::Close(_) => return Ok(None),
            Message::Ping(_) | Message::Pong(_) => continue,
        }
    }
}

/// Sends one message within the idle timeout.
pub(super) async fn send<S>(
    socket: &mut S,
    state: &AppState,
    stats: &SessionStats,
    msg: &ServerMsg,
) -> Ended
where
    S: Sink<Message> + Unpin,
{
    send_encoded(socket, state, stats, codec::encode(msg)).await
}

/// Sends one encoded message within the idle timeout.
pub(super) async fn send_encoded<S>(
    socket: &mut S,
    state: &AppState,
    stats: &SessionStats,
    bytes: Vec<u8>,
) -> Ended
where
    S: Sink<Message> + Unpin,
{
    let n = bytes.len() as u64;
    stats.largest_out.fetch_max(n, Relaxed);
    match tokio::time::timeout(
        state.limits.idle_timeout,
        socket.send(Message::Binary(bytes.into())),
    )
    .await
    {
        Err(_) => fail(
            CloseReason::SlowReader,
            "the client did not read its messages within the idle timeout",
        ),
        // The connection is gone: nobody to tell.
        Ok(Err(_)) => Ok(()),
        Ok(Ok(())) => {
            state.metrics.bytes_out_total.fetch_add(n, Relaxed);
            stats.bytes_out.fetch_add(n, Relaxed);
            Ok(())
        }
    }
}
