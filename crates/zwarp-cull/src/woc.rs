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

use std::time::Instant;

use glam::{Vec2, Vec3};
use rayon::prelude::*;
use serde::Serialize;
use zwarp_core::{Aabb, Camera, Error, Image, Result, Scene, EMPTY_DEPTH, NO_ITEM};
use zwarp_raster::{any_fragment_visible, draw_into, render_frame, FrameOptions};
use zwarp_warp::{warp_depth, HolePolicy, PixelState, Sampling, SourcePos, WarpLayer, WarpParams};

use crate::bounds::ObjectBounds;
use crate::frustum::Frustum;
use crate::maxdepth::{erode_max, MaxDepthKind, MaxDepthMap, MaxDepthQuery};
use crate::screen::{screen_rect_with, PixelRect, ScreenRect};

/// The previous frame: its rendered depth and item buffers, camera and scene time. In a real
/// engine these are the side products of drawing the previous frame's visible set.
#[derive(Clone, Copy, Debug)]
pub struct PrevFrame<'a> {
    /// Depth buffer of the previous frame (`[0, 1]`, 1 = empty).
    pub depth: &'a Image<f32>,
    /// Item buffer (instance ids, [`NO_ITEM`] where empty), same size.
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
    /// Erosion radius in pixels (each step is one 3x3 max, [`erode_max`]); only with
    /// `erosion`. Default 1 (the thesis). Measured on BL (scale 0.25, 960x540, 23 frames):
    /// radius 2 removes only 2 of 24 culling errors and lowers the culling ratio from 83.0%
    /// to 82.5%, so the errors there are not silhouette misplacements.
    pub erosion_radius: u32,
    /// Drop the *opening rims* of the previous frame before warping (see [`opening_rims`]):
    /// texels on the near side of a boundary between two objects whose screen motions pull
    /// them apart by more than this many pixels per frame become holes, so a disocclusion
    /// narrower than a pixel stays far. `None` disables it (the pre-fix behaviour).
    /// Default `Some(0.1)`. Measured (scale 0.25, 960x540, 23 frames, CR vs REF / culled
    /// visible objects): BL off 83.0% / 24, 0.4 px 76.3% / 7, 0.2 px 73.6% / 0, 0 px 72.8% / 0
    /// (VFC 68.9%, ideal 93.0%); CB off 95.9% / 1, 0.2 px 91.2% / 0, 0 px 85.6% / 0. 0 is the
    /// strictly conservative choice (any opening can expose a pixel centre); the default keeps
    /// a 2x margin below the smallest threshold that failed.
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

/// Depth tolerance of the pipeline's screen-space test: an object is culled only when the max
/// depth over its rect is below its nearest corner depth by more than this. The rasterizer
/// interpolates depth and the motion field reprojects it in f32, so a face seen head-on (an
/// AABB face, e.g. a building wall) can come out a few ulps nearer than its own box corner; a
/// window onto that face would then hide the object from itself. 1e-6 is about 16 ulps near
/// depth 1 (millimetres at 10 m with near = 0.1, far = 100) and far below real occluder gaps.
pub const DEPTH_TOLERANCE: f32 = 1e-6;

/// How one object was classified by [`test_objects`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Class {
    Frustum,
    Forced,
    CrossesNear,
    Occluded,
    Visible,
}

/// VFC + screen-space max-depth test of every object (parallel). `forced[id]` objects are
/// kept without a test.
fn test_objects(aabbs: &[Aabb], cam: &Camera, map: &impl MaxDepthQuery, forced: Option<&[bool]>) -> Vec<Class> {
    test_objects_in(aabbs, None, cam, map, forced)
}

/// [`test_objects`] with the VFC result given (`inside[id]`) when already computed.
fn test_objects_in(
    aabbs: &[Aabb],
    inside: Option<&[bool]>,
    cam: &Camera,
    map: &impl MaxDepthQuery,
    forced: Option<&[bool]>,
) -> Vec<Class> {
    let frustum = Frustum::from_camera(cam);
    let vp = cam.view_proj();
    aabbs
        .par_iter()
        .enumerate()
        .map(|(id, b)| {
            let in_view = match inside {
                Some(f) => f[id],
                None => frustum.intersects(b),
            };
            if !in_view {
                return Class::Frustum;
            }
            if forced.is_some_and(|f| f[id]) {
                return Class::Forced;
            }
            match screen_rect_with(b, &vp, cam.width, cam.height) {
                ScreenRect::CrossesNear => Class::CrossesNear,
                ScreenRect::Outside => Class::Frustum,
                ScreenRect::Rect { rect, nearest } => {
                    if map.is_occluded(rect, nearest - DEPTH_TOLERANCE) {
                        Class::Occluded
                    } else {
                        Class::Visible
                    }
                }
            }
        })
        .collect()
}

/// Largest screen rectangle (pixels of the culling resolution) given the silhouette test of
/// [`WocParams::hull_test`]; bigger objects keep the rectangle's answer (scanning them would
/// cost more than drawing most of them).
pub const HULL_TEST_MAX_AREA: u64 = 16_384;

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

/// Second screen-space test (see [`WocParams::hull_test`]): `true` when an object whose box
/// `b` has the screen rectangle `rect` (which the rectangle test kept) is hidden after all: no
/// pixel of its rectangle that could show it (`predicted` depth not nearer than `limit`, its
/// nearest corner depth minus [`DEPTH_TOLERANCE`]) touches the box's projected silhouette (the
/// convex hull of its 8 projected corners, [`crate::screen::screen_hull_with`]). The renderer
/// covers (full-resolution) pixel centres, so a pixel counts when the silhouette meets its
/// square grown by `slack` on each side: at full resolution -0.49 (the centre, within 0.01 px
/// against f32 rounding); at `1/f` of the resolution a coarse pixel bounds every fine pixel
/// whose centre lies in it, and those centres lie at least `0.5 / f` coarse px inside its
/// square, so `0.01 - 0.5 / f` (see [`hull_slack`]).
/// Rectangles above [`HULL_TEST_MAX_AREA`] and boxes crossing the near plane are kept.
#[allow(clippy::too_many_arguments)]
fn hull_hides(
    b: &Aabb,
    rect: PixelRect,
    limit: f32,
    vp: &glam::Mat4,
    (w, h): (u32, u32),
    predicted: &[f32],
    slack: f32,
) -> bool {
    use crate::screen::{fceil, ffloor};
    if rect.area() > HULL_TEST_MAX_AREA {
        return false;
    }
    let row_visible = |y: u32, row: &[f32], hull: &[Vec2; 8], n: usize| -> bool {
        if n < 3 {
            // Degenerate silhouette (a segment or a point): per-pixel test.
            return (rect.x0..rect.x1).any(|x| {
                row[x as usize] >= limit && crate::screen::square_meets_hull(x as f32, y as f32, slack, hull, n)
            });
        }
        // Pixel squares of this row span the strip [y - slack, y + 1 + slack]; the ones
        // meeting the silhouette are those whose x-interval overlaps its extent there.
        let Some((xa, xb)) = crate::screen::hull_x_range_in_strip(hull, n, y as f32 - slack, y as f32 + 1.0 + slack)
        else {
            return false;
        };
        // x - slack <= xb and x + 1 + slack >= xa. Clamped before rounding (integer limits:
        // same bounds as rounding first, and the fast rounding stays in its exact range).
        let (x0, x1) = (rect.x0 as f32, rect.x1 as f32);
        let first = fceil((xa - 1.0 - slack).clamp(x0, x1)) as u32;
        let last = (ffloor((xb + slack).clamp(x0 - 1.0, x1)) + 1.0).min(x1).max(first as f32) as u32;
        row[first as usize..last as usize].iter().any(|&p| p >= limit)
    };
    // The silhouette is built only once a row of the rectangle has a pixel that could show
    // the object (rectangles the max-depth structure kept conservatively often have none).
    let mut hull = None;
    for y in rect.y0..rect.y1 {
        let row = &predicted[y as usize * w as usize..(y as usize + 1) * w as usize];
        if !row[rect.x0 as usize..rect.x1 as usize].iter().any(|&p| p >= limit) {
            continue;
        }
        let Some((hull, n)) = hull.get_or_insert_with(|| crate::screen::screen_hull_with(b, vp, w, h)) else {
            return false;
        };
        if row_visible(y, row, hull, *n) {
            return false;
        }
    }
    true
}

