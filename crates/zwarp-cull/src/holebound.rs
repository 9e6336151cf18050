//! Upper bounds for WOC's far holes from static surfaces of the previous frame (a zwarp
//! addition to seed 000 Sec. 5, where "depth holes are conservatively kept at the far-clipping
//! depth").
//!
//! A hole of the warped depth (a disocclusion, an opening rim) is kept at the far depth because
//! whatever it shows was hidden in the previous frame. But the *ray* of the hole pixel is known:
//! if it crosses a surface that the previous frame did see, and that surface is static, the
//! surface is still there, so the nearest surface on the ray, the one the pixel shows, is no
//! farther than that crossing. Whatever the hidden content is (static or moving), the crossing
//! depth is a valid upper bound, i.e. a conservative occluder depth, and usually far nearer than
//! the far plane (the ground, a wall behind the opening).
//!
//! The crossing is found by marching the ray's projection in the previous view (its epipolar
//! segment) over the previous depth buffer: the ray is in front of the seen surface at one
//! sample and behind it a few samples later, every sample's 3x3 neighbourhood showing the same
//! static object with a locally affine (planar) depth. A ray that passes
//! *behind* an occluder enters it across a depth jump (or between two objects) and is not
//! accepted.

use glam::{Mat4, Vec2, Vec4};
use rayon::prelude::*;
use zwarp_core::{Camera, Error, Image, Result, Scene, EMPTY_DEPTH, NO_ITEM};

/// Longest march per ray (previous-view pixels, about one sample per pixel).
pub const MAX_MARCH_STEPS: usize = 256;

/// Largest second difference of the stored depth, relative to the first difference, along a
/// line of three pixels still taken as one smooth surface (0 for a plane up to rounding).
const SMOOTHNESS: f32 = 0.25;

/// Marches rays of the current view through the previous frame's depth and item buffers (see
/// the module docs).
pub struct StaticRays<'a> {
    prev_depth: &'a Image<f32>,
    prev_items: &'a Image<u32>,
    prev_cam: &'a Camera,
    /// Static object flags, indexed by item id.
    is_static: Vec<bool>,
    /// Current clip/NDC -> previous clip.
    to_prev: Mat4,
    cam: &'a Camera,
}

impl<'a> StaticRays<'a> {
    /// Prepares the marcher for rays of `cam` (any resolution with the same view volume)
    /// against the previous frame (`prev_depth`, `prev_items` rendered by `prev_cam`).
    ///
    /// Errors: buffer sizes differ from each other or from `prev_cam`.
    pub fn new(
        scene: &Scene,
        prev_depth: &'a Image<f32>,
        prev_items: &'a Image<u32>,
        prev_cam: &'a Camera,
        cam: &'a Camera,
    ) -> Result<Self> {
        prev_depth.check_same_size(prev_items, "previous depth vs item buffer")?;
        if prev_depth.size() != (prev_cam.width, prev_cam.height) {
            return Err(Error::invalid(format!(
                "previous depth is {}x{} but its camera renders {}x{}",
                prev_depth.width(),
                prev_depth.height(),
                prev_cam.width,
                prev_cam.height
            )));
        }
        let is_static = scene.instances.par_iter().map(|i| !i.animation.is_animated()).collect();
        let to_prev = prev_cam.view_proj() * cam.view_proj().inverse();
        Ok(StaticRays { prev_depth, prev_items, prev_cam, is_static, to_prev, cam })
    }

    /// The static object seen over the whole 3x3 neighbourhood of previous pixel `(x, y)` and
    /// its depth range there, if that neighbourhood is one object whose depth is locally
    /// affine: stored depth is affine in screen position over a plane, so along each of the
    /// four lines through the centre the second difference must be small next to the first
    /// ([`SMOOTHNESS`]). A depth jump (a part of the object in front of another) fails this.
    fn surface_around(&self, x: i64, y: i64) -> Option<(u32, f32, f32)> {
        let (w, h) = (self.prev_cam.width as i64, self.prev_cam.height as i64);
        if x < 1 || y < 1 || x + 1 >= w || y + 1 >= h {
            return None;
        }
        let id = *self.prev_items.get(x as u32, y as u32);
        if id == NO_ITEM || !self.is_static.get(id as usize).copied().unwrap_or(false) {
            return None;
        }
        let mut d = [[0.0f32; 3]; 3];
        for (j, row) in d.iter_mut().enumerate() {
            for (i, v) in row.iter_mut().enumerate() {
                let (xx, yy) = ((x + i as i64 - 1) as u32, (y + j as i64 - 1) as u32);
                let (dd, ii) = (*self.prev_depth.get(xx, yy), *self.prev_items.get(xx, yy));
                if ii != id || dd >= EMPTY_DEPTH {
                    return None;
                }
                *v = dd;
            }
        }
        let c = d[1][1];
        for (a, b) in [(d[1][0], d[1][2]), (d[0][1], d[2][1]), (d[0][0], d[2][2]), (d[0][2], d[2][0])] {
            let second = (a - 2.0 * c + b).abs();
            let first = 0.5 * (b - a).abs();
            if second > SMOOTHNESS * first + 2e-6 {
                return None;
            }
        }
        let lo = d.iter().flatten().copied().fold(f32::INFINITY, f32::min);
        let hi = d.iter().flatten().copied().fold(f32::NEG_INFINITY, f32::max);
        Some((id, lo, hi))
    }

