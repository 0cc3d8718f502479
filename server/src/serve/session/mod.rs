//! One session over a WebSocket (DESIGN.md section 6): hello and welcome, coalesced poses,
//! acknowledged deltas with a bounded window, the bandwidth budget, resume, and closes with a
//! reason. Generic over any `Sink + Stream` of WebSocket messages, so that tests can drive it
//! through channels.
//!
//! **Flow control.** The session computes a delta only while fewer than `max_in_flight` are
//! unacknowledged. Poses that arrive meanwhile replace one another (the latest wins), so a
//! client that stops reading holds at most `max_in_flight` deltas on the server, plus one pose.
//! A send that cannot complete within the idle timeout closes the session as a slow reader.
//!
//! **Budget.** A token bucket of `budget` bytes per second (one second of burst) meters delta
//! bodies. A delta may use the tokens there are; when the budgeted engine leaves splits for
//! later, the session waits for tokens and sends the rest without waiting for a new pose.
//!
//! - [`io`]: receiving and sending one message, with the idle timeout and the close reasons.
//! - [`flow`]: the loop after the welcome: coalescing, the window, the budget, the drain.
//! - [`query`]: a query session's loop: batches answered in order.

mod flow;
mod io;
mod query;
#[cfg(test)]
mod tests;

use super::limits::SlotPermit;
use super::state::{AppState, SessionStats, Terrain};
use super::stream::Stream as LodStream;
use super::validate;
use crate::lod::tile::TileEngine;
use crate::lod::tile::session::TileSession;
use crate::lod::vertex::{LodParams, VertexEngine};
use axum::extract::ws::{CloseFrame, Message};
use flow::stream_loop;
use futures_util::{Sink, SinkExt, Stream, StreamExt};
use io::{Ended, fail, receive, send};
use relief_proto::close::CloseReason;
use relief_proto::cut::Cut;
use relief_proto::msg::{ClientMsg, Hello, PROTOCOL_VERSION, ServerMsg, StreamKind, Welcome};
use std::error::Error as StdError;
use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::Ordering::Relaxed;
use std::time::Duration;

/// Runs a session to its end and closes the socket with the reason.
pub async fn run<S, E>(mut socket: S, state: Arc<AppState>, peer: SocketAddr, permit: SlotPermit)
where
    S: Stream<Item = Result<Message, E>> + Sink<Message> + Unpin + Send,
    E: StdError + Send + Sync + 'static,
{
    let (id, ended) = match state.register(peer) {
        Ok((id, stats)) => {
            let ended = session(&mut socket, &state, id, &stats).await;
            state.unregister(id);
            (id, ended)
        }
        Err(why) => (0, Err((CloseReason::ServerFull, why))),
    };
    // A slow reader has a socket full of what it has not read yet; its close frame comes after
    // all that, so it gets longer to arrive.
    let linger = match &ended {
        Err((CloseReason::SlowReader, _)) => SLOW_READER_LINGER,
        _ => Duration::from_secs(1),
    };
    if let Err((reason, detail)) = ended {
        state.metrics.close(reason);
        let text = reason.text(&detail);
        if reason == CloseReason::Draining {
            tracing::debug!(%peer, id, "session closed: {text}");
        } else {
            tracing::info!(%peer, id, "session closed: {text}");
        }
        let frame = Message::Close(Some(CloseFrame {
            code: reason.code(),
            reason: text.into(),
        }));
        let _ = tokio::time::timeout(linger, socket.send(frame)).await;
    }
    let _ = tokio::time::timeout(Duration::from_secs(1), socket.close()).await;
    // The closing handshake: read (and drop) what the client still sends until its close
    // frame. A socket closed with unread input is reset, and a reset discards what the
    // client had not yet read, the close frame included.
    let _ = tokio::time::timeout(linger, async {
        while let Some(Ok(_)) = socket.next().await {}
    })
    .await;
    drop(permit);
}

/// How long a slow reader's close frame may take to be written, and its closing handshake to
/// finish: the client may still be reading what was sent before.
const SLOW_READER_LINGER: Duration = Duration::from_secs(10);

/// The session's configuration, from the hello.
struct Opening<'a> {
    /// The LOD state, from the root or the resumed cut.
    lod: LodStream,
    /// Bytes per second for delta bodies, if budgeted.
    budget: Option<u32>,
    /// A large resume's turn among openings, given back after the first delta.
    turn: Option<tokio::sync::SemaphorePermit<'a>>,
}

/// Longest a resume waits for its address's resume work to be paid for; past it the session
/// is refused (and the client retries later).
const MAX_RESUME_WAIT: Duration = Duration::from_secs(10);

