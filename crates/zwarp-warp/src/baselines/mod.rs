//! Forward-warping baselines of seed 000 Sec. 4.1: vertex-driven forward warping (VFW, Lee et
//! al. 2008 / Zwicker et al. 2002) and atomics-driven forward warping (AFW, Yu et al. 2010 /
//! Cichocki 2017; the family of FSR3's depth scatter). Both write each source sample's target
//! depth (`Motion::depth`) with a depth test (atomic min on the `f32` bits: non-negative floats
//! order like their `u32` bit patterns), parallel with rayon, and both expand each sample's
//! support by half a pixel per side ([`FORWARD_SUPPORT_EXPANSION`]) so the comparison with the
//! backward warp is fair (without it they crack on every stretching surface). Multi-layer
//! versions splat every layer into the same buffer (paper: "we adapt VFW and AFW to repeat them
//! for each layer"). Holes keep the far depth `1.0`.

use glam::Vec2;
use rayon::prelude::*;
use zwarp_core::{Error, Image, Motion, Result, EMPTY_DEPTH};

use crate::depth_warp::WarpLayer;
use crate::sampling::CONTINUITY_PX;

/// Support expansion of the forward warps, in pixels per side (Sec. 4.1: "by a half-pixel
/// length to each side").
pub const FORWARD_SUPPORT_EXPANSION: f32 = 0.5;

/// VFW of one layer: every source pixel becomes a quad whose four corners move with the motion
/// interpolated at the pixel corners, expanded by half a pixel, rasterized (two triangles,
/// pixel centres strictly inside) with a depth test. See [`vfw_layers`].
pub fn vfw(depth: &Image<f32>, motion: &Image<Motion>) -> Result<Image<f32>> {
    vfw_layers(&[WarpLayer { depth, motion }])
}

/// AFW of one layer: every source pixel splats its target depth with atomic min into the target
/// pixels whose centres lie strictly inside its footprint (the pixel square moved by its motion,
/// expanded by half a pixel per side). See [`afw_layers`].
pub fn afw(depth: &Image<f32>, motion: &Image<Motion>) -> Result<Image<f32>> {
    afw_layers(&[WarpLayer { depth, motion }])
}

/// The rows a forward warp needs: per source row, the range of target rows its splats can
/// touch (`None` for a row without a valid sample), from one validating pass over the layer.
struct RowReach {
    /// Per source row: the smallest and largest `y + 0.5 + v.y` of its valid samples.
    rows: Vec<Option<(f32, f32)>>,
}

/// A valid forward-warp sample: source depth `< 1`, target depth in `[0, 1)`, finite motion
/// (the samples the backward warp searches, `PreparedLayer`).
#[inline(always)]
fn valid(d: f32, m: &Motion) -> bool {
    (d < EMPTY_DEPTH) & (m.depth >= 0.0) & (m.depth < 1.0) & m.v.x.is_finite() & m.v.y.is_finite()
}

