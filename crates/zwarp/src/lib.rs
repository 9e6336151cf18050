//! zwarp: predict the depth buffer of a new view by warping depth layers that were already
//! rendered (seed 000: backward warping by fixed-point iteration with tight motion bounds,
//! multi-layer hole filling), on the CPU or on a wgpu device behind the same calls.
//!
//! The common path is three calls: a [`Warper`] with a [`Backend`], [`Warper::prepare`] with
//! the rendered source view (its camera and peeled depth layers, nearest first), and
//! [`Warper::warp_to`] with the camera of the view to predict. The prediction runs the complete
//! pipeline of `zwarp eval`: the motion of every layer between the two views (Sec. 3.1), the
//! motion bounds (Sec. 3.3), the search over seeds and layers (Sec. 3.2, 3.4) and the hole
//! protocol of Sec. 4 (`zwarp_warp::holes::fill_background`).
//!
//! ```
//! use zwarp::{Backend, Camera, Warper, Vec3};
//! use zwarp::warp::synth::SynthScene;
//!
//! // Two views of a small analytic city, 20 cm apart (a renderer would supply the layers).
//! let (w, h) = (96, 64);
//! let cam = |x: f32| Camera::perspective(Vec3::new(x, 8.0, 10.0), Vec3::new(x, 0.0, -4.0), Vec3::Y, 1.0, 0.5, 100.0, w, h);
//! let (a, b) = (cam(0.0)?, cam(0.2)?);
//! let scene = SynthScene::city(3);
//! let source = scene.render(&a, 0.0, 3, true);
//!
//! let mut warper = Warper::new(Backend::Cpu, Warper::default_params())?;
//! warper.prepare(&a, &source.depth, Some(&source.items))?;
//! let prediction = warper.warp_to(&b, &[])?;
//!
//! let reference = scene.render(&b, 0.0, 1, false).depth.remove(0);
//! assert_eq!(prediction.depth.size(), reference.size());
//! assert!(prediction.converged_fraction() > 0.95);
//! # Ok::<(), zwarp::Error>(())
//! ```
//!
//! On a GPU the source can stay where the renderer left it: [`Warper::prepare_gpu`] takes the
//! engine's own depth and item textures (or buffers) on its own device
//! (`GpuContext::from_device`), and [`Warper::warp_to_gpu`] records the whole prediction (motion,
//! warp, the hole protocol with its limits measured on the GPU) into one command encoder and
//! leaves it in GPU buffers ([`GpuPrediction`]) for the engine's next pass:
//!
//! ```
//! use zwarp::gpu::{wgpu, GpuContext};
//! use zwarp::warp::synth::SynthScene;
//! use zwarp::{Backend, GpuImage, GpuSourceLayer, Warper};
//!
//! // The engine's device and queue (here a context zwarp opens; no GPU, nothing to show).
//! let Some(ctx) = zwarp::gpu::test_context() else { return Ok(()) };
//! let ctx = GpuContext::from_device(ctx.device, ctx.queue);
//! let (a, b) = SynthScene::city_views(96, 64)?;
//! let scene = SynthScene::moving_city();
//! let frame = scene.render(&a, 0.0, 1, false);
//!
//! // The engine's depth and item textures of view A (a `Depth32Float` depth attachment with
//! // TEXTURE_BINDING usage works alike; these are filled from the CPU for the example).
//! let texture = |format, bytes: Vec<u8>| {
//!     let size = wgpu::Extent3d { width: a.width, height: a.height, depth_or_array_layers: 1 };
//!     let usage = wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST;
//!     let t = ctx.device.create_texture(&wgpu::TextureDescriptor {
//!         label: None, size, mip_level_count: 1, sample_count: 1,
//!         dimension: wgpu::TextureDimension::D2, format, usage, view_formats: &[],
//!     });
//!     let row = Some(a.width * 4);
//!     let layout = wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: row, rows_per_image: None };
//!     ctx.queue.write_texture(t.as_image_copy(), &bytes, layout, size);
//!     t
//! };
//! let depth_bytes = frame.depth[0].data().iter().flat_map(|z| z.to_le_bytes()).collect();
//! let item_bytes = frame.items[0].data().iter().flat_map(|i| i.to_le_bytes()).collect();
//! let depth = texture(wgpu::TextureFormat::R32Float, depth_bytes);
//! let items = texture(wgpu::TextureFormat::R32Uint, item_bytes);
//!
//! let mut warper = Warper::new(Backend::Gpu(ctx.clone()), Warper::default_params())?;
//! let source = GpuSourceLayer { depth: GpuImage::Texture(&depth), items: Some(GpuImage::Texture(&items)) };
//! warper.prepare_gpu(&a, &[source])?;
//! let predicted = warper.warp_to_gpu(&b, &scene.object_deltas(0.0, 0.25))?;
//! // `predicted.depth()` is a `wgpu::Buffer` of 96 x 64 floats for the engine's next pass;
//! // reading it back is for checking only.
//! assert_eq!(predicted.size(), (96, 64));
//! assert!(predicted.read(&ctx)?.converged_fraction() > 0.9);
//! # Ok::<(), zwarp::Error>(())
//! ```
//!
//! Colour frames are predicted the same way by a [`FrameWarper`] (seed 001, Iterative Image
//! Warping): [`FrameWarper::prepare`] with a rendered frame's colour, depth and item buffers,
//! [`FrameWarper::warp_to`] with the new camera, and the heuristic or robust warp
//! ([`ColorMethod`]) gives the predicted colour with a per-pixel confidence
//! ([`ColorWarpOutput::residual`]) — an in-between frame for frame-rate upsampling, a late view,
//! the other eye. Its example is on [`FrameWarper`].
//!
//! Occlusion culling by warping (seed 000 Sec. 5, WOC) takes the engine's objects as plain
//! boxes ([`BoxObject`]: object-space box, previous and current transform; its index is the id
//! the item buffer stores) and last frame's depth and item buffers ([`PrevFrame`]), and returns
//! the objects to draw, without a hierarchy and without zwarp's scene type:
//!
//! ```
//! use zwarp::{woc_objects, Aabb, BoxObject, Camera, PrevFrame, Vec3, WocParams};
//! use zwarp::warp::synth::SynthScene;
//!
//! let (w, h) = (128, 72);
//! let cam = |x: f32| Camera::perspective(Vec3::new(x, 1.0, 16.0), Vec3::new(x, 1.0, 0.0), Vec3::Y, 1.0, 0.5, 100.0, w, h);
//! let (a, b) = (cam(0.0)?, cam(0.3)?);
//! let city = SynthScene::city(6);
//! // The engine's objects: the boxes, then the ground (id = number of boxes) as a thin slab.
//! let mut objects: Vec<BoxObject> = city.boxes.iter().map(|b| BoxObject::fixed(b.aabb)).collect();
//! objects.push(BoxObject::fixed(Aabb::new(Vec3::new(-40.0, -0.01, -40.0), Vec3::new(40.0, 0.0, 40.0))));
//!
//! // Last frame's depth and item buffers, as the renderer left them.
//! let last = city.render(&a, 0.0, 1, false);
//! let previous = PrevFrame { depth: &last.depth[0], items: &last.items[0], cam: &a, t: 0.0 };
//! let culled = woc_objects(objects.as_slice(), &previous, &b, &WocParams::default())?;
//!
//! // Every object the new view shows is kept; most boxes behind the front rows are not.
//! let truth = city.render(&b, 0.0, 1, false);
//! assert!(truth.items[0].data().iter().filter(|&&id| id != zwarp::core::NO_ITEM).all(|id| culled.visible.contains(id)));
//! assert!(culled.stats.occlusion_culled >= 10);
//! # Ok::<(), zwarp::Error>(())
//! ```
#![deny(missing_docs)]

