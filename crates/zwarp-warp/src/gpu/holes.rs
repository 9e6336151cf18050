//! Hole filling as a GPU post-pass over any warped depth + state buffers (seed 000 Sec. 3.5,
//! Fig. 8 dilation; Sec. 4's background fill): the WGSL twin of [`crate::fill_holes`]
//! (`HolePolicy::Dilate` = [`crate::dilate_holes`], `HolePolicy::Background`) and of
//! [`crate::holes::fill_background`] (the source layers' measurements, i.e. the
//! empty-background mask and [`BackgroundLimits`], then sky seen through holes, bracketed holes,
//! image-border strips), all from GPU-resident source layers. With the far-depth holes of
//! [`super::WarpKernel`] it gives every CPU hole policy but AWOC on the GPU, and
//! [`encode_predict`] / [`predict`] the complete prediction. Shader: `holes.wgsl`.

use bytemuck::{Pod, Zeroable};
use glam::Vec2;
use wgpu::util::DeviceExt;
use zwarp_core::{Error, Image, Result};
use zwarp_gpu::kernel::AutoPipelines;
use zwarp_gpu::readback::read_buffer;
use zwarp_gpu::GpuContext;

use super::{GpuWarpLayer, GpuWarpOutput};
use crate::bounds::MotionScales;
use crate::holes::BackgroundLimits;
use crate::{HolePolicy, PixelState, SearchParams, WarpLayer, WarpOutput};

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
    /// `surfaces`: the index of the measured source layer.
    layer: u32,
}

/// Largest accepted fill radius (as `crate::WarpParams::validate`).
const MAX_RADIUS: u32 = 64;

/// The hole-fill post-passes.
pub struct HoleFillKernel {
    ctx: GpuContext,
    fill: wgpu::ComputePipeline,
    fill_measured: wgpu::ComputePipeline,
    sky: wgpu::ComputePipeline,
    lone: wgpu::ComputePipeline,
    surfaces: wgpu::ComputePipeline,
    limits: wgpu::ComputePipeline,
}

