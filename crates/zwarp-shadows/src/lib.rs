//! zwarp-shadows: soft shadows from warped shadow maps (Lee, Kim, Eisemann, TOG 2018 — seed 000,
//! Sec. 6, Fig. 15, Table 8) with the reference and a PCSS baseline.
//!
//! An area light ([`zwarp_core::AreaLight`], rectangle or disc; local = perspective maps,
//! directional = orthographic maps) is sampled at S stratified points ([`light_samples`]). The
//! visibility of a camera pixel is the fraction of the S sample shadow maps that see its surface
//! point; the three methods differ only in where those maps come from:
//!
//! - [`Method::Reference`]: every sample map is rasterized directly (`zwarp_raster::render_depth`),
//!   the cost grows linearly with S;
//! - [`Method::Zwarp`]: the centre map is depth-peeled once into L layers with generalized umbra
//!   culling (Sec. 3.4, eq. (1), sized from the emitter) and the ground as the last layer, then
//!   warped to every sample view by multi-layer backward warping (Sec. 3.2-3.4, N = 4 seeds) —
//!   only at the texels the receivers look up ([`lookups`]), with one motion mipmap for all
//!   samples (every sample's parallax is a per-axis multiple of one reference field,
//!   [`ZwarpMaps`]); where many camera pixels share a texel, receivers are tested in groups
//!   that read the same one or two texels per axis ([`ReceiverGroups`], same visibility bit
//!   for bit); [`Method::ZwarpFull`] warps every texel of every map with per-sample
//!   mipmaps (the path before, same maps where looked up);
//! - [`Method::Pcss`]: Fernando 2005, filtering of the single centre map (no per-sample maps).
//!
//! All sample cameras share the centre camera's orientation, so centre -> sample is a pure
//! parallax ([`light`]); the motion comes from `zwarp_core::motion_field` with the two light
//! cameras. Shading is one function for all methods ([`Receivers::shade`]). The reference and
//! zwarp methods also run on a wgpu device: module `gpu` (feature `gpu`).
//!
//! Conventions (ARCHITECTURE.md "Conventions"): depth in `[0, 1]`, 1 = empty; pixel centres at
//! `+0.5`; row 0 on top.

#![deny(missing_docs)]
pub mod eval;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod light;
pub mod lookups;
pub mod pcss;
pub mod shade;

use std::time::Instant;

use glam::Vec2;
use rayon::prelude::*;
use zwarp_core::{AreaLight, Camera, Error, Image, Motion, Result, Scene};
use zwarp_raster::{render_depth, render_frame, render_layers, FrameOptions, Layer, PeelOptions};
use zwarp_warp::{
    warp_pixels, warp_prepared, BoundKind, HolePolicy, MotionScales, PreparedLayer, WarpLayer, WarpOutput, WarpParams,
};

pub use eval::{evaluate, evaluate_with, EvalConfig, EvalRow};
pub use light::{
    default_light, light_from_json_str, light_from_json_str_at, light_samples, light_to_json, load_light,
    load_light_at, validate_light, LightRig, MAX_SAMPLES,
};
pub use lookups::{GroupCounts, HotReceivers, ReceiverGroups, SparseMap, TexelSet};
pub use pcss::{pcss_visibility, PcssParams};
pub use shade::{reconstruct_normals, texel_at, texel_of, texel_xy, DepthBias, Receiver, Receivers, OFF_MAP};

/// How the sample shadow maps (and so the visibility) are obtained.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Method {
    /// S shadow maps rasterized directly (the reference of seed 000, Table 8).
    Reference,
    /// S shadow maps synthesized by multi-layer depth warping of the peeled centre map (Sec. 6),
    /// each warped only at the texels the receivers look up ([`lookups`]).
    Zwarp,
    /// As [`Method::Zwarp`], but every sample map is warped in full (all texels of all L
    /// layers): the path before the lazy synthesis, kept for comparison and for looking at the
    /// synthesized maps.
    ZwarpFull,
    /// Percentage-closer soft shadows from the centre map (Fernando 2005).
    Pcss,
}

impl Method {
    /// Lower-case name (`reference`, `zwarp`, `pcss`).
    pub fn name(&self) -> &'static str {
        match self {
            Method::Reference => "reference",
            Method::Zwarp => "zwarp",
            Method::ZwarpFull => "zwarp-full",
            Method::Pcss => "pcss",
        }
    }
}

