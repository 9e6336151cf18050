//! Motion field (seed 000, Sec. 3.1): `v(q) = C P^-1 q - q` in pixels, object motion included,
//! with each sample's depth in the target view. Used by the renderer (pixel-accurate motion
//! buffers), by the warps and by culling: one implementation.

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec2};
use rayon::prelude::*;

use crate::{camera::project_with, camera::unproject_with, Camera, Image, Result, NO_ITEM};

/// One motion-buffer sample: where the source pixel's surface point moves to (in pixels,
/// `v`) and its depth in the target view (Sec. 3.1: "the render target also stores the new
/// depths"). A warp writes `depth`, never the source depth.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Default, Pod, Zeroable)]
pub struct Motion {
    /// Motion in pixels, source -> target: the point at `q` lands at `q + v`.
    pub v: Vec2,
    /// Depth of the moved point in the target view, `[0, 1]`; may fall outside when it leaves
    /// the target's near/far range; `1.0` for empty source pixels.
    pub depth: f32,
}

/// Reprojects source pixel centre `(x + 0.5, y + 0.5)` with stored depth `d` to the target:
/// returns the [`Motion`] sample. `inv_a` = inverse view-projection of the source camera,
/// `m` = `VP_b * object_delta`. Empty pixels (`d >= 1`) are treated as points on the source far
/// plane that do not move with any object (background at the far plane); their depth is 1.
#[inline]
pub fn reproject_pixel(inv_a: &Mat4, m: &Mat4, a: (u32, u32), b: (u32, u32), x: u32, y: u32, d: f32) -> Motion {
    let (px, py) = (x as f32 + 0.5, y as f32 + 0.5);
    let w = unproject_with(inv_a, a.0, a.1, px, py, d.min(1.0));
    match project_with(m, b.0, b.1, w) {
        Some(s) => Motion { v: Vec2::new(s.x - px, s.y - py), depth: if d >= 1.0 { 1.0 } else { s.z } },
        // Behind the target eye: it cannot be seen there; send it far off-screen so no
        // fixed-point search converges to it.
        None => Motion { v: Vec2::splat(1.0e9), depth: 1.0 },
    }
}

/// Validates the inputs of a motion-field computation (shared by the CPU function and its GPU
/// twin): a non-empty, finite depth buffer of the source camera's size and a matching item buffer.
pub fn check_motion_inputs(depth: &Image<f32>, items: Option<&Image<u32>>, cam_a: &Camera) -> Result<()> {
    depth.check_nonempty("depth buffer")?;
    if let Some(it) = items {
        depth.check_same_size(it, "depth vs item buffer")?;
    }
    if depth.size() != (cam_a.width, cam_a.height) {
        return Err(crate::Error::invalid(format!(
            "depth buffer is {}x{} but the source camera renders {}x{}",
            depth.width(),
            depth.height(),
            cam_a.width,
            cam_a.height
        )));
    }
    if depth.data().iter().any(|d| !d.is_finite()) {
        return Err(crate::Error::invalid("depth buffer holds NaN or infinite values"));
    }
    Ok(())
}

/// Computes the motion buffer from a source depth buffer, its item buffer and the two cameras.
///
/// `object_deltas[id]` is the world-space motion `M(t_b) * M(t_a)^-1` of object `id` (see
/// [`crate::Scene::object_deltas`]); pass an empty slice for a static scene. Pixels with
/// [`NO_ITEM`] or ids beyond the slice move with the camera only.
pub fn motion_field(
    depth: &Image<f32>,
    items: Option<&Image<u32>>,
    cam_a: &Camera,
    cam_b: &Camera,
    object_deltas: &[Mat4],
) -> Result<Image<Motion>> {
    let n = object_deltas.len();
    motion_field_with(depth, items, cam_a, cam_b, |id| (id as usize) < n, |id| object_deltas[id as usize])
}

