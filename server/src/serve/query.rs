//! Terrain queries over HTTP (`POST /v1/query`, JSON or binary by content type) and the
//! computation both it and query sessions ([`super::session`]) run: a batch checked against the
//! limits, then answered item by item by [`crate::query::Terrain::answer_all`], on a blocking
//! thread holding a computation slot unless it is small.

use super::http::{ApiError, BINARY, read_body, ready};
use super::metrics::ErrorKind;
use super::state::{AppState, Terrain};
use axum::Json;
use axum::body::Body;
use axum::extract::State;
use axum::http::{HeaderMap, header};
use axum::response::{IntoResponse, Response};
use relief_proto::codec;
use relief_proto::query::{Answer, AnswerBatch, Fault, Query, QueryBatch, check_batch, check_len};
use std::sync::Arc;
use std::sync::atomic::Ordering::Relaxed;

/// Largest `POST /v1/query` body, bytes: a full batch of heights as JSON at full precision
/// (about 60 bytes each), or a full binary batch of rays (49 bytes each).
pub const MAX_QUERY_BODY: usize = 8 << 20;

/// Estimated microseconds below which a batch is answered on the async worker: less than the
/// trip to a blocking thread and back costs in latency under load.
const INLINE_US: f64 = 100.0;

/// Why a batch was not answered.
pub enum BatchError {
    /// Over the limits; the reason says which.
    Refused(String),
    /// The terrain cannot be queried, or the computation failed (logged).
    Unavailable(String),
}

/// Answers `batch` against the terrain: inline when it is small, else on a blocking thread
/// holding one of the server's computation slots.
pub async fn answer(
    state: &AppState,
    terrain: &Arc<Terrain>,
    batch: QueryBatch,
) -> Result<AnswerBatch, BatchError> {
    check_batch(&batch.queries).map_err(BatchError::Refused)?;
    if let Err(e) = &terrain.query {
        return Err(BatchError::Unavailable(format!(
            "this terrain cannot be queried: {e}"
        )));
    }
    let n = batch.queries.len() as u64;
    let lines = batch.queries.iter().filter(|q| q.is_line()).count();
    let cost_us = 0.25 * (batch.queries.len() - lines) as f64 + 5.0 * lines as f64;
    let run = move |t: &Terrain, batch: QueryBatch| {
        let mut answers = Vec::with_capacity(batch.queries.len());
        if let Ok(q) = &t.query {
            q.answer_all(&batch.queries, &mut answers);
        }
        AnswerBatch {
            id: batch.id,
            answers,
        }
    };
    let out = if cost_us <= INLINE_US {
        run(terrain, batch)
    } else {
        let _slot = state
            .one_shots
            .acquire()
            .await
            .map_err(|_| BatchError::Unavailable("the server is stopping".into()))?;
        let t = terrain.clone();
        tokio::task::spawn_blocking(move || run(&t, batch))
            .await
            .map_err(|e| {
                tracing::error!("query batch failed: {e}");
                BatchError::Unavailable("the query computation failed".into())
            })?
    };
    state.metrics.query_batches_total.fetch_add(1, Relaxed);
    state.metrics.queries_total.fetch_add(n, Relaxed);
    Ok(out)
}

/// The JSON body of `POST /v1/query`: queries are read one by one, so that an item that is
/// not a query gets its own error instead of failing the batch.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct JsonBatch {
    /// The batch's id (0 when absent).
    #[serde(default)]
    id: u64,
    /// The items, each parsed on its own.
    queries: Vec<serde_json::Value>,
}

/// `POST /v1/query`: a batch of queries, answered in order. `Content-Type:
/// application/octet-stream` sends a binary [`QueryBatch`] and gets a binary [`AnswerBatch`];
/// anything else is read as JSON and answered in JSON.
pub async fn query(
    State(state): State<Arc<AppState>>,
    headers: HeaderMap,
    body: Body,
) -> Result<Response, ApiError> {
    let t = ready(&state)?;
    let body = read_body(&state, body, MAX_QUERY_BODY).await?;
    let bad = |e: String| {
        state.metrics.error(ErrorKind::BadRequest);
        ApiError::BadRequest(e)
    };
    let binary = headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.starts_with(BINARY));
    // A JSON item that is not a query is answered with its own error, at its place.
    let mut malformed: Vec<(usize, String)> = Vec::new();
    let batch = if binary {
        codec::decode::<QueryBatch>(&body, MAX_QUERY_BODY)
            .map_err(|e| bad(format!("the body is not a binary query batch: {e}")))?
    } else {
        let j: JsonBatch = serde_json::from_slice(&body)
            .map_err(|e| bad(format!("the body is not a query batch: {e}")))?;
        check_len(j.queries.len()).map_err(bad)?;
        let queries = j
            .queries
            .into_iter()
            .enumerate()
            .map(|(i, v)| {
                serde_json::from_value::<Query>(v).unwrap_or_else(|e| {
                    malformed.push((i, format!("item {i} is not a query: {e}")));
                    // A placeholder that costs nothing; its answer is replaced below.
                    Query::Height {
                        at: [f64::NAN, f64::NAN],
                        bicubic: false,
                    }
                })
            })
            .collect();
        QueryBatch { id: j.id, queries }
    };
    let mut out = match answer(&state, &t, batch).await {
        Ok(a) => a,
        Err(BatchError::Refused(why)) => return Err(bad(why)),
        Err(BatchError::Unavailable(why)) => return Err(ApiError::Unavailable(why)),
    };
    for (i, message) in malformed {
        out.answers[i] = Answer::Error {
            fault: Fault::Malformed,
            message,
        };
    }
    let response = if binary {
        let bytes = codec::encode(&out);
        state
            .metrics
            .bytes_out_total
            .fetch_add(bytes.len() as u64, Relaxed);
        ([(header::CONTENT_TYPE, BINARY)], bytes).into_response()
    } else {
        Json(out).into_response()
    };
    Ok(response)
}