/// Validates every layer (equal sizes, finite depth, no NaN motion) and measures, per layer and
/// source row, the target rows its samples move to.
fn check_layers(layers: &[WarpLayer<'_>]) -> Result<(u32, u32, Vec<RowReach>)> {
    let first = layers.first().ok_or_else(|| Error::invalid("forward warp needs at least one layer"))?;
    let (w, h) = first.depth.size();
    if w == 0 || h == 0 {
        return Err(Error::invalid(format!("forward warp of a zero-size {w}x{h} layer")));
    }
    let mut out = Vec::with_capacity(layers.len());
    for (i, l) in layers.iter().enumerate() {
        if l.depth.size() != (w, h) || l.motion.size() != (w, h) {
            return Err(Error::invalid(format!(
                "layer {i} is {}x{} (motion {}x{}) but layer 0 is {w}x{h}",
                l.depth.width(),
                l.depth.height(),
                l.motion.width(),
                l.motion.height()
            )));
        }
        let (depth, motion) = (l.depth.data(), l.motion.data());
        let rows: Vec<(u8, Option<(f32, f32)>)> = (0..h as usize)
            .into_par_iter()
            .map(|y| {
                let (d, m) =
                    (&depth[y * w as usize..(y + 1) * w as usize], &motion[y * w as usize..(y + 1) * w as usize]);
                #[cfg(target_arch = "x86_64")]
                let (flags, lo, hi) = if crate::simd::has_avx2() {
                    // SAFETY: only taken when the CPU reports AVX2.
                    unsafe { avx2::row_check(d, m) }
                } else {
                    row_check(d, m)
                };
                #[cfg(not(target_arch = "x86_64"))]
                let (flags, lo, hi) = row_check(d, m);
                let c = y as f32 + 0.5;
                (flags, (lo <= hi).then_some((c + lo, c + hi)))
            })
            .collect();
        let flags = rows.iter().fold(0u8, |a, r| a | r.0);
        if flags & 1 != 0 {
            return Err(Error::invalid("layer depth holds NaN or infinite values"));
        }
        if flags & 2 != 0 {
            return Err(Error::invalid("motion buffer holds NaN values"));
        }
        out.push(RowReach { rows: rows.into_iter().map(|r| r.1).collect() });
    }
    Ok((w, h, out))
}

/// One source row's check: flags (bit 0: a non-finite depth, bit 1: a NaN in the motion) and
/// the range of the valid samples' vertical motion (empty: `lo > hi`).
#[inline(always)]
fn row_check(d: &[f32], m: &[Motion]) -> (u8, f32, f32) {
    let mut flags = 0u8;
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for (&d, m) in d.iter().zip(m) {
        flags |= (!d.is_finite()) as u8 | ((m.v.x.is_nan() | m.v.y.is_nan() | m.depth.is_nan()) as u8) << 1;
        if valid(d, m) {
            lo = lo.min(m.v.y);
            hi = hi.max(m.v.y);
        }
    }
    (flags, lo, hi)
}

/// Target rows per band of the forward warps: each band is written by one task, which splats
/// every source sample whose footprint reaches the band (clipped to it), so no two tasks write
/// the same pixel and no atomics are needed (the depth test is a min: order does not matter).
const BAND: usize = 32;

/// Runs `splat(scratch, band_rows, y0, layer, source_row)` for every band of `BAND` target rows and every
/// source row of every layer whose target rows (widened by `margin`) reach it, in parallel over
/// bands, into `target` (recycled: resized to `w x h`, every pixel reset to far depth by the band
/// that owns it, while it is in cache). `scratch` is a task's own state, carried from one source
/// row to the next (rows come in order, per layer).
fn forward<S: Default + Send>(
    w: u32,
    h: u32,
    reach: &[RowReach],
    margin: f32,
    target: &mut Image<f32>,
    splat: impl Fn(&mut S, &mut [f32], usize, usize, usize) + Sync,
) -> Result<()> {
    let n = w as usize * h as usize;
    let mut buf = std::mem::replace(target, Image::new(0, 0, EMPTY_DEPTH)).into_vec();
    if buf.capacity() < n {
        buf = zwarp_core::pages::filled(n, EMPTY_DEPTH);
    } else {
        buf.resize(n, EMPTY_DEPTH);
    }
    buf.par_chunks_mut(BAND * w as usize).enumerate().for_each_init(S::default, |scratch, (b, band)| {
        band.fill(EMPTY_DEPTH);
        let y0 = b * BAND;
        let y1 = y0 + band.len() / w as usize;
        let (lo, hi) = (y0 as f32 - margin, y1 as f32 + margin);
        for (k, r) in reach.iter().enumerate() {
            for (y, range) in r.rows.iter().enumerate() {
                if let Some((a, c)) = range {
                    if *c >= lo && *a <= hi {
                        splat(scratch, band, y0, k, y);
                    }
                }
            }
        }
    });
    *target = Image::from_vec(w, h, buf)?;
    Ok(())
}

/// Multi-layer AFW (see [`afw`]).
pub fn afw_layers(layers: &[WarpLayer<'_>]) -> Result<Image<f32>> {
    let mut out = Image::new(0, 0, EMPTY_DEPTH);
    afw_layers_into(layers, &mut out)?;
    Ok(out)
}

/// [`afw_layers`] into `out` (an earlier output of any size, recycled as an engine keeps its
/// buffers from frame to frame); the result is the same.
pub fn afw_layers_into(layers: &[WarpLayer<'_>], out: &mut Image<f32>) -> Result<()> {
    let (w, h, reach) = check_layers(layers)?;
    forward(w, h, &reach, AFW_HALF_SIZE + 1.0, out, |_: &mut (), band, y0, k, y| {
        #[cfg(target_arch = "x86_64")]
        if crate::simd::has_avx2() {
            // SAFETY: only taken when the CPU reports AVX2.
            unsafe { avx2::afw_row(&layers[k], w, h, band, y0, y) };
            return;
        }
        afw_row(&layers[k], w, h, band, y0, y)
    })
}

/// Half the side of an AFW footprint: the pixel's half side plus the expansion. It is one pixel,
/// so a footprint holds at most 2 x 2 target centres.
const AFW_HALF_SIZE: f32 = 0.5 + FORWARD_SUPPORT_EXPANSION;

/// The first and last target index `j` in `[lo, hi]` whose centre `j + 0.5` lies strictly inside
/// `(c - AFW_HALF_SIZE, c + AFW_HALF_SIZE)`, the range empty when `first > last`. The float
/// bounds are clamped before the conversion, which keeps every empty range empty.
#[inline(always)]
fn afw_span(c: f32, lo: i32, hi: i32) -> (i32, i32) {
    let (lof, hif) = (lo as f32 - 1.0, hi as f32 + 1.0);
    let first = ((c - AFW_HALF_SIZE - 0.5).floor().clamp(lof, hif) as i32 + 1).max(lo);
    let last = ((c + AFW_HALF_SIZE - 0.5).ceil().clamp(lof, hif) as i32 - 1).min(hi);
    (first, last)
}

/// A band of target rows being splatted into: `rows` holds target rows `y0..=y1` of width `w`.
struct Band<'a> {
    rows: &'a mut [f32],
    w: usize,
    /// The target's height.
    h: u32,
    y0: i32,
    y1: i32,
}

impl Band<'_> {
    /// The band of target rows starting at `y0` held by `rows` (whole rows of a `w x h` target).
    fn new(rows: &mut [f32], w: u32, h: u32, y0: usize) -> Band<'_> {
        let n = rows.len() / w as usize;
        Band { rows, w: w as usize, h, y0: y0 as i32, y1: (y0 + n).min(h as usize) as i32 - 1 }
    }

    /// The band's first and last target row, as floats.
    #[inline(always)]
    fn clip(&self) -> (f32, f32) {
        (self.y0 as f32, self.y1 as f32)
    }

    /// The AFW splat of the valid source sample whose moved centre is `(cx, cy)` with target
    /// depth `z`. A footprint covers at most 2 x 2 centres: the corners of its span are written,
    /// a centre twice where the span is one wide (the min makes that harmless), so no loop
    /// depends on the motion.
    #[inline(always)]
    fn afw_splat(&mut self, cx: f32, cy: f32, z: f32) {
        let (x0, x1) = afw_span(cx, 0, self.w as i32 - 1);
        let (t0, t1) = afw_span(cy, self.y0, self.y1);
        if x0 > x1 || t0 > t1 {
            return;
        }
        debug_assert!(x1 - x0 <= 1 && t1 - t0 <= 1);
        // `+ 0.0` turns -0.0 into +0.0 (the depth order of the bit patterns the atomic
        // versions compare).
        let z = z + 0.0;
        for t in [t0, t1] {
            let row = (t - self.y0) as usize * self.w;
            for i in [row + x0 as usize, row + x1 as usize] {
                let o = &mut self.rows[i];
                *o = if z < *o { z } else { *o };
            }
        }
    }
}

