//! Receivers, the shadow-map visibility test and the shading shared by every method (seed 000,
//! Sec. 6): only the visibility differs between the reference, zwarp and PCSS.
//!
//! The camera frame (depth + item buffer of `zwarp_raster::render_frame`) gives, per pixel, a
//! world point (unprojected depth), the object's albedo (item buffer) and a normal reconstructed
//! from the depth buffer. Each receiver is then expressed once in the centre light camera:
//! centre-map pixel `p_c`, the per-sample shift parameter `g` (see [`crate::light`]) and a depth
//! threshold — so testing it against shadow map `i` is `p_i = p_c + K_i g`, one texel fetch and
//! one compare.
//!
//! **Depth bias** (documented choice): slope-scaled, in linear light-view depth. A receiver at
//! light depth `z` is lit by map `i` iff `z - b <= z_map`, with
//! `b = texel(z) * (constant + slope * min(tan theta, 8))`, `texel(z)` the world size of a map
//! texel at depth `z` and `theta` the angle between the surface normal and the direction to the
//! light. Because every sample map measures the same view depth (parallel frusta), the test is
//! done in stored depth with one per-receiver threshold `stored(z - b)`: `D_map >= threshold`.

use glam::{Vec2, Vec3};
use rayon::prelude::*;
use zwarp_core::{Camera, Error, Image, Result, Scene, NO_ITEM};
use zwarp_raster::{shading, Frame};

use crate::light::LightRig;

/// Slope-scaled depth bias, in units of the world size of one shadow-map texel at the receiver.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DepthBias {
    /// Constant part (texels).
    pub constant: f32,
    /// Factor of `tan(theta)` (texels), `theta` = angle between normal and light direction.
    pub slope: f32,
}

impl Default for DepthBias {
    /// 0.5 texel constant + 1.5 texels per unit slope: no acne on the test planes and scenes at
    /// 512-2048 maps, little peter-panning.
    fn default() -> Self {
        DepthBias { constant: 0.5, slope: 1.5 }
    }
}

impl DepthBias {
    fn validate(&self) -> Result<()> {
        if !(self.constant.is_finite() && self.slope.is_finite() && self.constant >= 0.0 && self.slope >= 0.0) {
            return Err(Error::invalid(format!(
                "depth bias must be finite and >= 0, got constant={} slope={}",
                self.constant, self.slope
            )));
        }
        Ok(())
    }
}

/// One shaded camera pixel that shows a surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Receiver {
    /// Camera pixel index (row-major).
    pub pixel: u32,
    /// Position in the centre shadow map (continuous pixel coordinates).
    pub p_c: Vec2,
    /// Shift parameter `g` of [`LightRig::depth_param`].
    pub g: f32,
    /// Linear depth in the light view.
    pub z: f32,
    /// Stored-depth threshold: lit by a map iff its texel depth is `>= threshold`.
    pub threshold: f32,
    /// The depth bias `b` (world units) folded into `threshold`.
    pub bias: f32,
    /// `tan(theta)`, clamped to `[0, 8]` (for PCSS's per-tap bias).
    pub tan_theta: f32,
    /// Lambert factor `max(0, n . l)`.
    pub lambert: f32,
    /// Albedo (linear RGB).
    pub albedo: Vec3,
}

/// The camera-side inputs of the visibility and shading passes.
#[derive(Clone, Debug)]
pub struct Receivers {
    /// Camera image width.
    pub width: u32,
    /// Camera image height.
    pub height: u32,
    /// The receivers (pixels showing a surface).
    pub list: Vec<Receiver>,
}

