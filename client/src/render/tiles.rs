//! The GPU side of the tile stream: per tile, a position buffer and an index buffer (read by
//! `tiles.wgsl` as storage, so that the wireframe sees each triangle's corners), uploaded once
//! when the tile first becomes active and kept while the client's mirror holds the tile (active
//! or cached); one draw per active tile. Patches and skirts are vertical: nothing is culled;
//! under the wireframe they are tinted, so that screenshots show them.
//! Depth (reversed Z), frame block and shading are the vertex renderer's (`pass.rs`,
//! `shade.wgsl`).

use super::frame::{FrameParams, frame_block};
use super::gpu::Gpu;
use super::pass::{self, Depth};
use super::tile_scene::{TileMesh, TileScene};
use rustc_hash::FxHashMap;
use wgpu::util::DeviceExt;

/// A tile's buffers on the GPU.
struct GpuTile {
    /// Its positions and indices, bound as group 1.
    group: wgpu::BindGroup,
    /// Indices drawn with every patch.
    all: u32,
    /// Indices drawn without the raised patches.
    dropped_only: u32,
}

/// Pipeline and per-tile buffers for one [`TileScene`].
pub struct TileRenderer {
    /// The tile pass.
    pipeline: wgpu::RenderPipeline,
    /// The uniform block.
    frame: wgpu::Buffer,
    /// Group 0's layout: the frame block and the arrival times.
    layout_frame: wgpu::BindGroupLayout,
    /// Group 0: the frame block and the arrival times.
    frame_group: wgpu::BindGroup,
    /// Arrival time of each active tile, in the order of `active`.
    arrivals: wgpu::Buffer,
    /// Its capacity, floats.
    arrivals_cap: usize,
    /// Group 1's layout: a tile's positions, indices and normals.
    layout_tile: wgpu::BindGroupLayout,
    /// Buffers of the tiles held, by dense index.
    tiles: FxHashMap<u32, GpuTile>,
    /// The tiles to draw: the scene's active set at the last upload.
    active: Vec<u32>,
    /// The scene epoch the buffers belong to.
    epoch: u64,
    /// Depth buffer.
    depth: Depth,
}

fn storage(binding: u32) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::VERTEX,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only: true },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// A storage buffer of `cap` arrival times.
fn arrival_buffer(gpu: &Gpu, cap: usize) -> wgpu::Buffer {
    gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("relief tile arrivals"),
        size: 4 * cap.max(1) as u64,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// Group 0: the frame block and the arrival times.
fn frame_group(
    gpu: &Gpu,
    layout: &wgpu::BindGroupLayout,
    frame: &wgpu::Buffer,
    arrivals: &wgpu::Buffer,
) -> wgpu::BindGroup {
    gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("relief tile frame"),
        layout,
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: frame.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: arrivals.as_entire_binding(),
            },
        ],
    })
}

