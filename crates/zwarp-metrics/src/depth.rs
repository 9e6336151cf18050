//! The depth-quality protocol of ARCHITECTURE.md ("Evaluation protocol"): PSNR / SSIM of a
//! predicted depth buffer against the reference rendered at the target view (seed 000 Sec. 7),
//! on linear view depth normalized by the reference's own surface range, beside the same
//! metrics on the stored buffer.

use rayon::prelude::*;
use zwarp_core::{is_surface, Camera, Error, Image, Result};

use crate::psnr::sum_sq_diff;
use crate::ssim::{prepare, ssim_validated};
use crate::{check_finite, psnr_from_mse};

/// Nearest and farthest *linear* view depth (camera units along the view axis) of the surfaces
/// in a reference depth buffer: the normalization range of the headline depth metrics.
///
/// Empty pixels (stored depth `>= 1`, [`zwarp_core::EMPTY_DEPTH`]) and non-finite values are
/// ignored; stored depths below 0 (in front of the near plane) are treated as 0. `None` when the
/// buffer has no surface pixel at all.
pub fn surface_range(reference: &Image<f32>, cam: &Camera) -> Option<(f32, f32)> {
    let (lo, hi) = reference
        .data()
        .par_iter()
        .filter(|d| d.is_finite() && is_surface(**d))
        .map(|&d| {
            let l = cam.linear_depth(d.max(0.0));
            (l, l)
        })
        .reduce(|| (f32::INFINITY, f32::NEG_INFINITY), |a, b| (a.0.min(b.0), a.1.max(b.1)));
    (lo <= hi).then_some((lo, hi))
}

/// Linear view depth normalized to `[0, 1]` by `range = (nearest, farthest)` (from
/// [`surface_range`] of the *reference* frame, ARCHITECTURE.md "Evaluation protocol"):
/// `(linear - nearest) / (farthest - nearest)`, clamped to `[0, 1]`.
///
/// Empty pixels (stored depth `>= 1`, including far-plane hole fills) map to exactly 1, as do
/// surfaces beyond `farthest`; surfaces nearer than `nearest` map to 0. A degenerate range
/// (`farthest <= nearest`, e.g. a reference that is one fronto-parallel plane, or non-finite
/// bounds) falls back to the camera's `(near, far)` so the result stays finite. NaN inputs stay
/// NaN (the metrics reject them).
pub fn normalized_linear_depth(depth: &Image<f32>, cam: &Camera, range: (f32, f32)) -> Image<f32> {
    let (lo, hi) =
        if range.0.is_finite() && range.1.is_finite() && range.1 > range.0 { range } else { (cam.near, cam.far) };
    let inv = 1.0 / (hi - lo);
    let mut out = Image::new(depth.width(), depth.height(), 1.0f32);
    out.data_mut().par_iter_mut().zip(depth.data().par_iter()).for_each(|(o, &d)| {
        *o = if d >= 1.0 {
            1.0
        } else if d.is_nan() {
            f32::NAN
        } else {
            ((cam.linear_depth(d.max(0.0)) - lo) * inv).clamp(0.0, 1.0)
        };
    });
    out
}

/// Depth-warp quality against a reference render (ARCHITECTURE.md "Evaluation protocol";
/// the PSNR/SSIM pairs of seed 000 Sec. 7, Fig. 10-12, Tables 1-2).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DepthQuality {
    /// Headline PSNR (dB) on linear depth normalized by the reference's surface range
    /// (`data_range = 1`); `inf` when the normalized buffers are identical.
    pub psnr: f64,
    /// Headline SSIM (Wang et al. 2004, 11x11 Gaussian, sigma 1.5) on the same normalized depth.
    pub ssim: f64,
    /// PSNR (dB) on the stored post-projection depth in `[0, 1]` (`data_range = 1`). Reported
    /// beside the headline figure because stored depth crowds near 1 and flatters errors.
    pub psnr_buffer: f64,
    /// SSIM on the stored `[0, 1]` depth (`data_range = 1`).
    pub ssim_buffer: f64,
    /// The linear-depth normalization range `(nearest, farthest)` that was used: the
    /// reference's [`surface_range`], or the camera's `(near, far)` when the reference has no
    /// surface or a single depth.
    pub range: (f32, f32),
    /// Fraction of all pixels that are holes: empty in the prediction (stored depth `>= 1`,
    /// e.g. non-converged pixels filled with the far plane) where the reference has a surface.
    pub hole_fraction: f64,
}