impl std::str::FromStr for Method {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "reference" | "ref" => Ok(Method::Reference),
            "zwarp" | "warp" => Ok(Method::Zwarp),
            "zwarp-full" | "zwarp_full" | "full" => Ok(Method::ZwarpFull),
            "pcss" => Ok(Method::Pcss),
            other => {
                Err(Error::invalid(format!("unknown shadow method '{other}' (reference, zwarp, zwarp-full, pcss)")))
            }
        }
    }
}

/// Parameters of [`run_shadows`] (names follow seed 000).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadowParams {
    /// S: number of light samples (1..=[`MAX_SAMPLES`]; 1 = the emitter centre, a hard shadow).
    pub samples: u32,
    /// Shadow-map resolution (square).
    pub sm_size: u32,
    /// L: depth layers of the zwarp method, the ground layer included (Sec. 6 uses L = 3, one for
    /// the ground). Scenes without ground instances peel all L layers from the objects.
    pub layers: usize,
    /// N: search seeds of the warp (Sec. 6 uses N = 4).
    pub n_seeds: u32,
    /// T: fixed-point iterations per seed.
    pub iterations: u32,
    /// Convergence threshold of the fixed-point search (pixels). A converged `q` may be this far
    /// from the exact solution, which grows silhouettes by up to that much; shadow maps want it
    /// tighter than the warp crate's 0.5 px default.
    pub threshold: f32,
    /// Hole policy of the warp.
    pub holes: HolePolicy,
    /// Generalized umbra culling while peeling (Sec. 3.4).
    pub umbra: bool,
    /// Motion of each sample view as the scaled parallax field (one `motion_field` per layer,
    /// see [`ZwarpMaps`]) instead of one `motion_field` per layer and sample (per-sample
    /// mipmaps only; the shared mipmap always uses the reference field).
    pub parallax_motion: bool,
    /// One motion mipmap for all samples ([`ZwarpMaps`]): each layer is prepared once from the
    /// reference parallax field with axis-aligned tight bounds, and sample `i` is warped with
    /// `WarpParams::motion_scale = K_i / K_ref`. Otherwise every sample gets its own scaled
    /// motion buffers and mipmaps (oriented bounds). [`Method::ZwarpFull`] always uses the
    /// latter (the path before the lazy synthesis).
    pub shared_mipmap: bool,
    /// Depth bias of the shadow test.
    pub bias: DepthBias,
    /// Seed of the sample jitter.
    pub seed: u64,
    /// Jitter the stratified samples (else stratum centres).
    pub jitter: bool,
    /// Ambient term of the shading.
    pub ambient: f32,
    /// PCSS settings.
    pub pcss: PcssParams,
    /// Whether the lazy synthesis tests groups of receivers ([`ReceiverGroups`]) instead of
    /// single receivers (same visibility, bit for bit; [`Method::Zwarp`] with the shared mipmap).
    pub grouping: Grouping,
}

/// How [`Method::Zwarp`] tests the receivers against the lazily synthesized maps (same
/// visibility either way; only the cost differs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Grouping {
    /// [`ReceiverGroups`] when they pay ([`use_groups`]).
    #[default]
    Auto,
    /// Always one test per receiver and sample.
    Never,
    /// Always [`ReceiverGroups`].
    Always,
}

impl Default for ShadowParams {
    /// S = 16, 1024 maps, L = 3 (ground last), N = 4, T = 3, dilation of radius 2 for holes (a
    /// far-depth hole would be a light leak: a missing occluder; the few holes of a parallax
    /// warp are thin cracks at depth edges that the neighbours fill correctly), umbra culling
    /// on, default bias, jittered samples, ambient 0.25 (the renderer's).
    fn default() -> Self {
        ShadowParams {
            samples: 16,
            sm_size: 1024,
            layers: 3,
            n_seeds: 4,
            iterations: 3,
            threshold: 0.25,
            holes: HolePolicy::Dilate { radius: 2 },
            umbra: true,
            parallax_motion: true,
            shared_mipmap: true,
            bias: DepthBias::default(),
            seed: 1,
            jitter: true,
            ambient: zwarp_raster::shading::AMBIENT,
            pcss: PcssParams::default(),
            grouping: Grouping::Auto,
        }
    }
}

