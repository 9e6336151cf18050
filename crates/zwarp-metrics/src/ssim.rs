//! SSIM, the structural similarity index of Wang et al. 2004 (IEEE TIP 13(4)), which seed 000
//! reports beside PSNR for every warped depth buffer (Sec. 7, Fig. 10, Tables 1-2).
//!
//! The implementation reproduces scikit-image's
//! `structural_similarity(a, b, data_range=R, gaussian_weights=True, sigma=1.5,
//! use_sample_covariance=False)` exactly (checked against a committed skimage fixture):
//! - local statistics are weighted by a normalized Gaussian with `sigma = 1.5` truncated at
//!   `3.5 sigma`, i.e. radius `int(3.5 * 1.5 + 0.5) = 5` -> an 11x11 window, applied as two
//!   separable 1-D passes (scipy `gaussian_filter`);
//! - borders use scipy's `mode='reflect'` (half-sample symmetric: `d c b a | a b c d | d c b a`);
//! - population (not sample) covariance, `C1 = (0.01 R)^2`, `C2 = (0.03 R)^2`;
//! - the SSIM map is averaged after cropping `(11 - 1) / 2 = 5` pixels from every side, so images
//!   must be at least 11x11.
//!
//! Everything is computed in f64 from the f32 inputs: stored perspective depth crowds near 1
//! (ARCHITECTURE.md "Conventions"), where `E[x^2] - E[x]^2` in f32 would lose most of its digits.

use rayon::prelude::*;
use zwarp_core::{Error, Image, Result};

use crate::{check_pair, check_range, split_rgb};

/// Gaussian standard deviation of the SSIM window (Wang et al. 2004).
pub const SSIM_SIGMA: f64 = 1.5;
/// Gaussian truncation in standard deviations (scikit-image's choice for an 11-tap window).
pub const SSIM_TRUNCATE: f64 = 3.5;
/// Window radius: `int(SSIM_TRUNCATE * SSIM_SIGMA + 0.5)` as scipy computes it.
pub const SSIM_RADIUS: usize = 5;
/// Window side, `2 * SSIM_RADIUS + 1 = 11`; also the smallest accepted image side.
pub const SSIM_WIN_SIZE: usize = 2 * SSIM_RADIUS + 1;
/// Luminance stabilizer constant: `C1 = (K1 * data_range)^2`.
pub const SSIM_K1: f64 = 0.01;
/// Contrast/structure stabilizer constant: `C2 = (K2 * data_range)^2`.
pub const SSIM_K2: f64 = 0.03;

/// Output rows per parallel band. Fixed (not derived from the thread count) so the f64 sum of
/// the SSIM map is bit-identical on every machine; rows are independent (no halo to
/// recompute), so the band only sets the scheduling grain.
const BAND: usize = 32;

/// scipy `_gaussian_kernel1d(sigma, 0, radius)`: `exp(-x^2 / (2 sigma^2))`, normalized to sum 1.
fn gaussian_taps() -> [f64; SSIM_WIN_SIZE] {
    let mut w = [0.0; SSIM_WIN_SIZE];
    let s2 = SSIM_SIGMA * SSIM_SIGMA;
    for (i, t) in w.iter_mut().enumerate() {
        let x = i as f64 - SSIM_RADIUS as f64;
        *t = (-0.5 / s2 * x * x).exp();
    }
    let sum: f64 = w.iter().sum();
    w.iter_mut().for_each(|t| *t /= sum);
    w
}

/// scipy `mode='reflect'` index: half-sample symmetric extension, periodic with period `2n`
/// (so it is also right for offsets larger than the image).
#[inline]
fn reflect(i: isize, n: usize) -> usize {
    let n = n as isize;
    let m = i.rem_euclid(2 * n);
    (if m >= n { 2 * n - 1 - m } else { m }) as usize
}

