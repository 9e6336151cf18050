//! The per-frame warping-based occlusion culling pipeline (WOC, seed 000 Sec. 5 and Fig. 13;
//! thesis seed 002 Sec. III-IV, Fig. 1) and the baselines it is compared with (Sec. 5.3,
//! thesis Sec. V: NOCULL, VFC, last-frame depth, two-phase culling, REF, ideal screen-space).
//!
//! WOC, per frame, from the previous frame's depth + item buffers and the two cameras:
//! 1. motion buffer `v(q) = C P^-1 q - q` with per-object motion ([`zwarp_core::motion_field`]
//!    with [`Scene::object_deltas`]);
//! 2. single-layer backward depth warp (N = 8 seeds) with holes kept at the far depth
//!    (or, with [`WocParams::awoc`], AWOC's approximate fill, Sec. 5.3);
//! 3. 1-pixel erosion of the occluders (thesis Sec. IV.1, Fig. 4);
//! 4. rapid-motion objects (screen-space speed above a threshold, thesis Sec. IV.1, Fig. 5) are
//!    drawn directly into the predicted depth;
//! 5. a max-depth structure (Y-map by default) is built over the predicted depth;
//! 6. every object: VFC, then its AABB's screen rectangle + nearest depth against the
//!    structure;
//! 7. hybrid query (thesis Sec. IV.2): the K heaviest objects still classified visible are
//!    tested in object space (their AABB rasterized against the predicted depth).
//!
//! Depth follows the zwarp convention: `[0, 1]`, 0 = near, 1 = far / no surface.
//!
//! One file per idea: this file holds the parameters, results and the pipeline itself
//! ([`woc_with`]); [`motion`] step 1, [`rims`] the opening rims and erosion of step 3,
//! [`rapid`] step 4, [`query`] steps 6-7, [`coarse`] culling at a reduced resolution,
//! [`baselines`] the methods WOC is compared with, [`mod@accuracy`] the figures against REF.

use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;
use serde::Serialize;
use zwarp_core::{Aabb, Camera, Error, Image, Result, Scene, EMPTY_DEPTH};
use zwarp_warp::{warp_depth, HolePolicy, PixelState, Sampling, WarpLayer, WarpParams};

use crate::bounds::ObjectBounds;
use crate::maxdepth::{MaxDepthKind, MaxDepthMap};
use crate::objects::{CullObjects, SceneObjects};

pub mod accuracy;
pub mod baselines;
pub mod coarse;
pub mod motion;
pub mod query;
pub mod rapid;
pub mod rims;
#[cfg(test)]
mod tests;

pub use accuracy::*;
pub use baselines::*;
pub use coarse::*;
pub use motion::*;
pub use query::*;
pub use rapid::*;
pub use rims::*;

/// The previous frame: its rendered depth and item buffers, camera and scene time. In a real
/// engine these are the side products of drawing the previous frame's visible set.
#[derive(Clone, Copy, Debug)]
pub struct PrevFrame<'a> {
    /// Depth buffer of the previous frame (`[0, 1]`, 1 = empty).
    pub depth: &'a Image<f32>,
    /// Item buffer (instance ids, [`NO_ITEM`](zwarp_core::NO_ITEM) where empty), same size.
    pub items: &'a Image<u32>,
    /// Camera of the previous frame (same image size as the current one).
    pub cam: &'a Camera,
    /// Scene time of the previous frame (seconds).
    pub t: f32,
}

