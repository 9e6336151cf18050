//! GPU motion field (seed 000, Sec. 3.1), the WGSL twin of [`zwarp_core::motion_field`].
//! Shader: `motion.wgsl`.

use bytemuck::{Pod, Zeroable};
use glam::Mat4;
use wgpu::util::DeviceExt;
use zwarp_core::{Camera, Error, Image, Motion, Result};
use zwarp_gpu::readback::{padded_bytes_per_row, read_buffer};
use zwarp_gpu::render::{GpuFrame, GpuScene, LayerTargets, PeelOptions, Renderer};
use zwarp_gpu::GpuContext;

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Params {
    inv_a: [[f32; 4]; 4],
    vp_b: [[f32; 4]; 4],
    size_a: [u32; 2],
    size_b: [u32; 2],
    row_stride: u32,
    n_deltas: u32,
    has_items: u32,
    _pad: u32,
}

/// GPU-resident inputs of [`MotionKernel::encode`]: a depth buffer (f32 per texel) and
/// optionally an item buffer (u32 per texel) with the same row stride, e.g. 256-byte padded
/// copies of a depth texture and an item texture.
pub struct MotionInput<'a> {
    /// Source depth, `[0, 1]`, 1 = empty; `row_stride` elements per row.
    pub depth: &'a wgpu::Buffer,
    /// Source item ids (same layout), or `None` for camera motion only.
    pub items: Option<&'a wgpu::Buffer>,
    /// Elements per row (>= the source width).
    pub row_stride: u32,
}

/// Compute pipeline producing motion buffers on the GPU.
pub struct MotionKernel {
    ctx: GpuContext,
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    dummy: wgpu::Buffer,
}