/// `out[x] = sum_t taps[t] * src[x + t]` for a symmetric 11-tap kernel, written as whole-row
/// passes (`out += w * (src[x + t] + src[x + 10 - t])`) so the compiler vectorizes across `x`.
/// `src` holds `out.len() + 10` samples (the reflected halo included).
#[inline(always)]
fn filter_taps<'a>(taps: &[f64; SSIM_WIN_SIZE], out: &mut [f64], src: impl Fn(usize) -> &'a [f64]) {
    let n = out.len();
    let r = SSIM_RADIUS;
    for (o, &c) in out.iter_mut().zip(&src(r)[..n]) {
        *o = taps[r] * c;
    }
    for (t, &wt) in taps.iter().enumerate().take(r) {
        let (lo, hi) = (&src(t)[..n], &src(2 * r - t)[..n]);
        for ((o, &l), &h) in out.iter_mut().zip(lo).zip(hi) {
            *o += wt * (l + h);
        }
    }
}

thread_local! {
    /// Per-thread scratch reused across calls: SSIM runs on every evaluated frame, and fresh
    /// allocations per band cost page faults (measured: a per-band 5.7 MB buffer made 1080p
    /// SSIM 2.5x slower before scratch reuse).
    static SCRATCH: std::cell::RefCell<Vec<f64>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Computes SSIM map rows `y0..y1` of the `w x h` images `a`, `b` and hands each row to
/// `sink(y, row)`: the separable form of scipy's 2-D Gaussian filter applied to
/// `a, b, a^2, b^2, ab` (scipy filters columns first; the order only changes the last bits).
/// Horizontally filtered rows live in a ring of 11 rows, so the working set stays in cache.
#[allow(clippy::too_many_arguments)]
fn ssim_band(
    a: &[f32],
    b: &[f32],
    w: usize,
    h: usize,
    y0: usize,
    y1: usize,
    c: (f64, f64),
    sink: impl FnMut(usize, &[f64]),
) {
    // The default x86-64 target only guarantees SSE2 (2 f64 lanes); the same code compiled for
    // AVX2 (4 lanes) is selected at run time. Both compute identical values (no FMA contraction).
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2, detected just above.
        return unsafe { ssim_band_avx2(a, b, w, h, y0, y1, c, sink) };
    }
    ssim_band_generic(a, b, w, h, y0, y1, c, sink)
}

/// [`ssim_band_generic`] compiled with AVX2 enabled.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
fn ssim_band_avx2(
    a: &[f32],
    b: &[f32],
    w: usize,
    h: usize,
    y0: usize,
    y1: usize,
    c: (f64, f64),
    sink: impl FnMut(usize, &[f64]),
) {
    ssim_band_generic(a, b, w, h, y0, y1, c, sink)
}

/// The same source row of `a` and `b`.
type RowPair<'a> = (&'a [f32], &'a [f32]);

