//! Soft shadows on the GPU (seed 000, Sec. 6, Table 8, Fig. 15): the reference (one rendered
//! shadow map per light sample) and zwarp (L layers peeled once from the emitter centre, warped
//! to every sample view) with the visibility accumulated on the GPU. Shader: `shadows.wgsl`.
//!
//! The CPU method is this crate's `run_shadows`; this module reuses its receivers
//! ([`Receivers`], built on the CPU once per camera frame and uploaded once), its light rig
//! ([`LightRig`]: sample cameras and pixel shifts `K_i`), its peeling options
//! (`crate::peel_options`) and its warp parameters (`ShadowParams::warp_params`), and
//! reproduces on the GPU:
//!
//! - **accumulate** (`Receivers::accumulate`): one thread per receiver (it owns its lit
//!   counter, so no atomics), `p_i = p_c + K_i g`, truncation inside `[0, mw) x [0, mh)`, lit iff
//!   the texel's depth `>= threshold` or the point falls off the map;
//! - **parallax** (`LightRig::parallax_field`): the motion of each peeled layer to the reference
//!   emitter offset `o_ref = (e, e)` once, `v = K_ref g(z)`, plus the layer's coverage (the CPU
//!   drops empty layers; so does the GPU path after reading back L counters);
//! - the layers prepared once ([`WarpKernel::encode_prepare`]: samples and min-max mipmaps of
//!   the reference field), then per sample `i` [`WarpKernel::encode_prepared`] with the
//!   shared-mipmap parameters of `ZwarpMaps::sample_params` (axis-aligned tight bounds,
//!   `motion_scale = K_i / K_ref`, the dilation hole policy), then accumulate on the warped map. Holes left after the dilation are
//!   far depth, i.e. lit — as in the CPU's lazy path (`sparse_warp`: far-depth holes, then the
//!   dilation) and full-map path (`warp_prepared` with the same policy).
//!
//! Only the final lit counts are read back; visibility = lit / S.
//!
//! Differences to the CPU are floating point only: the GPU rasterizer matches the CPU on at
//! least 99.9 % of texels (shared edges), and GPU compilers may fuse `p_c + K_i g` into a
//! multiply-add, which moves a look-up across a texel border only when the position is within
//! one ulp of it. The tests bound the resulting lit-count differences (>= 99.5 % identical; on
//! the test scene all are).

use std::time::Instant;

use bytemuck::{Pod, Zeroable};
use glam::Vec2;
use wgpu::util::DeviceExt;
use zwarp_core::{AreaLight, Camera, Error, Image, Motion, Projection, Result, Scene};
use zwarp_gpu::kernel::AutoPipelines;
use zwarp_gpu::readback::read_buffer;
use zwarp_gpu::render::{DepthTarget, FrameOptions, GpuScene, LayerTargets, PeelOptions, Renderer, Umbra};
use zwarp_gpu::GpuContext;
use zwarp_raster::{Frame, ViewRegion};
use zwarp_warp::gpu::{GpuWarpLayer, WarpKernel, MAX_GPU_LAYERS};
use zwarp_warp::{BoundKind, MotionScales, WarpParams};

use crate::{peel_options, EvalConfig, EvalRow, LightRig, Method, Receivers, ShadowParams, ShadowResult, StageTimings};

