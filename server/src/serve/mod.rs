//! The streaming server (DESIGN.md section 6): sessions over WebSocket, the HTTP API, limits,
//! metrics and the graceful drain, on axum, hyper and tokio.
//!
//! - [`config`]: flags, `RELIEF_*` variables and the TOML file, resolved into [`ServeConfig`].
//! - [`source`]: the terrain to serve: a store, or a DEM built into the cache on first start.
//! - [`state`]: the shared state.
//! - [`router`]: [`router::app`], every route (testable without a socket).
//! - [`http`]: the HTTP endpoints and their error type.
//! - [`tiles`]: the tile pyramid over HTTP (`/v1/tiles.json`, `/v1/tiles/{z}/{x}/{y}`).
//! - [`formats`]: the standard formats over HTTP (`/cesium` quantized-mesh, `/tiles`
//!   terrain-RGB and Terrarium PNGs with TileJSON).
//! - [`pages`]: the CesiumJS and MapLibre pages (`/cesium/`, `/maplibre/`) and the npm
//!   libraries they load (`/lib/...`, from `web/node_modules`).
//! - [`query`]: terrain queries over HTTP (`POST /v1/query`), and the batch computation
//!   query sessions share.
//! - [`raycast`]: `/v1/raycast.png`, a ray-cast picture of a camera's view.
//! - [`pool`]: the background threads, at a lower priority, that run long computations apart
//!   from the sessions' updates.
//! - [`ws`]: the WebSocket upgrade and session admission.
//! - [`session`]: one session's protocol (hello, welcome, flow, closes), generic over
//!   `Sink + Stream`.
//! - [`stream`]: one session's LOD state and deltas, without I/O.
//! - [`validate`]: checks of client-supplied lenses, cameras and parameters.
//! - [`limits`]: session counts per server and per address, and the connection rate.
//! - [`metrics`]: counters and the Prometheus exposition.
//! - [`stall`]: the write timeout of HTTP connections.
//! - [`listen`]: the accept loop with the header timeout, and the drain.

pub mod config;
pub mod formats;
pub mod http;
pub mod limits;
pub mod listen;
pub mod metrics;
pub mod pages;
pub mod pool;
pub mod query;
pub mod raycast;
pub mod router;
pub mod session;
pub mod source;
pub mod stall;
pub mod state;
pub mod stream;
pub mod tiles;
pub mod validate;
pub mod ws;

pub use config::{ServeArgs, ServeConfig};

use state::{AppState, Terrain};
use std::net::SocketAddr;
use std::sync::Arc;
use tokio::net::TcpListener;
use tokio::sync::watch;

/// Why the server could not start or stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// The address cannot be bound.
    #[error("cannot listen on {addr}: {source}")]
    Bind {
        /// The address.
        addr: SocketAddr,
        /// Why.
        source: std::io::Error,
    },
    /// The terrain cannot be opened.
    #[error(transparent)]
    Terrain(#[from] source::SourceError),
}

/// A bound server, not yet serving.
pub struct Server {
    /// The listening socket.
    listener: TcpListener,
    /// The shared state.
    state: Arc<AppState>,
    /// Turns the state's draining flag on.
    draining: watch::Sender<bool>,
    /// What to serve and where to cache it.
    config: ServeConfig,
}

impl Server {
    /// Binds the configured address (port 0 picks a free one).
    pub async fn bind(config: ServeConfig) -> Result<Server, ServeError> {
        source::check_exists(&config.source)?;
        let listener = TcpListener::bind(config.addr)
            .await
            .map_err(|source| ServeError::Bind {
                addr: config.addr,
                source,
            })?;
        let (draining, rx) = watch::channel(false);
        let mut limits = config.limits.clone();
        limits.max_connections = listen::fit_connections(limits.max_connections);
        Ok(Server {
            listener,
            state: Arc::new(
                AppState::new(limits, rx)
                    .with_web_lib(config.web_lib.clone())
                    .with_public_url(config.public_url.clone()),
            ),
            draining,
            config,
        })
    }

    /// The bound address.
    pub fn local_addr(&self) -> SocketAddr {
        self.listener.local_addr().unwrap_or(self.config.addr)
    }

    /// The shared state (for tests and embedding).
    pub fn state(&self) -> Arc<AppState> {
        self.state.clone()
    }

    /// Serves until `shutdown` completes, then drains. The terrain is opened (and built, if it
    /// must be) in the background; `/readyz` turns ready when it is mapped. A terrain that cannot
    /// be opened stops the server with that error.
    pub async fn run(self, shutdown: impl Future<Output = ()>) -> Result<(), ServeError> {
        crate::return_freed_memory();
        let (src, cache) = (self.config.source.clone(), self.config.cache_dir.clone());
        let mut loader = tokio::task::spawn_blocking(move || source::open_terrain(&src, &cache));
        let state = self.state.clone();
        let (failed_tx, failed_rx) = tokio::sync::oneshot::channel();
        tokio::spawn(async move {
            match (&mut loader).await {
                Ok(Ok(store)) => {
                    let t = Terrain::new(store);
                    tracing::info!(
                        "ready: {}x{} samples, terrain {:016x}",
                        t.info.width,
                        t.info.height,
                        t.info.id
                    );
                    let _ = state.terrain.set(Arc::new(t));
                }
                Ok(Err(e)) => {
                    let _ = failed_tx.send(e);
                }
                Err(e) => tracing::error!("terrain loader failed: {e}"),
            }
        });
        let (failure_tx, mut failure_rx) = tokio::sync::oneshot::channel();
        let stop = async move {
            tokio::select! {
                _ = shutdown => {}
                // A dropped sender (the terrain loaded) disables this branch.
                Ok(e) = failed_rx => {
                    let _ = failure_tx.send(e);
                }
            }
        };
        let addr = self.local_addr();
        tracing::info!("listening on http://{addr}");
        pages::log_start(addr, &self.state.web_lib);
        listen::serve(self.listener, self.state, self.draining, stop).await;
        match failure_rx.try_recv() {
            Ok(e) => Err(e.into()),
            Err(_) => Ok(()),
        }
    }
}

/// Completes on SIGTERM or Ctrl-C.
pub async fn signal() {
    let ctrl_c = tokio::signal::ctrl_c();
    #[cfg(unix)]
    {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut term) => {
                tokio::select! {
                    _ = ctrl_c => {}
                    _ = term.recv() => {}
                }
            }
            Err(_) => {
                let _ = ctrl_c.await;
            }
        }
    }
    #[cfg(not(unix))]
    {
        let _ = ctrl_c.await;
    }
    tracing::info!("shutdown signal received");
}

/// Runs the server of `config` until SIGTERM or Ctrl-C.
pub async fn run(config: ServeConfig) -> Result<(), ServeError> {
    Server::bind(config).await?.run(signal()).await
}