/// Hybrid object-space query (thesis Sec. IV.2, a CPU analogue of the HOQ variant of Kubisch &
/// Tavenrath 2014): of `candidates` (objects the screen-space test kept), the `k` with the most
/// triangles (at least `min_tris`; ties by id) rasterize their AABB at time `t` against `depth`
/// with the renderer's coverage rules; those without a single fragment in front (by more than
/// [`DEPTH_TOLERANCE`]) are hidden. Returns `(hidden ids, number tested)`.
///
/// Conservative: any pixel centre an object covers is covered by its box at a depth no
/// farther, so a visible object always has a box fragment in front of an occluder map that is
/// itself no nearer than the truth.
pub fn hybrid_cull(
    scene: &Scene,
    depth: &Image<f32>,
    cam: &Camera,
    t: f32,
    candidates: &[u32],
    k: usize,
    min_tris: usize,
) -> Result<(Vec<u32>, usize)> {
    check_time(t)?;
    check_camera_depth(depth, cam, "occlusion depth")?;
    let n = scene.instances.len();
    if let Some(&bad) = candidates.iter().find(|&&id| id as usize >= n) {
        return Err(Error::invalid(format!("hybrid candidates name object {bad} but the scene has {n}")));
    }
    if k == 0 {
        return Ok((Vec::new(), 0));
    }
    let tris = |id: u32| scene.meshes[scene.instances[id as usize].mesh as usize].triangle_count();
    let mut cand: Vec<u32> = candidates.iter().copied().filter(|&id| tris(id) >= min_tris).collect();
    cand.sort_unstable_by(|&a, &b| tris(b).cmp(&tris(a)).then(a.cmp(&b)));
    cand.dedup();
    cand.truncate(k);
    if cand.is_empty() {
        return Ok((Vec::new(), 0));
    }
    // The map holds the candidates' own (warped) surfaces: a box face that *is* the surface
    // (buildings) must pass against itself, so fragments are compared with a small tolerance
    // (the same as the rect test), not strictly.
    let biased =
        Image::from_vec(depth.width(), depth.height(), depth.data().par_iter().map(|d| d + DEPTH_TOLERANCE).collect())?;
    let mut hidden: Vec<u32> = cand
        .par_iter()
        .copied()
        .filter(|&id| !any_fragment_visible(&biased, cam, &aabb_triangles(&scene.instance_aabb_at(id, t))))
        .collect();
    hidden.sort_unstable();
    Ok((hidden, cand.len()))
}

fn collect(classes: &[Class], hybrid_before: Option<&[Class]>) -> (Vec<u32>, CullStats) {
    let mut st = CullStats { objects: classes.len(), ..CullStats::default() };
    let mut visible = Vec::new();
    for (id, c) in classes.iter().enumerate() {
        match c {
            Class::Frustum => st.frustum_culled += 1,
            Class::Occluded => {
                if hybrid_before.is_some_and(|h| h[id] != Class::Occluded) {
                    st.hybrid_culled += 1;
                } else {
                    st.occlusion_culled += 1;
                }
            }
            Class::Forced => {
                st.rapid += 1;
                visible.push(id as u32);
            }
            Class::CrossesNear => {
                st.crosses_near += 1;
                visible.push(id as u32);
            }
            Class::Visible => visible.push(id as u32),
        }
    }
    (visible, st)
}

/// Screen-space speed (pixels per frame) of an instance between two views: the largest
/// displacement of its object-space bounding-box corners, each moved with the instance's
/// transform at each time (so rotating objects are tracked point by point). Infinite when a
/// corner is behind or in front of the near plane in either view. Pass the same camera twice
/// for the object's own motion only (0 for static objects).
pub fn screen_speed(scene: &Scene, id: u32, cam_a: &Camera, t_a: f32, cam_b: &Camera, t_b: f32) -> f32 {
    let inst = &scene.instances[id as usize];
    if !inst.animation.is_animated() && cam_a == cam_b {
        return 0.0;
    }
    let bounds = scene.meshes[inst.mesh as usize].bounds;
    if bounds.is_empty() {
        return 0.0;
    }
    let (ma, mb) = (inst.transform_at(t_a), inst.transform_at(t_b));
    let (vpa, vpb) = (cam_a.view_proj(), cam_b.view_proj());
    let mut speed = 0.0f32;
    for c in bounds.corners() {
        let pa = zwarp_core::camera::project_with(&vpa, cam_a.width, cam_a.height, ma.transform_point3(c));
        let pb = zwarp_core::camera::project_with(&vpb, cam_b.width, cam_b.height, mb.transform_point3(c));
        match (pa, pb) {
            (Some(a), Some(b)) if a.z >= 0.0 && b.z >= 0.0 => {
                speed = speed.max((b.truncate() - a.truncate()).length());
            }
            _ => return f32::INFINITY,
        }
    }
    speed
}

/// Culls the objects of `scene` at time `t` for `cam` against any depth buffer `depth` (VFC,
/// then the screen-space test with the chosen max-depth structure). Objects flagged in
/// `forced` are kept untested. Building block of [`woc`], [`lastframe`] and
/// [`ideal_screen_space`]; usable with an engine's own predicted depth.
pub fn cull_against_depth(
    scene: &Scene,
    depth: &Image<f32>,
    cam: &Camera,
    t: f32,
    kind: MaxDepthKind,
    forced: Option<&[bool]>,
) -> Result<CullResult> {
    cull_against_depth_with(scene, &ObjectBounds::new(scene), depth, cam, t, kind, forced)
}

/// [`cull_against_depth`] with the object boxes kept across frames (as [`woc_with`]).
pub fn cull_against_depth_with(
    scene: &Scene,
    bounds: &ObjectBounds,
    depth: &Image<f32>,
    cam: &Camera,
    t: f32,
    kind: MaxDepthKind,
    forced: Option<&[bool]>,
) -> Result<CullResult> {
    bounds.check(scene)?;
    check_time(t)?;
    check_camera_depth(depth, cam, "occlusion depth")?;
    if let Some(f) = forced {
        if f.len() != scene.instances.len() {
            return Err(Error::invalid(format!(
                "forced-visible flags: {} entries for {} objects",
                f.len(),
                scene.instances.len()
            )));
        }
    }
    let t0 = Instant::now();
    let map = MaxDepthMap::build(kind, depth)?;
    let build_ms = ms(t0);
    let t1 = Instant::now();
    let aabbs = bounds.all_at(scene, t);
    let classes = test_objects(&aabbs, cam, &map, forced);
    let (visible, stats) = collect(&classes, None);
    let test_ms = ms(t1);
    Ok(CullResult {
        visible,
        timings: CullTimings { build_ms, test_ms, total_ms: ms(t0), ..CullTimings::default() },
        stats,
        predrawn: Vec::new(),
        occlusion_map: Some(depth.clone()),
    })
}