/// The AFW splats of source row `y` into the band of target rows starting at `y0`.
#[inline(always)]
fn afw_row(l: &WarpLayer<'_>, w: u32, h: u32, band: &mut [f32], y0: usize, y: usize) {
    let mut band = Band::new(band, w, h, y0);
    let wu = w as usize;
    let (depth, motion) = (&l.depth.data()[y * wu..(y + 1) * wu], &l.motion.data()[y * wu..(y + 1) * wu]);
    let cy = y as f32 + 0.5;
    for (x, (&d, m)) in depth.iter().zip(motion).enumerate() {
        if valid(d, m) {
            band.afw_splat(x as f32 + 0.5 + m.v.x, cy + m.v.y, m.depth);
        }
    }
}

/// Multi-layer VFW (see [`vfw`]). Corner motion: the mean motion of the (up to four) pixels
/// sharing the corner that are valid and move within [`CONTINUITY_PX`] of the quad's own pixel,
/// so quads stitch on smooth surfaces but do not stretch across depth edges into disocclusions.
/// Each quad carries its pixel's target depth (flat), so zero motion reproduces the source.
pub fn vfw_layers(layers: &[WarpLayer<'_>]) -> Result<Image<f32>> {
    let mut out = Image::new(0, 0, EMPTY_DEPTH);
    vfw_layers_into(layers, &mut out)?;
    Ok(out)
}

/// [`vfw_layers`] into `out` (an earlier output of any size, recycled as an engine keeps its
/// buffers from frame to frame); the result is the same.
pub fn vfw_layers_into(layers: &[WarpLayer<'_>], out: &mut Image<f32>) -> Result<()> {
    let (w, h, reach) = check_layers(layers)?;
    // A corner moves within CONTINUITY_PX of its quad's pixel; corners lie one pixel apart,
    // pushed out by the expansion.
    forward(w, h, &reach, VFW_ROW_REACH, out, |rows: &mut RowCache, band, y0, k, y| {
        #[cfg(target_arch = "x86_64")]
        if crate::simd::has_avx2() {
            // SAFETY: only taken when the CPU reports AVX2.
            unsafe { avx2::vfw_row(&layers[k], k, w, h, band, y0, y, rows) };
            return;
        }
        vfw_row(&layers[k], w, h, band, y0, y)
    })
}

/// The corners (TL, TR, BR, BL) of the VFW quad of the valid pixel `(x, y)` with motion `v`:
/// each pixel corner moves by the mean motion of the (up to four) valid pixels sharing it that
/// move within [`CONTINUITY_PX`] of `v`, and is pushed outwards by
/// [`FORWARD_SUPPORT_EXPANSION`] per axis. `at` gives the valid samples (`None` outside the
/// image or where empty).
#[inline(always)]
fn vfw_quad<'m>(at: &impl Fn(i64, i64) -> Option<&'m Motion>, x: i64, y: i64, v: Vec2) -> [Vec2; 4] {
    let e = FORWARD_SUPPORT_EXPANSION;
    let corner = |cx: i64, cy: i64, out: Vec2| -> Vec2 {
        let mut sum = Vec2::ZERO;
        let mut n = 0.0f32;
        for (px, py) in [(cx - 1, cy - 1), (cx, cy - 1), (cx - 1, cy), (cx, cy)] {
            if let Some(s) = at(px, py) {
                if (s.v - v).abs().max_element() < CONTINUITY_PX {
                    sum += s.v;
                    n += 1.0;
                }
            }
        }
        // n >= 1: the quad's own pixel always shares the corner.
        Vec2::new(cx as f32, cy as f32) + sum / n + out * e
    };
    [
        corner(x, y, Vec2::new(-1.0, -1.0)),
        corner(x + 1, y, Vec2::new(1.0, -1.0)),
        corner(x + 1, y + 1, Vec2::new(1.0, 1.0)),
        corner(x, y + 1, Vec2::new(-1.0, 1.0)),
    ]
}

/// The valid sample at `(x, y)` of a layer (`None` outside the image or where invalid): the
/// neighbour look-up of [`vfw_quad`].
#[inline(always)]
fn sample_at<'m>(l: &WarpLayer<'m>, w: u32, h: u32, x: i64, y: i64) -> Option<&'m Motion> {
    if x < 0 || y < 0 || x >= w as i64 || y >= h as i64 {
        return None;
    }
    let i = y as usize * w as usize + x as usize;
    let m = &l.motion.data()[i];
    valid(l.depth.data()[i], m).then_some(m)
}

