//! What every terrain pass shares, whichever stream it draws: the reversed-Z depth buffer and
//! its test, the frame's uniform buffer, the shading shader (`shade.wgsl`, prepended to each
//! pass's own WGSL) and the opening of the render pass (clear to the background, depth 0).

use super::frame::FRAME_BYTES;
use super::gpu::Gpu;

/// Depth buffer format (reversed Z: near is 1, infinity 0).
pub(crate) const DEPTH: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// The shading shared by the passes: the `Frame` uniform block, the vertex output, the height
/// ramp and the fragment shader `fs`.
const SHADE_WGSL: &str = include_str!("shade.wgsl");

/// A shader module of `shade.wgsl` followed by a pass's own `source`.
pub(crate) fn shader(gpu: &Gpu, label: &str, source: &str) -> wgpu::ShaderModule {
    gpu.device
        .create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(label),
            source: wgpu::ShaderSource::Wgsl(format!("{SHADE_WGSL}\n{source}").into()),
        })
}

/// The depth test of every terrain pass: nearer is greater, written.
pub(crate) fn depth_state() -> wgpu::DepthStencilState {
    wgpu::DepthStencilState {
        format: DEPTH,
        depth_write_enabled: Some(true),
        depth_compare: Some(wgpu::CompareFunction::Greater),
        stencil: Default::default(),
        bias: Default::default(),
    }
}

/// The colour target of a pass drawing into `format`, without blending.
pub(crate) fn colour_target(format: wgpu::TextureFormat) -> [Option<wgpu::ColorTargetState>; 1] {
    [Some(wgpu::ColorTargetState {
        format,
        blend: None,
        write_mask: wgpu::ColorWrites::ALL,
    })]
}

/// A terrain render pipeline: triangles pulled by the vertex shader `vs` (no vertex buffers),
/// drawn from both faces (geomorphs may fold a triangle for a moment; crack patches and skirts
/// are vertical and face either way), with the shared depth test and colour target.
pub(crate) fn terrain_pipeline(
    gpu: &Gpu,
    label: &str,
    layout: &wgpu::PipelineLayout,
    module: &wgpu::ShaderModule,
    vs: &str,
    format: wgpu::TextureFormat,
) -> wgpu::RenderPipeline {
    gpu.device
        .create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(label),
            layout: Some(layout),
            vertex: wgpu::VertexState {
                module,
                entry_point: Some(vs),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                cull_mode: None,
                ..Default::default()
            },
            depth_stencil: Some(depth_state()),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module,
                entry_point: Some("fs"),
                compilation_options: Default::default(),
                targets: &colour_target(format),
            }),
            multiview_mask: None,
            cache: None,
        })
}

/// The uniform buffer of the `Frame` block.
pub(crate) fn frame_buffer(gpu: &Gpu) -> wgpu::Buffer {
    gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("relief frame"),
        size: FRAME_BYTES as u64,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// A depth buffer kept at the target's size.
#[derive(Default)]
pub(crate) struct Depth {
    /// The view and its size, made on first use and remade when the size changes.
    view: Option<(wgpu::TextureView, (u32, u32))>,
}

impl Depth {
    /// The depth view for a `size` target.
    pub(crate) fn view(&mut self, gpu: &Gpu, size: (u32, u32)) -> &wgpu::TextureView {
        let size = (size.0.max(1), size.1.max(1));
        if self.view.as_ref().is_none_or(|d| d.1 != size) {
            let tex = gpu.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("relief depth"),
                size: wgpu::Extent3d {
                    width: size.0,
                    height: size.1,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: DEPTH,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
                view_formats: &[],
            });
            self.view = Some((tex.create_view(&Default::default()), size));
        }
        &self.view.as_ref().expect("made above").0
    }
}

/// Opens the terrain pass: `target` cleared to `background`, `depth` cleared to 0 (infinity).
pub(crate) fn begin<'e>(
    enc: &'e mut wgpu::CommandEncoder,
    target: &wgpu::TextureView,
    depth: &wgpu::TextureView,
    background: [f64; 3],
) -> wgpu::RenderPass<'e> {
    let [r, g, b] = background;
    enc.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some("relief terrain"),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view: target,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load: wgpu::LoadOp::Clear(wgpu::Color { r, g, b, a: 1.0 }),
                store: wgpu::StoreOp::Store,
            },
        })],
        depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
            view: depth,
            depth_ops: Some(wgpu::Operations {
                load: wgpu::LoadOp::Clear(0.0),
                store: wgpu::StoreOp::Store,
            }),
            stencil_ops: None,
        }),
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    })
}