pub use glam::{Mat4, Vec2, Vec3};
pub use zwarp_core::{Aabb, Camera, Error, Image, Motion, Result};
pub use zwarp_cull::{woc_objects, BoxObject, CullResult, PrevFrame, WocParams};
pub use zwarp_warp::gpu::GpuImage;
pub use zwarp_warp::{HolePolicy, PixelState, WarpParams};

mod frames;
pub use frames::{ColorMethod, FrameWarper};
pub use zwarp_color::{ColorWarpOutput, HeuristicParams, RobustParams};

/// Colour warping stage by stage (seed 001): warp fields, the heuristic and robust warps,
/// their baselines and GPU twins.
pub use zwarp_color as color;
/// Soft shadows from warped shadow maps (seed 000 Sec. 6): area lights, the reference, zwarp's
/// lazily synthesized maps, PCSS.
pub use zwarp_shadows as shadows;
/// Both eyes of a stereo / VR frame from one rendered view (seed 003): the surface-estimation
/// quadtree, the adaptive grid warp, depth-aware hole filling, A-buffer ray casting.
pub use zwarp_vr as vr;

/// The building blocks: depth buffers, cameras, motion fields.
pub use zwarp_core as core;
/// Occlusion culling by warping and the baselines it is measured against (seed 000 Sec. 5).
pub use zwarp_cull as cull;
/// The GPU backend in one place: zwarp-gpu's context, renderer, read-back and timing, the
/// warp's kernels (`zwarp_warp::gpu`: motion field, motion mipmap, warp, hole filling) and
/// culling's (`zwarp_cull::gpu`: max-depth structures, cull, WOC), and the wgpu version they
/// are built against.
pub mod gpu {
    pub use zwarp_cull::gpu::*;
    pub use zwarp_gpu::*;
    pub use zwarp_warp::gpu::*;
}
/// The warp itself, stage by stage: preparation, search, baselines, hole protocol.
pub use zwarp_warp as warp;