    /// An upper bound on the stored depth (in `cam`) of the surface seen through pixel
    /// position `(px, py)` of `cam`, from the first static surface of the previous frame that
    /// the ray crosses; `None` if none is found.
    pub fn bound(&self, px: f32, py: f32) -> Option<f32> {
        let (w, h) = (self.cam.width as f32, self.cam.height as f32);
        let (nx, ny) = (px / w * 2.0 - 1.0, 1.0 - py / h * 2.0);
        // Homogeneous previous-clip position of the ray point at current stored depth z:
        // c(z) = c0 + z c1 (linear in z).
        let c0 = self.to_prev * Vec4::new(nx, ny, 0.0, 1.0);
        let c1 = self.to_prev.z_axis;
        // Keep the part of the ray inside the previous view volume's depth range,
        // 0 <= c.z <= c.w (behind its near plane, so c.w >= near > 0, and before its far
        // plane): the previous buffers know nothing elsewhere. Both are linear in z.
        let (mut z_lo, mut z_hi) = (0.0f32, 1.0f32);
        for (a, b) in [(c0.z, c1.z), (c0.w - c0.z, c1.w - c1.z)] {
            // a + z b >= 0
            if b.abs() < 1e-12 {
                if a < 0.0 {
                    return None;
                }
            } else if b > 0.0 {
                z_lo = z_lo.max(-a / b);
            } else {
                z_hi = z_hi.min(-a / b);
            }
        }
        if z_lo.partial_cmp(&z_hi) != Some(std::cmp::Ordering::Less) {
            return None;
        }
        let (pw, ph) = (self.prev_cam.width as f32, self.prev_cam.height as f32);
        let screen = |c: Vec4| Vec2::new((c.x / c.w + 1.0) * 0.5 * pw, (1.0 - c.y / c.w) * 0.5 * ph);
        let (ca, cb) = (c0 + z_lo * c1, c0 + z_hi * c1);
        let (sa, sb) = (screen(ca), screen(cb));
        // Clip the screen segment to the previous image (Liang-Barsky).
        let d = sb - sa;
        let (mut u0, mut u1) = (0.0f32, 1.0f32);
        for (p, q) in [(-d.x, sa.x), (d.x, pw - sa.x), (-d.y, sa.y), (d.y, ph - sa.y)] {
            if p == 0.0 {
                if q < 0.0 {
                    return None;
                }
            } else {
                let r = q / p;
                if p < 0.0 {
                    u0 = u0.max(r);
                } else {
                    u1 = u1.min(r);
                }
            }
        }
        if u0.partial_cmp(&u1) != Some(std::cmp::Ordering::Less) {
            return None;
        }
        let len = d.length() * (u1 - u0);
        let steps = ((len / 0.75).ceil() as usize).clamp(2, MAX_MARCH_STEPS);
        // Screen-linear u -> homogeneous blend lambda (perspective-correct) -> z.
        let z_at = |u: f32| {
            let lambda = u * ca.w / ((1.0 - u) * cb.w + u * ca.w);
            z_lo + lambda * (z_hi - z_lo)
        };
        // A chain of adjacent samples over one continuous static surface S (every sample's
        // 3x3 neighbourhood shows S, without a depth jump): the ray is strictly in front of
        // the whole neighbourhood at the chain's start and strictly behind it at its end, so it
        // crossed S in between.
        let mut chain: Option<(u32, (i64, i64))> = None; // (surface item, last pixel) after a front sample
        let mut last_z = z_at(u0);
        for k in 0..=steps {
            let u = u0 + (u1 - u0) * k as f32 / steps as f32;
            let z = z_at(u);
            let c = c0 + z * c1;
            let s = screen(c);
            let (ix, iy) = (s.x.floor() as i64, s.y.floor() as i64);
            if c.w <= 0.0 || ix < 0 || iy < 0 || ix >= pw as i64 || iy >= ph as i64 {
                chain = None;
                last_z = z;
                continue;
            }
            let zp = c.z / c.w;
            match self.surface_around(ix, iy) {
                Some((id, lo, hi)) => {
                    let linked =
                        chain.is_some_and(|(cid, (lx, ly))| cid == id && (ix - lx).abs() <= 1 && (iy - ly).abs() <= 1);
                    if linked && zp > hi {
                        // One more step of margin for the surface between pixel centres.
                        return Some((z + (z - last_z).max(0.0)).min(EMPTY_DEPTH));
                    }
                    // In front of the whole neighbourhood starts (or restarts) a chain; in
                    // between keeps a linked chain going.
                    chain = (zp < lo || linked).then_some((id, (ix, iy)));
                }
                None => chain = None,
            }
            last_z = z;
        }
        None
    }
}

/// Replaces far pixels of `predicted` (a depth map of `rays`' current camera) flagged in
/// `candidates` by their static-surface bound ([`StaticRays::bound`]) where one is found.
/// Returns how many were bounded.
///
/// Errors: sizes differ.
pub fn bound_far_pixels(predicted: &mut Image<f32>, candidates: &[bool], rays: &StaticRays<'_>) -> Result<usize> {
    if candidates.len() != predicted.len() || predicted.size() != (rays.cam.width, rays.cam.height) {
        return Err(Error::invalid("hole-bound candidates and the predicted depth differ in size"));
    }
    let w = predicted.width() as usize;
    Ok(predicted
        .data_mut()
        .par_chunks_mut(w)
        .enumerate()
        .map(|(y, row)| {
            let mut n = 0;
            for (x, d) in row.iter_mut().enumerate() {
                if *d >= EMPTY_DEPTH && candidates[y * w + x] {
                    if let Some(b) = rays.bound(x as f32 + 0.5, y as f32 + 0.5) {
                        if b < EMPTY_DEPTH {
                            *d = b;
                            n += 1;
                        }
                    }
                }
            }
            n
        })
        .sum())
}
