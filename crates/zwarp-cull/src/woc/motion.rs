//! WOC's motion buffer (seed 000 Sec. 5, step 1): the previous frame's pixels moved to the
//! current camera, with per-object motion from the item buffer.

use zwarp_core::{Camera, Image, Result, Scene};

/// The motion buffer of [`zwarp_core::motion_field`] (seed 000 Sec. 3.1, camera motion plus
/// each object's own motion through the item buffer) for a scene's instances, through
/// [`zwarp_core::motion_field_with`]: matrices only for the *animated objects present in the
/// item buffer*, since building all of
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
    zwarp_core::motion_field_with(depth, Some(items), cam_a, cam_b, animated, |id| {
        scene.instances[id as usize].delta(t_a, t_b)
    })
}
