//! Rapid-motion objects (thesis Sec. IV.1, Fig. 5): objects whose screen-space speed exceeds a
//! threshold are drawn exactly into the predicted depth instead of being warped.

use super::{hull_hides, max_over_footprints, WocParams, DEPTH_TOLERANCE};
use crate::frustum::{Frustum, OBJECT_CHUNK};
use crate::maxdepth::MaxDepthQuery;
use crate::objects::{corner_speed, object_screen_speed, CullObjects};
use crate::screen::{screen_rect_with, PixelRect, ScreenRect};
use rayon::prelude::*;
use zwarp_core::{Aabb, Camera, Image, Result, Scene, EMPTY_DEPTH};
use zwarp_raster::draw_into;

/// Screen-space speed (pixels per frame) of instance `id` of `scene` between view `cam_a` at
/// time `t_a` and view `cam_b` at `t_b` ([`crate::objects::object_screen_speed`] of the
/// scene's objects).
pub fn screen_speed(scene: &Scene, id: u32, cam_a: &Camera, t_a: f32, cam_b: &Camera, t_b: f32) -> f32 {
    let inst = &scene.instances[id as usize];
    if !inst.animation.is_animated() && cam_a == cam_b {
        return 0.0;
    }
    let local = scene.meshes[inst.mesh as usize].bounds;
    corner_speed((local, inst.transform_at(t_a), inst.transform_at(t_b)), cam_a, cam_b)
}

/// Draws `objects` at time `t` exactly into `predicted`, which has the size of the culling
/// resolution and bounds the depth `full_cam` renders: at full resolution directly; at a coarse
/// one into a far full-resolution buffer that is then reduced by max over each coarse pixel's
/// footprint (as the previous depth is, [`downsample_max`]) and merged by min, so every coarse
/// value stays an upper bound of the depth of the fine pixels under it. (Rasterizing at the
/// coarse resolution would give a covered coarse pixel the depth at its centre, which bounds
/// neither its uncovered fine pixels nor a sloped surface's far corner.)
pub(crate) fn draw_exact(
    predicted: &mut Image<f32>,
    scene: &Scene,
    full_cam: &Camera,
    t: f32,
    objects: &[u32],
) -> Result<()> {
    if predicted.size() == (full_cam.width, full_cam.height) {
        return draw_into(predicted, None, scene, full_cam, t, objects);
    }
    let mut fine = Image::new(full_cam.width, full_cam.height, EMPTY_DEPTH);
    draw_into(&mut fine, None, scene, full_cam, t, objects)?;
    let coarse = max_over_footprints(&fine, predicted.size());
    predicted.data_mut().par_iter_mut().zip(coarse.data().par_iter()).for_each(|(p, &c)| *p = p.min(c));
    Ok(())
}

/// What the screen-space stage still has to decide for an object in the frustum ([`prepass`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Test {
    /// Rapid-motion object: drawn into the occlusion map and kept.
    Forced,
    /// Its box crosses the near plane: kept.
    Keep,
    /// Test this screen rectangle (culling resolution) and nearest corner depth.
    Rect(PixelRect, f32),
}

/// An object of the frustum, after [`prepass`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct Prepassed {
    pub(crate) id: u32,
    pub(crate) aabb: Aabb,
    pub(crate) test: Test,
}

/// Rapid-motion classification of [`WocParams::rapid_motion`] for one frame pair.
pub(crate) struct Rapid<'a> {
    /// Threshold in full-resolution pixels per frame (`None`: path disabled).
    pub(crate) threshold: Option<f32>,
    /// Camera of the speed's first view (the current one unless the camera motion counts).
    pub(crate) cam_a: &'a Camera,
    /// Current full-resolution camera.
    pub(crate) cam_b: &'a Camera,
    pub(crate) includes_camera: bool,
}

impl<'a> Rapid<'a> {
    pub(crate) fn of(params: &WocParams, full_prev_cam: &'a Camera, full_cam: &'a Camera) -> Self {
        Rapid {
            threshold: params.rapid_threshold_px(full_cam.width),
            cam_a: if params.rapid_includes_camera { full_prev_cam } else { full_cam },
            cam_b: full_cam,
            includes_camera: params.rapid_includes_camera,
        }
    }
}

/// The per-object pass of [`woc`] before the occlusion map exists: current boxes, VFC, the
/// rapid-motion speed (thesis Sec. IV.1) and the box's screen rectangle for `cam` (the culling
/// resolution), in one read of each object. Returns the objects in the frustum (whose
/// rectangle is not outside the image), increasing ids. Static objects skip the speed unless the
/// camera's motion counts (their own speed is 0).
pub(crate) fn prepass(objects: &(impl CullObjects + ?Sized), cam: &Camera, rapid: &Rapid<'_>) -> Vec<Prepassed> {
    let frustum = Frustum::from_camera(cam);
    let vp = cam.view_proj();
    frustum.filter_map_ids(
        objects.len() as u32,
        |id| objects.world_box(id),
        |id, aabb| {
            if let Some(thr) = rapid.threshold {
                let moving = rapid.includes_camera || objects.is_animated(id);
                if moving && object_screen_speed(objects, id, rapid.cam_a, rapid.cam_b) > thr {
                    return Some(Prepassed { id, aabb, test: Test::Forced });
                }
            }
            let test = match screen_rect_with(&aabb, &vp, cam.width, cam.height) {
                ScreenRect::Outside => return None,
                ScreenRect::CrossesNear => Test::Keep,
                ScreenRect::Rect { rect, nearest } => Test::Rect(rect, nearest),
            };
            Some(Prepassed { id, aabb, test })
        },
    )
}

/// The screen-space stage of [`woc`] over the [`prepass`]ed objects: ids (increasing) of those
/// kept, i.e. forced, crossing the near plane, or whose rectangle is not occluded in `map`
/// ([`DEPTH_TOLERANCE`] included) and, with `hull = Some((predicted depth, slack))`,
/// whose silhouette still meets a pixel that could show them ([`WocParams::hull_test`]).
pub(crate) fn test_prepassed(
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
