//! The GPU WOC pipeline (seed 000 Sec. 5, Fig. 13; thesis seed 002 Sec. III-IV), a library an
//! engine calls with its own device ([`GpuContext::from_device`]), its own previous depth and
//! item textures and its own matrices: everything from the previous frame's buffers to the
//! visible list and indirect draw arguments runs on the GPU in one command encoder, with no
//! read-back in between. Shaders: `woc.wgsl` (+ the motion, warp, max-depth and cull kernels).
//!
//! Stage order mirrors [`crate::woc`] (as committed at 2d9b183 + later, with opening rims):
//! 1. the previous depth + item textures are gathered into buffers;
//! 2. motion buffer ([`zwarp_warp::gpu::MotionKernel`], camera + per-object motion through the items);
//! 3. opening rims in the source ([`crate::opening_rims`], `RimMode::Source`): near-side
//!    rim texels of separating boundaries become far holes before the warp;
//! 4. single-layer warp ([`zwarp_warp::gpu::WarpKernel`], N = 8, far-depth holes or AWOC's fill,
//!    nearest sampling);
//! 5. `erosion_radius` steps of the 3x3 max erosion ([`crate::erode_max`]);
//! 6. forced (rapid-motion) objects, flagged in [`CullObjects::forced`], are rasterized and
//!    merged into the predicted depth by the depth test ([`zwarp_raster::draw_into`]);
//! 7. max-depth structure ([`super::MaxDepthKernel`]) and 8. the cull kernel
//!    ([`super::CullKernel`], with the silhouette test of `WocParams::hull_test`) into the
//!    caller's [`CullOutput`].
//!
//! Differences from the CPU `woc`: opening rims are always dropped in the source
//! (`RimMode::Source`): the CPU default `RimMode::Target` needs each target pixel's source
//! position, which the GPU warp does not record; Source opens a superset of Target's pixels
//! (safe, culls less). The warp's bound frame axis is given (default
//! axis-aligned, i.e. the CPU's `BoundKind::Tight`; the CPU's PCA frame needs a pass over the
//! motion buffer on the CPU), the hybrid object-space query and coarse resolution
//! (`downsample`) and the static hole bounds (`hole_bound`, off by default on the CPU) are not
//! ported, and the rapid-motion flags are computed by
//! the caller ([`rapid_flags`] is the CPU rule).

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec2};
use zwarp_core::{Camera, Error, Image, Motion, Result, Scene};
use zwarp_gpu::kernel::AutoPipelines;
use zwarp_gpu::render::{DepthTarget, ITEM_FORMAT};
use zwarp_gpu::{GpuContext, GpuScene, Renderer};
use zwarp_warp::gpu::{GpuWarpLayer, MotionInput, MotionKernel, WarpKernel};
use zwarp_warp::{BoundKind, HolePolicy, WarpParams};

use super::cull::{CullKernel, CullObjects, CullOutput, CullParams};
use super::maxdepth::{GpuMaxDepth, MaxDepthKernel};
use crate::woc::RimMode;
use crate::{screen_speed, Frustum, MaxDepthKind, WocParams, DEPTH_TOLERANCE};

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Params {
    width: u32,
    height: u32,
    min_separation: f32,
    n_objects: u32,
}

/// Parameters of [`GpuWoc`] (the GPU subset of [`WocParams`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GpuWocParams {
    /// The single-layer warp (must pass [`WarpKernel::check_params`]).
    pub warp: WarpParams,
    /// Bound frame axis of the warp (`Vec2::X`: axis-aligned bounds).
    pub axis: Vec2,
    /// Opening-rim threshold in pixels per frame (`None`: off), as [`WocParams::open_rims`].
    pub open_rims: Option<f32>,
    /// Steps of 3x3 max erosion (0: off), as [`WocParams::erosion_radius`].
    pub erosion_radius: u32,
    /// Max-depth structure of the screen-space test.
    pub max_depth: MaxDepthKind,
    /// Depth tolerance of the occlusion test ([`DEPTH_TOLERANCE`]).
    pub tolerance: f32,
    /// The silhouette test after the rectangle test ([`WocParams::hull_test`]).
    pub hull_test: bool,
    /// AWOC (seed 000 Sec. 5.3, [`WocParams::awoc`]): the warp fills holes from the corners of
    /// the local search region instead of the far depth (approximate, may cull visible objects).
    pub awoc: bool,
}