impl ShadowParams {
    /// Checks the parameters (one-line errors).
    pub fn validate(&self) -> Result<()> {
        if self.samples == 0 || self.samples > MAX_SAMPLES {
            return Err(Error::invalid(format!("S must be in 1..={MAX_SAMPLES}, got {}", self.samples)));
        }
        if self.sm_size == 0 || self.sm_size > 16384 {
            return Err(Error::invalid(format!("shadow-map size must be in 1..=16384, got {}", self.sm_size)));
        }
        if self.layers == 0 || self.layers > 16 {
            return Err(Error::invalid(format!("L must be in 1..=16, got {}", self.layers)));
        }
        if !(self.ambient.is_finite() && (0.0..=1.0).contains(&self.ambient)) {
            return Err(Error::invalid(format!("ambient must be in [0, 1], got {}", self.ambient)));
        }
        self.warp_params().validate()
    }

    /// The warp parameters used for the zwarp maps: N, T and holes from here, the rest the warp
    /// crate's defaults (oriented tight bounds — the parallax motion of one sample is parallel
    /// everywhere, so the PCA frame is a thin strip — cross-layer seeding on).
    pub fn warp_params(&self) -> WarpParams {
        WarpParams {
            n_seeds: self.n_seeds,
            iterations: self.iterations,
            threshold: self.threshold,
            holes: self.holes,
            ..WarpParams::default()
        }
    }
}

/// Per-stage wall-clock times of one [`run_shadows`] call (ms).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StageTimings {
    /// Camera frame (depth + items) and receiver set-up (normals, light-space coordinates).
    pub camera: f64,
    /// Shadow-map rendering: S rasterized maps (reference), the peeled centre layers (zwarp) or
    /// the one centre map (PCSS).
    pub render: f64,
    /// Motion buffers centre -> sample (zwarp; 0 with the shared mipmap, whose preparation
    /// evaluates the rig's parallax itself).
    pub motion: f64,
    /// Motion mipmaps (`PreparedLayer`: once with the shared mipmap, from the parallax field,
    /// per sample otherwise).
    pub mipmap: f64,
    /// Warps (zwarp): the full maps, or the looked-up texels and hole neighbours.
    pub warp: f64,
    /// Visibility tests (accumulation over the maps, or the PCSS filter).
    pub visibility: f64,
    /// Shading.
    pub shade: f64,
}

/// Output of [`run_shadows`].
#[derive(Clone, Debug)]
pub struct ShadowResult {
    /// Shaded camera image (linear RGB).
    pub image: Image<[f32; 3]>,
    /// Visibility per camera pixel in `[0, 1]` (1 where the pixel shows no surface).
    pub visibility: Image<f32>,
    /// Total frame time (ms).
    pub ms: f64,
    /// Per-stage times.
    pub timings: StageTimings,
    /// Pixels of all warped maps without a converged sample after the hole policy, summed over
    /// the S maps (zwarp only; includes texels where the light sees no surface at all; the lazy
    /// synthesis counts only looked-up texels).
    pub warp_holes: usize,
    /// Texels warped, summed over the S maps (zwarp: `S * sm^2` for the full maps; the looked-up
    /// texels plus the hole neighbours the dilation needed for the lazy synthesis).
    pub warped_texels: usize,
}

