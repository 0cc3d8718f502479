//! The viewer's network thread: one session at a time, fed the window's latest camera at the
//! pose rate, its deltas applied to the mirror, the fans (or the tile mirror) and the shared
//! scene. When the server
//! goes away past the session's own reconnect deadline, it says so in the status and tries
//! again with growing waits; a change of tau starts a new session.

use crate::render::StreamScene;
use crate::session::{Session, SessionConfig};
use relief_proto::terrain::TerrainGeometry;
use relief_proto::view::{Camera, Lens};
use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// What the network thread shares with the window.
pub struct Shared {
    /// The scene and what the title shows.
    pub state: Mutex<NetState>,
    /// What the window asks the network side for.
    pub wanted: Mutex<Wanted>,
    /// Set by the window to end the thread.
    pub stop: AtomicBool,
    /// The clock split times are stamped with.
    pub clock: Instant,
}

/// What the window asks for: a change of tau or size starts a new session, since both are
/// fixed by the hello.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wanted {
    /// The camera to stream (`None` until the terrain is known).
    pub camera: Option<Camera>,
    /// Screen-space error threshold, pixels.
    pub tau: f32,
    /// Viewport width and height, pixels.
    pub size: (u32, u32),
}

/// The network side's state, read by the window each frame.
#[derive(Default)]
pub struct NetState {
    /// The scene of the current session (`None` before the first welcome). A new session or a
    /// rebuild after a desync makes a new scene, whose pools the renderer then sends whole.
    pub scene: Option<StreamScene>,
    /// The terrain's geometry.
    pub geom: Option<TerrainGeometry>,
    /// The terrain's extent, metres, and highest height.
    pub extent: Option<((f32, f32), f32)>,
    /// Lowest and highest height of the terrain, metres (the colour ramp's span).
    pub height_range: (f32, f32),
    /// Height of the mesh under the last camera sent, metres.
    pub ground: Option<f32>,
    /// Triangles in the mesh.
    pub triangles: usize,
    /// Bytes received over the last second.
    pub bytes_per_s: f64,
    /// Latency of the last answered pose, milliseconds.
    pub latency_ms: Option<f64>,
    /// The tau of the current session.
    pub tau: f32,
    /// Connection state in words ("connected", or why not and when the next try is).
    pub status: String,
    /// The current session's link: while it reconnects by itself, it says why.
    pub link: Option<Arc<crate::session::Link>>,
}

impl Shared {
    /// Fresh shared state asking for `tau` at `size`.
    pub fn new(tau: f32, size: (u32, u32)) -> Arc<Shared> {
        Arc::new(Shared {
            state: Mutex::new(NetState {
                status: "connecting".into(),
                tau,
                ..NetState::default()
            }),
            wanted: Mutex::new(Wanted {
                camera: None,
                tau,
                size,
            }),
            stop: AtomicBool::new(false),
            clock: Instant::now(),
        })
    }

    fn now(&self) -> f32 {
        self.clock.elapsed().as_secs_f32()
    }

    /// The connection state in words, for the window's title.
    pub fn status(st: &NetState) -> String {
        match st.link.as_ref().and_then(|l| l.down()) {
            Some(why) => format!("server unreachable: {why}"),
            None => st.status.clone(),
        }
    }

    fn set_status(&self, s: impl Into<String>) {
        if let Ok(mut st) = self.state.lock() {
            st.status = s.into();
        }
    }
}

/// Runs the network side until `shared.stop` is set.
pub fn run(shared: Arc<Shared>, config: SessionConfig, rate_hz: f64) {
    let rt = match tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
    {
        Ok(rt) => rt,
        Err(e) => {
            if let Ok(mut st) = shared.state.lock() {
                st.link = None;
            }
            shared.set_status(format!("cannot start the network thread: {e}"));
            return;
        }
    };
    rt.block_on(async move {
        let mut wait = Duration::from_millis(500);
        while !shared.stop.load(Ordering::Relaxed) {
            let (tau, size) = shared
                .wanted
                .lock()
                .map(|w| (w.tau, w.size))
                .unwrap_or((config.tau, (config.lens.width, config.lens.height)));
            let cfg = crate::render::renderer_config(SessionConfig {
                tau,
                lens: Lens {
                    width: size.0,
                    height: size.1,
                    ..config.lens
                },
                ..config.clone()
            });
            let why = match Session::connect(cfg).await {
                Ok(session) => {
                    wait = Duration::from_millis(500);
                    match fly(&shared, session, rate_hz).await {
                        Ok(()) => continue,
                        Err(e) => e,
                    }
                }
                Err(e) => e.to_string(),
            };
            if shared.stop.load(Ordering::Relaxed) {
                break;
            }
            if let Ok(mut st) = shared.state.lock() {
                st.link = None;
            }
            shared.set_status(format!(
                "server unreachable ({why}); retrying in {:.0} s",
                wait.as_secs_f32()
            ));
            tracing::warn!("{why}; retrying in {wait:?}");
            tokio::time::sleep(wait).await;
            wait = (wait * 2).min(Duration::from_secs(10));
        }
    });
}