/// Per-pixel normals reconstructed from a depth buffer (world space, facing the camera): the
/// cross product of the horizontal and vertical position differences, each taken towards the
/// neighbour on the same object with the smaller depth jump (avoids smearing across edges).
/// Zero where the pixel is empty or has no usable neighbour.
pub fn reconstruct_normals(frame: &Frame, cam: &Camera) -> Image<Vec3> {
    let (w, h) = frame.depth.size();
    let inv = cam.view_proj().inverse();
    let eye = cam.eye();
    let ortho_dir = -(cam.view.inverse().z_axis.truncate()).normalize_or_zero();
    let ortho = matches!(cam.projection, zwarp_core::Projection::Orthographic { .. });
    let pos = |x: u32, y: u32| {
        zwarp_core::camera::unproject_with(
            &inv,
            w,
            h,
            x as f32 + 0.5,
            y as f32 + 0.5,
            frame.depth.data()[(y * w + x) as usize],
        )
    };
    let mut out = Image::new(w, h, Vec3::ZERO);
    out.data_mut().par_chunks_mut(w as usize).enumerate().for_each(|(y, row)| {
        let y = y as u32;
        for (x, o) in row.iter_mut().enumerate() {
            let x = x as u32;
            let i = (y * w + x) as usize;
            let d = frame.depth.data()[i];
            let item = frame.items.data()[i];
            if d >= 1.0 || item == NO_ITEM {
                continue;
            }
            let pick = |cands: [(i64, i64); 2]| -> Option<(f32, (u32, u32), i32)> {
                let mut best: Option<(f32, (u32, u32), i32)> = None;
                for (k, (nx, ny)) in cands.iter().enumerate() {
                    if *nx < 0 || *ny < 0 || *nx >= w as i64 || *ny >= h as i64 {
                        continue;
                    }
                    let j = (*ny as u32 * w + *nx as u32) as usize;
                    let dn = frame.depth.data()[j];
                    if dn >= 1.0 || frame.items.data()[j] != item {
                        continue;
                    }
                    let jump = (dn - d).abs();
                    if best.is_none_or(|b| jump < b.0) {
                        best = Some((jump, (*nx as u32, *ny as u32), if k == 0 { -1 } else { 1 }));
                    }
                }
                best
            };
            let (xi, yi) = (x as i64, y as i64);
            let (Some(hx), Some(hy)) = (pick([(xi - 1, yi), (xi + 1, yi)]), pick([(xi, yi - 1), (xi, yi + 1)])) else {
                continue;
            };
            let p = pos(x, y);
            let dx = (pos(hx.1 .0, hx.1 .1) - p) * hx.2 as f32;
            let dy = (pos(hy.1 .0, hy.1 .1) - p) * hy.2 as f32;
            let n = dx.cross(dy).normalize_or_zero();
            let to_eye = if ortho { -ortho_dir } else { eye - p };
            *o = if n.dot(to_eye) < 0.0 { -n } else { n };
        }
    });
    out
}

/// The texel (row-major index) receiver `r` reads in the `mw x mh` map of the sample with pixel
/// shift `shift`: `floor(p_c + shift g)`, or `None` outside the map or for a non-finite
/// position (the receiver is then lit). The one definition shared by [`Receivers::accumulate`]
/// and the lazy synthesis ([`crate::lookups::SparseMap::collect`]), so both touch exactly the
/// same texels.
#[inline]
pub fn texel_of(r: &Receiver, shift: Vec2, mw: u32, mh: u32) -> Option<u32> {
    texel_at(r.p_c, r.g, shift, mw, mh)
}

/// [`texel_of`] from a receiver's centre-map position `p_c` and shift parameter `g`.
#[inline]
pub fn texel_at(p_c: Vec2, g: f32, shift: Vec2, mw: u32, mh: u32) -> Option<u32> {
    texel_xy(p_c, g, shift, mw, mh).map(|(x, y)| y * mw + x)
}

/// [`texel_at`] as `(x, y)`: `floor(p_c + shift g)` if inside the `mw x mh` map.
#[inline]
pub fn texel_xy(p_c: Vec2, g: f32, shift: Vec2, mw: u32, mh: u32) -> Option<(u32, u32)> {
    let p = p_c + shift * g;
    // Inside `[0, mw) x [0, mh)` truncation is floor (`f32::floor` is a libm call on baseline
    // x86-64); the comparisons are false for NaN, which is sent off the map.
    if p.x >= 0.0 && p.y >= 0.0 && p.x < mw as f32 && p.y < mh as f32 {
        Some((p.x as u32, p.y as u32))
    } else {
        None
    }
}

/// Marker of a receiver that reads no texel (its texel lies outside the map) in the per-receiver
/// slots of a [`SparseMap`](crate::SparseMap).
pub const OFF_MAP: u32 = u32::MAX;