fn ms_since(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Renders sample map `i` of `rig` directly (the reference path).
pub fn render_sample_map(scene: &Scene, rig: &LightRig, t: f32, i: usize) -> Result<Image<f32>> {
    let cam = rig.cameras.get(i).ok_or_else(|| Error::invalid(format!("no light sample {i}")))?;
    render_depth(scene, cam, t)
}

/// `WarpParams::ground_layer` of the kept (non-empty) layers: the ground was peeled alone as
/// the last layer, it covers texels, and object layers were kept in front of it (CPU and GPU).
pub(crate) fn ground_layer_kept(ground_separate: bool, ground_covered: bool, kept: usize) -> bool {
    ground_separate && ground_covered && kept > 1
}

/// The peeling options of the zwarp method: L layers with the ground as the last one when the
/// scene has ground instances (else L object layers), umbra culling sized from the emitter.
pub fn peel_options(scene: &Scene, rig: &LightRig, params: &ShadowParams) -> PeelOptions {
    let has_ground = scene.instances.iter().any(|i| i.is_ground);
    let umbra = params.umbra.then(|| rig.umbra());
    if has_ground && params.layers >= 2 {
        PeelOptions { layers: params.layers - 1, ground_separate: true, umbra }
    } else {
        PeelOptions { layers: params.layers, ground_separate: false, umbra }
    }
}

/// The deep depth buffer of the centre light view and the warps to the sample views (seed 000,
/// Sec. 6: "we efficiently synthesize these shadow maps").
///
/// **Motion.** The motion of a layer to sample view `i` is `zwarp_core::motion_field` from the
/// centre camera to sample camera `i`. Because every sample view is a pure parallax of the centre
/// view ([`light`]), that field is exactly linear in the emitter offset: `v_i(q) = K_i g(q)`.
/// With [`ShadowParams::parallax_motion`] (default) the field towards a reference offset `o_ref`
/// is computed **once per layer** — in closed form with the shared mipmap
/// ([`LightRig::parallax`]: `K_ref g(z)` from the stored depth, no unproject + project,
/// evaluated inside the preparation's pass by `PreparedLayer::new_parallax`, so no motion
/// buffer is written), else with `motion_field` — and each sample's field is that field scaled per axis by
/// `K_i / K_ref`; without it, `motion_field` runs per layer and sample. A test checks they
/// agree to 1e-3 px.
///
/// **One mipmap for all samples** ([`ShadowParams::shared_mipmap`], default). Scaling a field
/// per axis scales its per-axis min-max bounds alike, so the min-max motion mipmap of the
/// reference field, built once per layer, bounds every sample's field once its look-ups are
/// scaled by `K_i / K_ref` (`WarpParams::motion_scale`; exact only in the axis-aligned frame,
/// hence [`BoundKind::Tight`] there). The per-sample cost is then only the fixed-point searches
/// — at the looked-up texels ([`ZwarpMaps::warp_sparse`]). `K_ref` has no zero component: the
/// reference offset is `(e, e)`, `e` = the emitter's half diagonal (1 for a point emitter).
/// A test checks it equals warping the explicitly scaled buffers with their own AAB mipmaps,
/// bit for bit.
pub struct ZwarpMaps<'a> {
    rig: &'a LightRig,
    layers: Vec<Layer>,
    /// Per layer: motion to the reference offset camera (parallax mode without the shared
    /// mipmap; empty otherwise).
    reference: Vec<Image<Motion>>,
    /// Per layer: the reference field prepared once (shared mipmap), else empty.
    shared: Vec<PreparedLayer>,
    k_ref: Vec2,
    params: WarpParams,
    /// Accumulated time of the motion buffers (ms; none with the shared mipmap).
    pub motion_ms: f64,
    /// Accumulated time of the motion mipmaps (`PreparedLayer::new`, or `new_parallax` for the
    /// shared one, which includes its field, ms).
    pub mipmap_ms: f64,
    /// Accumulated time of the warps (ms).
    pub warp_ms: f64,
}

