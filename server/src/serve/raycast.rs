//! `GET /v1/raycast.png?camera=x,y,z,yaw,pitch&size=WxH&fov=DEG`: a picture of a camera's
//! view ray-cast on the exact surface, with no triangles, shaded like the client's renderer
//! ([`crate::query::view`]). A thumbnail, and the reference `relief-client shot` is compared
//! with.

use super::http::{ApiError, ApiQuery};
use super::metrics::ErrorKind;
use super::state::AppState;
use super::validate;
use crate::query::view;
use axum::extract::State;
use axum::http::header;
use axum::response::{IntoResponse, Response};
use relief_proto::msg::WireCamera;
use relief_proto::view::{Lens, parse_camera};
use std::sync::Arc;

/// The image size when the request names none.
pub const DEFAULT_SIZE: (u32, u32) = (640, 360);

/// The vertical field of view when the request names none, degrees.
pub const DEFAULT_FOV: f32 = 60.0;

/// Most threads one picture is cast on.
pub const MAX_THREADS: usize = 4;

/// The query of a ray-cast request, as text (parsed here, so that every mistake gets its
/// own sentence).
#[derive(Debug, serde::Deserialize)]
pub struct RaycastQuery {
    /// `x,y,z,yaw,pitch`: metres east and north of the south-west sample, metres of height,
    /// degrees counter-clockwise from east, degrees of elevation (negative looks down).
    camera: Option<String>,
    /// `WxH`, pixels.
    size: Option<String>,
    /// Vertical field of view, degrees.
    fov: Option<String>,
}

/// Parses `WxH` and checks it against [`view::MAX_PIXELS`].
fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let bad = || {
        format!(
            "size {s:?} is not WxH with whole sides of at least 1 pixel and at most {} pixels in all",
            view::MAX_PIXELS
        )
    };
    let (w, h) = s.split_once(['x', 'X']).ok_or_else(bad)?;
    let (w, h): (u32, u32) = (
        w.trim().parse().map_err(|_| bad())?,
        h.trim().parse().map_err(|_| bad())?,
    );
    if w == 0 || h == 0 || u64::from(w) * u64::from(h) > view::MAX_PIXELS {
        return Err(bad());
    }
    Ok((w, h))
}

/// Parses a vertical field of view in degrees, 1 to 170.
fn parse_fov(s: &str) -> Result<f32, String> {
    match s.trim().parse::<f32>() {
        Ok(f) if f.is_finite() && (1.0..=170.0).contains(&f) => Ok(f),
        _ => Err(format!(
            "fov {s:?} is not a number of degrees from 1 to 170"
        )),
    }
}

/// `GET /v1/raycast.png`: the PNG of the view (see the module docs). 400 with the reason for
/// a missing or malformed camera, size or fov, 503 before the terrain is ready or when it has
/// no query surface.
pub async fn image(
    State(state): State<Arc<AppState>>,
    ApiQuery(q): ApiQuery<RaycastQuery>,
) -> Result<Response, ApiError> {
    let t = state.terrain().ok_or(ApiError::NotReady)?;
    let bad = |e: String| {
        state.metrics.error(ErrorKind::BadRequest);
        ApiError::BadRequest(e)
    };
    let text = q.camera.as_deref().ok_or_else(|| {
        bad("the camera is missing: add camera=x,y,z,yaw,pitch (metres, degrees)".into())
    })?;
    let camera = parse_camera(text).map_err(bad)?;
    let camera = validate::camera(&WireCamera::from(camera), &t.info).map_err(bad)?;
    let (width, height) = match q.size.as_deref() {
        Some(s) => parse_size(s).map_err(bad)?,
        None => DEFAULT_SIZE,
    };
    let fov_y_deg = match q.fov.as_deref() {
        Some(s) => parse_fov(s).map_err(bad)?,
        None => DEFAULT_FOV,
    };
    let lens = Lens {
        width,
        height,
        fov_y_deg,
        near: Lens::STANDARD.near,
    };
    if let Err(e) = &t.query {
        tracing::error!("ray-cast without a query surface: {e}");
        return Err(ApiError::Unavailable(
            "this terrain has no query surface; see the server's log".into(),
        ));
    }
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(MAX_THREADS);
    let work = state.background.run(move || -> Result<Vec<u8>, String> {
        let Ok(terrain) = &t.query else {
            return Err("the query surface went away".into());
        };
        let img = view::render(terrain, &camera, &lens, threads).map_err(|e| e.to_string())?;
        let mut png = std::io::Cursor::new(Vec::new());
        img.write_to(&mut png, image::ImageFormat::Png)
            .map_err(|e| e.to_string())?;
        Ok(png.into_inner())
    });
    let png = work
        .await
        .map_err(|e| {
            tracing::error!("ray-cast failed: {e}");
            ApiError::Internal
        })?
        .map_err(bad)?;
    Ok(([(header::CONTENT_TYPE, "image/png")], png).into_response())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_cameras_sizes_and_fovs() {
        let c = parse_camera("1, 2,3,90,-30").unwrap();
        assert_eq!(c.eye, glam::Vec3::new(1.0, 2.0, 3.0));
        assert!((c.yaw - std::f32::consts::FRAC_PI_2).abs() < 1e-6);
        assert!(parse_camera("1,2,3,90").is_err());
        assert!(parse_camera("1,2,3,90,x").is_err());
        assert_eq!(parse_size("640x360"), Ok((640, 360)));
        assert_eq!(parse_size("1024X1024"), Ok((1024, 1024)));
        assert!(parse_size("1025x1024").is_err());
        assert!(parse_size("0x10").is_err());
        assert!(parse_size("640").is_err());
        assert_eq!(parse_fov("45"), Ok(45.0));
        assert!(parse_fov("0").is_err());
        assert!(parse_fov("NaN").is_err());
    }

    #[tokio::test]
    async fn answers_503_before_the_terrain_is_ready() {
        let (_tx, rx) = tokio::sync::watch::channel(false);
        let state = Arc::new(AppState::new(Default::default(), rx));
        let req = axum::http::Request::get("/v1/raycast.png?camera=0,0,100,0,-10")
            .body(axum::body::Body::empty())
            .unwrap();
        let r = tower::ServiceExt::oneshot(super::super::router::app(state), req)
            .await
            .unwrap();
        assert_eq!(r.status(), axum::http::StatusCode::SERVICE_UNAVAILABLE);
    }
}
