//! AABB occlusion culling on the GPU (seed 000 Sec. 5.2; thesis seed 002 Sec. III.2, IV.3):
//! VFC + screen-space max-depth test of every object in one dispatch, writing a compacted
//! visible-id list (atomic counter) and indirect draw arguments, so that the visible set is
//! drawn with `multi_draw_indexed_indirect(_count)` without a CPU round trip
//! ([`zwarp_gpu::Renderer::encode_depth_indirect`]). The WGSL twin of the classification in
//! [`crate::cull_against_depth`]. Shader: `cull.wgsl` (+ `maxquery.wgsl`).

use bytemuck::{Pod, Zeroable};
use glam::Mat4;
use rayon::prelude::*;
use wgpu::util::DeviceExt;
use zwarp_core::{Aabb, Camera, Error, Result, Scene};
use zwarp_gpu::readback::read_buffer;
use zwarp_gpu::{GpuContext, GpuScene, IndirectDraws, IndirectMode};

use super::maxdepth::GpuMaxDepth;
use crate::Frustum;

/// Uniform of the cull kernel (layout of `Params` in `cull.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Params {
    view_proj: [[f32; 4]; 4],
    planes: [[f32; 4]; 6],
    size_tol: [f32; 4],
    counts: [u32; 4],
}

/// Options of the cull kernel's occlusion test.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CullParams {
    /// An object is occluded when the max depth over its rectangle is below its nearest corner
    /// depth minus this ([`crate::DEPTH_TOLERANCE`] in the CPU pipeline).
    pub tolerance: f32,
    /// WOC's silhouette test (`crate::WocParams::hull_test`, full resolution): an object
    /// the rectangle test keeps (rectangle up to `crate::woc::HULL_TEST_MAX_AREA` pixels)
    /// is culled when no pixel centre of its rectangle whose depth (level 0 of the max
    /// structure) is not nearer than its nearest corner lies in the convex hull of its 8
    /// projected corners.
    pub hull_test: bool,
}

impl Default for CullParams {
    /// The tolerance of the CPU pipeline, no silhouette test (as `cull_against_depth`).
    fn default() -> Self {
        CullParams { tolerance: crate::DEPTH_TOLERANCE, hull_test: false }
    }
}

/// Slack of the silhouette test's pixel squares at full resolution: -0.49 shrinks the square
/// to 0.02 px around the centre, the renderer's coverage rule (as `refine_by_hull`).
const HULL_CENTRE_SLACK: f32 = -0.49;

/// How the cull kernel classified an object (as `crate::woc`'s stages count them).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum GpuCullClass {
    /// Outside the view frustum, or its box projects outside the image / beyond the far plane.
    Frustum,
    /// Kept untested (forced visible, e.g. a rapid-motion object drawn into the map).
    Forced,
    /// Its box crosses the near plane (or is unbounded): kept.
    CrossesNear,
    /// Hidden: the max depth over its rectangle is nearer than its nearest corner.
    Occluded,
    /// Passed the screen-space test: kept.
    Visible,
}

impl GpuCullClass {
    fn from_u32(v: u32) -> Result<Self> {
        Ok(match v {
            0 => GpuCullClass::Frustum,
            1 => GpuCullClass::Forced,
            2 => GpuCullClass::CrossesNear,
            3 => GpuCullClass::Occluded,
            4 => GpuCullClass::Visible,
            _ => return Err(Error::Unavailable(format!("cull kernel wrote an unknown class {v}"))),
        })
    }

    /// `true` for the classes that are drawn.
    pub fn is_kept(self) -> bool {
        matches!(self, GpuCullClass::Forced | GpuCullClass::CrossesNear | GpuCullClass::Visible)
    }
}

/// The objects a cull kernel tests: world AABBs, per-object draw records and forced flags, in
/// GPU buffers the caller owns and rewrites per frame (an engine may also fill `aabbs` with
/// its own compute pass: `(min.xyz, 0), (max.xyz, 0)` per object as f32).
#[derive(Debug)]
pub struct CullObjects {
    /// World AABBs, 2 `vec4<f32>` per object (`STORAGE | COPY_DST`).
    pub aabbs: wgpu::Buffer,
    /// Draw records `(first_index, index_count, base_vertex, slot)` per object.
    pub draws: wgpu::Buffer,
    /// Forced-visible flags (u32, non-zero = forced).
    pub forced: wgpu::Buffer,
    count: u32,
}

fn storage_init(ctx: &GpuContext, label: &str, bytes: &[u8]) -> wgpu::Buffer {
    ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: bytes,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
    })
}