/// Receivers per workgroup of the accumulate kernel.
const ACC_GROUP: u32 = 256;
/// Largest workgroup count per dispatch dimension (the WebGPU default limit).
const MAX_GROUPS: u32 = 65535;

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct AccParams {
    map_size: [u32; 2],
    count: u32,
    row: u32,
    shift: [f32; 2],
    _pad: [f32; 2],
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct ParParams {
    size: [u32; 2],
    directional: u32,
    layer: u32,
    k_ref: [f32; 2],
    fxn: f32,
    fmn: f32,
    far: f32,
    near: f32,
    pivot: f32,
    _pad: f32,
}

/// The receivers of one camera frame resident on the GPU (seed 000, Sec. 6: the camera pixels
/// whose visibility is estimated): per receiver `(p_c.x, p_c.y, g, threshold)` in
/// `Receivers::list` order, uploaded once and read by every sample's accumulate pass.
pub struct GpuReceivers {
    /// `count` x `vec4<f32>`: centre-map position, shift parameter `g`, stored-depth threshold.
    pub buffer: wgpu::Buffer,
    /// Number of receivers.
    pub count: u32,
}

/// The peeled centre map on the GPU (seed 000, Sec. 6: "a few depth layers rendered from the
/// light's centre"): the non-empty layers' depths and their motion to the reference offset.
pub struct GpuShadowLayers {
    /// Per kept layer: (depth `f32`, motion to the reference offset as [`Motion`]), both
    /// `STORAGE` buffers of the map size.
    pub layers: Vec<(wgpu::Buffer, wgpu::Buffer)>,
    /// Covered texels per peeled layer (before dropping the empty ones).
    pub coverage: Vec<u32>,
    /// Pixel shift of the reference offset, `K_ref` (no zero component).
    pub k_ref: Vec2,
    /// Map size (square maps: `sm x sm`).
    pub size: (u32, u32),
    /// The last kept layer is the separately peeled ground behind kept object layers
    /// (`WarpParams::ground_layer`, as the CPU's `ZwarpMaps`).
    pub ground_layer: bool,
}

/// The GPU soft-shadow pipeline (seed 000, Sec. 6) on one device: a depth renderer, the warp
/// kernel and the accumulate / parallax kernels, compiled once and reused for any scene, light
/// and map size. An engine passes its own device through [`GpuContext::from_device`].
pub struct GpuShadows {
    ctx: GpuContext,
    renderer: Renderer,
    warp: WarpKernel,
    accumulate: wgpu::ComputePipeline,
    parallax: wgpu::ComputePipeline,
}

/// The GPU peeling options equal to the CPU's `zwarp_raster::PeelOptions` (same layers, ground
/// layer and umbra region; no colour).
pub fn gpu_peel_options(p: &zwarp_raster::PeelOptions) -> Result<PeelOptions> {
    let layers = u32::try_from(p.layers).map_err(|_| Error::invalid(format!("L = {} layers is too many", p.layers)))?;
    Ok(PeelOptions {
        layers,
        ground_separate: p.ground_separate,
        umbra: p.umbra.map(|u| match u.region {
            ViewRegion::Disc { e, c } => Umbra::Disc { e, c },
            ViewRegion::Directions { max_angle } => Umbra::Directions { max_angle },
        }),
        frame: FrameOptions::default(),
    })
}

/// The reference emitter offset of the shared mipmap and its pixel shift `(o_ref, K_ref)`:
/// `(e, e)` with `e` the emitter's half diagonal, 1 for a point emitter (`ZwarpMaps::new`).
pub fn reference_shift(rig: &LightRig) -> Vec2 {
    let m = rig.max_offset();
    rig.offset_camera(Vec2::splat(if m > 0.0 { m } else { 1.0 })).1
}

/// Per-sample warp parameters of the shared-mipmap zwarp path (`ZwarpMaps::sample_params`):
/// `params.warp_params()` with axis-aligned tight bounds and `motion_scale = K_i / K_ref`.
pub fn sample_warp_params(params: &ShadowParams, shift: Vec2, k_ref: Vec2) -> WarpParams {
    WarpParams { bound: BoundKind::Tight, motion_scale: shift / k_ref, ..params.warp_params() }
}

fn ms_since(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

impl GpuShadows {
    /// Compiles the renderer, the warp kernel and `shadows.wgsl` on `ctx`'s device.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let pipelines = AutoPipelines::new(ctx, "shadows.wgsl", include_str!("shadows.wgsl"), "shadow")?;
        let pipe = |entry: &str| pipelines.pipeline(entry);
        Ok(GpuShadows {
            ctx: ctx.clone(),
            renderer: Renderer::new(ctx)?,
            warp: WarpKernel::new(ctx)?,
            accumulate: pipe("accumulate")?,
            parallax: pipe("parallax")?,
        })
    }

    /// The context this pipeline runs on.
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    /// The depth renderer (e.g. for the camera frame).
    pub fn renderer(&self) -> &Renderer {
        &self.renderer
    }

    fn storage(&self, bytes: u64, what: &str) -> Result<wgpu::Buffer> {
        self.ctx.check_storage_size(bytes, what)?;
        Ok(self.ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(what),
            size: bytes.max(16),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        }))
    }

    fn bind(&self, pipe: &wgpu::ComputePipeline, bindings: &[(u32, &wgpu::Buffer)]) -> wgpu::BindGroup {
        let entries: Vec<wgpu::BindGroupEntry<'_>> = bindings
            .iter()
            .map(|&(binding, b)| wgpu::BindGroupEntry { binding, resource: b.as_entire_binding() })
            .collect();
        self.ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("zwarp shadows"),
            layout: &pipe.get_bind_group_layout(0),
            entries: &entries,
        })
    }

    fn uniform<T: Pod>(&self, v: &T) -> wgpu::Buffer {
        self.ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("zwarp shadows params"),
            contents: bytemuck::bytes_of(v),
            usage: wgpu::BufferUsages::UNIFORM,
        })
    }

    /// Uploads the receivers of a camera frame (built on the CPU by `Receivers::build`, the one
    /// receiver construction of every method). Errors if the buffer exceeds the device limits.
    pub fn upload_receivers(&self, recv: &Receivers) -> Result<GpuReceivers> {
        let count = u32::try_from(recv.list.len())
            .map_err(|_| Error::invalid(format!("{} receivers is too many", recv.list.len())))?;
        let data: Vec<[f32; 4]> = recv.list.iter().map(|r| [r.p_c.x, r.p_c.y, r.g, r.threshold]).collect();
        let bytes: &[u8] = bytemuck::cast_slice(&data);
        self.ctx.check_storage_size(bytes.len() as u64, "shadow receivers")?;
        // Never bind a zero-size buffer: pad an empty list to one (unused) receiver.
        let pad = [[0.0f32; 4]];
        let contents = if data.is_empty() { bytemuck::cast_slice(&pad) } else { bytes };
        let buffer = self.ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("zwarp shadow receivers"),
            contents,
            usage: wgpu::BufferUsages::STORAGE,
        });
        Ok(GpuReceivers { buffer, count })
    }

    /// A zeroed lit-count buffer for `recv` (`count` `u32`; `STORAGE | COPY_SRC | COPY_DST`).
    pub fn lit_buffer(&self, recv: &GpuReceivers) -> Result<wgpu::Buffer> {
        // wgpu zero-initializes new buffers.
        self.storage(recv.count as u64 * 4, "zwarp shadow lit counts")
    }

    /// Records the accumulate pass of one sample map (`Receivers::accumulate` on the GPU):
    /// `lit[k] += 1` for every receiver `k` whose texel `floor(p_c + shift g)` of the
    /// `map_size` map `map` (row-major `f32`, `STORAGE`) holds a depth `>= threshold`, or that
    /// falls off the map. Errors on buffers too small for the map or the receivers.
    pub fn encode_accumulate(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        recv: &GpuReceivers,
        map: &wgpu::Buffer,
        map_size: (u32, u32),
        shift: Vec2,
        lit: &wgpu::Buffer,
    ) -> Result<()> {
        let (mw, mh) = map_size;
        if mw == 0 || mh == 0 {
            return Err(Error::invalid(format!("shadow map is a zero-size image ({mw}x{mh})")));
        }
        if map.size() < mw as u64 * mh as u64 * 4 {
            return Err(Error::invalid(format!("shadow-map buffer is too small for {mw}x{mh}")));
        }
        if lit.size() < recv.count as u64 * 4 {
            return Err(Error::invalid(format!("lit buffer is too small for {} receivers", recv.count)));
        }
        if !shift.is_finite() {
            return Err(Error::invalid(format!("sample shift must be finite, got {shift}")));
        }
        if recv.count == 0 {
            return Ok(());
        }
        let groups = recv.count.div_ceil(ACC_GROUP);
        let gx = groups.min(MAX_GROUPS);
        let gy = groups.div_ceil(gx);
        let u = self.uniform(&AccParams {
            map_size: [mw, mh],
            count: recv.count,
            row: gx * ACC_GROUP,
            shift: shift.to_array(),
            _pad: [0.0; 2],
        });
        let bind = self.bind(&self.accumulate, &[(0, &u), (1, &recv.buffer), (2, map), (3, lit)]);
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("zwarp accumulate"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.accumulate);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups(gx, gy, 1);
        Ok(())
    }

    /// [`Self::encode_accumulate`] with CPU inputs: uploads `map` and `lit`, runs the kernel and
    /// reads `lit` back (the GPU twin of `Receivers::accumulate`, for tests).
    pub fn accumulate(&self, recv: &Receivers, map: &Image<f32>, shift: Vec2, lit: &mut [u32]) -> Result<()> {
        if lit.len() != recv.list.len() {
            return Err(Error::invalid(format!("{} lit counts for {} receivers", lit.len(), recv.list.len())));
        }
        map.check_nonempty("shadow map")?;
        let gr = self.upload_receivers(recv)?;
        let dev = &self.ctx.device;
        let map_buf = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("zwarp shadow map"),
            contents: bytemuck::cast_slice(map.data()),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let lit_buf = self.lit_buffer(&gr)?;
        self.ctx.queue.write_buffer(&lit_buf, 0, bytemuck::cast_slice(lit));
        let mut enc = dev.create_command_encoder(&Default::default());
        self.encode_accumulate(&mut enc, &gr, &map_buf, map.size(), shift, &lit_buf)?;
        self.ctx.queue.submit([enc.finish()]);
        let out = read_buffer::<u32>(&self.ctx, &lit_buf, lit.len())?;
        lit.copy_from_slice(&out);
        Ok(())
    }

    /// Records the parallax kernel (`LightRig::parallax_field` on the GPU) for a layer: from
    /// the `f32` depth buffer `depth` of the rig's centre-map size into `motion` (one
    /// [`Motion`] per texel) with shift `k`, adding the layer's covered texels to
    /// `coverage[layer]` (a `u32` counter buffer).
    #[allow(clippy::too_many_arguments)]
    pub fn encode_parallax(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        rig: &LightRig,
        depth: &wgpu::Buffer,
        k: Vec2,
        motion: &wgpu::Buffer,
        coverage: &wgpu::Buffer,
        layer: u32,
    ) -> Result<()> {
        let c = &rig.center;
        let (w, h) = (c.width, c.height);
        let wh = w as u64 * h as u64;
        if depth.size() < wh * 4 || motion.size() < wh * 12 || coverage.size() < (layer as u64 + 1) * 4 {
            return Err(Error::invalid(format!("parallax: buffers too small for a {w}x{h} layer {layer}")));
        }
        if !k.is_finite() {
            return Err(Error::invalid(format!("parallax shift must be finite, got {k}")));
        }
        let directional = matches!(c.projection, Projection::Orthographic { .. });
        // The same f32 products the CPU's Camera::linear_depth forms.
        let (n, f) = (c.near, c.far);
        let u = self.uniform(&ParParams {
            size: [w, h],
            directional: directional as u32,
            layer,
            k_ref: k.to_array(),
            fxn: f * n,
            fmn: f - n,
            far: f,
            near: n,
            pivot: rig.pivot,
            _pad: 0.0,
        });
        let bind = self.bind(&self.parallax, &[(4, &u), (5, depth), (6, motion), (7, coverage)]);
        let mut pass = encoder
            .begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("zwarp parallax"), timestamp_writes: None });
        pass.set_pipeline(&self.parallax);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups(w.div_ceil(8), h.div_ceil(8), 1);
        Ok(())
    }

    /// [`Self::encode_parallax`] with a CPU depth image (for tests): the motion field and the
    /// coverage. Errors as `LightRig::parallax_field` (size mismatch, NaN depths).
    pub fn parallax_field(&self, rig: &LightRig, depth: &Image<f32>, k: Vec2) -> Result<(Image<Motion>, u32)> {
        // The CPU's checks (size, NaN, finite shift) with its messages.
        rig.parallax_field(&Image::new(depth.width(), depth.height(), 1.0), k)?;
        if depth.data().iter().any(|d| d.is_nan()) {
            return Err(Error::invalid("layer depth holds NaN values"));
        }
        let dev = &self.ctx.device;
        let d = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("zwarp parallax depth"),
            contents: bytemuck::cast_slice(depth.data()),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let n = depth.len() as u64;
        let m = self.storage(n * 12, "zwarp parallax motion")?;
        let cov = self.storage(4, "zwarp layer coverage")?;
        let mut enc = dev.create_command_encoder(&Default::default());
        self.encode_parallax(&mut enc, rig, &d, k, &m, &cov, 0)?;
        self.ctx.queue.submit([enc.finish()]);
        let motion = read_buffer::<Motion>(&self.ctx, &m, depth.len())?;
        let coverage = read_buffer::<u32>(&self.ctx, &cov, 1)?[0];
        Ok((Image::from_vec(depth.width(), depth.height(), motion)?, coverage))
    }

    /// The reference (seed 000, Table 8 "Ref."): per sample `i`, renders the sample shadow map
    /// with `rig.cameras[i]` (depth only) and accumulates it; returns the lit count per receiver
    /// (one read-back at the end).
    pub fn reference_lit(&self, scene: &GpuScene, rig: &LightRig, t: f32, recv: &GpuReceivers) -> Result<Vec<u32>> {
        let (w, h) = (rig.center.width, rig.center.height);
        let target = DepthTarget::new(&self.ctx, w, h)?;
        let map = self.storage(w as u64 * h as u64 * 4, "zwarp sample shadow map")?;
        let lit = self.lit_buffer(recv)?;
        for (cam, &shift) in rig.cameras.iter().zip(&rig.shifts) {
            // encode_depth writes the object matrices with a queue write, so one submission per
            // sample keeps each render with its own camera (the queue still runs them back to back).
            let mut enc = self.ctx.device.create_command_encoder(&Default::default());
            self.renderer.encode_depth(&mut enc, scene, cam, t, &target)?;
            self.renderer.encode_depth_copy(&mut enc, &target, &map, w)?;
            self.encode_accumulate(&mut enc, recv, &map, (w, h), shift, &lit)?;
            self.ctx.queue.submit([enc.finish()]);
        }
        read_buffer::<u32>(&self.ctx, &lit, recv.count as usize)
    }

    /// Peels the centre map of `rig` with `peel` (use [`gpu_peel_options`] of
    /// `crate::peel_options`), computes each layer's motion to the reference offset
    /// ([`reference_shift`]) and drops the empty layers (reading back only their coverage). A
    /// scene with nothing in front of the light keeps one empty layer, as on the CPU.
    pub fn peel(&self, scene: &GpuScene, rig: &LightRig, t: f32, peel: &PeelOptions) -> Result<GpuShadowLayers> {
        let (w, h) = (rig.center.width, rig.center.height);
        let total = peel.layers as usize + peel.ground_separate as usize;
        let targets = LayerTargets::new(&self.renderer, w, h, total, false)?;
        let k_ref = reference_shift(rig);
        let wh = w as u64 * h as u64;
        let coverage = self.storage(total as u64 * 4, "zwarp layer coverage")?;
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        self.renderer.encode_layers(&mut enc, scene, &rig.center, t, peel, &targets)?;
        let mut layers = Vec::with_capacity(total);
        for k in 0..total {
            let depth = self.storage(wh * 4, "zwarp peeled depth")?;
            let motion = self.storage(wh * 12, "zwarp parallax motion")?;
            self.renderer.encode_depth_copy(&mut enc, &targets.depth[k], &depth, w)?;
            self.encode_parallax(&mut enc, rig, &depth, k_ref, &motion, &coverage, k as u32)?;
            layers.push((depth, motion));
        }
        self.ctx.queue.submit([enc.finish()]);
        let counts = read_buffer::<u32>(&self.ctx, &coverage, total)?;
        let mut kept: Vec<(wgpu::Buffer, wgpu::Buffer)> =
            layers.into_iter().zip(&counts).filter(|(_, &c)| c > 0).map(|(l, _)| l).collect();
        if kept.is_empty() {
            // All layers are empty (depth 1, zero motion): keep one so the warps still give maps.
            kept.push((self.storage(wh * 4, "zwarp empty layer")?, self.storage(wh * 12, "zwarp empty motion")?));
            let (d, m) = &kept[0];
            self.ctx.queue.write_buffer(d, 0, bytemuck::cast_slice(&vec![1.0f32; wh as usize]));
            let empty = Motion { v: Vec2::ZERO, depth: 1.0 };
            self.ctx.queue.write_buffer(m, 0, bytemuck::cast_slice(&vec![empty; wh as usize]));
        }
        if kept.len() > MAX_GPU_LAYERS {
            return Err(Error::invalid(format!(
                "the GPU warp takes at most {MAX_GPU_LAYERS} layers, the light view has {}",
                kept.len()
            )));
        }
        let ground_layer =
            crate::ground_layer_kept(peel.ground_separate, counts.last().is_some_and(|&c| c > 0), kept.len());
        Ok(GpuShadowLayers { layers: kept, coverage: counts, k_ref, size: (w, h), ground_layer })
    }

    /// zwarp (seed 000, Sec. 6): per sample `i`, the full-map GPU warp of the peeled `layers`
    /// with [`sample_warp_params`] (one prepared reference field, `motion_scale = K_i / K_ref`)
    /// and the accumulate pass on the warped map; returns the lit count per receiver (one
    /// read-back at the end).
    pub fn zwarp_lit(
        &self,
        layers: &GpuShadowLayers,
        rig: &LightRig,
        params: &ShadowParams,
        recv: &GpuReceivers,
    ) -> Result<Vec<u32>> {
        params.validate()?;
        let (w, h) = layers.size;
        if (rig.center.width, rig.center.height) != (w, h) {
            return Err(Error::invalid(format!(
                "layers are {w}x{h} but the rig's maps are {}x{}",
                rig.center.width, rig.center.height
            )));
        }
        let views: Vec<GpuWarpLayer<'_>> =
            layers.layers.iter().map(|(d, m)| GpuWarpLayer { depth: d, motion: m, axis: Vec2::X }).collect();
        let lit = self.lit_buffer(recv)?;
        // One preparation (samples + min-max mipmaps of the reference field) for all samples:
        // only WarpParams::motion_scale differs between them.
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        let prepared = self.warp.encode_prepare_for(
            &mut enc,
            &views,
            w,
            h,
            &WarpParams { ground_layer: layers.ground_layer, ..sample_warp_params(params, layers.k_ref, layers.k_ref) },
            MotionScales::Any,
        )?;
        self.ctx.queue.submit([enc.finish()]);
        for &shift in &rig.shifts {
            // Only the motion scale differs from the prepared parameters.
            let wp = sample_warp_params(params, shift, layers.k_ref);
            let mut enc = self.ctx.device.create_command_encoder(&Default::default());
            let out = self.warp.encode_prepared(&mut enc, &prepared, wp.motion_scale)?;
            self.encode_accumulate(&mut enc, recv, &out.depth, (w, h), shift, &lit)?;
            // One submission per sample: the warp's output buffers are freed as each finishes.
            self.ctx.queue.submit([enc.finish()]);
        }
        read_buffer::<u32>(&self.ctx, &lit, recv.count as usize)
    }
}