impl TileRenderer {
    /// The pipeline drawing into `format` targets, with the buffers of `scene`'s active tiles.
    pub fn new(gpu: &Gpu, format: wgpu::TextureFormat, scene: &mut TileScene) -> TileRenderer {
        let dev = &gpu.device;
        let module = pass::shader(gpu, "relief tiles", include_str!("tiles.wgsl"));
        let layout_frame = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("relief tile frame"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                storage(1),
            ],
        });
        let layout_tile = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("relief tile"),
            entries: &[storage(0), storage(1), storage(2)],
        });
        let layout = dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("relief tiles"),
            bind_group_layouts: &[Some(&layout_frame), Some(&layout_tile)],
            immediate_size: 0,
        });
        // Crack patches and skirts are vertical and face either way: no culling.
        let pipeline =
            pass::terrain_pipeline(gpu, "relief tiles", &layout, &module, "vs_tile", format);
        let frame = pass::frame_buffer(gpu);
        let arrivals_cap = 256;
        let arrivals = arrival_buffer(gpu, arrivals_cap);
        let frame_group = frame_group(gpu, &layout_frame, &frame, &arrivals);
        let mut r = TileRenderer {
            pipeline,
            frame,
            layout_frame,
            frame_group,
            arrivals,
            arrivals_cap,
            layout_tile,
            tiles: FxHashMap::default(),
            active: Vec::new(),
            epoch: scene.epoch,
            depth: Depth::default(),
        };
        r.upload(gpu, scene);
        r
    }

    /// Uploads the active tiles that have no buffers yet and drops the buffers of evicted
    /// tiles (all of them when the scene started again); returns the bytes sent.
    pub fn upload(&mut self, gpu: &Gpu, scene: &mut TileScene) -> usize {
        if scene.epoch != self.epoch {
            self.tiles.clear();
            self.epoch = scene.epoch;
        }
        for i in scene.take_gone() {
            self.tiles.remove(&i);
        }
        let mut bytes = 0;
        for &i in &scene.active {
            if self.tiles.contains_key(&i) {
                continue;
            }
            let Some(mesh) = scene.meshes.get(&i) else {
                continue;
            };
            bytes += 4 * (mesh.positions.len() + mesh.normals.len() + mesh.indices.len());
            let tile = self.gpu_tile(gpu, mesh);
            self.tiles.insert(i, tile);
        }
        self.active.clone_from(&scene.active);
        let arrivals: Vec<f32> = self.active.iter().map(|&i| scene.arrival(i)).collect();
        if arrivals.len() > self.arrivals_cap {
            self.arrivals_cap = arrivals.len().next_power_of_two();
            self.arrivals = arrival_buffer(gpu, self.arrivals_cap);
            self.frame_group = frame_group(gpu, &self.layout_frame, &self.frame, &self.arrivals);
        }
        if !arrivals.is_empty() {
            gpu.queue
                .write_buffer(&self.arrivals, 0, bytemuck::cast_slice(&arrivals));
        }
        bytes + 4 * arrivals.len()
    }

    fn gpu_tile(&self, gpu: &Gpu, mesh: &TileMesh) -> GpuTile {
        let buffer = |label: &str, words: &[u8]| {
            gpu.device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents: words,
                    usage: wgpu::BufferUsages::STORAGE,
                })
        };
        // Storage buffers may not be empty.
        let positions = buffer(
            "relief tile positions",
            bytemuck::cast_slice(if mesh.positions.is_empty() {
                &[0.0f32; 4]
            } else {
                &mesh.positions[..]
            }),
        );
        let normals = buffer(
            "relief tile normals",
            bytemuck::cast_slice(if mesh.normals.is_empty() {
                &[0.0f32; 4]
            } else {
                &mesh.normals[..]
            }),
        );
        // The mesh's triangle count first: the shader tints what follows (patches, skirts).
        let mut words = Vec::with_capacity(1 + mesh.indices.len());
        words.push(mesh.counts[0]);
        words.extend_from_slice(&mesh.indices);
        let indices = buffer("relief tile indices", bytemuck::cast_slice(&words));
        let group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("relief tile"),
            layout: &self.layout_tile,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: positions.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: indices.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: normals.as_entire_binding(),
                },
            ],
        });
        GpuTile {
            group,
            all: 3 * mesh.drawn(false),
            dropped_only: 3 * mesh.drawn(true),
        }
    }

    /// Tiles with buffers on the GPU (active and cached).
    pub fn held_count(&self) -> usize {
        self.tiles.len()
    }

    /// Draws the active tiles into `target` (of the lens's size).
    pub fn render(&mut self, gpu: &Gpu, target: &wgpu::TextureView, f: &FrameParams) {
        gpu.queue
            .write_buffer(&self.frame, 0, bytemuck::cast_slice(&frame_block(f)));
        let mut enc = gpu.device.create_command_encoder(&Default::default());
        let depth = self.depth.view(gpu, (f.lens.width, f.lens.height));
        {
            let mut pass = pass::begin(&mut enc, target, depth, f.background);
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &self.frame_group, &[]);
            for (k, i) in self.active.iter().enumerate() {
                let Some(t) = self.tiles.get(i) else { continue };
                let n = if f.dropped_only {
                    t.dropped_only
                } else {
                    t.all
                };
                pass.set_bind_group(1, &t.group, &[]);
                // The instance index picks the tile's arrival time.
                let k = k as u32;
                pass.draw(0..n, k..k + 1);
            }
        }
        gpu.queue.submit([enc.finish()]);
    }
}
