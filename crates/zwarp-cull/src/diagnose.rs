//! Culling-error diagnostics (thesis Sec. V.1 "object error"): for every object a method culled
//! although the full render shows it, why it was culled. Used by [`crate::run_sequence`] to fill
//! [`crate::FrameReport::culled_visible`] and by the CLI's JSON output.

use serde::Serialize;
use zwarp_core::{Camera, Image, Scene, NO_ITEM};

use crate::maxdepth::max_in_rect;
use crate::screen::{screen_rect, ScreenRect};
use crate::woc::{screen_speed, PrevFrame, DEPTH_TOLERANCE};

/// One culling error: an object visible in the reference render (REF item buffer) that the
/// method culled, with the quantities that explain it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CulledVisible {
    /// Object (instance) id.
    pub id: u32,
    /// Pixels the object covers in the reference render.
    pub pixels: usize,
    /// Pixels it covered in the previous (drawn) frame; `None` without a previous frame.
    pub prev_pixels: Option<usize>,
    /// Screen-space speed of the object's own motion (pixels per frame, current camera).
    pub own_speed_px: f32,
    /// Screen-space speed including the camera motion (pixels per frame).
    pub total_speed_px: f32,
    /// Of its reference pixels, how many held an *animated* object in the previous frame at the
    /// same pixel (it was revealed there by a moving occluder).
    pub prev_moving_occluder_pixels: usize,
    /// Of its reference pixels, how many held nothing (sky) in the previous frame.
    pub prev_empty_pixels: usize,
    /// Distinct items of the previous frame in the 3x3 neighbourhoods of its reference pixels
    /// (`NO_ITEM` for empty pixels), increasing: what surrounded the place it appears at.
    pub prev_items_around: Vec<u32>,
    /// Previous-frame depth at its reference pixels (min, max).
    pub prev_depth: (f32, f32),
    /// Which test culled it: `"screen"` (its AABB rect is occluded in the occlusion map),
    /// `"hybrid"` (the rect passes; the object-space query culled it) or `"frustum"`.
    pub stage: &'static str,
    /// Nearest depth of its AABB (the value the rect test compares with).
    pub aabb_nearest: f32,
    /// Max of the occlusion map over the AABB's rect (it is culled when this is below
    /// `aabb_nearest - DEPTH_TOLERANCE`).
    pub map_max_over_rect: f32,
    /// True depth at its reference pixels (min, max).
    pub true_depth: (f32, f32),
    /// Occlusion-map (predicted) depth at its reference pixels (min, max).
    pub predicted_depth: (f32, f32),
    /// Its reference pixels where the predicted depth is *nearer* than the true depth by more
    /// than [`DEPTH_TOLERANCE`] (the prediction wrongly hides them).
    pub wrong_pixels: usize,
}

/// Lists every object of `reference_items` (the full render at time `t`, camera `cam`) that is
/// missing from `visible` (increasing or not), with the diagnostics of [`CulledVisible`].
/// `occlusion_map` is the depth the method tested against (same size as `cam`; `None` for
/// methods without one), `prev` the previous drawn frame (its items locate what covered the
/// object before). Sorted by id.
#[allow(clippy::too_many_arguments)]
pub fn culled_visible(
    scene: &Scene,
    visible: &[u32],
    reference_items: &Image<u32>,
    reference_depth: &Image<f32>,
    occlusion_map: Option<&Image<f32>>,
    cam: &Camera,
    t: f32,
    prev: Option<&PrevFrame<'_>>,
) -> Vec<CulledVisible> {
    let n = scene.instances.len();
    let mut kept = vec![false; n];
    for &id in visible.iter().filter(|&&i| (i as usize) < n) {
        kept[id as usize] = true;
    }
    let mut pixels: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (i, &id) in reference_items.data().iter().enumerate() {
        if id != NO_ITEM && (id as usize) < n && !kept[id as usize] {
            pixels[id as usize].push(i);
        }
    }
    let map_ok = occlusion_map.filter(|m| m.size() == reference_items.size());
    let prev_ok = prev.filter(|p| p.items.size() == reference_items.size());
    let mut out = Vec::new();
    for (id, px) in pixels.iter().enumerate().filter(|(_, p)| !p.is_empty()) {
        let id = id as u32;
        let aabb = scene.instance_aabb_at(id, t);
        let (stage, nearest, map_max) = match screen_rect(&aabb, cam) {
            ScreenRect::Rect { rect, nearest } => {
                let mx = map_ok.map_or(f32::NAN, |m| max_in_rect(m, rect));
                let stage = if mx < nearest - DEPTH_TOLERANCE { "screen" } else { "hybrid" };
                (stage, nearest, mx)
            }
            ScreenRect::CrossesNear => ("hybrid", 0.0, f32::NAN),
            ScreenRect::Outside => ("frustum", f32::NAN, f32::NAN),
        };
        let range = |img: &Image<f32>| {
            px.iter()
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &i| (lo.min(img.data()[i]), hi.max(img.data()[i])))
        };
        let true_depth = range(reference_depth);
        let predicted_depth = map_ok.map_or((f32::NAN, f32::NAN), range);
        let wrong_pixels = map_ok
            .map_or(0, |m| px.iter().filter(|&&i| m.data()[i] < reference_depth.data()[i] - DEPTH_TOLERANCE).count());
        let (mut moving, mut empty) = (0, 0);
        let mut prev_pixels = None;
        let mut total_speed_px = f32::NAN;
        let mut around = Vec::new();
        let mut prev_depth = (f32::NAN, f32::NAN);
        if let Some(p) = prev_ok {
            prev_pixels = Some(p.items.data().iter().filter(|&&v| v == id).count());
            for &i in px {
                let o = p.items.data()[i];
                if o == NO_ITEM {
                    empty += 1;
                } else if (o as usize) < n && o != id && scene.instances[o as usize].animation.is_animated() {
                    moving += 1;
                }
            }
            total_speed_px = screen_speed(scene, id, p.cam, p.t, cam, t);
            prev_depth = range(p.depth);
            let (w, h) = (p.items.width() as i64, p.items.height() as i64);
            for &i in px {
                let (x, y) = ((i as i64) % w, (i as i64) / w);
                for (dx, dy) in (-1..=1).flat_map(|dy| (-1..=1).map(move |dx| (dx, dy))) {
                    let (xx, yy) = (x + dx, y + dy);
                    if (0..w).contains(&xx) && (0..h).contains(&yy) {
                        around.push(*p.items.get(xx as u32, yy as u32));
                    }
                }
            }
            around.sort_unstable();
            around.dedup();
        }
        out.push(CulledVisible {
            id,
            pixels: px.len(),
            prev_pixels,
            own_speed_px: prev.map_or(f32::NAN, |p| screen_speed(scene, id, cam, p.t, cam, t)),
            total_speed_px,
            prev_moving_occluder_pixels: moving,
            prev_empty_pixels: empty,
            prev_items_around: around,
            prev_depth,
            stage,
            aabb_nearest: nearest,
            map_max_over_rect: map_max,
            true_depth,
            predicted_depth,
            wrong_pixels,
        });
    }
    out
}
