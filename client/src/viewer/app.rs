//! The viewer's window: a winit application drawing the shared scene every frame with the
//! camera the keys and mouse fly, and a title line as HUD (fps, triangles, bytes/s, tau,
//! latency, connection state).

use super::controls::{FlyCamera, Held};
use super::net::{self, Shared};
use super::{ViewerError, ViewerOptions};
use crate::render::{FrameParams, Gpu, StreamRenderer, fog_distance};
use relief_proto::mesh::MorphRule;
use relief_proto::view::Lens;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, KeyEvent, MouseButton, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop, OwnedDisplayHandle};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Window, WindowId};

/// How long a window size must hold before a session is opened for it (the lens is part of
/// the hello: the server's pixel errors are for the session's viewport).
const RESIZE_SETTLE: Duration = Duration::from_millis(400);
/// Sky colour, linear (also the clear colour).
const SKY: [f64; 3] = [0.36, 0.47, 0.62];

/// The window and everything drawn into it.
struct Surface {
    /// The window.
    window: Arc<Window>,
    /// Its surface.
    surface: wgpu::Surface<'static>,
    /// The surface's configuration.
    config: wgpu::SurfaceConfiguration,
    /// The device.
    gpu: Gpu,
    /// The renderer, made once the first scene exists.
    renderer: Option<StreamRenderer>,
}

/// The application state.
struct App {
    /// Options.
    opts: ViewerOptions,
    /// The display, handed to wgpu's instance.
    display: OwnedDisplayHandle,
    /// The network thread's shared state.
    shared: Arc<Shared>,
    /// The window, once resumed.
    surface: Option<Surface>,
    /// The camera (placed when the terrain is known).
    camera: Option<FlyCamera>,
    /// Keys held.
    held: Held,
    /// Whether the left button is down, and the cursor's last position.
    drag: (bool, Option<(f64, f64)>),
    /// Wireframe overlay on.
    wireframe: bool,
    /// When the last frame was drawn.
    last_frame: Instant,
    /// Frames since the title was last updated, and when that was.
    fps_window: (u32, Instant),
    /// Frames per second, last measured.
    fps: f64,
    /// When the viewer started.
    started: Instant,
    /// The window's new size and when it last changed, until it is sent to the server.
    resized: Option<((u32, u32), Instant)>,
    /// A fatal error to report after the loop.
    error: Option<ViewerError>,
}

/// Opens the window and runs the loop.
pub fn run(opts: ViewerOptions) -> Result<(), ViewerError> {
    let event_loop = EventLoop::new().map_err(|e| ViewerError::Window(e.to_string()))?;
    event_loop.set_control_flow(ControlFlow::Poll);
    let lens = opts.session.lens;
    let shared = Shared::new(opts.session.tau, (lens.width, lens.height));
    let net_thread = {
        let (shared, config, rate) = (shared.clone(), opts.session.clone(), opts.rate_hz);
        std::thread::Builder::new()
            .name("relief-net".into())
            .spawn(move || net::run(shared, config, rate))
            .map_err(|e| ViewerError::Window(e.to_string()))?
    };
    let now = Instant::now();
    let mut app = App {
        wireframe: opts.wireframe,
        display: event_loop.owned_display_handle(),
        opts,
        shared: shared.clone(),
        surface: None,
        camera: None,
        held: Held::default(),
        drag: (false, None),
        last_frame: now,
        fps_window: (0, now),
        fps: 0.0,
        started: now,
        resized: None,
        error: None,
    };
    let ran = event_loop.run_app(&mut app);
    shared.stop.store(true, Ordering::Relaxed);
    let _ = net_thread.join();
    ran.map_err(|e| ViewerError::Window(e.to_string()))?;
    app.error.map_or(Ok(()), Err)
}

