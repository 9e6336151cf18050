//! Frame generation by colour warping (seed 001, Iterative Image Warping): the colour frame seen
//! by a new camera predicted from one rendered frame (its colour, depth and item buffers), on
//! the CPU or on a wgpu device behind the same calls — an in-between frame for frame-rate
//! upsampling, a late-latched view, the other eye.

use glam::Mat4;
use zwarp_color::gpu::ColorWarpKernel;
use zwarp_color::{
    heuristic_warp_into, robust_warp_with, ColorWarpOutput, FieldParams, HeuristicParams, RobustParams, Subdivision,
    WarpBasis,
};
use zwarp_core::{Camera, Error, Image, Result};

use crate::{check_target, Backend};

/// Which colour warp a [`FrameWarper`] runs (seed 001 Sec. 3).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ColorMethod {
    /// Sec. 3.3: one seed per pixel, T unrolled fixed-point iterations, the orbit at
    /// disocclusions picks the background. The cheap one.
    Heuristic(HeuristicParams),
    /// Sec. 3.4: the convergence term `rho`, adaptive quads rasterised with a depth test,
    /// nearest sampling across discontinuities. The accurate one, about three times the
    /// heuristic's cost.
    Robust(RobustParams),
}

impl ColorMethod {
    /// The heuristic warp with `zwarp upsample`'s defaults.
    pub fn heuristic() -> Self {
        ColorMethod::Heuristic(HeuristicParams::default())
    }

    /// The robust warp with `zwarp upsample`'s defaults.
    pub fn robust() -> Self {
        ColorMethod::Robust(RobustParams::default())
    }

    /// Errors (one line) unless the parameters are valid.
    pub fn validate(&self) -> Result<()> {
        match self {
            ColorMethod::Heuristic(p) => p.validate(),
            ColorMethod::Robust(p) => p.validate(),
        }
    }
}

/// The rendered source frame of a [`FrameWarper`].
struct FrameSource {
    camera: Camera,
    depth: Image<f32>,
    color: Image<[f32; 3]>,
    items: Option<Image<u32>>,
}

/// Predicts colour frames for new cameras from one prepared rendered frame (seed 001): the
/// motion of every source pixel to the target view (camera and objects, Sec. 2), the warp field
/// `V`, and the fixed-point solution of `x + V(x) = p` per target pixel by the chosen
/// [`ColorMethod`], with bilinear colour on surfaces and nearest across discontinuities. The
/// output carries a per-pixel confidence (`residual`, `converged_mask`) an engine can use to
/// decide where to re-render or blend. Keeps its buffers between calls.
///
/// ```
/// use zwarp::{Backend, Camera, ColorMethod, FrameWarper, Image, Vec3};
/// use zwarp::warp::synth::SynthScene;
///
/// // Two views of a small analytic city 20 cm apart; the colour is the renderer's (here: a
/// // pattern on the world position, so that the target view's truth is known).
/// let (w, h) = (96, 64);
/// let cam = |x: f32| Camera::perspective(Vec3::new(x, 8.0, 10.0), Vec3::new(x, 0.0, -4.0), Vec3::Y, 1.0, 0.5, 100.0, w, h);
/// let (a, b) = (cam(0.0)?, cam(0.2)?);
/// let scene = SynthScene::city(3);
/// let shade = |c: &Camera, depth: &Image<f32>| {
///     Image::from_fn(w, h, |x, y| {
///         let p = c.unproject(x as f32 + 0.5, y as f32 + 0.5, *depth.get(x, y));
///         let s = 0.5 + 0.5 * (0.8 * p.x).sin() * (0.8 * p.z).cos();
///         if *depth.get(x, y) < 1.0 { [s, 0.5 * s, 0.25] } else { [0.2, 0.4, 0.8] }
///     })
/// };
/// let source = scene.render(&a, 0.0, 1, false);
/// let color = shade(&a, &source.depth[0]);
///
/// let mut frames = FrameWarper::new(Backend::Cpu, ColorMethod::robust())?;
/// frames.prepare(&a, &source.depth[0], &color, Some(&source.items[0]))?;
/// let predicted = frames.warp_to(&b, &[])?; // colour, depth and confidence of view B
///
/// let truth = shade(&b, &scene.render(&b, 0.0, 1, false).depth[0]);
/// let err = |img: &Image<[f32; 3]>| img.data().iter().zip(truth.data()).map(|(p, q)| (p[0] - q[0]).abs()).sum::<f32>();
/// assert!(predicted.converged_fraction() > 0.9);
/// assert!(err(&predicted.color) < 0.4 * err(&color)); // far closer than repeating frame A
/// # Ok::<(), zwarp::Error>(())
/// ```
pub struct FrameWarper {
    method: ColorMethod,
    gpu: Option<ColorWarpKernel>,
    source: Option<FrameSource>,
    /// The warp field's basis towards the last target, its buffers reused by the next call.
    basis: WarpBasis,
    output: ColorWarpOutput,
}