use zwarp_gpu::{wgpu, GpuContext};
use zwarp_warp::gpu::{GpuWarpLayer, GpuWarpOutput, MotionInput, MAX_GPU_LAYERS};
use zwarp_warp::{PreparedLayer, WarpLayer, WarpOutput};

/// Where the prediction runs.
pub enum Backend {
    /// Pure Rust on the CPU (AVX2 lanes where the CPU has them).
    Cpu,
    /// WGSL compute kernels on a wgpu device: the caller's own (`GpuContext::from_device`) or
    /// one zwarp opens (`GpuContext::new`).
    Gpu(zwarp_gpu::GpuContext),
}

/// A predicted depth buffer of the target view.
#[derive(Clone, Debug, PartialEq)]
pub struct Prediction {
    /// Predicted depth (`[0, 1]`, the source's depth convention; `1.0` = no surface).
    pub depth: Image<f32>,
    /// Per pixel, how the depth was obtained: a converged search (a warped sample), filled by
    /// the hole protocol (an estimate), or a hole (far depth).
    pub state: Image<PixelState>,
}

impl Prediction {
    /// Fraction of pixels whose depth is a warped sample ([`PixelState::Converged`]).
    pub fn converged_fraction(&self) -> f64 {
        let n = self.state.len().max(1) as f64;
        self.state.data().iter().filter(|s| **s == PixelState::Converged).count() as f64 / n
    }
}

/// One source layer that lives on the GPU, for [`Warper::prepare_gpu`]: the engine's own depth
/// (a `Depth32Float` attachment or an `R32Float` texture with `TEXTURE_BINDING` usage, or an
/// `f32` buffer with a row stride) and optionally its item (object id) image (`R32Uint`, or a
/// `u32` buffer), which carries object motion (seed 000 Sec. 3.1).
#[derive(Clone, Copy, Debug)]
pub struct GpuSourceLayer<'a> {
    /// Source depth, `[0, 1]`, `1.0` = empty.
    pub depth: GpuImage<'a>,
    /// Item ids of the layer's samples (indices into `object_deltas` of
    /// [`Warper::warp_to_gpu`]), or `None`: the layer moves with the camera only.
    pub items: Option<GpuImage<'a>>,
}

/// A predicted depth buffer that stays on the GPU ([`Warper::warp_to_gpu`]): the buffers an
/// engine binds in its next pass, e.g. as the occlusion map of seed 000 Sec. 5.
#[derive(Debug)]
pub struct GpuPrediction {
    out: GpuWarpOutput,
}

