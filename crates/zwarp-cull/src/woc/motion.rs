//! WOC's motion buffer (seed 000 Sec. 5, step 1): the previous frame's pixels moved to the
//! current camera, with per-object motion from the item buffer.

use rayon::prelude::*;
use zwarp_core::{Camera, Image, Result, Scene, NO_ITEM};

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
    motion_field_animated(animated, |id| scene.instances[id as usize].delta(t_a, t_b), depth, items, (cam_a, cam_b))
}

/// [`woc_motion_field`] with the animation flags given by `animated` and each animated
/// object's world-space motion by `delta` (from [`crate::CullObjects`] in [`woc_with`], so a
/// frame reads no instance of a static object). The animated ids on
/// screen are gathered from the item buffer itself (sorted, deduplicated: a few per frame),
/// with no per-frame array over all objects (at 1M objects those were 5 MB to allocate, clear
/// and scan every frame).
pub(crate) fn motion_field_animated(
    animated: impl Fn(u32) -> bool + Sync,
    delta: impl Fn(u32) -> glam::Mat4 + Sync,
    depth: &Image<f32>,
    items: &Image<u32>,
    (cam_a, cam_b): (&Camera, &Camera),
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
    let mats: Vec<glam::Mat4> = ids.par_iter().map(|&id| vp_b * delta(id)).collect();
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