impl<'a> ZwarpMaps<'a> {
    /// Peels the centre map of `rig` (see [`peel_options`]); empty layers are dropped (nothing to
    /// warp from them). When the ground layer is kept behind kept object layers, the warps apply
    /// `WarpParams::ground_layer` (seed 000 Sec. 3.4: the ground peeled alone, last).
    pub fn new(scene: &Scene, rig: &'a LightRig, t: f32, params: &ShadowParams) -> Result<Self> {
        params.validate()?;
        let peel = peel_options(scene, rig, params);
        let layers = render_layers(scene, &rig.center, t, &peel)?;
        let ground_covered = layers.last().is_some_and(|g| g.coverage() > 0);
        let mut layers: Vec<Layer> = layers.into_iter().filter(|l| l.coverage() > 0).collect();
        let ground_layer = ground_layer_kept(peel.ground_separate, ground_covered, layers.len());
        if layers.is_empty() {
            // Nothing in front of the light at all: keep one empty layer so warps still give maps.
            layers.push(Layer {
                depth: Image::new(rig.center.width, rig.center.height, 1.0),
                items: Image::new(rig.center.width, rig.center.height, zwarp_core::NO_ITEM),
            });
        }
        let mut maps = ZwarpMaps {
            rig,
            layers,
            reference: Vec::new(),
            shared: Vec::new(),
            k_ref: Vec2::ZERO,
            params: WarpParams { ground_layer, ..params.warp_params() },
            motion_ms: 0.0,
            mipmap_ms: 0.0,
            warp_ms: 0.0,
        };
        if params.parallax_motion || params.shared_mipmap {
            let m = rig.max_offset();
            let (cam_ref, k_ref) = rig.offset_camera(Vec2::splat(if m > 0.0 { m } else { 1.0 }));
            maps.k_ref = k_ref;
            if params.shared_mipmap {
                // The reference field is the rig's parallax, a function of the depth alone: the
                // preparation evaluates it in its pass, no motion buffer is written (its time is
                // in `mipmap_ms`).
                let t0 = Instant::now();
                let field = rig.parallax(k_ref);
                maps.shared = maps
                    .layers
                    .iter()
                    .map(|l| {
                        rig.check_map(&l.depth)?;
                        PreparedLayer::new_parallax(&l.depth, &field, BoundKind::Tight, MotionScales::Any)
                    })
                    .collect::<Result<Vec<_>>>()?;
                maps.mipmap_ms += ms_since(t0);
            } else {
                // The path before the shared mipmap, kept as it was measured: motion_field.
                let t0 = Instant::now();
                maps.reference = maps
                    .layers
                    .iter()
                    .map(|l| zwarp_core::motion_field(&l.depth, Some(&l.items), &rig.center, &cam_ref, &[]))
                    .collect::<Result<Vec<_>>>()?;
                maps.motion_ms += ms_since(t0);
            }
        }
        Ok(maps)
    }

    /// The peeled layers (nearest first, ground last).
    pub fn layers(&self) -> &[Layer] {
        &self.layers
    }

    /// Motion buffers of every layer to sample view `i` (see the type docs): the reference
    /// field scaled by `K_i / K_ref` (with the shared mipmap the rig's parallax field, built
    /// here), or `motion_field` to the sample's camera.
    pub fn motions(&self, i: usize) -> Result<Vec<Image<Motion>>> {
        let cam = self.rig.cameras.get(i).ok_or_else(|| Error::invalid(format!("no light sample {i}")))?;
        if self.reference.is_empty() && !self.shares_mipmap() {
            return self
                .layers
                .iter()
                .map(|l| zwarp_core::motion_field(&l.depth, Some(&l.items), &self.rig.center, cam, &[]))
                .collect();
        }
        let ratio = self.rig.shifts[i] / self.k_ref;
        let scaled = |m: &Image<Motion>| {
            let data: Vec<Motion> = m.data().par_iter().map(|s| Motion { v: s.v * ratio, depth: s.depth }).collect();
            Image::from_vec(m.width(), m.height(), data)
        };
        if self.shares_mipmap() {
            return self.layers.iter().map(|l| scaled(&self.rig.parallax_field(&l.depth, self.k_ref)?)).collect();
        }
        self.reference.iter().map(scaled).collect()
    }

    /// The layers of sample view `i` ready to warp: its motion buffers ([`ZwarpMaps::motions`])
    /// and their mipmaps (`PreparedLayer::new` with the warp's bound kind).
    pub fn prepared(&mut self, i: usize) -> Result<Vec<PreparedLayer>> {
        let t0 = Instant::now();
        let motions = self.motions(i)?;
        self.motion_ms += ms_since(t0);
        let t1 = Instant::now();
        let prepared = self
            .layers
            .iter()
            .zip(&motions)
            .map(|(l, m)| PreparedLayer::new(&WarpLayer { depth: &l.depth, motion: m }, self.params.bound))
            .collect::<Result<Vec<_>>>()?;
        self.mipmap_ms += ms_since(t1);
        Ok(prepared)
    }

    /// Whether the layers are prepared once for all samples ([`ShadowParams::shared_mipmap`]).
    pub fn shares_mipmap(&self) -> bool {
        !self.shared.is_empty()
    }

    /// The warp parameters of sample view `i`: with the shared mipmap, axis-aligned tight
    /// bounds and `motion_scale = K_i / K_ref`; otherwise the maps' own parameters.
    pub fn sample_params(&self, i: usize) -> Result<WarpParams> {
        let shift = *self.rig.shifts.get(i).ok_or_else(|| Error::invalid(format!("no light sample {i}")))?;
        if self.shared.is_empty() {
            return Ok(self.params);
        }
        Ok(WarpParams { bound: BoundKind::Tight, motion_scale: shift / self.k_ref, ..self.params })
    }