/// Interior nodes from which a resume is large enough to take a turn (see `open`): a first
/// update over 100,000 interior nodes takes some 10 ms or more.
const HEAVY_RESUME_NODES: u64 = 100_000;

/// Memory a session holds before its LOD state: the WebSocket read buffer (see `ws.rs`).
pub const SOCKET_BYTES: u64 = 4096;

/// Refuses a hello of another protocol version.
fn check_version(version: u32) -> Ended {
    if version != PROTOCOL_VERSION {
        return fail(
            CloseReason::Version,
            format!(
                "protocol version {version} is not supported; this server speaks {PROTOCOL_VERSION}"
            ),
        );
    }
    Ok(())
}

/// Paces resumes per address: a resume of `nodes` interior nodes goes ahead once the address
/// has paid for its earlier ones, at the configured rate; one that would wait longer than
/// [`MAX_RESUME_WAIT`] is refused.
async fn pace_resume(state: &AppState, peer: SocketAddr, nodes: u64) -> Ended {
    let now = std::time::Instant::now();
    match state
        .resume_work
        .take(peer.ip(), now, nodes as f64, MAX_RESUME_WAIT)
    {
        Ok(wait) => {
            tokio::time::sleep(wait).await;
            Ok(())
        }
        Err(wait) => fail(
            CloseReason::TooManyFromAddress,
            format!(
                "{} resumed more than {:.0} interior nodes a second; retry in {:.0} s",
                peer.ip(),
                state.limits.resume_nodes_per_s_per_ip,
                wait.as_secs_f64().ceil()
            ),
        ),
    }
}

async fn open<'a>(
    hello: Hello,
    terrain: &Arc<Terrain>,
    state: &'a AppState,
    stats: &SessionStats,
) -> Result<(Opening<'a>, bool), (CloseReason, String)> {
    check_version(hello.version)?;
    validate::params(&hello.lens, hello.tau, hello.budget)
        .map_err(|e| (CloseReason::BadParams, e))?;
    if let Some(r) = &hello.resume
        && r.terrain_id != terrain.info.id
    {
        return fail(
            CloseReason::BadSnapshot,
            format!(
                "the snapshot is for terrain {:016x}; this server holds {:016x}",
                r.terrain_id, terrain.info.id
            ),
        );
    }
    let mut turn = None;
    if let Some(r) = &hello.resume {
        // Accounted from the start: the snapshot, and the cut it becomes (under a byte per
        // interior node, twice while the first update reads the copy it resumed from).
        let nodes: u64 = r
            .snapshot
            .bits
            .iter()
            .map(|b| u64::from(b.count_ones()))
            .sum();
        let bytes = stats.socket_bytes() + r.snapshot.bits.len() as u64 + 2 * nodes;
        state
            .set_session_memory(stats, bytes)
            .map_err(|e| (CloseReason::ServerFull, e))?;
        pace_resume(state, stats.peer, nodes).await?;
        if nodes >= HEAVY_RESUME_NODES {
            // Large resumes take turns, until their first delta (which examines the whole
            // resumed cut): a flood of them from many addresses cannot take every core.
            turn =
                Some(
                    state.openings.acquire().await.map_err(|_| {
                        (CloseReason::Internal, "the server is stopping".to_string())
                    })?,
                );
        }
    }
    let t = terrain.clone();
    let max_nodes = state.limits.max_cut_nodes as usize;
    let resumed = hello.resume.is_some();
    let params = LodParams {
        tau: hello.tau,
        ..LodParams::default()
    };
    let lens = hello.lens.into();
    let budget = hello.budget;
    let built = tokio::task::spawn_blocking(move || {
        if let StreamKind::Tiles(tp) = hello.kind {
            let engine = TileEngine::new(&t.store);
            let session = match &hello.resume {
                Some(r) => {
                    let shape = engine.shape();
                    let active =
                        relief_proto::tile::snapshot::active_of(shape, &r.snapshot, max_nodes)
                            .map_err(|e| e.to_string())?;
                    TileSession::resume(&engine, tp, params.tau, params.merge_ratio, &active)?
                }
                None => TileSession::new(
                    engine.shape().tile_count(),
                    tp,
                    params.tau,
                    params.merge_ratio,
                ),
            };
            return Ok(LodStream::tiles(session, lens));
        }
        let engine = VertexEngine::new(&t.store);
        let shape = &engine.geometry().shape;
        let cut = match &hello.resume {
            Some(r) => r
                .snapshot
                .to_cut(shape, max_nodes)
                .map_err(|e| e.to_string())?,
            None => Cut::root(shape),
        };
        Ok::<_, String>(LodStream::new(
            &engine,
            &cut,
            params,
            lens,
            budget.is_some(),
            max_nodes,
        ))
    })
    .await;
    match built {
        Ok(Ok(lod)) => Ok((Opening { lod, budget, turn }, resumed)),
        Ok(Err(e)) => fail(CloseReason::BadSnapshot, e),
        Err(e) => fail(CloseReason::Internal, format!("session setup failed: {e}")),
    }
}

