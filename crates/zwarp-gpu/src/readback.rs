//! Copies GPU textures and buffers back into [`Image`]s and `Vec`s (the renderer's and the
//! stage crates' kernels' read-back).
//!
//! `copy_texture_to_buffer` needs `bytes_per_row` to be a multiple of 256
//! (`wgpu::COPY_BYTES_PER_ROW_ALIGNMENT`), so rows are padded on the GPU and unpadded here.

use bytemuck::Pod;
use zwarp_core::{Error, Image, Result};

use crate::GpuContext;

/// Padded row pitch in bytes for `width` texels of `texel_bytes` each.
pub fn padded_bytes_per_row(width: u32, texel_bytes: u32) -> u32 {
    let unpadded = width * texel_bytes;
    let align = wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    unpadded.div_ceil(align) * align
}

/// A staging buffer that receives one texture copy, recorded now and read after submission.
pub struct PendingTexture {
    buffer: wgpu::Buffer,
    width: u32,
    height: u32,
    texel_bytes: u32,
}

/// Records a copy of mip 0 / layer 0 of `texture` (aspect `aspect`) into a fresh staging buffer.
pub fn copy_texture(
    ctx: &GpuContext,
    encoder: &mut wgpu::CommandEncoder,
    texture: &wgpu::Texture,
    aspect: wgpu::TextureAspect,
    texel_bytes: u32,
) -> PendingTexture {
    let (width, height) = (texture.width(), texture.height());
    let bpr = padded_bytes_per_row(width, texel_bytes);
    let buffer = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("zwarp readback"),
        size: bpr as u64 * height as u64,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    encoder.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo { texture, mip_level: 0, origin: wgpu::Origin3d::ZERO, aspect },
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(bpr), rows_per_image: Some(height) },
        },
        wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
    );
    PendingTexture { buffer, width, height, texel_bytes }
}

/// Maps `buffer` (which must have `MAP_READ`) after the queue finished, blocking.
pub(crate) fn map_blocking(ctx: &GpuContext, buffer: &wgpu::Buffer) -> Result<()> {
    let (tx, rx) = std::sync::mpsc::channel();
    buffer.map_async(wgpu::MapMode::Read, .., move |r| {
        let _ = tx.send(r);
    });
    ctx.wait()?;
    match rx.recv() {
        Ok(Ok(())) => Ok(()),
        Ok(Err(e)) => Err(Error::Unavailable(format!("mapping a GPU readback buffer failed: {e}"))),
        Err(_) => Err(Error::Unavailable("GPU readback callback never ran".into())),
    }
}

impl PendingTexture {
    /// Maps the staging buffer (the copy must have been submitted) and unpads it into an image
    /// of `T` (whose size must equal the texel size).
    pub fn read<T: Pod>(self, ctx: &GpuContext) -> Result<Image<T>> {
        debug_assert_eq!(std::mem::size_of::<T>() as u32, self.texel_bytes);
        map_blocking(ctx, &self.buffer)?;
        let bpr = padded_bytes_per_row(self.width, self.texel_bytes) as usize;
        let row_bytes = (self.width * self.texel_bytes) as usize;
        let mut out: Vec<T> = Vec::with_capacity(self.width as usize * self.height as usize);
        {
            let view = self
                .buffer
                .get_mapped_range(..)
                .map_err(|e| Error::Unavailable(format!("reading a mapped GPU buffer failed: {e}")))?;
            for y in 0..self.height as usize {
                let row = &view[y * bpr..y * bpr + row_bytes];
                // `pod_collect_to_vec` copies, so unaligned mapped memory is fine.
                out.extend(bytemuck::pod_collect_to_vec::<u8, T>(row));
            }
        }
        self.buffer.unmap();
        Image::from_vec(self.width, self.height, out)
    }
}

/// Reads a whole storage buffer of `T` back (records the copy, submits, maps).
pub fn read_buffer<T: Pod>(ctx: &GpuContext, src: &wgpu::Buffer, count: usize) -> Result<Vec<T>> {
    let bytes = (count * std::mem::size_of::<T>()) as u64;
    let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("zwarp readback"),
        size: bytes.max(4).next_multiple_of(4),
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut enc = ctx.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("readback") });
    enc.copy_buffer_to_buffer(src, 0, &staging, 0, bytes);
    ctx.queue.submit([enc.finish()]);
    map_blocking(ctx, &staging)?;
    let out = {
        let view = staging
            .get_mapped_range(..)
            .map_err(|e| Error::Unavailable(format!("reading a mapped GPU buffer failed: {e}")))?;
        bytemuck::pod_collect_to_vec::<u8, T>(&view[..bytes as usize])
    };
    staging.unmap();
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn row_padding_is_256_aligned() {
        assert_eq!(padded_bytes_per_row(1, 4), 256);
        assert_eq!(padded_bytes_per_row(64, 4), 256);
        assert_eq!(padded_bytes_per_row(65, 4), 512);
        assert_eq!(padded_bytes_per_row(1920, 4), 7680);
        assert_eq!(padded_bytes_per_row(97, 12), 1280);
    }
}