/// The band kernel behind [`ssim_band`], inlined into each instruction-set variant.
///
/// Vertical pass first (as scipy does): each output row reads its 11 reflected source rows
/// directly (f32, cache-resident) and forms `a, b, a^2, b^2, ab` on the fly, so no filtered
/// rows are stored between rows and bands need no recomputed halo. Then the horizontal pass on
/// the 5 column-reflected planes of that one row, then the SSIM formula.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn ssim_band_generic(
    a: &[f32],
    b: &[f32],
    w: usize,
    h: usize,
    y0: usize,
    y1: usize,
    c: (f64, f64),
    mut sink: impl FnMut(usize, &[f64]),
) {
    const WIN: usize = SSIM_WIN_SIZE;
    let taps = gaussian_taps();
    let r = SSIM_RADIUS;
    let pw = w + 2 * r;
    let mut scratch = SCRATCH.with(|s| std::mem::take(&mut *s.borrow_mut()));
    // Layout: 5 vertically filtered planes with reflected column halo (pw each), 5 fully
    // filtered planes (w each), 1 output row.
    let need = 5 * pw + 5 * w + w;
    if scratch.len() < need {
        scratch.resize(need, 0.0);
    }
    {
        let (vp, rest) = scratch.split_at_mut(5 * pw);
        let (hp, rest) = rest.split_at_mut(5 * w);
        let srow = &mut rest[..w];
        let (c1, c2) = c;
        for y in y0..y1 {
            // Symmetric row pairs (y - k, y + k) share a weight: 5 pairs + the centre row.
            let row = |t: usize| {
                let s = reflect(y as isize + t as isize - r as isize, h) * w;
                (&a[s..s + w], &b[s..s + w])
            };
            let (ca, cb) = row(r);
            let pairs: [(RowPair, RowPair); SSIM_RADIUS] = std::array::from_fn(|t| (row(t), row(WIN - 1 - t)));
            let (v0, rest) = vp.split_at_mut(pw);
            let (v1, rest) = rest.split_at_mut(pw);
            let (v2, rest) = rest.split_at_mut(pw);
            let (v3, v4) = rest.split_at_mut(pw);
            let (v0, v1, v2, v3, v4) =
                (&mut v0[r..r + w], &mut v1[r..r + w], &mut v2[r..r + w], &mut v3[r..r + w], &mut v4[r..r + w]);
            let wc = taps[r];
            for x in 0..w {
                let (va, vb) = (ca[x] as f64, cb[x] as f64);
                v0[x] = wc * va;
                v1[x] = wc * vb;
                v2[x] = wc * (va * va);
                v3[x] = wc * (vb * vb);
                v4[x] = wc * (va * vb);
            }
            for (t, ((la, lb), (ha, hb))) in pairs.iter().enumerate() {
                let wt = taps[t];
                let (la, lb, ha, hb) = (&la[..w], &lb[..w], &ha[..w], &hb[..w]);
                for x in 0..w {
                    let (pa, pb, qa, qb) = (la[x] as f64, lb[x] as f64, ha[x] as f64, hb[x] as f64);
                    v0[x] += wt * (pa + qa);
                    v1[x] += wt * (pb + qb);
                    v2[x] += wt * (pa * pa + qa * qa);
                    v3[x] += wt * (pb * pb + qb * qb);
                    v4[x] += wt * (pa * pb + qa * qb);
                }
            }
            // Column halo: reflecting the columns commutes with the vertical filter.
            for q in 0..5 {
                let plane = &mut vp[q * pw..(q + 1) * pw];
                for k in (0..r).chain(r + w..pw) {
                    plane[k] = plane[r + reflect(k as isize - r as isize, w)];
                }
                let p = &vp[q * pw..(q + 1) * pw];
                filter_taps(&taps, &mut hp[q * w..(q + 1) * w], |t| &p[t..]);
            }
            let (ma, rest) = hp.split_at(w);
            let (mb, rest) = rest.split_at(w);
            let (maa, rest) = rest.split_at(w);
            let (mbb, mab) = rest.split_at(w);
            for (i, o) in srow.iter_mut().enumerate() {
                let (ux, uy) = (ma[i], mb[i]);
                // Population covariance (use_sample_covariance=False), as in Wang et al. 2004.
                let vx = maa[i] - ux * ux;
                let vy = mbb[i] - uy * uy;
                let vxy = mab[i] - ux * uy;
                let a1 = 2.0 * ux * uy + c1;
                let a2 = 2.0 * vxy + c2;
                let b1 = ux * ux + uy * uy + c1;
                let b2 = vx + vy + c2;
                *o = (a1 * a2) / (b1 * b2);
            }
            sink(y, srow);
        }
    }
    SCRATCH.with(|s| *s.borrow_mut() = scratch);
}

/// Validates an SSIM input pair and returns `(w, h, (C1, C2))`.
pub(crate) fn prepare(
    a: &Image<f32>,
    b: &Image<f32>,
    data_range: f32,
    what: &str,
) -> Result<(usize, usize, (f64, f64))> {
    check_range(data_range, what)?;
    check_pair(a, b, what)?;
    let (w, h) = (a.width() as usize, a.height() as usize);
    if w < SSIM_WIN_SIZE || h < SSIM_WIN_SIZE {
        return Err(Error::invalid(format!(
            "{what}: image {w}x{h} is smaller than the {SSIM_WIN_SIZE}x{SSIM_WIN_SIZE} Gaussian window"
        )));
    }
    let r = data_range as f64;
    Ok((w, h, ((SSIM_K1 * r).powi(2), (SSIM_K2 * r).powi(2))))
}

/// Mean SSIM (Wang et al. 2004) of two single-channel images, as seed 000 Sec. 7 reports it
/// and exactly as scikit-image's `structural_similarity(a, b, data_range=data_range,
/// gaussian_weights=True, sigma=1.5, use_sample_covariance=False)` computes it (see the module
/// docs): 11x11 Gaussian window (sigma 1.5), reflect borders, mean over the map with a
/// 5-pixel border strip cropped.
///
/// In `[-1, 1]`, exactly `1.0` for identical images and exactly symmetric in `a`, `b`.
/// Errors on size mismatch, images smaller than 11x11, non-finite values or a non-positive
/// `data_range`. Parallel over row bands (rayon); the result does not depend on the thread count.
pub fn ssim(a: &Image<f32>, b: &Image<f32>, data_range: f32) -> Result<f64> {
    let (w, h, c) = prepare(a, b, data_range, "ssim")?;
    Ok(ssim_validated(a.data(), b.data(), w, h, c))
}

