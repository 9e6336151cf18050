//! PCSS baseline (Fernando 2005, "Percentage-closer soft shadows"; seed 000, Sec. 6 names it as
//! the kind of filtering method that does not compute true visibility): from the single centre
//! shadow map, (1) a blocker search over the region of the map that can hold occluders of the
//! receiver, (2) a penumbra estimate from the average blocker depth by similar triangles, (3)
//! percentage-closer filtering with a kernel of that size.
//!
//! Geometry (per axis, `R` = emitter half extent, `z` = receiver depth, `z_b` = blocker depth,
//! `f = (W/2) P00` the map's focal length in pixels):
//! - local light: a blocker at depth `z_b` on a ray from an emitter point to the receiver shows
//!   up in the centre map at most `f R (1/z_b - 1/z)` pixels from the receiver; the search uses
//!   the nearest possible blocker (the map's near plane), the filter uses the average blocker;
//! - directional light: the same with `f (R / D) (z - z_b)` (parallel projection).
//!
//! The kernel has the shape of the emitter (a stratified grid mapped to a rectangle or a disc).

use glam::Vec2;
use rayon::prelude::*;
use zwarp_core::{Error, Image, Result};

use crate::light::{half_extents, light_samples, LightRig};
use crate::shade::Receivers;

/// Parameters of the PCSS baseline.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PcssParams {
    /// Blocker-search taps (a stratified kernel of this many points, >= 1).
    pub blocker_taps: u32,
    /// PCF taps (>= 1).
    pub pcf_taps: u32,
    /// Largest search / filter radius in texels (bounds the cost of huge penumbrae).
    pub max_radius: f32,
}

impl Default for PcssParams {
    /// 36 blocker taps, 64 PCF taps, radius up to 64 texels (typical real-time settings).
    fn default() -> Self {
        PcssParams { blocker_taps: 36, pcf_taps: 64, max_radius: 64.0 }
    }
}

impl PcssParams {
    fn validate(&self) -> Result<()> {
        if self.blocker_taps == 0 || self.pcf_taps == 0 || self.blocker_taps > 4096 || self.pcf_taps > 4096 {
            return Err(Error::invalid(format!(
                "PCSS tap counts must be in 1..=4096, got {} / {}",
                self.blocker_taps, self.pcf_taps
            )));
        }
        if !(self.max_radius.is_finite() && self.max_radius > 0.0) {
            return Err(Error::invalid(format!("PCSS max radius must be > 0, got {}", self.max_radius)));
        }
        Ok(())
    }
}

/// Unit kernel (offsets in `[-1, 1]^2`, emitter-shaped) with `n` taps.
fn unit_kernel(rig: &LightRig, n: u32) -> Result<Vec<Vec2>> {
    let half = half_extents(&rig.light.shape);
    let pts = light_samples(&rig.light.shape, n, 0, false)?;
    Ok(pts
        .into_iter()
        .map(|p| {
            Vec2::new(if half.x > 0.0 { p.x / half.x } else { 0.0 }, if half.y > 0.0 { p.y / half.y } else { 0.0 })
        })
        .collect())
}

/// PCSS visibility of every receiver (in `recv.list` order) from the centre shadow map `map`
/// (rendered with `rig.center`).
pub fn pcss_visibility(recv: &Receivers, rig: &LightRig, map: &Image<f32>, params: &PcssParams) -> Result<Vec<f32>> {
    params.validate()?;
    let lc = &rig.center;
    if map.size() != (lc.width, lc.height) {
        return Err(Error::invalid(format!(
            "PCSS map is {}x{} but the light camera renders {}x{}",
            map.width(),
            map.height(),
            lc.width,
            lc.height
        )));
    }
    let blocker_k = unit_kernel(rig, params.blocker_taps)?;
    let pcf_k = unit_kernel(rig, params.pcf_taps)?;
    let half = half_extents(&rig.light.shape);
    let focal = Vec2::new(0.5 * lc.width as f32 * lc.proj.x_axis.x, 0.5 * lc.height as f32 * lc.proj.y_axis.y);
    // Pixel extent (per axis) of the cone between emitter and receiver at blocker depth zb.
    let directional = rig.light.directional;
    let dist = rig.distance;
    let spread = move |z: f32, zb: f32| -> Vec2 {
        if directional {
            focal * half / dist * (z - zb).max(0.0)
        } else {
            focal * half * (1.0 / zb.max(1e-6) - 1.0 / z).max(0.0)
        }
    };
    let (mw, mh) = map.size();
    let data = map.data();
    let fetch = |p: Vec2| -> Option<f32> {
        let (fx, fy) = (zwarp_core::round::floor(p.x), zwarp_core::round::floor(p.y));
        if fx < 0.0 || fy < 0.0 || fx >= mw as f32 || fy >= mh as f32 {
            None
        } else {
            Some(data[fy as usize * mw as usize + fx as usize])
        }
    };
    let near = lc.near;
    let maxr = params.max_radius;
    Ok(recv
        .list
        .par_iter()
        .map(|r| {
            let texel = rig.texel_world(r.z);
            // Per-tap threshold: the receiver plane recedes by tan(theta) per world unit of offset.
            let thr = |off: Vec2| -> f32 {
                let extra = r.tan_theta * off.length() * texel;
                lc.stored_depth(r.z - r.bias - extra)
            };
            // 1. Blocker search.
            let search = spread(r.z, near).min(Vec2::splat(maxr));
            let (mut sum, mut count) = (0.0f32, 0u32);
            for k in &blocker_k {
                let off = *k * search;
                if let Some(d) = fetch(r.p_c + off) {
                    if d < thr(off) {
                        sum += lc.linear_depth(d);
                        count += 1;
                    }
                }
            }
            if count == 0 {
                return 1.0;
            }
            // 2. Penumbra estimate from the average blocker depth.
            let zb = sum / count as f32;
            let radius = spread(r.z, zb).min(Vec2::splat(maxr));
            // 3. PCF over the emitter-shaped kernel.
            let lit = pcf_k
                .iter()
                .filter(|k| {
                    let off = **k * radius;
                    fetch(r.p_c + off).is_none_or(|d| d >= thr(off))
                })
                .count();
            lit as f32 / pcf_k.len() as f32
        })
        .collect())
}