impl GpuPrediction {
    /// Predicted depth: `width * height` `f32`, row-major (`[0, 1]`, `1.0` = no surface);
    /// `STORAGE | COPY_SRC` usage.
    pub fn depth(&self) -> &wgpu::Buffer {
        &self.out.depth
    }

    /// Per pixel, how the depth was obtained ([`PixelState`] as `u32`: 0 converged, 1 filled,
    /// 2 hole, 3 converged on a source layer after the first, i.e. revealed where the front
    /// layers disocclude); `STORAGE | COPY_SRC` usage.
    pub fn state(&self) -> &wgpu::Buffer {
        &self.out.state
    }

    /// `(width, height)` of the prediction: the target camera's image.
    pub fn size(&self) -> (u32, u32) {
        (self.out.width, self.out.height)
    }

    /// Reads the prediction back into a CPU [`Prediction`] (submits a copy and waits).
    pub fn read(&self, ctx: &GpuContext) -> Result<Prediction> {
        let o = self.out.read(ctx)?;
        Ok(Prediction { depth: o.depth, state: o.state })
    }
}

/// The source view: CPU images ([`Warper::prepare`]) or GPU-resident copies
/// ([`Warper::prepare_gpu`], held in [`GpuKernels::layers`]).
enum Source {
    Cpu { camera: Camera, depth: Vec<Image<f32>>, items: Option<Vec<Image<u32>>> },
    Gpu { camera: Camera, items: Vec<bool> },
}

/// The buffers of one GPU-resident source layer, reused while the source size stays.
struct GpuLayerBuffers {
    size: (u32, u32),
    depth: wgpu::Buffer,
    items: wgpu::Buffer,
    motion: wgpu::Buffer,
}

/// The GPU kernels of a [`Backend::Gpu`] warper and the buffers of its GPU-resident source.
struct GpuKernels {
    ctx: GpuContext,
    warp: zwarp_warp::gpu::WarpKernel,
    fill: zwarp_warp::gpu::HoleFillKernel,
    motion: zwarp_warp::gpu::MotionKernel,
    source: zwarp_warp::gpu::SourceKernel,
    layers: Vec<GpuLayerBuffers>,
}

impl GpuKernels {
    /// Buffers for `n` source layers of `w x h` samples.
    fn layer_buffers(&self, n: usize, w: u32, h: u32) -> Result<Vec<GpuLayerBuffers>> {
        let samples = w as u64 * h as u64;
        self.ctx.check_storage_size(samples * 12, "source motion")?;
        let buffer = |label, bytes| {
            self.ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            })
        };
        Ok((0..n)
            .map(|_| GpuLayerBuffers {
                size: (w, h),
                depth: buffer("zwarp source depth", samples * 4),
                items: buffer("zwarp source items", samples * 4),
                motion: buffer("zwarp source motion", samples * 12),
            })
            .collect())
    }
}

/// Predicts target views from one prepared source view. Keeps its buffers between calls (an
/// engine's steady state: one allocation, then reuse).
pub struct Warper {
    params: WarpParams,
    gpu: Option<GpuKernels>,
    source: Option<Source>,
    recycled: Vec<PreparedLayer>,
    /// The CPU path's motion buffers, one per layer, reused by the next prediction.
    motions: Vec<Image<Motion>>,
    prediction: Option<Prediction>,
    gpu_prediction: Option<GpuPrediction>,
}

impl Warper {
    /// The parameters `zwarp eval` uses by default: [`WarpParams::default`] with the hole
    /// protocol of Sec. 4 (`HolePolicy::Background` with a 64-pixel radius).
    pub fn default_params() -> WarpParams {
        WarpParams { holes: HolePolicy::PAPER, ..WarpParams::default() }
    }

