//! The frame-generation baselines the colour warps are measured against (seed 001 Sec. 2, 5,
//! Table 1, Fig. 8; ARCHITECTURE.md "Pitfalls of public implementations"):
//!
//! - [`repeat`]: show the last frame again;
//! - [`mesh_warp`]: the per-pixel forward mesh warp of Mark et al. 1997 — texel centres as
//!   vertices moved by the field, two triangles per cell rasterised with a depth test, triangles
//!   across depth discontinuities discarded (Sec. 5: "triangles that straddle discontinuities in
//!   the warp are discarded");
//! - [`reproject`]: reverse reprojection caching (Nehab et al. 2007): the caller re-renders the
//!   target's depth, every target pixel is reprojected into the source, validated against the
//!   point-sampled source depth and looks up the colour bilinearly;
//! - [`scatter_warp`]: an FSR3-like forward scatter — every source texel splats to the target
//!   pixels its footprint (expanded by half a pixel, `zwarp_warp::FORWARD_SUPPORT_EXPANSION`)
//!   covers, nearest depth wins (atomic min on depth and texel index) — with the push-pull
//!   in-painting pyramid ([`push_pull`]) for what stays empty.
//!
//! Holes of the mesh warp and cache misses of the reprojection get the same [`push_pull`]
//! fill, so every method delivers a complete frame. Outputs use [`ColorWarpOutput`]: residual
//! 0 where the method produced a value, `+inf` where the pixel was in-painted.

use std::sync::atomic::{AtomicU64, Ordering};

use glam::Vec2;
use rayon::prelude::*;
use zwarp_core::{Camera, Image, Motion, Result};
use zwarp_warp::FORWARD_SUPPORT_EXPANSION;

use crate::field::Field;
use crate::heuristic::check_color;
use crate::ColorWarpOutput;

/// Repeat-the-last-frame: the source colour unchanged (residual 0 everywhere).
pub fn repeat(color: &Image<[f32; 3]>, depth: &Image<f32>) -> Result<ColorWarpOutput> {
    color.check_same_size(depth, "repeat")?;
    let (w, h) = color.size();
    Ok(ColorWarpOutput { color: color.clone(), depth: depth.clone(), residual: Image::new(w, h, 0.0), threshold: 0.5 })
}

/// Relative linear-depth jump above which [`mesh_warp`] treats two vertices as disconnected
/// (together with a motion difference of at least a pixel).
pub const MESH_DEPTH_JUMP: f32 = 0.1;

/// Relative linear-depth tolerance of the cache validation of [`reproject`] (Nehab et al. 2007's
/// epsilon test on point-sampled cached depth).
pub const REPROJECT_DEPTH_TOLERANCE: f32 = 0.02;

const EMPTY_KEY: u64 = u64::MAX;

#[inline]
fn key(depth: f32, id: u32) -> u64 {
    ((depth.max(0.0).to_bits() as u64) << 32) | id as u64
}