impl Receivers {
    /// Builds the receivers of a camera frame (depth + items of `cam`) for a light rig.
    ///
    /// Errors: frame / camera size mismatch, invalid bias.
    pub fn build(frame: &Frame, cam: &Camera, scene: &Scene, rig: &LightRig, bias: &DepthBias) -> Result<Self> {
        bias.validate()?;
        if frame.depth.size() != (cam.width, cam.height) {
            return Err(Error::invalid(format!(
                "camera frame is {}x{} but the camera renders {}x{}",
                frame.depth.width(),
                frame.depth.height(),
                cam.width,
                cam.height
            )));
        }
        frame.depth.check_same_size(&frame.items, "camera depth vs item buffer")?;
        let (w, h) = frame.depth.size();
        let normals = reconstruct_normals(frame, cam);
        let inv = cam.view_proj().inverse();
        let lc = &rig.center;
        let light_vp = lc.view_proj();
        let lview = lc.view;
        let list: Vec<Receiver> = (0..h)
            .into_par_iter()
            .flat_map_iter(|y| {
                let normals = &normals;
                (0..w).filter_map(move |x| {
                    let i = (y * w + x) as usize;
                    let d = frame.depth.data()[i];
                    let item = frame.items.data()[i];
                    if d >= 1.0 || item == NO_ITEM {
                        return None;
                    }
                    let p = zwarp_core::camera::unproject_with(&inv, w, h, x as f32 + 0.5, y as f32 + 0.5, d);
                    let albedo = scene.instances.get(item as usize).map_or(Vec3::splat(0.5), |inst| inst.albedo);
                    let n = normals.data()[i];
                    let l = rig.to_light(p);
                    let cos = n.dot(l);
                    let lambert = cos.max(0.0);
                    let tan_theta =
                        if n == Vec3::ZERO { 1.0 } else { (1.0 - cos * cos).max(0.0).sqrt() / cos.abs().max(0.125) };
                    let tan_theta = tan_theta.min(8.0);
                    let z = -(lview * p.extend(1.0)).z;
                    // Scene points are in front of the light by construction (LightRig); anything else is
                    // sent off the map, i.e. lit.
                    let s = zwarp_core::camera::project_with(&light_vp, lc.width, lc.height, p)
                        .unwrap_or(Vec3::new(-1.0e9, -1.0e9, 0.0));
                    let b = rig.texel_world(z) * (bias.constant + bias.slope * tan_theta);
                    let threshold = lc.stored_depth(z - b);
                    Some(Receiver {
                        pixel: i as u32,
                        p_c: Vec2::new(s.x, s.y),
                        g: rig.depth_param(z),
                        z,
                        threshold: if threshold.is_finite() { threshold } else { f32::NEG_INFINITY },
                        bias: b,
                        tan_theta,
                        lambert,
                        albedo,
                    })
                })
            })
            .collect();
        Ok(Receivers { width: w, height: h, list })
    }

    /// Adds to `lit[k]` 1 for every receiver `k` that shadow map `map` (the map of the sample
    /// with pixel shift `shift`) does not occlude: texel `floor(p_c + shift g)` holds a depth
    /// `>= threshold` (empty texels, depth 1, are lit; points outside the map are lit).
    pub fn accumulate(&self, map: &Image<f32>, shift: Vec2, lit: &mut [u32]) {
        let (mw, mh) = map.size();
        let data = map.data();
        lit.par_chunks_mut(4096).zip(self.list.par_chunks(4096)).for_each(|(acc, recv)| {
            for (a, r) in acc.iter_mut().zip(recv) {
                let lit_here = match texel_of(r, shift, mw, mh) {
                    None => true,
                    Some(t) => data[t as usize] >= r.threshold,
                };
                *a += lit_here as u32;
            }
        });
    }

    /// Visibility image: `lit[k] / samples` at receiver pixels, 1 elsewhere.
    pub fn visibility_image(&self, lit: &[u32], samples: u32) -> Image<f32> {
        let mut v = Image::new(self.width, self.height, 1.0f32);
        let inv = 1.0 / samples.max(1) as f32;
        for (r, &l) in self.list.iter().zip(lit) {
            v.data_mut()[r.pixel as usize] = l as f32 * inv;
        }
        v
    }

    /// The shading every method shares: `albedo * (ambient + (1 - ambient) * V * max(0, n . l))`
    /// at receivers (V = visibility), the renderer's sky colour elsewhere
    /// ([`zwarp_raster::shading::SKY_COLOR`]).
    pub fn shade(&self, visibility: &Image<f32>, ambient: f32) -> Result<Image<[f32; 3]>> {
        if visibility.size() != (self.width, self.height) {
            return Err(Error::invalid(format!(
                "visibility is {}x{} but the camera image is {}x{}",
                visibility.width(),
                visibility.height(),
                self.width,
                self.height
            )));
        }
        let mut img = Image::new(self.width, self.height, shading::SKY_COLOR);
        for r in &self.list {
            let v = visibility.data()[r.pixel as usize];
            let k = ambient + (1.0 - ambient) * v * r.lambert;
            img.data_mut()[r.pixel as usize] = (r.albedo * k).to_array();
        }
        Ok(img)
    }
}
