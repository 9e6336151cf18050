//! An engine's own source images on the GPU (seed 000 Sec. 3: the source view's depth layers
//! and the item buffer that carries object motion, Sec. 3.1): depth and item textures, or
//! buffers with a row stride, copied on the GPU into the tight buffers that
//! [`super::MotionKernel`] and [`super::WarpKernel`] read, so that a renderer's output is warped
//! without a round trip through the CPU. Shader: `source.wgsl`.

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;
use zwarp_core::{Error, Result};
use zwarp_gpu::GpuContext;

/// Mirror of `Params` in source.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Params {
    width: u32,
    height: u32,
    stride: u32,
    _pad: u32,
}

/// A source image that lives on the caller's GPU (the device of the [`GpuContext`] the kernels
/// were built on).
#[derive(Clone, Copy, Debug)]
pub enum GpuImage<'a> {
    /// A 2-D texture, read at mip level 0 and array layer 0: `Depth32Float` (a depth
    /// attachment) or `R32Float` for depth, `R32Uint` for item ids; single-sampled, with
    /// `TEXTURE_BINDING` usage.
    Texture(&'a wgpu::Texture),
    /// A buffer of 4-byte texels (`f32` depth or `u32` item ids), row-major, `row_stride`
    /// texels per row (>= the width; e.g. a 256-byte padded texture copy has
    /// `padded_bytes_per_row / 4`), with `STORAGE` usage.
    Buffer {
        /// The texels.
        buffer: &'a wgpu::Buffer,
        /// Texels per row.
        row_stride: u32,
    },
}

/// What a source image holds, which decides the texture formats it may have.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    Depth,
    Items,
}

/// The copy of [`GpuImage`]s into tight buffers (`width * height` 4-byte texels, row-major),
/// bit-exact.
pub struct SourceKernel {
    ctx: GpuContext,
    depth_texture: (wgpu::BindGroupLayout, wgpu::ComputePipeline),
    item_texture: (wgpu::BindGroupLayout, wgpu::ComputePipeline),
    strided_buffer: (wgpu::BindGroupLayout, wgpu::ComputePipeline),
}

