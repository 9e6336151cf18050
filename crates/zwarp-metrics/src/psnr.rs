//! MSE and PSNR (seed 000 Sec. 7 quality metric; seed 002 thesis Sec. V.1 "image error").

use rayon::prelude::*;
use zwarp_core::{Error, Image, Result};

use crate::{check_pair, check_range, split_rgb};

/// Pixels per parallel chunk. Fixed (not derived from the thread count) so the f64 summation
/// order, and therefore the result bit pattern, is the same on every machine.
const CHUNK: usize = 1 << 14;

/// Sum of squared differences in f64 over two equally long slices.
pub(crate) fn sum_sq_diff(a: &[f32], b: &[f32]) -> f64 {
    a.par_chunks(CHUNK)
        .zip(b.par_chunks(CHUNK))
        .map(|(ca, cb)| ca.iter().zip(cb).map(|(&x, &y)| (x as f64 - y as f64).powi(2)).sum::<f64>())
        .collect::<Vec<f64>>()
        .into_iter()
        .sum()
}

/// Mean squared error `mean((a - b)^2)`, accumulated in f64 (as scikit-image's
/// `mean_squared_error`, which promotes to float64).
///
/// Errors on size mismatch, empty images or non-finite values.
pub fn mse(a: &Image<f32>, b: &Image<f32>) -> Result<f64> {
    check_pair(a, b, "mse")?;
    Ok(sum_sq_diff(a.data(), b.data()) / a.len() as f64)
}

/// PSNR in dB from a mean squared error: `10 log10(data_range^2 / mse)`; `+inf` when
/// `mse == 0` (identical images).
pub fn psnr_from_mse(mse: f64, data_range: f32) -> Result<f64> {
    check_range(data_range, "psnr")?;
    if !(mse >= 0.0 && mse.is_finite()) {
        return Err(Error::invalid(format!("psnr: mse must be finite and >= 0, got {mse}")));
    }
    if mse == 0.0 {
        return Ok(f64::INFINITY);
    }
    let r = data_range as f64;
    Ok(10.0 * (r * r / mse).log10())
}

/// Peak signal-to-noise ratio in dB, `10 log10(data_range^2 / mse(a, b))`, the metric of
/// seed 000 Sec. 7 (Fig. 10, Tables 1-2, 7) and scikit-image's `peak_signal_noise_ratio`.
///
/// Symmetric in `a` and `b`. Returns `f64::INFINITY` for identical images. For depth use
/// `data_range = 1` (depth lives in `[0, 1]`; see [`crate::depth_quality`]).
pub fn psnr(a: &Image<f32>, b: &Image<f32>, data_range: f32) -> Result<f64> {
    check_range(data_range, "psnr")?;
    psnr_from_mse(mse(a, b)?, data_range)
}

/// Colour MSE: the mean over all `3 * width * height` samples, i.e. the mean of the three
/// per-channel MSEs (scikit-image's `mean_squared_error` on an `HxWx3` array).
pub fn mse_rgb(a: &Image<[f32; 3]>, b: &Image<[f32; 3]>) -> Result<f64> {
    a.check_nonempty("mse_rgb")?;
    a.check_same_size(b, "mse_rgb")?;
    let (ca, cb) = (split_rgb(a), split_rgb(b));
    let mut sum = 0.0;
    for (x, y) in ca.iter().zip(cb.iter()) {
        sum += mse(x, y)?;
    }
    Ok(sum / 3.0)
}