/// Parameters of [`woc`] (seed 000 Sec. 5.3 and thesis Sec. V "Method" give the defaults).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WocParams {
    /// The depth warp (single layer). Default: N = 8 seeds, far-depth holes (Sec. 5.3: "Our
    /// warping solution used a single layer (depth holes are conservatively kept at the
    /// far-clipping depth). The number of used search seeds (N) was 8."), and *nearest* motion
    /// sampling: bilinear sampling interpolates across the boundary of two objects with similar
    /// motion and closes the 1-2 pixel gaps between them, which then hide what is seen through
    /// the gap. Measured on BL (scale 0.1, 640x360, 11 frames): 6 culling errors with adaptive
    /// bilinear vs 2 with nearest at the same culling ratio, and a faster warp.
    pub warp: WarpParams,
    /// Use AWOC (Sec. 5.3): fill holes from the motion at the extrema of the local search
    /// bound instead of the far depth. Approximate (may cull visible objects), better under
    /// fast motion. Overrides `warp.holes`.
    pub awoc: bool,
    /// 1-pixel max erosion of the predicted depth (thesis Sec. IV.1). Default on.
    pub erosion: bool,
    /// Erosion radius in pixels (each step is one 3x3 max, [`erode_max`](crate::maxdepth::erode_max)); only with
    /// `erosion`. Default 1 (the thesis). Measured on BL (scale 0.25, 960x540, 23 frames):
    /// radius 2 removes only 2 of 24 culling errors and lowers the culling ratio from 83.0%
    /// to 82.5%, so the errors there are not silhouette misplacements.
    pub erosion_radius: u32,
    /// Drop the *opening rims* of the previous frame before warping (see [`opening_rims`]):
    /// texels on the near side of a boundary between two objects whose screen motions pull
    /// them apart by more than this many pixels per frame become holes, so a disocclusion
    /// narrower than a pixel stays far. `None` disables it (every texel is warped, rims included).
    /// Default `Some(0.1)`: slower openings are trusted. The strip an opening uncovers lies
    /// anywhere between the two texel centres (the source samples only those), so any
    /// separation can expose a pixel centre; CB at full resolution (960x540, 24 frames) culls
    /// one visible object through a rim separating by 0.077 px. The tightest meaningful
    /// threshold is the motion field's own precision (0 also opens rims where nothing moves: a
    /// static view's reprojected motion is off by up to 0.003 px): 0.01 costs CB 2.6 points of
    /// culling ratio vs REF at 1080p and 1/4 (95.4% -> 92.8%, frame 16.0 -> 18.2 ms), BL 1.3
    /// points at 960x540.
    /// Measured (scale 0.25, 960x540, 23 frames, CR vs REF / culled visible objects, source
    /// rims): BL off 83.0% / 24, 0.4 px 76.3% / 7, 0.2 px 73.6% / 0, 0 px 72.8% / 0 (VFC
    /// 68.9%, ideal 93.0%); CB off 95.9% / 1, 0.2 px 91.2% / 0, 0 px 85.6% / 0.
    pub open_rims: Option<f32>,
    /// Where the opening rims become far (see [`RimMode`]). Default [`RimMode::Target`].
    pub rim_mode: RimMode,
    /// Bound far pixels near surfaces by the first static surface of the previous frame that
    /// their ray crosses ([`crate::holebound`]), instead of leaving them at the far depth.
    /// Full resolution only (`downsample == 1`). Default off: measured on CB, MO and BL
    /// (scale 0.25, 960x540, 23 frames) it changes the culling ratio by less than 0.01
    /// points. The far pixels that matter are disocclusions and opening rims, which show
    /// surfaces the previous frame never saw; a ray that hits such a surface is behind the
    /// seen surfaces from then on and never crosses one in front-to-back order. (A first
    /// version that accepted crossings within one pixel of a rim gained 2 points on CB, but
    /// those were rays passing behind the occluder's edge: unsound.)
    pub hole_bound: bool,
    /// Rapid-motion threshold per frame in units of the canonical view volume (thesis
    /// Sec. IV.1: "a 3D movement of > 0.02 in the canonical view volume, means a horizontal
    /// movement of 1152 pixel/second on a full-HD image"): objects whose AABB corners move
    /// farther than this on screen are drawn directly into the predicted depth and kept
    /// visible. `None` disables the path. Default 0.02. A fraction of the view, not a pixel
    /// count, so the decision does not depend on the resolution (or on
    /// [`WocParams::downsample`]): in pixels it is [`WocParams::rapid_threshold_px`],
    /// `0.02 * width / 2` = 19.2 px at 1920 wide (1152 px/s at 60 Hz), 9.6 px at 960.
    pub rapid_motion: Option<f32>,
    /// Whether the rapid-motion speed includes the camera's motion. Default `false`: only the
    /// object's own motion, seen from the current camera, counts. The warp handles camera
    /// motion (the motion field is exact per pixel); counting it makes every object rapid
    /// when the camera turns fast: on CB at 4x speed all ~2300 objects in view became rapid
    /// and WOC culled nothing beyond VFC (measured, 640x360).
    pub rapid_includes_camera: bool,
    /// Max-depth structure for the screen-space test. Default: Y-map with 2 mip levels.
    pub max_depth: MaxDepthKind,
    /// After the rectangle test, re-test the kept objects (rectangles up to
    /// [`HULL_TEST_MAX_AREA`] pixels) against their box's exact screen silhouette instead of
    /// its bounding rectangle (the rectangle of a box seen obliquely is up to twice its
    /// silhouette): a far pixel in a rectangle's corner (an opening rim, a disocclusion sliver
    /// beside the object) no longer keeps it. Works at any culling resolution (full-resolution
    /// pixel centres; at `1/f`, the part of each coarse pixel that holds fine pixel centres).
    /// Default on. A zwarp addition between the thesis' rectangle test and its
    /// object-space hybrid query.
    pub hull_test: bool,
    /// K: how many of the heaviest still-visible objects get the hybrid object-space query
    /// (thesis Sec. IV.2 used 300 objects of > 100K triangles). 0 disables it.
    pub hybrid_objects: usize,
    /// Only objects with at least this many triangles are hybrid candidates.
    pub hybrid_min_triangles: usize,
    /// Run the warp and the tests at `1/downsample` of the resolution (1 = full; at most
    /// [`MAX_DOWNSAMPLE`]). The thesis (Sec. VI) and Kasyan et al. 2011 cull at a coarse
    /// resolution for speed. The previous depth is reduced conservatively (each coarse pixel
    /// takes the max over every fine pixel its footprint touches, with the item of that
    /// farthest pixel), rapid-motion objects are drawn at full resolution and reduced the same
    /// way (see `draw_exact`), and the hybrid query is skipped
    /// (coarse pixel-centre coverage can miss small objects). With `open_rims`, coarse texels
    /// whose footprint straddles two separating objects also open (see
    /// `coarse_internal_openings`): without that, BL at 1/4 culled a visible 2-pixel balloon in
    /// 23 frames (scale 0.25, 960x540); with it 0, at a cost in culling ratio (BL 72.8% ->
    /// 71.3%, CB 91.4% -> 87.6% vs REF).
    pub downsample: u32,
}

