//! The standard formats over HTTP (DESIGN.md section 6b), for CesiumJS and MapLibre with no
//! glue code:
//!
//! - `GET /cesium/layer.json` and `GET /cesium/{z}/{x}/{y}.terrain`: Cesium quantized-mesh-1.0
//!   in the geographic scheme. The `octvertexnormals` and `metadata` extensions are sent when
//!   the `Accept` header asks for them, as CesiumJS does.
//! - `GET /tiles/{encoding}.json[?tile_size=512]` and `GET /tiles/{encoding}/{z}/{x}/{y}.png`
//!   (`{y}@2x.png` for 512 pixels): terrain-RGB or Terrarium PNG tiles in Web Mercator, and
//!   their TileJSON.
//!
//! Tiles never change for a terrain, so each carries a strong `ETag` (terrain id, tile, and
//! what varies the bytes) and `Cache-Control`; a matching `If-None-Match` gets 304. The router
//! adds gzip (for the meshes; PNGs are compressed already) and CORS. Tiles are made on request
//! on the background pool, off the async threads. A terrain without a georeference answers 404
//! with the reason; a malformed z/x/y gets 400, a tile outside the terrain or too deep 404.

use super::http::{ApiError, ApiQuery, MAX_AGE_S, not_modified};
use super::metrics::ErrorKind;
use super::state::{AppState, Terrain};
use crate::formats::cesium::tile_mesh;
use crate::formats::quantized_mesh::{QmExtensions, QmMesh, encode, extensions_from_accept};
use crate::formats::raster::{RasterLayer, tile_png};
use crate::formats::sampler::Resampler;
use crate::formats::terrain_rgb::Encoding;
use crate::geo::tiling::{MAX_LEVEL, TileXyz};
use axum::Json;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, HeaderValue, header};
use axum::response::{IntoResponse, Response};
use serde::Deserialize;
use std::sync::Arc;

/// Cesium's media type for quantized-mesh tiles.
const QUANTIZED_MESH: &str = "application/vnd.quantized-mesh";

/// The terrain and its formats, or 503 / 404 with the reason.
fn georeferenced(state: &AppState) -> Result<Arc<Terrain>, ApiError> {
    let t = state.terrain().ok_or(ApiError::NotReady)?;
    if let Err(why) = &t.formats {
        return Err(ApiError::NotFoundWhy(why.clone()));
    }
    Ok(t)
}

/// Parses a tile address: `z` and `x` as given, `file` as `{y}{suffix}` for one of `suffixes`;
/// returns the tile and the index of the suffix that matched.
fn address(
    state: &AppState,
    z: &str,
    x: &str,
    file: &str,
    suffixes: &[&str],
) -> Result<(TileXyz, usize), ApiError> {
    let bad = |e: String| {
        state.metrics.error(ErrorKind::BadRequest);
        ApiError::BadRequest(e)
    };
    let (y, which) = suffixes
        .iter()
        .enumerate()
        .find_map(|(i, s)| file.strip_suffix(s).map(|y| (y, i)))
        .ok_or_else(|| bad(format!("{file:?} is not {{y}}{}", suffixes.join(" or {y}"))))?;
    let num = |what: &str, v: &str| {
        v.parse::<u32>()
            .map_err(|_| bad(format!("tile {what} {v:?} is not a non-negative integer")))
    };
    let (z, x, y) = (num("level", z)?, num("column", x)?, num("row", y)?);
    if z > u32::from(MAX_LEVEL) {
        return Err(bad(format!(
            "level {z} is deeper than any served ({MAX_LEVEL} at most)"
        )));
    }
    Ok((TileXyz { z: z as u8, x, y }, which))
}

/// Runs `work` (a tile's making) on the background pool, off the async threads.
async fn compute<T: Send + 'static>(
    state: &AppState,
    work: impl FnOnce() -> Result<T, String> + Send + 'static,
) -> Result<T, ApiError> {
    match state.background.run(work).await {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(e)) => {
            tracing::warn!("tile failed: {e}");
            Err(ApiError::Internal)
        }
        Err(super::pool::PoolError::Stopping) => Err(ApiError::NotReady),
        Err(_) => Err(ApiError::Internal),
    }
}