/// Computes [`DepthQuality`] of `predicted` against `reference`, both stored depth buffers of
/// the target camera `cam` (ARCHITECTURE.md "Evaluation protocol").
///
/// The headline `psnr` / `ssim` compare [`normalized_linear_depth`] of both buffers with the
/// range from [`surface_range`]`(reference)`; `*_buffer` compare the stored buffers clamped to
/// `[0, 1]` (a warp may write a reprojected depth slightly outside, which the depth test would
/// clip). Errors when sizes differ from each other or from the camera, the images are smaller
/// than 11x11 (the SSIM window), or they hold NaN / infinite values.
pub fn depth_quality(predicted: &Image<f32>, reference: &Image<f32>, cam: &Camera) -> Result<DepthQuality> {
    reference.check_nonempty("depth_quality reference")?;
    predicted.check_same_size(reference, "depth_quality predicted vs reference")?;
    if reference.size() != (cam.width, cam.height) {
        return Err(Error::invalid(format!(
            "depth_quality: buffers are {}x{} but the camera renders {}x{}",
            reference.width(),
            reference.height(),
            cam.width,
            cam.height
        )));
    }
    check_finite(predicted, "depth_quality", "predicted")?;
    check_finite(reference, "depth_quality", "reference")?;
    let range = match surface_range(reference, cam) {
        Some((lo, hi)) if hi > lo => (lo, hi),
        _ => (cam.near, cam.far),
    };
    let np = normalized_linear_depth(predicted, cam, range);
    let nr = normalized_linear_depth(reference, cam, range);
    // Stored buffers clamped to [0, 1]; copied only when something lies outside.
    let clamp = |img: &Image<f32>| -> Option<Image<f32>> {
        img.data().iter().any(|d| !(0.0..=1.0).contains(d)).then(|| img.map(|d| d.clamp(0.0, 1.0)))
    };
    let (cp, cr) = (clamp(predicted), clamp(reference));
    let (cp, cr) = (cp.as_ref().unwrap_or(predicted), cr.as_ref().unwrap_or(reference));
    let holes = predicted
        .data()
        .par_iter()
        .zip(reference.data().par_iter())
        .filter(|(p, r)| !is_surface(**p) && is_surface(**r))
        .count();
    // Everything is validated above: all four buffers are finite and of one size >= 11x11.
    let (w, h, c) = prepare(&np, &nr, 1.0, "depth_quality")?;
    let n = reference.len() as f64;
    Ok(DepthQuality {
        psnr: psnr_from_mse(sum_sq_diff(np.data(), nr.data()) / n, 1.0)?,
        ssim: ssim_validated(np.data(), nr.data(), w, h, c),
        psnr_buffer: psnr_from_mse(sum_sq_diff(cp.data(), cr.data()) / n, 1.0)?,
        ssim_buffer: ssim_validated(cp.data(), cr.data(), w, h, c),
        range,
        hole_fraction: holes as f64 / reference.len() as f64,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn cam(w: u32, h: u32) -> Camera {
        Camera::perspective(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 1.0, 0.1, 100.0, w, h).unwrap()
    }

    /// Reference: linear depth 2 m on the left half, 3 m on the right, one empty row at the top.
    fn two_planes(c: &Camera) -> Image<f32> {
        let (d2, d3) = (c.stored_depth(2.0), c.stored_depth(3.0));
        Image::from_fn(c.width, c.height, |x, y| {
            if y == 0 {
                1.0
            } else if x < c.width / 2 {
                d2
            } else {
                d3
            }
        })
    }

    #[test]
    fn surface_range_ignores_empty_pixels() {
        let c = cam(16, 12);
        let (lo, hi) = surface_range(&two_planes(&c), &c).unwrap();
        assert!((lo - 2.0).abs() < 1e-4 && (hi - 3.0).abs() < 1e-3, "{lo} {hi}");
        assert_eq!(surface_range(&Image::new(4, 4, 1.0), &c), None);
    }

    #[test]
    fn normalization_endpoints_and_clamping() {
        let c = cam(4, 1);
        let depth =
            Image::from_vec(4, 1, vec![c.stored_depth(2.0), c.stored_depth(2.5), c.stored_depth(10.0), 1.0]).unwrap();
        let n = normalized_linear_depth(&depth, &c, (2.0, 3.0));
        assert!(n.data()[0].abs() < 1e-3);
        assert!((n.data()[1] - 0.5).abs() < 1e-3);
        assert_eq!(n.data()[2], 1.0, "beyond the farthest reference surface clamps to 1");
        assert_eq!(n.data()[3], 1.0, "empty pixel is 1");
        // Nearer than the nearest surface clamps to 0.
        let near = Image::new(1, 1, c.stored_depth(1.0));
        assert_eq!(normalized_linear_depth(&near, &c, (2.0, 3.0)).data()[0], 0.0);
        // Degenerate range falls back to the camera's near/far.
        let flat = normalized_linear_depth(&Image::new(1, 1, c.stored_depth(50.05)), &c, (2.0, 2.0));
        assert!((flat.data()[0] - 0.5).abs() < 1e-3, "{}", flat.data()[0]);
    }

    #[test]
    fn perfect_prediction_and_known_error() {
        let c = cam(24, 20);
        let r = two_planes(&c);
        let q = depth_quality(&r, &r, &c).unwrap();
        assert_eq!((q.psnr, q.ssim, q.psnr_buffer, q.ssim_buffer), (f64::INFINITY, 1.0, f64::INFINITY, 1.0));
        assert_eq!(q.hole_fraction, 0.0);
        // Predict the 3 m plane at 2.5 m: normalized error 0.5 on half the non-empty pixels.
        let mut p = r.clone();
        let (d25, d3) = (c.stored_depth(2.5), c.stored_depth(3.0));
        p.data_mut().iter_mut().filter(|d| **d == d3).for_each(|d| *d = d25);
        let q = depth_quality(&p, &r, &c).unwrap();
        let wrong = 12.0 * 19.0;
        let expect = 10.0 * (480.0f64 / (wrong * 0.25)).log10();
        assert!((q.psnr - expect).abs() < 0.01, "{} vs {expect}", q.psnr);
        // The stored buffer hides the same error: its PSNR is far higher.
        let eb = (d3 - d25) as f64;
        let expect_buf = 10.0 * (480.0 / (wrong * eb * eb)).log10();
        assert!((q.psnr_buffer - expect_buf).abs() < 0.01);
        assert!(q.psnr_buffer > q.psnr + 30.0);
        assert!(q.ssim < q.ssim_buffer && q.ssim < 1.0);
        // A far hole (depth 1) in the prediction counts as an error of up to 1.
        let mut h = r.clone();
        *h.get_mut(3, 5) = 1.0;
        let q = depth_quality(&h, &r, &c).unwrap();
        assert!((q.psnr - 10.0 * 480f64.log10()).abs() < 0.01, "{}", q.psnr);
        assert_eq!(q.hole_fraction, 1.0 / 480.0);
    }

    #[test]
    fn empty_reference_uses_camera_range() {
        let c = cam(12, 12);
        let r = Image::new(12, 12, 1.0f32);
        let q = depth_quality(&r, &r, &c).unwrap();
        assert_eq!(q.range, (0.1, 100.0));
        assert_eq!(q.psnr, f64::INFINITY);
    }

    #[test]
    fn bad_input_is_an_error() {
        let c = cam(12, 12);
        let r = Image::new(12, 12, 0.5f32);
        assert!(depth_quality(&Image::new(12, 13, 0.5), &r, &c).unwrap_err().to_string().contains("size mismatch"));
        let c2 = cam(13, 12);
        assert!(depth_quality(&r, &r, &c2).unwrap_err().to_string().contains("camera renders"));
        let mut n = r.clone();
        *n.get_mut(1, 1) = f32::NAN;
        assert!(depth_quality(&n, &r, &c).unwrap_err().to_string().contains("predicted"));
        let small = cam(8, 8);
        let s = Image::new(8, 8, 0.5f32);
        assert!(depth_quality(&s, &s, &small).unwrap_err().to_string().contains("window"));
    }
}