/// The same view volume rendered at `1/factor` of the resolution (rounded up): projection and
/// view are unchanged, only the pixel grid is coarser.
pub fn coarse_camera(cam: &Camera, factor: u32) -> Camera {
    Camera { width: cam.width.div_ceil(factor.max(1)), height: cam.height.div_ceil(factor.max(1)), ..*cam }
}

/// Fine pixels `[lo, hi)` touched by coarse pixel `i` when `fine` pixels map onto `coarse`.
#[inline]
fn footprint(i: u32, fine: u32, coarse: u32) -> (u32, u32) {
    let (i, fine, coarse) = (i as u64, fine as u64, coarse as u64);
    let lo = i * fine / coarse;
    let hi = ((i + 1) * fine).div_ceil(coarse).min(fine);
    (lo as u32, hi as u32)
}

/// Conservative reduction of a depth + item buffer to `width x height` (the size of
/// [`coarse_camera`]): each coarse pixel takes the max depth over every fine pixel its
/// footprint touches, and the item of that farthest pixel (first one on ties).
pub fn downsample_max(
    depth: &Image<f32>,
    items: &Image<u32>,
    width: u32,
    height: u32,
) -> Result<(Image<f32>, Image<u32>)> {
    depth.check_nonempty("depth buffer")?;
    depth.check_same_size(items, "depth vs item buffer")?;
    if width == 0 || height == 0 || width > depth.width() || height > depth.height() {
        return Err(Error::invalid(format!("cannot reduce {}x{} to {width}x{height}", depth.width(), depth.height())));
    }
    let r = reduce_prev(depth, items, (width, height), None);
    Ok((r.depth, r.items))
}

/// A fine pixel of a coarse footprint: depth, item, x, y.
type Px = (f32, u32, u32, u32);

/// The previous frame at the culling resolution ([`reduce_prev`]).
struct CoarsePrev {
    /// [`downsample_max`]'s depth.
    depth: Image<f32>,
    /// [`downsample_max`]'s items.
    items: Image<u32>,
    /// Per coarse texel, its nearest and farthest non-empty fine pixel when they belong to two
    /// different objects (ids below the object count given), the nearer strictly nearer
    /// (input of [`coarse_internal_openings`]); empty unless asked for.
    pairs: Vec<Option<(Px, Px)>>,
    /// A fine depth was NaN.
    nan: bool,
}

/// One pass over the fine previous buffers for the coarse culling resolution (seed 002
/// Sec. VI): [`downsample_max`]'s conservative reduction, the near/far object pairs of
/// [`coarse_internal_openings`] when `pairs_below` gives the object count, and the NaN check,
/// reading each fine pixel once (separate passes cost ~1.5 ms per 0.5 Mpx frame, more than the
/// coarse warp itself). Ties keep the first pixel in row-major order.
fn reduce_prev(depth: &Image<f32>, items: &Image<u32>, (cw, ch): (u32, u32), pairs_below: Option<usize>) -> CoarsePrev {
    let (fw, fh) = depth.size();
    let xs: Vec<(u32, u32)> = (0..cw).map(|cx| footprint(cx, fw, cw)).collect();
    let (cwu, n) = (cw as usize, cw as usize * ch as usize);
    let mut out_d = vec![0.0f32; n];
    let mut out_i = vec![NO_ITEM; n];
    let mut out_p: Vec<Option<(Px, Px)>> = if pairs_below.is_some() { vec![None; n] } else { Vec::new() };
    let limit = pairs_below.unwrap_or(0);
    // Per coarse column of one coarse row: farthest pixel (depth, item) and, for the pairs,
    // the nearest and farthest valid pixel (depth, fine x, fine y). The fine rows are walked
    // whole, so consecutive pixels update different columns' accumulators: no loop-carried
    // dependency through one running max (the per-texel loop was latency-bound, ~7 cycles per
    // fine pixel). Ties keep the first pixel in row-major order (strict comparisons).
    #[derive(Clone, Copy)]
    struct Acc {
        best: (f32, u32),
        near: (f32, u32, u32),
        far: (f32, u32, u32),
    }
    const EMPTY_ACC: Acc =
        Acc { best: (f32::NEG_INFINITY, NO_ITEM), near: (f32::INFINITY, 0, 0), far: (f32::NEG_INFINITY, 0, 0) };
    let row = |cy: usize, od: &mut [f32], oi: &mut [u32], op: Option<&mut [Option<(Px, Px)>]>| -> bool {
        let (y0, y1) = footprint(cy as u32, fh, ch);
        let mut acc = vec![EMPTY_ACC; xs.len()];
        let mut nan = false;
        for y in y0..y1 {
            let (ds, is) = (depth.row(y), items.row(y));
            for (a, &(x0, x1)) in acc.iter_mut().zip(&xs) {
                for x in x0..x1 {
                    let (d, id) = (ds[x as usize], is[x as usize]);
                    nan |= d.is_nan();
                    if d > a.best.0 {
                        a.best = (d, id);
                    }
                    // `NO_ITEM` is never below the object count.
                    if d < EMPTY_DEPTH && (id as usize) < limit {
                        if d < a.near.0 {
                            a.near = (d, x, y);
                        }
                        if d > a.far.0 {
                            a.far = (d, x, y);
                        }
                    }
                }
            }
        }
        for (cx, a) in acc.iter().enumerate() {
            od[cx] = a.best.0;
            oi[cx] = a.best.1;
        }
        if let Some(p) = op {
            for (o, a) in p.iter_mut().zip(&acc) {
                *o = (a.near.0 < a.far.0).then(|| {
                    let near = (a.near.0, *items.get(a.near.1, a.near.2), a.near.1, a.near.2);
                    let far = (a.far.0, *items.get(a.far.1, a.far.2), a.far.1, a.far.2);
                    (near, far)
                });
                if o.is_some_and(|(n, f)| n.1 == f.1) {
                    *o = None;
                }
            }
        }
        nan
    };
    let nan = if pairs_below.is_some() {
        out_d
            .par_chunks_mut(cwu)
            .zip(out_i.par_chunks_mut(cwu))
            .zip(out_p.par_chunks_mut(cwu))
            .enumerate()
            .map(|(cy, ((od, oi), op))| row(cy, od, oi, Some(op)))
            .reduce(|| false, |a, b| a || b)
    } else {
        out_d
            .par_chunks_mut(cwu)
            .zip(out_i.par_chunks_mut(cwu))
            .enumerate()
            .map(|(cy, (od, oi))| row(cy, od, oi, None))
            .reduce(|| false, |a, b| a || b)
    };
    CoarsePrev {
        depth: Image::from_vec(cw, ch, out_d).expect("cw x ch values"),
        items: Image::from_vec(cw, ch, out_i).expect("cw x ch values"),
        pairs: out_p,
        nan,
    }
}

/// The motion buffer of [`zwarp_core::motion_field`] (seed 000 Sec. 3.1, camera motion plus
/// each object's own motion through the item buffer), with the per-object matrices computed
/// only for the *animated objects present in the item buffer*: building all of
/// [`Scene::object_deltas`] costs O(objects) serial matrix products per frame (6-7 ms at 93K
/// objects, more than the coarse warp), while a frame shows a few thousand. Bit-identical to
/// `motion_field(depth, Some(items), cam_a, cam_b, &scene.object_deltas(t_a, t_b))`.
///
/// Errors: as [`zwarp_core::motion_field`].
pub fn woc_motion_field(
    scene: &Scene,
    depth: &Image<f32>,
    items: &Image<u32>,
    cam_a: &Camera,
    cam_b: &Camera,
    t_a: f32,
    t_b: f32,
) -> Result<Image<zwarp_core::Motion>> {
    let n = scene.instances.len();
    let animated = |id: u32| (id as usize) < n && scene.instances[id as usize].animation.is_animated();
    motion_field_animated(scene, animated, depth, items, (cam_a, cam_b), (t_a, t_b))
}

