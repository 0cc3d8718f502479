//! The browser pages: `GET /` (and `/view`), Relief's own thin client, which streams tiles over
//! `/v1/stream` and draws them in WebGL2; `GET /cesium/`, a CesiumJS viewer over the quantized-mesh
//! terrain, and `GET /maplibre/` (`?encoding=terrarium` for Terrarium tiles), a MapLibre GL JS map
//! in terrain mode over the terrain-RGB tiles, both over this server's terrain.
//!
//! The pages (`web/page/`, `web/cesium/`, `web/maplibre/`) are compiled into the binary, and so
//! is Relief's page's WebAssembly (`web/page/pkg/`, relief-proto built by `web/build-wasm.sh`
//! and committed): that page needs nothing else. The libraries they
//! load are the npm packages of `web/package.json`, served from disk, never from a CDN:
//! `/lib/cesium/` from `cesium/Build/Cesium` and `/lib/maplibre-gl/` from `maplibre-gl/dist`
//! under the `--web-lib` folder (by default `web/node_modules` in the repository the server was
//! built from, where `npm ci --prefix web` installs them). Without them a page answers 503
//! with a message saying to run that command, and the server says so in its log at start.
//! What the pages share (`web/common/`) is served at `/pages/common.js` and `/pages/common.css`.

use super::state::AppState;
use axum::Router;
use axum::extract::State;
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Redirect, Response};
use axum::routing::get;
use std::net::SocketAddr;
use std::path::Path;
use std::sync::Arc;
use tower_http::compression::CompressionLayer;
use tower_http::services::ServeDir;

const PAGE_HTML: &str = include_str!("../../../web/page/index.html");
const PAGE_JS: &str = include_str!("../../../web/page/main.js");
const PAGE_GLUE: &str = include_str!("../../../web/page/pkg/relief_wasm.js");
const PAGE_WASM: &[u8] = include_bytes!("../../../web/page/pkg/relief_wasm_bg.wasm");
const CESIUM_HTML: &str = include_str!("../../../web/cesium/index.html");
const CESIUM_JS: &str = include_str!("../../../web/cesium/main.js");
const MAPLIBRE_HTML: &str = include_str!("../../../web/maplibre/index.html");
const MAPLIBRE_JS: &str = include_str!("../../../web/maplibre/main.js");
const COMMON_JS: &str = include_str!("../../../web/common/page.js");
const COMMON_CSS: &str = include_str!("../../../web/common/page.css");

/// An npm package a page loads, served from the web library folder.
#[derive(Clone, Copy, Debug)]
pub struct Lib {
    /// The npm package.
    pub package: &'static str,
    /// Where it is served.
    pub url: &'static str,
    /// The folder served, under the web library folder.
    pub dir: &'static str,
    /// A file the page loads, there when the package is installed.
    pub probe: &'static str,
}

/// CesiumJS's build.
pub const CESIUM: Lib = Lib {
    package: "cesium",
    url: "/lib/cesium",
    dir: "cesium/Build/Cesium",
    probe: "Cesium.js",
};

/// MapLibre GL JS's ES modules.
pub const MAPLIBRE: Lib = Lib {
    package: "maplibre-gl",
    url: "/lib/maplibre-gl",
    dir: "maplibre-gl/dist",
    probe: "maplibre-gl.mjs",
};

impl Lib {
    /// Whether the package is installed under `web_lib`.
    pub fn installed(&self, web_lib: &Path) -> bool {
        web_lib.join(self.dir).join(self.probe).is_file()
    }
}

/// The pages and the libraries they load, the libraries from `web_lib`.
pub fn routes(web_lib: &Path) -> Router<Arc<AppState>> {
    let page = |html: &'static str, lib: Lib| {
        move |State(state): State<Arc<AppState>>| async move {
            if lib.installed(&state.web_lib) {
                text(StatusCode::OK, "text/html; charset=utf-8", html.to_string())
            } else {
                missing_page(&state.web_lib, lib)
            }
        }
    };
    let js = |body: &'static str| {
        move || async move {
            text(
                StatusCode::OK,
                "text/javascript; charset=utf-8",
                body.into(),
            )
        }
    };
    let own = || async { text(StatusCode::OK, "text/html; charset=utf-8", PAGE_HTML.into()) };
    // Relief's page, gzip-compressed for browsers that accept it (the wasm to a third).
    let relief_page = Router::new()
        .route("/", get(own))
        .route("/view", get(own))
        .route("/page/main.js", get(js(PAGE_JS)))
        .route("/page/pkg/relief_wasm.js", get(js(PAGE_GLUE)))
        .route(
            "/page/pkg/relief_wasm_bg.wasm",
            get(|| async {
                (
                    [
                        (header::CONTENT_TYPE, "application/wasm"),
                        (header::CACHE_CONTROL, "no-cache"),
                    ],
                    PAGE_WASM,
                )
            }),
        )
        .layer(CompressionLayer::new().gzip(true));
    Router::new()
        .merge(relief_page)
        .route("/cesium", get(|| async { Redirect::permanent("/cesium/") }))
        .route("/cesium/", get(page(CESIUM_HTML, CESIUM)))
        .route("/cesium/main.js", get(js(CESIUM_JS)))
        .route(
            "/maplibre",
            get(|| async { Redirect::permanent("/maplibre/") }),
        )
        .route("/maplibre/", get(page(MAPLIBRE_HTML, MAPLIBRE)))
        .route("/maplibre/main.js", get(js(MAPLIBRE_JS)))
        .route("/pages/common.js", get(js(COMMON_JS)))
        .route(
            "/pages/common.css",
            get(|| async { text(StatusCode::OK, "text/css; charset=utf-8", COMMON_CSS.into()) }),
        )
        .nest_service(CESIUM.url, ServeDir::new(web_lib.join(CESIUM.dir)))
        .nest_service(MAPLIBRE.url, ServeDir::new(web_lib.join(MAPLIBRE.dir)))
}

