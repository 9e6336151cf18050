//! GPU min-max motion mipmap (seed 000, Sec. 3.3, Fig. 5), the WGSL twin of
//! `crate::bounds::MotionPyramid::build_in_frame`. Shader: `pyramid.wgsl`.

use bytemuck::{Pod, Zeroable};
use glam::Vec2;
use wgpu::util::DeviceExt;
use zwarp_core::{Error, Image, Motion, Result};
use zwarp_gpu::readback::read_buffer;
use zwarp_gpu::GpuContext;

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Params {
    src_size: [u32; 2],
    dst_size: [u32; 2],
    axis: [f32; 2],
    empty: [f32; 2],
}

/// `ceil(log2(n))` for `n >= 1`, 0 for `n <= 1` (same as the CPU pyramid).
fn ceil_log2(n: u32) -> u32 {
    if n <= 1 {
        0
    } else {
        32 - (n - 1).leading_zeros()
    }
}

/// Sizes of levels `1..=top` for a `w x h` motion buffer: `ceil` halving (odd sizes keep their
/// last row and column, so every pixel is covered at every level), `top = max(1,
/// ceil(log2(max(w, h))))`, whose single texel is the global bound.
pub fn pyramid_level_sizes(w: u32, h: u32) -> Vec<(u32, u32)> {
    let top = ceil_log2(w.max(h)).max(1);
    let mut sizes = Vec::with_capacity(top as usize);
    let (mut lw, mut lh) = (w, h);
    for _ in 0..top {
        lw = lw.div_ceil(2);
        lh = lh.div_ceil(2);
        sizes.push((lw, lh));
    }
    sizes
}

/// A min-max motion mipmap resident on the GPU: one storage buffer of `vec4<f32>` texels
/// `(lo.x, lo.y, hi.x, hi.y)` per level `1..=top` (empty texel: `lo = +inf`, `hi = -inf`).
#[derive(Debug)]
pub struct GpuMotionPyramid {
    /// `levels[i]` is mip level `i + 1`.
    pub levels: Vec<wgpu::Buffer>,
    /// `sizes[i]` is the texel size of level `i + 1`.
    pub sizes: Vec<(u32, u32)>,
    /// Bound frame axis `(c, s)` the motion was rotated into.
    pub axis: Vec2,
}

impl GpuMotionPyramid {
    /// Reads every level back as images of `[lo.x, lo.y, hi.x, hi.y]` texels.
    pub fn read(&self, ctx: &GpuContext) -> Result<Vec<Image<[f32; 4]>>> {
        self.levels
            .iter()
            .zip(&self.sizes)
            .map(|(b, &(w, h))| Image::from_vec(w, h, read_buffer::<[f32; 4]>(ctx, b, (w * h) as usize)?))
            .collect()
    }
}

/// Builds min-max motion mipmaps on the GPU.
pub struct PyramidKernel {
    ctx: GpuContext,
    from_motion: wgpu::ComputePipeline,
    from_level: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    dummy: wgpu::Buffer,
}