    /// A warper on `backend` with `params` (checked: a one-line [`Error::Invalid`] for bad
    /// values or, on the GPU, for what the GPU twin does not compute, e.g. `record_source`).
    pub fn new(backend: Backend, params: WarpParams) -> Result<Self> {
        params.validate()?;
        let gpu = match backend {
            Backend::Cpu => None,
            Backend::Gpu(ctx) => {
                zwarp_warp::gpu::WarpKernel::check_params(&params)?;
                Some(GpuKernels {
                    warp: zwarp_warp::gpu::WarpKernel::new(&ctx)?,
                    fill: zwarp_warp::gpu::HoleFillKernel::new(&ctx)?,
                    motion: zwarp_warp::gpu::MotionKernel::new(&ctx)?,
                    source: zwarp_warp::gpu::SourceKernel::new(&ctx)?,
                    layers: Vec::new(),
                    ctx,
                })
            }
        };
        Ok(Warper {
            params,
            gpu,
            source: None,
            recycled: Vec::new(),
            motions: Vec::new(),
            prediction: None,
            gpu_prediction: None,
        })
    }

    /// The parameters of this warper.
    pub fn params(&self) -> &WarpParams {
        &self.params
    }

    /// The GPU context of a [`Backend::Gpu`] warper (`None` on the CPU).
    pub fn gpu_context(&self) -> Option<&GpuContext> {
        self.gpu.as_ref().map(|g| &g.ctx)
    }

    /// Sets the source view: its camera, its peeled depth layers (nearest first, `1.0` =
    /// empty; a last layer may hold the ground alone, Sec. 3.4, with `WarpParams::ground_layer`
    /// set) and optionally the item (object id) buffer of each layer, which moving objects need
    /// (see [`Warper::warp_to`]). The buffers are copied into the warper's own (reused while
    /// the layers keep their number and size).
    pub fn prepare(&mut self, camera: &Camera, layers: &[Image<f32>], items: Option<&[Image<u32>]>) -> Result<()> {
        let Some(first) = layers.first() else {
            return Err(Error::invalid("prepare needs at least one depth layer"));
        };
        if layers.iter().any(|l| l.size() != first.size()) {
            return Err(Error::invalid("all depth layers must have the same size"));
        }
        let m = self.params.multisample;
        if first.size() != (camera.width * m, camera.height * m) {
            return Err(Error::invalid(format!(
                "depth layers are {}x{}, the camera's image at multisample {m} is {}x{}",
                first.width(),
                first.height(),
                camera.width * m,
                camera.height * m
            )));
        }
        if let Some(items) = items {
            if items.len() != layers.len() || items.iter().any(|i| i.size() != first.size()) {
                return Err(Error::invalid("item buffers must match the depth layers in number and size"));
            }
        }
        // Into the previous source's buffers where the layers keep their number and size (an
        // engine's steady state: a copy, no fresh pages every frame).
        match &mut self.source {
            Some(Source::Cpu { camera: c, depth, items: it })
                if depth.len() == layers.len() && depth[0].size() == first.size() =>
            {
                *c = *camera;
                for (d, l) in depth.iter_mut().zip(layers) {
                    d.copy_from(l);
                }
                match (it, items) {
                    (Some(mine), Some(theirs)) => {
                        for (d, l) in mine.iter_mut().zip(theirs) {
                            d.copy_from(l);
                        }
                    }
                    (mine, theirs) => *mine = theirs.map(|i| i.to_vec()),
                }
            }
            _ => {
                self.source =
                    Some(Source::Cpu { camera: *camera, depth: layers.to_vec(), items: items.map(|i| i.to_vec()) })
            }
        }
        Ok(())
    }