/// A page or script, never cached for long (it changes with the server).
fn text(status: StatusCode, content_type: &'static str, body: String) -> Response {
    (
        status,
        [
            (header::CONTENT_TYPE, content_type),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        body,
    )
        .into_response()
}

/// The message a page shows in place of itself when its library is not installed.
fn missing_page(web_lib: &Path, lib: Lib) -> Response {
    let dir = escape(&web_lib.display().to_string());
    let body = format!(
        "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <title>Relief: {pkg} is not installed</title></head>\n<body style=\"font: 16px/1.5 \
         system-ui, sans-serif; max-width: 48em; margin: 3em auto\">\n\
         <h1>The page's library is not installed</h1>\n\
         <p>This page loads the npm package <code>{pkg}</code> from this server, which looks \
         for it in <code>{dir}</code>, and it is not there.</p>\n\
         <p>Install the pages' libraries: from the repository, run</p>\n\
         <pre>npm ci --prefix web</pre>\n\
         <p>then reload (no restart needed). To use another <code>node_modules</code> folder, \
         start the server with <code>--web-lib DIR</code> (or <code>RELIEF_WEB_LIB</code>, or \
         <code>web_lib</code> in the config file).</p>\n</body></html>\n",
        pkg = lib.package,
    );
    text(
        StatusCode::SERVICE_UNAVAILABLE,
        "text/html; charset=utf-8",
        body,
    )
}

/// `s` with HTML's special characters escaped.
fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Logs the pages' addresses, and what is missing for them, when the server starts on `addr`.
pub fn log_start(addr: SocketAddr, web_lib: &Path) {
    // A wildcard address is reachable on loopback, so that is the URL to show.
    let host = match addr.ip() {
        ip if ip.is_unspecified() && ip.is_ipv4() => format!("127.0.0.1:{}", addr.port()),
        ip if ip.is_unspecified() => format!("[::1]:{}", addr.port()),
        _ => addr.to_string(),
    };
    tracing::info!("the terrain in your browser: http://{host}/");
    tracing::info!(
        "pages: http://{host}/cesium/ (CesiumJS), http://{host}/maplibre/ (MapLibre GL JS)"
    );
    let missing: Vec<&str> = [CESIUM, MAPLIBRE]
        .iter()
        .filter(|l| !l.installed(web_lib))
        .map(|l| l.package)
        .collect();
    if !missing.is_empty() {
        tracing::warn!(
            "the pages' libraries ({}) are not installed in {}: run `npm ci --prefix web` in the \
             repository, or give their node_modules folder with --web-lib; until then the pages \
             show this message",
            missing.join(", "),
            web_lib.display()
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_library_gets_a_message_with_the_command() {
        let dir = tempfile::tempdir().unwrap();
        assert!(!CESIUM.installed(dir.path()));
        let r = missing_page(&dir.path().join("<x>"), CESIUM);
        assert_eq!(r.status(), StatusCode::SERVICE_UNAVAILABLE);
        let lib = dir.path().join(MAPLIBRE.dir);
        std::fs::create_dir_all(&lib).unwrap();
        std::fs::write(lib.join(MAPLIBRE.probe), "").unwrap();
        assert!(MAPLIBRE.installed(dir.path()));
        assert_eq!(
            escape("<a href=\"x\">&</a>"),
            "&lt;a href=&quot;x&quot;&gt;&amp;&lt;/a&gt;"
        );
    }

    #[test]
    fn relief_page_loads_its_wasm_from_this_server_only() {
        assert!(PAGE_HTML.contains("/page/main.js"));
        assert!(PAGE_JS.contains("/page/pkg/relief_wasm.js"));
        for text in [PAGE_HTML, PAGE_JS] {
            assert!(!text.contains("http://") && !text.contains("https://"));
        }
        assert_eq!(&PAGE_WASM[..4], b"\0asm", "a WebAssembly module");
        assert!(PAGE_GLUE.contains("relief_wasm_bg.wasm"));
    }

    #[test]
    fn the_pages_load_their_libraries_from_this_server() {
        for (html, lib) in [(CESIUM_HTML, CESIUM), (MAPLIBRE_HTML, MAPLIBRE)] {
            assert!(html.contains(lib.url), "{}", lib.package);
            assert!(!html.contains("://"), "{}: no absolute URLs", lib.package);
        }
        assert!(CESIUM_JS.contains("CesiumTerrainProvider.fromUrl('/cesium/'"));
        assert!(MAPLIBRE_JS.contains("/lib/maplibre-gl/maplibre-gl.mjs"));
        for js in [CESIUM_JS, MAPLIBRE_JS] {
            assert!(!js.contains("http://") && !js.contains("https://"));
        }
    }
}