async fn session<S, E>(
    socket: &mut S,
    state: &Arc<AppState>,
    id: u64,
    stats: &SessionStats,
) -> Ended
where
    S: Stream<Item = Result<Message, E>> + Sink<Message> + Unpin + Send,
    E: StdError + Send + Sync + 'static,
{
    let Some(terrain) = state.terrain() else {
        return fail(CloseReason::NotReady, "the terrain is not ready yet");
    };
    // A client that has not said hello by the time the server drains is told so at once: it
    // holds no state worth waiting for.
    let mut draining = state.draining.clone();
    let first = tokio::select! {
        r = receive(socket, state, stats) => r?,
        _ = async { draining.wait_for(|d| *d).await.map(|_| ()) } => {
            return fail(CloseReason::Draining, "the server is shutting down");
        }
    };
    let hello = match first {
        None => return Ok(()),
        Some(ClientMsg::Hello(h)) => h,
        Some(_) => return fail(CloseReason::Protocol, "the first message must be a hello"),
    };
    if hello.kind == StreamKind::Query {
        return query_session(socket, state, id, stats, &terrain, &hello).await;
    }
    let tiles = matches!(hello.kind, StreamKind::Tiles(_));
    let (
        Opening {
            mut lod,
            budget,
            turn,
        },
        resumed,
    ) = open(hello, &terrain, state, stats).await?;
    state
        .set_session_memory(stats, stats.socket_bytes() + lod.memory_bytes() as u64)
        .map_err(|e| (CloseReason::ServerFull, e))?;
    state.metrics.sessions_total.fetch_add(1, Relaxed);
    if resumed {
        state.metrics.resumes_total.fetch_add(1, Relaxed);
    }
    let welcome = welcome(state, id, &terrain, resumed, lod.digest(), tiles);
    send(socket, state, stats, &welcome).await?;
    state.metrics.sessions_active.fetch_add(1, Relaxed);
    let r = stream_loop(socket, state, stats, &terrain, &mut lod, budget, turn).await;
    state.metrics.sessions_active.fetch_sub(1, Relaxed);
    r
}

/// The welcome of session `id`.
fn welcome(
    state: &AppState,
    id: u64,
    terrain: &Terrain,
    resumed: bool,
    digest: u64,
    tiles: bool,
) -> ServerMsg {
    ServerMsg::Welcome(Welcome {
        version: PROTOCOL_VERSION,
        session_id: id,
        terrain: terrain.info.clone(),
        resumed,
        digest,
        max_in_flight: state.limits.max_in_flight,
        max_message_bytes: state.limits.max_message_bytes,
        idle_timeout_ms: state.limits.idle_timeout.as_millis().min(u32::MAX as u128) as u32,
        tiles: tiles.then(|| terrain.store.tile_info().clone()),
    })
}

/// A query session (`StreamKind::Query`) from its hello: no cut, no deltas; its welcome's
/// digest is 0.
async fn query_session<S, E>(
    socket: &mut S,
    state: &Arc<AppState>,
    id: u64,
    stats: &SessionStats,
    terrain: &Arc<Terrain>,
    hello: &Hello,
) -> Ended
where
    S: Stream<Item = Result<Message, E>> + Sink<Message> + Unpin + Send,
    E: StdError + Send + Sync + 'static,
{
    check_version(hello.version)?;
    if hello.resume.is_some() {
        return fail(
            CloseReason::BadParams,
            "a query session has no cut to resume: send no snapshot",
        );
    }
    if let Err(e) = &terrain.query {
        return fail(
            CloseReason::Internal,
            format!("this terrain cannot be queried: {e}"),
        );
    }
    state.metrics.sessions_total.fetch_add(1, Relaxed);
    send(
        socket,
        state,
        stats,
        &welcome(state, id, terrain, false, 0, false),
    )
    .await?;
    state.metrics.sessions_active.fetch_add(1, Relaxed);
    let r = query::query_loop(socket, state, stats, terrain).await;
    state.metrics.sessions_active.fetch_sub(1, Relaxed);
    r
}
