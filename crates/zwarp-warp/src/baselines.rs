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
use crate::search::CONTINUITY_PX;

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
                let mut flags = 0u8;
                let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
                for (&d, m) in d.iter().zip(m) {
                    flags |= (!d.is_finite()) as u8 | ((m.v.x.is_nan() | m.v.y.is_nan() | m.depth.is_nan()) as u8) << 1;
                    if valid(d, m) {
                        lo = lo.min(m.v.y);
                        hi = hi.max(m.v.y);
                    }
                }
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

/// Target rows per band of the forward warps: each band is written by one task, which splats
/// every source sample whose footprint reaches the band (clipped to it), so no two tasks write
/// the same pixel and no atomics are needed (the depth test is a min: order does not matter).
const BAND: usize = 32;

/// Runs `splat(band_rows, y0, layer, source_row)` for every band of `BAND` target rows and every
/// source row of every layer whose target rows (widened by `margin`) reach it, in parallel over
/// bands; returns the `w x h` target.
fn forward(
    w: u32,
    h: u32,
    reach: &[RowReach],
    margin: f32,
    splat: impl Fn(&mut [f32], usize, usize, usize) + Sync,
) -> Result<Image<f32>> {
    let mut target = crate::pages::filled(w as usize * h as usize, EMPTY_DEPTH);
    target.par_chunks_mut(BAND * w as usize).enumerate().for_each(|(b, band)| {
        let y0 = b * BAND;
        let y1 = y0 + band.len() / w as usize;
        let (lo, hi) = (y0 as f32 - margin, y1 as f32 + margin);
        for (k, r) in reach.iter().enumerate() {
            for (y, range) in r.rows.iter().enumerate() {
                if let Some((a, c)) = range {
                    if *c >= lo && *a <= hi {
                        splat(band, y0, k, y);
                    }
                }
            }
        }
    });
    Image::from_vec(w, h, target)
}