impl CullObjects {
    /// `n` objects without geometry (draw records with zero indices, slot = id): for culling
    /// alone. AABBs start empty (culled), no object forced.
    pub fn new(ctx: &GpuContext, n: usize) -> Result<Self> {
        let draws: Vec<[u32; 4]> = (0..n as u32).map(|i| [0, 0, 0, i]).collect();
        Self::with_draws(ctx, &draws)
    }

    /// The objects of a [`GpuScene`] with the draw records its renderer uses (so the
    /// indirect arguments draw exactly what [`zwarp_gpu::Renderer::encode_depth`] draws per object).
    pub fn for_scene(ctx: &GpuContext, scene: &GpuScene) -> Result<Self> {
        Self::with_draws(ctx, scene.draws())
    }

    fn with_draws(ctx: &GpuContext, draws: &[[u32; 4]]) -> Result<Self> {
        let n = draws.len();
        if n == 0 {
            return Err(Error::invalid("culling needs at least one object"));
        }
        ctx.check_storage_size(n as u64 * 32, "object AABB buffer")?;
        let empty = Aabb::EMPTY;
        let boxes: Vec<[f32; 4]> =
            (0..n).flat_map(|_| [empty.min.extend(0.0).to_array(), empty.max.extend(0.0).to_array()]).collect();
        Ok(CullObjects {
            aabbs: storage_init(ctx, "zwarp cull aabbs", bytemuck::cast_slice(&boxes)),
            draws: storage_init(ctx, "zwarp cull draws", bytemuck::cast_slice(draws)),
            forced: storage_init(ctx, "zwarp cull forced", &vec![0u8; n * 4]),
            count: n as u32,
        })
    }

    /// Number of objects.
    pub fn len(&self) -> usize {
        self.count as usize
    }

    /// `true` when there are no objects (never: construction rejects it).
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Uploads world AABBs (one per object).
    pub fn write_aabbs(&self, ctx: &GpuContext, aabbs: &[Aabb]) -> Result<()> {
        if aabbs.len() != self.len() {
            return Err(Error::invalid(format!("{} AABBs for {} objects", aabbs.len(), self.len())));
        }
        let data: Vec<[f32; 4]> =
            aabbs.iter().flat_map(|b| [b.min.extend(0.0).to_array(), b.max.extend(0.0).to_array()]).collect();
        ctx.queue.write_buffer(&self.aabbs, 0, bytemuck::cast_slice(&data));
        Ok(())
    }

    /// Uploads the world AABBs of `scene`'s instances at time `t`
    /// ([`Scene::instance_aabb_at`], the boxes the CPU culling tests).
    pub fn write_scene_aabbs(&self, ctx: &GpuContext, scene: &Scene, t: f32) -> Result<()> {
        if !t.is_finite() {
            return Err(Error::invalid(format!("scene time must be finite, got {t}")));
        }
        if scene.instances.len() != self.len() {
            return Err(Error::invalid(format!(
                "scene has {} objects, the cull buffers {}",
                scene.instances.len(),
                self.len()
            )));
        }
        let boxes: Vec<Aabb> = (0..self.count).into_par_iter().map(|id| scene.instance_aabb_at(id, t)).collect();
        self.write_aabbs(ctx, &boxes)
    }

    /// Uploads forced-visible flags (`None`: no object forced).
    pub fn write_forced(&self, ctx: &GpuContext, forced: Option<&[bool]>) -> Result<()> {
        let flags: Vec<u32> = match forced {
            None => vec![0; self.len()],
            Some(f) if f.len() == self.len() => f.iter().map(|&b| b as u32).collect(),
            Some(f) => {
                return Err(Error::invalid(format!(
                    "forced-visible flags: {} entries for {} objects",
                    f.len(),
                    self.len()
                )))
            }
        };
        ctx.queue.write_buffer(&self.forced, 0, bytemuck::cast_slice(&flags));
        Ok(())
    }
}

/// What the cull kernel writes, in buffers the caller owns (allocate once, reuse per frame).
#[derive(Debug)]
pub struct CullOutput {
    /// Class per object (u32, see [`GpuCullClass`]).
    pub classes: wgpu::Buffer,
    /// Compacted ids of the kept objects (the first `counter[0]` entries; order arbitrary).
    pub visible: wgpu::Buffer,
    /// One u32: the number of kept objects (the count buffer of
    /// `multi_draw_indexed_indirect_count`).
    pub counter: wgpu::Buffer,
    /// `DrawIndexedIndirectArgs` of the kept objects, compacted like `visible`.
    pub draw_args: wgpu::Buffer,
    /// `DrawIndexedIndirectArgs` per draw slot (every object, instance count 0 when culled):
    /// the fallback for adapters without indirect count.
    pub slot_args: wgpu::Buffer,
    count: u32,
}

