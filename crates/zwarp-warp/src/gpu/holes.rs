//! Hole filling as a GPU post-pass over any warped depth + state buffers (seed 000 Sec. 3.5,
//! Fig. 8 dilation; Sec. 4's background fill): the WGSL twin of [`crate::fill_holes`]
//! (`HolePolicy::Dilate` = [`crate::dilate_holes`], `HolePolicy::Background`) and of
//! [`crate::holes::fill_background`] (sky seen through holes, bracketed holes, image-border
//! strips). With the far-depth holes of [`super::WarpKernel`] it gives every CPU hole policy but
//! AWOC on the GPU. Shader: `holes.wgsl`.

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;
use zwarp_core::{Error, Image, Result, EMPTY_DEPTH};
use zwarp_gpu::kernel::AutoPipelines;
use zwarp_gpu::GpuContext;

use super::GpuWarpOutput;
use crate::holes::BackgroundLimits;
use crate::{HolePolicy, PixelState, SearchParams, WarpLayer};

/// Mirror of `Params` in holes.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Default)]
struct Params {
    width: u32,
    height: u32,
    radius: u32,
    rule: u32,
    iterations: u32,
    threshold: f32,
    reach: u32,
    accelerate: u32,
    /// `sky`: the source layers' size, `multisample` times `width x height`.
    src_width: u32,
    src_height: u32,
    /// `sky`: source samples per pixel and axis (`crate::WarpParams::multisample`), as a
    /// float.
    multisample: f32,
    _pad: u32,
}

/// Largest accepted fill radius (as `crate::WarpParams::validate`).
const MAX_RADIUS: u32 = 64;

/// The hole-fill post-passes.
pub struct HoleFillKernel {
    ctx: GpuContext,
    fill: wgpu::ComputePipeline,
    sky: wgpu::ComputePipeline,
}