impl PyramidKernel {
    /// Compiles `pyramid.wgsl`.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let dev = &ctx.device;
        let module = ctx.shader("pyramid.wgsl", include_str!("pyramid.wgsl"))?;
        let ro = wgpu::BufferBindingType::Storage { read_only: true };
        let (layout, pl) = zwarp_gpu::kernel::buffer_layouts(
            dev,
            "zwarp pyramid",
            &[wgpu::BufferBindingType::Uniform, ro, ro, wgpu::BufferBindingType::Storage { read_only: false }],
        );
        let pipe = |entry| {
            dev.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(&pl),
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        let dummy = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("zwarp dummy"),
            contents: &[0u8; 16],
            usage: wgpu::BufferUsages::STORAGE,
        });
        Ok(PyramidKernel {
            ctx: ctx.clone(),
            from_motion: ctx.catch("building the mipmap pipeline", || pipe("level_from_motion"))?,
            from_level: ctx.catch("building the mipmap pipeline", || pipe("level_from_level"))?,
            layout,
            dummy,
        })
    }

    /// Records the build of all levels from a GPU motion buffer of `width x height`
    /// [`Motion`] samples (as written by [`super::MotionKernel::encode`]), with motion rotated
    /// into the frame of unit `axis` (`Vec2::X` = axis-aligned bounds).
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        motion: &wgpu::Buffer,
        width: u32,
        height: u32,
        axis: Vec2,
    ) -> Result<GpuMotionPyramid> {
        if width == 0 || height == 0 {
            return Err(Error::invalid(format!("motion buffer is a zero-size image ({width}x{height})")));
        }
        if !axis.is_finite() || (axis.length() - 1.0).abs() > 1e-3 {
            return Err(Error::invalid(format!("bound frame axis must be a unit vector, got {axis:?}")));
        }
        let need = width as u64 * height as u64 * std::mem::size_of::<Motion>() as u64;
        if motion.size() < need {
            return Err(Error::invalid(format!("motion buffer holds {} < {need} bytes", motion.size())));
        }
        let dev = &self.ctx.device;
        let sizes = pyramid_level_sizes(width, height);
        let mut levels: Vec<wgpu::Buffer> = Vec::with_capacity(sizes.len());
        let mut src = (width, height);
        for (i, &(lw, lh)) in sizes.iter().enumerate() {
            let bytes = lw as u64 * lh as u64 * 16;
            self.ctx.check_storage_size(bytes, "motion mipmap level")?;
            let dst = dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some("zwarp motion mip"),
                size: bytes,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let params = Params {
                src_size: [src.0, src.1],
                dst_size: [lw, lh],
                axis: axis.to_array(),
                empty: [f32::INFINITY, f32::NEG_INFINITY],
            };
            let ubuf = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("zwarp pyramid params"),
                contents: bytemuck::bytes_of(&params),
                usage: wgpu::BufferUsages::UNIFORM,
            });
            let (m, p) = if i == 0 { (motion, &self.dummy) } else { (&self.dummy, &levels[i - 1]) };
            let bind = dev.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("zwarp pyramid"),
                layout: &self.layout,
                entries: &[
                    wgpu::BindGroupEntry { binding: 0, resource: ubuf.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 1, resource: m.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 2, resource: p.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 3, resource: dst.as_entire_binding() },
                ],
            });
            {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("zwarp pyramid"),
                    timestamp_writes: None,
                });
                pass.set_pipeline(if i == 0 { &self.from_motion } else { &self.from_level });
                pass.set_bind_group(0, &bind, &[]);
                pass.dispatch_workgroups(lw.div_ceil(8), lh.div_ceil(8), 1);
            }
            levels.push(dst);
            src = (lw, lh);
        }
        Ok(GpuMotionPyramid { levels, sizes, axis })
    }

    /// Builds the pyramid of a CPU motion buffer (uploads, builds, keeps it on the GPU).
    /// Errors like the CPU build: zero size, NaN motion or depth, non-unit axis.
    pub fn build(&self, motion: &Image<Motion>, axis: Vec2) -> Result<GpuMotionPyramid> {
        motion.check_nonempty("motion buffer")?;
        if motion.data().iter().any(|m| m.v.is_nan() || m.depth.is_nan()) {
            return Err(Error::invalid("motion buffer holds NaN values"));
        }
        let bytes = std::mem::size_of_val(motion.data()) as u64;
        self.ctx.check_storage_size(bytes, "motion buffer")?;
        let buf = self.ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("zwarp motion in"),
            contents: bytemuck::cast_slice(motion.data()),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        let pyr = self.encode(&mut enc, &buf, motion.width(), motion.height(), axis)?;
        self.ctx.queue.submit([enc.finish()]);
        Ok(pyr)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn level_sizes_cover_odd_and_prime_sides() {
        assert_eq!(pyramid_level_sizes(1, 1), vec![(1, 1)]);
        assert_eq!(pyramid_level_sizes(2, 1), vec![(1, 1)]);
        assert_eq!(pyramid_level_sizes(5, 3), vec![(3, 2), (2, 1), (1, 1)]);
        assert_eq!(pyramid_level_sizes(13, 7), vec![(7, 4), (4, 2), (2, 1), (1, 1)]);
        for (w, h) in [(1920, 1080), (17, 31), (128, 96)] {
            let s = pyramid_level_sizes(w, h);
            assert_eq!(*s.last().unwrap(), (1, 1));
            // Level l texel (i, j) covers [i 2^l, (i+1) 2^l): the level must reach every pixel.
            for (l, &(lw, lh)) in s.iter().enumerate() {
                assert!((lw as u64) << (l + 1) >= w as u64 && (lh as u64) << (l + 1) >= h as u64);
            }
        }
    }
}