/// A [`CullOutput`] read back to the CPU.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CullReadback {
    /// Class per object.
    pub classes: Vec<GpuCullClass>,
    /// Kept object ids, increasing (sorted on read-back; the GPU order is arbitrary).
    pub visible: Vec<u32>,
}

impl CullOutput {
    /// Output buffers for `n` objects.
    pub fn new(ctx: &GpuContext, n: usize) -> Result<Self> {
        if n == 0 {
            return Err(Error::invalid("culling needs at least one object"));
        }
        let args_bytes = n as u64 * std::mem::size_of::<wgpu::util::DrawIndexedIndirectArgs>() as u64;
        ctx.check_storage_size(args_bytes, "indirect argument buffer")?;
        let buf = |label, size: u64, extra| {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | extra,
                mapped_at_creation: false,
            })
        };
        let ind = wgpu::BufferUsages::INDIRECT;
        Ok(CullOutput {
            classes: buf("zwarp cull classes", n as u64 * 4, wgpu::BufferUsages::empty()),
            visible: buf("zwarp cull visible", n as u64 * 4, wgpu::BufferUsages::empty()),
            counter: buf("zwarp cull counter", 4, ind | wgpu::BufferUsages::COPY_DST),
            draw_args: buf("zwarp cull draw args", args_bytes, ind),
            slot_args: buf("zwarp cull slot args", args_bytes, ind),
            count: n as u32,
        })
    }

    /// Wraps buffers the caller already owns (an engine's): `classes` and `visible` of `4 n`
    /// bytes, `counter` of 4 bytes (`INDIRECT | COPY_DST`, the draw count), `draw_args` and
    /// `slot_args` of `20 n` bytes (`INDIRECT`); all `STORAGE` (and `COPY_SRC` for
    /// [`CullOutput::read`]). Errors name the first buffer that does not fit.
    pub fn from_buffers(
        n: usize,
        classes: wgpu::Buffer,
        visible: wgpu::Buffer,
        counter: wgpu::Buffer,
        draw_args: wgpu::Buffer,
        slot_args: wgpu::Buffer,
    ) -> Result<Self> {
        if n == 0 {
            return Err(Error::invalid("culling needs at least one object"));
        }
        let args = n as u64 * std::mem::size_of::<wgpu::util::DrawIndexedIndirectArgs>() as u64;
        let (st, ind) = (wgpu::BufferUsages::STORAGE, wgpu::BufferUsages::INDIRECT);
        for (name, b, bytes, usage) in [
            ("classes", &classes, n as u64 * 4, st),
            ("visible", &visible, n as u64 * 4, st),
            ("counter", &counter, 4, st | ind | wgpu::BufferUsages::COPY_DST),
            ("draw_args", &draw_args, args, st | ind),
            ("slot_args", &slot_args, args, st | ind),
        ] {
            if b.size() < bytes || !b.usage().contains(usage) {
                return Err(Error::invalid(format!(
                    "cull output buffer '{name}' needs {bytes} bytes and {usage:?}, has {} bytes and {:?}",
                    b.size(),
                    b.usage()
                )));
            }
        }
        Ok(CullOutput { classes, visible, counter, draw_args, slot_args, count: n as u32 })
    }

    /// Number of objects it holds results for.
    pub fn len(&self) -> usize {
        self.count as usize
    }

    /// `true` when it holds no object (never: construction rejects it).
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Reads classes and the visible list back (after the cull was submitted).
    pub fn read(&self, ctx: &GpuContext) -> Result<CullReadback> {
        let classes = read_buffer::<u32>(ctx, &self.classes, self.len())?
            .into_iter()
            .map(GpuCullClass::from_u32)
            .collect::<Result<Vec<_>>>()?;
        let n = read_buffer::<u32>(ctx, &self.counter, 1)?[0] as usize;
        if n > self.len() {
            return Err(Error::Unavailable(format!("cull kernel counted {n} visible of {} objects", self.len())));
        }
        let mut visible = read_buffer::<u32>(ctx, &self.visible, n)?;
        visible.sort_unstable();
        Ok(CullReadback { classes, visible })
    }
}

/// What [`zwarp_gpu::Renderer::encode_depth_indirect`] draws: `draw_args` with `counter` in
/// [`IndirectMode::Count`], `slot_args` in [`IndirectMode::Slots`].
impl IndirectDraws for CullOutput {
    fn slot_count(&self) -> usize {
        self.len()
    }

    fn args(&self, mode: IndirectMode) -> (&wgpu::Buffer, Option<&wgpu::Buffer>) {
        match mode {
            IndirectMode::Count => (&self.draw_args, Some(&self.counter)),
            IndirectMode::Slots => (&self.slot_args, None),
        }
    }
}

