//! Terrain queries over HTTP (`POST /v1/query`, JSON or binary by content type) and the
//! computation both it and query sessions ([`super::session`]) run: a batch checked against the
//! limits, then answered item by item by [`crate::query::Terrain::answer_all`], on the background
//! pool ([`super::pool`]) unless it is small.

use super::http::{ApiError, BINARY, read_body, ready};
use super::metrics::ErrorKind;
use super::state::{AppState, Terrain};
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

/// Answers `batch` against the terrain, on the calling thread.
fn answer_now(terrain: &Terrain, batch: QueryBatch) -> Result<AnswerBatch, BatchError> {
    check_batch(&batch.queries).map_err(BatchError::Refused)?;
    let q = terrain
        .query
        .as_ref()
        .map_err(|e| BatchError::Unavailable(format!("this terrain cannot be queried: {e}")))?;
    let mut answers = Vec::with_capacity(batch.queries.len());
    q.answer_all(&batch.queries, &mut answers);
    Ok(AnswerBatch {
        id: batch.id,
        answers,
    })
}

/// Answers `batch` against the terrain: inline when it is small, else on the background pool.
pub async fn answer(
    state: &AppState,
    terrain: &Arc<Terrain>,
    batch: QueryBatch,
) -> Result<AnswerBatch, BatchError> {
    let n = batch.queries.len() as u64;
    let lines = batch.queries.iter().filter(|q| q.is_line()).count();
    let cost_us = 0.25 * (batch.queries.len() - lines) as f64 + 5.0 * lines as f64;
    let out = if cost_us <= INLINE_US {
        answer_now(terrain, batch)?
    } else {
        let t = terrain.clone();
        state
            .background
            .run(move || answer_now(&t, batch))
            .await
            .map_err(|e| BatchError::Unavailable(e.to_string()))??
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
/// anything else is read as JSON and answered in JSON. Parsing, answering and writing all run
/// on the background pool: a JSON body of megabytes takes the async workers no time.
pub async fn query(
    State(state): State<Arc<AppState>>,
    headers: HeaderMap,
    body: Body,
) -> Result<Response, ApiError> {
    let t = ready(&state)?;
    let body = read_body(&state, body, MAX_QUERY_BODY).await?;
    let binary = headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.starts_with(BINARY));
    let done = state
        .background
        .run(move || respond(&t, &body, binary))
        .await
        .map_err(super::http::background_failed)?;
    let (bytes, n) = match done {
        Ok(v) => v,
        Err(BatchError::Refused(why)) => {
            state.metrics.error(ErrorKind::BadRequest);
            return Err(ApiError::BadRequest(why));
        }
        Err(BatchError::Unavailable(why)) => return Err(ApiError::Unavailable(why)),
    };
    state.metrics.query_batches_total.fetch_add(1, Relaxed);
    state.metrics.queries_total.fetch_add(n, Relaxed);
    state
        .metrics
        .bytes_out_total
        .fetch_add(bytes.len() as u64, Relaxed);
    let kind = if binary { BINARY } else { "application/json" };
    Ok(([(header::CONTENT_TYPE, kind)], bytes).into_response())
}

/// Parses a `POST /v1/query` body, answers it and writes the answer: the encoded answer batch
/// and the number of queries.
fn respond(t: &Terrain, body: &[u8], binary: bool) -> Result<(Vec<u8>, u64), BatchError> {
    let refused = BatchError::Refused;
    // A JSON item that is not a query is answered with its own error, at its place.
    let mut malformed: Vec<(usize, String)> = Vec::new();
    let batch = if binary {
        codec::decode::<QueryBatch>(body, MAX_QUERY_BODY)
            .map_err(|e| refused(format!("the body is not a binary query batch: {e}")))?
    } else {
        let j: JsonBatch = serde_json::from_slice(body)
            .map_err(|e| refused(format!("the body is not a query batch: {e}")))?;
        check_len(j.queries.len()).map_err(refused)?;
        let queries = j
            .queries
            .into_iter()
            .enumerate()
            .map(|(i, v)| {
                serde_json::from_value::<Query>(v).unwrap_or_else(|e| {
                    malformed.push((
                        i,
                        crate::query::batch::clip(format!("item {i} is not a query: {e}")),
                    ));
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
    let n = batch.queries.len() as u64;
    let mut out = answer_now(t, batch)?;
    for (i, message) in malformed {
        out.answers[i] = Answer::Error {
            fault: Fault::Malformed,
            message,
        };
    }
    let bytes = if binary {
        codec::encode(&out)
    } else {
        serde_json::to_vec(&out).map_err(|e| BatchError::Unavailable(e.to_string()))?
    };
    Ok((bytes, n))
}