/// Colour PSNR (seed 001's colour warps; seed 000 Table 7 colour renderings) from
/// [`mse_rgb`]: what scikit-image's `peak_signal_noise_ratio` gives on an `HxWx3` array.
pub fn psnr_rgb(a: &Image<[f32; 3]>, b: &Image<[f32; 3]>, data_range: f32) -> Result<f64> {
    check_range(data_range, "psnr_rgb")?;
    psnr_from_mse(mse_rgb(a, b)?, data_range)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identical_images_give_infinite_psnr() {
        let a = Image::from_fn(7, 5, |x, y| (x * 3 + y) as f32 / 40.0);
        assert_eq!(mse(&a, &a).unwrap(), 0.0);
        assert_eq!(psnr(&a, &a, 1.0).unwrap(), f64::INFINITY);
    }

    #[test]
    fn constant_offset_has_analytic_psnr() {
        // Exactly representable values: mse = 0.125^2, PSNR = 10 log10(1 / 0.125^2) = 18.06 dB;
        // range 2 adds 20 log10(2).
        let a = Image::from_fn(13, 9, |x, y| ((x + y) % 5) as f32 * 0.25);
        let b = a.map(|v| v + 0.125);
        let expect = 10.0 * (1.0 / (0.125f64 * 0.125)).log10();
        assert!((psnr(&a, &b, 1.0).unwrap() - expect).abs() < 1e-9);
        assert!((psnr(&a, &b, 2.0).unwrap() - expect - 20.0 * 2f64.log10()).abs() < 1e-9);
        assert!((mse(&a, &b).unwrap() - 0.015625).abs() < 1e-12);
    }

    #[test]
    fn single_wrong_pixel() {
        // One pixel of 100 off by 1 -> mse 0.01 -> 20 dB.
        let a = Image::new(10, 10, 0.0f32);
        let mut b = a.clone();
        *b.get_mut(3, 4) = 1.0;
        assert!((psnr(&a, &b, 1.0).unwrap() - 20.0).abs() < 1e-12);
        assert_eq!(psnr(&a, &b, 1.0).unwrap(), psnr(&b, &a, 1.0).unwrap());
    }

    #[test]
    fn rgb_is_mean_of_channel_mse() {
        let a = Image::new(4, 3, [0.0f32, 0.0, 0.0]);
        let b = Image::new(4, 3, [0.5f32, 0.0, 0.25]);
        let expect = (0.25 + 0.0 + 0.0625) / 3.0;
        assert!((mse_rgb(&a, &b).unwrap() - expect).abs() < 1e-12);
        assert!((psnr_rgb(&a, &b, 1.0).unwrap() - 10.0 * (1.0 / expect).log10()).abs() < 1e-9);
        assert_eq!(psnr_rgb(&a, &a, 1.0).unwrap(), f64::INFINITY);
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(32))]
        #[test]
        fn symmetric_and_consistent_with_mse(w in 1u32..20, h in 1u32..20, seed in 0u32..10_000, r in 0.5f32..4.0) {
            let a = Image::from_fn(w, h, |x, y| ((x * 7919 + y * 104_729 + seed) % 997) as f32 / 997.0);
            let b = Image::from_fn(w, h, |x, y| ((x * 31 + y * 17 + seed * 3) % 101) as f32 / 101.0);
            let ab = psnr(&a, &b, r).unwrap();
            proptest::prop_assert_eq!(ab, psnr(&b, &a, r).unwrap());
            let m = mse(&a, &b).unwrap();
            if m > 0.0 {
                proptest::prop_assert!((ab - 10.0 * ((r as f64).powi(2) / m).log10()).abs() < 1e-9);
            } else {
                proptest::prop_assert_eq!(ab, f64::INFINITY);
            }
        }
    }

    #[test]
    fn bad_input_is_an_error() {
        let a = Image::new(4, 4, 0.0f32);
        let b = Image::new(4, 5, 0.0f32);
        assert!(psnr(&a, &b, 1.0).unwrap_err().to_string().contains("size mismatch"));
        assert!(psnr(&a, &a, 0.0).unwrap_err().to_string().contains("data_range"));
        assert!(psnr(&a, &a, f32::NAN).is_err());
        let mut n = a.clone();
        *n.get_mut(2, 1) = f32::NAN;
        let e = psnr(&a, &n, 1.0).unwrap_err().to_string();
        assert!(e.contains("non-finite") && e.contains("(2, 1)"), "{e}");
        let z = Image::new(0, 3, 0.0f32);
        assert!(mse(&z, &z).unwrap_err().to_string().contains("zero-size"));
        assert!(psnr_from_mse(-1.0, 1.0).is_err());
        let c = Image::new(2, 2, [0.0f32; 3]);
        assert!(psnr_rgb(&c, &Image::new(2, 3, [0.0f32; 3]), 1.0).is_err());
    }
}