/// The VFW quad of the valid pixel `(x, y)` (motion `m`) of layer `l` rasterized into `band`.
#[inline(always)]
fn vfw_pixel(l: &WarpLayer<'_>, band: &mut Band<'_>, x: usize, y: usize, m: &Motion) {
    // The quad's corners lie within 2 px of the pixel's moved centre (corner motion within
    // CONTINUITY_PX of its own, half a pixel of expansion), so its rows lie within 2.5 px:
    // quads that cannot reach the band are skipped before their corners are averaged.
    let c = y as f32 + 0.5 + m.v.y;
    let clip = band.clip();
    if c + VFW_ROW_REACH < clip.0 || c - VFW_ROW_REACH > clip.1 {
        return;
    }
    let (w, h) = (band.w as u32, band.h);
    let q = vfw_quad(&|x, y| sample_at(l, w, h, x, y), x as i64, y as i64, m.v);
    raster_triangle(band, [q[0], q[1], q[2]], m.depth);
    raster_triangle(band, [q[0], q[2], q[3]], m.depth);
}

/// The VFW quads of source row `y` into the band of target rows starting at `y0`.
#[inline(always)]
fn vfw_row(l: &WarpLayer<'_>, w: u32, h: u32, band: &mut [f32], y0: usize, y: usize) {
    let mut band = Band::new(band, w, h, y0);
    for x in 0..w as usize {
        if let Some(m) = sample_at(l, w, h, x as i64, y as i64) {
            vfw_pixel(l, &mut band, x, y, m);
        }
    }
}