/// Largest accepted [`WocParams::downsample`].
pub const MAX_DOWNSAMPLE: u32 = 8;

/// Where WOC turns *opening rims* (near-side texels of boundaries between two objects that
/// separate, [`opening_rim_dirs`]) into far depth. Both keep sub-pixel disocclusions open
/// (seed 000 Sec. 5: holes stay at the far depth); they differ in how much else they open.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RimMode {
    /// Drop the whole rim texel from the source before the warp ([`opening_rims`]): its 1x1
    /// footprint becomes a hole in the target, which the erosion then widens by a pixel on each
    /// side. Simple and safe, but on a scene where everything moves (BL) it opens ~10 points of
    /// culling ratio more than needed.
    Source,
    /// Warp the unchanged source, then, after the erosion, set to far only the target pixels
    /// whose exact preimage lies in the *outer* part of a rim texel, towards the separating
    /// neighbour ([`open_rims_in_target`]): exactly where the disocclusion can show through.
    #[default]
    Target,
}

impl Default for WocParams {
    fn default() -> Self {
        WocParams {
            warp: WarpParams {
                n_seeds: 8,
                holes: HolePolicy::FarDepth,
                sampling: Sampling::Nearest,
                ..WarpParams::default()
            },
            awoc: false,
            erosion: true,
            erosion_radius: 1,
            open_rims: Some(0.1),
            rim_mode: RimMode::Target,
            hole_bound: false,
            hull_test: true,
            rapid_motion: Some(0.02),
            rapid_includes_camera: false,
            max_depth: MaxDepthKind::YMap { switch: 2 },
            hybrid_objects: 300,
            hybrid_min_triangles: 10_000,
            downsample: 1,
        }
    }
}

impl WocParams {
    /// The rapid-motion threshold in pixels per frame for an image `width` pixels wide:
    /// [`WocParams::rapid_motion`] is measured across the canonical view volume, whose
    /// horizontal extent `[-1, 1]` spans `width` pixels (the thesis' own conversion). `None`
    /// when the path is disabled.
    pub fn rapid_threshold_px(&self, width: u32) -> Option<f32> {
        self.rapid_motion.map(|v| v * 0.5 * width as f32)
    }