impl HoleFillKernel {
    /// Compiles `holes.wgsl`.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let pipelines = AutoPipelines::new(ctx, "holes.wgsl", include_str!("holes.wgsl"), "hole-fill")?;
        Ok(HoleFillKernel { ctx: ctx.clone(), fill: pipelines.pipeline("fill")?, sky: pipelines.pipeline("sky")? })
    }

    /// Records one `w x h` dispatch of `pipeline` with `params` at binding 0 and `buffers` at
    /// their bindings.
    fn dispatch(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        pipeline: &wgpu::ComputePipeline,
        params: Params,
        buffers: &[(u32, &wgpu::Buffer)],
    ) {
        let dev = &self.ctx.device;
        let ubuf = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("zwarp holes params"),
            contents: bytemuck::bytes_of(&params),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let entries: Vec<wgpu::BindGroupEntry> = std::iter::once((0, &ubuf))
            .chain(buffers.iter().copied())
            .map(|(binding, b)| wgpu::BindGroupEntry { binding, resource: b.as_entire_binding() })
            .collect();
        let bind = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("zwarp holes"),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &entries,
        });
        let mut pass = encoder
            .begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("zwarp holes"), timestamp_writes: None });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups(params.width.div_ceil(8), params.height.div_ceil(8), 1);
    }

    /// Two new `w x h` storage buffers (depth, state) for a pass's output.
    fn output_buffers(&self, w: u32, h: u32) -> Result<(wgpu::Buffer, wgpu::Buffer)> {
        let bytes = w as u64 * h as u64 * 4;
        self.ctx.check_storage_size(bytes, "filled depth")?;
        let out = |label| {
            self.ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        Ok((out("zwarp filled depth"), out("zwarp filled state")))
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
        Self::check_warped(warped)?;
        let (depth, state) = self.output_buffers(w, h)?;
        let params = Params { width: w, height: h, radius, rule, ..Params::default() };
        self.dispatch(encoder, &self.fill, params, &[(1, &warped.depth), (2, &warped.state), (3, &depth), (4, &state)]);
        Ok(GpuWarpOutput { depth, state, width: w, height: h })
    }

    fn check_warped(warped: &GpuWarpOutput) -> Result<()> {
        let (w, h) = (warped.width, warped.height);
        let bytes = w as u64 * h as u64 * 4;
        if w == 0 || h == 0 || warped.depth.size() < bytes || warped.state.size() < bytes {
            return Err(Error::invalid(format!("warped buffers are too small for {w}x{h}")));
        }
        Ok(())
    }

    /// Records [`crate::holes::fill_background`] of `warped` (a far-hole warp) into new
    /// buffers: the sky pass (in place on a copy), the bracketed fill within `limits.bracket`,
    /// the border pass within `limits.reach`. `empty` holds one `u32` per pixel, 1 where no
    /// source layer has a surface; `motion` layer 0's motion as `vec2<f32>` per pixel; `limits`
    /// from [`BackgroundLimits::of`] on the same layers.
    pub fn encode_background(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        warped: &GpuWarpOutput,
        empty: &wgpu::Buffer,
        motion: &wgpu::Buffer,
        limits: BackgroundLimits,
        search: &SearchParams,
    ) -> Result<GpuWarpOutput> {
        self.encode_background_multisampled(encoder, warped, empty, motion, 1, limits, search)
    }

    /// [`Self::encode_background`] for a warp from a multisampled source
    /// (`crate::WarpParams::multisample` = `multisample`): `empty` and `motion` hold one
    /// entry per source sample, `multisample` times `warped`'s size on both axes, and `limits`
    /// come from [`BackgroundLimits::of_multisampled`]. The sky pass searches target pixel
    /// `(x, y)` at the source position `multisample * (x + 0.5, y + 0.5)`, as the CPU does.
    #[allow(clippy::too_many_arguments)]
    pub fn encode_background_multisampled(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        warped: &GpuWarpOutput,
        empty: &wgpu::Buffer,
        motion: &wgpu::Buffer,
        multisample: u32,
        limits: BackgroundLimits,
        search: &SearchParams,
    ) -> Result<GpuWarpOutput> {
        Self::check_warped(warped)?;
        let (w, h) = (warped.width, warped.height);
        let m = multisample;
        let n = w as u64 * h as u64;
        let (sw, sh) = (w as u64 * m as u64, h as u64 * m as u64);
        if m == 0 || sw > u32::MAX as u64 || sh > u32::MAX as u64 {
            return Err(Error::invalid(format!("multisample {m} is not a valid source for {w}x{h}")));
        }
        let sn = sw * sh;
        if empty.size() < sn * 4 || motion.size() < sn * 8 {
            return Err(Error::invalid(format!("background buffers are too small for {sw}x{sh}")));
        }
        let (depth, state) = self.output_buffers(w, h)?;
        encoder.copy_buffer_to_buffer(&warped.depth, 0, &depth, 0, n * 4);
        encoder.copy_buffer_to_buffer(&warped.state, 0, &state, 0, n * 4);
        let params = Params {
            width: w,
            height: h,
            iterations: search.iterations,
            threshold: search.threshold,
            accelerate: search.accelerate as u32,
            src_width: sw as u32,
            src_height: sh as u32,
            multisample: m as f32,
            ..Params::default()
        };
        self.dispatch(encoder, &self.sky, params, &[(3, &depth), (4, &state), (5, empty), (6, motion)]);
        let sky = GpuWarpOutput { depth, state, width: w, height: h };
        let bracketed = self.encode(encoder, &sky, HolePolicy::Background { radius: limits.bracket })?;
        let (depth, state) = self.output_buffers(w, h)?;
        let params = Params { width: w, height: h, rule: 2, reach: limits.reach, ..Params::default() };
        self.dispatch(
            encoder,
            &self.fill,
            params,
            &[(1, &bracketed.depth), (2, &bracketed.state), (3, &depth), (4, &state)],
        );
        Ok(GpuWarpOutput { depth, state, width: w, height: h })
    }

    /// [`crate::holes::fill_background`] on the GPU for CPU buffers: `depth` / `state` of
    /// a far-hole warp of `layers`, filled and read back. Like the CPU, source layers that are
    /// `m` times `depth`'s size on both axes are a multisampled source
    /// (`crate::WarpParams::multisample` = m, inferred from the size ratio). Same errors
    /// as the CPU function, plus size mismatches between `depth` and `state`.
    pub fn fill_background(
        &self,
        layers: &[WarpLayer<'_>],
        depth: &Image<f32>,
        state: &Image<PixelState>,
        radius: u32,
        search: &SearchParams,
    ) -> Result<(Image<f32>, Image<PixelState>)> {
        depth.check_nonempty("warped depth")?;
        depth.check_same_size(state, "warped depth vs state")?;
        let (w, h) = depth.size();
        let (sw, sh) = layers.first().map_or((w, h), |l| l.depth.size());
        let m = crate::holes::source_multisample(layers, w);
        let limits = BackgroundLimits::of_multisampled(layers, w, h, m, radius)?;
        let n = sw as usize * sh as usize;
        let empty: Vec<u32> = (0..n).map(|i| layers.iter().all(|l| l.depth.data()[i] >= EMPTY_DEPTH) as u32).collect();
        let motion: Vec<[f32; 2]> = layers[0].motion.data().iter().map(|m| m.v.to_array()).collect();
        let input = self.upload(depth, state);
        let dev = &self.ctx.device;
        let storage = |label, contents: &[u8]| {
            dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::STORAGE,
            })
        };
        let empty = storage("zwarp holes empty", bytemuck::cast_slice(&empty));
        let motion = storage("zwarp holes motion", bytemuck::cast_slice(&motion));
        let mut enc = dev.create_command_encoder(&Default::default());
        let out = self.encode_background_multisampled(&mut enc, &input, &empty, &motion, m, limits, search)?;
        self.ctx.queue.submit([enc.finish()]);
        let r = out.read(&self.ctx)?;
        Ok((r.depth, r.state))
    }

    /// Uploads CPU depth + state buffers as a [`GpuWarpOutput`].
    fn upload(&self, depth: &Image<f32>, state: &Image<PixelState>) -> GpuWarpOutput {
        let init = |label, contents: &[u8]| {
            self.ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            })
        };
        let states: Vec<u32> = state.data().iter().map(|s| *s as u32).collect();
        GpuWarpOutput {
            depth: init("zwarp holes depth in", bytemuck::cast_slice(depth.data())),
            state: init("zwarp holes state in", bytemuck::cast_slice(&states)),
            width: depth.width(),
            height: depth.height(),
        }
    }

    /// Fills CPU buffers on the GPU and reads them back (the twin of
    /// [`crate::fill_holes`] for tests and CPU callers). Errors on size mismatch, empty
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
        let input = self.upload(depth, state);
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        let out = self.encode(&mut enc, &input, policy)?;
        self.ctx.queue.submit([enc.finish()]);
        let r = out.read(&self.ctx)?;
        Ok((r.depth, r.state))
    }
}

/// The WGSL twin of `crate::predict_into`: the warp of `layers` (`warp`) and, under
/// `HolePolicy::Background`, the background protocol over its far holes (`fill`); any other
/// hole policy runs inside the warp.
pub fn predict(
    warp: &super::WarpKernel,
    fill: &HoleFillKernel,
    layers: &[WarpLayer<'_>],
    params: &crate::WarpParams,
) -> Result<crate::WarpOutput> {
    match params.holes {
        HolePolicy::Background { radius } => {
            let far = crate::WarpParams { holes: HolePolicy::FarDepth, ..*params };
            let mut o = warp.warp(layers, &far)?;
            (o.depth, o.state) = fill.fill_background(layers, &o.depth, &o.state, radius, &params.search())?;
            Ok(o)
        }
        _ => warp.warp(layers, params),
    }
}