/// [`woc_motion_field`] with the animation flags given by `animated` (from [`ObjectBounds`]
/// in [`woc_with`], so a frame reads no instance of a static object). The animated ids on
/// screen are gathered from the item buffer itself (sorted, deduplicated: a few per frame),
/// with no per-frame array over all objects (at 1M objects those were 5 MB to allocate, clear
/// and scan every frame).
fn motion_field_animated(
    scene: &Scene,
    animated: impl Fn(u32) -> bool + Sync,
    depth: &Image<f32>,
    items: &Image<u32>,
    (cam_a, cam_b): (&Camera, &Camera),
    (t_a, t_b): (f32, f32),
) -> Result<Image<zwarp_core::Motion>> {
    zwarp_core::motion::check_motion_inputs(depth, Some(items), cam_a)?;
    let (w, h) = depth.size();
    let wu = w as usize;
    // Empty pixels (depth 1) move with the camera, whatever their id (as motion_field).
    let mut ids: Vec<u32> = items
        .data()
        .par_chunks(wu)
        .zip(depth.data().par_chunks(wu))
        .flat_map_iter(|(ir, dr)| {
            let mut last = NO_ITEM;
            let mut seen = Vec::new();
            for (&id, &d) in ir.iter().zip(dr) {
                if id != last && d < 1.0 && animated(id) {
                    seen.push(id);
                    last = id;
                }
            }
            seen
        })
        .collect();
    ids.sort_unstable();
    ids.dedup();
    let vp_b = cam_b.view_proj();
    let mats: Vec<glam::Mat4> = ids.par_iter().map(|&id| vp_b * scene.instances[id as usize].delta(t_a, t_b)).collect();
    let inv_a = cam_a.view_proj().inverse();
    let mut out = Image::new(w, h, zwarp_core::Motion::default());
    out.data_mut().par_chunks_mut(wu).enumerate().for_each(|(y, row)| {
        for (x, o) in row.iter_mut().enumerate() {
            let i = y * wu + x;
            let (d, id) = (depth.data()[i], items.data()[i]);
            let m = match d < 1.0 && !ids.is_empty() && animated(id) {
                true => ids.binary_search(&id).map_or(&vp_b, |k| &mats[k]),
                false => &vp_b,
            };
            *o = zwarp_core::motion::reproject_pixel(
                &inv_a,
                m,
                (w, h),
                (cam_b.width, cam_b.height),
                x as u32,
                y as u32,
                d,
            );
        }
    });
    Ok(out)
}

/// Coarse texels whose footprint holds an *internal opening*: two different objects (the
/// nearest and the farthest fine pixel of the footprint) whose own screen motions, from
/// `prev_cam` at `t_a` to `cam` at `t_b` in fine pixels, pull them apart by more than
/// `min_separation` px/frame. Returns one flag per coarse texel (row-major, `cw x ch` of
/// [`coarse_camera`]).
///
/// Why: [`downsample_max`] keeps the farthest fine pixel of a footprint and that pixel's item,
/// so a coarse texel straddling a near object `A` and a farther `B` moves rigidly with `B`.
/// Where `A` slides away from `B` inside the footprint, the strip it uncovers (what is behind
/// `A`: `B`'s hidden part, or anything farther when `B` ends there too) gets `B`'s depth, and
/// the coarse opening-rim test never sees the boundary (it is inside one texel). Blanking these
/// texels is the coarse analogue of [`RimMode::Source`]. The separation direction is taken from
/// the far pixel to the near one; any relative motion within 120 degrees of it counts, so a
/// boundary running obliquely through the footprint is still caught. `pairs` comes from
/// [`reduce_prev`] (fine pixel coordinates in a `fw x fh` image).
#[allow(clippy::too_many_arguments)]
fn coarse_internal_openings(
    scene: &Scene,
    pairs: &[Option<(Px, Px)>],
    (fw, fh): (u32, u32),
    prev_cam: &Camera,
    cam: &Camera,
    t_a: f32,
    t_b: f32,
    min_separation: f32,
) -> Vec<bool> {
    // Object matrices of the items involved, computed once each.
    let mut ids: Vec<u32> = pairs.iter().flatten().flat_map(|(a, b)| [a.1, b.1]).collect();
    ids.sort_unstable();
    ids.dedup();
    let vp_b = cam.view_proj();
    let mats: Vec<glam::Mat4> = ids.par_iter().map(|&id| vp_b * scene.instances[id as usize].delta(t_a, t_b)).collect();
    let mat = |id: u32| &mats[ids.binary_search(&id).expect("collected above")];
    let inv_a = prev_cam.view_proj().inverse();
    let motion = |p: &Px| {
        zwarp_core::motion::reproject_pixel(&inv_a, mat(p.1), (fw, fh), (cam.width, cam.height), p.2, p.3, p.0).v
    };
    pairs
        .par_iter()
        .map(|pair| {
            pair.is_some_and(|(near, far)| {
                let rel = motion(&near) - motion(&far);
                let dir = Vec2::new(near.2 as f32 - far.2 as f32, near.3 as f32 - far.3 as f32).normalize();
                let len = rel.length();
                len > min_separation && rel.dot(dir) > -0.5 * len
            })
        })
        .collect()
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
    params.validate()?;
    check_time(t)?;
    check_time(prev.t)?;
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
    let n = scene.instances.len();
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
    let n_obj = bounds.len();
    let animated = |id: u32| (id as usize) < n_obj && bounds.is_animated(id);
    let motion = motion_field_animated(scene, animated, prev_depth, prev_items, (prev_cam, cam), (prev.t, t))?;
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
            Some(coarse_internal_openings(scene, &pairs, prev.depth.size(), full_prev_cam, full_cam, prev.t, t, sep))
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
    let objects = prepass(scene, bounds, t, cam, &Rapid::of(params, full_prev_cam, full_cam, prev.t));
    let predrawn: Vec<u32> = objects.iter().filter(|o| o.test == Test::Forced).map(|o| o.id).collect();
    if !predrawn.is_empty() {
        draw_exact(&mut predicted, scene, full_cam, t, &predrawn)?;
    }
    tm.draw_ms = ms(t0);

    // 4c. Far pixels near surfaces: bounded by static surfaces their ray crosses.
    if params.hole_bound && f == 1 {
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
    let kept = test_prepassed(&objects, cam, &map, hull);
    tm.test_ms = ms(t0);

    // 7. Hybrid object-space query of the heaviest survivors (not the predrawn ones).
    let t0 = Instant::now();
    let k = if f > 1 { 0 } else { params.hybrid_objects };
    let (hidden, tested) = if k > 0 {
        let candidates: Vec<u32> = kept.iter().copied().filter(|id| predrawn.binary_search(id).is_err()).collect();
        hybrid_cull(scene, &predicted, cam, t, &candidates, k, params.hybrid_min_triangles)?
    } else {
        (Vec::new(), 0)
    };
    let visible: Vec<u32> = if hidden.is_empty() {
        kept
    } else {
        kept.into_iter().filter(|id| hidden.binary_search(id).is_err()).collect()
    };
    tm.hybrid_ms = ms(t0);

    let crosses_near = objects.iter().filter(|o| o.test == Test::Keep).count();
    let stats = CullStats {
        objects: n,
        frustum_culled: n - objects.len(),
        occlusion_culled: objects.len() - visible.len() - hidden.len(),
        hybrid_culled: hidden.len(),
        hybrid_tested: tested,
        crosses_near,
        rapid: predrawn.len(),
    };
    tm.total_ms = ms(start);
    Ok(CullResult { visible, timings: tm, stats, predrawn, occlusion_map: Some(predicted) })
}

/// Draws `objects` at time `t` exactly into `predicted`, which has the size of the culling
/// resolution and bounds the depth `full_cam` renders: at full resolution directly; at a coarse
/// one into a far full-resolution buffer that is then reduced by max over each coarse pixel's
/// footprint (as the previous depth is, [`downsample_max`]) and merged by min, so every coarse
/// value stays an upper bound of the depth of the fine pixels under it. (Rasterizing at the
/// coarse resolution would give a covered coarse pixel the depth at its centre, which bounds
/// neither its uncovered fine pixels nor a sloped surface's far corner.)
fn draw_exact(predicted: &mut Image<f32>, scene: &Scene, full_cam: &Camera, t: f32, objects: &[u32]) -> Result<()> {
    if predicted.size() == (full_cam.width, full_cam.height) {
        return draw_into(predicted, None, scene, full_cam, t, objects);
    }
    let mut fine = Image::new(full_cam.width, full_cam.height, EMPTY_DEPTH);
    draw_into(&mut fine, None, scene, full_cam, t, objects)?;
    let coarse = max_over_footprints(&fine, predicted.size());
    predicted.data_mut().par_iter_mut().zip(coarse.data().par_iter()).for_each(|(p, &c)| *p = p.min(c));
    Ok(())
}

/// Depth-only twin of [`downsample_max`]: each of the `cw x ch` coarse pixels takes the max of
/// `fine` over every fine pixel its footprint touches (the bound each coarse texel of an
/// occlusion map must respect). `cw`, `ch` at least 1 and at most `fine`'s size.
pub fn max_over_footprints(fine: &Image<f32>, (cw, ch): (u32, u32)) -> Image<f32> {
    let (fw, fh) = fine.size();
    let xs: Vec<(u32, u32)> = (0..cw).map(|cx| footprint(cx, fw, cw)).collect();
    let mut out = Image::new(cw, ch, f32::NEG_INFINITY);
    out.data_mut().par_chunks_mut(cw as usize).enumerate().for_each(|(cy, row)| {
        let (y0, y1) = footprint(cy as u32, fh, ch);
        for (o, &(x0, x1)) in row.iter_mut().zip(&xs) {
            for y in y0..y1 {
                for &d in &fine.row(y)[x0 as usize..x1 as usize] {
                    *o = o.max(d);
                }
            }
        }
    });
    out
}

/// What the screen-space stage still has to decide for an object in the frustum ([`prepass`]).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Test {
    /// Rapid-motion object: drawn into the occlusion map and kept.
    Forced,
    /// Its box crosses the near plane: kept.
    Keep,
    /// Test this screen rectangle (culling resolution) and nearest corner depth.
    Rect(PixelRect, f32),
}