/// Multi-layer AFW (see [`afw`]).
pub fn afw_layers(layers: &[WarpLayer<'_>]) -> Result<Image<f32>> {
    let (w, h, reach) = check_layers(layers)?;
    let hs = 0.5 + FORWARD_SUPPORT_EXPANSION;
    forward(w, h, &reach, hs + 1.0, |band, y0, k, y| {
        #[cfg(target_arch = "x86_64")]
        if crate::simd::has_avx2() {
            // SAFETY: only taken when the CPU reports AVX2.
            unsafe { afw_row_avx2(&layers[k], w, h, band, y0, y, hs) };
            return;
        }
        afw_row(&layers[k], w, h, band, y0, y, hs)
    })
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn afw_row_avx2(l: &WarpLayer<'_>, w: u32, h: u32, band: &mut [f32], y0: usize, y: usize, hs: f32) {
    afw_row(l, w, h, band, y0, y, hs)
}

/// The AFW splats of source row `y` into the band of target rows starting at `y0`.
#[inline(always)]
fn afw_row(l: &WarpLayer<'_>, w: u32, h: u32, band: &mut [f32], y0: usize, y: usize, hs: f32) {
    let wu = w as usize;
    let rows = band.len() / wu;
    let (by0, by1) = (y0 as f32, (y0 + rows) as f32 - 1.0);
    let (depth, motion) = (&l.depth.data()[y * wu..(y + 1) * wu], &l.motion.data()[y * wu..(y + 1) * wu]);
    for (x, (&d, m)) in depth.iter().zip(motion).enumerate() {
        if !valid(d, m) {
            continue;
        }
        let c = Vec2::new(x as f32 + 0.5, y as f32 + 0.5) + m.v;
        // Target centres j + 0.5 strictly inside (c - hs, c + hs).
        let x0 = ((c.x - hs - 0.5).floor() + 1.0).max(0.0);
        let x1 = ((c.x + hs - 0.5).ceil() - 1.0).min(w as f32 - 1.0);
        let ty0 = ((c.y - hs - 0.5).floor() + 1.0).max(0.0).max(by0);
        let ty1 = ((c.y + hs - 0.5).ceil() - 1.0).min(h as f32 - 1.0).min(by1);
        if x0 > x1 || ty0 > ty1 {
            continue;
        }
        // `+ 0.0` turns -0.0 into +0.0 (the depth order of the bit patterns the atomic
        // versions compare).
        let z = m.depth + 0.0;
        for ty in ty0 as usize..=ty1 as usize {
            let row = &mut band[(ty - y0) * wu..(ty - y0 + 1) * wu];
            for t in &mut row[x0 as usize..=x1 as usize] {
                *t = t.min(z);
            }
        }
    }
}

/// Multi-layer VFW (see [`vfw`]). Corner motion: the mean motion of the (up to four) pixels
/// sharing the corner that are valid and move within [`CONTINUITY_PX`] of the quad's own pixel,
/// so quads stitch on smooth surfaces but do not stretch across depth edges into disocclusions.
/// Each quad carries its pixel's target depth (flat), so zero motion reproduces the source.
pub fn vfw_layers(layers: &[WarpLayer<'_>]) -> Result<Image<f32>> {
    let (w, h, reach) = check_layers(layers)?;
    // A corner moves within CONTINUITY_PX of its quad's pixel; corners lie one pixel apart,
    // pushed out by the expansion.
    forward(w, h, &reach, VFW_ROW_REACH, |band, y0, k, y| {
        #[cfg(target_arch = "x86_64")]
        if crate::simd::has_avx2() {
            // SAFETY: only taken when the CPU reports AVX2.
            unsafe { vfw_row_avx2(&layers[k], w, h, band, y0, y) };
            return;
        }
        vfw_row(&layers[k], w, h, band, y0, y)
    })
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn vfw_row_avx2(l: &WarpLayer<'_>, w: u32, h: u32, band: &mut [f32], y0: usize, y: usize) {
    vfw_row(l, w, h, band, y0, y)
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

/// The VFW quads of source row `y` into the band of target rows starting at `y0`.
#[inline(always)]
fn vfw_row(l: &WarpLayer<'_>, w: u32, h: u32, band: &mut [f32], y0: usize, y: usize) {
    let (depth, motion) = (l.depth.data(), l.motion.data());
    let at = |x: i64, y: i64| -> Option<&Motion> {
        if x < 0 || y < 0 || x >= w as i64 || y >= h as i64 {
            return None;
        }
        let i = y as usize * w as usize + x as usize;
        let m = &motion[i];
        valid(depth[i], m).then_some(m)
    };
    let rows = band.len() / w as usize;
    let clip = (y0 as f32, (y0 + rows) as f32 - 1.0);
    let cy = y as f32 + 0.5;
    for x in 0..w as usize {
        let Some(m) = at(x as i64, y as i64) else { continue };
        // The quad's corners lie within 2 px of the pixel's moved centre (corner motion within
        // CONTINUITY_PX of its own, half a pixel of expansion), so its rows lie within 2.5 px:
        // quads that cannot reach the band are skipped before their corners are averaged.
        let c = cy + m.v.y;
        if c + VFW_ROW_REACH < clip.0 || c - VFW_ROW_REACH > clip.1 {
            continue;
        }
        let q = vfw_quad(&at, x as i64, y as i64, m.v);
        raster_triangle(band, y0, w, h, clip, [q[0], q[1], q[2]], m.depth);
        raster_triangle(band, y0, w, h, clip, [q[0], q[2], q[3]], m.depth);
    }
}

/// A bound of the target rows a VFW quad covers around its pixel's moved centre (2.5 px, with
/// room for rounding).
const VFW_ROW_REACH: f32 = 1.0 + CONTINUITY_PX + FORWARD_SUPPORT_EXPANSION + 1.0;

#[inline]
fn edge(a: Vec2, b: Vec2, p: Vec2) -> f32 {
    (b - a).perp_dot(p - a)
}

/// Rasterizes triangle `t = [a, b, c]` where edge `c -> a` is the quad diagonal: pixel centres
/// strictly inside the outer edges `a -> b`, `b -> c` and on or inside the diagonal (so the two
/// halves of a quad leave no gap; a centre on the diagonal may be written twice, which the
/// min makes harmless), for target rows within `clip` (the band starting at row `y0`).
#[inline(always)]
fn raster_triangle(band: &mut [f32], y0: usize, w: u32, h: u32, clip: (f32, f32), t: [Vec2; 3], z: f32) {
    let area = edge(t[0], t[1], t[2]);
    if area == 0.0 || !area.is_finite() {
        return;
    }
    let s = area.signum();
    let lo = t[0].min(t[1]).min(t[2]);
    let hi = t[0].max(t[1]).max(t[2]);
    let x0 = ((lo.x - 0.5).floor() + 1.0).max(0.0);
    let x1 = ((hi.x - 0.5).ceil() - 1.0).min(w as f32 - 1.0);
    let ty0 = ((lo.y - 0.5).floor() + 1.0).max(0.0).max(clip.0);
    let ty1 = ((hi.y - 0.5).ceil() - 1.0).min(h as f32 - 1.0).min(clip.1);
    if x0 > x1 || ty0 > ty1 {
        return;
    }
    let z = z + 0.0;
    for ty in ty0 as u32..=ty1 as u32 {
        for tx in x0 as u32..=x1 as u32 {
            let p = Vec2::new(tx as f32 + 0.5, ty as f32 + 0.5);
            if s * edge(t[0], t[1], p) > 0.0 && s * edge(t[1], t[2], p) > 0.0 && s * edge(t[2], t[0], p) >= 0.0 {
                let i = (ty as usize - y0) * w as usize + tx as usize;
                band[i] = band[i].min(z);
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
    /// layers, odd sizes.
    #[test]
    fn band_partitioned_warps_equal_the_atomic_reference() {
        for (w, h, seed) in [(37u32, 23u32, 1u32), (64, 97, 2), (5, 3, 3), (120, 70, 4)] {
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
                    let jump = if (x / 9 + k).is_multiple_of(3) { 7.0 } else { 0.0 };
                    let v = Vec2::new(
                        0.3 * x as f32 - 4.0 + jump + (t % 100) as f32 * 0.004,
                        -0.2 * y as f32 + 40.0 * (k as f32 - 0.5) + ((t >> 8) % 100) as f32 * 0.004,
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
        let z: Image<f32> = Image::new(0, 0, 0.5);
        let mz: Image<Motion> = Image::new(0, 0, Motion::default());
        assert!(matches!(vfw(&z, &mz), Err(Error::Invalid(_))));
    }
}
