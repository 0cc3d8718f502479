//! The GPU side of the vertex stream: buffers mirroring a [`Scene`]'s pools, the geomorph
//! compute pass and the terrain render pass (shaders in `terrain.wgsl`, after `shade.wgsl`).
//!
//! Each frame is one render pass. The vertex shader pulls triangles' node slots from the cell
//! records and geomorphs each vertex from its node's record and its ancestors' for this frame's
//! camera (paper 000, section 3.6, down the chain of ancestors). Nothing per vertex is uploaded
//! per frame: only the uniform block, and after a delta the pages of records it changed. A
//! compute pass runs the same geomorph function for every node slot and writes the positions
//! out, for tests that read back what is drawn ([`Renderer::morph_only`]).

use super::frame::{FrameParams, MorphStage, frame_block};
use super::gpu::{Gpu, RenderError};
use super::offscreen::read_buffer;
use super::pass::{self, Depth};
use glam::Vec3;
use relief_proto::mesh::scene::{CELL_WORDS, Pool, Scene};
use wgpu::util::DeviceExt;

/// GPU buffers, pipelines and bind groups for one scene.
pub struct Renderer {
    /// Node records.
    nodes: GpuPool,
    /// Cell records.
    cells: GpuPool,
    /// Drawn positions, one `vec4<f32>` per node slot, written by the compute pass (tests).
    drawn: wgpu::Buffer,
    /// Smooth normals, four `i32` per node slot: sums of the drawn triangles' unit normals
    /// around each node, cleared and written each frame by the normals pass.
    normal_sums: wgpu::Buffer,
    /// The uniform block.
    frame: wgpu::Buffer,
    /// Group 0: frame and nodes.
    layout_common: wgpu::BindGroupLayout,
    /// Group 1: drawn positions, written.
    layout_morph: wgpu::BindGroupLayout,
    /// Group 2: cells, drawn positions and normals, read.
    layout_draw: wgpu::BindGroupLayout,
    /// Group 1 of the normals pass: the normal sums, written.
    layout_sums: wgpu::BindGroupLayout,
    /// Group 2 of the normals pass: cells and drawn positions, read.
    layout_mesh: wgpu::BindGroupLayout,
    /// Bind groups (common, morph, draw, sums, mesh), remade when a buffer grows.
    groups: Option<[wgpu::BindGroup; 5]>,
    /// The geomorph pass.
    morph: wgpu::ComputePipeline,
    /// The smooth-normals pass (after the geomorph pass).
    normals: wgpu::ComputePipeline,
    /// The terrain pass, geomorphing per vertex.
    draw: wgpu::RenderPipeline,
    /// The terrain pass, reading the geomorph pass's output.
    draw_pre: wgpu::RenderPipeline,
    /// Node slots the geomorph pass covers, and cell slots the draw covers: the pools' high
    /// water marks, not their capacities.
    used: (usize, usize),
    /// Depth buffer.
    depth: Depth,
}

/// One pool's GPU buffer.
struct GpuPool {
    /// The buffer, sized to the pool's capacity.
    buffer: wgpu::Buffer,
    /// Its capacity in records.
    records: usize,
}

impl GpuPool {
    fn new(gpu: &Gpu, pool: &Pool, label: &str) -> GpuPool {
        GpuPool {
            buffer: gpu
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents: bytemuck::cast_slice(pool.words()),
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                }),
            records: pool.capacity(),
        }
    }

    /// Uploads what changed in `pool` (all of it after growth); returns the bytes sent and
    /// whether the buffer was made anew.
    fn sync(&mut self, gpu: &Gpu, pool: &mut Pool, label: &str) -> (usize, bool) {
        if pool.grown() || pool.capacity() != self.records {
            *self = GpuPool::new(gpu, pool, label);
            let _ = pool.take_dirty();
            return (pool.words().len() * 4, true);
        }
        let mut bytes = 0;
        for (start, len) in pool.take_dirty() {
            let words = &pool.words()[start..start + len];
            gpu.queue
                .write_buffer(&self.buffer, start as u64 * 4, bytemuck::cast_slice(words));
            bytes += len * 4;
        }
        (bytes, false)
    }
}

fn storage(binding: u32, read_only: bool, vis: wgpu::ShaderStages) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: vis,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