/// An object of the frustum, after [`prepass`].
#[derive(Clone, Copy, Debug)]
struct Prepassed {
    id: u32,
    aabb: Aabb,
    test: Test,
}

/// Rapid-motion classification of [`WocParams::rapid_motion`] for one frame pair.
struct Rapid<'a> {
    /// Threshold in full-resolution pixels per frame (`None`: path disabled).
    threshold: Option<f32>,
    /// Camera of the speed's first view (the current one unless the camera motion counts).
    cam_a: &'a Camera,
    /// Current full-resolution camera.
    cam_b: &'a Camera,
    t_a: f32,
    includes_camera: bool,
}

impl<'a> Rapid<'a> {
    fn of(params: &WocParams, full_prev_cam: &'a Camera, full_cam: &'a Camera, t_a: f32) -> Self {
        Rapid {
            threshold: params.rapid_threshold_px(full_cam.width),
            cam_a: if params.rapid_includes_camera { full_prev_cam } else { full_cam },
            cam_b: full_cam,
            t_a,
            includes_camera: params.rapid_includes_camera,
        }
    }
}

/// Objects handed to the parallel per-object loops in runs of at least this many (one rayon
/// task per object costs more than the test of a culled one).
const OBJECT_CHUNK: usize = 512;

/// The per-object pass of [`woc`] before the occlusion map exists: bounds at `t`, VFC, the
/// rapid-motion speed (thesis Sec. IV.1) and the box's screen rectangle for `cam` (the culling
/// resolution), in one read of each instance. Returns the objects in the frustum (whose
/// rectangle is not outside the image), increasing ids. Static objects skip the speed unless the
/// camera's motion counts (their own speed is 0).
fn prepass(scene: &Scene, bounds: &ObjectBounds, t: f32, cam: &Camera, rapid: &Rapid<'_>) -> Vec<Prepassed> {
    let frustum = Frustum::from_camera(cam);
    let vp = cam.view_proj();
    (0..scene.instances.len() as u32)
        .into_par_iter()
        .with_min_len(OBJECT_CHUNK)
        .filter_map(|id| {
            let aabb = bounds.at(scene, id, t);
            if !frustum.intersects(&aabb) {
                return None;
            }
            if let Some(thr) = rapid.threshold {
                let moving = rapid.includes_camera || bounds.is_animated(id);
                if moving && screen_speed(scene, id, rapid.cam_a, rapid.t_a, rapid.cam_b, t) > thr {
                    return Some(Prepassed { id, aabb, test: Test::Forced });
                }
            }
            let test = match screen_rect_with(&aabb, &vp, cam.width, cam.height) {
                ScreenRect::Outside => return None,
                ScreenRect::CrossesNear => Test::Keep,
                ScreenRect::Rect { rect, nearest } => Test::Rect(rect, nearest),
            };
            Some(Prepassed { id, aabb, test })
        })
        .collect()
}

/// The screen-space stage of [`woc`] over the [`prepass`]ed objects: ids (increasing) of those
/// kept, i.e. forced, crossing the near plane, or whose rectangle is not occluded in `map`
/// ([`DEPTH_TOLERANCE`] included) and, with `hull = Some((predicted depth, slack))`,
/// whose silhouette still meets a pixel that could show them ([`WocParams::hull_test`]).
fn test_prepassed(
    objects: &[Prepassed],
    cam: &Camera,
    map: &impl MaxDepthQuery,
    hull: Option<(&[f32], f32)>,
) -> Vec<u32> {
    let vp = cam.view_proj();
    objects
        .par_iter()
        .with_min_len(OBJECT_CHUNK / 2)
        .filter_map(|o| match o.test {
            Test::Forced | Test::Keep => Some(o.id),
            Test::Rect(rect, nearest) => {
                let limit = nearest - DEPTH_TOLERANCE;
                if map.is_occluded(rect, limit) {
                    return None;
                }
                match hull {
                    Some((depth, slack))
                        if hull_hides(&o.aabb, rect, limit, &vp, (cam.width, cam.height), depth, slack) =>
                    {
                        None
                    }
                    _ => Some(o.id),
                }
            }
        })
        .collect()
}

/// The 8 neighbour offsets `(dx, dy)` of [`opening_rim_dirs`]; bit `k` of a direction mask
/// stands for `NEIGHBOURS[k]`.
pub const NEIGHBOURS: [(i32, i32); 8] = [(-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1)];

/// How far (pixels, along the unit neighbour direction) behind a rim texel's centre a preimage
/// still counts as "outer" in [`open_rims_in_target`]. A rim texel's centre is covered by its
/// object; for a locally straight edge with outward normal `n`, the uncovered part of the
/// texel lies in `(q - c) . n > 0`. The nearest of the 8 neighbour directions `d` is within
/// 22.5 degrees of `n` (and that neighbour is not covered), so over the texel
/// (`|q - c| <= 0.71`) the uncovered part satisfies `(q - c) . d >= -0.71 sin 22.5 = -0.27`.
pub const RIM_MARGIN: f32 = 0.3;