impl Default for GpuWocParams {
    /// [`WocParams::default`] mapped by [`GpuWocParams::from_cpu`].
    fn default() -> Self {
        Self::from_cpu(&WocParams::default()).expect("the CPU defaults map onto the GPU")
    }
}

impl GpuWocParams {
    /// The GPU configuration computing what `crate::woc` computes with
    /// [`GpuWocParams::cpu_twin`]`(p)`: an oriented warp bound becomes axis-aligned
    /// (`BoundKind::Tight`), target-side opening rims become source-side, `hole_bound` and
    /// `hybrid_objects` are ignored.
    /// Errors on `downsample > 1` (not ported).
    pub fn from_cpu(p: &WocParams) -> Result<Self> {
        p.validate()?;
        if p.downsample != 1 {
            return Err(Error::invalid(format!("the GPU WOC runs at full resolution (downsample {})", p.downsample)));
        }
        let bound = if p.warp.bound == BoundKind::Oriented { BoundKind::Tight } else { p.warp.bound };
        let warp = WarpParams { bound, record_source: false, ..p.warp };
        WarpKernel::check_params(&warp)?;
        Ok(GpuWocParams {
            warp,
            axis: Vec2::X,
            open_rims: p.open_rims,
            erosion_radius: if p.erosion { p.erosion_radius } else { 0 },
            max_depth: p.max_depth,
            tolerance: DEPTH_TOLERANCE,
            hull_test: p.hull_test,
            awoc: p.awoc,
        })
    }

    /// The CPU parameters whose `woc` the GPU computes from [`GpuWocParams::from_cpu`]`(cpu)`
    /// (for cross-checks): the warp bound axis-aligned, opening rims in the source, no static
    /// hole bounds (`hole_bound`), no hybrid query.
    pub fn cpu_twin(cpu: &WocParams) -> WocParams {
        let bound = if cpu.warp.bound == BoundKind::Oriented { BoundKind::Tight } else { cpu.warp.bound };
        WocParams {
            warp: WarpParams { bound, ..cpu.warp },
            rim_mode: RimMode::Source,
            hole_bound: false,
            hybrid_objects: 0,
            ..*cpu
        }
    }
}

/// The rapid-motion rule of `crate::woc` (thesis Sec. IV.1): objects in the current
/// frustum whose AABB corners move more than `params.rapid_motion_px` pixels on screen between
/// the frames (own motion only unless `rapid_includes_camera`). All `false` when the rule is
/// off. Feed the result to [`CullObjects::write_forced`].
pub fn rapid_flags(
    scene: &Scene,
    prev_cam: &Camera,
    prev_t: f32,
    cam: &Camera,
    t: f32,
    params: &WocParams,
) -> Vec<bool> {
    let n = scene.instances.len();
    let Some(thr) = params.rapid_threshold_px(cam.width) else { return vec![false; n] };
    let frustum = Frustum::from_camera(cam);
    let cam_a = if params.rapid_includes_camera { prev_cam } else { cam };
    (0..n as u32)
        .map(|id| {
            frustum.intersects(&scene.instance_aabb_at(id, t)) && screen_speed(scene, id, cam_a, prev_t, cam, t) > thr
        })
        .collect()
}

/// The stages of [`GpuWoc`] in order, for [`GpuWoc::encode_stages`] (per-stage timings).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum WocStage {
    /// Previous depth + items gathered from the textures.
    Gather,
    /// Motion buffer.
    Motion,
    /// Source-side opening rims.
    Rims,
    /// Single-layer warp.
    Warp,
    /// Max erosion.
    Erosion,
    /// Rapid-motion objects drawn and merged.
    Rapid,
    /// Max-depth structure built.
    MaxDepth,
    /// Cull kernel (the whole pipeline).
    Cull,
}

/// The previous frame as an engine has it on the GPU.
#[derive(Clone, Copy, Debug)]
pub struct GpuPrevFrame<'a> {
    /// Its depth (a `Depth32Float` texture view, `[0, 1]`, 1 = empty).
    pub depth: &'a wgpu::TextureView,
    /// Its item ids (an `R32Uint` texture view, `u32::MAX` where empty).
    pub items: &'a wgpu::TextureView,
    /// Its camera (same image size as the current one).
    pub cam: &'a Camera,
    /// Its scene time.
    pub t: f32,
}

