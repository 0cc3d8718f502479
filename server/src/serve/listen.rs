//! The accept loop: per-IP connection rate, connection limits in all and per IP, HTTP/1.1
//! with a header-read timeout (against slowloris; hyper also starts it while a kept-alive
//! connection idles) and WebSocket upgrades, and the graceful drain.
//!
//! axum's own `serve` sets neither a header timeout nor connection limits, so connections are
//! served here with hyper directly. Each request carries the peer's address as axum's
//! `ConnectInfo`, and its connection's slot as a [`ConnSlot`], which a WebSocket session
//! keeps for as long as it runs.
//!
//! **At the limit.** A connection over the limits is still read, briefly and one request only,
//! by a small router that answers `/healthz` and `/readyz` as usual and everything else with
//! 503 (server full) or 429 (address full); a few such connections at a time, beyond which
//! they get the refusal unread. The limit itself is kept below the process's open-file limit
//! (raised to its hard maximum at start), so that `accept` never runs out of descriptors.

use super::limits::{IpBuckets, Refusal, SlotPermit};
use super::metrics::ErrorKind;
use super::router::{app, overflow_app};
use super::stall::{StallIo, WriteStall};
use super::state::AppState;
use axum::extract::ConnectInfo;
use hyper::body::Incoming;
use hyper::server::conn::http1;
use hyper_util::rt::{TokioIo, TokioTimer};
use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};
use std::time::{Duration, Instant};
use tokio::io::AsyncWriteExt;
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::watch;
use tower::ServiceExt;

/// What a connection over its rate is told before it is closed.
const TOO_MANY: &[u8] = b"HTTP/1.1 429 Too Many Requests\r\ncontent-type: application/json\r\nconnection: close\r\ncontent-length: 67\r\n\r\n{\"error\":\"too many connections from your address; retry after 1 s\"}";

/// What a connection over the connection limit is told, unread, when even the small router's
/// few places are taken.
const FULL: &[u8] = b"HTTP/1.1 503 Service Unavailable\r\ncontent-type: application/json\r\nconnection: close\r\ncontent-length: 64\r\n\r\n{\"error\":\"the server holds its maximum of connections; retry later\"}";

/// Connections over the limit read at once by the small router.
const OVERFLOW_READERS: usize = 32;

/// How long the small router waits for an over-limit connection's request.
const OVERFLOW_TIMEOUT: Duration = Duration::from_secs(2);

/// Descriptors kept back from the connection limit: the store, the listener, logs, the
/// blocking pool's files, and the over-limit connections being answered.
const RESERVED_FDS: u64 = 64 + OVERFLOW_READERS as u64;

/// A connection's slot, held by the connection and by a WebSocket session upgraded from it.
#[derive(Clone, Debug)]
pub struct ConnSlot(
    #[allow(
        dead_code,
        reason = "held, never read: dropping the last clone frees the slot"
    )]
    Arc<SlotPermit>,
);

/// Raises the open-file limit to its hard maximum and returns how many connections fit
/// under it, at most `wanted`.
pub fn fit_connections(wanted: u32) -> u32 {
    use nix::sys::resource::{Resource, getrlimit, setrlimit};
    let Ok((soft, hard)) = getrlimit(Resource::RLIMIT_NOFILE) else {
        return wanted;
    };
    let soft = if soft < hard && setrlimit(Resource::RLIMIT_NOFILE, hard, hard).is_ok() {
        hard
    } else {
        soft
    };
    let fit = soft.saturating_sub(RESERVED_FDS).max(1);
    if fit < u64::from(wanted) {
        tracing::warn!(
            "the open-file limit ({soft}) allows {fit} connections, not {wanted}; raise `ulimit -n` for more"
        );
        fit as u32
    } else {
        wanted
    }
}

/// Requests of one connection being answered, from their headers to the last byte of the
/// response, so that the drain waits for those and for nothing else.
#[derive(Clone, Default)]
struct Busy(Arc<AtomicUsize>);

/// Decrements a [`Busy`] count when dropped.
struct BusyGuard(Arc<AtomicUsize>);

impl Drop for BusyGuard {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Relaxed);
    }
}

impl Busy {
    /// Whether a request is being answered.
    fn any(&self) -> bool {
        self.0.load(Relaxed) > 0
    }

    /// Answers `req` with `router`, counted until the response's body is dropped (written in
    /// full, or abandoned).
    async fn serve(
        self,
        router: axum::Router,
        req: hyper::Request<Incoming>,
    ) -> Result<axum::response::Response, std::convert::Infallible> {
        use http_body_util::BodyExt;
        self.0.fetch_add(1, Relaxed);
        let guard = BusyGuard(self.0.clone());
        let res = router.oneshot(req).await?;
        Ok(res.map(move |b| {
            axum::body::Body::new(b.map_frame(move |f| {
                let _held = &guard;
                f
            }))
        }))
    }
}

/// Counts live HTTP connections, so that the drain can wait for them.
#[derive(Clone, Default)]
struct Live(Arc<AtomicUsize>);

/// Decrements the count when a connection task ends, however it ends.
struct LiveGuard(Arc<AtomicUsize>);

impl Live {
    fn enter(&self) -> LiveGuard {
        self.0.fetch_add(1, Relaxed);
        LiveGuard(self.0.clone())
    }
}

impl Drop for LiveGuard {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Relaxed);
    }
}

