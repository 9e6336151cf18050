//! Hole filling as a GPU post-pass over any warped depth + state buffers (seed 000 Sec. 3.5,
//! Fig. 8 dilation; Sec. 4's background fill): the WGSL twin of [`zwarp_warp::fill_holes`]
//! (`HolePolicy::Dilate` = [`zwarp_warp::dilate_holes`], `HolePolicy::Background`). With the
//! far-depth holes of [`crate::WarpKernel`] it gives every CPU hole policy but AWOC on the GPU.
//! Shader: `holes.wgsl`.

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;
use zwarp_core::{Error, Image, Result};
use zwarp_warp::{HolePolicy, PixelState};

use crate::{GpuContext, GpuWarpOutput};

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Params {
    width: u32,
    height: u32,
    radius: u32,
    rule: u32,
}

/// Largest accepted fill radius (as `zwarp_warp::WarpParams::validate`).
const MAX_RADIUS: u32 = 64;

/// The hole-fill post-pass.
pub struct HoleFillKernel {
    ctx: GpuContext,
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
}

impl HoleFillKernel {
    /// Compiles `holes.wgsl`.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let dev = &ctx.device;
        let module = ctx.catch("compiling holes.wgsl", || {
            dev.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("holes.wgsl"),
                source: wgpu::ShaderSource::Wgsl(include_str!("holes.wgsl").into()),
            })
        })?;
        let ro = wgpu::BufferBindingType::Storage { read_only: true };
        let rw = wgpu::BufferBindingType::Storage { read_only: false };
        let (layout, pl) =
            super::buffer_layouts(dev, "zwarp holes", &[wgpu::BufferBindingType::Uniform, ro, ro, rw, rw]);
        let pipeline = ctx.catch("building the hole-fill pipeline", || {
            dev.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("zwarp holes"),
                layout: Some(&pl),
                module: &module,
                entry_point: Some("fill"),
                compilation_options: Default::default(),
                cache: None,
            })
        })?;
        Ok(HoleFillKernel { ctx: ctx.clone(), pipeline, layout })
    }

    /// `(rule, radius)` of a policy; `None` for `FarDepth` (nothing to do).
    fn rule(policy: HolePolicy) -> Result<Option<(u32, u32)>> {
        let (rule, radius) = match policy {
            HolePolicy::FarDepth => return Ok(None),
            HolePolicy::Dilate { radius } => (0, radius),
            HolePolicy::Background { radius } => (1, radius),
            HolePolicy::Awoc => {
                return Err(Error::invalid("AWOC fills holes inside the warp, not as a post-pass"));
            }
        };
        if !(1..=MAX_RADIUS).contains(&radius) {
            return Err(Error::invalid(format!("hole fill radius must be in 1..={MAX_RADIUS}, got {radius}")));
        }
        Ok(Some((rule, radius)))
    }

    /// Records the fill of `warped`'s holes under `policy` into new buffers (the input is read
    /// only). `FarDepth` returns the input buffers unchanged; `Awoc` is an error.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        warped: &GpuWarpOutput,
        policy: HolePolicy,
    ) -> Result<GpuWarpOutput> {
        let (w, h) = (warped.width, warped.height);
        let Some((rule, radius)) = Self::rule(policy)? else {
            return Ok(GpuWarpOutput { depth: warped.depth.clone(), state: warped.state.clone(), width: w, height: h });
        };
        let bytes = w as u64 * h as u64 * 4;
        if w == 0 || h == 0 || warped.depth.size() < bytes || warped.state.size() < bytes {
            return Err(Error::invalid(format!("warped buffers are too small for {w}x{h}")));
        }
        self.ctx.check_storage_size(bytes, "filled depth")?;
        let dev = &self.ctx.device;
        let out = |label| {
            dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        let (depth, state) = (out("zwarp filled depth"), out("zwarp filled state"));
        let ubuf = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("zwarp holes params"),
            contents: bytemuck::bytes_of(&Params { width: w, height: h, radius, rule }),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let bufs = [&ubuf, &warped.depth, &warped.state, &depth, &state];
        let entries: Vec<wgpu::BindGroupEntry> = bufs
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry { binding: i as u32, resource: b.as_entire_binding() })
            .collect();
        let bind = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("zwarp holes"),
            layout: &self.layout,
            entries: &entries,
        });
        let mut pass = encoder
            .begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("zwarp holes"), timestamp_writes: None });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups(w.div_ceil(8), h.div_ceil(8), 1);
        drop(pass);
        Ok(GpuWarpOutput { depth, state, width: w, height: h })
    }

    /// Fills CPU buffers on the GPU and reads them back (the twin of
    /// [`zwarp_warp::fill_holes`] for tests and CPU callers). Errors on size mismatch, empty
    /// images, NaN depths, AWOC or a bad radius.
    pub fn fill(
        &self,
        depth: &Image<f32>,
        state: &Image<PixelState>,
        policy: HolePolicy,
    ) -> Result<(Image<f32>, Image<PixelState>)> {
        depth.check_nonempty("warped depth")?;
        depth.check_same_size(state, "warped depth vs state")?;
        if depth.data().iter().any(|d| d.is_nan()) {
            return Err(Error::invalid("warped depth holds NaN"));
        }
        Self::rule(policy)?;
        let dev = &self.ctx.device;
        let init = |label, contents: &[u8]| {
            dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            })
        };
        let states: Vec<u32> = state.data().iter().map(|s| *s as u32).collect();
        let input = GpuWarpOutput {
            depth: init("zwarp holes depth in", bytemuck::cast_slice(depth.data())),
            state: init("zwarp holes state in", bytemuck::cast_slice(&states)),
            width: depth.width(),
            height: depth.height(),
        };
        let mut enc = dev.create_command_encoder(&Default::default());
        let out = self.encode(&mut enc, &input, policy)?;
        self.ctx.queue.submit([enc.finish()]);
        let r = out.read(&self.ctx)?;
        Ok((r.depth, r.state))
    }
}
