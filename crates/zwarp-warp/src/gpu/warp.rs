//! GPU backward depth warp (seed 000 Sec. 3.2-3.4, Fig. 3, 5, 6), the WGSL twin of
//! [`crate::warp_depth`]. Shader: `warp.wgsl`.
//!
//! **Which CPU function.** The GPU computes `crate::warp_depth(layers, params)` for every
//! [`WarpParams`] with `record_source: false` (every hole policy, AWOC included), every
//! [`BoundKind`] (Oriented: the per-layer PCA frame is chosen on the CPU by
//! [`WarpKernel::frames`], exactly as `PreparedLayer::prepare_stack` does, and passed in
//! [`GpuWarpLayer::axis`]); everything else is reproduced as on the CPU: N stratified seeds (corners + R2 sequence with the same PCG `seed_key` jitter),
//! T iterations, the convergence threshold, Newton steps (`accelerate`), adaptive or nearest
//! sampling, minimal-depth (or first-converged) candidates,
//! cross-layer seeding and borrowing (Fig. 6), the 4x4-tile then per-pixel bound tightening
//! (Fig. 5, recomputed per pixel from the same tile), the single-seed shortcut for sub-pixel
//! tile bounds, the min-depth mipmap pruning of later layers, and the ground-layer de-duplication
//! of `PreparedLayer::prepare_stack`, `WarpParams::motion_scale` (scaled texel fetches and
//! mipmap look-ups, rejected when non-uniform under an oriented frame),
//! `WarpParams::multisample` = m (source layers of m x m samples per target pixel: target
//! pixel `(x, y)` and the 4x4 target tiles are searched at the source position
//! `m * (x + 0.5, y + 0.5)`, the output is the source size divided by m), and the AWOC fill
//! (Sec. 5.3: nearest sample over all layers at the corners of the first searched layer's tight
//! region). `record_source` returns [`Error::Invalid`]; [`WarpKernel::gpu_params`] turns any CPU
//! configuration into the one the GPU reproduces.
//!
//! Differences are floating-point only (the GPU compiler may fuse multiply-adds), which moves a
//! few converged positions by ulps; the tests require warped-depth SSIM >= 0.999 and equal
//! converged masks on >= 99.5 % of the pixels.
//!
//! Pipeline (all on the GPU, no CPU round trip in [`WarpKernel::encode`]): per layer `prepare`
//! (validated samples), `mip_base` + `mip_up` (min-max motion mipmap with a min-depth channel,
//! same level layout as [`super::PyramidKernel`] and the CPU `MotionPyramid`), then one `warp`
//! dispatch over the target pixels, then `dilate` for `HolePolicy::Dilate`.

use bytemuck::{Pod, Zeroable};
use glam::Vec2;
use rayon::prelude::*;
use wgpu::util::DeviceExt;
use zwarp_core::{Error, Image, Motion, Result};
use zwarp_gpu::kernel::AutoPipelines;
use zwarp_gpu::readback::read_buffer;
use zwarp_gpu::GpuContext;

use super::pyramid_level_sizes;
use crate::bounds::{choose_frame, ImageClip, MotionScales};
use crate::{
    BoundFrame, BoundKind, CandidateChoice, HolePolicy, PixelState, Sampling, SeedStrategy, WarpLayer, WarpOutput,
    WarpParams,
};

/// Largest number of layers L the GPU warp takes in one call.
pub const MAX_GPU_LAYERS: usize = 8;
/// Largest number of mip levels (images up to 65536 pixels per side).
const MAX_LEVELS: usize = 16;

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Params {
    size: [u32; 2],
    layers: u32,
    top: u32,
    layer: u32,
    level: u32,
    n_seeds: u32,
    iterations: u32,
    threshold: f32,
    bound_iterations: u32,
    flags: u32,
    radius: u32,
    seed_offset: [f32; 2],
    expand: f32,
    level_total: u32,
    inf: [f32; 2],
    motion_scale: [f32; 2],
    /// Target image size: `size / multisample` (`WarpParams::multisample`).
    target: [u32; 2],
    /// `WarpParams::multisample` as a float: target pixel `(x, y)` is searched at the source
    /// position `multisample * (x + 0.5, y + 0.5)`.
    multisample: f32,
    /// `WarpParams::cover_radius` squared.
    cover2: f32,
    /// `WarpParams::extra_iterations`, then padding to the arrays' 16-byte alignment.
    extra_iterations: u32,
    pad: [u32; 3],
    levels: [[u32; 4]; MAX_LEVELS],
    axes: [[f32; 4]; MAX_GPU_LAYERS],
    /// `bounds::ImageClip` per layer in its frame: `(lo.x, lo.y, hi.x, hi.y)`.
    clips: [[f32; 4]; MAX_GPU_LAYERS],
}