/// Opening-rim directions of the previous frame (seed 000 Sec. 5, "depth holes are
/// conservatively kept at the far-clipping depth", applied to sub-pixel holes): for every
/// texel `c`, bit `k` is set when its neighbour `c' = c + NEIGHBOURS[k]` shows a different,
/// farther object (both non-empty) and their motions separate them by more than
/// `min_separation` pixels per frame, `(v(c) - v(c')) . (c - c') > min_separation`.
///
/// Why: the backward warp accepts a source texel whose forward position is within half a
/// pixel of a target pixel centre, i.e. every texel carries a 1x1 footprint. Where a near
/// object `A` slides away from a farther object `B` by less than a pixel per frame, the strip
/// between them is a disocclusion (what is behind is unknown: `B`'s hidden part or anything
/// farther), but the footprint of `A`'s rim texel still covers it, so the warp fills it with
/// `A`'s depth and no hole appears; the 1-pixel erosion cannot reopen it because both sides are
/// near. (`B`'s rim texel's footprint starts where `B`'s visible part starts, so only the near
/// side needs care.) Boundaries against empty pixels need nothing (the empty side is already a
/// far hole that the erosion widens), and closing boundaries (`A` moving over `B`) reveal
/// nothing.
///
/// Errors: sizes differ, negative or non-finite threshold.
pub fn opening_rim_dirs(
    depth: &Image<f32>,
    items: &Image<u32>,
    motion: &Image<zwarp_core::Motion>,
    min_separation: f32,
) -> Result<Image<u8>> {
    if !(min_separation.is_finite() && min_separation >= 0.0) {
        return Err(Error::invalid(format!("rim separation threshold must be >= 0 pixels, got {min_separation}")));
    }
    depth.check_same_size(items, "depth vs item buffer")?;
    depth.check_same_size(motion, "depth vs motion buffer")?;
    let (w, h) = depth.size();
    let (wi, hi) = (w as i64, h as i64);
    let (dd, it, mv) = (depth.data(), items.data(), motion.data());
    let mut out = vec![0u8; dd.len()];
    out.par_chunks_mut(w as usize).enumerate().for_each(|(y, row)| {
        let y = y as i64;
        for (x, o) in row.iter_mut().enumerate() {
            let x = x as i64;
            let i = (y * wi + x) as usize;
            let (d, id) = (dd[i], it[i]);
            if d >= EMPTY_DEPTH || id == NO_ITEM {
                continue;
            }
            let v = mv[i].v;
            let mut mask = 0u8;
            for (k, &(dx, dy)) in NEIGHBOURS.iter().enumerate() {
                let (xx, yy) = (x + dx as i64, y + dy as i64);
                if !(0..wi).contains(&xx) || !(0..hi).contains(&yy) {
                    continue;
                }
                let j = (yy * wi + xx) as usize;
                let (dn, idn) = (dd[j], it[j]);
                if idn == NO_ITEM || idn == id || dn >= EMPTY_DEPTH || dn <= d {
                    continue;
                }
                // c - c' = (-dx, -dy): positive when c moves away from c' relative to it.
                let rel = v - mv[j].v;
                if -(rel.x * dx as f32 + rel.y * dy as f32) > min_separation {
                    mask |= 1 << k;
                }
            }
            *o = mask;
        }
    });
    Image::from_vec(w, h, out)
}

/// `depth` with every texel that has an opening-rim direction set to [`EMPTY_DEPTH`].
fn blank_rims(depth: &Image<f32>, dirs: &Image<u8>) -> Image<f32> {
    let data = depth.data().par_iter().zip(dirs.data().par_iter()).map(|(&d, &m)| if m != 0 { EMPTY_DEPTH } else { d });
    Image::from_vec(depth.width(), depth.height(), data.collect()).expect("same size as depth")
}

/// Source-side opening rims ([`RimMode::Source`]): `depth` with every texel that has an
/// opening-rim direction ([`opening_rim_dirs`]) set to [`EMPTY_DEPTH`], so the warp leaves a
/// hole over its whole footprint.
///
/// Errors: sizes differ, negative or non-finite threshold.
pub fn opening_rims(
    depth: &Image<f32>,
    items: &Image<u32>,
    motion: &Image<zwarp_core::Motion>,
    min_separation: f32,
) -> Result<Image<f32>> {
    let dirs = opening_rim_dirs(depth, items, motion, min_separation)?;
    Ok(blank_rims(depth, &dirs))
}

/// Target-side opening rims ([`RimMode::Target`]): sets to [`EMPTY_DEPTH`] every pixel `p` of
/// `predicted` (the warped, possibly eroded depth) that converged on a source texel `c` with
/// opening-rim directions `dirs` (from [`opening_rim_dirs`]) and whose exact preimage
/// `q* = p - v(c)` lies on the outer side of `c`, `(q* - c) . d >= -RIM_MARGIN` for one of the
/// texel's unit opening directions `d`. Returns how many pixels were opened.
///
/// Why this is enough: with nearest motion sampling the texel moves rigidly by `v(c)`, so `p`
/// shows the point `q*` of texel `c`. If `q*` is covered by `c`'s object (the inner side of
/// its centre, which the object covers), `p` truly shows that object's surface moved by its
/// own motion; only preimages beyond the texel centre towards the separating neighbour can be
/// uncovered, i.e. be the disocclusion strip ([`RIM_MARGIN`] covers oblique edges). The
/// pixels opened are the strip itself, so unlike [`RimMode::Source`] they are set after the
/// erosion and are not widened.
///
/// Errors: sizes differ.
pub fn open_rims_in_target(
    predicted: &mut Image<f32>,
    source: &Image<SourcePos>,
    state: &Image<PixelState>,
    motion: &Image<zwarp_core::Motion>,
    dirs: &Image<u8>,
) -> Result<usize> {
    predicted.check_same_size(source, "predicted depth vs warp sources")?;
    predicted.check_same_size(state, "predicted depth vs warp states")?;
    motion.check_same_size(dirs, "motion vs rim directions")?;
    let w = predicted.width();
    let (sw, sh) = motion.size();
    let unit: [Vec2; 8] = NEIGHBOURS.map(|(dx, dy)| Vec2::new(dx as f32, dy as f32).normalize());
    let (src, st, mv, dm) = (source.data(), state.data(), motion.data(), dirs.data());
    let opened: usize = predicted
        .data_mut()
        .par_chunks_mut(w as usize)
        .enumerate()
        .map(|(y, row)| {
            let mut n = 0;
            for (x, d) in row.iter_mut().enumerate() {
                let i = y * w as usize + x;
                if st[i] != PixelState::Converged || *d >= EMPTY_DEPTH {
                    continue;
                }
                let q = src[i].q;
                let (cx, cy) = (q.x.floor(), q.y.floor());
                if !(cx >= 0.0 && cy >= 0.0 && cx < sw as f32 && cy < sh as f32) {
                    continue;
                }
                let c = cy as usize * sw as usize + cx as usize;
                let mask = dm[c];
                if mask == 0 {
                    continue;
                }
                let p = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                let local = p - mv[c].v - Vec2::new(cx + 0.5, cy + 0.5);
                if (0..8).any(|k| mask & (1 << k) != 0 && local.dot(unit[k]) >= -RIM_MARGIN) {
                    *d = EMPTY_DEPTH;
                    n += 1;
                }
            }
            n
        })
        .sum();
    Ok(opened)
}

/// Far pixels within this many pixels (Chebyshev) of a surface pixel get a static-ray bound
/// ([`WocParams::hole_bound`]); the inside of wide far regions (sky) is not marched.
pub const HOLE_BOUND_RADIUS: usize = 4;