impl Renderer {
    /// Pipelines drawing into `format` targets, with buffers for `scene`.
    pub fn new(gpu: &Gpu, format: wgpu::TextureFormat, scene: &mut Scene) -> Renderer {
        let dev = &gpu.device;
        let module = pass::shader(gpu, "relief terrain", include_str!("terrain.wgsl"));
        let cv = wgpu::ShaderStages::COMPUTE | wgpu::ShaderStages::VERTEX_FRAGMENT;
        let layout_common = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("relief common"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: cv,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                storage(
                    1,
                    true,
                    wgpu::ShaderStages::COMPUTE | wgpu::ShaderStages::VERTEX,
                ),
            ],
        });
        let layout_morph = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("relief morph"),
            entries: &[storage(0, false, wgpu::ShaderStages::COMPUTE)],
        });
        let layout_draw = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("relief draw"),
            entries: &[
                storage(0, true, wgpu::ShaderStages::VERTEX),
                storage(1, true, wgpu::ShaderStages::VERTEX),
                storage(2, true, wgpu::ShaderStages::VERTEX),
            ],
        });
        let layout_sums = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("relief normal sums"),
            entries: &[storage(1, false, wgpu::ShaderStages::COMPUTE)],
        });
        let layout_mesh = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("relief mesh"),
            entries: &[
                storage(0, true, wgpu::ShaderStages::COMPUTE),
                storage(1, true, wgpu::ShaderStages::COMPUTE),
            ],
        });
        let empty = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("relief empty"),
            entries: &[],
        });
        let morph_layout = dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("relief morph"),
            bind_group_layouts: &[Some(&layout_common), Some(&layout_morph)],
            immediate_size: 0,
        });
        let draw_layout = dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("relief draw"),
            bind_group_layouts: &[Some(&layout_common), Some(&empty), Some(&layout_draw)],
            immediate_size: 0,
        });
        let normals_layout = dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("relief normals"),
            bind_group_layouts: &[Some(&layout_common), Some(&layout_sums), Some(&layout_mesh)],
            immediate_size: 0,
        });
        let normals = dev.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("relief normals"),
            layout: Some(&normals_layout),
            module: &module,
            entry_point: Some("normals_pass"),
            compilation_options: Default::default(),
            cache: None,
        });
        let morph = dev.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("relief morph"),
            layout: Some(&morph_layout),
            module: &module,
            entry_point: Some("morph"),
            compilation_options: Default::default(),
            cache: None,
        });
        // Geomorphs may fold a triangle for a moment: both faces are drawn.
        let pipeline = |vs: &str| {
            pass::terrain_pipeline(gpu, "relief terrain", &draw_layout, &module, vs, format)
        };
        let (draw, draw_pre) = (pipeline("vs"), pipeline("vs_pre"));
        let frame = pass::frame_buffer(gpu);
        let nodes = GpuPool::new(gpu, &scene.nodes, "relief nodes");
        let cells = GpuPool::new(gpu, &scene.cells, "relief cells");
        let _ = scene.nodes.take_dirty();
        let _ = scene.cells.take_dirty();
        let drawn = drawn_buffer(gpu, nodes.records);
        let normal_sums = sums_buffer(gpu, nodes.records);
        Renderer {
            nodes,
            cells,
            drawn,
            normal_sums,
            frame,
            layout_common,
            layout_morph,
            layout_draw,
            layout_sums,
            layout_mesh,
            groups: None,
            morph,
            normals,
            draw,
            draw_pre,
            used: (scene.nodes.high_water(), scene.cells.high_water()),
            depth: Depth::default(),
        }
    }

    /// Uploads the records `scene` changed since the last call; returns the bytes sent. A pool
    /// that grew, or a scene made anew (its pools start out marked grown), is sent whole, so one
    /// renderer serves a new session's scene too.
    pub fn upload(&mut self, gpu: &Gpu, scene: &mut Scene) -> usize {
        let (a, grew_nodes) = self.nodes.sync(gpu, &mut scene.nodes, "relief nodes");
        let (b, grew_cells) = self.cells.sync(gpu, &mut scene.cells, "relief cells");
        if grew_nodes {
            self.drawn = drawn_buffer(gpu, self.nodes.records);
            self.normal_sums = sums_buffer(gpu, self.nodes.records);
        }
        if grew_nodes || grew_cells {
            self.groups = None;
        }
        self.used = (scene.nodes.high_water(), scene.cells.high_water());
        a + b
    }

    fn groups(&mut self, gpu: &Gpu) -> &[wgpu::BindGroup; 5] {
        let dev = &gpu.device;
        self.groups.get_or_insert_with(|| {
            fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
                wgpu::BindGroupEntry {
                    binding,
                    resource: buffer.as_entire_binding(),
                }
            }
            [
                dev.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("relief common"),
                    layout: &self.layout_common,
                    entries: &[entry(0, &self.frame), entry(1, &self.nodes.buffer)],
                }),
                dev.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("relief morph"),
                    layout: &self.layout_morph,
                    entries: &[entry(0, &self.drawn)],
                }),
                dev.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("relief draw"),
                    layout: &self.layout_draw,
                    entries: &[
                        entry(0, &self.cells.buffer),
                        entry(1, &self.drawn),
                        entry(2, &self.normal_sums),
                    ],
                }),
                dev.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("relief normal sums"),
                    layout: &self.layout_sums,
                    entries: &[entry(1, &self.normal_sums)],
                }),
                dev.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("relief mesh"),
                    layout: &self.layout_mesh,
                    entries: &[entry(0, &self.cells.buffer), entry(1, &self.drawn)],
                }),
            ]
        })
    }

    /// Runs the geomorph pass alone, for every node slot, into the drawn-position buffer (for
    /// tests that read back what is drawn, [`Renderer::read_drawn`]).
    pub fn morph_only(&mut self, gpu: &Gpu, f: &FrameParams) {
        gpu.queue
            .write_buffer(&self.frame, 0, bytemuck::cast_slice(&frame_block(f)));
        let mut enc = gpu.device.create_command_encoder(&Default::default());
        self.encode_morph(gpu, &mut enc);
        gpu.queue.submit([enc.finish()]);
    }

    fn encode_morph(&mut self, gpu: &Gpu, enc: &mut wgpu::CommandEncoder) {
        let workgroups = self.used.0.max(1).div_ceil(64) as u32;
        let (x, y) = (workgroups.min(65_535), workgroups.div_ceil(65_535));
        let morph = self.morph.clone();
        let groups = self.groups(gpu);
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("relief morph"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&morph);
        pass.set_bind_group(0, &groups[0], &[]);
        pass.set_bind_group(1, &groups[1], &[]);
        pass.dispatch_workgroups(x, y, 1);
    }

    /// Clears the normal sums and adds every drawn triangle's unit normal to its corners'.
    fn encode_normals(&mut self, gpu: &Gpu, enc: &mut wgpu::CommandEncoder) {
        enc.clear_buffer(&self.normal_sums, 0, None);
        let triangles = self.used.1 * CELL_WORDS / 3;
        let workgroups = triangles.max(1).div_ceil(64) as u32;
        let (x, y) = (workgroups.min(65_535), workgroups.div_ceil(65_535));
        let normals = self.normals.clone();
        let groups = self.groups(gpu);
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("relief normals"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&normals);
        pass.set_bind_group(0, &groups[0], &[]);
        pass.set_bind_group(1, &groups[3], &[]);
        pass.set_bind_group(2, &groups[4], &[]);
        pass.dispatch_workgroups(x, y, 1);
    }

    /// Draws the scene into `target` (of the lens's size).
    pub fn render(&mut self, gpu: &Gpu, target: &wgpu::TextureView, f: &FrameParams) {
        gpu.queue
            .write_buffer(&self.frame, 0, bytemuck::cast_slice(&frame_block(f)));
        let mut enc = gpu.device.create_command_encoder(&Default::default());
        let draw = match f.morph {
            MorphStage::Compute => {
                self.encode_morph(gpu, &mut enc);
                self.encode_normals(gpu, &mut enc);
                self.draw_pre.clone()
            }
            MorphStage::Vertex => self.draw.clone(),
        };
        let vertices = (self.used.1 * CELL_WORDS) as u32;
        let groups = self.groups(gpu).clone();
        let depth = self.depth.view(gpu, (f.lens.width, f.lens.height));
        {
            let mut pass = pass::begin(&mut enc, target, depth, f.background);
            pass.set_pipeline(&draw);
            pass.set_bind_group(0, &groups[0], &[]);
            pass.set_bind_group(2, &groups[2], &[]);
            pass.draw(0..vertices, 0..1);
        }
        gpu.queue.submit([enc.finish()]);
    }

    /// The drawn positions of the last [`Renderer::morph_only`], one per node slot (waits for
    /// the GPU).
    pub fn read_drawn(&self, gpu: &Gpu) -> Result<Vec<Vec3>, RenderError> {
        let bytes = read_buffer(gpu, &self.drawn, (self.nodes.records * 16) as u64)?;
        let floats: Vec<f32> = bytes
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        Ok(floats
            .chunks_exact(4)
            .map(|v| Vec3::new(v[0], v[1], v[2]))
            .collect())
    }
}

/// The normal sums: four `i32` per node slot, cleared each frame.
fn sums_buffer(gpu: &Gpu, records: usize) -> wgpu::Buffer {
    gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("relief normal sums"),
        size: (records.max(1) * 16) as u64,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

fn drawn_buffer(gpu: &Gpu, records: usize) -> wgpu::Buffer {
    gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("relief drawn"),
        size: (records.max(1) * 16) as u64,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    })
}