    /// Warps the layers to sample view `i` (`zwarp_warp::warp_prepared`): the full map.
    pub fn map(&mut self, i: usize) -> Result<WarpOutput> {
        let params = self.sample_params(i)?;
        if self.shares_mipmap() {
            let t1 = Instant::now();
            let out = warp_prepared(&self.shared, &params)?;
            self.warp_ms += ms_since(t1);
            return Ok(out);
        }
        let prepared = self.prepared(i)?;
        let t1 = Instant::now();
        let out = warp_prepared(&prepared, &params)?;
        self.warp_ms += ms_since(t1);
        Ok(out)
    }

    /// Warps the layers to sample view `i` at the texels `sparse` collected
    /// ([`SparseMap::collect`]) with `zwarp_warp::warp_pixels`, then applies the hole policy
    /// there ([`SparseMap::dilate`] for the dilation). The depth at those texels equals
    /// [`ZwarpMaps::map`]`(i)` bit for bit.
    pub fn warp_sparse(&mut self, i: usize, sparse: &mut SparseMap) -> Result<()> {
        if self.shares_mipmap() {
            let t1 = Instant::now();
            let r = self.warp_sparse_shared(i, sparse);
            self.warp_ms += ms_since(t1);
            return r;
        }
        let params = self.sample_params(i)?;
        let prepared = self.prepared(i)?;
        let t1 = Instant::now();
        let r = sparse_warp(&prepared, &params, sparse);
        self.warp_ms += ms_since(t1);
        r
    }
}

impl ZwarpMaps<'_> {
    /// [`ZwarpMaps::warp_sparse`] with the shared mipmap, through a shared reference (nothing
    /// is prepared per sample), so several samples can be warped concurrently; not timed.
    /// Errors without the shared mipmap ([`ShadowParams::shared_mipmap`]).
    pub fn warp_sparse_shared(&self, i: usize, sparse: &mut SparseMap) -> Result<()> {
        if !self.shares_mipmap() {
            return Err(Error::invalid("warp_sparse_shared needs the shared mipmap (ShadowParams::shared_mipmap)"));
        }
        sparse_warp(&self.shared, &self.sample_params(i)?, sparse)
    }
}

/// Per-thread outcome of the parallel lazy synthesis in [`run_shadows`].
struct ThreadOut {
    lit: Vec<u32>,
    /// Lit counts of the grouped receivers ([`ReceiverGroups`]), `None` on the per-receiver
    /// path.
    counts: Option<GroupCounts>,
    holes: usize,
    warped: usize,
    warp_ms: f64,
    vis_ms: f64,
}

/// Whether the lazy synthesis should test [`ReceiverGroups`] instead of single receivers
/// ([`Grouping::Auto`]): when S >= [`GROUP_MIN_SAMPLES`] and the receivers read at least
/// [`GROUP_MIN_DENSITY`] receivers per texel of the centre map on average (counted once, at
/// the centre), i.e. when the group tests replace many receiver tests per texel. Below that the
/// groups hold about one receiver each and only add their look-up boxes to the warp.
pub fn use_groups(grouping: Grouping, hot: &HotReceivers, rig: &LightRig) -> bool {
    match grouping {
        Grouping::Never => false,
        Grouping::Always => true,
        Grouping::Auto => {
            if rig.samples() < GROUP_MIN_SAMPLES as usize || hot.is_empty() {
                return false;
            }
            let mut set = SparseMap::new(rig.center.width, rig.center.height);
            let texels = set.collect(hot, Vec2::ZERO).max(1);
            hot.len() as f64 / texels as f64 >= GROUP_MIN_DENSITY
        }
    }
}

/// Smallest S at which [`Grouping::Auto`] groups the receivers (the grouping sorts them once).
pub const GROUP_MIN_SAMPLES: u32 = 8;

/// Smallest mean number of receivers per looked-up centre-map texel at which
/// [`Grouping::Auto`] groups the receivers (a group covers a quarter texel).
pub const GROUP_MIN_DENSITY: f64 = 16.0;

