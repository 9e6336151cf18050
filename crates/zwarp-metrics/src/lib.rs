//! zwarp-metrics: the quality numbers every zwarp experiment reports (ARCHITECTURE.md
//! "Evaluation protocol").
//!
//! - [`psnr`] / [`mse`] and [`ssim`] / [`ssim_map`]: PSNR and SSIM (Wang et al. 2004) as the
//!   depth-warping paper (seed 000, Sec. 7, Fig. 10, Tables 1-2) reports them, computed exactly
//!   like scikit-image's `peak_signal_noise_ratio` and `structural_similarity(...,
//!   gaussian_weights=True, sigma=1.5, use_sample_covariance=False)` (cross-checked against a
//!   committed skimage fixture to 1e-4). Colour variants [`psnr_rgb`] / [`ssim_rgb`].
//! - [`depth_quality`]: the headline depth metrics on linear view depth normalized by the
//!   reference frame's own surface range ([`surface_range`], [`normalized_linear_depth`]),
//!   plus the same metrics on the stored `[0, 1]` buffer.
//! - Colour ([`color_quality`]): luminance and per-channel PSNR / SSIM on linear colour, CIE94
//!   under D65 ([`cie94_mean`], seed 001 Fig. 8) and NVIDIA FLIP ([`flip`], feature `flip`: the
//!   reference implementation through the `nv-flip` crate, which builds its C++ with the
//!   system's C++ compiler).
//! - Culling safety (seed 002, thesis Sec. V.1): a predicted depth *nearer* than the reference
//!   is an error (it can hide visible objects), a *farther* one is a conservative
//!   over-estimation; [`signed_depth_errors`] counts both separately and gives the thesis'
//!   one-sided PSNRs. [`abs_diff`], [`count_differing`] for the rest.
//!
//! All functions validate their input (same size, non-empty, finite values, positive data range)
//! and return [`zwarp_core::Error::Invalid`] with a one-line message instead of panicking.

#![deny(missing_docs)]
mod color;
mod depth;
mod diff;
mod psnr;
mod ssim;
mod timing;

pub use color::{
    cie94, cie94_map, cie94_mean, color_quality, linear_rgb_to_lab, luminance, masked_mean, psnr_channels,
    psnr_rgb_masked, ColorQuality, D65_WHITE, LUMA, RGB_TO_XYZ,
};
#[cfg(feature = "flip")]
pub use color::{flip, Flip, FLIP_DEFAULT_PPD};
pub use depth::{depth_quality, normalized_linear_depth, surface_range, DepthQuality};
pub use diff::{
    abs_diff, count_differing, count_differing_exact, count_farther, count_nearer, signed_depth_errors, signed_diff,
    SignedDepthErrors,
};
pub use psnr::{mse, mse_rgb, psnr, psnr_from_mse, psnr_rgb};
pub use ssim::{ssim, ssim_map, ssim_rgb, SSIM_K1, SSIM_K2, SSIM_RADIUS, SSIM_SIGMA, SSIM_TRUNCATE, SSIM_WIN_SIZE};
pub use timing::Timing;

use zwarp_core::{Error, Image, Result};

/// Errors unless `a` and `b` are non-empty, the same size and hold only finite values.
pub(crate) fn check_pair(a: &Image<f32>, b: &Image<f32>, what: &str) -> Result<()> {
    a.check_nonempty(what)?;
    a.check_same_size(b, what)?;
    check_finite(a, what, "first")?;
    check_finite(b, what, "second")
}

/// Errors if the image holds NaN or infinite values (metrics on them would be meaningless).
pub(crate) fn check_finite(img: &Image<f32>, what: &str, which: &str) -> Result<()> {
    // Locate only on failure.
    if img.all_finite() {
        return Ok(());
    }
    let i = img.data().iter().position(|v| !v.is_finite()).unwrap_or(0);
    let w = img.width() as usize;
    Err(Error::invalid(format!(
        "{what}: {which} image holds a non-finite value ({}) at pixel ({}, {})",
        img.data()[i],
        i % w,
        i / w
    )))
}

/// Errors unless `data_range` is finite and positive (PSNR's peak, SSIM's `L`).
pub(crate) fn check_range(data_range: f32, what: &str) -> Result<()> {
    if data_range.is_finite() && data_range > 0.0 {
        Ok(())
    } else {
        Err(Error::invalid(format!("{what}: data_range must be finite and > 0, got {data_range}")))
    }
}

/// Splits an RGB image into its three channel planes.
pub(crate) fn split_rgb(img: &Image<[f32; 3]>) -> [Image<f32>; 3] {
    [img.map(|p| p[0]), img.map(|p| p[1]), img.map(|p| p[2])]
}
