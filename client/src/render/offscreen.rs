//! A render target without a window, read back into an image (for `shot`, tests and timing),
//! and the crack test's count of background pixels the terrain encloses.

use super::gpu::{Gpu, RenderError};
use std::collections::VecDeque;

/// The offscreen colour format: plain 8-bit RGBA, so that the stored bytes are exactly what
/// the shader wrote (it encodes sRGB itself) and the clear colour's bytes come back unchanged.
pub const FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;

/// A colour texture to draw into.
pub struct Offscreen {
    /// The texture.
    texture: wgpu::Texture,
    /// Its view, the render target.
    pub view: wgpu::TextureView,
    /// Width and height, pixels.
    pub size: (u32, u32),
}

impl Offscreen {
    /// A `width` x `height` target.
    pub fn new(gpu: &Gpu, width: u32, height: u32) -> Offscreen {
        let texture = gpu.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("relief offscreen"),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let view = texture.create_view(&Default::default());
        Offscreen {
            texture,
            view,
            size: (width, height),
        }
    }

    /// The pixels drawn so far (waits for the GPU).
    pub fn read(&self, gpu: &Gpu) -> Result<image::RgbaImage, RenderError> {
        let (w, h) = self.size;
        let row = (w * 4).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
            * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let staging = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("relief frame readback"),
            size: u64::from(row * h),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut enc = gpu.device.create_command_encoder(&Default::default());
        enc.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: &self.texture,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &staging,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(row),
                    rows_per_image: Some(h),
                },
            },
            wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
        );
        gpu.queue.submit([enc.finish()]);
        let bytes = map_read(gpu, &staging)?;
        let mut pixels = Vec::with_capacity((w * h * 4) as usize);
        for r in 0..h as usize {
            let at = r * row as usize;
            pixels.extend_from_slice(&bytes[at..at + w as usize * 4]);
        }
        image::RgbaImage::from_raw(w, h, pixels)
            .ok_or_else(|| RenderError::Readback("frame size mismatch".into()))
    }
}

/// Copies `size` bytes of `src` into a mapped buffer and returns them (waits for the GPU).
pub(crate) fn read_buffer(
    gpu: &Gpu,
    src: &wgpu::Buffer,
    size: u64,
) -> Result<Vec<u8>, RenderError> {
    let staging = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("relief readback"),
        size,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut enc = gpu.device.create_command_encoder(&Default::default());
    enc.copy_buffer_to_buffer(src, 0, &staging, 0, size);
    gpu.queue.submit([enc.finish()]);
    map_read(gpu, &staging)
}

/// Maps `buffer` for reading and returns its bytes (waits for the GPU).
pub(crate) fn map_read(gpu: &Gpu, buffer: &wgpu::Buffer) -> Result<Vec<u8>, RenderError> {
    let slice = buffer.slice(..);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    gpu.wait();
    rx.recv()
        .map_err(|e| RenderError::Readback(e.to_string()))?
        .map_err(|e| RenderError::Readback(e.to_string()))?;
    let out = slice
        .get_mapped_range()
        .map_err(|e| RenderError::Readback(e.to_string()))?
        .to_vec();
    buffer.unmap();
    Ok(out)
}

/// Background pixels not connected (4-neighbours, through background) to the top edge: holes
/// in the terrain where the clear colour `bg` shows through (the crack test in images).
pub fn enclosed_background(img: &image::RgbaImage, bg: [u8; 3]) -> usize {
    let (w, h) = img.dimensions();
    let is_bg = |x: u32, y: u32| {
        let p = img.get_pixel(x, y);
        [p[0], p[1], p[2]] == bg
    };
    let mut seen = vec![false; (w * h) as usize];
    let mut queue: VecDeque<(u32, u32)> = (0..w).filter(|&x| is_bg(x, 0)).map(|x| (x, 0)).collect();
    for &(x, y) in &queue {
        seen[(y * w + x) as usize] = true;
    }
    while let Some((x, y)) = queue.pop_front() {
        let near = [
            (x.wrapping_sub(1), y),
            (x + 1, y),
            (x, y.wrapping_sub(1)),
            (x, y + 1),
        ];
        for (nx, ny) in near {
            if nx < w && ny < h && !seen[(ny * w + nx) as usize] && is_bg(nx, ny) {
                seen[(ny * w + nx) as usize] = true;
                queue.push_back((nx, ny));
            }
        }
    }
    let mut count = 0;
    for y in 0..h {
        for x in 0..w {
            count += usize::from(is_bg(x, y) && !seen[(y * w + x) as usize]);
        }
    }
    count
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn enclosed_background_counts_holes_not_sky() {
        let bg = [255, 0, 255];
        let mut img = image::RgbaImage::from_pixel(8, 6, image::Rgba([10, 20, 30, 255]));
        for x in 0..8 {
            img.put_pixel(x, 0, image::Rgba([255, 0, 255, 255]));
        }
        img.put_pixel(3, 1, image::Rgba([255, 0, 255, 255]));
        assert_eq!(enclosed_background(&img, bg), 0, "sky and what touches it");
        img.put_pixel(4, 4, image::Rgba([255, 0, 255, 255]));
        img.put_pixel(5, 4, image::Rgba([255, 0, 255, 255]));
        assert_eq!(enclosed_background(&img, bg), 2, "a two-pixel crack");
    }
}