async fn refuse(mut tcp: TcpStream, answer: &'static [u8]) {
    let _ = tokio::time::timeout(Duration::from_secs(1), tcp.write_all(answer)).await;
    let _ = tcp.shutdown().await;
}

/// Answers one request of a connection over the limit with the small router, then closes it.
async fn serve_overflow(
    tcp: TcpStream,
    peer: SocketAddr,
    state: Arc<AppState>,
    why: Refusal,
    _guard: LiveGuard,
) {
    let router = overflow_app(state, why);
    let svc = hyper::service::service_fn(move |mut req: hyper::Request<Incoming>| {
        req.extensions_mut().insert(ConnectInfo::<SocketAddr>(peer));
        router.clone().oneshot(req)
    });
    let conn = http1::Builder::new()
        .timer(TokioTimer::new())
        .header_read_timeout(OVERFLOW_TIMEOUT)
        .keep_alive(false)
        .serve_connection(TokioIo::new(tcp), svc);
    let _ = tokio::time::timeout(OVERFLOW_TIMEOUT, conn).await;
}

/// Serves connections from `listener` until `shutdown` completes, then drains: sessions are
/// told to reconnect (`draining` turns true), HTTP connections finish their requests, and the
/// function returns once all are gone or the drain timeout has passed.
pub async fn serve(
    listener: TcpListener,
    state: Arc<AppState>,
    draining: watch::Sender<bool>,
    shutdown: impl std::future::Future<Output = ()>,
) {
    let router = app(state.clone());
    let rate = IpBuckets::connection_rate(state.limits.conn_rate_per_ip);
    let live = Live::default();
    let overflow = Live::default();
    let mut stop = draining.subscribe();
    tokio::pin!(shutdown);
    loop {
        let (tcp, peer) = tokio::select! {
            _ = &mut shutdown => break,
            r = listener.accept() => match r {
                Ok(x) => x,
                Err(e) => {
                    // Out of file descriptors and the like: back off instead of spinning.
                    tracing::warn!("accept failed: {e}");
                    tokio::time::sleep(Duration::from_millis(50)).await;
                    continue;
                }
            },
        };
        if !rate.allow(peer.ip(), Instant::now()) {
            state.metrics.error(ErrorKind::RateLimited);
            tracing::debug!(%peer, "connection refused: over the per-address rate");
            tokio::spawn(refuse(tcp, TOO_MANY));
            continue;
        }
        let _ = tcp.set_nodelay(true);
        let slot = match state.connections.admit(peer.ip()) {
            Ok(p) => ConnSlot(Arc::new(p)),
            Err(why) => {
                state.metrics.error(ErrorKind::ConnectionLimit);
                tracing::debug!(%peer, "connection over the limit: {why:?}");
                if overflow.0.load(Relaxed) >= OVERFLOW_READERS {
                    tokio::spawn(refuse(tcp, FULL));
                } else {
                    let guard = overflow.enter();
                    tokio::spawn(serve_overflow(tcp, peer, state.clone(), why, guard));
                }
                continue;
            }
        };
        let router = router.clone();
        let conn_slot = slot.clone();
        let stall = WriteStall::new(state.limits.write_timeout);
        let conn_stall = stall.clone();
        let busy = Busy::default();
        let conn_busy = busy.clone();
        let svc = hyper::service::service_fn(move |mut req: hyper::Request<Incoming>| {
            req.extensions_mut().insert(ConnectInfo::<SocketAddr>(peer));
            req.extensions_mut().insert(conn_slot.clone());
            req.extensions_mut().insert(conn_stall.clone());
            conn_busy.clone().serve(router.clone(), req)
        });
        let conn = http1::Builder::new()
            .timer(TokioTimer::new())
            .header_read_timeout(state.limits.header_timeout)
            .serve_connection(TokioIo::new(StallIo::new(tcp, stall)), svc)
            .with_upgrades();
        let guard = live.enter();
        let mut stop = stop.clone();
        let st = state.clone();
        tokio::spawn(async move {
            let _guard = guard;
            let _slot = slot;
            tokio::pin!(conn);
            let result = tokio::select! {
                r = conn.as_mut() => r,
                _ = async { stop.wait_for(|d| *d).await.map(|_| ()) } => {
                    conn.as_mut().graceful_shutdown();
                    // A request being answered is finished; a connection between requests,
                    // or still sending its headers, is closed at once.
                    loop {
                        tokio::select! {
                            r = conn.as_mut() => break r,
                            _ = tokio::time::sleep(Duration::from_millis(20)) => {
                                if !busy.any() {
                                    break Ok(());
                                }
                            }
                        }
                    }
                }
            };
            if let Err(e) = result {
                st.metrics.error(ErrorKind::Connection);
                tracing::debug!(%peer, "connection ended: {e}");
            }
        });
    }
    drop(listener);
    tracing::info!(
        "draining: telling {} sessions to reconnect",
        state.sessions.open()
    );
    let _ = draining.send(true);
    let _ = stop.borrow_and_update();
    let deadline = Instant::now() + state.limits.drain_timeout;
    while (state.sessions.open() > 0 || live.0.load(Relaxed) > 0) && Instant::now() < deadline {
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    let left = state.sessions.open();
    if left > 0 {
        tracing::warn!("drain timeout: {left} sessions still open");
    } else {
        tracing::info!("drained");
    }
}