/// Per-pixel forward mesh warp (Mark et al. 1997) of `color` by `field`; `cam` is the source
/// camera (linear depth for the discontinuity test). Holes are in-painted by [`push_pull`].
pub fn mesh_warp(field: &Field<'_>, color: &Image<[f32; 3]>, cam: &Camera) -> Result<ColorWarpOutput> {
    check_color(field, color)?;
    let (w, h) = field.size();
    let (wu, hu) = (w as usize, h as usize);
    let buf: Vec<AtomicU64> = (0..wu * hu).map(|_| AtomicU64::new(EMPTY_KEY)).collect();
    let depth = field.depth();
    let pos = |i: usize| Vec2::new((i % wu) as f32 + 0.5, (i / wu) as f32 + 0.5) + field.v(i);
    if w >= 2 && h >= 2 {
        (0..hu - 1).into_par_iter().for_each(|cy| {
            for cx in 0..wu - 1 {
                let i = [cy * wu + cx, cy * wu + cx + 1, (cy + 1) * wu + cx, (cy + 1) * wu + cx + 1];
                let p = i.map(pos);
                let z = i.map(|k| depth[k]);
                let lin = z.map(|d| cam.linear_depth(d));
                for (half, tri) in [[0usize, 1, 3], [0, 3, 2]].iter().enumerate() {
                    let (vs, ls) = (
                        tri.map(|k| p[k] - Vec2::new((i[k] % wu) as f32 + 0.5, (i[k] / wu) as f32 + 0.5)),
                        tri.map(|k| lin[k]),
                    );
                    let lo = vs[0].min(vs[1]).min(vs[2]);
                    let hi = vs[0].max(vs[1]).max(vs[2]);
                    let (lmin, lmax) = (ls[0].min(ls[1]).min(ls[2]), ls[0].max(ls[1]).max(ls[2]));
                    if (hi - lo).max_element() >= 1.0 && lmax > lmin * (1.0 + MESH_DEPTH_JUMP) {
                        continue; // straddles a discontinuity
                    }
                    let id = ((cy * (wu - 1) + cx) * 2 + half) as u32;
                    raster_triangle(
                        &buf,
                        w,
                        h,
                        [p[tri[0]], p[tri[1]], p[tri[2]]],
                        [z[tri[0]], z[tri[1]], z[tri[2]]],
                        id,
                    );
                }
            }
        });
    }
    let mut out = ColorWarpOutput::empty();
    out.resize(w, h, 0.5);
    let src = color.data();
    let mut valid = Image::new(w, h, false);
    out.color
        .data_mut()
        .par_iter_mut()
        .zip(out.depth.data_mut().par_iter_mut())
        .zip(out.residual.data_mut().par_iter_mut())
        .zip(valid.data_mut().par_iter_mut())
        .enumerate()
        .for_each(|(j, (((c, d), r), ok))| {
            let k = buf[j].load(Ordering::Relaxed);
            if k == EMPTY_KEY {
                *r = f32::INFINITY;
                *d = 1.0;
                return;
            }
            let id = (k & 0xffff_ffff) as usize;
            let (cell, half) = (id / 2, id % 2);
            let (cx, cy) = (cell % (wu - 1), cell / (wu - 1));
            let i = [cy * wu + cx, cy * wu + cx + 1, (cy + 1) * wu + cx, (cy + 1) * wu + cx + 1];
            let tri = if half == 0 { [i[0], i[1], i[3]] } else { [i[0], i[3], i[2]] };
            let p = Vec2::new((j % wu) as f32 + 0.5, (j / wu) as f32 + 0.5);
            let b = barycentric(tri.map(pos), p);
            *c = [0, 1, 2].map(|ch| b[0] * src[tri[0]][ch] + b[1] * src[tri[1]][ch] + b[2] * src[tri[2]][ch]);
            *d = f32::from_bits((k >> 32) as u32);
            *r = 0.0;
            *ok = true;
        });
    push_pull(&mut out.color, &valid)?;
    Ok(out)
}