/// A bound of the target rows a VFW quad covers around its pixel's moved centre (2.5 px, with
/// room for rounding).
const VFW_ROW_REACH: f32 = 1.0 + CONTINUITY_PX + FORWARD_SUPPORT_EXPANSION + 1.0;

#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
use avx2::RowCache;
/// No row cache without the AVX2 build (the portable one reads the layer directly).
#[cfg(not(target_arch = "x86_64"))]
type RowCache = ();

#[inline]
fn edge(a: Vec2, b: Vec2, p: Vec2) -> f32 {
    (b - a).perp_dot(p - a)
}

/// Rasterizes triangle `t = [a, b, c]` where edge `c -> a` is the quad diagonal: pixel centres
/// strictly inside the outer edges `a -> b`, `b -> c` and on or inside the diagonal (so the two
/// halves of a quad leave no gap; a centre on the diagonal may be written twice, which the
/// min makes harmless), for target rows within the band.
#[inline(always)]
fn raster_triangle(band: &mut Band<'_>, t: [Vec2; 3], z: f32) {
    let area = edge(t[0], t[1], t[2]);
    if area == 0.0 || !area.is_finite() {
        return;
    }
    let s = area.signum();
    let lo = t[0].min(t[1]).min(t[2]);
    let hi = t[0].max(t[1]).max(t[2]);
    let clip = band.clip();
    let x0 = ((lo.x - 0.5).floor() + 1.0).max(0.0);
    let x1 = ((hi.x - 0.5).ceil() - 1.0).min(band.w as f32 - 1.0);
    let ty0 = ((lo.y - 0.5).floor() + 1.0).max(0.0).max(clip.0);
    let ty1 = ((hi.y - 0.5).ceil() - 1.0).min(band.h as f32 - 1.0).min(clip.1);
    if x0 > x1 || ty0 > ty1 {
        return;
    }
    let z = z + 0.0;
    for ty in ty0 as u32..=ty1 as u32 {
        for tx in x0 as u32..=x1 as u32 {
            let p = Vec2::new(tx as f32 + 0.5, ty as f32 + 0.5);
            if s * edge(t[0], t[1], p) > 0.0 && s * edge(t[1], t[2], p) > 0.0 && s * edge(t[2], t[0], p) >= 0.0 {
                let i = (ty as usize - band.y0 as usize) * band.w + tx as usize;
                band.rows[i] = band.rows[i].min(z);
            }
        }
    }
}

/// The atomics-based forward warps these implementations replace, kept as the reference the
/// band-partitioned ones are tested against (same splats, same depth test).
#[cfg(test)]
mod reference {
    use super::*;
    use crate::prepare::validated_samples;
    use std::sync::atomic::{AtomicU32, Ordering};

