//! The session after its welcome (DESIGN.md section 6, "Updates" and "Budget"): poses
//! coalesce, deltas go out while the window has room and the budget has tokens, and the drain
//! ends it.

use super::io::{Ended, fail, receive, send};
use crate::serve::state::{AppState, SessionStats, Terrain};
use crate::serve::stream::{Produced, Stream as LodStream};
use crate::serve::validate;
use axum::extract::ws::Message;
use futures_util::{Sink, Stream};
use relief_proto::close::CloseReason;
use relief_proto::msg::{ClientMsg, ServerMsg, SessionDelta, WireDelta};
use relief_proto::view::Camera;
use std::error::Error as StdError;
use std::sync::Arc;
use std::sync::atomic::Ordering::Relaxed;
use std::time::{Duration, Instant};

/// Smallest allowance a budgeted delta waits for, bytes: small deltas cost framing too.
const MIN_CHUNK: f64 = 256.0;

/// What the loop knows between events.
struct Flow {
    /// The newest pose not yet answered.
    pending: Option<(u64, Camera)>,
    /// The newest pose received (answered or not).
    latest: Option<(u64, Camera)>,
    /// The last delta answered an older pose only in part (budget).
    incomplete: bool,
    /// Deltas sent.
    sent: u64,
    /// Newest acknowledged delta.
    acked: u64,
    /// Budget tokens, bytes, and when they were last refilled.
    tokens: f64,
    /// When the tokens were last refilled.
    refilled: Instant,
}

pub(super) async fn stream_loop<S, E>(
    socket: &mut S,
    state: &Arc<AppState>,
    stats: &SessionStats,
    terrain: &Arc<Terrain>,
    lod: &mut LodStream,
    budget: Option<u32>,
    turn: Option<tokio::sync::SemaphorePermit<'_>>,
) -> Ended
where
    S: Stream<Item = Result<Message, E>> + Sink<Message> + Unpin + Send,
    E: StdError + Send + Sync + 'static,
{
    let mut turn = turn;
    let mut draining = state.draining.clone();
    let mut f = Flow {
        pending: None,
        latest: None,
        incomplete: false,
        sent: 0,
        acked: 0,
        tokens: budget.map_or(0.0, f64::from),
        refilled: Instant::now(),
    };
    let window = u64::from(state.limits.max_in_flight);
    loop {
        if *draining.borrow() {
            send(
                socket,
                state,
                stats,
                &ServerMsg::Reconnect { after_ms: 100 },
            )
            .await?;
            return fail(
                CloseReason::Draining,
                "the server is restarting; reconnect and resume",
            );
        }
        let want = f.pending.is_some() || f.incomplete;
        let open = f.sent - f.acked < window;
        let mut wait_for_tokens = None;
        if let Some(b) = budget {
            let now = Instant::now();
            f.tokens = (f.tokens + now.duration_since(f.refilled).as_secs_f64() * f64::from(b))
                .min(f64::from(b));
            f.refilled = now;
            if f.tokens < MIN_CHUNK {
                wait_for_tokens = Some(Duration::from_secs_f64(
                    (MIN_CHUNK - f.tokens) / f64::from(b),
                ));
            }
        }
        if want && open && wait_for_tokens.is_none() {
            let Some((pose_seq, camera)) = f.pending.take().or(f.latest) else {
                continue;
            };
            let allowance = if budget.is_some() {
                f.tokens as usize
            } else {
                usize::MAX
            };
            let produced = compute(lod, terrain, state, camera, allowance).await?;
            // The first delta examined the whole resumed cut: a large resume's turn ends.
            drop(turn.take());
            f.incomplete = !produced.complete;
            f.tokens -= produced.body.len() as f64;
            f.sent += 1;
            let msg = ServerMsg::Delta(SessionDelta {
                pose_seq,
                complete: produced.complete,
                delta: WireDelta {
                    seq: produced.seq,
                    digest: produced.digest,
                    body: produced.body,
                },
            });
            send(socket, state, stats, &msg).await?;
            state.metrics.deltas_total.fetch_add(1, Relaxed);
            stats.deltas.fetch_add(1, Relaxed);
            stats.active_nodes.store(lod.active_count(), Relaxed);
            state
                .set_session_memory(stats, stats.socket_bytes() + lod.memory_bytes() as u64)
                .map_err(|e| (CloseReason::ServerFull, e))?;
            let max_nodes = state.limits.max_cut_nodes as usize;
            if lod.over_limit(max_nodes) {
                return fail(CloseReason::CutLimit, validate::cut_limit(max_nodes));
            }
            continue;
        }
        let sleep = tokio::time::sleep(wait_for_tokens.unwrap_or(Duration::from_secs(3600)));
        tokio::select! {
            _ = draining.changed() => continue,
            _ = sleep, if want && open && wait_for_tokens.is_some() => continue,
            m = receive(socket, state, stats) => match m? {
                None => return Ok(()),
                Some(ClientMsg::Hello(_)) => return fail(CloseReason::Protocol, "a second hello"),
                Some(ClientMsg::Query(_)) => return fail(CloseReason::Protocol, "query batches belong to query sessions (stream kind query)"),
                Some(ClientMsg::Pose { seq, camera }) => {
                    let cam = validate::camera(&camera, &terrain.info).map_err(|e| (CloseReason::BadCamera, e))?;
                    if f.latest.is_none_or(|(s, _)| seq > s) {
                        f.latest = Some((seq, cam));
                        f.pending = Some((seq, cam));
                    }
                }
                Some(ClientMsg::Ack { seq }) => {
                    if seq > f.sent {
                        return fail(CloseReason::Protocol, format!("acknowledged delta {seq}, but only {} were sent", f.sent));
                    }
                    f.acked = f.acked.max(seq);
                    stats.acked.store(f.acked, Relaxed);
                }
            },
        }
    }
}