impl App {
    fn open(&mut self, el: &ActiveEventLoop) -> Result<Surface, ViewerError> {
        let lens = self.opts.session.lens;
        let attrs = Window::default_attributes()
            .with_title("Relief")
            .with_inner_size(PhysicalSize::new(lens.width, lens.height));
        let window = Arc::new(
            el.create_window(attrs)
                .map_err(|e| ViewerError::Window(e.to_string()))?,
        );
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_with_display_handle(
            Box::new(self.display.clone()),
        ));
        let surface = instance
            .create_surface(window.clone())
            .map_err(|e| crate::render::RenderError::Surface(e.to_string()))?;
        let gpu = Gpu::with_instance(instance, Some(&surface))?;
        let size = window.inner_size();
        let mut config = surface
            .get_default_config(&gpu.adapter, size.width.max(1), size.height.max(1))
            .ok_or_else(|| {
                crate::render::RenderError::Surface("the adapter cannot present to it".into())
            })?;
        let caps = surface.get_capabilities(&gpu.adapter);
        if let Some(f) = caps.formats.iter().find(|f| f.is_srgb()) {
            config.format = *f;
        }
        config.present_mode = wgpu::PresentMode::AutoVsync;
        surface.configure(&gpu.device, &config);
        tracing::info!("drawing with {}", gpu.describe());
        Ok(Surface {
            window,
            surface,
            config,
            gpu,
            renderer: None,
        })
    }

    fn key(&mut self, code: KeyCode, pressed: bool, el: &ActiveEventLoop) {
        let h = &mut self.held;
        match code {
            KeyCode::KeyW | KeyCode::ArrowUp => h.forward = pressed,
            KeyCode::KeyS | KeyCode::ArrowDown => h.back = pressed,
            KeyCode::KeyA | KeyCode::ArrowLeft => h.left = pressed,
            KeyCode::KeyD | KeyCode::ArrowRight => h.right = pressed,
            KeyCode::KeyE | KeyCode::PageUp => h.up = pressed,
            KeyCode::KeyQ | KeyCode::PageDown => h.down = pressed,
            KeyCode::ShiftLeft | KeyCode::ShiftRight => h.fast = pressed,
            KeyCode::ControlLeft | KeyCode::ControlRight => h.slow = pressed,
            _ if !pressed => {}
            KeyCode::Escape => el.exit(),
            KeyCode::KeyF => self.wireframe = !self.wireframe,
            KeyCode::KeyG => {
                let ground = self.shared.state.lock().ok().and_then(|s| s.ground);
                if let Some(c) = self.camera.as_mut() {
                    c.toggle_follow(ground);
                }
            }
            KeyCode::Equal | KeyCode::NumpadAdd | KeyCode::Minus | KeyCode::NumpadSubtract => {
                let up = matches!(code, KeyCode::Equal | KeyCode::NumpadAdd);
                if let Ok(mut w) = self.shared.wanted.lock() {
                    let t = if up { w.tau * 1.25 } else { w.tau / 1.25 };
                    w.tau = t.clamp(0.25, 64.0);
                }
            }
            _ => {}
        }
    }

    fn frame(&mut self) {
        let now = Instant::now();
        let dt = now.duration_since(self.last_frame).as_secs_f32().min(0.25);
        self.last_frame = now;
        let Some(s) = self.surface.as_mut() else {
            return;
        };
        let Ok(mut st) = self.shared.state.lock() else {
            return;
        };
        if self.camera.is_none()
            && let Some((extent, z_max)) = st.extent
        {
            self.camera = Some(FlyCamera::over(extent, z_max));
        }
        if let Some(c) = self.camera.as_mut() {
            c.step(dt, self.held, st.ground);
        }
        let camera = self.camera.map(|c| c.camera);
        if let Ok(mut w) = self.shared.wanted.lock() {
            w.camera = camera;
            // A new size goes to the server once the window has kept it for a moment.
            if let Some((size, at)) = self.resized
                && now.duration_since(at) >= RESIZE_SETTLE
            {
                w.size = size;
                self.resized = None;
            }
        }
        let (tau, range, geom_fog) = (
            st.tau,
            st.height_range,
            st.geom.as_ref().map(fog_distance).unwrap_or(10_000.0),
        );
        let lens = Lens {
            width: s.config.width,
            height: s.config.height,
            ..self.opts.session.lens
        };
        if let Some(scene) = st.scene.as_mut() {
            match s.renderer.as_mut() {
                Some(r) => {
                    r.upload(&s.gpu, scene);
                }
                None => {
                    s.renderer = Some(StreamRenderer::new(&s.gpu, s.config.format, scene));
                }
            }
        }
        let title = format!(
            "Relief  |  {:.0} fps  |  {:.2} M triangles  |  {:.1} kB/s  |  tau {:.2} px  |  latency {}  |  {}{}",
            self.fps,
            st.triangles as f64 / 1e6,
            st.bytes_per_s / 1e3,
            tau,
            st.latency_ms
                .map_or("-".to_string(), |l| format!("{l:.0} ms")),
            Shared::status(&st),
            if self.camera.and_then(|c| c.follow).is_some() {
                "  |  following ground"
            } else {
                ""
            },
        );
        drop(st);
        let frame = match s.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(f)
            | wgpu::CurrentSurfaceTexture::Suboptimal(f) => f,
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                s.surface.configure(&s.gpu.device, &s.config);
                return;
            }
            _ => return,
        };
        let view = frame.texture.create_view(&Default::default());
        match (s.renderer.as_mut(), camera) {
            (Some(r), Some(camera)) => {
                let params = FrameParams {
                    camera,
                    lens,
                    rule: MorphRule::new(tau),
                    now: self.shared.clock.elapsed().as_secs_f32(),
                    wireframe: self.wireframe,
                    z_range: range,
                    encode_srgb: !s.config.format.is_srgb(),
                    background: SKY,
                    fog_distance: geom_fog,
                    morph: self.opts.morph,
                    dropped_only: self.opts.dropped_only,
                };
                r.render(&s.gpu, &view, &params);
            }
            _ => clear(&s.gpu, &view),
        }
        s.gpu.queue.present(frame);
        self.fps_window.0 += 1;
        let since = now.duration_since(self.fps_window.1);
        if since >= Duration::from_millis(500) {
            self.fps = f64::from(self.fps_window.0) / since.as_secs_f64();
            self.fps_window = (0, now);
            s.window.set_title(&title);
        }
    }
}