/// The GPU WOC pipeline for one image size (see the module docs); buffers are allocated once.
pub struct GpuWoc {
    ctx: GpuContext,
    params: GpuWocParams,
    width: u32,
    height: u32,
    renderer: Renderer,
    motion_k: MotionKernel,
    warp_k: WarpKernel,
    max_k: MaxDepthKernel,
    cull_k: CullKernel,
    gather: wgpu::ComputePipeline,
    rims: wgpu::ComputePipeline,
    erode: wgpu::ComputePipeline,
    forced_draws: wgpu::ComputePipeline,
    merge_min: wgpu::ComputePipeline,
    to_texture: wgpu::ComputePipeline,
    uniform: wgpu::Buffer,
    prev_depth: wgpu::Buffer,
    prev_items: wgpu::Buffer,
    motion: wgpu::Buffer,
    rimmed: wgpu::Buffer,
    /// Predicted depth ping-pong buffers (the result is in `predicted[final_index]`).
    predicted: [wgpu::Buffer; 2],
    map: GpuMaxDepth,
    rapid: DepthTarget,
}

impl GpuWoc {
    /// Compiles the kernels and allocates the buffers of a `width x height` pipeline.
    pub fn new(ctx: &GpuContext, width: u32, height: u32, params: GpuWocParams) -> Result<Self> {
        ctx.check_texture_size(width, height, "WOC")?;
        WarpKernel::check_params(&params.warp)?;
        if !params.axis.is_finite() || (params.axis.length() - 1.0).abs() > 1e-3 {
            return Err(Error::invalid(format!("bound frame axis must be a unit vector, got {}", params.axis)));
        }
        if !(params.tolerance.is_finite() && params.tolerance >= 0.0) {
            return Err(Error::invalid(format!("depth tolerance must be finite and >= 0, got {}", params.tolerance)));
        }
        if let Some(s) = params.open_rims {
            if !(s.is_finite() && s >= 0.0) {
                return Err(Error::invalid(format!("rim separation threshold must be >= 0 pixels, got {s}")));
            }
        }
        let dev = &ctx.device;
        let pipelines = AutoPipelines::new(ctx, "woc.wgsl", include_str!("woc.wgsl"), "WOC")?;
        let pipe = |entry: &str| pipelines.pipeline(entry);
        let n = width as u64 * height as u64;
        ctx.check_storage_size(n * std::mem::size_of::<Motion>() as u64, "WOC motion buffer")?;
        let buf = |label, bytes: u64| {
            dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let max_k = MaxDepthKernel::new(ctx)?;
        let map = max_k.create(params.max_depth, width, height)?;
        Ok(GpuWoc {
            ctx: ctx.clone(),
            params,
            width,
            height,
            renderer: Renderer::new(ctx)?,
            motion_k: MotionKernel::new(ctx)?,
            warp_k: WarpKernel::new(ctx)?,
            max_k,
            cull_k: CullKernel::new(ctx)?,
            gather: pipe("gather")?,
            rims: pipe("rims")?,
            erode: pipe("erode")?,
            forced_draws: pipe("forced_draws")?,
            merge_min: pipe("merge_min")?,
            to_texture: pipe("to_texture")?,
            uniform: dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some("zwarp woc params"),
                size: std::mem::size_of::<Params>() as u64,
                usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            prev_depth: buf("zwarp woc prev depth", n * 4),
            prev_items: buf("zwarp woc prev items", n * 4),
            motion: buf("zwarp woc motion", n * std::mem::size_of::<Motion>() as u64),
            rimmed: buf("zwarp woc rimmed depth", n * 4),
            predicted: [buf("zwarp woc predicted a", n * 4), buf("zwarp woc predicted b", n * 4)],
            map,
            rapid: DepthTarget::new(ctx, width, height)?,
        })
    }

    /// Its parameters.
    pub fn params(&self) -> &GpuWocParams {
        &self.params
    }

    /// The predicted (warped, eroded, rapid-merged) depth of the last [`GpuWoc::encode`]:
    /// `width * height` f32, what the max-depth structure was built on (WOC's occlusion map).
    pub fn predicted(&self) -> &wgpu::Buffer {
        &self.predicted[self.params.erosion_radius as usize % 2]
    }

    /// The max-depth structure of the last [`GpuWoc::encode`].
    pub fn max_depth(&self) -> &GpuMaxDepth {
        &self.map
    }

    fn dispatch(
        &self,
        enc: &mut wgpu::CommandEncoder,
        pipe: &wgpu::ComputePipeline,
        bindings: &[(u32, wgpu::BindingResource<'_>)],
        groups: (u32, u32),
    ) {
        let entries: Vec<wgpu::BindGroupEntry<'_>> = bindings
            .iter()
            .map(|(binding, r)| wgpu::BindGroupEntry { binding: *binding, resource: r.clone() })
            .collect();
        let bind = self.ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("zwarp woc"),
            layout: &pipe.get_bind_group_layout(0),
            entries: &entries,
        });
        let mut pass =
            enc.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("zwarp woc"), timestamp_writes: None });
        pass.set_pipeline(pipe);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups(groups.0.max(1), groups.1.max(1), 1);
    }

    /// Records a copy of a `width x height` f32 depth buffer of this pipeline's size (e.g.
    /// [`GpuWoc::predicted`] or a [`zwarp_warp::gpu::GpuWarpOutput`]'s depth) into `target`, an
    /// `R32Float` texture of the same size with `STORAGE_BINDING` usage that the caller owns
    /// (issue #6: "warp into a texture it owns"). Bit-exact.
    pub fn encode_depth_to_texture(
        &self,
        enc: &mut wgpu::CommandEncoder,
        depth: &wgpu::Buffer,
        target: &wgpu::TextureView,
    ) -> Result<()> {
        let (w, h) = (self.width, self.height);
        let tex = target.texture();
        if (tex.width(), tex.height()) != (w, h)
            || tex.format() != wgpu::TextureFormat::R32Float
            || !tex.usage().contains(wgpu::TextureUsages::STORAGE_BINDING)
        {
            return Err(Error::invalid(format!(
                "depth texture must be {w}x{h} R32Float with STORAGE_BINDING, got {}x{} {:?}",
                tex.width(),
                tex.height(),
                tex.format()
            )));
        }
        if depth.size() < w as u64 * h as u64 * 4 {
            return Err(Error::invalid(format!("depth buffer holds {} bytes, {w}x{h} needs more", depth.size())));
        }
        let params = Params { width: w, height: h, min_separation: 0.0, n_objects: 0 };
        let ubuf = {
            use wgpu::util::DeviceExt;
            self.ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("zwarp depth to texture"),
                contents: bytemuck::bytes_of(&params),
                usage: wgpu::BufferUsages::UNIFORM,
            })
        };
        self.dispatch(
            enc,
            &self.to_texture,
            &[
                (0, ubuf.as_entire_binding()),
                (5, depth.as_entire_binding()),
                (12, wgpu::BindingResource::TextureView(target)),
            ],
            (w.div_ceil(8), h.div_ceil(8)),
        );
        Ok(())
    }

    /// Uploads a CPU buffer (`STORAGE | COPY_SRC`).
    fn upload<T: bytemuck::Pod>(&self, data: &[T]) -> wgpu::Buffer {
        use wgpu::util::DeviceExt;
        self.ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("zwarp woc upload"),
            contents: bytemuck::cast_slice(data),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        })
    }

    fn check_image_size(&self, w: u32, h: u32) -> Result<()> {
        if (w, h) != (self.width, self.height) {
            return Err(Error::invalid(format!(
                "image is {w}x{h} but the WOC pipeline is {}x{}",
                self.width, self.height
            )));
        }
        Ok(())
    }

    /// Runs one pixel stage (`rims` or `erode`) on uploaded buffers and reads the result.
    fn run_stage(&self, pipe: &wgpu::ComputePipeline, inputs: &[(u32, &wgpu::Buffer)], sep: f32) -> Result<Image<f32>> {
        let params = Params { width: self.width, height: self.height, min_separation: sep, n_objects: 0 };
        self.ctx.queue.write_buffer(&self.uniform, 0, bytemuck::bytes_of(&params));
        let mut bindings: Vec<(u32, wgpu::BindingResource<'_>)> = vec![(0, self.uniform.as_entire_binding())];
        bindings.extend(inputs.iter().map(|(b, buf)| (*b, buf.as_entire_binding())));
        bindings.push((8, self.rimmed.as_entire_binding()));
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        self.dispatch(&mut enc, pipe, &bindings, (self.width.div_ceil(8), self.height.div_ceil(8)));
        self.ctx.queue.submit([enc.finish()]);
        let data =
            zwarp_gpu::readback::read_buffer::<f32>(&self.ctx, &self.rimmed, (self.width * self.height) as usize)?;
        Image::from_vec(self.width, self.height, data)
    }

    /// The erosion stage on a CPU image (the twin of [`crate::erode_max`], for tests).
    pub fn erode_image(&self, depth: &Image<f32>) -> Result<Image<f32>> {
        self.check_image_size(depth.width(), depth.height())?;
        let buf = self.upload(depth.data());
        self.run_stage(&self.erode, &[(5, &buf)], 0.0)
    }

    /// The opening-rims stage on CPU images (the twin of [`crate::opening_rims`], for
    /// tests). Errors on sizes that differ from the pipeline's or a bad threshold.
    pub fn opening_rims_image(
        &self,
        depth: &Image<f32>,
        items: &Image<u32>,
        motion: &Image<Motion>,
        min_separation: f32,
    ) -> Result<Image<f32>> {
        self.check_image_size(depth.width(), depth.height())?;
        depth.check_same_size(items, "depth vs item buffer")?;
        depth.check_same_size(motion, "depth vs motion buffer")?;
        if !(min_separation.is_finite() && min_separation >= 0.0) {
            return Err(Error::invalid(format!("rim separation threshold must be >= 0 pixels, got {min_separation}")));
        }
        let (d, i, m) = (self.upload(depth.data()), self.upload(items.data()), self.upload(motion.data()));
        self.run_stage(&self.rims, &[(5, &d), (6, &i), (7, &m)], min_separation)
    }

    /// Records WOC for the frame seen by `cam` at time `t`, predicted from `prev`: the kept
    /// objects' ids and indirect draw arguments land in `out` (see [`CullOutput`]), ready for
    /// [`Renderer::encode_depth_indirect`]. `objects` comes from [`CullObjects::for_scene`]
    /// with this frame's AABBs ([`CullObjects::write_scene_aabbs`]) and the rapid-motion
    /// objects flagged ([`CullObjects::write_forced`]); they are drawn into the prediction with
    /// `scene`. `object_deltas`: [`GpuScene::object_deltas`]`(prev.t, t)` (or the engine's).
    /// Writes uniforms and the scene's per-object matrices (queue writes): submit before
    /// encoding another frame.
    #[allow(clippy::too_many_arguments)]
    pub fn encode(
        &self,
        enc: &mut wgpu::CommandEncoder,
        scene: &GpuScene,
        prev: &GpuPrevFrame<'_>,
        object_deltas: &[Mat4],
        cam: &Camera,
        t: f32,
        objects: &CullObjects,
        out: &CullOutput,
    ) -> Result<()> {
        self.encode_stages(enc, scene, prev, object_deltas, cam, t, objects, out, WocStage::Gather..=WocStage::Cull)
    }

    /// Records only the `stages` of [`GpuWoc::encode`] (for per-stage timings): every stage
    /// reads what the earlier stages left in this pipeline's buffers, so after one full
    /// [`GpuWoc::encode`] any single stage can be re-run and timed on its own (the result is
    /// only that of a full run when every stage runs).
    #[allow(clippy::too_many_arguments)]
    pub fn encode_stages(
        &self,
        enc: &mut wgpu::CommandEncoder,
        scene: &GpuScene,
        prev: &GpuPrevFrame<'_>,
        object_deltas: &[Mat4],
        cam: &Camera,
        t: f32,
        objects: &CullObjects,
        out: &CullOutput,
        stages: std::ops::RangeInclusive<WocStage>,
    ) -> Result<()> {
        let (w, h) = (self.width, self.height);
        for c in [prev.cam, cam] {
            if (c.width, c.height) != (w, h) {
                return Err(Error::invalid(format!(
                    "camera renders {}x{} but the WOC pipeline is {w}x{h}",
                    c.width, c.height
                )));
            }
        }
        if !(prev.t.is_finite() && t.is_finite()) {
            return Err(Error::invalid(format!("scene times must be finite, got {} and {t}", prev.t)));
        }
        for (view, what, format) in [
            (prev.depth, "previous depth", zwarp_gpu::render::DEPTH_FORMAT),
            (prev.items, "previous items", ITEM_FORMAT),
        ] {
            let tex = view.texture();
            if (tex.width(), tex.height()) != (w, h) || tex.format() != format {
                return Err(Error::invalid(format!(
                    "{what} texture is {}x{} {:?}, the pipeline needs {w}x{h} {format:?}",
                    tex.width(),
                    tex.height(),
                    tex.format()
                )));
            }
        }
        if objects.len() != scene.object_count() || out.len() != objects.len() {
            return Err(Error::invalid(format!(
                "scene has {} objects, cull buffers {} and {}",
                scene.object_count(),
                objects.len(),
                out.len()
            )));
        }
        let params = Params {
            width: w,
            height: h,
            min_separation: self.params.open_rims.unwrap_or(0.0),
            n_objects: objects.len() as u32,
        };
        self.ctx.queue.write_buffer(&self.uniform, 0, bytemuck::bytes_of(&params));
        let u = || self.uniform.as_entire_binding();
        let px = (w.div_ceil(8), h.div_ceil(8));
        let run = |stage: WocStage| stages.contains(&stage);
        // 1. Previous depth + items into buffers.
        if run(WocStage::Gather) {
            self.dispatch(
                enc,
                &self.gather,
                &[
                    (0, u()),
                    (1, wgpu::BindingResource::TextureView(prev.depth)),
                    (2, wgpu::BindingResource::TextureView(prev.items)),
                    (3, self.prev_depth.as_entire_binding()),
                    (4, self.prev_items.as_entire_binding()),
                ],
                px,
            );
        }
        // 2. Motion (camera + objects through the item buffer).
        if run(WocStage::Motion) {
            let input = MotionInput { depth: &self.prev_depth, items: Some(&self.prev_items), row_stride: w };
            self.motion_k.encode(enc, &input, prev.cam, cam, object_deltas, &self.motion)?;
        }
        // 3. Opening rims.
        if run(WocStage::Rims) && self.params.open_rims.is_some() {
            self.dispatch(
                enc,
                &self.rims,
                &[
                    (0, u()),
                    (5, self.prev_depth.as_entire_binding()),
                    (6, self.prev_items.as_entire_binding()),
                    (7, self.motion.as_entire_binding()),
                    (8, self.rimmed.as_entire_binding()),
                ],
                px,
            );
        }
        // 4. Single-layer warp with far holes (any other fill would be unsafe for culling) or
        //    AWOC's approximate fill, into the first predicted buffer.
        if run(WocStage::Warp) {
            let src = if self.params.open_rims.is_some() { &self.rimmed } else { &self.prev_depth };
            let holes = if self.params.awoc { HolePolicy::Awoc } else { HolePolicy::FarDepth };
            let wp = WarpParams { holes, ..self.params.warp };
            let layer = GpuWarpLayer { depth: src, motion: &self.motion, axis: self.params.axis };
            let warped = self.warp_k.encode(enc, &[layer], w, h, &wp)?;
            enc.copy_buffer_to_buffer(&warped.depth, 0, &self.predicted[0], 0, w as u64 * h as u64 * 4);
        }
        // 5. Erosion, ping-ponging so that the result ends in `predicted()`.
        if run(WocStage::Erosion) {
            for k in 0..self.params.erosion_radius as usize {
                let (a, b) = (&self.predicted[k % 2], &self.predicted[(k + 1) % 2]);
                self.dispatch(
                    enc,
                    &self.erode,
                    &[(0, u()), (5, a.as_entire_binding()), (8, b.as_entire_binding())],
                    px,
                );
            }
        }
        let predicted = self.predicted();
        // 6. Forced objects drawn into the prediction (after the erosion, as on the CPU).
        if run(WocStage::Rapid) {
            let forced_args = self.ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("zwarp woc forced args"),
                size: objects.len() as u64 * std::mem::size_of::<wgpu::util::DrawIndexedIndirectArgs>() as u64,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::INDIRECT,
                mapped_at_creation: false,
            });
            self.dispatch(
                enc,
                &self.forced_draws,
                &[
                    (0, u()),
                    (9, objects.draws.as_entire_binding()),
                    (10, objects.forced.as_entire_binding()),
                    (11, forced_args.as_entire_binding()),
                ],
                ((objects.len() as u32).div_ceil(64), 1),
            );
            self.renderer.encode_depth_from_args(enc, scene, cam, t, &self.rapid, &forced_args, None)?;
            self.dispatch(
                enc,
                &self.merge_min,
                &[
                    (0, u()),
                    (1, wgpu::BindingResource::TextureView(&self.rapid.view)),
                    (8, predicted.as_entire_binding()),
                ],
                px,
            );
        }
        // 7. Max-depth structure, 8. cull.
        if run(WocStage::MaxDepth) {
            self.max_k.encode(enc, predicted, &self.map)?;
        }
        if !run(WocStage::Cull) {
            return Ok(());
        }
        let cp = CullParams { tolerance: self.params.tolerance, hull_test: self.params.hull_test };
        self.cull_k.encode(enc, objects, &cam.view_proj(), w, h, &cp, &self.map, out)
    }
}