/// The cull kernel (see the module docs).
pub struct CullKernel {
    ctx: GpuContext,
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
}

impl CullKernel {
    /// Compiles `maxquery.wgsl` + `cull.wgsl`.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let dev = &ctx.device;
        let module = ctx.shader("cull.wgsl", concat!(include_str!("maxquery.wgsl"), include_str!("cull.wgsl")))?;
        let ro = wgpu::BufferBindingType::Storage { read_only: true };
        let rw = wgpu::BufferBindingType::Storage { read_only: false };
        let (layout, pl) = zwarp_gpu::kernel::buffer_layouts(
            dev,
            "zwarp cull",
            &[wgpu::BufferBindingType::Uniform, ro, ro, ro, ro, ro, rw, rw, rw, rw, rw],
        );
        let pipeline = ctx.catch("building the cull pipeline", || {
            dev.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("zwarp cull"),
                layout: Some(&pl),
                module: &module,
                entry_point: Some("cull"),
                compilation_options: Default::default(),
                cache: None,
            })
        })?;
        Ok(CullKernel { ctx: ctx.clone(), pipeline, layout })
    }

    /// Records the culling of `objects` seen through `view_proj` on a `width x height` image
    /// against `map` (built over the same image): an object is occluded when the max depth over
    /// its rectangle is below its nearest corner depth minus `params.tolerance`
    /// ([`CullParams`]). Clears the counter first.
    #[allow(clippy::too_many_arguments)]
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        objects: &CullObjects,
        view_proj: &Mat4,
        width: u32,
        height: u32,
        params: &CullParams,
        map: &GpuMaxDepth,
        out: &CullOutput,
    ) -> Result<()> {
        let tolerance = params.tolerance;
        if map.layout.size != (width, height) {
            return Err(Error::invalid(format!(
                "max-depth structure is {}x{} but the camera renders {width}x{height}",
                map.layout.size.0, map.layout.size.1
            )));
        }
        if out.len() != objects.len() {
            return Err(Error::invalid(format!("cull output for {} objects, {} given", out.len(), objects.len())));
        }
        if !view_proj.is_finite() {
            return Err(Error::invalid("camera matrices are not finite"));
        }
        if !(tolerance.is_finite() && tolerance >= 0.0) {
            return Err(Error::invalid(format!("depth tolerance must be finite and >= 0, got {tolerance}")));
        }
        let planes = Frustum::from_view_proj(view_proj).planes.map(|p| p.to_array());
        let uniform = Params {
            view_proj: view_proj.to_cols_array_2d(),
            planes,
            size_tol: [width as f32, height as f32, tolerance, HULL_CENTRE_SLACK],
            counts: [objects.count, width, height, params.hull_test as u32],
        };
        let dev = &self.ctx.device;
        let ubuf = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("zwarp cull params"),
            contents: bytemuck::bytes_of(&uniform),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let bufs = [
            &ubuf,
            &map.table,
            &map.data,
            &objects.aabbs,
            &objects.draws,
            &objects.forced,
            &out.classes,
            &out.visible,
            &out.counter,
            &out.draw_args,
            &out.slot_args,
        ];
        let entries: Vec<wgpu::BindGroupEntry> = bufs
            .iter()
            .enumerate()
            .map(|(i, b)| wgpu::BindGroupEntry { binding: i as u32, resource: b.as_entire_binding() })
            .collect();
        let bind = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("zwarp cull"),
            layout: &self.layout,
            entries: &entries,
        });
        encoder.clear_buffer(&out.counter, 0, None);
        let mut pass = encoder
            .begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("zwarp cull"), timestamp_writes: None });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &bind, &[]);
        // 2-D grid: one dimension caps at 65535 workgroups (4M objects at 64 per group).
        let groups = objects.count.div_ceil(64);
        pass.dispatch_workgroups(groups.min(65535), groups.div_ceil(65535), 1);
        Ok(())
    }

    /// Culls `objects` for `camera` against `map` with [`CullParams::default`] (the test of
    /// `crate::cull_against_depth`), submits and reads the result back.
    pub fn cull(
        &self,
        objects: &CullObjects,
        camera: &Camera,
        map: &GpuMaxDepth,
        out: &CullOutput,
    ) -> Result<CullReadback> {
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        self.encode(
            &mut enc,
            objects,
            &camera.view_proj(),
            camera.width,
            camera.height,
            &CullParams::default(),
            map,
            out,
        )?;
        self.ctx.queue.submit([enc.finish()]);
        out.read(&self.ctx)
    }
}
