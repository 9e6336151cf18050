//! The one seam between a command and the backend it runs on: a command opens a [`Device`]
//! from `--backend` and calls the same methods on either backend — render the reference,
//! predict a view, run a culling sequence, evaluate soft shadows — so its loop, timing and
//! comparisons are written once. Kernels are created on first use (shader compilation on
//! lavapipe is not free).

use std::cell::OnceCell;

use anyhow::Result;
use zwarp_color::{ColorWarpOutput, Field, HeuristicParams, RobustParams, Subdivision};
use zwarp_core::{AreaLight, Camera, Image, Scene};
use zwarp_cull::{run_sequence_repeated, FrameReport, Method, WocParams};
use zwarp_shadows::{EvalConfig, EvalRow, ShadowResult};
use zwarp_warp::{PreparedLayer, WarpLayer, WarpOutput, WarpParams};

use crate::args::Backend;

/// Where a command's work runs.
pub enum Device {
    /// zwarp-raster, zwarp-warp, zwarp-cull, zwarp-shadows on the CPU (rayon).
    Cpu,
    /// The wgpu twins on the first adapter (lavapipe without a GPU).
    Gpu(Box<Gpu>),
}

/// A wgpu device and the kernels the commands use, created on first use.
pub struct Gpu {
    /// The device.
    pub ctx: zwarp_gpu::GpuContext,
    renderer: OnceCell<zwarp_gpu::Renderer>,
    motion: OnceCell<zwarp_warp::gpu::MotionKernel>,
    warp: OnceCell<(zwarp_warp::gpu::WarpKernel, zwarp_warp::gpu::HoleFillKernel)>,
    shadows: OnceCell<zwarp_shadows::gpu::GpuShadows>,
    color: OnceCell<zwarp_color::gpu::ColorWarpKernel>,
    grid: OnceCell<zwarp_vr::gpu::GridWarpKernel>,
}

/// `cell`'s value, made by `make` the first time.
fn once<T>(cell: &OnceCell<T>, make: impl FnOnce() -> zwarp_core::Result<T>) -> Result<&T> {
    if cell.get().is_none() {
        let _ = cell.set(make()?);
    }
    Ok(cell.get().expect("set above"))
}

/// Depth, item ids and (when rendered) linear colour of one view.
pub type ViewBuffers = (Image<f32>, Image<u32>, Option<Image<[f32; 3]>>);

/// A scene on a device: the scene itself and, on the GPU, its upload.
pub struct DeviceScene<'s> {
    /// The scene (CPU data: bounds, animation, what CPU-side stages read).
    pub scene: &'s Scene,
    gpu: Option<zwarp_gpu::GpuScene>,
}

impl Device {
    /// Opens `backend`: one `error:` line when the GPU backend has no adapter.
    pub fn open(backend: Backend) -> Result<Device> {
        Ok(match backend {
            Backend::Cpu => Device::Cpu,
            Backend::Gpu => Device::Gpu(Box::new(Gpu {
                ctx: zwarp_gpu::GpuContext::new()?,
                renderer: OnceCell::new(),
                motion: OnceCell::new(),
                warp: OnceCell::new(),
                shadows: OnceCell::new(),
                color: OnceCell::new(),
                grid: OnceCell::new(),
            })),
        })
    }

    /// Whether this is the GPU backend.
    pub fn is_gpu(&self) -> bool {
        matches!(self, Device::Gpu(_))
    }

    /// The GPU adapter's description, `None` on the CPU.
    pub fn adapter(&self) -> Option<String> {
        match self {
            Device::Cpu => None,
            Device::Gpu(g) => Some(g.ctx.adapter.to_string()),
        }
    }

    /// One line for a command's header: `CPU with 2 threads` or `GPU <adapter>`.
    pub fn describe(&self) -> String {
        match self {
            Device::Cpu => format!("CPU with {} threads", rayon::current_num_threads()),
            Device::Gpu(g) => format!("GPU {}", g.ctx.adapter),
        }
    }

