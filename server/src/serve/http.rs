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
use axum::http::{HeaderMap, StatusCode, header};
use axum::response::{IntoResponse, Response};
use relief_proto::close::CloseReason;
use relief_proto::codec;
use relief_proto::cut::Cut;
use relief_proto::delta::Known;
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
    /// The body did not arrive within the body timeout.
    #[error("{0}")]
    Timeout(String),
    /// The body is larger than the endpoint takes.
    #[error("{0}")]
    TooLarge(String),
    /// The server is at a limit; retry later.
    #[error("{0}")]
    Unavailable(String),
    /// The client's address is at a limit.
    #[error("{0}")]
    TooMany(String),
    /// The request's credentials are wrong.
    #[error("{0}")]
    Unauthorized(String),
    /// The request's target is longer than the server reads.
    #[error("{0}")]
    UriTooLong(String),
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
            ApiError::Timeout(_) => StatusCode::REQUEST_TIMEOUT,
            ApiError::TooLarge(_) => StatusCode::PAYLOAD_TOO_LARGE,
            ApiError::Unavailable(_) => StatusCode::SERVICE_UNAVAILABLE,
            ApiError::TooMany(_) => StatusCode::TOO_MANY_REQUESTS,
            ApiError::Unauthorized(_) => StatusCode::UNAUTHORIZED,
            ApiError::UriTooLong(_) => StatusCode::URI_TOO_LONG,
            ApiError::Internal => StatusCode::INTERNAL_SERVER_ERROR,
        };
        (
            status,
            Json(serde_json::json!({ "error": self.to_string() })),
        )
            .into_response()
    }
}

/// A query string, refused with a JSON [`ApiError`] (400) naming the parameter, where axum's
/// own extractor answers in plain text.
pub struct ApiQuery<T>(pub T);

impl<T, S> axum::extract::FromRequestParts<S> for ApiQuery<T>
where
    T: serde::de::DeserializeOwned,
    S: Send + Sync,
{
    type Rejection = ApiError;

    async fn from_request_parts(
        parts: &mut axum::http::request::Parts,
        state: &S,
    ) -> Result<Self, ApiError> {
        match axum::extract::Query::<T>::from_request_parts(parts, state).await {
            Ok(axum::extract::Query(v)) => Ok(ApiQuery(v)),
            Err(e) => Err(ApiError::BadRequest(format!(
                "bad query string: {}",
                e.body_text()
                    .trim_start_matches("Failed to deserialize query string: ")
            ))),
        }
    }
}

/// Longest request target (path and query) the server reads, bytes; longer ones get 414.
pub const MAX_URI_BYTES: usize = 8192;

/// Refuses a request whose target is longer than [`MAX_URI_BYTES`] with a JSON 414.
pub async fn uri_limit(req: axum::extract::Request, next: axum::middleware::Next) -> Response {
    let len = req.uri().path_and_query().map_or(0, |p| p.as_str().len());
    if len > MAX_URI_BYTES {
        return ApiError::UriTooLong(format!(
            "the request target is {len} bytes; at most {MAX_URI_BYTES}"
        ))
        .into_response();
    }
    next.run(req).await
}

/// How long clients and caches may keep a tile without asking again, seconds.
pub const MAX_AGE_S: u32 = 86_400;

/// 304 Not Modified (with the tag and caching headers) when `If-None-Match` names `etag`: for
/// resources that never change for a terrain (tiles).
pub fn not_modified(headers: &HeaderMap, etag: &str) -> Option<Response> {
    let matches = headers
        .get(header::IF_NONE_MATCH)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.split(',').any(|e| e.trim() == etag || e.trim() == "*"));
    matches.then(|| {
        (
            StatusCode::NOT_MODIFIED,
            [
                (header::ETAG, etag.to_string()),
                (
                    header::CACHE_CONTROL,
                    format!("public, max-age={MAX_AGE_S}"),
                ),
            ],
        )
            .into_response()
    })
}

/// The answer when the background pool gave no result: the server is stopping, or the
/// computation failed (logged where it happened).
pub(super) fn background_failed(e: super::pool::PoolError) -> ApiError {
    match e {
        super::pool::PoolError::Stopping => ApiError::NotReady,
        super::pool::PoolError::Panicked => ApiError::Internal,
    }
}

pub(super) fn ready(state: &AppState) -> Result<Arc<Terrain>, ApiError> {
    state.terrain().ok_or(ApiError::NotReady)
}