/// Flies one session; returns `Ok` when it should be replaced (tau or size changed, or
/// stopping).
async fn fly(shared: &Shared, mut session: Session, rate_hz: f64) -> Result<(), String> {
    let scene = StreamScene::new(&mut session);
    let geom = session.geometry().clone();
    let info = session.terrain().clone();
    let extent = crate::flight::extent(&info);
    let tau = session.tau();
    let size = (session.lens().width, session.lens().height);
    if let Ok(mut st) = shared.state.lock() {
        st.scene = Some(scene);
        st.geom = Some(geom.clone());
        st.extent = Some((extent, info.height_range[1]));
        st.height_range = (info.height_range[0], info.height_range[1]);
        st.tau = tau;
        st.status = "connected".into();
        st.link = Some(session.link());
    }
    let period = Duration::from_secs_f64(1.0 / rate_hz);
    let mut next_pose = Instant::now();
    let mut last_sent: Option<Camera> = None;
    let mut sent_at: HashMap<u64, Instant> = HashMap::new();
    let mut window: Vec<(Instant, usize)> = Vec::new();
    loop {
        if shared.stop.load(Ordering::Relaxed) {
            session.close().await;
            return Ok(());
        }
        let Ok(want) = shared.wanted.lock().map(|w| *w) else {
            return Ok(());
        };
        let cam = want.camera;
        if want.tau != tau || want.size != size {
            session.close().await;
            return Ok(());
        }
        let now = Instant::now();
        if now >= next_pose {
            next_pose = now + period;
            if let Some(c) = cam.filter(|c| Some(*c) != last_sent && c.is_valid()) {
                let seq = session.send_pose(c).await.map_err(|e| e.to_string())?;
                sent_at.insert(seq, Instant::now());
                last_sent = Some(c);
            }
        }
        let until = next_pose.saturating_duration_since(Instant::now());
        let applied = tokio::time::timeout(until, session.next_delta()).await;
        let t = Instant::now();
        window.retain(|(at, _)| t.duration_since(*at) <= Duration::from_secs(1));
        let Ok(applied) = applied else {
            // Nothing arrived before the next pose is due: the rate still falls as time passes.
            if let Ok(mut st) = shared.state.lock() {
                st.bytes_per_s = bytes_in(&window);
            }
            continue;
        };
        let a = applied.map_err(|e| e.to_string())?;
        window.push((t, a.bytes));
        let latency = if a.complete {
            let l = sent_at
                .remove(&a.pose_seq)
                .map(|s| t.duration_since(s).as_secs_f64() * 1e3);
            sent_at.retain(|&k, _| k > a.pose_seq);
            l
        } else {
            None
        };
        let ground = last_sent.map(|c| ground_under(&session, c.eye.x, c.eye.y));
        let stamp = shared.now();
        if let Ok(mut st) = shared.state.lock() {
            if let Some(f) = st.scene.as_mut() {
                f.sync(&mut session, stamp);
            }
            st.triangles = session.triangle_count();
            st.bytes_per_s = bytes_in(&window);
            if latency.is_some() {
                st.latency_ms = latency;
            }
            if ground.is_some() {
                st.ground = ground.flatten();
            }
        }
    }
}

/// Bytes received within the window (an empty window is 0, not the -0.0 of an empty float sum).
fn bytes_in(window: &[(Instant, usize)]) -> f64 {
    window.iter().map(|w| w.1 as u64).sum::<u64>() as f64
}

/// Height of the cut's active node (or of the active tiles' surface) over world `x`, `y`,
/// metres (`None` off the terrain).
fn ground_under(session: &Session, x: f32, y: f32) -> Option<f32> {
    let geom = session.geometry();
    if let Some(t) = session.tiles() {
        return t.height_at(geom, x, y);
    }
    let (c, r) = geom.frame.to_grid(x, y);
    let (w, h) = (geom.shape.width(), geom.shape.height());
    if !(c >= 0.0 && r >= 0.0 && c < w as f32 && r < h as f32) {
        return None;
    }
    let n = session
        .mirror()
        .cut()
        .active_ancestor(&geom.shape, c as u32, r as u32);
    let d = session.mirror().node(geom, n)?;
    Some(geom.world_pos(n, d.z).z)
}