/// Barycentric weights of `p` in triangle `t` (clamped to the triangle, degenerate -> vertex 0).
#[inline]
fn barycentric(t: [Vec2; 3], p: Vec2) -> [f32; 3] {
    let e = |a: Vec2, b: Vec2, c: Vec2| (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    let area = e(t[0], t[1], t[2]);
    if area.abs() < 1e-12 {
        return [1.0, 0.0, 0.0];
    }
    let b1 = (e(t[2], t[0], p) / area).clamp(0.0, 1.0);
    let b2 = (e(t[0], t[1], p) / area).clamp(0.0, 1.0);
    let b0 = (1.0 - b1 - b2).max(0.0);
    let s = b0 + b1 + b2;
    [b0 / s, b1 / s, b2 / s]
}

/// Rasterises one triangle (pixel centres inside or on an edge) with an atomic depth test.
fn raster_triangle(buf: &[AtomicU64], w: u32, h: u32, p: [Vec2; 3], z: [f32; 3], id: u32) {
    let lo = p[0].min(p[1]).min(p[2]);
    let hi = p[0].max(p[1]).max(p[2]);
    if !(lo.is_finite() && hi.is_finite()) || hi.x < 0.0 || hi.y < 0.0 || lo.x > w as f32 || lo.y > h as f32 {
        return;
    }
    let x0 = (zwarp_core::round::ceil(lo.x - 0.5).max(0.0)) as u32;
    let y0 = (zwarp_core::round::ceil(lo.y - 0.5).max(0.0)) as u32;
    let x1 = (zwarp_core::round::floor(hi.x - 0.5).min(w as f32 - 1.0)) as i64;
    let y1 = (zwarp_core::round::floor(hi.y - 0.5).min(h as f32 - 1.0)) as i64;
    let e = |a: Vec2, b: Vec2, c: Vec2| (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    let area = e(p[0], p[1], p[2]);
    if area.abs() < 1e-12 {
        return;
    }
    let inv = 1.0 / area;
    for y in y0 as i64..=y1 {
        for x in x0 as i64..=x1 {
            let q = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            let (w0, w1, w2) = (e(p[1], p[2], q) * inv, e(p[2], p[0], q) * inv, e(p[0], p[1], q) * inv);
            if w0 >= 0.0 && w1 >= 0.0 && w2 >= 0.0 {
                let d = w0 * z[0] + w1 * z[1] + w2 * z[2];
                buf[y as usize * w as usize + x as usize].fetch_min(key(d, id), Ordering::Relaxed);
            }
        }
    }
}

/// FSR3-like forward scatter of `color` by `field`: each texel splats its colour to the target
/// pixels whose centres lie strictly inside its footprint (1 px, expanded by
/// `FORWARD_SUPPORT_EXPANSION` per side) moved by `V`, nearest source depth wins (ties: lower
/// texel index); [`push_pull`] fills the rest.
pub fn scatter_warp(field: &Field<'_>, color: &Image<[f32; 3]>) -> Result<ColorWarpOutput> {
    check_color(field, color)?;
    let (w, h) = field.size();
    let wu = w as usize;
    let buf: Vec<AtomicU64> = (0..wu * h as usize).map(|_| AtomicU64::new(EMPTY_KEY)).collect();
    let depth = field.depth();
    let hs = 0.5 + FORWARD_SUPPORT_EXPANSION;
    (0..h as usize).into_par_iter().for_each(|y| {
        for x in 0..wu {
            let i = y * wu + x;
            let p = Vec2::new(x as f32 + 0.5, y as f32 + 0.5) + field.v(i);
            if !p.is_finite() {
                continue;
            }
            // Centres c with p - hs < c < p + hs.
            let xa = (zwarp_core::round::floor(p.x - hs - 0.5) + 1.0).max(0.0);
            let xb = (zwarp_core::round::ceil(p.x + hs - 0.5) - 1.0).min(w as f32 - 1.0);
            let ya = (zwarp_core::round::floor(p.y - hs - 0.5) + 1.0).max(0.0);
            let yb = (zwarp_core::round::ceil(p.y + hs - 0.5) - 1.0).min(h as f32 - 1.0);
            if xa > xb || ya > yb {
                continue;
            }
            let k = key(depth[i], i as u32);
            for ty in ya as usize..=yb as usize {
                for tx in xa as usize..=xb as usize {
                    buf[ty * wu + tx].fetch_min(k, Ordering::Relaxed);
                }
            }
        }
    });
    let mut out = ColorWarpOutput::empty();
    out.resize(w, h, 0.5);
    let src = color.data();
    let mut valid = Image::new(w, h, false);
    out.color
        .data_mut()
        .par_iter_mut()
        .zip(out.depth.data_mut().par_iter_mut())
        .zip(out.residual.data_mut().par_iter_mut())
        .zip(valid.data_mut().par_iter_mut())
        .zip(buf.par_iter())
        .for_each(|((((c, d), r), ok), b)| {
            let k = b.load(Ordering::Relaxed);
            if k == EMPTY_KEY {
                (*d, *r) = (1.0, f32::INFINITY);
            } else {
                *c = src[(k & 0xffff_ffff) as usize];
                (*d, *r, *ok) = (f32::from_bits((k >> 32) as u32), 0.0, true);
            }
        });
    push_pull(&mut out.color, &valid)?;
    Ok(out)
}

fn check_reproject(target_depth: &Image<f32>, to_source: &Image<Motion>, source_depth: &Image<f32>) -> Result<()> {
    target_depth.check_nonempty("reprojection target depth")?;
    target_depth.check_same_size(to_source, "reprojection target depth vs motion")?;
    source_depth.check_nonempty("reprojection source depth")?;
    Ok(())
}

/// The cache test of [`reproject`]: `true` where the target pixel's surface point, moved into
/// the source by `to_source` (the motion field of the re-rendered target depth towards the
/// source view, `zwarp_core::motion_field`), lands inside the source on a texel whose
/// point-sampled depth agrees with the reprojected depth within
/// [`REPROJECT_DEPTH_TOLERANCE`] (relative, linear depth of `cam_source`). `false` marks the
/// pixels the source did not see (disocclusions and the image border).
pub fn source_visibility(
    target_depth: &Image<f32>,
    to_source: &Image<Motion>,
    source_depth: &Image<f32>,
    cam_source: &Camera,
) -> Result<Image<bool>> {
    check_reproject(target_depth, to_source, source_depth)?;
    let (sw, sh) = source_depth.size();
    let (w, _) = target_depth.size();
    let data: Vec<bool> = to_source
        .data()
        .par_iter()
        .zip(target_depth.data())
        .enumerate()
        .map(|(j, (m, &zt))| {
            let p = Vec2::new((j % w as usize) as f32 + 0.5, (j / w as usize) as f32 + 0.5);
            let q = p + m.v;
            if !(q.x >= 0.0 && q.y >= 0.0 && q.x < sw as f32 && q.y < sh as f32) {
                return false;
            }
            let zs = *source_depth.get(q.x as u32, q.y as u32);
            if zt >= 1.0 || m.depth >= 1.0 {
                return zs >= 1.0; // sky sees sky
            }
            let (ls, lr) = (cam_source.linear_depth(zs.min(1.0)), cam_source.linear_depth(m.depth.clamp(0.0, 1.0)));
            (ls - lr).abs() <= REPROJECT_DEPTH_TOLERANCE * lr
        })
        .collect();
    Image::from_vec(target_depth.width(), target_depth.height(), data)
}

/// Reverse reprojection caching (Nehab et al. 2007): colour of each target pixel looked up
/// bilinearly in the source `color` at `p + to_source(p)` where [`source_visibility`] accepts
/// the cache entry; misses are in-painted by [`push_pull`]. The output depth is the target's.
pub fn reproject(
    target_depth: &Image<f32>,
    to_source: &Image<Motion>,
    source_depth: &Image<f32>,
    color: &Image<[f32; 3]>,
    cam_source: &Camera,
) -> Result<ColorWarpOutput> {
    source_depth.check_same_size(color, "reprojection source depth vs colour")?;
    let valid = source_visibility(target_depth, to_source, source_depth, cam_source)?;
    let (w, h) = target_depth.size();
    let (sw, sh) = color.size();
    let src = color.data();
    let mut out = ColorWarpOutput::empty();
    out.resize(w, h, 0.5);
    out.depth.data_mut().copy_from_slice(target_depth.data());
    out.color.data_mut().par_iter_mut().zip(out.residual.data_mut().par_iter_mut()).enumerate().for_each(
        |(j, (c, r))| {
            if !valid.data()[j] {
                *r = f32::INFINITY;
                return;
            }
            let p = Vec2::new((j % w as usize) as f32 + 0.5, (j / w as usize) as f32 + 0.5);
            *c = bilinear(src, sw, sh, p + to_source.data()[j].v);
            *r = 0.0;
        },
    );
    push_pull(&mut out.color, &valid)?;
    Ok(out)
}

/// Plain bilinear look-up of a `w x h` colour image at `q` (texel centres at `+0.5`, clamped).
#[inline]
pub(crate) fn bilinear(src: &[[f32; 3]], w: u32, h: u32, q: Vec2) -> [f32; 3] {
    let t = (q - Vec2::splat(0.5)).clamp(Vec2::ZERO, Vec2::new(w as f32 - 1.0, h as f32 - 1.0));
    let (x0, y0) = (t.x as u32, t.y as u32);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (ax, ay) = (t.x - x0 as f32, t.y - y0 as f32);
    let at = |x: u32, y: u32| src[y as usize * w as usize + x as usize];
    let (c00, c10, c01, c11) = (at(x0, y0), at(x1, y0), at(x0, y1), at(x1, y1));
    [0, 1, 2].map(|k| {
        let top = c00[k] + (c10[k] - c00[k]) * ax;
        let bot = c01[k] + (c11[k] - c01[k]) * ax;
        top + (bot - top) * ay
    })
}

/// Push-pull in-painting (the mip "inpainting pyramid" of FSR3's frame interpolation): a pull
/// pass averages the valid pixels of every 2x2 block level by level, a push pass fills every
/// invalid pixel with the bilinear value of the coarser level. Pixels marked valid keep their
/// colour. Errors on a size mismatch; an image without a valid pixel is left unchanged.
pub fn push_pull(color: &mut Image<[f32; 3]>, valid: &Image<bool>) -> Result<()> {
    color.check_same_size(valid, "push-pull")?;
    if valid.data().iter().all(|&v| v) || !valid.data().iter().any(|&v| v) {
        return Ok(());
    }
    let (w, h) = color.size();
    /// One level of the pyramid: size, colours, coverage.
    struct Level {
        w: usize,
        h: usize,
        c: Vec<[f32; 3]>,
        v: Vec<bool>,
    }
    // Pull: level l + 1 averages the valid texels of each 2x2 block of level l (level 0 is the
    // image itself, read in place).
    let pull = |lw: usize, lh: usize, c: &[[f32; 3]], v: &[bool]| -> Level {
        let (nw, nh) = (lw.div_ceil(2), lh.div_ceil(2));
        let mut nc = vec![[0.0f32; 3]; nw * nh];
        let mut nv = vec![false; nw * nh];
        nc.par_chunks_mut(nw).zip(nv.par_chunks_mut(nw)).enumerate().for_each(|(ny, (oc, ov))| {
            for nx in 0..nw {
                let (x, y) = (2 * nx, 2 * ny);
                let mut s = [0.0f32; 3];
                let mut n = 0u32;
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let (cx, cy) = (x + dx, y + dy);
                    if cx < lw && cy < lh && v[cy * lw + cx] {
                        let p = c[cy * lw + cx];
                        s = [s[0] + p[0], s[1] + p[1], s[2] + p[2]];
                        n += 1;
                    }
                }
                if n > 0 {
                    oc[nx] = s.map(|x| x / n as f32);
                    ov[nx] = true;
                }
            }
        });
        Level { w: nw, h: nh, c: nc, v: nv }
    };
    let mut levels = vec![pull(w as usize, h as usize, color.data(), valid.data())];
    while {
        let l = levels.last().expect("a level");
        l.w > 1 || l.h > 1
    } {
        let l = levels.last().expect("a level");
        let next = pull(l.w, l.h, &l.c, &l.v);
        levels.push(next);
    }
    // Push: every invalid texel takes the bilinear value of the level above.
    let push = |lw: usize, c: &mut [[f32; 3]], v: &[bool], up: &Level| {
        c.par_chunks_mut(lw).enumerate().for_each(|(y, row)| {
            for (x, o) in row.iter_mut().enumerate() {
                if !v[y * lw + x] {
                    let q = Vec2::new((x as f32 + 0.5) * 0.5, (y as f32 + 0.5) * 0.5);
                    *o = bilinear(&up.c, up.w as u32, up.h as u32, q);
                }
            }
        });
    };
    for l in (0..levels.len() - 1).rev() {
        let (lower, upper) = levels.split_at_mut(l + 1);
        let cur = &mut lower[l];
        push(cur.w, &mut cur.c, &cur.v, &upper[0]);
        cur.v.iter_mut().for_each(|v| *v = true);
    }
    push(w as usize, color.data_mut(), valid.data(), &levels[0]);
    Ok(())
}