    fn check_layers(layers: &[WarpLayer<'_>]) -> Result<(u32, u32, Vec<Vec<Motion>>)> {
        let first = layers.first().ok_or_else(|| Error::invalid("forward warp needs at least one layer"))?;
        let (w, h) = first.depth.size();
        let mut out = Vec::with_capacity(layers.len());
        for (i, l) in layers.iter().enumerate() {
            if l.depth.size() != (w, h) {
                return Err(Error::invalid(format!(
                    "layer {i} is {}x{} but layer 0 is {w}x{h}",
                    l.depth.width(),
                    l.depth.height()
                )));
            }
            out.push(validated_samples(l)?);
        }
        Ok((w, h, out))
    }

    fn new_target(n: usize) -> Vec<AtomicU32> {
        (0..n).map(|_| AtomicU32::new(EMPTY_DEPTH.to_bits())).collect()
    }

    fn finish(w: u32, h: u32, buf: Vec<AtomicU32>) -> Result<Image<f32>> {
        Image::from_vec(w, h, buf.into_iter().map(|a| f32::from_bits(a.into_inner())).collect())
    }

    #[inline]
    fn depth_test(buf: &[AtomicU32], i: usize, z: f32) {
        // `+ 0.0` turns -0.0 into +0.0, whose bits order correctly.
        buf[i].fetch_min((z + 0.0).to_bits(), Ordering::Relaxed);
    }

    /// Multi-layer AFW (see [`afw`]).
    pub(super) fn afw_layers(layers: &[WarpLayer<'_>]) -> Result<Image<f32>> {
        let (w, h, layers) = check_layers(layers)?;
        let buf = new_target(w as usize * h as usize);
        let hs = 0.5 + FORWARD_SUPPORT_EXPANSION;
        for samples in &layers {
            samples.par_chunks(w as usize).enumerate().for_each(|(y, row)| {
                for (x, m) in row.iter().enumerate() {
                    if m.depth >= 1.0 {
                        continue;
                    }
                    let c = Vec2::new(x as f32 + 0.5, y as f32 + 0.5) + m.v;
                    // Target centres j + 0.5 strictly inside (c - hs, c + hs).
                    let x0 = ((c.x - hs - 0.5).floor() + 1.0).max(0.0);
                    let x1 = ((c.x + hs - 0.5).ceil() - 1.0).min(w as f32 - 1.0);
                    let y0 = ((c.y - hs - 0.5).floor() + 1.0).max(0.0);
                    let y1 = ((c.y + hs - 0.5).ceil() - 1.0).min(h as f32 - 1.0);
                    if x0 > x1 || y0 > y1 {
                        continue;
                    }
                    for ty in y0 as usize..=y1 as usize {
                        for tx in x0 as usize..=x1 as usize {
                            depth_test(&buf, ty * w as usize + tx, m.depth);
                        }
                    }
                }
            });
        }
        finish(w, h, buf)
    }

    /// Multi-layer VFW (see [`vfw`]). Corner motion: the mean motion of the (up to four) pixels
    /// sharing the corner that are valid and move within [`CONTINUITY_PX`] of the quad's own pixel,
    /// so quads stitch on smooth surfaces but do not stretch across depth edges into disocclusions.
    /// Each quad carries its pixel's target depth (flat), so zero motion reproduces the source.
    pub(super) fn vfw_layers(layers: &[WarpLayer<'_>]) -> Result<Image<f32>> {
        let (w, h, layers) = check_layers(layers)?;
        let buf = new_target(w as usize * h as usize);
        for samples in &layers {
            let at = |x: i64, y: i64| -> Option<&Motion> {
                if x < 0 || y < 0 || x >= w as i64 || y >= h as i64 {
                    return None;
                }
                let m = &samples[y as usize * w as usize + x as usize];
                (m.depth < 1.0).then_some(m)
            };
            samples.par_chunks(w as usize).enumerate().for_each(|(y, row)| {
                for (x, m) in row.iter().enumerate() {
                    if m.depth >= 1.0 {
                        continue;
                    }
                    let q = vfw_quad(&at, x as i64, y as i64, m.v);
                    raster_triangle(&buf, w, h, [q[0], q[1], q[2]], m.depth);
                    raster_triangle(&buf, w, h, [q[0], q[2], q[3]], m.depth);
                }
            });
        }
        finish(w, h, buf)
    }

    #[inline]
    fn edge(a: Vec2, b: Vec2, p: Vec2) -> f32 {
        (b - a).perp_dot(p - a)
    }

    /// Rasterizes triangle `t = [a, b, c]` where edge `c -> a` is the quad diagonal: pixel centres
    /// strictly inside the outer edges `a -> b`, `b -> c` and on or inside the diagonal (so the two
    /// halves of a quad leave no gap; a centre on the diagonal may be written twice, which the
    /// atomic min makes harmless).
    fn raster_triangle(buf: &[AtomicU32], w: u32, h: u32, t: [Vec2; 3], z: f32) {
        let area = edge(t[0], t[1], t[2]);
        if area == 0.0 || !area.is_finite() {
            return;
        }
        let s = area.signum();
        let lo = t[0].min(t[1]).min(t[2]);
        let hi = t[0].max(t[1]).max(t[2]);
        let x0 = ((lo.x - 0.5).floor() + 1.0).max(0.0);
        let x1 = ((hi.x - 0.5).ceil() - 1.0).min(w as f32 - 1.0);
        let y0 = ((lo.y - 0.5).floor() + 1.0).max(0.0);
        let y1 = ((hi.y - 0.5).ceil() - 1.0).min(h as f32 - 1.0);
        if x0 > x1 || y0 > y1 {
            return;
        }
        for ty in y0 as u32..=y1 as u32 {
            for tx in x0 as u32..=x1 as u32 {
                let p = Vec2::new(tx as f32 + 0.5, ty as f32 + 0.5);
                if s * edge(t[0], t[1], p) > 0.0 && s * edge(t[1], t[2], p) > 0.0 && s * edge(t[2], t[0], p) >= 0.0 {
                    depth_test(buf, ty as usize * w as usize + tx as usize, z);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(w: u32, h: u32) -> Image<f32> {
        Image::from_fn(w, h, |x, y| if (x + y) % 7 == 0 { 1.0 } else { 0.5 + 0.01 * x as f32 + 0.003 * y as f32 })
    }

    fn motion_of(depth: &Image<f32>, v: Vec2) -> Image<Motion> {
        depth.map(|&d| Motion { v, depth: d })
    }

    #[test]
    fn zero_motion_reproduces_the_source() {
        let d = ramp(13, 9);
        let m = motion_of(&d, Vec2::ZERO);
        assert_eq!(vfw(&d, &m).unwrap(), d);
        assert_eq!(afw(&d, &m).unwrap(), d);
    }

    #[test]
    fn integer_shift_moves_the_image_and_leaves_the_band_far() {
        let d = Image::from_fn(12, 8, |x, y| 0.2 + 0.05 * x as f32 + 0.01 * y as f32);
        let m = motion_of(&d, Vec2::new(3.0, 1.0));
        for out in [vfw(&d, &m).unwrap(), afw(&d, &m).unwrap()] {
            for y in 0..8 {
                for x in 0..12 {
                    let want = if x >= 3 && y >= 1 { *d.get(x - 3, y - 1) } else { 1.0 };
                    assert_eq!(*out.get(x, y), want, "({x},{y})");
                }
            }
        }
    }

    #[test]
    fn expansion_closes_cracks_of_a_stretching_surface_and_depth_test_keeps_nearest() {
        // Motion v = 0.4 x: neighbours move 1.4 px apart. Without expansion AFW would leave
        // every other pixel empty; with it the interior is covered.
        let d = Image::new(20, 4, 0.5f32);
        let m = Image::from_fn(20, 4, |x, _| Motion { v: Vec2::new(0.4 * (x as f32 + 0.5), 0.0), depth: 0.5 });
        for out in [vfw(&d, &m).unwrap(), afw(&d, &m).unwrap()] {
            for x in 0..20 {
                assert_eq!(*out.get(x, 1), 0.5, "x={x}");
            }
        }
        // Two layers overlapping: nearest wins.
        let near = Image::new(4, 4, 0.3f32);
        let far = Image::new(4, 4, 0.7f32);
        let mn = motion_of(&near, Vec2::ZERO);
        let mf = motion_of(&far, Vec2::ZERO);
        let l = [WarpLayer { depth: &far, motion: &mf }, WarpLayer { depth: &near, motion: &mn }];
        assert!(vfw_layers(&l).unwrap().data().iter().all(|&z| z == 0.3));
        assert!(afw_layers(&l).unwrap().data().iter().all(|&z| z == 0.3));
    }

    /// The band-partitioned warps equal the atomics-based reference bit for bit: random smooth
    /// and discontinuous fields, empty and invalid samples, motion larger than a band, several
    /// layers, odd sizes; and gently varying fields (sub-pixel motion gradients), where AFW's
    /// AVX2 build splats eight consecutive footprints at once.
    #[test]
    fn band_partitioned_warps_equal_the_atomic_reference() {
        let cases = [(37u32, 23u32, 1u32, 0.3f32), (64, 97, 2, 0.3), (5, 3, 3, 0.3), (120, 70, 4, 0.3)];
        let gentle = [(37, 23, 5, 0.01), (131, 75, 6, 0.004), (64, 40, 7, 0.0)];
        for (w, h, seed, grad) in cases.into_iter().chain(gentle) {
            let hash = |i: u32| crate::search::hash_u32(i ^ seed.wrapping_mul(0x9e37_79b9));
            let layer = |k: u32| {
                let d = Image::from_fn(w, h, |x, y| {
                    if hash(x * 7 + y * 131 + k) % 9 == 0 {
                        1.0
                    } else {
                        0.2 + 0.001 * ((x + 3 * y + k) % 500) as f32
                    }
                });
                let m = Image::from_fn(w, h, |x, y| {
                    let t = hash(x + 1000 * y + 77 * k);
                    let jump = if grad > 0.1 && (x / 9 + k).is_multiple_of(3) { 7.0 } else { 0.0 };
                    let noise = if grad > 0.1 { 0.004 } else { 0.0 };
                    let v = Vec2::new(
                        grad * x as f32 - 4.3 + jump + (t % 100) as f32 * noise,
                        -grad * y as f32 + 40.0 * (k as f32 - 0.5) + 0.37 + ((t >> 8) % 100) as f32 * noise,
                    );
                    let depth = if t % 23 == 0 { 1.5 } else { *d.get(x, y) * 0.9 };
                    Motion { v, depth }
                });
                (d, m)
            };
            let (a, b) = (layer(0), layer(1));
            let layers = [WarpLayer { depth: &a.0, motion: &a.1 }, WarpLayer { depth: &b.0, motion: &b.1 }];
            let bits = |i: &Image<f32>| i.data().iter().map(|z| z.to_bits()).collect::<Vec<_>>();
            for l in [1, 2] {
                assert_eq!(
                    bits(&afw_layers(&layers[..l]).unwrap()),
                    bits(&reference::afw_layers(&layers[..l]).unwrap())
                );
                assert_eq!(
                    bits(&vfw_layers(&layers[..l]).unwrap()),
                    bits(&reference::vfw_layers(&layers[..l]).unwrap())
                );
            }
        }
    }

    #[test]
    fn bad_input_is_an_error() {
        let d = Image::new(4, 4, 0.5f32);
        let m = Image::new(4, 3, Motion::default());
        assert!(matches!(vfw(&d, &m), Err(Error::Invalid(_))));
        assert!(matches!(afw_layers(&[]), Err(Error::Invalid(_))));
        let mut m = Image::new(4, 4, Motion::default());
        m.get_mut(0, 0).v.y = f32::NAN;
        assert!(matches!(afw(&d, &m), Err(Error::Invalid(_))));
        // Past the first eight columns (the AVX2 row check's vectors).
        let d16 = Image::new(19, 3, 0.5f32);
        let mut m16 = Image::new(19, 3, Motion::default());
        m16.get_mut(11, 1).depth = f32::NAN;
        assert!(matches!(vfw(&d16, &m16), Err(Error::Invalid(_))));
        let mut d16 = d16;
        *d16.get_mut(9, 2) = f32::INFINITY;
        assert!(matches!(afw(&d16, &Image::new(19, 3, Motion::default())), Err(Error::Invalid(_))));
        let z: Image<f32> = Image::new(0, 0, 0.5);
        let mz: Image<Motion> = Image::new(0, 0, Motion::default());
        assert!(matches!(vfw(&z, &mz), Err(Error::Invalid(_))));
    }

    /// The AVX2 VFW's row cache holds a row of one layer: the same row of another layer read
    /// right after is converted anew (a cache keyed by the row alone would splat layer 0 again).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn the_row_cache_tells_layers_apart() {
        if !crate::simd::has_avx2() {
            return;
        }
        let (w, h) = (27, 5);
        let d0 = ramp(w, h);
        let d1 = Image::from_fn(w, h, |x, y| 0.2 + 0.02 * ((x * 3 + y) % 5) as f32);
        let (m0, m1) = (motion_of(&d0, Vec2::new(0.6, 0.3)), motion_of(&d1, Vec2::new(-1.3, 0.4)));
        let layers = [WarpLayer { depth: &d0, motion: &m0 }, WarpLayer { depth: &d1, motion: &m1 }];
        let fresh = || vec![EMPTY_DEPTH; (w * h) as usize];
        let (mut shared, mut a, mut b, mut c) = (RowCache::default(), fresh(), fresh(), fresh());
        // SAFETY: AVX2 is reported by the CPU.
        unsafe {
            avx2::vfw_row(&layers[0], 0, w, h, &mut a, 0, 2, &mut shared);
            avx2::vfw_row(&layers[1], 1, w, h, &mut b, 0, 2, &mut shared);
        }
        vfw_row(&layers[1], w, h, &mut c, 0, 2);
        assert_eq!(b, c);
        assert_ne!(a, c);
    }
}
