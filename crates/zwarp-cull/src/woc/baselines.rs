//! The baselines WOC is compared with (seed 000 Sec. 5.3, thesis Sec. V): NOCULL, VFC,
//! last-frame depth, two-phase culling, the ideal screen-space test and REF (exact
//! visibility from the item buffer).

use super::{check_time, cull_against_depth, ms, test_objects, Class, CullResult, CullStats, CullTimings};
use crate::bounds::ObjectBounds;
use crate::frustum::Frustum;
use crate::maxdepth::{MaxDepthKind, MaxDepthMap};
use std::time::Instant;
use zwarp_core::{Camera, Error, Image, Result, Scene, NO_ITEM};
use zwarp_raster::{draw_into, render_frame, FrameOptions};

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

/// [`vfc_cull`] with the object boxes kept across frames (as [`woc_with`](super::woc_with)).
pub fn vfc_cull_with(scene: &Scene, bounds: &ObjectBounds, cam: &Camera, t: f32) -> Result<CullResult> {
    bounds.check(scene)?;
    check_time(t)?;
    let t0 = Instant::now();
    let frustum = Frustum::from_camera(cam);
    let n = scene.instances.len();
    let visible = frustum.filter_map_ids(n as u32, |id| bounds.at(scene, id, t), |id, _| Some(id));
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
/// reprojection** (a common shortcut; ARCHITECTURE.md "Pitfalls of public implementations").
/// Unsafe: it culls objects that became visible; kept to show that error, never a default.
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

/// [`twophase`] with the object boxes kept across frames (as [`woc_with`](super::woc_with)).
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
