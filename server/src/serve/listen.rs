//! The accept loop: per-IP connection rate, HTTP/1.1 with a header-read timeout (against
//! slowloris) and WebSocket upgrades, and the graceful drain.
//!
//! axum's own `serve` sets neither a header timeout nor a connection-rate limit, so
//! connections are served here with hyper directly. Each request carries the peer's address as
//! axum's `ConnectInfo`.

use super::limits::ConnectionRate;
use super::metrics::ErrorKind;
use super::router::app;
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

async fn refuse(mut tcp: TcpStream) {
    let _ = tokio::time::timeout(Duration::from_secs(1), tcp.write_all(TOO_MANY)).await;
    let _ = tcp.shutdown().await;
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
    let rate = ConnectionRate::new(state.limits.conn_rate_per_ip);
    let live = Live::default();
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
            tokio::spawn(refuse(tcp));
            continue;
        }
        let _ = tcp.set_nodelay(true);
        let router = router.clone();
        let svc = hyper::service::service_fn(move |mut req: hyper::Request<Incoming>| {
            req.extensions_mut().insert(ConnectInfo::<SocketAddr>(peer));
            router.clone().oneshot(req)
        });
        let conn = http1::Builder::new()
            .timer(TokioTimer::new())
            .header_read_timeout(state.limits.header_timeout)
            .serve_connection(TokioIo::new(tcp), svc)
            .with_upgrades();
        let guard = live.enter();
        let mut stop = stop.clone();
        let st = state.clone();
        tokio::spawn(async move {
            let _guard = guard;
            tokio::pin!(conn);
            let result = tokio::select! {
                r = conn.as_mut() => r,
                _ = async { stop.wait_for(|d| *d).await.map(|_| ()) } => {
                    conn.as_mut().graceful_shutdown();
                    conn.await
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
