//! The wgpu instance, adapter, device and queue, found headless or for a window's surface.

use wgpu::{Adapter, Device, Instance, Queue};

/// Why rendering could not start or go on.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// No adapter: no GPU driver, not even a software one.
    #[error(
        "no GPU adapter found ({0}); on Debian, `apt-get install -y mesa-vulkan-drivers` gives a software Vulkan driver (lavapipe)"
    )]
    NoAdapter(String),
    /// The adapter refused to open a device with what the renderer needs.
    #[error("the GPU adapter {adapter} cannot open a device: {detail}")]
    Device {
        /// The adapter's name.
        adapter: String,
        /// wgpu's reason.
        detail: String,
    },
    /// The adapter lacks something the renderer needs.
    #[error("the GPU adapter {adapter} cannot run the renderer: {detail}")]
    Unsupported {
        /// The adapter's name.
        adapter: String,
        /// What is missing.
        detail: String,
    },
    /// A window surface could not be made.
    #[error("cannot draw into the window: {0}")]
    Surface(String),
    /// Reading a frame back failed.
    #[error("reading the frame back failed: {0}")]
    Readback(String),
}

/// A device to render with.
pub struct Gpu {
    /// The instance (kept for surfaces).
    pub instance: Instance,
    /// The adapter the device came from.
    pub adapter: Adapter,
    /// The device.
    pub device: Device,
    /// Its queue.
    pub queue: Queue,
}

impl Gpu {
    /// A device without any window: the first adapter of the primary backends (Vulkan, Metal,
    /// DX12; lavapipe on a machine with Mesa's software Vulkan and no GPU), else of OpenGL.
    /// `WGPU_BACKEND` (e.g. `gl`) chooses the backends instead.
    pub fn headless() -> Result<Gpu, RenderError> {
        let instance = |backends| {
            let mut d = wgpu::InstanceDescriptor::new_without_display_handle();
            d.backends = wgpu::Backends::from_env().unwrap_or(backends);
            Instance::new(d)
        };
        Gpu::with_instance(instance(wgpu::Backends::PRIMARY), None)
            .or_else(|_| Gpu::with_instance(instance(wgpu::Backends::SECONDARY), None))
    }

    /// A device from `instance` that can present to `surface`, if given.
    pub fn with_instance(
        instance: Instance,
        surface: Option<&wgpu::Surface<'_>>,
    ) -> Result<Gpu, RenderError> {
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            compatible_surface: surface,
            ..Default::default()
        }))
        .map_err(|e| RenderError::NoAdapter(e.to_string()))?;
        let info = adapter.get_info();
        let name = format!("{} ({:?}, {:?})", info.name, info.backend, info.device_type);
        let downlevel = adapter.get_downlevel_capabilities();
        if !downlevel
            .flags
            .contains(wgpu::DownlevelFlags::VERTEX_STORAGE | wgpu::DownlevelFlags::COMPUTE_SHADERS)
        {
            return Err(RenderError::Unsupported {
                adapter: name,
                detail: "storage buffers in vertex shaders and compute shaders are required".into(),
            });
        }
        let limits = adapter.limits();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("relief"),
            required_features: wgpu::Features::empty(),
            required_limits: limits,
            ..Default::default()
        }))
        .map_err(|e| RenderError::Device {
            adapter: name,
            detail: e.to_string(),
        })?;
        Ok(Gpu {
            instance,
            adapter,
            device,
            queue,
        })
    }

    /// The adapter in words: name, backend and type.
    pub fn describe(&self) -> String {
        let i = self.adapter.get_info();
        format!("{} ({:?}, {:?})", i.name, i.backend, i.device_type)
    }

    /// Waits until the GPU has finished everything submitted.
    pub fn wait(&self) {
        let _ = self.device.poll(wgpu::PollType::wait_indefinitely());
    }
}