    /// Checks the parameters (warp parameters included).
    pub fn validate(&self) -> Result<()> {
        self.warp.validate()?;
        if !(1..=MAX_DOWNSAMPLE).contains(&self.downsample) {
            return Err(Error::invalid(format!(
                "downsample factor must be in 1..={MAX_DOWNSAMPLE}, got {}",
                self.downsample
            )));
        }
        if let Some(px) = self.open_rims {
            if !(px.is_finite() && px >= 0.0) {
                return Err(Error::invalid(format!("rim separation threshold must be >= 0 pixels, got {px}")));
            }
        }
        if let Some(v) = self.rapid_motion {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::invalid(format!(
                    "rapid-motion threshold must be >= 0 (view-volume units), got {v}"
                )));
            }
        }
        Ok(())
    }
}

/// Wall-clock time of each stage in milliseconds (stages a method does not run stay 0).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct CullTimings {
    /// Motion buffer generation.
    pub motion_ms: f64,
    /// Depth warping.
    pub warp_ms: f64,
    /// Erosion of the predicted depth.
    pub erosion_ms: f64,
    /// Drawing rapid-motion objects (WOC) or the first-phase objects (two-phase).
    pub draw_ms: f64,
    /// Building the max-depth structure.
    pub build_ms: f64,
    /// VFC + screen-space tests of all objects.
    pub test_ms: f64,
    /// Hybrid object-space queries.
    pub hybrid_ms: f64,
    /// The whole culling step.
    pub total_ms: f64,
}

/// Per-frame counts of how objects were classified.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct CullStats {
    /// Objects in the scene.
    pub objects: usize,
    /// Removed by view-frustum culling.
    pub frustum_culled: usize,
    /// Removed by the screen-space max-depth test.
    pub occlusion_culled: usize,
    /// Removed by the hybrid object-space query.
    pub hybrid_culled: usize,
    /// Objects given the hybrid query.
    pub hybrid_tested: usize,
    /// Kept because their box crosses the near plane.
    pub crosses_near: usize,
    /// Rapid-motion objects drawn into the predicted depth (and kept).
    pub rapid: usize,
}

/// What a culling method decided for one frame.
#[derive(Clone, Debug, PartialEq)]
pub struct CullResult {
    /// Ids of the objects to draw, increasing.
    pub visible: Vec<u32>,
    /// Stage timings.
    pub timings: CullTimings,
    /// Classification counts.
    pub stats: CullStats,
    /// Objects already drawn into the occlusion map (WOC's rapid-motion objects): an engine
    /// that shades them in that pass can skip them in the main pass.
    pub predrawn: Vec<u32>,
    /// The depth buffer the screen-space tests ran against (predicted depth for WOC, at the
    /// coarse resolution when [`WocParams::downsample`] > 1), if any.
    pub occlusion_map: Option<Image<f32>>,
}