    /// `scene` made ready for this device (uploaded on the GPU).
    pub fn load<'s>(&self, scene: &'s Scene) -> Result<DeviceScene<'s>> {
        let gpu = match self {
            Device::Cpu => None,
            Device::Gpu(g) => Some(zwarp_gpu::GpuScene::upload(&g.ctx, scene)?),
        };
        Ok(DeviceScene { scene, gpu })
    }

    /// The depth-only render of `cam` at time `t` (the reference a prediction replaces) into
    /// `out`, a target recycled from an earlier render (on the CPU its pages are reused, as the
    /// warps reuse theirs; the GPU reads back into a new buffer).
    pub fn render_depth_into(&self, s: &DeviceScene<'_>, cam: &Camera, t: f32, out: &mut Image<f32>) -> Result<()> {
        match (self, &s.gpu) {
            (Device::Gpu(g), Some(up)) => {
                let r = once(&g.renderer, || zwarp_gpu::Renderer::new(&g.ctx))?;
                *out = r.render_depth(up, cam, t)?;
            }
            _ => zwarp_raster::render_depth_into(s.scene, cam, t, out)?,
        }
        Ok(())
    }

    /// Times of `reps` depth-only renders of `cam` at `t` (ms; on the GPU fenced on the device,
    /// without reading the depth back).
    pub fn time_depth_only(&self, s: &DeviceScene<'_>, cam: &Camera, t: f32, reps: usize) -> Result<Vec<f64>> {
        let samples = match (self, &s.gpu) {
            (Device::Gpu(g), Some(up)) => {
                let r = once(&g.renderer, || zwarp_gpu::Renderer::new(&g.ctx))?;
                let target = zwarp_gpu::DepthTarget::new(&g.ctx, cam.width, cam.height)?;
                crate::harness::time_repeated(reps, || {
                    let mut enc = g.ctx.device.create_command_encoder(&Default::default());
                    r.encode_depth(&mut enc, up, cam, t, &target)?;
                    g.ctx.queue.submit([enc.finish()]);
                    Ok(g.ctx.wait()?)
                })?
                .1
            }
            _ => {
                let mut target = Image::new(0, 0, 1.0);
                crate::harness::time_into(reps, &mut target, |d| {
                    Ok(zwarp_raster::render_depth_into(s.scene, cam, t, d)?)
                })?
                .1
            }
        };
        Ok(samples)
    }

    /// The motion field (seed 000 Sec. 3.1) of a view of `s` (`depth`, `items` seen by `cam_a`
    /// at `t_a`) towards `cam_b` at `t_b`, with each object's own motion.
    #[allow(clippy::too_many_arguments)]
    pub fn motion_field(
        &self,
        s: &DeviceScene<'_>,
        depth: &Image<f32>,
        items: &Image<u32>,
        (cam_a, t_a): (&Camera, f32),
        (cam_b, t_b): (&Camera, f32),
    ) -> Result<Image<zwarp_core::Motion>> {
        match (self, &s.gpu) {
            (Device::Gpu(g), Some(up)) => {
                let k = once(&g.motion, || zwarp_warp::gpu::MotionKernel::new(&g.ctx))?;
                Ok(k.motion_field(depth, Some(items), cam_a, cam_b, &up.object_deltas(t_a, t_b))?)
            }
            _ => Ok(zwarp_core::motion_field(depth, Some(items), cam_a, cam_b, &s.scene.object_deltas(t_a, t_b))?),
        }
    }

    /// The depth of `layers` layers peeled from `cam` at `t` (standard peeling; with
    /// `ground_separate` the ground alone as one more, last layer).
    pub fn peel_depths(
        &self,
        s: &DeviceScene<'_>,
        cam: &Camera,
        t: f32,
        layers: usize,
        ground_separate: bool,
    ) -> Result<Vec<Image<f32>>> {
        Ok(match (self, &s.gpu) {
            (Device::Gpu(g), Some(up)) => {
                let r = once(&g.renderer, || zwarp_gpu::Renderer::new(&g.ctx))?;
                let opts = zwarp_gpu::PeelOptions { layers: layers as u32, ground_separate, ..Default::default() };
                r.render_layers(up, cam, t, &opts)?.into_iter().map(|l| l.depth).collect()
            }
            _ => {
                let opts = zwarp_raster::PeelOptions { layers, ground_separate, umbra: None };
                zwarp_raster::render_layers(s.scene, cam, t, &opts)?.into_iter().map(|l| l.depth).collect()
            }
        })
    }

    /// The complete depth prediction (preparation, search, hole protocol) of `layers` into
    /// `out`. On the CPU the preparation buffers in `recycled` and the output's buffers carry
    /// over between calls, as an engine keeps them across frames.
    pub fn predict(
        &self,
        layers: &[WarpLayer<'_>],
        params: &WarpParams,
        recycled: &mut Vec<PreparedLayer>,
        out: &mut WarpOutput,
    ) -> Result<()> {
        match self {
            Device::Cpu => {
                *recycled = zwarp_warp::predict_into(layers, params, std::mem::take(recycled), out)?;
            }
            Device::Gpu(g) => {
                let (warp, fill) = once(&g.warp, || {
                    Ok((zwarp_warp::gpu::WarpKernel::new(&g.ctx)?, zwarp_warp::gpu::HoleFillKernel::new(&g.ctx)?))
                })?;
                *out = zwarp_warp::gpu::predict(warp, fill, layers, params)?;
            }
        }
        Ok(())
    }

    /// Whether culling `method` runs on this device (two-phase is CPU-only).
    pub fn supports_cull(&self, method: Method) -> bool {
        !self.is_gpu() || zwarp_cull::gpu::gpu_supports(method)
    }

    /// `method` along `frames` (the engine's loop timed alone, then the comparisons), each
    /// frame culled `repeat` times on the CPU (the median-cost repetition kept).
    pub fn cull_sequence(
        &self,
        scene: &Scene,
        frames: &[(f32, Camera)],
        method: Method,
        params: &WocParams,
        repeat: usize,
    ) -> Result<Vec<FrameReport>> {
        match self {
            Device::Cpu => Ok(run_sequence_repeated(scene, frames, method, params, repeat)?),
            Device::Gpu(g) => {
                if repeat != 1 {
                    anyhow::bail!("--repeat is CPU-only (the GPU backend culls each frame once)");
                }
                Ok(zwarp_cull::gpu::run_gpu_sequence(&g.ctx, scene, frames, method, params)?)
            }
        }
    }

    /// Soft shadows of `light` seen from `cam` at time `t` for every S and map size of `cfg`
    /// (seed 000 Sec. 6), `on_result` called with each result and its reference.
    #[allow(clippy::too_many_arguments)]
    pub fn shadows(
        &self,
        s: &DeviceScene<'_>,
        cam: &Camera,
        t: f32,
        light: &AreaLight,
        cfg: &EvalConfig,
        on_result: impl FnMut(&EvalRow, &ShadowResult, &ShadowResult) -> zwarp_core::Result<()>,
    ) -> Result<Vec<EvalRow>> {
        match (self, &s.gpu) {
            (Device::Gpu(g), Some(up)) => {
                let gs = once(&g.shadows, || zwarp_shadows::gpu::GpuShadows::new(&g.ctx))?;
                Ok(zwarp_shadows::gpu::evaluate_gpu(gs, s.scene, up, cam, t, light, cfg, on_result)?)
            }
            _ => Ok(zwarp_shadows::evaluate(s.scene, cam, t, light, cfg, on_result)?),
        }
    }

    /// Depth, item ids and textured linear colour of `cam` at time `t`.
    pub fn render_view(&self, s: &DeviceScene<'_>, cam: &Camera, t: f32) -> Result<ViewBuffers> {
        match (self, &s.gpu) {
            (Device::Gpu(g), Some(up)) => {
                let r = once(&g.renderer, || zwarp_gpu::Renderer::new(&g.ctx))?;
                let f = r.render_frame(up, cam, t, &zwarp_gpu::FrameOptions { color: true, ..Default::default() })?;
                Ok((f.depth, f.items, f.color))
            }
            _ => {
                let opts = zwarp_raster::FrameOptions { color: true, objects: None };
                let f = zwarp_raster::render_frame(s.scene, cam, t, &opts)?;
                Ok((f.depth, f.items, f.color))
            }
        }
    }

    /// Seed 003's warp of `src` to the view `dst` with `method` (`zwarp_vr::warp`): on the GPU
    /// the mesh (quadtree, cells) is built on the CPU and drawn by the GPU's rasteriser, and
    /// `fpi` runs the GPU heuristic colour warp.
    pub fn vr_warp(
        &self,
        src: &zwarp_vr::grid::Source<'_>,
        dst: &Camera,
        method: zwarp_vr::Method,
        p: &zwarp_vr::grid::WarpParams,
    ) -> Result<zwarp_vr::WarpOutput> {
        let Device::Gpu(g) = self else { return Ok(zwarp_vr::warp(src, dst, method, p)?) };
        if method == zwarp_vr::Method::Fpi {
            let k = self.color_kernel()?.expect("the GPU device has a colour kernel");
            let t = std::time::Instant::now();
            let (basis, hp) = zwarp_vr::grid::fpi_setup(src, dst)?;
            let o = k.heuristic(&basis.field(zwarp_color::FieldParams::temporal(1.0))?, src.color, &hp)?;
            let mut out = zwarp_vr::WarpOutput::filled(o.color, o.depth);
            out.ms.warp = t.elapsed().as_secs_f64() * 1e3;
            return Ok(out);
        }
        let k = once(&g.grid, || zwarp_vr::gpu::GridWarpKernel::new(&g.ctx))?;
        Ok(k.raster(src, dst, &zwarp_vr::grid::Mesh::build(src, dst, method, p)?)?)
    }

    fn color_kernel(&self) -> Result<Option<&zwarp_color::gpu::ColorWarpKernel>> {
        match self {
            Device::Cpu => Ok(None),
            Device::Gpu(g) => Ok(Some(once(&g.color, || zwarp_color::gpu::ColorWarpKernel::new(&g.ctx))?)),
        }
    }

    /// Seed 001's heuristic colour warp into `out` (whose buffers a CPU warp reuses).
    pub fn heuristic_into(
        &self,
        field: &Field<'_>,
        color: &Image<[f32; 3]>,
        p: &HeuristicParams,
        out: &mut ColorWarpOutput,
    ) -> Result<()> {
        match self.color_kernel()? {
            None => zwarp_color::heuristic_warp_into(field, color, p, out)?,
            Some(k) => *out = k.heuristic(field, color, p)?,
        }
        Ok(())
    }

    /// Seed 001's robust colour warp with the subdivision `sub` (of this field, or shared by
    /// several, as blur does) into `out`; `None` subdivides the field first.
    pub fn robust_into(
        &self,
        sub: Option<&Subdivision>,
        field: &Field<'_>,
        color: &Image<[f32; 3]>,
        p: &RobustParams,
        out: &mut ColorWarpOutput,
    ) -> Result<()> {
        match (self.color_kernel()?, sub) {
            (None, Some(sub)) => {
                zwarp_color::robust_warp_with(sub, field, color, p, out)?;
            }
            (None, None) => {
                zwarp_color::robust_warp_with(&Subdivision::of_field(field, p.tile)?, field, color, p, out)?;
            }
            (Some(k), Some(sub)) => *out = k.robust_with(sub, field, color, p)?,
            (Some(k), None) => *out = k.robust(field, color, p)?,
        }
        Ok(())
    }
}
