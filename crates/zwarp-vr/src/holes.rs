//! Hole filling (seed 003 Sec. 5.2, Table 2).
//!
//! [`HoleMethod::LowPass`] is the paper's depth-aware low-pass pyramid: each level halves the
//! resolution and averages, per 2x2 kernel, only the non-hole texels at or behind the kernel's
//! mean depth, so foreground dissolves and background spreads into holes (Fig. 9). A hole pixel
//! finds its distance to the background border by an epipolar search with exponentially
//! growing steps and reads the level whose filter radius covers that distance. A hole pixel
//! next to the foreground's warped silhouette also takes the foreground's expected share of it:
//! the source's samples place a silhouette only to within a texel.
//!
//! Baselines: rubber sheets (the warp with quads connecting every pixel, shown in the holes),
//! stretch in-painting (the background border pixel repeated along the epipolar line) and a
//! depth-unaware push-pull (what FSR3 does).

use glam::{Vec2, Vec4};
use rayon::prelude::*;
use zwarp_core::{Camera, Error, Image, Result};

use crate::grid::{raster_where, Mesh, Method, Source, WarpMatrix, WarpOutput, WarpParams};

/// A hole-filling method (JSON `holes`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HoleMethod {
    /// Seed 003 Sec. 5.2: depth-aware low-pass pyramid, level from the epipolar border distance.
    LowPass,
    /// Rubber sheets: the per-pixel connected quad warp shown in the holes.
    Rubber,
    /// Stretch in-painting along the epipolar direction (seed 003 Table 2).
    Stretch,
    /// Depth-unaware push-pull pyramid.
    PushPull,
}

impl HoleMethod {
    /// CLI / JSON name.
    pub fn name(self) -> &'static str {
        match self {
            HoleMethod::LowPass => "lowpass",
            HoleMethod::Rubber => "rubber",
            HoleMethod::Stretch => "stretch",
            HoleMethod::PushPull => "pushpull",
        }
    }

    /// Parses a name of [`HoleMethod::name`].
    pub fn parse(s: &str) -> Result<Self> {
        Ok(match s {
            "lowpass" => HoleMethod::LowPass,
            "rubber" => HoleMethod::Rubber,
            "stretch" => HoleMethod::Stretch,
            "pushpull" => HoleMethod::PushPull,
            o => return Err(Error::invalid(format!("unknown hole method '{o}' (lowpass, rubber, stretch, pushpull)"))),
        })
    }
}

/// The epipole of the source eye in the target image as homogeneous pixel coordinates
/// `(X w, Y w, w)`: every point of the source moves along the line through it.
pub fn epipole(src: &Camera, dst: &Camera) -> glam::Vec3 {
    let e = dst.view_proj() * src.eye().extend(1.0);
    let (w, h) = (dst.width as f32, dst.height as f32);
    glam::Vec3::new((e.x + e.w) * 0.5 * w, (e.w - e.y) * 0.5 * h, e.w)
}

/// Unit epipolar direction at pixel centre `p` for the homogeneous epipole `e` (horizontal
/// where undefined, i.e. at the epipole itself).
#[inline]
pub fn epipolar_dir(e: glam::Vec3, p: Vec2) -> Vec2 {
    let d = Vec2::new(p.x * e.z - e.x, p.y * e.z - e.y);
    let l = d.length();
    if l > 1e-6 * (1.0 + e.truncate().length()) {
        d / l
    } else {
        Vec2::X
    }
}

/// One level of the low-pass pyramid: colour, depth, validity.
#[derive(Clone, Debug)]
pub struct PyramidLevel {
    /// Texels per row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Row-major `(r, g, b, depth)`.
    pub texels: Vec<Vec4>,
    /// Texel holds background colour.
    pub valid: Vec<bool>,
}