/// Flags the far pixels of `depth` that have a non-far pixel within `r` (Chebyshev).
fn near_surface(depth: &Image<f32>, r: usize) -> Vec<bool> {
    let (w, h) = (depth.width() as usize, depth.height() as usize);
    let d = depth.data();
    // Separable dilation of the surface mask: rows, then columns.
    let rows: Vec<bool> = (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            (x.saturating_sub(r)..(x + r + 1).min(w)).any(|xx| d[y * w + xx] < EMPTY_DEPTH)
        })
        .collect();
    (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            d[i] >= EMPTY_DEPTH && (y.saturating_sub(r)..(y + r + 1).min(h)).any(|yy| rows[yy * w + x])
        })
        .collect()
}

/// `radius` steps of the 3x3 max erosion ([`erode_max`]): a `(2 radius + 1)^2` max filter.
fn erode_n(mut depth: Image<f32>, radius: u32) -> Image<f32> {
    for _ in 0..radius {
        depth = erode_max(&depth);
    }
    depth
}

/// Baseline NOCULL: every object is drawn.
pub fn nocull(scene: &Scene) -> CullResult {
    let n = scene.instances.len();
    CullResult {
        visible: (0..n as u32).collect(),
        timings: CullTimings::default(),
        stats: CullStats { objects: n, ..CullStats::default() },
        predrawn: Vec::new(),
        occlusion_map: None,
    }
}

/// Baseline VFC: view-frustum culling only.
pub fn vfc_cull(scene: &Scene, cam: &Camera, t: f32) -> Result<CullResult> {
    vfc_cull_with(scene, &ObjectBounds::new(scene), cam, t)
}

/// [`vfc_cull`] with the object boxes kept across frames (as [`woc_with`]).
pub fn vfc_cull_with(scene: &Scene, bounds: &ObjectBounds, cam: &Camera, t: f32) -> Result<CullResult> {
    bounds.check(scene)?;
    check_time(t)?;
    let t0 = Instant::now();
    let frustum = Frustum::from_camera(cam);
    let n = scene.instances.len();
    let visible: Vec<u32> = (0..n as u32)
        .into_par_iter()
        .with_min_len(OBJECT_CHUNK)
        .filter(|&id| frustum.intersects(&bounds.at(scene, id, t)))
        .collect();
    let stats = CullStats { objects: n, frustum_culled: n - visible.len(), ..CullStats::default() };
    let total = ms(t0);
    Ok(CullResult {
        visible,
        timings: CullTimings { test_ms: total, total_ms: total, ..CullTimings::default() },
        stats,
        predrawn: Vec::new(),
        occlusion_map: None,
    })
}

/// Baseline "last frame": the previous depth buffer used as the occlusion map **without
/// reprojection** (a common shortcut, DESIGN.md). Unsafe: it culls objects that became
/// visible; kept to show that error, never a default.
pub fn lastframe(
    scene: &Scene,
    prev_depth: &Image<f32>,
    cam: &Camera,
    t: f32,
    kind: MaxDepthKind,
) -> Result<CullResult> {
    cull_against_depth(scene, prev_depth, cam, t, kind, None)
}

/// The ideal screen-space test (thesis Sec. V.1 "reference screen-space culling using the true
/// depth buffer"): VFC + exact N-buffer test of every AABB against the depth buffer rendered
/// at the current view. The best culling ratio any AABB-in-screen-space method can reach.
pub fn ideal_screen_space(scene: &Scene, true_depth: &Image<f32>, cam: &Camera, t: f32) -> Result<CullResult> {
    cull_against_depth(scene, true_depth, cam, t, MaxDepthKind::NBuffer, None)
}

/// Sorted distinct object ids present in an item buffer (ids `>= n_objects` and [`NO_ITEM`]
/// ignored): the ideal visible set REF.
pub fn visible_from_items(items: &Image<u32>, n_objects: usize) -> Vec<u32> {
    let mut seen = vec![false; n_objects];
    for &id in items.data() {
        if id != NO_ITEM && (id as usize) < n_objects {
            seen[id as usize] = true;
        }
    }
    (0..n_objects as u32).filter(|&i| seen[i as usize]).collect()
}

/// Baseline REF: renders the full frame and returns the objects present in its item buffer
/// (the ideal visible set); the rendered depth is returned as `occlusion_map`.
pub fn reference(scene: &Scene, cam: &Camera, t: f32) -> Result<CullResult> {
    check_time(t)?;
    let t0 = Instant::now();
    let frame = render_frame(scene, cam, t, &FrameOptions::default())?;
    let visible = visible_from_items(&frame.items, scene.instances.len());
    let total = ms(t0);
    let objects = scene.instances.len();
    Ok(CullResult {
        stats: CullStats { objects, occlusion_culled: objects - visible.len(), ..CullStats::default() },
        visible,
        timings: CullTimings { draw_ms: total, total_ms: total, ..CullTimings::default() },
        predrawn: Vec::new(),
        occlusion_map: Some(frame.depth),
    })
}

/// Outcome of [`twophase`].
#[derive(Clone, Debug, PartialEq)]
pub struct TwoPhaseResult {
    /// Phase 1: last frame's visible objects still in the frustum (drawn first).
    pub first: Vec<u32>,
    /// Phase 2: objects found visible against the phase-1 depth (drawn second).
    pub second: Vec<u32>,
    /// `first` and `second` together, increasing.
    pub visible: Vec<u32>,
    /// The drawn objects that pass the screen-space test against the *final* depth: the set
    /// the next frame draws first (without this re-test an object drawn once would be drawn in
    /// phase 1 forever, and the set would only grow).
    pub next_visible: Vec<u32>,
    /// Depth after both draws (the frame's final depth buffer).
    pub depth: Image<f32>,
    /// Triangles drawn in phase 1 and phase 2.
    pub triangles: (usize, usize),
    /// `draw_ms` = both draws, `build_ms`/`test_ms` = the culling between them.
    pub timings: CullTimings,
}

/// Baseline two-phase culling (Haar & Aaltonen 2015; Nießner & Loop 2012; seed 000 Sec. 5.1):
/// draw last frame's visible set, build the max-depth structure from that depth, test the rest,
/// draw the newly visible ones. Safe, but costs two geometry passes with a dependency between
/// them.
pub fn twophase(
    scene: &Scene,
    prev_visible: &[u32],
    cam: &Camera,
    t: f32,
    kind: MaxDepthKind,
) -> Result<TwoPhaseResult> {
    twophase_with(scene, &ObjectBounds::new(scene), prev_visible, cam, t, kind)
}