impl FrameWarper {
    /// A frame warper on `backend` running `method` (checked: a one-line [`Error::Invalid`] for
    /// bad parameters).
    pub fn new(backend: Backend, method: ColorMethod) -> Result<Self> {
        method.validate()?;
        let gpu = match backend {
            Backend::Cpu => None,
            Backend::Gpu(ctx) => Some(ColorWarpKernel::new(&ctx)?),
        };
        Ok(FrameWarper { method, gpu, source: None, basis: WarpBasis::default(), output: ColorWarpOutput::empty() })
    }

    /// The colour warp this warper runs.
    pub fn method(&self) -> &ColorMethod {
        &self.method
    }

    /// Sets the source frame: its camera, depth (`[0, 1]`, `1.0` = sky), linear RGB colour
    /// and optionally its item (object id) buffer, which moving objects need (see
    /// [`FrameWarper::warp_to`]). All buffers have the camera's image size. The buffers are
    /// copied into the warper's own (reused while the size stays).
    pub fn prepare(
        &mut self,
        camera: &Camera,
        depth: &Image<f32>,
        color: &Image<[f32; 3]>,
        items: Option<&Image<u32>>,
    ) -> Result<()> {
        let size = (camera.width, camera.height);
        let mut buffers = vec![("depth", depth.size()), ("colour", color.size())];
        if let Some(i) = items {
            buffers.push(("item", i.size()));
        }
        for (what, s) in buffers {
            if s != size {
                return Err(Error::invalid(format!(
                    "{what} buffer is {}x{}, the camera's image {}x{}",
                    s.0, s.1, size.0, size.1
                )));
            }
        }
        match &mut self.source {
            Some(s) if s.depth.size() == size => {
                s.camera = *camera;
                s.depth.copy_from(depth);
                s.color.copy_from(color);
                match (&mut s.items, items) {
                    (Some(mine), Some(theirs)) => mine.copy_from(theirs),
                    (mine, theirs) => *mine = theirs.cloned(),
                }
            }
            _ => {
                self.source = Some(FrameSource {
                    camera: *camera,
                    depth: depth.clone(),
                    color: color.clone(),
                    items: items.cloned(),
                })
            }
        }
        Ok(())
    }

    /// Predicts the colour frame seen by `camera` (the source camera's image size).
    /// `object_deltas[id]` is the world-space motion `M(t_b) M(t_a)^-1` of the object with item
    /// id `id` between the two views (empty: a static scene; ids without an entry stay put). The
    /// output's buffers are the warper's, reused by the next call; on the GPU backend the warp
    /// runs in WGSL (the robust warp's subdivision on the CPU) and is read back.
    pub fn warp_to(&mut self, camera: &Camera, object_deltas: &[Mat4]) -> Result<&ColorWarpOutput> {
        let Some(src) = &self.source else {
            return Err(Error::invalid("warp_to before prepare: no source frame"));
        };
        check_target(&src.camera, camera)?;
        // The field towards the target itself: t = 1 of the exact motion (eq. 2), the motion
        // written straight into the basis' planes.
        let basis = &mut self.basis;
        basis.set_temporal_with(&src.depth, |x, y| {
            zwarp_core::motion_planes_into(&src.depth, src.items.as_ref(), &src.camera, camera, object_deltas, (x, y))
        })?;
        let field = basis.field(FieldParams::temporal(1.0))?;
        match (&self.gpu, &self.method) {
            (Some(k), ColorMethod::Heuristic(p)) => self.output = k.heuristic(&field, &src.color, p)?,
            (Some(k), ColorMethod::Robust(p)) => self.output = k.robust(&field, &src.color, p)?,
            (None, ColorMethod::Heuristic(p)) => heuristic_warp_into(&field, &src.color, p, &mut self.output)?,
            (None, ColorMethod::Robust(p)) => {
                let sub = Subdivision::of_field(&field, p.tile)?;
                robust_warp_with(&sub, &field, &src.color, p, &mut self.output)?;
            }
        }
        Ok(&self.output)
    }
}