/// The lazy synthesis with the shared mipmap over all samples (seed 000, Sec. 6): the samples
/// are split into one interleaved set per worker thread, each with its own [`SparseMap`] and
/// lit counts (summed at the end, so the result does not depend on the split). The serial
/// parts of a sample (texel set, scatter, dilation bookkeeping) then overlap with the other
/// thread's warps. With `groups` the receivers are tested per [`ReceiverGroups`] group (same
/// counts). Stage times are per-thread times divided by the number of threads.
fn lazy_shared(
    maps: &ZwarpMaps<'_>,
    rig: &LightRig,
    hot: &HotReceivers,
    groups: Option<&ReceiverGroups>,
    lit: &mut [u32],
    tm: &mut StageTimings,
) -> Result<(usize, usize)> {
    let s = rig.samples();
    let threads = rayon::current_num_threads().clamp(1, s.max(1));
    let outs: Vec<Result<ThreadOut>> = (0..threads)
        .into_par_iter()
        .map(|g| {
            let mut sparse = SparseMap::new(rig.center.width, rig.center.height);
            let mut out = ThreadOut {
                lit: if groups.is_some() { Vec::new() } else { vec![0u32; hot.len()] },
                counts: groups.map(GroupCounts::new),
                holes: 0,
                warped: 0,
                warp_ms: 0.0,
                vis_ms: 0.0,
            };
            for i in (g..s).step_by(threads) {
                let shift = rig.shifts[i];
                let t0 = Instant::now();
                match groups {
                    Some(gr) => sparse.collect_groups(gr, shift),
                    None => sparse.collect(hot, shift),
                };
                out.vis_ms += ms_since(t0);
                let t1 = Instant::now();
                maps.warp_sparse_shared(i, &mut sparse)?;
                out.warp_ms += ms_since(t1);
                out.holes += sparse.holes();
                out.warped += sparse.warped();
                let t2 = Instant::now();
                match (groups, out.counts.as_mut()) {
                    (Some(gr), Some(c)) => {
                        sparse.accumulate_groups(gr, shift, c);
                    }
                    _ => sparse.accumulate(hot, &mut out.lit),
                }
                out.vis_ms += ms_since(t2);
            }
            Ok(out)
        })
        .collect();
    let (mut holes, mut warped) = (0, 0);
    let mut counts: Option<GroupCounts> = None;
    for out in outs {
        let out = out?;
        match (&mut counts, out.counts) {
            (Some(c), Some(o)) => c.add(&o),
            (c @ None, Some(o)) => *c = Some(o),
            _ => lit.iter_mut().zip(&out.lit).for_each(|(a, b)| *a += b),
        }
        holes += out.holes;
        warped += out.warped;
        tm.warp += out.warp_ms / threads as f64;
        tm.visibility += out.vis_ms / threads as f64;
    }
    if let (Some(gr), Some(c)) = (groups, &counts) {
        let t = Instant::now();
        gr.lit_counts(c, s as u32, lit);
        tm.visibility += ms_since(t);
    }
    Ok((holes, warped))
}

/// `warp_pixels` at the texels of `sparse` plus the hole policy (the dilation needs the
/// neighbours of holes, warped on demand; the other policies are per pixel).
fn sparse_warp(layers: &[PreparedLayer], params: &WarpParams, sparse: &mut SparseMap) -> Result<()> {
    if sparse.texels().is_empty() {
        return Ok(());
    }
    let radius = match params.holes {
        HolePolicy::Dilate { radius } => Some(radius),
        _ => None,
    };
    let per_pixel = WarpParams { holes: if radius.is_some() { HolePolicy::FarDepth } else { params.holes }, ..*params };
    let values = warp_pixels(layers, &per_pixel, sparse.texels())?;
    sparse.scatter_looked_up(&values);
    if let Some(r) = radius {
        sparse.dilate(r, |extra| warp_pixels(layers, &per_pixel, extra))?;
    }
    Ok(())
}