/// `crate::run_shadows` on the GPU (seed 000, Sec. 6): the camera frame is rendered on
/// the GPU (depth + items), the receivers are built on the CPU exactly as the CPU path does
/// (`Receivers::build`) and uploaded once; the visibility comes from
/// [`GpuShadows::reference_lit`] ([`Method::Reference`]) or [`GpuShadows::peel`] +
/// [`GpuShadows::zwarp_lit`] ([`Method::Zwarp`] and [`Method::ZwarpFull`]: the GPU always warps
/// full maps); shading on the CPU (`Receivers::shade`). `scene` and `gpu_scene` must be the same
/// scene (`GpuScene::upload`).
///
/// Timings (wall clock, each stage waits for the GPU): `camera` = frame + receivers + upload,
/// `render` = the S rendered maps with their accumulation (reference) or the peel + parallax
/// motion (zwarp), `warp` = the S warps with their accumulation (zwarp), `shade`.
/// Errors: invalid parameters or light, [`Method::Pcss`] (no GPU path), device errors.
#[allow(clippy::too_many_arguments)]
pub fn run_shadows_gpu(
    gpu: &GpuShadows,
    scene: &Scene,
    gpu_scene: &GpuScene,
    cam: &Camera,
    t: f32,
    light: &AreaLight,
    method: Method,
    params: &ShadowParams,
) -> Result<ShadowResult> {
    params.validate()?;
    if method == Method::Pcss {
        return Err(Error::invalid("PCSS has no GPU path (use --backend cpu)"));
    }
    if !t.is_finite() {
        return Err(Error::invalid(format!("frame time must be finite, got {t}")));
    }
    let start = Instant::now();
    let mut tm = StageTimings::default();

    let t0 = Instant::now();
    let rig = LightRig::new(scene, t, light, params.samples, params.sm_size, params.seed, params.jitter)?;
    let gf = gpu.renderer.render_frame(gpu_scene, cam, t, &FrameOptions::default())?;
    let frame = Frame { depth: gf.depth, items: gf.items, color: None };
    let recv = Receivers::build(&frame, cam, scene, &rig, &params.bias)?;
    let grecv = gpu.upload_receivers(&recv)?;
    tm.camera = ms_since(t0);

    let t1 = Instant::now();
    let lit = match method {
        Method::Reference => {
            let lit = gpu.reference_lit(gpu_scene, &rig, t, &grecv)?;
            tm.render = ms_since(t1);
            lit
        }
        _ => {
            let peel = gpu_peel_options(&peel_options(scene, &rig, params))?;
            let layers = gpu.peel(gpu_scene, &rig, t, &peel)?;
            tm.render = ms_since(t1);
            let t2 = Instant::now();
            let lit = gpu.zwarp_lit(&layers, &rig, params, &grecv)?;
            tm.warp = ms_since(t2);
            lit
        }
    };
    let visibility = recv.visibility_image(&lit, rig.samples() as u32);
    let t3 = Instant::now();
    let image = recv.shade(&visibility, params.ambient)?;
    tm.shade = ms_since(t3);
    // Every texel of every sample map is warped (the hole count would need a state read-back).
    let warped_texels = if method == Method::Reference {
        0
    } else {
        rig.samples() * (rig.center.width as usize * rig.center.height as usize)
    };
    Ok(ShadowResult { image, visibility, ms: ms_since(start), timings: tm, warp_holes: 0, warped_texels })
}

/// [`crate::evaluate`] on the GPU (seed 000, Table 8 / Fig. 15 protocol,
/// [`crate::evaluate_with`]): the GPU reference and the GPU zwarp ([`run_shadows_gpu`]) on the
/// same device. [`Method::Pcss`] has no GPU path and is skipped (the caller says so);
/// [`Method::ZwarpFull`] runs the same full-map GPU warps as [`Method::Zwarp`].
#[allow(clippy::too_many_arguments)]
pub fn evaluate_gpu(
    gpu: &GpuShadows,
    scene: &Scene,
    gpu_scene: &GpuScene,
    cam: &Camera,
    t: f32,
    light: &AreaLight,
    cfg: &EvalConfig,
    on_result: impl FnMut(&EvalRow, &ShadowResult, &ShadowResult) -> Result<()>,
) -> Result<Vec<EvalRow>> {
    crate::evaluate_with(
        cfg,
        |m, p| run_shadows_gpu(gpu, scene, gpu_scene, cam, t, light, m, p),
        |m| m != Method::Pcss,
        on_result,
    )
}
