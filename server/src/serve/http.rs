//! The HTTP endpoints (DESIGN.md section 6, "HTTP"): terrain metadata, the stateless one-shot,
//! the session list, metrics, health and readiness. Errors go through [`ApiError`], which
//! answers with a status and a one-line JSON message and never leaks internals.

use super::state::{AppState, Terrain};
use super::validate;
use crate::lod::vertex::diff::diff_delta;
use crate::lod::vertex::{LodParams, UpdateStats, VertexEngine};
use axum::Json;
use axum::body::Body;
use axum::extract::State;
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use relief_proto::codec;
use relief_proto::cut::Cut;
use relief_proto::msg::{LodRequest, LodResponse, PROTOCOL_VERSION, WireDelta};
use relief_proto::snapshot::Snapshot;
use relief_proto::view::ViewState;
use std::sync::Arc;
use std::sync::atomic::Ordering::Relaxed;
use std::time::Instant;

/// The media type of binary protocol bodies.
pub const BINARY: &str = "application/octet-stream";

/// An HTTP error.
#[derive(Debug, thiserror::Error)]
pub enum ApiError {
    /// The terrain is not mapped yet.
    #[error("the server is starting: the terrain is not ready yet")]
    NotReady,
    /// The request is wrong; the message says how.
    #[error("{0}")]
    BadRequest(String),
    /// No such route.
    #[error("no such endpoint")]
    NotFound,
    /// No such resource; the message says why.
    #[error("{0}")]
    NotFoundWhy(String),
    /// A server fault (details are logged, not sent).
    #[error("internal error")]
    Internal,
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let status = match self {
            ApiError::NotReady => StatusCode::SERVICE_UNAVAILABLE,
            ApiError::BadRequest(_) => StatusCode::BAD_REQUEST,
            ApiError::NotFound | ApiError::NotFoundWhy(_) => StatusCode::NOT_FOUND,
            ApiError::Internal => StatusCode::INTERNAL_SERVER_ERROR,
        };
        (
            status,
            Json(serde_json::json!({ "error": self.to_string() })),
        )
            .into_response()
    }
}

fn ready(state: &AppState) -> Result<Arc<Terrain>, ApiError> {
    state.terrain().ok_or(ApiError::NotReady)
}

/// `GET /v1/terrain`: the terrain's metadata as JSON.
pub async fn terrain(State(state): State<Arc<AppState>>) -> Result<Response, ApiError> {
    let t = ready(&state)?;
    let i = &t.info;
    let meta = t.store.meta();
    Ok(Json(serde_json::json!({
        "id": format!("{:016x}", i.id),
        "width": i.width,
        "height": i.height,
        "depth": t.store.geometry().shape.depth(),
        "spacing_m": [i.spacing_x, i.spacing_y],
        "z_quantum_m": i.z_quantum,
        "root_z": i.root_z,
        "height_range_m": i.height_range,
        "extent_m": [i.width.saturating_sub(1) as f32 * i.spacing_x,
                     i.height.saturating_sub(1) as f32 * i.spacing_y],
        "source": meta.source,
        "crs": meta.crs,
        "void_count": meta.void_count,
        "protocol_version": PROTOCOL_VERSION,
    }))
    .into_response())
}