/// [`ssim`] on inputs already validated by [`prepare`] (callers computing several metrics on
/// the same buffers validate once).
pub(crate) fn ssim_validated(a: &[f32], b: &[f32], w: usize, h: usize, c: (f64, f64)) -> f64 {
    let r = SSIM_RADIUS;
    // Only the rows that survive the crop are computed.
    let (lo, hi) = (r, h - r);
    let bands: Vec<(usize, usize)> = (lo..hi).step_by(BAND).map(|y| (y, (y + BAND).min(hi))).collect();
    let sums: Vec<f64> = bands
        .par_iter()
        .map(|&(y0, y1)| {
            let mut s = 0.0;
            ssim_band(a, b, w, h, y0, y1, c, |_, row| s += row[r..w - r].iter().sum::<f64>());
            s
        })
        .collect();
    let n = ((w - 2 * r) * (h - 2 * r)) as f64;
    sums.iter().sum::<f64>() / n
}

/// The full-size local SSIM map (Wang et al. 2004; scikit-image's `full=True` output) for heat
/// maps: one value per pixel, border pixels included (computed with reflected windows). The
/// [`ssim`] score is the mean of this map without its 5-pixel border strip.
///
/// Same validation as [`ssim`].
pub fn ssim_map(a: &Image<f32>, b: &Image<f32>, data_range: f32) -> Result<Image<f32>> {
    let (w, h, c) = prepare(a, b, data_range, "ssim_map")?;
    let mut out = Image::new(w as u32, h as u32, 0.0f32);
    out.data_mut().par_chunks_mut(BAND * w).enumerate().for_each(|(bi, chunk)| {
        let y0 = bi * BAND;
        let y1 = y0 + chunk.len() / w;
        ssim_band(a.data(), b.data(), w, h, y0, y1, c, |y, row| {
            let dst = &mut chunk[(y - y0) * w..(y - y0 + 1) * w];
            dst.iter_mut().zip(row).for_each(|(d, &s)| *d = s as f32);
        });
    });
    Ok(out)
}

