//! A query session (`StreamKind::Query`): after the welcome, each [`ClientMsg::Query`] batch is
//! answered in order with [`ServerMsg::Answers`], or refused whole with [`ServerMsg::Refused`]
//! when it is over the limits (the session goes on). A client may pipeline batches: the server
//! reads the next one when it has answered the last, so the socket's buffers bound what waits.
//! A drain ends the session once the batch in hand is answered.

use super::io::{Ended, fail, receive, send_encoded};
use crate::serve::query::{BatchError, answer};
use crate::serve::state::{AppState, SessionStats, Terrain};
use axum::extract::ws::Message;
use futures_util::{Sink, Stream};
use relief_proto::close::CloseReason;
use relief_proto::codec;
use relief_proto::msg::{ClientMsg, ServerMsg};
use relief_proto::query::BatchRefused;
use std::error::Error as StdError;
use std::sync::Arc;
use std::sync::atomic::Ordering::Relaxed;

pub(super) async fn query_loop<S, E>(
    socket: &mut S,
    state: &Arc<AppState>,
    stats: &SessionStats,
    terrain: &Arc<Terrain>,
) -> Ended
where
    S: Stream<Item = Result<Message, E>> + Sink<Message> + Unpin + Send,
    E: StdError + Send + Sync + 'static,
{
    let mut draining = state.draining.clone();
    loop {
        if *draining.borrow() {
            return fail(CloseReason::Draining, "the server is shutting down");
        }
        let msg = tokio::select! {
            _ = draining.changed() => continue,
            m = receive(socket, state, stats) => m?,
        };
        let batch = match msg {
            None => return Ok(()),
            Some(ClientMsg::Query(b)) => b,
            Some(ClientMsg::Hello(_)) => return fail(CloseReason::Protocol, "a second hello"),
            Some(ClientMsg::Pose { .. } | ClientMsg::Ack { .. }) => {
                return fail(
                    CloseReason::Protocol,
                    "poses and acknowledgements belong to stream sessions, not a query session",
                );
            }
        };
        let id = batch.id;
        let reply = match answer(state, terrain, batch).await {
            Ok(a) => {
                stats.deltas.fetch_add(1, Relaxed);
                ServerMsg::Answers(a)
            }
            Err(BatchError::Refused(reason)) => {
                state
                    .metrics
                    .error(crate::serve::metrics::ErrorKind::BadRequest);
                ServerMsg::Refused(BatchRefused { id, reason })
            }
            Err(BatchError::Unavailable(why)) => return fail(CloseReason::Internal, why),
        };
        let mut bytes = codec::encode(&reply);
        // The answer waits in the socket's write buffer until the client reads it: charged
        // against the memory budget first, or refused.
        if let Err(why) =
            state.set_session_memory(stats, stats.socket_bytes_with(bytes.len() as u64))
        {
            state
                .metrics
                .error(crate::serve::metrics::ErrorKind::MemoryBudget);
            bytes = codec::encode(&ServerMsg::Refused(BatchRefused { id, reason: why }));
        }
        send_encoded(socket, state, stats, bytes).await?;
        // The write buffer keeps the room of the largest message (`largest_out`).
        let _ = state.set_session_memory(stats, stats.socket_bytes());
    }
}