/// Clears a frame to the sky (before the first welcome).
fn clear(gpu: &Gpu, view: &wgpu::TextureView) {
    let mut enc = gpu.device.create_command_encoder(&Default::default());
    let [r, g, b] = SKY;
    drop(enc.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some("relief clear"),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load: wgpu::LoadOp::Clear(wgpu::Color { r, g, b, a: 1.0 }),
                store: wgpu::StoreOp::Store,
            },
        })],
        depth_stencil_attachment: None,
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    }));
    gpu.queue.submit([enc.finish()]);
}

impl ApplicationHandler for App {
    fn resumed(&mut self, el: &ActiveEventLoop) {
        if self.surface.is_some() {
            return;
        }
        match self.open(el) {
            Ok(s) => self.surface = Some(s),
            Err(e) => {
                self.error = Some(e);
                el.exit();
            }
        }
    }

    fn window_event(&mut self, el: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::CloseRequested => el.exit(),
            WindowEvent::Resized(size) => {
                if let Some(s) = self.surface.as_mut()
                    && size.width > 0
                    && size.height > 0
                {
                    s.config.width = size.width;
                    s.config.height = size.height;
                    s.surface.configure(&s.gpu.device, &s.config);
                    self.resized = Some(((size.width, size.height), Instant::now()));
                }
            }
            WindowEvent::KeyboardInput {
                event:
                    KeyEvent {
                        physical_key: PhysicalKey::Code(code),
                        state,
                        ..
                    },
                ..
            } => self.key(code, state == ElementState::Pressed, el),
            WindowEvent::MouseInput {
                state,
                button: MouseButton::Left,
                ..
            } => {
                self.drag.0 = state == ElementState::Pressed;
            }
            WindowEvent::CursorMoved { position, .. } => {
                if let (true, Some((x, y)), Some(c)) =
                    (self.drag.0, self.drag.1, self.camera.as_mut())
                {
                    c.turn((position.x - x) as f32, (position.y - y) as f32);
                }
                self.drag.1 = Some((position.x, position.y));
            }
            WindowEvent::RedrawRequested => self.frame(),
            _ => {}
        }
    }

    fn about_to_wait(&mut self, el: &ActiveEventLoop) {
        if self
            .opts
            .exit_after
            .is_some_and(|d| self.started.elapsed() >= d)
        {
            el.exit();
            return;
        }
        if let Some(s) = self.surface.as_ref() {
            s.window.request_redraw();
        }
    }
}
