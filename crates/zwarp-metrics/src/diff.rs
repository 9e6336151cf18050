//! Difference images and counts, including the culling-safety split of the WOC thesis (seed
//! 002, Sec. V.1): a predicted depth *nearer* than the reference is an **error** (unsafe: the
//! occlusion map claims an occluder that is not there, so a visible object can be culled); a
//! predicted depth *farther* than the reference is an **over-estimation** (safe: it only
//! culls less).

use rayon::prelude::*;
use zwarp_core::{Error, Image, Result};

use crate::{check_pair, check_range, psnr_from_mse};

/// Errors unless `tolerance` is finite and `>= 0`.
fn check_tolerance(tolerance: f32, what: &str) -> Result<()> {
    if tolerance.is_finite() && tolerance >= 0.0 {
        Ok(())
    } else {
        Err(Error::invalid(format!("{what}: tolerance must be finite and >= 0, got {tolerance}")))
    }
}

/// Per-pixel `|a - b|` (for heat maps and thresholds). Errors on size mismatch, empty images or
/// non-finite values.
pub fn abs_diff(a: &Image<f32>, b: &Image<f32>) -> Result<Image<f32>> {
    check_pair(a, b, "abs_diff")?;
    let data = a.data().par_iter().zip(b.data().par_iter()).map(|(x, y)| (x - y).abs()).collect();
    Image::from_vec(a.width(), a.height(), data)
}

/// Per-pixel signed difference `predicted - reference`. With depth (0 = near): negative =
/// predicted nearer (unsafe for culling), positive = predicted farther (safe).
pub fn signed_diff(predicted: &Image<f32>, reference: &Image<f32>) -> Result<Image<f32>> {
    check_pair(predicted, reference, "signed_diff")?;
    let data = predicted.data().par_iter().zip(reference.data().par_iter()).map(|(p, r)| p - r).collect();
    Image::from_vec(predicted.width(), predicted.height(), data)
}

/// Number of pixels with `|a - b| > tolerance`.
pub fn count_differing(a: &Image<f32>, b: &Image<f32>, tolerance: f32) -> Result<usize> {
    check_tolerance(tolerance, "count_differing")?;
    check_pair(a, b, "count_differing")?;
    Ok(a.data().par_iter().zip(b.data().par_iter()).filter(|(x, y)| (*x - *y).abs() > tolerance).count())
}

/// Number of pixels whose values differ at all (item buffers, masks, 8-bit images).
pub fn count_differing_exact<T: PartialEq + Sync>(a: &Image<T>, b: &Image<T>) -> Result<usize> {
    a.check_same_size(b, "count_differing_exact")?;
    Ok(a.data().par_iter().zip(b.data().par_iter()).filter(|(x, y)| x != y).count())
}

/// Number of pixels where the predicted depth is **nearer** than the reference by more than
/// `tolerance` (`predicted < reference - tolerance`): the unsafe culling errors of seed 002
/// Sec. V.1. Depths in any consistent unit (stored `[0, 1]` or linear).
pub fn count_nearer(predicted: &Image<f32>, reference: &Image<f32>, tolerance: f32) -> Result<usize> {
    Ok(signed_depth_errors(predicted, reference, tolerance, 1.0)?.nearer)
}

/// Number of pixels where the predicted depth is **farther** than the reference by more than
/// `tolerance` (`predicted > reference + tolerance`): conservative over-estimation.
pub fn count_farther(predicted: &Image<f32>, reference: &Image<f32>, tolerance: f32) -> Result<usize> {
    Ok(signed_depth_errors(predicted, reference, tolerance, 1.0)?.farther)
}

/// Culling-safety statistics of a predicted depth buffer (seed 002, thesis Sec. V.1, Fig. 8).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SignedDepthErrors {
    /// Pixels with `predicted < reference - tolerance`: predicted **nearer**, UNSAFE (can cull
    /// a visible object).
    pub nearer: usize,
    /// Pixels with `predicted > reference + tolerance`: predicted **farther**, safe
    /// over-estimation (hole fills at the far plane land here).
    pub farther: usize,
    /// Total number of pixels.
    pub pixels: usize,
    /// The thesis' one-sided "error" PSNR (dB): PSNR of `max(reference - predicted, 0)`, i.e.
    /// only nearer-than-reference differences count; `inf` when there are none.
    pub psnr_nearer: f64,
    /// One-sided "over-estimation" PSNR (dB) of `max(predicted - reference, 0)`.
    pub psnr_farther: f64,
}

impl SignedDepthErrors {
    /// `nearer / pixels`: fraction of unsafe pixels.
    pub fn nearer_fraction(&self) -> f64 {
        self.nearer as f64 / self.pixels as f64
    }
    /// `farther / pixels`: fraction of over-estimated pixels.
    pub fn farther_fraction(&self) -> f64 {
        self.farther as f64 / self.pixels as f64
    }
}