/// The depth-aware low-pass pyramid of seed 003 Sec. 5.2 (Fig. 9).
pub fn lowpass_pyramid(color: &Image<[f32; 3]>, depth: &Image<f32>, hole: &Image<bool>) -> Result<Vec<PyramidLevel>> {
    color.check_same_size(depth, "low-pass pyramid colour vs depth")?;
    color.check_same_size(hole, "low-pass pyramid colour vs hole mask")?;
    let (w, h) = color.size();
    let texels = color.data().par_iter().zip(depth.data()).map(|(c, &d)| Vec4::new(c[0], c[1], c[2], d)).collect();
    let valid = hole.data().par_iter().map(|&x| !x).collect();
    let mut levels = vec![PyramidLevel { width: w, height: h, texels, valid }];
    while levels.last().is_some_and(|l| l.width > 1 || l.height > 1) {
        let p = levels.last().expect("a level");
        let (nw, nh) = (p.width.div_ceil(2), p.height.div_ceil(2));
        let mut texels = vec![Vec4::ZERO; (nw * nh) as usize];
        let mut valid = vec![false; (nw * nh) as usize];
        texels.par_chunks_mut(nw as usize).zip(valid.par_chunks_mut(nw as usize)).enumerate().for_each(
            |(y, (trow, vrow))| {
                let y = y as u32;
                for (x, (t, v)) in trow.iter_mut().zip(vrow.iter_mut()).enumerate() {
                    let x = x as u32;
                    // The valid children in order (no allocation: this runs per texel).
                    let mut kids = [Vec4::ZERO; 4];
                    let mut n = 0;
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        let (cx, cy) = (2 * x + dx, 2 * y + dy);
                        if cx < p.width && cy < p.height {
                            let k = (cy * p.width + cx) as usize;
                            if p.valid[k] {
                                kids[n] = p.texels[k];
                                n += 1;
                            }
                        }
                    }
                    if n == 0 {
                        continue;
                    }
                    let kids = &kids[..n];
                    let mean = kids.iter().map(|t| t.w).sum::<f32>() / n as f32;
                    // Only texels at or behind the mean depth (a hair of slack for equal depths).
                    let slack = 1e-6 * mean.abs().max(1.0);
                    let behind = || kids.iter().filter(|t| t.w >= mean - slack);
                    *t = behind().copied().sum::<Vec4>() / behind().count() as f32;
                    *v = true;
                }
            },
        );
        levels.push(PyramidLevel { width: nw, height: nh, texels, valid });
    }
    Ok(levels)
}

/// Reads level `l` at full-resolution pixel centre `p`: bilinear over the valid texels at or
/// behind their mean depth (the kernel rule again, so a foreground-only texel next to the hole
/// does not bleed in). `None` if no texel is valid.
fn read_level(l: &PyramidLevel, scale: f32, p: Vec2) -> Option<Vec4> {
    let q = p / scale - Vec2::splat(0.5);
    let (x0, y0) = (zwarp_core::round::floor(q.x) as i32, zwarp_core::round::floor(q.y) as i32);
    let (ax, ay) = (q.x - x0 as f32, q.y - y0 as f32);
    let mut taps = [(Vec4::ZERO, 0.0f32); 4];
    let mut n = 0;
    for (dx, dy, wt) in
        [(0, 0, (1.0 - ax) * (1.0 - ay)), (1, 0, ax * (1.0 - ay)), (0, 1, (1.0 - ax) * ay), (1, 1, ax * ay)]
    {
        let (tx, ty) = ((x0 + dx).clamp(0, l.width as i32 - 1), (y0 + dy).clamp(0, l.height as i32 - 1));
        let k = (ty as u32 * l.width + tx as u32) as usize;
        if l.valid[k] {
            taps[n] = (l.texels[k], wt.max(1e-4));
            n += 1;
        }
    }
    if n == 0 {
        return None;
    }
    let mean = taps[..n].iter().map(|t| t.0.w).sum::<f32>() / n as f32;
    let slack = 1e-6 * mean.abs().max(1.0);
    let (mut acc, mut ws) = (Vec4::ZERO, 0.0);
    for t in &taps[..n] {
        if t.0.w >= mean - slack {
            acc += t.0 * t.1;
            ws += t.1;
        }
    }
    Some(acc / ws)
}