/// `POST /v1/lod`: one stateless LOD step. The body is a [`LodRequest`], the answer a
/// [`LodResponse`], both in the binary codec.
pub async fn lod(State(state): State<Arc<AppState>>, body: Body) -> Result<Response, ApiError> {
    let t = ready(&state)?;
    let bad = |e: String| {
        state.metrics.error(super::metrics::ErrorKind::BadRequest);
        ApiError::BadRequest(e)
    };
    // Read the body only when a computation slot is free.
    let _slot = state
        .one_shots
        .acquire()
        .await
        .map_err(|_| ApiError::NotReady)?;
    let max = state.limits.max_message_bytes as usize;
    let body = axum::body::to_bytes(body, max)
        .await
        .map_err(|_| bad(format!("the body is unreadable or larger than {max} bytes")))?;
    let req: LodRequest = codec::decode(&body, state.limits.max_message_bytes as usize)
        .map_err(|e| bad(e.to_string()))?;
    if req.version != PROTOCOL_VERSION {
        return Err(bad(format!(
            "protocol version {} is not supported; this server speaks {PROTOCOL_VERSION}",
            req.version
        )));
    }
    validate::params(&req.lens, req.tau, None).map_err(bad)?;
    let camera = validate::camera(&req.camera, &t.info).map_err(bad)?;
    if let Some(b) = &req.base
        && b.terrain_id != t.info.id
    {
        return Err(bad(format!(
            "the base cut is for terrain {:016x}; this server holds {:016x}",
            b.terrain_id, t.info.id
        )));
    }
    let max_nodes = state.limits.max_cut_nodes as usize;
    let st = state.clone();
    let work = tokio::task::spawn_blocking(move || -> Result<Vec<u8>, String> {
        let started = Instant::now();
        let engine = VertexEngine::new(&t.store);
        let shape = &engine.geometry().shape;
        let base = match &req.base {
            Some(b) => b
                .snapshot
                .to_cut(shape, max_nodes)
                .map_err(|e| format!("bad base cut: {e}"))?,
            None => Cut::root(shape),
        };
        let params = LodParams {
            tau: req.tau,
            ..LodParams::default()
        };
        let view = ViewState::new(&camera, &req.lens.into());
        let target = engine.initial_cut(&view, &params, &mut UpdateStats::default());
        let delta = diff_delta(&engine, &base, &target, 1);
        let resp = LodResponse {
            delta: WireDelta::pack(&delta, shape, engine.geometry().z_quantum),
            snapshot: Snapshot::of(shape, &target),
        };
        st.metrics.observe_update(started.elapsed().as_secs_f64());
        Ok(codec::encode(&resp))
    });
    let bytes = work
        .await
        .map_err(|e| {
            tracing::error!("one-shot update failed: {e}");
            ApiError::Internal
        })?
        .map_err(bad)?;
    state
        .metrics
        .bytes_out_total
        .fetch_add(bytes.len() as u64, Relaxed);
    Ok(([(header::CONTENT_TYPE, BINARY)], bytes).into_response())
}

/// Most points in one `POST /v1/heights` request.
pub const MAX_HEIGHT_POINTS: usize = 50_000;

/// The body of `POST /v1/heights`.
#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HeightsRequest {
    /// World positions `[x, y]` in metres.
    pub points: Vec<[f64; 2]>,
}

/// `POST /v1/heights`: terrain heights in metres at world positions (the nearest sample's,
/// as stored; `null` outside the grid). JSON in, JSON out.
pub async fn heights(
    State(state): State<Arc<AppState>>,
    body: Result<Json<HeightsRequest>, axum::extract::rejection::JsonRejection>,
) -> Result<Response, ApiError> {
    let t = ready(&state)?;
    let Json(req) = body.map_err(|e| {
        state.metrics.error(super::metrics::ErrorKind::BadRequest);
        ApiError::BadRequest(e.body_text())
    })?;
    if req.points.len() > MAX_HEIGHT_POINTS {
        state.metrics.error(super::metrics::ErrorKind::BadRequest);
        return Err(ApiError::BadRequest(format!(
            "{} points requested; at most {MAX_HEIGHT_POINTS} per request",
            req.points.len()
        )));
    }
    let g = t.store.geometry();
    let (w, h) = (g.shape.width(), g.shape.height());
    let out: Vec<Option<f32>> = req
        .points
        .iter()
        .map(|&[x, y]| {
            let (c, r) = g.frame.to_grid(x as f32, y as f32);
            let (c, r) = (c.round(), r.round());
            if !(c >= 0.0 && r >= 0.0 && c < w as f32 && r < h as f32) {
                return None;
            }
            Some(t.store.sample_z(c as u32, r as u32) as f32 * g.z_quantum)
        })
        .collect();
    Ok(Json(serde_json::json!({ "heights": out })).into_response())
}

/// `GET /v1/sessions`: the open sessions as JSON.
pub async fn sessions(State(state): State<Arc<AppState>>) -> Response {
    Json(state.session_reports()).into_response()
}

/// `GET /metrics`: Prometheus text.
pub async fn metrics(State(state): State<Arc<AppState>>) -> Response {
    (
        [(
            header::CONTENT_TYPE,
            "text/plain; version=0.0.4; charset=utf-8",
        )],
        state.metrics.render(),
    )
        .into_response()
}

/// `GET /healthz`: the process is up.
pub async fn healthz() -> &'static str {
    "ok\n"
}

/// `GET /readyz`: 200 once the terrain is mapped, 503 before and while draining.
pub async fn readyz(State(state): State<Arc<AppState>>) -> Result<&'static str, ApiError> {
    ready(&state)?;
    if *state.draining.borrow() {
        return Err(ApiError::NotReady);
    }
    Ok("ready\n")
}

/// Any other path.
pub async fn not_found() -> ApiError {
    ApiError::NotFound
}
