//! The streaming floor of a depth prediction: the least memory traffic any backward warp of L
//! layers needs, timed as a pass that does exactly that and nothing else (ARCHITECTURE.md "The
//! floor is the yardstick"). It reads every source sample of every layer once — its f32 depth
//! and its [`Motion`] (motion and target depth), as a caller hands them — and writes one f32 per
//! target pixel, in parallel over rows with all threads. A warp's `floor_ratio` is its time over
//! this pass's time in the same run.
//!
//! The pass keeps every value it reads alive (the minimum of the candidate depths, with the
//! motion folded in), so the compiler cannot drop a load; an AVX2 build is chosen at run time
//! where the CPU has it, so the floor is the memory's speed, not the loop's.

use rayon::prelude::*;
use zwarp_core::{Error, Motion, Result};

use crate::WarpLayer;

/// One floor pass over `layers` (equal sizes `m w x m h`) into `out` (`w x h`, `w` given):
/// target pixel `(x, y)` reads the `m x m` source samples of its footprint in every layer.
pub fn floor_pass(layers: &[WarpLayer<'_>], m: u32, w: u32, out: &mut [f32]) -> Result<()> {
    let first = layers.first().ok_or_else(|| Error::invalid("the floor pass needs at least one layer"))?;
    let (sw, sh) = first.depth.size();
    if m == 0 || w == 0 || sw != w * m || out.len() as u64 * (m as u64 * m as u64) != sw as u64 * sh as u64 {
        return Err(Error::invalid(format!(
            "floor pass: {}x{} sources do not hold {m}x{m} samples per pixel of a {w}-wide output",
            sw, sh
        )));
    }
    if layers.iter().any(|l| l.depth.size() != (sw, sh) || l.motion.size() != (sw, sh)) {
        return Err(Error::invalid("floor pass: the layers differ in size"));
    }
    let depths: Vec<&[f32]> = layers.iter().map(|l| l.depth.data()).collect();
    let motions: Vec<&[Motion]> = layers.iter().map(|l| l.motion.data()).collect();
    let (wu, mu, swu) = (w as usize, m as usize, sw as usize);
    out.par_chunks_mut(wu * 8).enumerate().for_each(|(c, rows)| {
        #[cfg(target_arch = "x86_64")]
        if crate::simd::has_avx2() {
            // SAFETY: only taken when the CPU reports AVX2.
            unsafe { rows_simd(&depths, &motions, c * 8, wu, mu, swu, rows) };
            return;
        }
        rows_impl(&depths, &motions, c * 8, wu, mu, swu, rows);
    });
    Ok(())
}

#[cfg(target_arch = "x86_64")]
zwarp_core::avx2_or_avx512! {
    /// [`rows_impl`] vectorized for AVX2, or for AVX-512 where the CPU has it: the floor is the
    /// memory's speed, so it takes the widest build there is.
    unsafe fn rows_simd(d: &[&[f32]], mo: &[&[Motion]], y0: usize, w: usize, m: usize, sw: usize, rows: &mut [f32])
    where wide = crate::simd::has_avx512(); {
        rows_impl(d, mo, y0, w, m, sw, rows)
    }
}

#[inline(always)]
fn rows_impl(depths: &[&[f32]], motions: &[&[Motion]], y0: usize, w: usize, m: usize, sw: usize, rows: &mut [f32]) {
    for (r, row) in rows.chunks_mut(w).enumerate() {
        let y = y0 + r;
        row.fill(1.0);
        for (d, mo) in depths.iter().zip(motions) {
            for sy in y * m..(y + 1) * m {
                let (d, mo) = (&d[sy * sw..(sy + 1) * sw], &mo[sy * sw..(sy + 1) * sw]);
                if m == 1 {
                    for ((o, &d), mo) in row.iter_mut().zip(d).zip(mo) {
                        let cand = if d < 1.0 { mo.depth + 0.0 * (mo.v.x + mo.v.y) } else { 1.0 };
                        *o = o.min(cand);
                    }
                } else {
                    for (x, o) in row.iter_mut().enumerate() {
                        for sx in x * m..(x + 1) * m {
                            let (d, mo) = (d[sx], mo[sx]);
                            let cand = if d < 1.0 { mo.depth + 0.0 * (mo.v.x + mo.v.y) } else { 1.0 };
                            *o = o.min(cand);
                        }
                    }
                }
            }
        }
    }
}

/// The bytes one [`floor_pass`] over `layers` with `m x m` samples per output pixel moves: every
/// layer's f32 depth and [`Motion`] read once, one f32 per output pixel written. Over
/// [`floor_ms`] it is the streaming bandwidth the machine gave in that run, which is what a
/// `floor_ratio` is relative to.
pub fn floor_bytes(layers: &[WarpLayer<'_>], m: u32) -> u64 {
    let per_sample = (std::mem::size_of::<f32>() + std::mem::size_of::<Motion>()) as u64;
    let read: u64 = layers.iter().map(|l| l.depth.len() as u64 * per_sample).sum();
    let out = layers.first().map_or(0, |l| l.depth.len() as u64 / (m.max(1) as u64 * m.max(1) as u64));
    read + out * std::mem::size_of::<f32>() as u64
}

/// Timed passes a floor measurement takes at the least, whatever the caller's `reps`: a pass of
/// a few milliseconds on a shared 2-core machine settles only after thread wake-ups and clock
/// ramps, and the median of three scatters by up to 2x between runs (colour floor at 1280x720:
/// 0.99-2.23 ms over three passes, 0.69-0.80 ms over fifteen), which would flatter every
/// `floor_ratio`. Passes are cheap next to the warps they are the yardstick of.
pub const FLOOR_MIN_REPS: usize = 15;

/// The median and spread (min, max) of `reps` (at least [`FLOOR_MIN_REPS`]) timed floor passes
/// (ms) after one warm-up, into a buffer allocated once: the figure `zwarp eval` reports as
/// `floor_ms`.
pub fn floor_ms(layers: &[WarpLayer<'_>], m: u32, reps: usize) -> Result<(f64, f64, f64)> {
    let first = layers.first().ok_or_else(|| Error::invalid("the floor pass needs at least one layer"))?;
    let (sw, sh) = first.depth.size();
    let (w, h) = crate::target_size(sw, sh, m)?;
    let mut out = vec![0.0f32; w as usize * h as usize];
    floor_pass(layers, m, w, &mut out)?;
    let reps = reps.max(FLOOR_MIN_REPS);
    let mut t = Vec::with_capacity(reps);
    for _ in 0..reps {
        let t0 = std::time::Instant::now();
        floor_pass(layers, m, w, &mut out)?;
        t.push(t0.elapsed().as_secs_f64() * 1e3);
    }
    t.sort_by(f64::total_cmp);
    Ok((t[t.len() / 2], t[0], t[t.len() - 1]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec2;
    use zwarp_core::Image;

    #[test]
    fn the_floor_reads_every_sample_and_writes_the_nearest_candidate() {
        let d0 = Image::from_fn(6, 4, |x, _| if x == 2 { 1.0 } else { 0.5 });
        let m0 = Image::from_fn(6, 4, |x, y| Motion { v: Vec2::new(x as f32, 1.0), depth: 0.1 * (x + y) as f32 });
        let d1 = Image::new(6, 4, 0.5f32);
        let m1 = Image::new(6, 4, Motion { v: Vec2::ZERO, depth: 0.35 });
        let layers = [WarpLayer { depth: &d0, motion: &m0 }, WarpLayer { depth: &d1, motion: &m1 }];
        let mut out = vec![0.0; 24];
        floor_pass(&layers, 1, 6, &mut out).unwrap();
        for y in 0..4 {
            for x in 0..6 {
                let a = if x == 2 { 1.0 } else { 0.1 * (x + y) as f32 };
                assert_eq!(out[y * 6 + x], a.min(0.35));
            }
        }
        // 2x2 samples per pixel: the minimum over each footprint.
        let mut out = vec![0.0; 6];
        floor_pass(&layers[..1], 2, 3, &mut out).unwrap();
        assert_eq!(out[0], 0.0);
        assert!((out[1] - 0.3).abs() < 1e-6, "{}", out[1]);
        assert!(floor_pass(&layers, 2, 4, &mut out).is_err());
        assert!(floor_pass(&[], 1, 6, &mut out).is_err());
        assert!(floor_ms(&layers, 1, 2).unwrap().0 >= 0.0);
        // Two layers of 24 samples (4 + 12 bytes each) read, 24 (m = 1) or 6 (m = 2) f32 written.
        assert_eq!(floor_bytes(&layers, 1), 2 * 24 * 16 + 24 * 4);
        assert_eq!(floor_bytes(&layers, 2), 2 * 24 * 16 + 6 * 4);
    }
}