impl MotionKernel {
    /// Compiles `motion.wgsl`.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let dev = &ctx.device;
        let module = ctx.shader("motion.wgsl", include_str!("motion.wgsl"))?;
        let ro = wgpu::BufferBindingType::Storage { read_only: true };
        let (layout, pl) = zwarp_gpu::kernel::buffer_layouts(
            dev,
            "zwarp motion",
            &[wgpu::BufferBindingType::Uniform, ro, ro, ro, wgpu::BufferBindingType::Storage { read_only: false }],
        );
        let pipeline = ctx.catch("building the motion pipeline", || {
            dev.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("zwarp motion"),
                layout: Some(&pl),
                module: &module,
                entry_point: Some("motion_field"),
                compilation_options: Default::default(),
                cache: None,
            })
        })?;
        // Bound where a caller has no item buffer / no deltas (bindings cannot be empty).
        let dummy = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("zwarp dummy"),
            contents: &[0u8; 64],
            usage: wgpu::BufferUsages::STORAGE,
        });
        Ok(MotionKernel { ctx: ctx.clone(), pipeline, layout, dummy })
    }

    /// Records the motion kernel: `out` receives `width_a * height_a` [`Motion`] samples
    /// (12 bytes each, row-major, no padding). `object_deltas` as in
    /// [`zwarp_core::motion_field`] (`M(t_b) M(t_a)^-1` per object id).
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        input: &MotionInput<'_>,
        cam_a: &Camera,
        cam_b: &Camera,
        object_deltas: &[Mat4],
        out: &wgpu::Buffer,
    ) -> Result<()> {
        let (wa, ha) = (cam_a.width, cam_a.height);
        self.ctx.check_texture_size(wa, ha, "motion source")?;
        if input.row_stride < wa {
            return Err(Error::invalid(format!("motion input row stride {} < width {wa}", input.row_stride)));
        }
        let need_in = input.row_stride as u64 * (ha as u64 - 1) * 4 + wa as u64 * 4;
        if input.depth.size() < need_in || input.items.is_some_and(|b| b.size() < need_in) {
            return Err(Error::invalid(format!("motion input buffers hold fewer than {need_in} bytes")));
        }
        let need_out = wa as u64 * ha as u64 * std::mem::size_of::<Motion>() as u64;
        if out.size() < need_out {
            return Err(Error::invalid(format!("motion output buffer holds {} < {need_out} bytes", out.size())));
        }
        self.ctx.check_storage_size(need_out, "motion buffer")?;
        let vp_b = cam_b.view_proj();
        let inv_a = cam_a.view_proj().inverse();
        if !inv_a.is_finite() || !vp_b.is_finite() || object_deltas.iter().any(|m| !m.is_finite()) {
            return Err(Error::invalid("camera or object motion matrices are not finite"));
        }
        // Same products as the CPU (`vp_b * delta`), formed on the CPU in f32.
        let deltas: Vec<[[f32; 4]; 4]> = object_deltas.iter().map(|d| (vp_b * *d).to_cols_array_2d()).collect();
        self.ctx.check_storage_size((deltas.len() * 64) as u64, "object motion buffer")?;
        let params = Params {
            inv_a: inv_a.to_cols_array_2d(),
            vp_b: vp_b.to_cols_array_2d(),
            size_a: [wa, ha],
            size_b: [cam_b.width, cam_b.height],
            row_stride: input.row_stride,
            n_deltas: deltas.len() as u32,
            has_items: input.items.is_some() as u32,
            _pad: 0,
        };
        let dev = &self.ctx.device;
        let ubuf = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("zwarp motion params"),
            contents: bytemuck::bytes_of(&params),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let dbuf = (!deltas.is_empty()).then(|| {
            dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("zwarp object deltas"),
                contents: bytemuck::cast_slice(&deltas),
                usage: wgpu::BufferUsages::STORAGE,
            })
        });
        let bind = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("zwarp motion"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: ubuf.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: input.depth.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: input.items.unwrap_or(&self.dummy).as_entire_binding() },
                wgpu::BindGroupEntry { binding: 3, resource: dbuf.as_ref().unwrap_or(&self.dummy).as_entire_binding() },
                wgpu::BindGroupEntry { binding: 4, resource: out.as_entire_binding() },
            ],
        });
        let mut pass = encoder
            .begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("zwarp motion"), timestamp_writes: None });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups(wa.div_ceil(8), ha.div_ceil(8), 1);
        Ok(())
    }

    /// Motion buffer from CPU images: same inputs, validation and result as
    /// [`zwarp_core::motion_field`] (to within float rounding: tests require < 1e-3 px).
    pub fn motion_field(
        &self,
        depth: &Image<f32>,
        items: Option<&Image<u32>>,
        cam_a: &Camera,
        cam_b: &Camera,
        object_deltas: &[Mat4],
    ) -> Result<Image<Motion>> {
        zwarp_core::motion::check_motion_inputs(depth, items, cam_a)?;
        let dev = &self.ctx.device;
        let n = depth.len();
        self.ctx.check_storage_size((n * std::mem::size_of::<Motion>()) as u64, "motion buffer")?;
        let dbuf = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("zwarp depth in"),
            contents: bytemuck::cast_slice(depth.data()),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let ibuf = items.map(|it| {
            dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("zwarp items in"),
                contents: bytemuck::cast_slice(it.data()),
                usage: wgpu::BufferUsages::STORAGE,
            })
        });
        let out = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("zwarp motion out"),
            size: (n * std::mem::size_of::<Motion>()) as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let mut enc = dev.create_command_encoder(&Default::default());
        let input = MotionInput { depth: &dbuf, items: ibuf.as_ref(), row_stride: depth.width() };
        self.encode(&mut enc, &input, cam_a, cam_b, object_deltas, &out)?;
        self.ctx.queue.submit([enc.finish()]);
        let data: Vec<Motion> = read_buffer(&self.ctx, &out, n)?;
        Image::from_vec(depth.width(), depth.height(), data)
    }

    /// Renders view A (depth + items) and its motion field towards view B entirely on the GPU
    /// (render pass, texture-to-buffer copies, motion kernel in one submission), the twin of
    /// `zwarp_raster::render_motion` (seed 000 Sec. 3.1, object motion from
    /// [`GpuScene::object_deltas`]`(t_a, t_b)`).
    pub fn render_motion(
        &self,
        renderer: &Renderer,
        scene: &GpuScene,
        cam_a: &Camera,
        t_a: f32,
        cam_b: &Camera,
        t_b: f32,
    ) -> Result<(GpuFrame, Image<Motion>)> {
        if !t_b.is_finite() {
            return Err(Error::invalid(format!("target time t_b must be finite, got {t_b}")));
        }
        self.ctx.check_texture_size(cam_b.width, cam_b.height, "motion target view")?;
        let (w, h) = (cam_a.width, cam_a.height);
        let targets = LayerTargets::new(renderer, w, h, 1, false)?;
        let dev = &self.ctx.device;
        let mut enc = dev.create_command_encoder(&Default::default());
        renderer.encode_layers(
            &mut enc,
            scene,
            cam_a,
            t_a,
            &PeelOptions { layers: 1, ..Default::default() },
            &targets,
        )?;
        // The item texture -> buffer copy needs 256-byte row padding; depth is copied with the
        // same stride, and the kernel reads with that row stride instead of repacking.
        let bpr = padded_bytes_per_row(w, 4);
        let bytes = bpr as u64 * h as u64;
        self.ctx.check_storage_size(bytes, "padded depth buffer")?;
        let make = |label| {
            dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        let (dbuf, ibuf) = (make("zwarp depth copy"), make("zwarp items copy"));
        renderer.encode_depth_copy(&mut enc, &targets.depth[0], &dbuf, bpr / 4)?;
        enc.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: &targets.items[0],
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &ibuf,
                layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(bpr), rows_per_image: Some(h) },
            },
            wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
        );
        let n = w as usize * h as usize;
        let out = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("zwarp motion out"),
            size: (n * std::mem::size_of::<Motion>()) as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let input = MotionInput { depth: &dbuf, items: Some(&ibuf), row_stride: bpr / 4 };
        let deltas = scene.object_deltas(t_a, t_b);
        self.encode(&mut enc, &input, cam_a, cam_b, &deltas, &out)?;
        self.ctx.queue.submit([enc.finish()]);
        let stride = (bpr / 4) as usize;
        let unpad = |v: Vec<u32>| -> Vec<u32> { v.chunks(stride).flat_map(|row| row[..w as usize].to_vec()).collect() };
        let depth_bits = unpad(read_buffer::<u32>(&self.ctx, &dbuf, stride * h as usize)?);
        let items = unpad(read_buffer::<u32>(&self.ctx, &ibuf, stride * h as usize)?);
        let motion: Vec<Motion> = read_buffer(&self.ctx, &out, n)?;
        let frame = GpuFrame {
            depth: Image::from_vec(w, h, depth_bits.into_iter().map(f32::from_bits).collect())?,
            items: Image::from_vec(w, h, items)?,
            color: None,
        };
        Ok((frame, Image::from_vec(w, h, motion)?))
    }
}
