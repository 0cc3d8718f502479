//! The router: every route of the server over the shared state, built in one place so that
//! tests can call it without a socket.

use super::http::ApiError;
use super::limits::Refusal;
use super::state::AppState;
use super::{formats, http, pages, query, raycast, tiles, ws};
use axum::Router;
use axum::extract::DefaultBodyLimit;
use axum::http::{Method, header};
use axum::routing::{get, post};
use std::sync::Arc;
use tower_http::compression::CompressionLayer;
use tower_http::cors::{Any, CorsLayer};

/// The router: every route of the server over `state`.
pub fn app(state: Arc<AppState>) -> Router {
    // Tiles and their description are gzip-compressed for clients that accept it.
    let tile_routes = Router::new()
        .route("/v1/tiles.json", get(tiles::tileset))
        .route("/v1/tiles/{z}/{x}/{y}", get(tiles::tile))
        .layer(CompressionLayer::new().gzip(true));
    // The standard formats: gzip for the meshes and JSON (PNGs are compressed already, and the
    // layer's default predicate skips images), and CORS for pages on other origins.
    let format_routes = Router::new()
        .route("/cesium/layer.json", get(formats::cesium_layer))
        .route("/cesium/{z}/{x}/{y}", get(formats::cesium_tile))
        .route("/tiles/{file}", get(formats::tilejson))
        .route("/tiles/{encoding}/{z}/{x}/{y}", get(formats::raster_tile))
        .layer(CompressionLayer::new().gzip(true))
        .layer(
            CorsLayer::new()
                .allow_origin(Any)
                .allow_methods([Method::GET])
                .expose_headers([header::ETAG]),
        );
    Router::new()
        .route("/v1/stream", get(ws::upgrade))
        .route("/v1/terrain", get(http::terrain))
        .route("/v1/lod", post(http::lod))
        .route("/v1/heights", post(http::heights))
        .route("/v1/query", post(query::query))
        .route("/v1/raycast.png", get(raycast::image))
        .route("/v1/sessions", get(http::sessions))
        .route("/metrics", get(http::metrics))
        .route("/healthz", get(http::healthz))
        .route("/readyz", get(http::readyz))
        .merge(tile_routes)
        .merge(format_routes)
        .merge(pages::routes(&state.web_lib))
        .fallback(http::not_found)
        .layer(axum::middleware::from_fn(http::uri_limit))
        .layer(DefaultBodyLimit::max(
            state.limits.max_message_bytes as usize,
        ))
        .with_state(state)
}

/// The small router for a connection over the connection limits: health and readiness as
/// usual, and the refusal for everything else.
pub fn overflow_app(state: Arc<AppState>, why: Refusal) -> Router {
    let refusal = move || async move {
        match why {
            Refusal::ServerFull => ApiError::Unavailable(
                "the server holds its maximum of connections; retry later".into(),
            ),
            Refusal::PerAddress => ApiError::TooMany(
                "your address holds its maximum of connections; close some or retry later".into(),
            ),
        }
    };
    Router::new()
        .route("/healthz", get(http::healthz))
        .route("/readyz", get(http::readyz))
        .fallback(refusal)
        .with_state(state)
}