/// A tile's response: its bytes with type, tag and caching; `by_accept` when the bytes
/// depend on the `Accept` header.
fn tile_response(body: Vec<u8>, content_type: String, etag: String, by_accept: bool) -> Response {
    let mut r = (
        [
            (header::CONTENT_TYPE, content_type),
            (header::ETAG, etag),
            (
                header::CACHE_CONTROL,
                format!("public, max-age={MAX_AGE_S}"),
            ),
        ],
        body,
    )
        .into_response();
    if by_accept {
        r.headers_mut()
            .insert(header::VARY, HeaderValue::from_static("Accept"));
    }
    r
}

/// `GET /cesium/layer.json`.
pub async fn cesium_layer(State(state): State<Arc<AppState>>) -> Result<Response, ApiError> {
    let t = georeferenced(&state)?;
    let f = t
        .formats
        .as_ref()
        .map_err(|e| ApiError::NotFoundWhy(e.clone()))?;
    Ok(Json(f.cesium.layer_json(t.store.tile_mesh(), t.info.id)).into_response())
}

/// `GET /cesium/{z}/{x}/{y}.terrain`: one quantized-mesh tile.
pub async fn cesium_tile(
    State(state): State<Arc<AppState>>,
    Path((z, x, file)): Path<(String, String, String)>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let t = georeferenced(&state)?;
    let (tile, _) = address(&state, &z, &x, &file, &[".terrain"])?;
    let layer = &t
        .formats
        .as_ref()
        .map_err(|e| ApiError::NotFoundWhy(e.clone()))?
        .cesium;
    if !layer.available(tile) {
        return Err(ApiError::NotFoundWhy(format!(
            "tile {}/{}/{} is not available: see \"available\" in layer.json",
            tile.z, tile.x, tile.y
        )));
    }
    let accept = headers
        .get(header::ACCEPT)
        .and_then(|v| v.to_str().ok())
        .unwrap_or("");
    let asked = extensions_from_accept(accept);
    let names: Vec<&str> = [
        (asked.normals, "octvertexnormals"),
        (asked.metadata, "metadata"),
    ]
    .iter()
    .filter_map(|&(on, n)| on.then_some(n))
    .collect();
    let etag = format!(
        "\"{:016x}-qm-{}-{}-{}-{}\"",
        t.info.id,
        tile.z,
        tile.x,
        tile.y,
        names.join("-")
    );
    if let Some(r) = not_modified(&headers, &etag) {
        return Ok(r);
    }
    let content_type = if names.is_empty() {
        QUANTIZED_MESH.to_string()
    } else {
        format!("{QUANTIZED_MESH};extensions={}", names.join("-"))
    };
    let terrain = t.clone();
    let body = compute(&state, move || {
        let f = terrain.formats.as_ref().map_err(Clone::clone)?;
        let r = Resampler::new(&terrain.store, &f.geo);
        let m = tile_mesh(&r, terrain.store.tile_mesh(), tile);
        let mesh = QmMesh {
            west: m.bounds.west,
            south: m.bounds.south,
            east: m.bounds.east,
            north: m.bounds.north,
            vertices: m.vertices,
            triangles: m.triangles,
        };
        let ext = QmExtensions {
            normals: asked.normals,
            metadata: asked.metadata.then(|| f.cesium.metadata(tile)),
        };
        encode(&mesh, &ext).map_err(|e| e.to_string())
    })
    .await?;
    Ok(tile_response(body, content_type, etag, true))
}

/// The query of a TileJSON request.
#[derive(Debug, Deserialize)]
pub struct TileJsonQuery {
    /// 256 (the default) or 512 pixels a side.
    tile_size: Option<u32>,
}

/// The encoding named in a path, or 404.
fn encoding(name: &str) -> Result<Encoding, ApiError> {
    name.parse::<Encoding>().map_err(|_| {
        ApiError::NotFoundWhy(format!(
            "{name:?} is not an elevation encoding: use terrain-rgb or terrarium"
        ))
    })
}

/// The terrain's Web Mercator layer at `size` pixels.
fn raster_layer(t: &Terrain, size: u32) -> Result<&RasterLayer, ApiError> {
    let f = t
        .formats
        .as_ref()
        .map_err(|e| ApiError::NotFoundWhy(e.clone()))?;
    Ok(if size == 512 {
        &f.raster[1]
    } else {
        &f.raster[0]
    })
}