/// The nearest non-hole pixel along `dir` from `p` with exponentially growing steps (1, 2, 4,
/// ...; seed 003 Sec. 5.2), then bisected between the last two steps: the distance to the
/// hole border and the border pixel's depth. `None` if the ray leaves the image first.
fn border_exp(hole: &Image<bool>, depth: &Image<f32>, p: Vec2, dir: Vec2) -> Option<(f32, f32)> {
    let (w, h) = (hole.width() as f32, hole.height() as f32);
    let mut s = 1.0f32;
    loop {
        let q = p + dir * s;
        if !(q.x >= 0.0 && q.y >= 0.0 && q.x < w && q.y < h) {
            return None;
        }
        let (x, y) = (q.x as u32, q.y as u32);
        if !*hole.get(x, y) {
            // Bisect (s/2, s] for the first non-hole pixel: the border itself, not just a
            // bound (log2 s more reads).
            let (mut lo, mut hi) = (s * 0.5, s);
            while hi - lo > 1.0 {
                let mid = zwarp_core::round::floor(0.5 * (lo + hi));
                let m = p + dir * mid;
                if *hole.get(m.x as u32, m.y as u32) {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            let b = p + dir * hi;
            return Some((hi, *depth.get(b.x as u32, b.y as u32)));
        }
        s *= 2.0;
    }
}

/// The nearest non-hole pixel along `dir` from `p`, pixel by pixel: its position and depth.
fn border_linear(hole: &Image<bool>, depth: &Image<f32>, p: Vec2, dir: Vec2) -> Option<((u32, u32), f32)> {
    let (w, h) = (hole.width() as f32, hole.height() as f32);
    let mut s = 1.0f32;
    loop {
        let q = p + dir * s;
        if !(q.x >= 0.0 && q.y >= 0.0 && q.x < w && q.y < h) {
            return None;
        }
        let (x, y) = (q.x as u32, q.y as u32);
        if !*hole.get(x, y) {
            return Some(((x, y), *depth.get(x, y)));
        }
        s += 1.0;
    }
}

/// Where a foreground silhouette bordering a hole lies in the target, and how much of a hole
/// pixel beside it the foreground is expected to cover.
///
/// The grid puts a discontinuity on the boundary between the last foreground texel and the
/// first background texel, but the source's point samples place the true silhouette only to
/// within about a texel of it. With the edge uniform within +-1 texel of that boundary, a target
/// pixel whose centre lies `u` pixels beyond the warped boundary is covered by the foreground
/// with probability `(1 - u) / 2`, and its least-squares colour is that mix of the foreground and
/// the background fill (what rubber sheets get right in one-pixel slivers and the paper's
/// background-only fill gets wrong). Measured on Sponza 1280x720 (hole PSNR, cyclops +0.05 to
/// +0.25 dB, alternate +0.1 dB over the background alone); a +-0.5 texel spread or a tent
/// measured the same within 0.03 dB.
pub(crate) struct ForegroundEdge {
    to_src: WarpMatrix,
    to_dst: WarpMatrix,
}

impl ForegroundEdge {
    pub(crate) fn new(src: &Camera, dst: &Camera) -> Result<Self> {
        Ok(ForegroundEdge { to_src: WarpMatrix::new(dst, src)?, to_dst: WarpMatrix::new(src, dst)? })
    }

    /// The foreground's expected share of hole pixel centre `p` whose foreground border pixel is
    /// `fg`, at target depth `fg_depth`, lying along unit direction `to_fg`: the source texel
    /// under `fg` is found by warping it back, its boundary crossed on the way to `p` is warped
    /// forward at the same depth, and `u` is how far beyond that boundary `p` lies.
    pub(crate) fn share(&self, p: Vec2, fg: (u32, u32), fg_depth: f32, to_fg: Vec2) -> f32 {
        let c = Vec2::new(fg.0 as f32 + 0.5, fg.1 as f32 + 0.5);
        let (Some(a), Some(b)) = (self.to_src.project(c.x, c.y, fg_depth), self.to_src.project(p.x, p.y, fg_depth))
        else {
            return 0.0;
        };
        let (sa, r) = (Vec2::new(a.0, a.1), Vec2::new(b.0 - a.0, b.1 - a.1));
        // Leave the texel of `sa` towards `p`'s source position: the ray parameter of the exit.
        let lo = sa.map(zwarp_core::round::floor);
        let mut t = f32::INFINITY;
        for k in 0..2 {
            if r[k] > 1e-9 {
                t = t.min((lo[k] + 1.0 - sa[k]) / r[k]);
            } else if r[k] < -1e-9 {
                t = t.min((lo[k] - sa[k]) / r[k]);
            }
        }
        let u = if t >= 1.0 {
            0.0 // `p` warps back into the foreground texel itself: on the boundary
        } else {
            let e = sa + t * r;
            match self.to_dst.project(e.x, e.y, a.2) {
                Some(e) => (Vec2::new(e.0, e.1) - p).dot(to_fg),
                None => return 0.0,
            }
        };
        (0.5 * (1.0 - u)).clamp(0.0, 1.0)
    }
}

/// Fills the holes of `warped` (a warp of `src` to `dst`) with `method`; pixels outside the
/// holes keep their colour. Rubber sheets run the connected quad warp of `src`; holes it leaves
/// at the image border get the push-pull.
pub fn fill_holes(warped: &WarpOutput, src: &Source<'_>, dst: &Camera, method: HoleMethod) -> Result<Image<[f32; 3]>> {
    let (color, depth, hole) = (&warped.color, &warped.depth, &warped.hole);
    color.check_same_size(hole, "hole filling colour vs mask")?;
    color.check_same_size(depth, "hole filling colour vs depth")?;
    if color.size() != (dst.width, dst.height) {
        return Err(Error::invalid("hole filling: the warp does not have the target camera's size"));
    }
    let (w, _) = color.size();
    if !hole.data().iter().any(|&x| x) {
        return Ok(color.clone());
    }
    let e = epipole(src.cam, dst);
    let mut out = color.clone();
    match method {
        HoleMethod::PushPull => {
            zwarp_color::push_pull(&mut out, &hole.map(|&x| !x))?;
        }
        HoleMethod::Rubber => {
            // The connected quads drawn where the holes are (exact there, a fraction of the work).
            let mesh = Mesh::build(src, dst, Method::Quads, &WarpParams::default())?;
            let q = raster_where(src, dst, &mesh, hole)?;
            let mut still = hole.clone();
            for (i, (o, &hl)) in out.data_mut().iter_mut().zip(hole.data()).enumerate() {
                if hl && !q.hole.data()[i] {
                    *o = q.color.data()[i];
                    still.data_mut()[i] = false;
                }
            }
            zwarp_color::push_pull(&mut out, &still.map(|&x| !x))?;
        }
        HoleMethod::Stretch => {
            let fill: Vec<Option<[f32; 3]>> = (0..hole.len())
                .into_par_iter()
                .map(|i| {
                    if !hole.data()[i] {
                        return None;
                    }
                    let p = Vec2::new((i as u32 % w) as f32 + 0.5, (i as u32 / w) as f32 + 0.5);
                    let d = epipolar_dir(e, p);
                    let a = border_linear(hole, depth, p, d);
                    let b = border_linear(hole, depth, p, -d);
                    // The background side: the farther border.
                    let pick = match (a, b) {
                        (Some(a), Some(b)) => Some(if a.1 >= b.1 { a } else { b }),
                        (a, b) => a.or(b),
                    };
                    pick.map(|((x, y), _)| *color.get(x, y))
                })
                .collect();
            let mut valid = hole.map(|&x| !x);
            for (i, f) in fill.iter().enumerate() {
                if let Some(c) = f {
                    out.data_mut()[i] = *c;
                    valid.data_mut()[i] = true;
                }
            }
            // Pixels whose epipolar line leaves the image on both sides.
            zwarp_color::push_pull(&mut out, &valid)?;
        }
        HoleMethod::LowPass => {
            let pyr = lowpass_pyramid(color, depth, hole)?;
            let top = pyr.len() - 1;
            let edge = ForegroundEdge::new(src.cam, dst)?;
            let at_pixel = |q: Vec2| (q.x as u32, q.y as u32);
            out.data_mut().par_iter_mut().enumerate().for_each(|(i, o)| {
                if !hole.data()[i] {
                    return;
                }
                let p = Vec2::new((i as u32 % w) as f32 + 0.5, (i as u32 / w) as f32 + 0.5);
                let d = epipolar_dir(e, p);
                let a = border_exp(hole, depth, p, d);
                let b = border_exp(hole, depth, p, -d);
                // Between two borders: the farther one is the background side, the other the
                // foreground where its depth is nearer (distance and depth along +-d, direction).
                let sides = match (a, b) {
                    (Some(a), Some(b)) => Some(if a.1 >= b.1 { ((a, d), (b, -d)) } else { ((b, -d), (a, d)) }),
                    _ => None,
                };
                let fg = sides.filter(|(g, f)| f.0 .1 < g.0 .1).map(|(_, f)| f);
                let mix = |bg: [f32; 3]| match fg {
                    Some(((dist, z), to_fg)) => {
                        let f = at_pixel(p + dist * to_fg);
                        let s = edge.share(p, f, z, to_fg);
                        let c = *color.get(f.0, f.1);
                        [bg[0] + s * (c[0] - bg[0]), bg[1] + s * (c[1] - bg[1]), bg[2] + s * (c[2] - bg[2])]
                    }
                    None => bg,
                };
                // Read half way to the background border, at the level whose filter radius
                // (2^(l-1) pixels) reaches it: the colour of the border, blurred more the farther
                // the pixel is from it (Mark's blurred stripes, seed 003 Sec. 5.2). A hole one
                // pixel across between a foreground and a background reads its background
                // neighbour itself (nothing to low-pass). A hole that reaches the image border has
                // no background side: it continues the surface at its inner border, read there at
                // level 0 (nothing on the far side to blend with; a blur measured worse there).
                let (mut lvl, at) = match (sides, a, b) {
                    (Some((((gd, _), to_bg), ((fd, _), _))), _, _) => {
                        if fg.is_some() && gd + fd <= 2.0 {
                            let g = at_pixel(p + gd * to_bg);
                            *o = mix(*color.get(g.0, g.1));
                            return;
                        }
                        let v = gd * to_bg;
                        ((0.5 * v.length()).log2().ceil().max(0.0) as usize + 1, p + 0.5 * v)
                    }
                    (None, Some(a), _) => (0, p + a.0 * d),
                    (None, _, Some(b)) => (0, p - b.0 * d),
                    (None, None, None) => (top, p),
                };
                lvl = lvl.min(top);
                loop {
                    if let Some(t) = read_level(&pyr[lvl], (1u32 << lvl) as f32, at) {
                        *o = mix([t.x, t.y, t.z]);
                        break;
                    }
                    if lvl == top {
                        break;
                    }
                    lvl += 1;
                }
            });
        }
    }
    Ok(out)
}