/// [`motion_field`] with each object's motion given by functions: `moving(id)` says whether
/// object `id` moves on its own, `delta(id)` is then its world-space motion `M(t_b) *
/// M(t_a)^-1`. Only the moving ids that appear on a surface pixel of the item buffer are
/// looked up, each once, so a frame costs nothing per object it does not show (a scene of a
/// million objects needs no per-frame array of matrices). Bit-identical to [`motion_field`]
/// with the full slice of deltas.
pub fn motion_field_with(
    depth: &Image<f32>,
    items: Option<&Image<u32>>,
    cam_a: &Camera,
    cam_b: &Camera,
    moving: impl Fn(u32) -> bool + Sync,
    delta: impl Fn(u32) -> Mat4 + Sync,
) -> Result<Image<Motion>> {
    check_motion_inputs(depth, items, cam_a)?;
    let (w, h) = depth.size();
    let wu = w as usize;
    // The moving ids on screen, sorted and unique (empty pixels move with the camera, whatever
    // their id).
    let mut ids: Vec<u32> = match items {
        Some(items) => items
            .data()
            .par_chunks(wu)
            .zip(depth.data().par_chunks(wu))
            .flat_map_iter(|(ir, dr)| {
                let mut last = NO_ITEM;
                let mut seen = Vec::new();
                for (&id, &d) in ir.iter().zip(dr) {
                    if id != last && d < 1.0 && moving(id) {
                        seen.push(id);
                        last = id;
                    }
                }
                seen
            })
            .collect(),
        None => Vec::new(),
    };
    ids.sort_unstable();
    ids.dedup();
    let vp_b = cam_b.view_proj();
    let mats: Vec<Mat4> = ids.par_iter().map(|&id| vp_b * delta(id)).collect();
    let inv_a = cam_a.view_proj().inverse();
    let mut out = Image::new(w, h, Motion::default());
    out.data_mut().par_chunks_mut(wu).enumerate().for_each(|(y, row)| {
        for (x, o) in row.iter_mut().enumerate() {
            let i = y * wu + x;
            let d = depth.data()[i];
            let m = match (d < 1.0 && !ids.is_empty(), items) {
                (true, Some(items)) => ids.binary_search(&items.data()[i]).map_or(&vp_b, |k| &mats[k]),
                _ => &vp_b,
            };
            *o = reproject_pixel(&inv_a, m, (w, h), (cam_b.width, cam_b.height), x as u32, y as u32, d);
        }
    });
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// The per-id form gives the slice form's field bit for bit: moving and static objects,
    /// ids beyond the slice, `NO_ITEM` and empty pixels.
    #[test]
    fn motion_by_id_equals_the_slice_of_deltas() {
        let (w, h) = (23, 17);
        let a = Camera::perspective(Vec3::new(0.0, 1.0, 6.0), Vec3::ZERO, Vec3::Y, 1.0, 0.1, 50.0, w, h).unwrap();
        let b = Camera::perspective(Vec3::new(0.3, 1.1, 5.8), Vec3::X * 0.1, Vec3::Y, 1.0, 0.1, 50.0, w, h).unwrap();
        let depth = Image::from_fn(w, h, |x, y| if (x + y) % 7 == 0 { 1.0 } else { 0.9 + 0.004 * x as f32 });
        let items = Image::from_fn(w, h, |x, y| match (x / 5 + y) % 5 {
            4 => NO_ITEM,
            k => k,
        });
        let deltas = [Mat4::IDENTITY, Mat4::from_translation(Vec3::new(0.2, 0.0, -0.1)), Mat4::from_rotation_y(0.05)];
        let by_slice = motion_field(&depth, Some(&items), &a, &b, &deltas).unwrap();
        let by_id =
            motion_field_with(&depth, Some(&items), &a, &b, |id| id == 1 || id == 2, |id| deltas[id as usize]).unwrap();
        let bits =
            |m: &Image<Motion>| m.data().iter().map(|s| [s.v.x, s.v.y, s.depth].map(f32::to_bits)).collect::<Vec<_>>();
        assert_eq!(bits(&by_id), bits(&by_slice));
        // Object 1 moves on its own: its pixels differ from the camera-only field.
        let still = motion_field(&depth, Some(&items), &a, &b, &[]).unwrap();
        let i = items.data().iter().zip(depth.data()).position(|(&id, &d)| id == 1 && d < 1.0).unwrap();
        assert_ne!(by_id.data()[i], still.data()[i]);
    }

    #[test]
    fn zero_motion_for_identical_cameras() {
        let cam = Camera::perspective(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 1.0, 0.1, 100.0, 16, 8).unwrap();
        let depth = Image::new(16, 8, 0.95f32);
        let m = motion_field(&depth, None, &cam, &cam, &[]).unwrap();
        for s in m.data() {
            assert!(s.v.length() < 1e-3, "{:?}", s);
            assert!((s.depth - 0.95).abs() < 1e-5);
        }
    }

    #[test]
    fn camera_translation_parallel_to_image_plane_gives_analytic_shift() {
        // Camera moves +x by dx at distance z; a point at depth z shifts by -dx * f / z pixels.
        let (w, h) = (64, 64);
        let fov = 1.0f32;
        let a =
            Camera::perspective(Vec3::new(0.0, 0.0, 10.0), Vec3::new(0.0, 0.0, 0.0), Vec3::Y, fov, 0.1, 100.0, w, h)
                .unwrap();
        let b =
            Camera::perspective(Vec3::new(0.5, 0.0, 10.0), Vec3::new(0.5, 0.0, 0.0), Vec3::Y, fov, 0.1, 100.0, w, h)
                .unwrap();
        let d = a.stored_depth(10.0);
        let depth = Image::new(w, h, d);
        let m = motion_field(&depth, None, &a, &b, &[]).unwrap();
        let focal = h as f32 * 0.5 / (fov * 0.5).tan();
        let expect = -0.5 * focal / 10.0;
        for s in m.data() {
            assert!((s.v.x - expect).abs() < 1e-2 && s.v.y.abs() < 1e-2, "{:?} vs {expect}", s.v);
            assert!((s.depth - d).abs() < 1e-5);
        }
    }
}