const FLAG_CROSS: u32 = 1;
const FLAG_ACCEL: u32 = 2;
const FLAG_ADAPTIVE: u32 = 4;
const FLAG_FIRST: u32 = 8;
const FLAG_SEED_PIXEL: u32 = 16;
const FLAG_SEED_OFFSET: u32 = 32;
/// The `dilate` pass applies `FillRule::Background` instead of Fig. 8's nearest-neighbour rule.
const FLAG_BACKGROUND: u32 = 64;
/// `HolePolicy::Awoc`: the warp pass fills non-converged pixels from the region corners.
const FLAG_AWOC: u32 = 128;
/// `WarpParams::ground_layer`: the last layer is the ground peeled alone.
const FLAG_GROUND: u32 = 256;
/// A preparation of the motion as given (`MotionScales::AtLeastOne`): the gradient mipmap holds
/// the fold bound and the one-seed test is monotonicity (`gradient::OneSeedTest::Monotone`);
/// else the squared row norms and the contraction test.
const FLAG_MONOTONE: u32 = 512;

/// One source layer resident on the GPU: `width x height` source depths (`f32`, 1 = empty)
/// and [`Motion`] samples (3 `f32` each: motion x, y, target depth), e.g. as written by
/// [`super::MotionKernel::encode`]. Both buffers need `STORAGE` usage.
#[derive(Clone, Copy, Debug)]
pub struct GpuWarpLayer<'a> {
    /// Source depth buffer.
    pub depth: &'a wgpu::Buffer,
    /// Motion buffer (source -> target, plus target depth).
    pub motion: &'a wgpu::Buffer,
    /// Unit axis of the layer's bound frame (`BoundFrame::axis`): `Vec2::X` for axis-aligned
    /// bounds (always used under `BoundKind::Tight` / `Global`); under `BoundKind::Oriented`
    /// the axis [`WarpKernel::frames`] returns reproduces the CPU exactly.
    pub axis: Vec2,
}

/// Result of [`WarpKernel::encode`], resident on the GPU.
#[derive(Debug)]
pub struct GpuWarpOutput {
    /// Warped depth, `width * height` `f32` (1 = hole under `FarDepth`); `STORAGE | COPY_SRC`.
    /// The size is the target's: the source size divided by `WarpParams::multisample`.
    pub depth: wgpu::Buffer,
    /// Per-pixel [`PixelState`] as `u32` (0 converged, 1 filled, 2 hole, 3 converged on a layer
    /// after the first, listed in [`WarpOutput::revealed`] when read back); `STORAGE | COPY_SRC`.
    pub state: wgpu::Buffer,
    /// Target image width.
    pub width: u32,
    /// Target image height.
    pub height: u32,
}

impl GpuWarpOutput {
    /// Reads depth and state back (submits a copy and waits).
    pub fn read(&self, ctx: &GpuContext) -> Result<WarpOutput> {
        let n = self.width as usize * self.height as usize;
        let depth = read_buffer::<f32>(ctx, &self.depth, n)?;
        let raw = read_buffer::<u32>(ctx, &self.state, n)?;
        let revealed = (0..n as u32).filter(|&i| raw[i as usize] == 3).collect();
        let state = raw
            .into_iter()
            .map(|s| match s {
                0 | 3 => PixelState::Converged,
                1 => PixelState::Filled,
                _ => PixelState::Hole,
            })
            .collect();
        Ok(WarpOutput {
            depth: Image::from_vec(self.width, self.height, depth)?,
            state: Image::from_vec(self.width, self.height, state)?,
            source: None,
            revealed,
        })
    }
}

