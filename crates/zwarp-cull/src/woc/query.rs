//! The screen-space occlusion query of WOC (seed 000 Sec. 5.2, thesis Sec. III-IV): VFC, then
//! each object's AABB rectangle and nearest depth against a max-depth structure, the
//! projected-hull refinement of small rectangles, and the hybrid object-space query of the
//! heaviest survivors (thesis Sec. IV.2).

use super::{aabb_triangles, check_camera_depth, check_time, ms, CullResult, CullStats, CullTimings};
use crate::bounds::ObjectBounds;
use crate::frustum::Frustum;
use crate::maxdepth::{MaxDepthKind, MaxDepthMap, MaxDepthQuery};
use crate::screen::{screen_rect_with, PixelRect, ScreenRect};
use glam::Vec2;
use rayon::prelude::*;
use std::time::Instant;
use zwarp_core::{Aabb, Camera, Error, Image, Result, Scene};
use zwarp_raster::any_fragment_visible;

/// Depth tolerance of the pipeline's screen-space test: an object is culled only when the max
/// depth over its rect is below its nearest corner depth by more than this. The rasterizer
/// interpolates depth and the motion field reprojects it in f32, so a face seen head-on (an
/// AABB face, e.g. a building wall) can come out a few ulps nearer than its own box corner; a
/// window onto that face would then hide the object from itself. 1e-6 is about 16 ulps near
/// depth 1 (millimetres at 10 m with near = 0.1, far = 100) and far below real occluder gaps.
pub const DEPTH_TOLERANCE: f32 = 1e-6;

/// How one object was classified by [`test_objects`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Class {
    Frustum,
    Forced,
    CrossesNear,
    Occluded,
    Visible,
}

/// VFC + screen-space max-depth test of every object (parallel). `forced[id]` objects are
/// kept without a test.
pub(crate) fn test_objects(
    aabbs: &[Aabb],
    cam: &Camera,
    map: &impl MaxDepthQuery,
    forced: Option<&[bool]>,
) -> Vec<Class> {
    test_objects_in(aabbs, None, cam, map, forced)
}

/// [`test_objects`] with the VFC result given (`inside[id]`) when already computed.
pub(crate) fn test_objects_in(
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
/// [`WocParams::hull_test`](super::WocParams::hull_test); bigger objects keep the rectangle's answer (scanning them would
/// cost more than drawing most of them).
pub const HULL_TEST_MAX_AREA: u64 = 16_384;

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
pub(crate) fn hull_hides(
    b: &Aabb,
    rect: PixelRect,
    limit: f32,
    vp: &glam::Mat4,
    (w, h): (u32, u32),
    predicted: &[f32],
    slack: f32,
) -> bool {
    use zwarp_core::round::{ceil, floor};
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
        // x - slack <= xb and x + 1 + slack >= xa, clamped before rounding (integer limits:
        // the same bounds as rounding first).
        let (x0, x1) = (rect.x0 as f32, rect.x1 as f32);
        let first = ceil((xa - 1.0 - slack).clamp(x0, x1)) as u32;
        let last = (floor((xb + slack).clamp(x0 - 1.0, x1)) + 1.0).min(x1).max(first as f32) as u32;
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

pub(crate) fn collect(classes: &[Class], hybrid_before: Option<&[Class]>) -> (Vec<u32>, CullStats) {
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

/// Culls the objects of `scene` at time `t` for `cam` against any depth buffer `depth` (VFC,
/// then the screen-space test with the chosen max-depth structure). Objects flagged in
/// `forced` are kept untested. Building block of [`woc`](super::woc), [`lastframe`](super::lastframe) and
/// [`ideal_screen_space`](super::ideal_screen_space); usable with an engine's own predicted depth.
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

/// [`cull_against_depth`] with the object boxes kept across frames (as [`woc_with`](super::woc_with)).
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
