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

use super::limits::SessionPermit;
use super::state::{AppState, SessionStats, Terrain};
use super::stream::Stream as LodStream;
use super::validate;
use crate::lod::vertex::{LodParams, VertexEngine};
use axum::extract::ws::{CloseFrame, Message};
use futures_util::{Sink, SinkExt, Stream, StreamExt};
use relief_proto::close::CloseReason;
use relief_proto::codec;
use relief_proto::cut::Cut;
use relief_proto::msg::{
    ClientMsg, Hello, PROTOCOL_VERSION, ServerMsg, SessionDelta, StreamKind, Welcome, WireDelta,
};
use relief_proto::view::Camera;
use std::error::Error as StdError;
use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::Ordering::Relaxed;
use std::time::{Duration, Instant};

/// Smallest allowance a budgeted delta waits for, bytes: small deltas cost framing too.
const MIN_CHUNK: f64 = 256.0;

/// How a session ended.
type Ended = Result<(), (CloseReason, String)>;

fn fail<T>(reason: CloseReason, detail: impl Into<String>) -> Result<T, (CloseReason, String)> {
    Err((reason, detail.into()))
}

/// Whether a socket error is the codec's message-size limit.
fn too_large(e: &(dyn StdError + 'static)) -> bool {
    let mut cur = Some(e);
    while let Some(err) = cur {
        if let Some(t) = err.downcast_ref::<tungstenite::Error>() {
            return matches!(t, tungstenite::Error::Capacity(_));
        }
        cur = err.source();
    }
    false
}

/// Runs a session to its end and closes the socket with the reason.
pub async fn run<S, E>(mut socket: S, state: Arc<AppState>, peer: SocketAddr, permit: SessionPermit)
where
    S: Stream<Item = Result<Message, E>> + Sink<Message> + Unpin + Send,
    E: StdError + Send + Sync + 'static,
{
    let (id, stats) = state.register(peer);
    let ended = session(&mut socket, &state, id, &stats).await;
    state.unregister(id);
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
        let _ = tokio::time::timeout(Duration::from_secs(1), socket.send(frame)).await;
    }
    let _ = tokio::time::timeout(Duration::from_secs(1), socket.close()).await;
    drop(permit);
}