    /// [`Warper::prepare`] from images that live on the GPU (a [`Backend::Gpu`] warper only):
    /// the source view's camera and its depth layers (nearest first, `1.0` = empty; a last
    /// layer may hold the ground alone, Sec. 3.4, with `WarpParams::ground_layer` set), each with
    /// its optional item image, all of
    /// the camera's size times `WarpParams::multisample` and on the warper's device. The
    /// images are copied on the GPU into the warper's buffers (reused while the size stays;
    /// the copy is submitted here, so the caller may overwrite its images afterwards);
    /// nothing is read back. Then [`Warper::warp_to_gpu`] (or [`Warper::warp_to`]) predicts.
    /// Errors ([`Error::Invalid`], one line): a CPU warper, no layer or more than
    /// [`MAX_GPU_LAYERS`], an image whose size, format, sample count or usage does not fit
    /// ([`GpuImage`]), a buffer too small for its row stride. On an error the previous source
    /// stays.
    pub fn prepare_gpu(&mut self, camera: &Camera, layers: &[GpuSourceLayer<'_>]) -> Result<()> {
        let Some(gpu) = &mut self.gpu else {
            return Err(Error::invalid(
                "prepare_gpu needs a Backend::Gpu warper (a CPU warper takes CPU images: prepare)",
            ));
        };
        if layers.is_empty() {
            return Err(Error::invalid("prepare_gpu needs at least one depth layer"));
        }
        if layers.len() > MAX_GPU_LAYERS {
            return Err(Error::invalid(format!("the GPU takes at most {MAX_GPU_LAYERS} layers, got {}", layers.len())));
        }
        let (w, h) = source_size(camera, self.params.multisample)?;
        let n = layers.len();
        let reuse = gpu.layers.len() >= n && gpu.layers.iter().all(|b| b.size == (w, h));
        let fresh = if reuse { Vec::new() } else { gpu.layer_buffers(n, w, h)? };
        let buffers = if reuse { &gpu.layers[..n] } else { &fresh[..] };
        let mut enc = gpu.ctx.device.create_command_encoder(&Default::default());
        for (k, (l, b)) in layers.iter().zip(buffers).enumerate() {
            gpu.source.encode_depth(&mut enc, &l.depth, w, h, &b.depth, &format!("layer {k} depth"))?;
            if let Some(items) = &l.items {
                gpu.source.encode_items(&mut enc, items, w, h, &b.items, &format!("layer {k} items"))?;
            }
        }
        gpu.ctx.queue.submit([enc.finish()]);
        if !reuse {
            gpu.layers = fresh;
        }
        self.source = Some(Source::Gpu { camera: *camera, items: layers.iter().map(|l| l.items.is_some()).collect() });
        Ok(())
    }

    /// [`Warper::warp_to`] without leaving the GPU (a source from [`Warper::prepare_gpu`]): the
    /// motion of every layer (Sec. 3.1), the warp (Sec. 3.2-3.4) and the hole protocol of
    /// Sec. 4 with its limits measured on the GPU, recorded into one command encoder and
    /// submitted; the result stays on the GPU ([`GpuPrediction::read`] fetches it). The
    /// pipeline is `zwarp_warp::gpu::encode_predict`, the one the CPU-image GPU path runs
    /// after its upload. Two differences from [`Warper::warp_to`] on CPU images: the motion is
    /// the GPU's (`MotionKernel`, equal to the CPU's up to float rounding), and under
    /// `BoundKind::Oriented` (the default) the bound frames are axis-aligned, i.e. the
    /// prediction is the CPU's with `BoundKind::Tight`: Sec. 3.3's PCA frame is chosen from
    /// the motion on the CPU, which this path never reads. NaN depths are not checked (as in
    /// `WarpKernel::encode`); the hole protocol's limits stay bounded whatever the input.
    /// Errors as [`Warper::warp_to`], and when the source came from [`Warper::prepare`].
    pub fn warp_to_gpu(&mut self, camera: &Camera, object_deltas: &[Mat4]) -> Result<&GpuPrediction> {
        let Some(gpu) = &self.gpu else {
            return Err(Error::invalid("warp_to_gpu needs a Backend::Gpu warper (on the CPU: warp_to)"));
        };
        let (src_camera, items) = match &self.source {
            None => return Err(Error::invalid("warp_to_gpu before prepare_gpu: no source view")),
            Some(Source::Cpu { .. }) => return Err(Error::invalid(
                "warp_to_gpu needs a GPU-resident source (prepare_gpu); a source from prepare predicts with warp_to",
            )),
            Some(Source::Gpu { camera, items }) => (camera, items),
        };
        check_target(src_camera, camera)?;
        let (cam_a, cam_b) = sampled_cameras(src_camera, camera, self.params.multisample)?;
        let (w, h) = (cam_a.width, cam_a.height);
        let mut enc = gpu.ctx.device.create_command_encoder(&Default::default());
        let buffers = &gpu.layers[..items.len()];
        for (b, &has_items) in buffers.iter().zip(items) {
            let input = MotionInput { depth: &b.depth, items: has_items.then_some(&b.items), row_stride: w };
            gpu.motion.encode(&mut enc, &input, &cam_a, &cam_b, object_deltas, &b.motion)?;
        }
        let views: Vec<GpuWarpLayer<'_>> =
            buffers.iter().map(|b| GpuWarpLayer { depth: &b.depth, motion: &b.motion, axis: Vec2::X }).collect();
        let out = zwarp_warp::gpu::encode_predict(&gpu.warp, &gpu.fill, &mut enc, &views, w, h, &self.params)?;
        gpu.ctx.queue.submit([enc.finish()]);
        Ok(self.gpu_prediction.insert(GpuPrediction { out }))
    }

    /// Predicts the depth buffer seen by `camera` (same image size as the source's camera).
    /// `object_deltas[id]` is the world-space motion `M(t_b) M(t_a)^-1` of the object with item
    /// id `id` between the two views (empty: a static scene; ids without an entry stay put).
    /// The prediction's buffers are the warper's, reused by the next call. A source from
    /// [`Warper::prepare_gpu`] is predicted by [`Warper::warp_to_gpu`] and read back.
    pub fn warp_to(&mut self, camera: &Camera, object_deltas: &[Mat4]) -> Result<&Prediction> {
        let src = match &self.source {
            None => return Err(Error::invalid("warp_to before prepare: no source view")),
            Some(Source::Gpu { .. }) => {
                let ctx = self.gpu.as_ref().map(|g| g.ctx.clone()).expect("a GPU source implies a GPU warper");
                let p = self.warp_to_gpu(camera, object_deltas)?.read(&ctx)?;
                return Ok(self.prediction.insert(p));
            }
            Some(Source::Cpu { camera, depth, items }) => (camera, depth, items),
        };
        let (src_camera, src_depth, src_items) = src;
        check_target(src_camera, camera)?;
        let (cam_a, cam_b) = sampled_cameras(src_camera, camera, self.params.multisample)?;
        self.motions.resize_with(src_depth.len(), || Image::new(0, 0, Motion::default()));
        for (k, (d, m)) in src_depth.iter().zip(self.motions.iter_mut()).enumerate() {
            zwarp_core::motion_field_into(d, src_items.as_ref().map(|i| &i[k]), &cam_a, &cam_b, object_deltas, m)?;
        }
        let layers: Vec<WarpLayer<'_>> =
            src_depth.iter().zip(&self.motions).map(|(depth, motion)| WarpLayer { depth, motion }).collect();
        let out = match &self.gpu {
            Some(k) => zwarp_warp::gpu::predict(&k.warp, &k.fill, &layers, &self.params)?,
            None => {
                let mut o = match self.prediction.take() {
                    Some(p) => WarpOutput { depth: p.depth, state: p.state, source: None, revealed: Vec::new() },
                    None => WarpOutput::empty(),
                };
                self.recycled =
                    zwarp_warp::predict_into(&layers, &self.params, std::mem::take(&mut self.recycled), &mut o)?;
                o
            }
        };
        Ok(self.prediction.insert(Prediction { depth: out.depth, state: out.state }))
    }
}

/// Errors unless `target` has the source camera's image size.
fn check_target(source: &Camera, target: &Camera) -> Result<()> {
    if (target.width, target.height) != (source.width, source.height) {
        return Err(Error::invalid(format!(
            "target camera is {}x{}, the source's {}x{}",
            target.width, target.height, source.width, source.height
        )));
    }
    Ok(())
}

/// The source size of a `camera` image at `m x m` samples per pixel.
fn source_size(camera: &Camera, m: u32) -> Result<(u32, u32)> {
    match (camera.width.checked_mul(m), camera.height.checked_mul(m)) {
        (Some(w), Some(h)) => Ok((w, h)),
        _ => Err(Error::invalid(format!("{}x{} at multisample {m} is too large", camera.width, camera.height))),
    }
}

/// Both cameras at the layers' resolution (multisampled sources).
fn sampled_cameras(a: &Camera, b: &Camera, m: u32) -> Result<(Camera, Camera)> {
    if m == 1 {
        return Ok((*a, *b));
    }
    Ok((a.with_size(a.width * m, a.height * m)?, b.with_size(b.width * m, b.height * m)?))
}