/// Soft shadows of `scene` at time `t` seen by `cam`, lit by `light` (seed 000, Sec. 6).
///
/// Renders the camera frame, builds the light rig (S samples, `sm_size` maps), obtains the
/// visibility with `method` and shades. Every stage is timed ([`StageTimings`]); `ms` is the
/// whole call. Errors: invalid parameters or light, empty scene, unusable camera.
pub fn run_shadows(
    scene: &Scene,
    cam: &Camera,
    t: f32,
    light: &AreaLight,
    method: Method,
    params: &ShadowParams,
) -> Result<ShadowResult> {
    params.validate()?;
    if !t.is_finite() {
        return Err(Error::invalid(format!("frame time must be finite, got {t}")));
    }
    let start = Instant::now();
    let mut tm = StageTimings::default();

    let t0 = Instant::now();
    let samples = if method == Method::Pcss { 1 } else { params.samples };
    let rig = LightRig::new(scene, t, light, samples, params.sm_size, params.seed, params.jitter)?;
    let frame = render_frame(scene, cam, t, &FrameOptions::default())?;
    let recv = Receivers::build(&frame, cam, scene, &rig, &params.bias)?;
    tm.camera = ms_since(t0);

    let mut lit = vec![0u32; recv.list.len()];
    let mut warp_holes = 0usize;
    let mut warped_texels = 0usize;
    let visibility = match method {
        Method::Reference => {
            for i in 0..rig.samples() {
                let t1 = Instant::now();
                let map = render_sample_map(scene, &rig, t, i)?;
                tm.render += ms_since(t1);
                let t2 = Instant::now();
                recv.accumulate(&map, rig.shifts[i], &mut lit);
                tm.visibility += ms_since(t2);
            }
            recv.visibility_image(&lit, rig.samples() as u32)
        }
        Method::Zwarp => {
            let t1 = Instant::now();
            let mut maps = ZwarpMaps::new(scene, &rig, t, params)?;
            tm.render = ms_since(t1) - maps.motion_ms - maps.mipmap_ms;
            let hot = HotReceivers::new(&recv);
            if maps.shares_mipmap() {
                let t2 = Instant::now();
                let groups = use_groups(params.grouping, &hot, &rig).then(|| ReceiverGroups::new(&hot, &rig.shifts));
                tm.visibility += ms_since(t2);
                (warp_holes, warped_texels) = lazy_shared(&maps, &rig, &hot, groups.as_ref(), &mut lit, &mut tm)?;
            } else {
                let mut sparse = SparseMap::new(rig.center.width, rig.center.height);
                for i in 0..rig.samples() {
                    let t2 = Instant::now();
                    sparse.collect(&hot, rig.shifts[i]);
                    tm.visibility += ms_since(t2);
                    maps.warp_sparse(i, &mut sparse)?;
                    warp_holes += sparse.holes();
                    warped_texels += sparse.warped();
                    let t2 = Instant::now();
                    sparse.accumulate(&hot, &mut lit);
                    tm.visibility += ms_since(t2);
                }
            }
            tm.motion = maps.motion_ms;
            tm.mipmap = maps.mipmap_ms;
            tm.warp += maps.warp_ms;
            recv.visibility_image(&lit, rig.samples() as u32)
        }
        Method::ZwarpFull => {
            let t1 = Instant::now();
            let mut maps = ZwarpMaps::new(scene, &rig, t, &ShadowParams { shared_mipmap: false, ..*params })?;
            tm.render = ms_since(t1) - maps.motion_ms - maps.mipmap_ms;
            for i in 0..rig.samples() {
                let out = maps.map(i)?;
                warp_holes += out.counts().2;
                warped_texels += out.depth.len();
                let t2 = Instant::now();
                recv.accumulate(&out.depth, rig.shifts[i], &mut lit);
                tm.visibility += ms_since(t2);
            }
            tm.motion = maps.motion_ms;
            tm.mipmap = maps.mipmap_ms;
            tm.warp = maps.warp_ms;
            recv.visibility_image(&lit, rig.samples() as u32)
        }
        Method::Pcss => {
            let t1 = Instant::now();
            let map = render_depth(scene, &rig.center, t)?;
            tm.render = ms_since(t1);
            let t2 = Instant::now();
            let v = pcss_visibility(&recv, &rig, &map, &params.pcss)?;
            let mut img = Image::new(recv.width, recv.height, 1.0f32);
            for (r, v) in recv.list.iter().zip(v) {
                img.data_mut()[r.pixel as usize] = v;
            }
            tm.visibility = ms_since(t2);
            img
        }
    };
    let t3 = Instant::now();
    let image = recv.shade(&visibility, params.ambient)?;
    tm.shade = ms_since(t3);
    Ok(ShadowResult { image, visibility, ms: ms_since(start), timings: tm, warp_holes, warped_texels })
}

#[cfg(test)]
mod tests;