/// Source layers prepared once on the GPU by [`WarpKernel::encode_prepare`] (validated
/// samples, min-max motion mipmaps and min-depth mipmaps of every layer), warped any number of
/// times by [`WarpKernel::encode_prepared`] with different `WarpParams::motion_scale`.
pub struct GpuPreparedWarp {
    samples: wgpu::Buffer,
    mip: wgpu::Buffer,
    zmin: wgpu::Buffer,
    base: Params,
    holes: HolePolicy,
    layers: usize,
    scales: MotionScales,
}

impl GpuPreparedWarp {
    /// `(width, height)` of the prepared source layers.
    pub fn size(&self) -> (u32, u32) {
        (self.base.size[0], self.base.size[1])
    }

    /// `(width, height)` of every warp from the prepared layers: [`Self::size`] divided by
    /// `WarpParams::multisample` (equal to it for one sample per pixel).
    pub fn target_size(&self) -> (u32, u32) {
        (self.base.target[0], self.base.target[1])
    }
}

/// The GPU depth warp (seed 000 Sec. 3): compiled pipelines, reusable across calls and sizes.
pub struct WarpKernel {
    ctx: GpuContext,
    prepare: wgpu::ComputePipeline,
    mip_base: wgpu::ComputePipeline,
    mip_up: wgpu::ComputePipeline,
    warp: wgpu::ComputePipeline,
    dilate: wgpu::ComputePipeline,
}