/// Colour SSIM: the mean of the three per-channel [`ssim`] scores, as scikit-image's
/// `structural_similarity(..., channel_axis=-1)` (used for seed 001's colour warps and the
/// colour renderings compared in seed 000 Table 7).
pub fn ssim_rgb(a: &Image<[f32; 3]>, b: &Image<[f32; 3]>, data_range: f32) -> Result<f64> {
    a.check_same_size(b, "ssim_rgb")?;
    let (ca, cb) = (split_rgb(a), split_rgb(b));
    let mut sum = 0.0;
    for (x, y) in ca.iter().zip(cb.iter()) {
        sum += ssim(x, y, data_range)?;
    }
    Ok(sum / 3.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn pattern(w: u32, h: u32, seed: u32) -> Image<f32> {
        Image::from_fn(w, h, |x, y| {
            let v = (x.wrapping_mul(2654435761) ^ y.wrapping_mul(40503) ^ seed.wrapping_mul(97)) % 1000;
            v as f32 / 1000.0
        })
    }

    #[test]
    fn taps_are_scipys_kernel() {
        let t = gaussian_taps();
        assert_eq!(SSIM_RADIUS, (SSIM_TRUNCATE * SSIM_SIGMA + 0.5) as usize);
        assert!((t.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        // Hand-computed: 1 / (1 + 2 sum_{x=1..5} exp(-x^2 / 4.5)) = 0.26601...
        assert!((t[5] - 0.266011).abs() < 1e-6, "{}", t[5]);
        for i in 0..5 {
            assert_eq!(t[i], t[10 - i]);
            assert!(t[i] < t[i + 1]);
        }
    }

    #[test]
    fn reflect_is_half_sample_symmetric() {
        // scipy 'reflect' on n = 3: ... 2 1 0 | 0 1 2 | 2 1 0 | 0 1 2 ...
        let got: Vec<usize> = (-6..9).map(|i| reflect(i, 3)).collect();
        assert_eq!(got, vec![0, 1, 2, 2, 1, 0, 0, 1, 2, 2, 1, 0, 0, 1, 2]);
        assert_eq!(reflect(-1, 1), 0);
    }

    #[test]
    fn identical_is_exactly_one() {
        let a = pattern(23, 17, 1);
        assert_eq!(ssim(&a, &a, 1.0).unwrap(), 1.0);
        let m = ssim_map(&a, &a, 1.0).unwrap();
        assert!(m.data().iter().all(|&v| v == 1.0));
    }

    #[test]
    fn constant_images_have_analytic_luminance_term() {
        // Flat images: variances vanish, S = (2 x y + C1) / (x^2 + y^2 + C1) everywhere.
        let a = Image::new(12, 11, 0.25f32);
        let b = Image::new(12, 11, 0.75f32);
        let c1 = (0.01f64 * 1.0).powi(2);
        let expect = (2.0 * 0.25 * 0.75 + c1) / (0.0625 + 0.5625 + c1);
        assert!((ssim(&a, &b, 1.0).unwrap() - expect).abs() < 1e-9);
    }

    #[test]
    fn map_interior_mean_is_the_score_and_bands_join_seamlessly() {
        // 150 rows: several bands in both code paths.
        let a = pattern(31, 150, 2);
        let b = pattern(31, 150, 3).map(|v| 0.5 * v + 0.25);
        let s = ssim(&a, &b, 1.0).unwrap();
        let m = ssim_map(&a, &b, 1.0).unwrap();
        let mut sum = 0.0f64;
        for y in 5..145 {
            for x in 5..26 {
                sum += *m.get(x, y) as f64;
            }
        }
        assert!((sum / (21.0 * 140.0) - s).abs() < 1e-6);
        // Rows at band seams equal a single-band computation of the same rows.
        let (w, h) = (31usize, 150usize);
        let mut single = vec![0.0f64; w * h];
        ssim_band(a.data(), b.data(), w, h, 0, h, ((0.01f64).powi(2), (0.03f64).powi(2)), |y, row| {
            single[y * w..(y + 1) * w].copy_from_slice(row)
        });
        for (i, (&m, &s)) in m.data().iter().zip(&single).enumerate() {
            assert_eq!(m, s as f32, "pixel {i}");
        }
    }

    #[test]
    fn rgb_is_mean_of_channels() {
        let (r, g, bl) = (pattern(14, 12, 4), pattern(14, 12, 5), pattern(14, 12, 6));
        let a = Image::from_fn(14, 12, |x, y| [*r.get(x, y), *g.get(x, y), *bl.get(x, y)]);
        let b = a.map(|p| [p[0], p[1] * 0.5, 1.0 - p[2]]);
        let expect =
            (1.0 + ssim(&g, &g.map(|v| v * 0.5), 1.0).unwrap() + ssim(&bl, &bl.map(|v| 1.0 - v), 1.0).unwrap()) / 3.0;
        assert!((ssim_rgb(&a, &b, 1.0).unwrap() - expect).abs() < 1e-12);
    }

    #[test]
    fn bad_input_is_an_error() {
        let a = pattern(10, 20, 1);
        let e = ssim(&a, &a, 1.0).unwrap_err().to_string();
        assert!(e.contains("smaller than the 11x11"), "{e}");
        let a = pattern(11, 11, 1);
        assert!(ssim(&a, &a, 1.0).is_ok());
        assert!(ssim(&a, &pattern(11, 12, 1), 1.0).unwrap_err().to_string().contains("size mismatch"));
        assert!(ssim(&a, &a, -1.0).unwrap_err().to_string().contains("data_range"));
        assert!(ssim_map(&a, &a, f32::INFINITY).is_err());
        let mut n = a.clone();
        *n.get_mut(0, 0) = f32::INFINITY;
        assert!(ssim(&a, &n, 1.0).unwrap_err().to_string().contains("non-finite"));
        let c = Image::new(11, 11, [0.0f32; 3]);
        assert!(ssim_rgb(&c, &Image::new(12, 11, [0.0f32; 3]), 1.0).is_err());
    }

    /// Direct, non-separable 2-D evaluation of the same definition (11x11 outer-product window,
    /// scipy reflect borders, population statistics, cropped mean): an independent check of the
    /// banded, ring-buffered separable implementation.
    fn ssim_naive(a: &Image<f32>, b: &Image<f32>, range: f64) -> (f64, Vec<f64>) {
        let t = gaussian_taps();
        let (w, h) = (a.width() as usize, a.height() as usize);
        let (c1, c2) = ((SSIM_K1 * range).powi(2), (SSIM_K2 * range).powi(2));
        let mut map = vec![0.0; w * h];
        for y in 0..h {
            for x in 0..w {
                let mut m = [0.0f64; 5];
                for (j, &wy) in t.iter().enumerate() {
                    for (i, &wx) in t.iter().enumerate() {
                        let sy = reflect(y as isize + j as isize - 5, h);
                        let sx = reflect(x as isize + i as isize - 5, w);
                        let (va, vb) = (a.data()[sy * w + sx] as f64, b.data()[sy * w + sx] as f64);
                        let k = wx * wy;
                        m[0] += k * va;
                        m[1] += k * vb;
                        m[2] += k * va * va;
                        m[3] += k * vb * vb;
                        m[4] += k * va * vb;
                    }
                }
                let (vx, vy, vxy) = (m[2] - m[0] * m[0], m[3] - m[1] * m[1], m[4] - m[0] * m[1]);
                map[y * w + x] =
                    ((2.0 * m[0] * m[1] + c1) * (2.0 * vxy + c2)) / ((m[0] * m[0] + m[1] * m[1] + c1) * (vx + vy + c2));
            }
        }
        let mut sum = 0.0;
        for y in 5..h - 5 {
            for x in 5..w - 5 {
                sum += map[y * w + x];
            }
        }
        (sum / ((w - 10) * (h - 10)) as f64, map)
    }

    #[test]
    fn simd_dispatch_matches_portable_kernel() {
        let (w, h) = (37usize, 29usize);
        let (a, b) = (pattern(w as u32, h as u32, 8), pattern(w as u32, h as u32, 9));
        let c = ((0.01f64).powi(2), (0.03f64).powi(2));
        let run = |generic: bool| {
            let mut out = vec![0.0f64; w * h];
            let sink = |y: usize, row: &[f64]| out[y * w..(y + 1) * w].copy_from_slice(row);
            if generic {
                ssim_band_generic(a.data(), b.data(), w, h, 0, h, c, sink);
            } else {
                ssim_band(a.data(), b.data(), w, h, 0, h, c, sink);
            }
            out
        };
        assert_eq!(run(true), run(false));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(12))]
        #[test]
        fn separable_banded_equals_naive_2d(w in 11u32..30, h in 11u32..140, s1 in 0u32..1000, s2 in 0u32..1000,
                                            range in 0.5f32..3.0) {
            let a = pattern(w, h, s1);
            let b = pattern(w, h, s2).map(|v| 0.7 * v + 0.1);
            let (want, want_map) = ssim_naive(&a, &b, range as f64);
            prop_assert!((ssim(&a, &b, range).unwrap() - want).abs() < 1e-12);
            let got_map = ssim_map(&a, &b, range).unwrap();
            for (g, w) in got_map.data().iter().zip(&want_map) {
                prop_assert!((*g as f64 - w).abs() < 1e-6);
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(24))]
        #[test]
        fn symmetric_bounded_and_shift_sensitive(w in 11u32..24, h in 11u32..24, s1 in 0u32..1000, s2 in 0u32..1000,
                                                 k in 0.1f32..1.0) {
            let a = pattern(w, h, s1);
            let b = pattern(w, h, s2).map(|v| v * k);
            let ab = ssim(&a, &b, 1.0).unwrap();
            let ba = ssim(&b, &a, 1.0).unwrap();
            prop_assert_eq!(ab, ba);
            prop_assert!((-1.0..=1.0).contains(&ab));
            prop_assert_eq!(ssim(&a, &a, 1.0).unwrap(), 1.0);
            let m = ssim_map(&a, &b, 1.0).unwrap();
            prop_assert!(m.data().iter().all(|v| (-1.0..=1.0).contains(v)));
        }
    }
}