/// Splits the depth difference into unsafe (nearer) and safe (farther) parts, seed 002 thesis
/// Sec. V.1: counts beyond `tolerance` and one-sided PSNRs with peak `data_range` (the one-sided
/// PSNRs use every pixel's positive part, no tolerance, as the thesis' difference images do).
/// 0 = near, as every zwarp depth; pass stored buffers, linear or normalized depth alike.
pub fn signed_depth_errors(
    predicted: &Image<f32>,
    reference: &Image<f32>,
    tolerance: f32,
    data_range: f32,
) -> Result<SignedDepthErrors> {
    check_tolerance(tolerance, "signed_depth_errors")?;
    check_range(data_range, "signed_depth_errors")?;
    check_pair(predicted, reference, "signed_depth_errors")?;
    // Fixed chunks keep the f64 sums identical across thread counts.
    let parts: Vec<(usize, usize, f64, f64)> = predicted
        .data()
        .par_chunks(1 << 14)
        .zip(reference.data().par_chunks(1 << 14))
        .map(|(cp, cr)| {
            let mut s = (0usize, 0usize, 0.0f64, 0.0f64);
            for (&p, &r) in cp.iter().zip(cr) {
                let d = p as f64 - r as f64;
                if d < -(tolerance as f64) {
                    s.0 += 1;
                } else if d > tolerance as f64 {
                    s.1 += 1;
                }
                if d < 0.0 {
                    s.2 += d * d;
                } else {
                    s.3 += d * d;
                }
            }
            s
        })
        .collect();
    let n = predicted.len();
    let (mut nearer, mut farther, mut sn, mut sf) = (0, 0, 0.0, 0.0);
    for p in parts {
        nearer += p.0;
        farther += p.1;
        sn += p.2;
        sf += p.3;
    }
    Ok(SignedDepthErrors {
        nearer,
        farther,
        pixels: n,
        psnr_nearer: psnr_from_mse(sn / n as f64, data_range)?,
        psnr_farther: psnr_from_mse(sf / n as f64, data_range)?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn img(v: &[f32]) -> Image<f32> {
        Image::from_vec(v.len() as u32, 1, v.to_vec()).unwrap()
    }

    #[test]
    fn sign_convention() {
        let reference = img(&[0.5, 0.5, 0.5, 0.5, 0.5]);
        // nearer by 0.2, nearer within tolerance, equal, farther by 0.1, far hole.
        let predicted = img(&[0.3, 0.495, 0.5, 0.6, 1.0]);
        let e = signed_depth_errors(&predicted, &reference, 0.01, 1.0).unwrap();
        assert_eq!((e.nearer, e.farther, e.pixels), (1, 2, 5));
        assert!((e.nearer_fraction() - 0.2).abs() < 1e-12 && (e.farther_fraction() - 0.4).abs() < 1e-12);
        let mse_n = (0.2f64.powi(2) + 0.005f64.powi(2)) / 5.0;
        assert!((e.psnr_nearer - 10.0 * (1.0 / mse_n).log10()).abs() < 1e-4);
        let mse_f = (0.1f64.powi(2) + 0.25) / 5.0;
        assert!((e.psnr_farther - 10.0 * (1.0 / mse_f).log10()).abs() < 1e-4);
        assert_eq!(count_nearer(&predicted, &reference, 0.01).unwrap(), 1);
        assert_eq!(count_nearer(&predicted, &reference, 0.0).unwrap(), 2);
        assert_eq!(count_farther(&predicted, &reference, 0.01).unwrap(), 2);
        // Swapping the roles swaps the split.
        let s = signed_depth_errors(&reference, &predicted, 0.01, 1.0).unwrap();
        assert_eq!((s.nearer, s.farther), (2, 1));
        assert_eq!((s.psnr_nearer, s.psnr_farther), (e.psnr_farther, e.psnr_nearer));
        let sd = signed_diff(&predicted, &reference).unwrap();
        assert!(sd.data()[0] < 0.0 && sd.data()[3] > 0.0);
    }

    #[test]
    fn perfect_prediction_has_no_errors() {
        let r = img(&[0.1, 0.9, 1.0]);
        let e = signed_depth_errors(&r, &r, 0.0, 1.0).unwrap();
        assert_eq!((e.nearer, e.farther), (0, 0));
        assert_eq!((e.psnr_nearer, e.psnr_farther), (f64::INFINITY, f64::INFINITY));
    }

    #[test]
    fn differences_and_counts() {
        let a = img(&[0.0, 1.0, 0.5, 0.25]);
        let b = img(&[0.0, 0.5, 0.75, 0.25]);
        assert_eq!(abs_diff(&a, &b).unwrap().data(), &[0.0, 0.5, 0.25, 0.0]);
        assert_eq!(count_differing(&a, &b, 0.0).unwrap(), 2);
        assert_eq!(count_differing(&a, &b, 0.3).unwrap(), 1);
        assert_eq!(count_differing(&a, &b, 0.5).unwrap(), 0);
        let ia = Image::from_vec(3, 1, vec![1u32, 2, u32::MAX]).unwrap();
        let ib = Image::from_vec(3, 1, vec![1u32, 3, 7]).unwrap();
        assert_eq!(count_differing_exact(&ia, &ib).unwrap(), 2);
    }

    #[test]
    fn bad_input_is_an_error() {
        let a = img(&[0.0, 1.0]);
        let b = img(&[0.0, 1.0, 2.0]);
        assert!(abs_diff(&a, &b).is_err());
        assert!(signed_diff(&a, &b).is_err());
        assert!(count_differing(&a, &a, -1.0).unwrap_err().to_string().contains("tolerance"));
        assert!(count_differing(&a, &a, f32::NAN).is_err());
        assert!(signed_depth_errors(&a, &a, 0.0, 0.0).unwrap_err().to_string().contains("data_range"));
        assert!(count_differing_exact(&Image::new(2, 2, 0u32), &Image::new(2, 1, 0u32)).is_err());
        let n = img(&[f32::NAN, 0.0]);
        assert!(count_nearer(&n, &a, 0.0).unwrap_err().to_string().contains("non-finite"));
    }
}