impl WarpKernel {
    /// Compiles `warp.wgsl` on `ctx`'s device (an engine's own via [`GpuContext::from_device`]).
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let pipelines = AutoPipelines::new(
            ctx,
            "warp.wgsl",
            concat!(include_str!("fill_rule.wgsl"), include_str!("warp.wgsl")),
            "warp",
        )?;
        let pipe = |entry: &str| pipelines.pipeline(entry);
        Ok(WarpKernel {
            ctx: ctx.clone(),
            prepare: pipe("prepare")?,
            mip_base: pipe("mip_base")?,
            mip_up: pipe("mip_up")?,
            warp: pipe("warp")?,
            dilate: pipe("dilate")?,
        })
    }

    /// The configuration of `params` the GPU reproduces: `record_source` is cleared. Run the
    /// CPU `warp_depth` with the result to get the GPU's function exactly.
    pub fn gpu_params(params: &WarpParams) -> WarpParams {
        WarpParams { record_source: false, ..*params }
    }

    /// Checks that `params` is valid and within what the GPU computes (see the module docs).
    pub fn check_params(params: &WarpParams) -> Result<()> {
        params.validate()?;
        if params.record_source {
            return Err(Error::invalid("GPU warp does not record source positions (record_source must be false)"));
        }
        Ok(())
    }

    /// The target image of a warp from `width x height` source layers with
    /// `WarpParams::multisample` = `m`: [`crate::target_size`], the CPU warp's rule and
    /// error (the source must hold exactly `m x m` samples per target pixel).
    pub fn target_size(width: u32, height: u32, m: u32) -> Result<(u32, u32)> {
        crate::target_size(width, height, m)
    }

    fn uniform(&self, p: &Params) -> wgpu::Buffer {
        self.ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("zwarp warp params"),
            contents: bytemuck::bytes_of(p),
            usage: wgpu::BufferUsages::UNIFORM,
        })
    }

    fn dispatch(
        &self,
        enc: &mut wgpu::CommandEncoder,
        pipe: &wgpu::ComputePipeline,
        bindings: &[(u32, &wgpu::Buffer)],
        groups: (u32, u32),
    ) {
        let entries: Vec<wgpu::BindGroupEntry<'_>> = bindings
            .iter()
            .map(|&(binding, b)| wgpu::BindGroupEntry { binding, resource: b.as_entire_binding() })
            .collect();
        let bind = self.ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("zwarp warp"),
            layout: &pipe.get_bind_group_layout(0),
            entries: &entries,
        });
        let mut pass =
            enc.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("zwarp warp"), timestamp_writes: None });
        pass.set_pipeline(pipe);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups(groups.0.max(1), groups.1.max(1), 1);
    }

    fn storage(&self, bytes: u64, what: &str) -> Result<wgpu::Buffer> {
        self.ctx.check_storage_size(bytes, what)?;
        Ok(self.ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(what),
            size: bytes.max(16),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        }))
    }

    /// Records the warp of GPU-resident `layers` (nearest first, ground last if separate) of
    /// `width x height` source samples into `encoder`; the output (of
    /// [`Self::target_size`]`(width, height, params.multisample)`) stays on the GPU. Errors
    /// ([`Error::Invalid`]) on an empty or too long layer list, zero size, a source size not
    /// divisible by `params.multisample`, buffers too small, unsupported params.
    /// NaN inputs are not checked here (the CPU-input [`Self::warp`] rejects them).
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        layers: &[GpuWarpLayer<'_>],
        width: u32,
        height: u32,
        params: &WarpParams,
    ) -> Result<GpuWarpOutput> {
        let prepared = self.encode_prepare(encoder, layers, width, height, params)?;
        self.encode_prepared(encoder, &prepared, params.motion_scale)
    }

    /// The first half of [`Self::encode`]: records the per-layer `prepare` pass and the
    /// min-max motion mipmaps (Sec. 3.3) for the scales `params.motion_scale` needs
    /// ([`MotionScales::for_scale`], as `crate::warp_depth` prepares). See
    /// [`Self::encode_prepare_for`].
    pub fn encode_prepare(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        layers: &[GpuWarpLayer<'_>],
        width: u32,
        height: u32,
        params: &WarpParams,
    ) -> Result<GpuPreparedWarp> {
        let scales = MotionScales::for_scale(params.motion_scale);
        self.encode_prepare_for(encoder, layers, width, height, params, scales)
    }

    /// [`Self::encode_prepare`] for the motion scales `scales`: the mipmaps serve every
    /// warp whose `WarpParams::motion_scale` they serve ([`Self::encode_prepared`]), e.g. under
    /// [`MotionScales::Any`] the S light-sample views of a soft shadow (seed 000 Sec. 6), each
    /// the reference parallax field scaled by `K_i / K_ref`. Errors as [`Self::encode`].
    pub fn encode_prepare_for(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        layers: &[GpuWarpLayer<'_>],
        width: u32,
        height: u32,
        params: &WarpParams,
        scales: MotionScales,
    ) -> Result<GpuPreparedWarp> {
        Self::check_params(params)?;
        if layers.is_empty() {
            return Err(Error::invalid("warp_depth needs at least one layer"));
        }
        if layers.len() > MAX_GPU_LAYERS {
            return Err(Error::invalid(format!(
                "GPU warp takes at most {MAX_GPU_LAYERS} layers, got {}",
                layers.len()
            )));
        }
        if width == 0 || height == 0 {
            return Err(Error::invalid(format!("warp target is a zero-size image ({width}x{height})")));
        }
        let (tw, th) = Self::target_size(width, height, params.multisample)?;
        let wh = width as u64 * height as u64;
        let mut axes = [[1.0f32, 0.0, 0.0, 0.0]; MAX_GPU_LAYERS];
        let mut clips = [[0.0f32; 4]; MAX_GPU_LAYERS];
        for (k, l) in layers.iter().enumerate() {
            if l.depth.size() < wh * 4 || l.motion.size() < wh * 12 {
                return Err(Error::invalid(format!("layer {k}: GPU buffers are too small for {width}x{height}")));
            }
            if !l.axis.is_finite() || (l.axis.length() - 1.0).abs() > 1e-3 {
                return Err(Error::invalid(format!(
                    "layer {k}: bound frame axis must be a unit vector, got {:?}",
                    l.axis
                )));
            }
            // Global / Tight bounds are axis-aligned on the CPU whatever the caller passes.
            if params.bound == BoundKind::Oriented {
                axes[k] = [l.axis.x, l.axis.y, 0.0, 0.0];
            }
            let frame = BoundFrame { axis: Vec2::new(axes[k][0], axes[k][1]) };
            let clip = ImageClip::new(width, height, frame, scales);
            clips[k] = [clip.lo.x, clip.lo.y, clip.hi.x, clip.hi.y];
        }
        // The CPU's check (crate::warp_prepared): per-axis motion scaling does not commute
        // with a rotated bound frame.
        let sc = params.motion_scale;
        if sc.x != sc.y {
            if let Some(k) = axes.iter().take(layers.len()).position(|a| !(a[0] == 1.0 && a[1] == 0.0)) {
                return Err(Error::invalid(format!(
                    "non-uniform motion_scale {sc} needs axis-aligned bounds, but layer {k} has an oriented frame (use BoundKind::Tight)"
                )));
            }
        }
        let sizes = pyramid_level_sizes(width, height);
        if sizes.len() > MAX_LEVELS {
            return Err(Error::invalid(format!("{width}x{height} is too large for the GPU warp")));
        }
        let mut levels = [[0u32; 4]; MAX_LEVELS];
        let mut total = 0u32;
        for (l, &(lw, lh)) in sizes.iter().enumerate() {
            levels[l] = [total, lw, lh, 0];
            total += lw * lh;
        }
        let nl = layers.len() as u32;
        let (mut flags, mut seed_offset) = (0u32, [0.0f32; 2]);
        if params.cross_layer {
            flags |= FLAG_CROSS;
        }
        if params.accelerate {
            flags |= FLAG_ACCEL;
        }
        if params.sampling == Sampling::Adaptive {
            flags |= FLAG_ADAPTIVE;
        }
        if params.choice == CandidateChoice::FirstConverged {
            flags |= FLAG_FIRST;
        }
        if params.ground_layer {
            flags |= FLAG_GROUND;
        }
        if scales == MotionScales::AtLeastOne {
            flags |= FLAG_MONOTONE;
        }
        match params.seeding {
            SeedStrategy::Stratified => {}
            SeedStrategy::Pixel => flags |= FLAG_SEED_PIXEL,
            SeedStrategy::Offset(d) => {
                flags |= FLAG_SEED_OFFSET;
                seed_offset = d.to_array();
            }
        }
        let radius = match params.holes {
            HolePolicy::Dilate { radius } => radius,
            HolePolicy::Background { radius } => {
                flags |= FLAG_BACKGROUND;
                radius
            }
            HolePolicy::Awoc => {
                flags |= FLAG_AWOC;
                0
            }
            HolePolicy::FarDepth => 0,
        };
        let base = Params {
            size: [width, height],
            layers: nl,
            top: sizes.len() as u32,
            layer: 0,
            level: 0,
            n_seeds: params.n_seeds,
            iterations: params.iterations,
            threshold: params.threshold,
            bound_iterations: if params.bound == BoundKind::Global { 0 } else { params.bound_iterations },
            flags,
            radius,
            seed_offset,
            expand: params.sampling.footprint(),
            level_total: total,
            inf: [f32::INFINITY, f32::NEG_INFINITY],
            motion_scale: params.motion_scale.to_array(),
            target: [tw, th],
            multisample: params.multisample as f32,
            cover2: params.cover_radius * params.cover_radius,
            extra_iterations: params.extra_iterations,
            pad: [0; 3],
            levels,
            axes,
            clips,
        };
        let samples = self.storage(nl as u64 * wh * 16, "zwarp warp samples")?;
        let mip = self.storage(nl as u64 * total as u64 * 16, "zwarp warp mipmap")?;
        let zmin = self.storage(nl as u64 * total as u64 * 16, "zwarp warp min-depth and gradient mipmap")?;
        let groups = (width.div_ceil(8), height.div_ceil(8));
        // Samples of every layer first: the mipmap of layer k reads layers < k (de-duplication).
        for (k, l) in layers.iter().enumerate() {
            let u = self.uniform(&Params { layer: k as u32, ..base });
            self.dispatch(encoder, &self.prepare, &[(0, &u), (1, l.depth), (2, l.motion), (3, &samples)], groups);
        }
        for k in 0..nl {
            let u = self.uniform(&Params { layer: k, ..base });
            let (lw, lh) = sizes[0];
            self.dispatch(
                encoder,
                &self.mip_base,
                &[(0, &u), (3, &samples), (4, &mip), (5, &zmin)],
                (lw.div_ceil(8), lh.div_ceil(8)),
            );
            for (l, &(lw, lh)) in sizes.iter().enumerate().skip(1) {
                let u = self.uniform(&Params { layer: k, level: l as u32 + 1, ..base });
                self.dispatch(
                    encoder,
                    &self.mip_up,
                    &[(0, &u), (4, &mip), (5, &zmin)],
                    (lw.div_ceil(8), lh.div_ceil(8)),
                );
            }
        }
        Ok(GpuPreparedWarp { samples, mip, zmin, base, holes: params.holes, layers: layers.len(), scales })
    }

    /// The second half of [`Self::encode`]: records the warp (and the hole pass) of layers
    /// prepared by [`Self::encode_prepare`] with `WarpParams::motion_scale = motion_scale`
    /// (every other parameter as prepared); the output is exactly [`Self::encode`]'s with those
    /// parameters. The prepared buffers are only read, so any number of warps may follow one
    /// preparation. Errors on a non-finite scale, a non-uniform one with oriented frames, or
    /// one the preparation does not serve ([`MotionScales`]).
    pub fn encode_prepared(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        prepared: &GpuPreparedWarp,
        motion_scale: Vec2,
    ) -> Result<GpuWarpOutput> {
        if !motion_scale.is_finite() {
            return Err(Error::invalid(format!("motion_scale must be finite, got {motion_scale}")));
        }
        if !prepared.scales.serves(motion_scale) {
            return Err(Error::invalid(format!(
                "motion_scale {motion_scale} is below 1, but the layers were prepared for scales >= 1 (prepare with MotionScales::Any)"
            )));
        }
        let base = Params { motion_scale: motion_scale.to_array(), ..prepared.base };
        let sc = motion_scale;
        if sc.x != sc.y {
            if let Some(k) = base.axes.iter().take(prepared.layers).position(|a| !(a[0] == 1.0 && a[1] == 0.0)) {
                return Err(Error::invalid(format!(
                    "non-uniform motion_scale {sc} needs axis-aligned bounds, but layer {k} has an oriented frame (use BoundKind::Tight)"
                )));
            }
        }
        // The warp and its hole pass run over the target pixels.
        let [width, height] = base.target;
        let wh = width as u64 * height as u64;
        let (samples, mip, zmin) = (&prepared.samples, &prepared.mip, &prepared.zmin);
        let out_depth = self.storage(wh * 4, "zwarp warp depth")?;
        let out_state = self.storage(wh * 4, "zwarp warp state")?;
        let groups = (width.div_ceil(8), height.div_ceil(8));
        let u = self.uniform(&base);
        self.dispatch(
            encoder,
            &self.warp,
            &[(0, &u), (3, samples), (4, mip), (5, zmin), (6, &out_depth), (7, &out_state)],
            groups,
        );
        if let HolePolicy::Dilate { .. } | HolePolicy::Background { .. } = prepared.holes {
            let fill_depth = self.storage(wh * 4, "zwarp warp dilated depth")?;
            let fill_state = self.storage(wh * 4, "zwarp warp dilated state")?;
            self.dispatch(
                encoder,
                &self.dilate,
                &[(0, &u), (6, &out_depth), (7, &out_state), (8, &fill_depth), (9, &fill_state)],
                groups,
            );
            return Ok(GpuWarpOutput { depth: fill_depth, state: fill_state, width, height });
        }
        Ok(GpuWarpOutput { depth: out_depth, state: out_state, width, height })
    }

    /// Uploads CPU `layers` (validated exactly like `crate::warp_depth`: at least one
    /// layer, equal non-zero sizes, no NaN/infinite depth, no NaN motion), records the warp,
    /// waits and reads the result back. `WarpOutput::source` is `None`.
    pub fn warp(&self, layers: &[WarpLayer<'_>], params: &WarpParams) -> Result<WarpOutput> {
        let gpu = self.upload(layers, params)?;
        let frames = Self::frames(layers, params.bound, MotionScales::for_scale(params.motion_scale));
        let views: Vec<GpuWarpLayer<'_>> =
            gpu.iter().zip(frames).map(|((d, m), axis)| GpuWarpLayer { depth: d, motion: m, axis }).collect();
        let (w, h) = layers[0].depth.size();
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        let out = self.encode(&mut enc, &views, w, h, params)?;
        self.ctx.queue.submit([enc.finish()]);
        out.read(&self.ctx)
    }

    /// The bound frame axis per layer that `crate::warp_depth` uses (Sec. 3.3): `Vec2::X`
    /// unless `bound` is `Oriented`; then, like `PreparedLayer::prepare_stack_for` with `scales`,
    /// the PCA frame of the layer's valid samples (for layers `k > 0` only the samples that do
    /// not repeat an earlier layer) when its global bound (clipped for `scales`) has a smaller
    /// `(ex + 1)(ey + 1)` than the axis-aligned one. Layers must be valid and of equal size (see [`Self::warp`]). A CPU pass
    /// over the buffers; an engine can reuse the axes of the previous frame.
    pub fn frames(layers: &[WarpLayer<'_>], bound: BoundKind, scales: MotionScales) -> Vec<Vec2> {
        if bound != BoundKind::Oriented {
            return vec![Vec2::X; layers.len()];
        }
        (0..layers.len())
            .map(|k| {
                let l = &layers[k];
                let (w, h) = l.depth.size();
                let earlier: Vec<&[f32]> = layers[..k].iter().map(|e| e.depth.data()).collect();
                let depth = l.depth.data();
                let samples: Vec<Motion> = depth
                    .par_iter()
                    .zip(l.motion.data().par_iter())
                    .enumerate()
                    .map(|(i, (&d, m))| {
                        let valid = d < 1.0 && m.depth >= 0.0 && m.depth < 1.0 && m.v.is_finite();
                        if valid && !earlier.iter().any(|e| e[i] == d) {
                            *m
                        } else {
                            Motion { v: Vec2::ZERO, depth: f32::INFINITY }
                        }
                    })
                    .collect();
                choose_frame(&samples, w, h, bound, scales).axis
            })
            .collect()
    }

    /// Validates and uploads CPU layers into GPU buffers `(depth, motion)` usable as
    /// [`GpuWarpLayer`]s (e.g. to time [`Self::encode`] without the upload).
    pub fn upload(&self, layers: &[WarpLayer<'_>], params: &WarpParams) -> Result<Vec<(wgpu::Buffer, wgpu::Buffer)>> {
        Self::check_params(params)?;
        let first = layers.first().ok_or_else(|| Error::invalid("warp_depth needs at least one layer"))?;
        let (w, h) = first.depth.size();
        for (k, l) in layers.iter().enumerate() {
            l.depth.check_nonempty("layer depth")?;
            l.depth.check_same_size(l.motion, "layer depth vs motion")?;
            if l.depth.size() != (w, h) {
                let (lw, lh) = l.depth.size();
                return Err(Error::invalid(format!("layer {k} is {lw}x{lh} but layer 0 is {w}x{h}")));
            }
            if !l.depth.all_finite() {
                return Err(Error::invalid("layer depth holds NaN or infinite values"));
            }
            if l.motion.data().iter().any(|m| m.v.is_nan() || m.depth.is_nan()) {
                return Err(Error::invalid("motion buffer holds NaN values"));
            }
        }
        if layers.len() > MAX_GPU_LAYERS {
            return Err(Error::invalid(format!(
                "GPU warp takes at most {MAX_GPU_LAYERS} layers, got {}",
                layers.len()
            )));
        }
        upload_layers(&self.ctx, layers)
    }
}

/// Uploads the depth and motion buffers of `layers` as they are (no checks): the
/// [`GpuWarpLayer`] buffers of the CPU-input paths (the warp, the background fill).
pub(super) fn upload_layers(ctx: &GpuContext, layers: &[WarpLayer<'_>]) -> Result<Vec<(wgpu::Buffer, wgpu::Buffer)>> {
    let up = |bytes: &[u8], what: &str| -> Result<wgpu::Buffer> {
        ctx.check_storage_size(bytes.len() as u64, what)?;
        Ok(ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(what),
            contents: bytes,
            usage: wgpu::BufferUsages::STORAGE,
        }))
    };
    layers
        .iter()
        .map(|l| {
            let m: &[Motion] = l.motion.data();
            Ok((
                up(bytemuck::cast_slice(l.depth.data()), "zwarp warp source depth")?,
                up(bytemuck::cast_slice(m), "zwarp warp motion")?,
            ))
        })
        .collect()
}