/// Receives the next message within the idle timeout. `None`: the client closed.
async fn receive<S, E>(
    socket: &mut S,
    state: &AppState,
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
            Ok(Some(Err(e))) if too_large(&e) => {
                return fail(
                    CloseReason::TooLarge,
                    format!(
                        "message exceeds the limit of {} bytes",
                        state.limits.max_message_bytes
                    ),
                );
            }
            Ok(Some(Err(_))) => return Ok(None),
            Ok(Some(Ok(m))) => m,
        };
        match msg {
            Message::Binary(bytes) => {
                state
                    .metrics
                    .bytes_in_total
                    .fetch_add(bytes.len() as u64, Relaxed);
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
async fn send<S>(socket: &mut S, state: &AppState, stats: &SessionStats, msg: &ServerMsg) -> Ended
where
    S: Sink<Message> + Unpin,
{
    let bytes = codec::encode(msg);
    let n = bytes.len() as u64;
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

/// The session's configuration, from the hello.
struct Opening {
    /// The LOD state, from the root or the resumed cut.
    lod: LodStream,
    /// Bytes per second for delta bodies, if budgeted.
    budget: Option<u32>,
}

async fn open(
    hello: Hello,
    terrain: &Arc<Terrain>,
    state: &AppState,
) -> Result<(Opening, bool), (CloseReason, String)> {
    if hello.version != PROTOCOL_VERSION {
        return fail(
            CloseReason::Version,
            format!(
                "protocol version {} is not supported; this server speaks {PROTOCOL_VERSION}",
                hello.version
            ),
        );
    }
    let StreamKind::Vertex = hello.kind;
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
        Ok(Ok(lod)) => Ok((Opening { lod, budget }, resumed)),
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
    let hello = match receive(socket, state).await? {
        None => return Ok(()),
        Some(ClientMsg::Hello(h)) => h,
        Some(_) => return fail(CloseReason::Protocol, "the first message must be a hello"),
    };
    let (Opening { mut lod, budget }, resumed) = open(hello, &terrain, state).await?;
    state.metrics.sessions_total.fetch_add(1, Relaxed);
    if resumed {
        state.metrics.resumes_total.fetch_add(1, Relaxed);
    }
    let welcome = ServerMsg::Welcome(Welcome {
        version: PROTOCOL_VERSION,
        session_id: id,
        terrain: terrain.info.clone(),
        resumed,
        digest: lod.digest(),
        max_in_flight: state.limits.max_in_flight,
        max_message_bytes: state.limits.max_message_bytes,
        idle_timeout_ms: state.limits.idle_timeout.as_millis().min(u32::MAX as u128) as u32,
    });
    send(socket, state, stats, &welcome).await?;
    state.metrics.sessions_active.fetch_add(1, Relaxed);
    let r = stream_loop(socket, state, stats, &terrain, &mut lod, budget).await;
    state.metrics.sessions_active.fetch_sub(1, Relaxed);
    r
}

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

async fn stream_loop<S, E>(
    socket: &mut S,
    state: &Arc<AppState>,
    stats: &SessionStats,
    terrain: &Arc<Terrain>,
    lod: &mut LodStream,
    budget: Option<u32>,
) -> Ended
where
    S: Stream<Item = Result<Message, E>> + Sink<Message> + Unpin + Send,
    E: StdError + Send + Sync + 'static,
{
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
            let (produced, body) = compute(lod, terrain, state, camera, allowance).await?;
            f.incomplete = !produced.complete;
            f.tokens -= body.len() as f64;
            f.sent += 1;
            let msg = ServerMsg::Delta(SessionDelta {
                pose_seq,
                complete: produced.complete,
                delta: WireDelta {
                    seq: produced.delta.seq,
                    digest: produced.delta.digest,
                    body,
                },
            });
            send(socket, state, stats, &msg).await?;
            state.metrics.deltas_total.fetch_add(1, Relaxed);
            stats.deltas.fetch_add(1, Relaxed);
            stats.active_nodes.store(lod.active_count(), Relaxed);
            stats.memory_bytes.store(lod.memory_bytes() as u64, Relaxed);
            let max_nodes = state.limits.max_cut_nodes as usize;
            if lod.over_limit(max_nodes) {
                return fail(
                    CloseReason::BadParams,
                    format!(
                        "the cut reached the server's limit of {max_nodes} interior nodes; raise tau or shrink the viewport"
                    ),
                );
            }
            continue;
        }
        let sleep = tokio::time::sleep(wait_for_tokens.unwrap_or(Duration::from_secs(3600)));
        tokio::select! {
            _ = draining.changed() => continue,
            _ = sleep, if want && open && wait_for_tokens.is_some() => continue,
            m = receive(socket, state) => match m? {
                None => return Ok(()),
                Some(ClientMsg::Hello(_)) => return fail(CloseReason::Protocol, "a second hello"),
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

/// Computes the next delta off the async runtime and packs its body.
async fn compute(
    lod: &mut LodStream,
    terrain: &Arc<Terrain>,
    state: &AppState,
    camera: Camera,
    allowance: usize,
) -> Result<(super::stream::Produced, Vec<u8>), (CloseReason, String)> {
    let t = terrain.clone();
    // The state moves to a blocking thread and back; a placeholder holds its place.
    let mut owned = std::mem::replace(lod, LodStream::placeholder());
    let joined = tokio::task::spawn_blocking(move || {
        let started = Instant::now();
        let engine = VertexEngine::new(&t.store);
        let produced = owned.update(&engine, &camera, allowance);
        let g = engine.geometry();
        let body = produced.delta.pack_body(&g.shape, g.z_quantum);
        (owned, produced, body, started.elapsed().as_secs_f64())
    })
    .await;
    match joined {
        Ok((back, produced, body, secs)) => {
            *lod = back;
            state.metrics.observe_update(secs);
            Ok((produced, body))
        }
        Err(e) => fail(CloseReason::Internal, format!("update failed: {e}")),
    }
}

#[cfg(test)]
mod tests {
    //! The session driven through channels instead of a socket, on paused time.

    use super::*;
    use crate::serve::config::Limits;
    use crate::serve::limits::SessionLimits;
    use std::pin::Pin;
    use std::task::{Context, Poll};
    use tokio::sync::mpsc;

    /// One end of an in-memory WebSocket: messages in from the test, messages out to it.
    struct Duplex {
        /// What the test sends.
        rx: mpsc::UnboundedReceiver<Result<Message, std::io::Error>>,
        /// What the session sends.
        tx: mpsc::UnboundedSender<Message>,
    }

    impl Stream for Duplex {
        type Item = Result<Message, std::io::Error>;
        fn poll_next(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<Self::Item>> {
            self.rx.poll_recv(cx)
        }
    }

    impl Sink<Message> for Duplex {
        type Error = std::io::Error;
        fn poll_ready(self: Pin<&mut Self>, _: &mut Context<'_>) -> Poll<Result<(), Self::Error>> {
            Poll::Ready(Ok(()))
        }
        fn start_send(self: Pin<&mut Self>, item: Message) -> Result<(), Self::Error> {
            self.tx
                .send(item)
                .map_err(|_| std::io::Error::other("the test hung up"))
        }
        fn poll_flush(self: Pin<&mut Self>, _: &mut Context<'_>) -> Poll<Result<(), Self::Error>> {
            Poll::Ready(Ok(()))
        }
        fn poll_close(self: Pin<&mut Self>, _: &mut Context<'_>) -> Poll<Result<(), Self::Error>> {
            Poll::Ready(Ok(()))
        }
    }

    fn state(
        dir: &std::path::Path,
        limits: Limits,
    ) -> (Arc<AppState>, tokio::sync::watch::Sender<bool>) {
        let store =
            crate::serve::source::open_terrain(&crate::serve::config::TerrainSource::Embedded, dir)
                .unwrap();
        let (tx, rx) = tokio::sync::watch::channel(false);
        let s = Arc::new(AppState::new(limits, rx));
        let _ = s.terrain.set(Arc::new(Terrain::new(store)));
        (s, tx)
    }

    fn frame(msg: &ClientMsg) -> Result<Message, std::io::Error> {
        Ok(Message::Binary(codec::encode(msg).into()))
    }

    fn decode_server(m: &Message) -> ServerMsg {
        match m {
            Message::Binary(b) => codec::decode(b, codec::HARD_LIMIT).unwrap(),
            other => panic!("expected a binary frame, got {other:?}"),
        }
    }

    #[tokio::test(start_paused = true)]
    async fn poses_coalesce_while_the_window_is_full_and_silence_times_out() {
        let dir = tempfile::tempdir().unwrap();
        let limits = Limits {
            max_in_flight: 1,
            idle_timeout: Duration::from_secs(60),
            ..Limits::default()
        };
        let (state, _draining) = state(dir.path(), limits);
        let (to_server, rx) = mpsc::unbounded_channel();
        let (tx, mut from_server) = mpsc::unbounded_channel();
        let permit = SessionLimits::new(1, 1)
            .admit("127.0.0.1".parse().unwrap())
            .unwrap();
        let peer = "127.0.0.1:1".parse().unwrap();
        let task = tokio::spawn(run(Duplex { rx, tx }, state.clone(), peer, permit));

        let lens = relief_proto::view::Lens::STANDARD.into();
        let hello = ClientMsg::Hello(Hello {
            version: PROTOCOL_VERSION,
            kind: StreamKind::Vertex,
            lens,
            tau: 1.0,
            budget: None,
            resume: None,
        });
        to_server.send(frame(&hello)).unwrap();
        assert!(matches!(
            decode_server(&from_server.recv().await.unwrap()),
            ServerMsg::Welcome(_)
        ));
        // Three poses before any acknowledgement: the first is answered, the next two wait for
        // the window and coalesce into the newest.
        let info = state.terrain().unwrap().info.clone();
        let cam = |i: u64| relief_proto::msg::WireCamera {
            eye: [9000.0 + 100.0 * i as f32, 9000.0, 4000.0],
            yaw: 0.5,
            pitch: -0.3,
        };
        assert!(info.width > 0);
        for seq in 1..=3 {
            to_server
                .send(frame(&ClientMsg::Pose {
                    seq,
                    camera: cam(seq),
                }))
                .unwrap();
        }
        let ServerMsg::Delta(first) = decode_server(&from_server.recv().await.unwrap()) else {
            panic!("expected a delta");
        };
        assert_eq!(first.pose_seq, 1);
        tokio::time::sleep(Duration::from_secs(1)).await;
        assert!(from_server.try_recv().is_err(), "a delta beyond the window");
        to_server.send(frame(&ClientMsg::Ack { seq: 1 })).unwrap();
        let ServerMsg::Delta(second) = decode_server(&from_server.recv().await.unwrap()) else {
            panic!("expected a delta");
        };
        assert_eq!(second.pose_seq, 3, "pose 2 should have been coalesced away");
        to_server.send(frame(&ClientMsg::Ack { seq: 2 })).unwrap();
        // Then silence: a minute later (of paused time) the session closes as idle.
        let close = from_server.recv().await.unwrap();
        let Message::Close(Some(f)) = close else {
            panic!("expected a close frame, got {close:?}");
        };
        assert_eq!(f.code, CloseReason::Idle.code());
        task.await.unwrap();
        assert!(
            state
                .metrics
                .render()
                .contains("relief_errors_total{kind=\"idle\"} 1")
        );
    }
}
