//! Checks of what clients send, shared by sessions and the one-shot endpoint. Each failure is
//! a sentence naming the field and the accepted range.

use relief_proto::msg::{TerrainInfo, WireCamera, WireLens};
use relief_proto::view::Camera;

/// Smallest tau accepted, pixels: below it a small viewport could ask for every node.
pub const MIN_TAU: f32 = 0.25;
/// Largest viewport side, pixels.
pub const MAX_VIEWPORT: u32 = 16384;
/// Smallest bandwidth budget, bytes per second: enough for a few splits per update.
pub const MIN_BUDGET: u32 = 1024;
/// How far beyond the terrain's extent (and above its highest point) a camera may be, metres.
pub const CAMERA_REACH_M: f32 = 1.0e6;

/// Checks a viewport, tau and optional budget.
pub fn params(lens: &WireLens, tau: f32, budget: Option<u32>) -> Result<(), String> {
    if !(1..=MAX_VIEWPORT).contains(&lens.width) || !(1..=MAX_VIEWPORT).contains(&lens.height) {
        return Err(format!(
            "viewport {}x{} is outside 1..={MAX_VIEWPORT} pixels a side",
            lens.width, lens.height
        ));
    }
    if !(lens.fov_y_deg.is_finite() && (1.0..=170.0).contains(&lens.fov_y_deg)) {
        return Err(format!(
            "vertical field of view {} is outside 1..=170 degrees",
            lens.fov_y_deg
        ));
    }
    if !(lens.near.is_finite() && lens.near > 0.0 && lens.near <= 1e4) {
        return Err(format!(
            "near plane {} is outside (0, 10000] metres",
            lens.near
        ));
    }
    if !(tau.is_finite() && (MIN_TAU..=1e4).contains(&tau)) {
        return Err(format!("tau {tau} is outside {MIN_TAU}..=10000 pixels"));
    }
    if let Some(b) = budget
        && b < MIN_BUDGET
    {
        return Err(format!(
            "bandwidth budget {b} B/s is below the minimum of {MIN_BUDGET} B/s"
        ));
    }
    Ok(())
}

/// Why a cut past the server's limit of interior nodes is refused: the same words for a
/// session (closed with `cut_limit`) and the one-shot (400).
pub fn cut_limit(max_nodes: usize) -> String {
    format!(
        "the cut reached the server's limit of {max_nodes} interior nodes; raise tau or shrink the viewport"
    )
}

/// Checks a camera against the terrain: finite, pitch inside (-90, 90) degrees, and within
/// [`CAMERA_REACH_M`] of the terrain.
pub fn camera(c: &WireCamera, t: &TerrainInfo) -> Result<Camera, String> {
    let cam = Camera::from(*c);
    if !cam.is_valid() {
        return Err(format!(
            "camera eye {:?}, yaw {}, pitch {} is not finite or looks straight up or down",
            c.eye, c.yaw, c.pitch
        ));
    }
    let w = t.width.saturating_sub(1) as f32 * t.spacing_x;
    let h = t.height.saturating_sub(1) as f32 * t.spacing_y;
    let [x, y, z] = c.eye;
    let r = CAMERA_REACH_M;
    if x < -r
        || x > w + r
        || y < -r
        || y > h + r
        || z < t.height_range[0] - r
        || z > t.height_range[1] + r
    {
        return Err(format!(
            "camera eye {:?} is more than {r} m away from the terrain",
            c.eye
        ));
    }
    Ok(cam)
}

#[cfg(test)]
mod tests {
    use super::*;
    use relief_proto::view::Lens;

    fn info() -> TerrainInfo {
        TerrainInfo {
            id: 1,
            width: 100,
            height: 100,
            spacing_x: 10.0,
            spacing_y: 10.0,
            z_quantum: 1.0,
            root_z: 0,
            height_range: [0.0, 500.0],
        }
    }

    #[test]
    fn good_values_pass_and_bad_ones_are_named() {
        let lens: WireLens = Lens::STANDARD.into();
        assert!(params(&lens, 1.0, Some(50_000)).is_ok());
        assert!(params(&lens, f32::NAN, None).unwrap_err().contains("tau"));
        assert!(params(&lens, 1.0, Some(10)).unwrap_err().contains("budget"));
        let wide = WireLens { width: 0, ..lens };
        assert!(params(&wide, 1.0, None).unwrap_err().contains("viewport"));
        let good = WireCamera {
            eye: [500.0, 500.0, 800.0],
            yaw: 0.0,
            pitch: -0.3,
        };
        assert!(camera(&good, &info()).is_ok());
        let nan = WireCamera {
            eye: [f32::NAN, 0.0, 0.0],
            ..good
        };
        assert!(camera(&nan, &info()).unwrap_err().contains("not finite"));
        let far = WireCamera {
            eye: [5e7, 0.0, 0.0],
            ..good
        };
        assert!(camera(&far, &info()).unwrap_err().contains("away"));
        let up = WireCamera { pitch: 2.0, ..good };
        assert!(camera(&up, &info()).is_err());
    }
}
