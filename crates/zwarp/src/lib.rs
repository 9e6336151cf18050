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
pub use zwarp_warp::{HolePolicy, PixelState, WarpParams};

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

/// The source view handed to [`Warper::prepare`].
struct Source {
    camera: Camera,
    depth: Vec<Image<f32>>,
    items: Option<Vec<Image<u32>>>,
}

/// The GPU kernels of a [`Backend::Gpu`] warper.
struct GpuKernels {
    warp: zwarp_warp::gpu::WarpKernel,
    fill: zwarp_warp::gpu::HoleFillKernel,
}

/// Predicts target views from one prepared source view. Keeps its buffers between calls (an
/// engine's steady state: one allocation, then reuse).
pub struct Warper {
    params: WarpParams,
    gpu: Option<GpuKernels>,
    source: Option<Source>,
    recycled: Vec<PreparedLayer>,
    prediction: Option<Prediction>,
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
                })
            }
        };
        Ok(Warper { params, gpu, source: None, recycled: Vec::new(), prediction: None })
    }

    /// The parameters of this warper.
    pub fn params(&self) -> &WarpParams {
        &self.params
    }

    /// Sets the source view: its camera, its peeled depth layers (nearest first, `1.0` =
    /// empty; a last layer may hold the ground alone, Sec. 3.4) and optionally the item (object
    /// id) buffer of each layer, which moving objects need (see [`Warper::warp_to`]).
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
        self.source = Some(Source { camera: *camera, depth: layers.to_vec(), items: items.map(|i| i.to_vec()) });
        Ok(())
    }

    /// Predicts the depth buffer seen by `camera` (same image size as the source's camera).
    /// `object_deltas[id]` is the world-space motion `M(t_b) M(t_a)^-1` of the object with item
    /// id `id` between the two views (empty: a static scene; ids without an entry stay put).
    /// The prediction's buffers are the warper's, reused by the next call.
    pub fn warp_to(&mut self, camera: &Camera, object_deltas: &[Mat4]) -> Result<&Prediction> {
        let Some(src) = &self.source else {
            return Err(Error::invalid("warp_to before prepare: no source view"));
        };
        if (camera.width, camera.height) != (src.camera.width, src.camera.height) {
            return Err(Error::invalid(format!(
                "target camera is {}x{}, the source's {}x{}",
                camera.width, camera.height, src.camera.width, src.camera.height
            )));
        }
        // The source's camera at the layers' resolution (multisampled sources).
        let m = self.params.multisample;
        let (cam_a, cam_b) = if m == 1 {
            (src.camera, *camera)
        } else {
            (
                src.camera.with_size(src.camera.width * m, src.camera.height * m)?,
                camera.with_size(camera.width * m, camera.height * m)?,
            )
        };
        let motions: Vec<Image<Motion>> = src
            .depth
            .iter()
            .enumerate()
            .map(|(k, d)| zwarp_core::motion_field(d, src.items.as_ref().map(|i| &i[k]), &cam_a, &cam_b, object_deltas))
            .collect::<Result<_>>()?;
        let layers: Vec<WarpLayer<'_>> =
            src.depth.iter().zip(&motions).map(|(depth, motion)| WarpLayer { depth, motion }).collect();
        let out = match &self.gpu {
            Some(k) => zwarp_warp::gpu::predict(&k.warp, &k.fill, &layers, &self.params)?,
            None => {
                let mut o = match self.prediction.take() {
                    Some(p) => WarpOutput { depth: p.depth, state: p.state, source: None },
                    None => WarpOutput {
                        depth: Image::new(0, 0, 1.0),
                        state: Image::new(0, 0, PixelState::Hole),
                        source: None,
                    },
                };
                self.recycled =
                    zwarp_warp::predict_into(&layers, &self.params, std::mem::take(&mut self.recycled), &mut o)?;
                o
            }
        };
        Ok(self.prediction.insert(Prediction { depth: out.depth, state: out.state }))
    }
}