/// Reads a whole request body of at most `max` bytes, within the body timeout: a client that
/// sends its body slowly (or not at all) holds nothing for longer than that.
pub(super) async fn read_body(
    state: &AppState,
    body: Body,
    max: usize,
) -> Result<axum::body::Bytes, ApiError> {
    let limit = state.limits.body_timeout;
    // A body declared larger than the endpoint takes is refused before any of it is read, so
    // an `Expect: 100-continue` client is never told to send it.
    let declared = axum::body::HttpBody::size_hint(&body).lower();
    if declared > max as u64 {
        state.metrics.error(super::metrics::ErrorKind::BadRequest);
        return Err(ApiError::TooLarge(format!(
            "the request body of {declared} bytes is larger than {max} bytes"
        )));
    }
    match tokio::time::timeout(limit, axum::body::to_bytes(body, max)).await {
        Err(_) => {
            state.metrics.error(super::metrics::ErrorKind::BodyTimeout);
            Err(ApiError::Timeout(format!(
                "the request body did not arrive within {:.0} s",
                limit.as_secs_f64()
            )))
        }
        Ok(Ok(b)) => Ok(b),
        Ok(Err(e)) => {
            state.metrics.error(super::metrics::ErrorKind::BadRequest);
            let too_large = std::error::Error::source(&e)
                .is_some_and(|s| s.is::<http_body_util::LengthLimitError>());
            Err(if too_large {
                ApiError::TooLarge(format!("the request body is larger than {max} bytes"))
            } else {
                ApiError::BadRequest(format!("the request body is unreadable: {e}"))
            })
        }
    }
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
        "bounds_lonlat": meta.bounds.map(|b| b.to_array()),
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
    // The body first, within the body timeout; then a background slot. A slow body holds
    // no slot, and a waiting request holds at most one message.
    let body = read_body(&state, body, state.limits.max_message_bytes as usize).await?;
    let max = state.limits.max_message_bytes as usize;
    let max_nodes = state.limits.max_cut_nodes as usize;
    let st = state.clone();
    // Decoding, checks and the step, in one trip to the background pool (one turn in its queue).
    let work = state.background.run(move || -> Result<Vec<u8>, String> {
        let req: LodRequest = codec::decode(&body, max).map_err(|e| e.to_string())?;
        if req.version != PROTOCOL_VERSION {
            return Err(format!(
                "protocol version {} is not supported; this server speaks {PROTOCOL_VERSION}",
                req.version
            ));
        }
        validate::params(&req.lens, req.tau, None)?;
        let camera = validate::camera(&req.camera, &t.info)?;
        if let Some(b) = &req.base
            && b.terrain_id != t.info.id
        {
            return Err(format!(
                "the base cut is for terrain {:016x}; this server holds {:016x}",
                b.terrain_id, t.info.id
            ));
        }
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
        if target.interior_count() >= max_nodes {
            return Err(format!(
                "{}: {}",
                CloseReason::CutLimit.name(),
                validate::cut_limit(max_nodes)
            ));
        }
        let delta = diff_delta(&engine, &base, &target, 1);
        let resp = LodResponse {
            delta: WireDelta::pack(
                &delta,
                shape,
                engine.geometry().z_quantum,
                Known {
                    parents: &engine,
                    cut: &target,
                },
            ),
            snapshot: Snapshot::of(shape, &target),
        };
        st.metrics.observe_update(started.elapsed().as_secs_f64());
        Ok(codec::encode(&resp))
    });
    let bytes = work.await.map_err(background_failed)?.map_err(bad)?;
    state
        .metrics
        .bytes_out_total
        .fetch_add(bytes.len() as u64, Relaxed);
    Ok(([(header::CONTENT_TYPE, BINARY)], bytes).into_response())
}

/// Most points in one `POST /v1/heights` request.
pub const MAX_HEIGHT_POINTS: usize = 50_000;

/// Largest `POST /v1/heights` body, bytes: [`MAX_HEIGHT_POINTS`] points written by any JSON
/// library at full `f64` precision (`[-1234567.8901234567,-1234567.8901234567],` is 42 bytes;
/// 64 leaves room for spaces and exponents).
pub const MAX_HEIGHTS_BODY: usize = 64 * MAX_HEIGHT_POINTS + 1024;

/// The body of `POST /v1/heights`.
#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HeightsRequest {
    /// World positions `[x, y]` in metres.
    pub points: Vec<[f64; 2]>,
}

/// `POST /v1/heights`: terrain heights in metres at world positions (the nearest sample's,
/// as stored; `null` outside the grid). JSON in, JSON out.
pub async fn heights(State(state): State<Arc<AppState>>, body: Body) -> Result<Response, ApiError> {
    let t = ready(&state)?;
    let body = read_body(&state, body, MAX_HEIGHTS_BODY).await?;
    let bad = |e: String| {
        state.metrics.error(super::metrics::ErrorKind::BadRequest);
        ApiError::BadRequest(e)
    };
    // Parsing and writing up to 3 MB of JSON take milliseconds: on the background pool, not
    // on an async worker that other connections share.
    let json = state
        .background
        .run(move || -> Result<Vec<u8>, String> {
            let req: HeightsRequest = serde_json::from_slice(&body)
                .map_err(|e| format!("the body is not a heights request: {e}"))?;
            if req.points.len() > MAX_HEIGHT_POINTS {
                return Err(format!(
                    "{} points requested; at most {MAX_HEIGHT_POINTS} per request",
                    req.points.len()
                ));
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
            serde_json::to_vec(&serde_json::json!({ "heights": out })).map_err(|e| e.to_string())
        })
        .await
        .map_err(background_failed)?
        .map_err(bad)?;
    Ok(([(header::CONTENT_TYPE, "application/json")], json).into_response())
}

/// `GET /v1/sessions`: the open sessions as JSON. Clients' addresses are personal data: they
/// are listed only for a request with `Authorization: Bearer <operator token>`, and a request
/// with a wrong token is refused (401).
pub async fn sessions(
    State(state): State<Arc<AppState>>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let with_peers = match headers.get(header::AUTHORIZATION) {
        None => false,
        Some(v) => {
            let given = v.to_str().ok().and_then(|v| v.strip_prefix("Bearer "));
            match (&state.limits.operator_token, given) {
                (Some(t), Some(g)) if constant_time_eq(t.0.as_bytes(), g.trim().as_bytes()) => true,
                _ => {
                    return Err(ApiError::Unauthorized(
                        "the bearer token is not the server's operator token".into(),
                    ));
                }
            }
        }
    };
    Ok(Json(state.session_reports(with_peers)).into_response())
}

/// Compares two secrets in a time that does not depend on where they first differ.
fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
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