impl HoleFillKernel {
    /// Compiles `holes.wgsl`.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let pipelines = AutoPipelines::new(
            ctx,
            "holes.wgsl",
            concat!(include_str!("fill_rule.wgsl"), include_str!("holes.wgsl")),
            "hole-fill",
        )?;
        Ok(HoleFillKernel {
            ctx: ctx.clone(),
            fill: pipelines.pipeline("fill")?,
            fill_measured: pipelines.pipeline("fill_measured")?,
            sky: pipelines.pipeline("sky")?,
            lone: pipelines.pipeline("lone")?,
            surfaces: pipelines.pipeline("surfaces")?,
            limits: pipelines.pipeline("limits")?,
        })
    }

    /// Records one dispatch of `groups` workgroups of `pipeline` with `params` at binding 0 and
    /// `buffers` at their bindings.
    fn dispatch(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        pipeline: &wgpu::ComputePipeline,
        params: Params,
        buffers: &[(u32, &wgpu::Buffer)],
        groups: (u32, u32),
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
        pass.dispatch_workgroups(groups.0, groups.1, 1);
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
        let groups = (w.div_ceil(8), h.div_ceil(8));
        let buffers = [(1, &warped.depth), (2, &warped.state), (3, &depth), (4, &state)];
        self.dispatch(encoder, &self.fill, params, &buffers, groups);
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

    /// Records [`crate::holes::fill_background`] of `warped` (a far-hole warp of `layers`, one
    /// sample per pixel) into new buffers; see [`Self::encode_background_multisampled`].
    pub fn encode_background(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        warped: &GpuWarpOutput,
        layers: &[GpuWarpLayer<'_>],
        radius: u32,
        search: &SearchParams,
    ) -> Result<GpuWarpOutput> {
        self.encode_background_multisampled(encoder, warped, layers, 1, radius, search)
    }

    /// Records [`crate::holes::fill_background`] (seed 000 Sec. 4) of `warped`, a far-hole warp
    /// of the GPU-resident source `layers` (nearest first; their depth and
    /// [`Motion`](zwarp_core::Motion) buffers, `axis` unused) with
    /// `crate::WarpParams::multisample` = `multisample` (the layers hold `multisample` times
    /// `warped`'s size on both axes), into new buffers: the measurements of the layers
    /// ([`Self::encode_limits`]), the lone revealed pixels made holes (from `warped` into a
    /// copy, the warp's state code 3 marking [`crate::WarpOutput::revealed`]), the sky pass (in place on a copy, searching target pixel
    /// `(x, y)` at the source position `multisample * (x + 0.5, y + 0.5)` as the CPU does), the
    /// bracketed fill within the measured bracket, the border pass within the measured reach.
    /// Nothing is read back. Errors as [`Self::encode_limits`].
    #[allow(clippy::too_many_arguments)]
    pub fn encode_background_multisampled(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        warped: &GpuWarpOutput,
        layers: &[GpuWarpLayer<'_>],
        multisample: u32,
        radius: u32,
        search: &SearchParams,
    ) -> Result<GpuWarpOutput> {
        Self::check_warped(warped)?;
        let (w, h) = (warped.width, warped.height);
        let limits = self.encode_limits(encoder, layers, w, h, multisample, radius)?;
        let (sw, sh) = limits.source_size;
        let (depth, state) = self.output_buffers(w, h)?;
        let params = Params {
            width: w,
            height: h,
            iterations: search.iterations,
            threshold: search.threshold,
            accelerate: search.accelerate as u32,
            src_width: sw,
            src_height: sh,
            multisample: multisample as f32,
            ..Params::default()
        };
        let groups = (w.div_ceil(8), h.div_ceil(8));
        // 0. Lone revealed pixels become holes (into the copy the sky pass then works on in place).
        self.dispatch(
            encoder,
            &self.lone,
            Params { width: w, height: h, ..Params::default() },
            &[(1, &warped.depth), (2, &warped.state), (3, &depth), (4, &state)],
            groups,
        );
        let (empty, motion) = (&limits.empty, layers[0].motion);
        self.dispatch(encoder, &self.sky, params, &[(3, &depth), (4, &state), (5, empty), (6, motion)], groups);
        let mut current = (depth, state);
        // 2. Bracketed holes (rule 1), 3. holes open to the image border (rule 2).
        for rule in [1, 2] {
            let (depth, state) = self.output_buffers(w, h)?;
            let params = Params { width: w, height: h, rule, ..Params::default() };
            self.dispatch(
                encoder,
                &self.fill_measured,
                params,
                &[(1, &current.0), (2, &current.1), (3, &depth), (4, &state), (8, &limits.limits)],
                groups,
            );
            current = (depth, state);
        }
        Ok(GpuWarpOutput { depth: current.0, state: current.1, width: w, height: h })
    }

    /// Records the measurements [`crate::holes::fill_background`] takes from the source layers,
    /// on the GPU: the empty-background mask (per source sample, 1 where no layer has a
    /// surface) and [`BackgroundLimits::of_multisampled`]`(layers, width, height, multisample,
    /// radius)` (a workgroup then atomic min-max reduction of the surfaces' motion, then the
    /// CPU's arithmetic). The values equal the CPU's on finite motion (for a `multisample`
    /// that is not a power of two, up to WGSL's division accuracy). Motion is not checked for
    /// NaN or infinities (the CPU rejects them): such limits count as the widest ones, which
    /// stay bounded (bracket <= `radius`, reach <= `max(width, height)`). Errors
    /// ([`Error::Invalid`], the CPU's messages where it has them) on no layer, a radius outside
    /// 1..=64, a zero size or `multisample`, buffers smaller than the source size.
    pub fn encode_limits(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        layers: &[GpuWarpLayer<'_>],
        width: u32,
        height: u32,
        multisample: u32,
        radius: u32,
    ) -> Result<GpuBackgroundLimits> {
        if layers.is_empty() {
            return Err(Error::invalid("fill_background needs at least one source layer"));
        }
        if !(1..=MAX_RADIUS).contains(&radius) {
            return Err(Error::invalid(format!("fill_background: radius must be in 1..={MAX_RADIUS}, got {radius}")));
        }
        let m = multisample;
        let (sw, sh) = (width as u64 * m as u64, height as u64 * m as u64);
        if width == 0 || height == 0 || m == 0 || sw > u32::MAX as u64 || sh > u32::MAX as u64 {
            return Err(Error::invalid(format!("fill_background: no {m}x{m}-sampled source for {width}x{height}")));
        }
        let sn = sw * sh;
        if let Some(k) = layers.iter().position(|l| l.depth.size() < sn * 4 || l.motion.size() < sn * 12) {
            return Err(Error::invalid(format!(
                "fill_background: source layer {k}'s buffers are too small for {sw}x{sh}"
            )));
        }
        self.ctx.check_storage_size(sn * 4, "empty-background mask")?;
        let dev = &self.ctx.device;
        let empty = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("zwarp holes empty"),
            size: sn * 4,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let limits = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("zwarp holes limits"),
            size: 32,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        // Zero is the identity of the reduction's keys.
        encoder.clear_buffer(&limits, 0, None);
        let (sw, sh) = (sw as u32, sh as u32);
        let base =
            Params { width, height, radius, src_width: sw, src_height: sh, multisample: m as f32, ..Params::default() };
        for (k, l) in layers.iter().enumerate() {
            self.dispatch(
                encoder,
                &self.surfaces,
                Params { layer: k as u32, ..base },
                &[(5, &empty), (6, l.motion), (7, l.depth), (8, &limits)],
                (sw.div_ceil(8), sh.div_ceil(8)),
            );
        }
        self.dispatch(encoder, &self.limits, base, &[(8, &limits)], (1, 1));
        Ok(GpuBackgroundLimits { empty, limits, source_size: (sw, sh) })
    }

    /// [`crate::holes::fill_background`] on the GPU for CPU buffers: `warped`, a far-hole warp
    /// of `layers` (its depth, state and [`crate::WarpOutput::revealed`]), filled and read back:
    /// the layers are uploaded and filled by [`Self::encode_background_multisampled`]. Like the CPU, source layers that are `m` times
    /// `depth`'s size on both axes are a multisampled source (`crate::WarpParams::multisample`
    /// = m, inferred from the size ratio). Same errors as the CPU function (its checks run
    /// first), plus size mismatches between `depth` and `state`.
    pub fn fill_background(
        &self,
        layers: &[WarpLayer<'_>],
        warped: &WarpOutput,
        radius: u32,
        search: &SearchParams,
    ) -> Result<WarpOutput> {
        let (depth, state) = (&warped.depth, &warped.state);
        depth.check_nonempty("warped depth")?;
        depth.check_same_size(state, "warped depth vs state")?;
        let (w, h) = depth.size();
        let m = crate::holes::source_multisample(layers, w);
        // The CPU's checks and errors (sizes, finite motion, radius); the GPU measures the
        // limits itself.
        BackgroundLimits::of_multisampled(layers, w, h, m, radius)?;
        let buffers = super::warp::upload_layers(&self.ctx, layers)?;
        let views: Vec<GpuWarpLayer<'_>> =
            buffers.iter().map(|(d, m)| GpuWarpLayer { depth: d, motion: m, axis: Vec2::X }).collect();
        crate::holes::check_revealed(state, &warped.revealed)?;
        let input = self.upload(depth, state, &warped.revealed);
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        let out = self.encode_background_multisampled(&mut enc, &input, &views, m, radius, search)?;
        self.ctx.queue.submit([enc.finish()]);
        out.read(&self.ctx)
    }

    /// Uploads CPU depth + state buffers as a [`GpuWarpOutput`], the `revealed` pixels
    /// (converged) with the warp's state code 3.
    fn upload(&self, depth: &Image<f32>, state: &Image<PixelState>, revealed: &[u32]) -> GpuWarpOutput {
        let init = |label, contents: &[u8]| {
            self.ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            })
        };
        let mut states: Vec<u32> = state.data().iter().map(|s| *s as u32).collect();
        for &i in revealed {
            states[i as usize] = 3;
        }
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
        let input = self.upload(depth, state, &[]);
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        let out = self.encode(&mut enc, &input, policy)?;
        self.ctx.queue.submit([enc.finish()]);
        let r = out.read(&self.ctx)?;
        Ok((r.depth, r.state))
    }
}

/// The measurements of the source layers that the background protocol (seed 000 Sec. 4) fills
/// with, resident on the GPU: written by [`HoleFillKernel::encode_limits`].
#[derive(Debug)]
pub struct GpuBackgroundLimits {
    /// One `u32` per source sample: 1 where no source layer has a surface (every depth `>= 1`),
    /// the samples the sky pass converges on.
    pub empty: wgpu::Buffer,
    /// Eight `u32`: the surfaces' motion range as order keys (0..4), then
    /// [`BackgroundLimits::bracket`] (4) and [`BackgroundLimits::reach`] (5).
    pub limits: wgpu::Buffer,
    /// The source layers' size (samples).
    pub source_size: (u32, u32),
}

impl GpuBackgroundLimits {
    /// Reads the limits back (submits a copy and waits).
    pub fn read(&self, ctx: &GpuContext) -> Result<BackgroundLimits> {
        let v = read_buffer::<u32>(ctx, &self.limits, 8)?;
        Ok(BackgroundLimits { bracket: v[4], reach: v[5] })
    }
}

/// The WGSL twin of `crate::predict_into` for CPU buffers: `layers` are checked (the CPU's
/// checks, [`super::WarpKernel::upload`]), uploaded and predicted by [`encode_predict`] with
/// the bound frames of [`super::WarpKernel::frames`], and the result is read back.
pub fn predict(
    warp: &super::WarpKernel,
    fill: &HoleFillKernel,
    layers: &[WarpLayer<'_>],
    params: &crate::WarpParams,
) -> Result<crate::WarpOutput> {
    let HolePolicy::Background { radius } = params.holes else {
        return warp.warp(layers, params);
    };
    let buffers = warp.upload(layers, params)?;
    let (w, h) = layers[0].depth.size();
    let (tw, th) = super::WarpKernel::target_size(w, h, params.multisample)?;
    // The CPU's errors for the background protocol (non-finite motion, radius).
    BackgroundLimits::of_multisampled(layers, tw, th, params.multisample, radius)?;
    let frames = super::WarpKernel::frames(layers, params.bound, MotionScales::for_scale(params.motion_scale));
    let views: Vec<GpuWarpLayer<'_>> =
        buffers.iter().zip(frames).map(|((d, m), axis)| GpuWarpLayer { depth: d, motion: m, axis }).collect();
    let mut enc = fill.ctx.device.create_command_encoder(&Default::default());
    let out = encode_predict(warp, fill, &mut enc, &views, w, h, params)?;
    fill.ctx.queue.submit([enc.finish()]);
    out.read(&fill.ctx)
}

/// Records the complete prediction of seed 000 (the twin of `crate::predict_into`) from
/// GPU-resident source layers of `width x height` samples: the warp (Sec. 3,
/// [`super::WarpKernel::encode`]) and, under `HolePolicy::Background`, the warp with far holes
/// followed by the background protocol of Sec. 4
/// ([`HoleFillKernel::encode_background_multisampled`], its limits measured on the GPU); any
/// other hole policy runs inside the warp. Nothing is read back: the output stays on the GPU.
/// NaN inputs are not checked (as in [`super::WarpKernel::encode`]). `warp` and `fill` must
/// share a device.
pub fn encode_predict(
    warp: &super::WarpKernel,
    fill: &HoleFillKernel,
    encoder: &mut wgpu::CommandEncoder,
    layers: &[GpuWarpLayer<'_>],
    width: u32,
    height: u32,
    params: &crate::WarpParams,
) -> Result<GpuWarpOutput> {
    match params.holes {
        HolePolicy::Background { radius } => {
            let far = crate::WarpParams { holes: HolePolicy::FarDepth, ..*params };
            let warped = warp.encode(encoder, layers, width, height, &far)?;
            fill.encode_background_multisampled(encoder, &warped, layers, params.multisample, radius, &params.search())
        }
        _ => warp.encode(encoder, layers, width, height, params),
    }
}