/// [`twophase`] with the object boxes kept across frames (as [`woc_with`]).
pub fn twophase_with(
    scene: &Scene,
    bounds: &ObjectBounds,
    prev_visible: &[u32],
    cam: &Camera,
    t: f32,
    kind: MaxDepthKind,
) -> Result<TwoPhaseResult> {
    bounds.check(scene)?;
    check_time(t)?;
    let n = scene.instances.len();
    if let Some(&bad) = prev_visible.iter().find(|&&id| id as usize >= n) {
        return Err(Error::invalid(format!("previous visible set names object {bad} but the scene has {n}")));
    }
    let start = Instant::now();
    let mut tm = CullTimings::default();
    let aabbs = bounds.all_at(scene, t);
    let frustum = Frustum::from_camera(cam);
    let mut in_first = vec![false; n];
    for &id in prev_visible {
        in_first[id as usize] = frustum.intersects(&aabbs[id as usize]);
    }
    let first: Vec<u32> = (0..n as u32).filter(|&id| in_first[id as usize]).collect();
    let tris = |ids: &[u32]| -> usize {
        ids.iter().map(|&id| scene.meshes[scene.instances[id as usize].mesh as usize].triangle_count()).sum()
    };

    let t0 = Instant::now();
    let mut depth = Image::new(cam.width, cam.height, 1.0f32);
    if !first.is_empty() {
        draw_into(&mut depth, None, scene, cam, t, &first)?;
    }
    tm.draw_ms = ms(t0);

    let t0 = Instant::now();
    let map = MaxDepthMap::build(kind, &depth)?;
    tm.build_ms = ms(t0);
    let t0 = Instant::now();
    let classes = test_objects(&aabbs, cam, &map, Some(&in_first));
    let second: Vec<u32> =
        (0..n).filter(|&id| matches!(classes[id], Class::Visible | Class::CrossesNear)).map(|id| id as u32).collect();
    tm.test_ms = ms(t0);

    let t0 = Instant::now();
    if !second.is_empty() {
        draw_into(&mut depth, None, scene, cam, t, &second)?;
    }
    tm.draw_ms += ms(t0);
    let mut visible = [first.as_slice(), second.as_slice()].concat();
    visible.sort_unstable();

    // Visibility for the next frame: re-test the drawn objects against the final depth.
    let t0 = Instant::now();
    let final_map = MaxDepthMap::build(kind, &depth)?;
    let mut drawn = vec![false; n];
    for &id in &visible {
        drawn[id as usize] = true;
    }
    let recheck = test_objects(&aabbs, cam, &final_map, None);
    let next_visible: Vec<u32> = (0..n)
        .filter(|&id| drawn[id] && matches!(recheck[id], Class::Visible | Class::CrossesNear))
        .map(|id| id as u32)
        .collect();
    tm.build_ms += ms(t0);
    tm.total_ms = ms(start);
    Ok(TwoPhaseResult {
        triangles: (tris(&first), tris(&second)),
        first,
        second,
        visible,
        next_visible,
        depth,
        timings: tm,
    })
}

/// Culling accuracy of a visible set against REF (thesis Sec. V.1, Table 1 and 3).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct CullAccuracy {
    /// Objects in the scene.
    pub objects: usize,
    /// Objects the method keeps.
    pub visible: usize,
    /// Objects REF keeps.
    pub reference: usize,
    /// Visible in REF but culled (culling errors, unsafe).
    pub false_negatives: usize,
    /// Kept but invisible in REF (wasted draws, safe).
    pub false_positives: usize,
    /// Object error: `false_negatives / objects` (thesis Table 1).
    pub object_error: f64,
    /// Culling ratio CR: culled objects over the objects REF culls (thesis Table 3: NOCULL 0,
    /// REF 1); 1 when REF culls nothing.
    pub culling_ratio: f64,
}

/// Compares a visible set with the reference one (both increasing or not; duplicates ignored).
pub fn accuracy(visible: &[u32], reference: &[u32], n_objects: usize) -> CullAccuracy {
    let mut v = vec![false; n_objects];
    let mut r = vec![false; n_objects];
    for &id in visible.iter().filter(|&&i| (i as usize) < n_objects) {
        v[id as usize] = true;
    }
    for &id in reference.iter().filter(|&&i| (i as usize) < n_objects) {
        r[id as usize] = true;
    }
    let (mut nv, mut nr, mut fneg, mut fpos) = (0, 0, 0, 0);
    for i in 0..n_objects {
        nv += v[i] as usize;
        nr += r[i] as usize;
        fneg += (r[i] && !v[i]) as usize;
        fpos += (v[i] && !r[i]) as usize;
    }
    let ref_culled = n_objects - nr;
    CullAccuracy {
        objects: n_objects,
        visible: nv,
        reference: nr,
        false_negatives: fneg,
        false_positives: fpos,
        object_error: if n_objects == 0 { 0.0 } else { fneg as f64 / n_objects as f64 },
        culling_ratio: if ref_culled == 0 { 1.0 } else { (n_objects - nv) as f64 / ref_culled as f64 },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_draw_at_a_coarse_resolution_is_the_max_reduction_of_the_fine_draw() {
        // A sloped quad and a small copy in front of it over a far prediction, at 1/3 of an odd size
        // (97x61: the footprints straddle fine pixels): every coarse value must be the max of
        // the full-resolution drawing over its footprint (far where any fine pixel is
        // uncovered), min with what was predicted there.
        use zwarp_core::{Animation, Mesh};
        let mut s = Scene { name: "exact".into(), ..Default::default() };
        let quad = Mesh::new(
            vec![
                Vec3::new(-2.0, -1.0, -1.0),
                Vec3::new(2.0, -1.0, 1.0),
                Vec3::new(2.0, 1.0, 1.0),
                Vec3::new(-2.0, 1.0, -1.0),
            ],
            vec![[0, 1, 2], [0, 2, 3]],
        )
        .unwrap();
        let q = s.add_mesh(quad);
        s.add_instance(q, glam::Mat4::IDENTITY, Vec3::ONE, Animation::Static, false);
        s.add_instance(
            q,
            glam::Mat4::from_scale_rotation_translation(
                Vec3::splat(0.2),
                glam::Quat::IDENTITY,
                Vec3::new(0.5, 0.3, 1.5),
            ),
            Vec3::ONE,
            Animation::Static,
            false,
        );
        let cam = Camera::perspective(Vec3::new(0.3, 0.2, 6.0), Vec3::ZERO, Vec3::Y, 0.9, 0.5, 50.0, 97, 61).unwrap();
        let coarse = coarse_camera(&cam, 3);
        let mut predicted = Image::new(coarse.width, coarse.height, 0.999f32);
        *predicted.get_mut(16, 10) = 0.5; // a near prediction the draw must not raise
        let before = predicted.clone();
        draw_exact(&mut predicted, &s, &cam, 0.0, &[0, 1]).unwrap();
        let mut fine = Image::new(cam.width, cam.height, EMPTY_DEPTH);
        draw_into(&mut fine, None, &s, &cam, 0.0, &[0, 1]).unwrap();
        let items = Image::new(cam.width, cam.height, 0u32);
        let (reduced, _) = downsample_max(&fine, &items, coarse.width, coarse.height).unwrap();
        let mut lowered = 0;
        for i in 0..predicted.len() {
            assert_eq!(predicted.data()[i], before.data()[i].min(reduced.data()[i]), "texel {i}");
            lowered += usize::from(predicted.data()[i] < before.data()[i]);
        }
        assert!(lowered > 50, "the quad covers ~15 % of the view: {lowered} texels lowered");
        // At full resolution it is the plain depth-tested draw.
        let mut full = Image::new(cam.width, cam.height, 0.999f32);
        draw_exact(&mut full, &s, &cam, 0.0, &[0, 1]).unwrap();
        let mut direct = Image::new(cam.width, cam.height, 0.999f32);
        draw_into(&mut direct, None, &s, &cam, 0.0, &[0, 1]).unwrap();
        assert_eq!(full, direct);
    }

    #[test]
    fn hull_slack_shrinks_to_fine_centres_only_at_exact_divisors() {
        let cam = Camera::perspective(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 1.0, 0.1, 50.0, 960, 540).unwrap();
        assert_eq!(hull_slack(&cam, &cam), 0.01 - 0.5);
        assert_eq!(hull_slack(&coarse_camera(&cam, 4), &cam), 0.01 - 0.125);
        assert_eq!(hull_slack(&coarse_camera(&cam, 6), &cam), 0.01 - 0.5 / 6.0);
        // 540 / 8 = 67.5: the coarse rows straddle fine rows, the whole square counts.
        assert_eq!(hull_slack(&coarse_camera(&cam, 8), &cam), 0.01);
        let odd = cam.with_size(97, 61).unwrap();
        assert_eq!(hull_slack(&coarse_camera(&odd, 2), &odd), 0.01);
    }
}