impl SourceKernel {
    /// Compiles `source.wgsl`.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let dev = &ctx.device;
        let module = ctx.shader("source.wgsl", include_str!("source.wgsl"))?;
        let entry = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty,
            count: None,
        };
        let buffer = |ty| wgpu::BindingType::Buffer { ty, has_dynamic_offset: false, min_binding_size: None };
        let texture = |sample_type| wgpu::BindingType::Texture {
            sample_type,
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        };
        // Explicit layouts: depth formats bind only as unfilterable float textures, which an
        // automatic layout would not declare.
        let pipeline = |name: &str, input: wgpu::BindGroupLayoutEntry| -> Result<_> {
            let layout = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some(name),
                entries: &[
                    entry(0, buffer(wgpu::BufferBindingType::Uniform)),
                    entry(1, buffer(wgpu::BufferBindingType::Storage { read_only: false })),
                    input,
                ],
            });
            let pl = dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(name),
                bind_group_layouts: &[Some(&layout)],
                immediate_size: 0,
            });
            let pipeline = ctx.catch("building the source copy pipelines", || {
                dev.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(name),
                    layout: Some(&pl),
                    module: &module,
                    entry_point: Some(name),
                    compilation_options: Default::default(),
                    cache: None,
                })
            })?;
            Ok((layout, pipeline))
        };
        Ok(SourceKernel {
            ctx: ctx.clone(),
            depth_texture: pipeline(
                "depth_texture",
                entry(2, texture(wgpu::TextureSampleType::Float { filterable: false })),
            )?,
            item_texture: pipeline("item_texture", entry(3, texture(wgpu::TextureSampleType::Uint)))?,
            strided_buffer: pipeline(
                "strided_buffer",
                entry(4, buffer(wgpu::BufferBindingType::Storage { read_only: true })),
            )?,
        })
    }

    /// Records the copy of the depth image `src` (`width x height`, `[0, 1]`, 1 = empty) into
    /// `dst` (`width * height` `f32`, `STORAGE` usage). `what` names the image in errors.
    /// Errors ([`Error::Invalid`], one line) on a size, format, sample count or usage that does
    /// not fit, or a buffer too small for its stride.
    pub fn encode_depth(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        src: &GpuImage<'_>,
        width: u32,
        height: u32,
        dst: &wgpu::Buffer,
        what: &str,
    ) -> Result<()> {
        self.encode(encoder, src, Kind::Depth, width, height, dst, what)
    }

    /// Records the copy of the item (object id) image `src` into `dst` (`width * height` `u32`);
    /// as [`Self::encode_depth`] with `R32Uint` textures.
    pub fn encode_items(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        src: &GpuImage<'_>,
        width: u32,
        height: u32,
        dst: &wgpu::Buffer,
        what: &str,
    ) -> Result<()> {
        self.encode(encoder, src, Kind::Items, width, height, dst, what)
    }

    #[allow(clippy::too_many_arguments)]
    fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        src: &GpuImage<'_>,
        kind: Kind,
        width: u32,
        height: u32,
        dst: &wgpu::Buffer,
        what: &str,
    ) -> Result<()> {
        self.ctx.check_texture_size(width, height, what)?;
        let n = width as u64 * height as u64 * 4;
        if dst.size() < n || !dst.usage().contains(wgpu::BufferUsages::STORAGE) {
            return Err(Error::invalid(format!("{what}: the destination needs {n} bytes and STORAGE usage")));
        }
        let dev = &self.ctx.device;
        let params = |stride| {
            dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("zwarp source copy params"),
                contents: bytemuck::bytes_of(&Params { width, height, stride, _pad: 0 }),
                usage: wgpu::BufferUsages::UNIFORM,
            })
        };
        let view;
        let (params, (layout, pipeline), input) = match *src {
            GpuImage::Texture(t) => {
                check_texture(t, kind, width, height, what)?;
                let depth_format = t.format().is_depth_stencil_format();
                view = t.create_view(&wgpu::TextureViewDescriptor {
                    label: Some("zwarp source"),
                    dimension: Some(wgpu::TextureViewDimension::D2),
                    aspect: if depth_format { wgpu::TextureAspect::DepthOnly } else { wgpu::TextureAspect::All },
                    base_mip_level: 0,
                    mip_level_count: Some(1),
                    base_array_layer: 0,
                    array_layer_count: Some(1),
                    ..Default::default()
                });
                let (pipe, binding) =
                    if kind == Kind::Depth { (&self.depth_texture, 2) } else { (&self.item_texture, 3) };
                (
                    params(width),
                    pipe,
                    wgpu::BindGroupEntry { binding, resource: wgpu::BindingResource::TextureView(&view) },
                )
            }
            GpuImage::Buffer { buffer, row_stride } => {
                let need = (row_stride as u64 * (height as u64 - 1) + width as u64) * 4;
                if row_stride < width {
                    return Err(Error::invalid(format!("{what}: row stride {row_stride} < width {width}")));
                }
                if buffer.size() < need {
                    return Err(Error::invalid(format!(
                        "{what}: buffer of {} bytes is too small for {width}x{height} with row stride {row_stride} ({need} bytes)",
                        buffer.size()
                    )));
                }
                if !buffer.usage().contains(wgpu::BufferUsages::STORAGE) {
                    return Err(Error::invalid(format!("{what}: buffer needs STORAGE usage")));
                }
                self.ctx.check_storage_size(buffer.size(), what)?;
                (
                    params(row_stride),
                    &self.strided_buffer,
                    wgpu::BindGroupEntry { binding: 4, resource: buffer.as_entire_binding() },
                )
            }
        };
        let bind = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("zwarp source copy"),
            layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: params.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: dst.as_entire_binding() },
                input,
            ],
        });
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("zwarp source copy"),
            timestamp_writes: None,
        });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups(width.div_ceil(8), height.div_ceil(8), 1);
        Ok(())
    }
}

/// Errors on a texture the copy cannot read as a `kind` image of `width x height`: checked
/// here because wgpu would report them as device errors (a panic by default), not as values.
fn check_texture(t: &wgpu::Texture, kind: Kind, width: u32, height: u32, what: &str) -> Result<()> {
    let f = t.format();
    let formats: &[wgpu::TextureFormat] = match kind {
        Kind::Depth => &[wgpu::TextureFormat::Depth32Float, wgpu::TextureFormat::R32Float],
        Kind::Items => &[wgpu::TextureFormat::R32Uint],
    };
    if !formats.contains(&f) {
        let names: Vec<String> = formats.iter().map(|f| format!("{f:?}")).collect();
        return Err(Error::invalid(format!("{what}: texture format {f:?} is not {}", names.join(" or "))));
    }
    if (t.width(), t.height()) != (width, height) {
        return Err(Error::invalid(format!(
            "{what}: texture is {}x{}, expected {width}x{height}",
            t.width(),
            t.height()
        )));
    }
    if t.dimension() != wgpu::TextureDimension::D2 || t.sample_count() != 1 {
        return Err(Error::invalid(format!("{what}: texture must be 2-D and single-sampled")));
    }
    if !t.usage().contains(wgpu::TextureUsages::TEXTURE_BINDING) {
        return Err(Error::invalid(format!("{what}: texture needs TEXTURE_BINDING usage")));
    }
    Ok(())
}