fn ms(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

/// The 12 triangles of a box (two per face), for object-space queries of its proxy.
pub fn aabb_triangles(b: &Aabb) -> [[Vec3; 3]; 12] {
    let c = b.corners();
    // Corner index bits: x = 1, y = 2, z = 4 (see `Aabb::corners`).
    const FACES: [[usize; 4]; 6] = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
    let mut out = [[Vec3::ZERO; 3]; 12];
    for (f, q) in FACES.iter().enumerate() {
        out[2 * f] = [c[q[0]], c[q[1]], c[q[2]]];
        out[2 * f + 1] = [c[q[0]], c[q[2]], c[q[3]]];
    }
    out
}

/// World AABBs of every instance at time `t`.
pub fn instance_aabbs(scene: &Scene, t: f32) -> Vec<Aabb> {
    (0..scene.instances.len() as u32).into_par_iter().map(|id| scene.instance_aabb_at(id, t)).collect()
}

fn check_camera_depth(depth: &Image<f32>, cam: &Camera, what: &str) -> Result<()> {
    check_camera_size(depth, cam, what)?;
    if depth.data().par_iter().any(|d| d.is_nan()) {
        return Err(Error::invalid(format!("{what} holds NaN")));
    }
    Ok(())
}

/// [`check_camera_depth`] without the NaN scan (done by the caller's own pass over the data).
fn check_camera_size(depth: &Image<f32>, cam: &Camera, what: &str) -> Result<()> {
    depth.check_nonempty(what)?;
    if depth.size() != (cam.width, cam.height) {
        return Err(Error::invalid(format!(
            "{what} is {}x{} but the camera renders {}x{}",
            depth.width(),
            depth.height(),
            cam.width,
            cam.height
        )));
    }
    Ok(())
}

fn check_time(t: f32) -> Result<()> {
    if t.is_finite() {
        Ok(())
    } else {
        Err(Error::invalid(format!("scene time must be finite, got {t}")))
    }
}

/// Pixel-square slack of the silhouette test ([`hull_hides`]) when testing at the resolution of
/// `cam` for a frame rendered at the resolution of `full_cam` (same view volume): `0.01 - 0.5 /
/// f` coarse pixels for a divisor `f` that divides both image sides (-0.49 at full resolution):
/// the coarse squares shrink to the fine pixel centres they hold, so a silhouette that only
/// grazes a coarse pixel's border strip, where it covers none of its fine centres, no longer
/// keeps the object. When `f` does not divide a side the coarse borders fall anywhere between
/// fine pixels (even on a fine centre), and the whole square counts (`0.01`).
pub(crate) fn hull_slack(cam: &Camera, full_cam: &Camera) -> f32 {
    let exact = |c: u32, fine: u32| c > 0 && fine.is_multiple_of(c) && fine / c == full_cam.width / cam.width.max(1);
    if exact(cam.width, full_cam.width) && exact(cam.height, full_cam.height) {
        0.01 - 0.5 * cam.width as f32 / full_cam.width as f32
    } else {
        0.01
    }
}

/// WOC for one frame (see the module docs): the visible objects of `scene` at time `t` seen by
/// `cam`, predicted from the previous frame `prev`.
///
/// Errors: invalid parameters, non-finite times, buffer sizes that differ from the cameras',
/// NaN depths.
pub fn woc(scene: &Scene, prev: &PrevFrame<'_>, cam: &Camera, t: f32, params: &WocParams) -> Result<CullResult> {
    woc_with(scene, &ObjectBounds::new(scene), prev, cam, t, params)
}

/// [`woc`] with the object boxes kept across frames ([`ObjectBounds`], built once for `scene`):
/// what an engine calls every frame ([`crate::run_sequence`] does).
///
/// Errors: as [`woc`], and bounds built for a different number of objects.
pub fn woc_with(
    scene: &Scene,
    bounds: &ObjectBounds,
    prev: &PrevFrame<'_>,
    cam: &Camera,
    t: f32,
    params: &WocParams,
) -> Result<CullResult> {
    bounds.check(scene)?;
    check_time(t)?;
    check_time(prev.t)?;
    woc_objects(&SceneObjects { scene, bounds, t_prev: prev.t, t }, prev, cam, params)
}

/// WOC for one frame over any [`CullObjects`]: the pipeline of [`woc_with`], which calls it with
/// a scene's instances. For bounds-only objects (an engine's [`crate::BoxObject`]s, whose ids
/// are what `prev.items` holds) the steps that need triangles are skipped: rapid-motion objects
/// are kept visible without being drawn into the predicted depth, and the hybrid query and the
/// hole bounds do not run. `prev.t` is not read.
///
/// Errors: as [`woc`], and an item buffer naming objects beyond `objects.len()` is not an
/// error (such pixels move with the camera, as empty ones do).
pub fn woc_objects(
    objects: &(impl CullObjects + ?Sized),
    prev: &PrevFrame<'_>,
    cam: &Camera,
    params: &WocParams,
) -> Result<CullResult> {
    params.validate()?;
    let geometry = objects.geometry();
    let f = params.downsample;
    // At a coarse resolution the NaN scan is part of the reduction's single pass (below).
    if f > 1 {
        check_camera_size(prev.depth, prev.cam, "previous depth buffer")?;
    } else {
        check_camera_depth(prev.depth, prev.cam, "previous depth buffer")?;
    }
    prev.depth.check_same_size(prev.items, "previous depth vs item buffer")?;
    if (prev.cam.width, prev.cam.height) != (cam.width, cam.height) {
        return Err(Error::invalid(format!(
            "previous camera renders {}x{} but the current one {}x{}",
            prev.cam.width, prev.cam.height, cam.width, cam.height
        )));
    }
    let start = Instant::now();
    let mut tm = CullTimings::default();

    // 0. Optional coarse resolution: the whole pipeline runs on the coarse grid (the rapid-
    //    motion speed stays in full-resolution pixels). One pass over the fine buffers gives
    //    the reduced depth + items and the near/far pairs of the internal openings.
    let t0 = Instant::now();
    let (full_prev_cam, full_cam) = (prev.cam, cam);
    let n = objects.len();
    let mut pairs = Vec::new();
    let coarse = if f > 1 {
        let (ca, cb) = (coarse_camera(prev.cam, f), coarse_camera(cam, f));
        let r = reduce_prev(prev.depth, prev.items, (ca.width, ca.height), params.open_rims.map(|_| n));
        if r.nan {
            return Err(Error::invalid("previous depth buffer holds NaN"));
        }
        pairs = r.pairs;
        Some((ca, cb, r.depth, r.items))
    } else {
        None
    };
    let (prev_cam, cam, prev_depth, prev_items) = match &coarse {
        Some((ca, cb, d, it)) => (ca, cb, d, it),
        None => (prev.cam, cam, prev.depth, prev.items),
    };

    // 1. Motion buffer with object motion through the item buffer (Sec. 3.1).
    let animated = |id: u32| (id as usize) < n && objects.is_animated(id);
    // Ids beyond the objects (and NO_ITEM) move with the camera only.
    let delta = |id: u32| if (id as usize) < n { objects.delta(id) } else { glam::Mat4::IDENTITY };
    let motion = zwarp_core::motion_field_with(prev_depth, Some(prev_items), prev_cam, cam, animated, delta)?;
    tm.motion_ms = ms(t0);

    // 2. Single-layer warp; holes at the far depth (or AWOC's approximate fill).
    let t0 = Instant::now();
    let mut wp = params.warp;
    wp.holes = if params.awoc { HolePolicy::Awoc } else { params.warp.holes };
    let rim_dirs = match params.open_rims {
        Some(sep) => Some(opening_rim_dirs(prev_depth, prev_items, &motion, sep)?),
        None => None,
    };
    let target_rims = rim_dirs.as_ref().filter(|_| params.rim_mode == RimMode::Target);
    // The target rule (and the coarse internal openings) need each pixel's source texel.
    wp.record_source = target_rims.is_some() || (params.open_rims.is_some() && f > 1);
    let rimmed;
    let src_depth = match &rim_dirs {
        Some(dirs) if params.rim_mode == RimMode::Source => {
            rimmed = blank_rims(prev_depth, dirs);
            &rimmed
        }
        _ => prev_depth,
    };
    // Coarse culling: openings inside one coarse texel are invisible to the coarse rim test.
    let inner_open = match (params.open_rims, f > 1) {
        (Some(sep), true) => {
            let texels = prev_depth.len();
            Some(coarse_internal_openings(delta, &pairs, texels, prev.depth.size(), full_prev_cam, full_cam, sep))
        }
        _ => None,
    };
    drop(pairs);
    let warped = warp_depth(&[WarpLayer { depth: src_depth, motion: &motion }], &wp)?;
    tm.warp_ms = ms(t0);

    // 3. Erosion: occluder silhouettes pulled back by a pixel (warping is off by 1-2 px at
    //    boundaries, thesis Fig. 4).
    let t0 = Instant::now();
    let (warped_depth, warped_state, warped_source) = (warped.depth, warped.state, warped.source);
    let mut predicted = if params.erosion { erode_n(warped_depth, params.erosion_radius) } else { warped_depth };
    tm.erosion_ms = ms(t0);

    // 3a. Coarse internal openings, after the erosion: every pixel that took its depth from
    //     such a texel becomes far.
    if let (Some(inner), Some(src)) = (inner_open.as_ref(), warped_source.as_ref()) {
        let t0 = Instant::now();
        let (sw, sh) = (prev_cam.width, prev_cam.height);
        predicted.data_mut().par_iter_mut().zip(src.data().par_iter()).zip(warped_state.data().par_iter()).for_each(
            |((d, q), st)| {
                let (cx, cy) = (q.q.x.floor(), q.q.y.floor());
                let inside = cx >= 0.0 && cy >= 0.0 && cx < sw as f32 && cy < sh as f32;
                if *st == PixelState::Converged && inside && inner[cy as usize * sw as usize + cx as usize] {
                    *d = EMPTY_DEPTH;
                }
            },
        );
        tm.warp_ms += ms(t0);
    }

    // 3b. Opening rims in the target, after the erosion: these pixels are exactly where a
    //     disocclusion can show through, so they need no further margin.
    if let (Some(dirs), Some(src)) = (target_rims, warped_source.as_ref()) {
        let t0 = Instant::now();
        open_rims_in_target(&mut predicted, src, &warped_state, &motion, dirs)?;
        tm.warp_ms += ms(t0);
    }

    // 4. One pass over the objects (bounds at `t`, VFC, rapid-motion speed, screen rectangle
    //    at the culling resolution), keeping only those in the frustum: the tests after the
    //    occlusion map is built then read a compact list instead of every instance again.
    //    Rapid-motion objects are drawn exactly into the predicted depth, last (their
    //    rasterized depth needs no margin and no rim can hide a gap in it), and kept visible.
    let t0 = Instant::now();
    let in_frustum = prepass(objects, cam, &Rapid::of(params, full_prev_cam, full_cam));
    let predrawn: Vec<u32> = in_frustum.iter().filter(|o| o.test == Test::Forced).map(|o| o.id).collect();
    if let (false, Some((scene, t))) = (predrawn.is_empty(), geometry) {
        draw_exact(&mut predicted, scene, full_cam, t, &predrawn)?;
    }
    tm.draw_ms = ms(t0);

    // 4c. Far pixels near surfaces: bounded by static surfaces their ray crosses.
    if let (true, 1, Some((scene, _))) = (params.hole_bound, f, geometry) {
        let t0 = Instant::now();
        let rays = crate::holebound::StaticRays::new(scene, prev.depth, prev.items, prev.cam, cam)?;
        let candidates = near_surface(&predicted, HOLE_BOUND_RADIUS);
        crate::holebound::bound_far_pixels(&mut predicted, &candidates, &rays)?;
        tm.erosion_ms += ms(t0);
    }

    // 5. Max-depth structure.
    let t0 = Instant::now();
    let map = MaxDepthMap::build(params.max_depth, &predicted)?;
    tm.build_ms = ms(t0);

    // 6. Screen-space tests of the objects in the frustum: rectangle against the max-depth
    //    structure, then the silhouette of the survivors.
    let t0 = Instant::now();
    let hull = params.hull_test.then_some((predicted.data(), hull_slack(cam, full_cam)));
    let kept = test_prepassed(&in_frustum, cam, &map, hull);
    tm.test_ms = ms(t0);

    // 7. Hybrid object-space query of the heaviest survivors (not the predrawn ones).
    let t0 = Instant::now();
    let k = if f > 1 { 0 } else { params.hybrid_objects };
    let (hidden, tested) = match geometry {
        Some((scene, t)) if k > 0 => {
            let candidates: Vec<u32> = kept.iter().copied().filter(|id| predrawn.binary_search(id).is_err()).collect();
            hybrid_cull(scene, &predicted, cam, t, &candidates, k, params.hybrid_min_triangles)?
        }
        _ => (Vec::new(), 0),
    };
    let visible: Vec<u32> = if hidden.is_empty() {
        kept
    } else {
        kept.into_iter().filter(|id| hidden.binary_search(id).is_err()).collect()
    };
    tm.hybrid_ms = ms(t0);

    let crosses_near = in_frustum.iter().filter(|o| o.test == Test::Keep).count();
    let stats = CullStats {
        objects: n,
        frustum_culled: n - in_frustum.len(),
        occlusion_culled: in_frustum.len() - visible.len() - hidden.len(),
        hybrid_culled: hidden.len(),
        hybrid_tested: tested,
        crosses_near,
        rapid: predrawn.len(),
    };
    tm.total_ms = ms(start);
    Ok(CullResult { visible, timings: tm, stats, predrawn, occlusion_map: Some(predicted) })
}
