//! The tile pyramid over HTTP, for clients that select tiles themselves (DESIGN.md section 4):
//! `GET /v1/tiles.json` describes the pyramid, `GET /v1/tiles/{z}/{x}/{y}` returns one tile
//! with its crack patches. Tiles never change for a terrain, so each carries a strong `ETag`
//! (the terrain id, the tile and the crack mode) and `Cache-Control`; a matching
//! `If-None-Match` gets `304 Not Modified`. The router gzips both for clients that accept it.
//!
//! A tile's body is the record of an added tile in a tile delta without its index: `varint`
//! mesh length, `varint` patch length, the mesh blob, the patch blob (`docs/protocol.md`).

use super::http::{ApiError, ApiQuery, BINARY, MAX_AGE_S, not_modified};
use super::state::AppState;
use axum::Json;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, header};
use axum::response::{IntoResponse, Response};
use relief_proto::tile::TileId;
use relief_proto::tile::delta::put_varint;
use serde::Deserialize;
use std::sync::Arc;

/// The query of a tile request.
#[derive(Debug, Deserialize)]
pub struct TileQuery {
    /// `patches` (default), or `skirts` or `none`: whether the body carries the patch blob
    /// (skirts are built by the client from the mesh alone).
    crack: Option<String>,
}

/// `GET /v1/tiles.json`: the pyramid's description.
pub async fn tileset(State(state): State<Arc<AppState>>) -> Result<Response, ApiError> {
    let t = state.terrain().ok_or(ApiError::NotReady)?;
    let shape = t.store.tile_shape();
    let info = t.store.tile_info();
    let levels: Vec<_> = (0..=shape.depth())
        .map(|k| {
            let (nx, ny) = shape.level_dims(k);
            serde_json::json!({
                "level": k,
                "tiles": [nx, ny],
                "stride_samples": shape.stride(k),
                "max_error_m": info.level_errors[k as usize],
            })
        })
        .collect();
    Ok(Json(serde_json::json!({
        "terrain_id": format!("{:016x}", t.info.id),
        "width": t.info.width,
        "height": t.info.height,
        "spacing_m": [t.info.spacing_x, t.info.spacing_y],
        "z_quantum_m": t.info.z_quantum,
        "tile_size": info.tile_size,
        "depth": info.depth,
        "mesh": info.mesh,
        "tile_count": shape.tile_count(),
        "levels": levels,
        "tiles": "/v1/tiles/{z}/{x}/{y}",
        "crack": ["patches", "skirts", "none"],
        "skirt_height_rule": "5 x max_error_m of the level above (level 0: its own)",
        "protocol_version": relief_proto::msg::PROTOCOL_VERSION,
    }))
    .into_response())
}

/// `GET /v1/tiles/{z}/{x}/{y}[?crack=patches|none]`: one tile with its crack patches.
pub async fn tile(
    State(state): State<Arc<AppState>>,
    Path((z, x, y)): Path<(String, String, String)>,
    ApiQuery(q): ApiQuery<TileQuery>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let t = state.terrain().ok_or(ApiError::NotReady)?;
    let bad = |e: String| {
        state.metrics.error(super::metrics::ErrorKind::BadRequest);
        ApiError::BadRequest(e)
    };
    let num = |what: &str, v: &str| {
        v.parse::<u32>()
            .map_err(|_| bad(format!("tile {what} {v:?} is not a non-negative integer")))
    };
    let (z, x, y) = (num("level", &z)?, num("column", &x)?, num("row", &y)?);
    let patches = match q.crack.as_deref() {
        None | Some("patches") => true,
        Some("none" | "skirts") => false,
        Some(o) => {
            return Err(bad(format!(
                "crack {o:?} is not one of patches, skirts, none"
            )));
        }
    };
    let shape = t.store.tile_shape();
    if z > u32::from(shape.depth()) {
        return Err(ApiError::NotFoundWhy(format!(
            "level {z} does not exist: levels go from 0 to {}",
            shape.depth()
        )));
    }
    let tile = TileId {
        level: z as u8,
        x,
        y,
    };
    if !shape.contains(tile) {
        let (nx, ny) = shape.level_dims(tile.level);
        return Err(ApiError::NotFoundWhy(format!(
            "tile {z}/{x}/{y} does not exist: level {z} has {nx} x {ny} tiles"
        )));
    }
    let index = shape.index(tile);
    let etag = format!(
        "\"{:016x}-{index}-{}\"",
        t.info.id,
        if patches { "p" } else { "n" }
    );
    if let Some(r) = not_modified(&headers, &etag) {
        return Ok(r);
    }
    let cache = format!("public, max-age={MAX_AGE_S}");
    let (mesh, patch) = t.store.tile_blobs(index);
    let patch = if patches { patch } else { &[] };
    let mut body = Vec::with_capacity(mesh.len() + patch.len() + 8);
    put_varint(&mut body, mesh.len() as u32);
    put_varint(&mut body, patch.len() as u32);
    body.extend_from_slice(mesh);
    body.extend_from_slice(patch);
    Ok((
        [
            (header::CONTENT_TYPE, BINARY.to_string()),
            (header::ETAG, etag),
            (header::CACHE_CONTROL, cache),
        ],
        body,
    )
        .into_response())
}