/// Computes the next delta and packs its body: off the async runtime unless it is cheap.
async fn compute(
    lod: &mut LodStream,
    terrain: &Arc<Terrain>,
    state: &AppState,
    camera: Camera,
    allowance: usize,
) -> Result<Produced, (CloseReason, String)> {
    if lod.is_cheap() {
        // A tile update, or a vertex update of a session whose recent updates were small
        // (`LodStream::is_cheap`): tens of microseconds to a millisecond, where a trip to a
        // blocking thread costs two thread switches. A panic fails this session as it would on
        // a blocking thread, not the worker's other tasks.
        let started = Instant::now();
        let run = std::panic::AssertUnwindSafe(|| lod.update(&terrain.store, &camera, allowance));
        let produced = std::panic::catch_unwind(run)
            .map_err(|_| (CloseReason::Internal, "update failed: panicked".to_string()))?;
        state
            .metrics
            .observe_update(started.elapsed().as_secs_f64());
        return Ok(produced);
    }
    let t = terrain.clone();
    let heavy = lod.is_heavy();
    // The state moves to a worker thread and back; a placeholder holds its place.
    let mut owned = std::mem::replace(lod, LodStream::placeholder());
    let work = move || {
        let started = Instant::now();
        let produced = owned.update(&t.store, &camera, allowance);
        (owned, produced, started.elapsed().as_secs_f64())
    };
    // An expensive session waits its turn on the background pool, at a lower priority;
    // an ordinary one goes to a blocking thread at once.
    let joined = if heavy {
        state.background.run(work).await.map_err(|e| e.to_string())
    } else {
        tokio::task::spawn_blocking(work)
            .await
            .map_err(|e| e.to_string())
    };
    match joined {
        Ok((back, produced, secs)) => {
            *lod = back;
            state.metrics.observe_update(secs);
            Ok(produced)
        }
        Err(e) => fail(CloseReason::Internal, format!("update failed: {e}")),
    }
}