/// `GET /tiles/{encoding}.json`: the TileJSON of an encoding's tiles.
pub async fn tilejson(
    State(state): State<Arc<AppState>>,
    Path(file): Path<String>,
    ApiQuery(q): ApiQuery<TileJsonQuery>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let t = georeferenced(&state)?;
    let name = file.strip_suffix(".json").ok_or(ApiError::NotFound)?;
    let enc = encoding(name)?;
    let size = q.tile_size.unwrap_or(256);
    if !crate::formats::raster::TILE_SIZES.contains(&size) {
        state.metrics.error(ErrorKind::BadRequest);
        return Err(ApiError::BadRequest(format!(
            "tile_size {size} is not 256 or 512"
        )));
    }
    let layer = raster_layer(&t, size)?;
    // Tile URLs are absolute (MapLibre does not resolve relative ones): on the configured
    // public URL, else on the host (and scheme, behind a proxy) the client used.
    let base = match &state.public_url {
        Some(u) => u.clone(),
        None => {
            let host = headers
                .get(header::HOST)
                .and_then(|v| v.to_str().ok())
                .unwrap_or("localhost");
            if !valid_host(host) {
                state.metrics.error(ErrorKind::BadRequest);
                return Err(ApiError::BadRequest(
                    "the Host header is not a host name with an optional port".into(),
                ));
            }
            let scheme = headers
                .get("x-forwarded-proto")
                .and_then(|v| v.to_str().ok())
                .filter(|s| *s == "https")
                .unwrap_or("http");
            format!("{scheme}://{host}")
        }
    };
    let suffix = if size == 512 { "@2x" } else { "" };
    let url = format!(
        "{base}/tiles/{}/{{z}}/{{x}}/{{y}}{suffix}.png?v={:016x}",
        enc.name(),
        t.info.id
    );
    let mut r = Json(layer.tilejson(enc, &url)).into_response();
    if state.public_url.is_none() {
        // The body depends on these headers: a shared cache keys it by them too, so that one
        // client's Host never reaches another's copy.
        r.headers_mut().insert(
            header::VARY,
            header::HeaderValue::from_static("host, x-forwarded-proto"),
        );
    }
    Ok(r)
}

/// Whether `h` is a host name or IP address with an optional port, as a Host header holds:
/// letters, digits, `-`, `.`, `:`, `[`, `]`, at most 255 bytes.
fn valid_host(h: &str) -> bool {
    !h.is_empty()
        && h.len() <= 255
        && h.bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'-' | b'.' | b':' | b'[' | b']'))
}

/// `GET /tiles/{encoding}/{z}/{x}/{y}.png` (256 pixels) or `{y}@2x.png` (512).
pub async fn raster_tile(
    State(state): State<Arc<AppState>>,
    Path((name, z, x, file)): Path<(String, String, String, String)>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let t = georeferenced(&state)?;
    let enc = encoding(&name)?;
    let (tile, which) = address(&state, &z, &x, &file, &["@2x.png", ".png"])?;
    let size = if which == 0 { 512 } else { 256 };
    let layer = raster_layer(&t, size)?;
    if !layer.available(tile) {
        return Err(ApiError::NotFoundWhy(format!(
            "tile {}/{}/{} is outside the terrain (levels 0 to {}, bounds in the TileJSON)",
            tile.z, tile.x, tile.y, layer.max_level
        )));
    }
    let etag = format!(
        "\"{:016x}-{}-{size}-{}-{}-{}\"",
        t.info.id,
        enc.name(),
        tile.z,
        tile.x,
        tile.y
    );
    if let Some(r) = not_modified(&headers, &etag) {
        return Ok(r);
    }
    let terrain = t.clone();
    let body = compute(&state, move || {
        let f = terrain.formats.as_ref().map_err(Clone::clone)?;
        let r = Resampler::new(&terrain.store, &f.geo);
        Ok(tile_png(&r, enc, tile, size))
    })
    .await?;
    Ok(tile_response(body, "image/png".into(), etag, false))
}
