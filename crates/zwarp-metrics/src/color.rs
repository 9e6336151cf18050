//! Colour-image metrics for colour warping (seed 001): luminance PSNR / SSIM, per-channel
//! PSNR, CIE94 colour difference under D65 (seed 001 Fig. 8), NVIDIA FLIP (Andersson et al.
//! 2020, LDR; feature `flip`, through the `nv-flip` wrapper of the reference implementation),
//! and [`color_quality`], which bundles them for one predicted frame against its reference.
//!
//! Inputs are linear RGB `f32` images (ARCHITECTURE.md "Colour"); FLIP sees them as 8-bit sRGB, as
//! the reference tool sees PNG files.

use rayon::prelude::*;
use zwarp_core::{Error, Image, Result};

use crate::psnr::sum_sq_diff;
use crate::{psnr_from_mse, split_rgb, ssim};

/// Rec. 709 / sRGB luminance weights of linear R, G, B (the `Y` row of the sRGB -> XYZ matrix).
pub const LUMA: [f32; 3] = [0.2126729, 0.7151522, 0.0721750];

/// Linear RGB -> CIE XYZ for sRGB primaries and the D65 white point (IEC 61966-2-1).
pub const RGB_TO_XYZ: [[f64; 3]; 3] =
    [[0.4124564, 0.3575761, 0.1804375], [0.2126729, 0.7151522, 0.0721750], [0.0193339, 0.1191920, 0.9503041]];

/// The D65 reference white in XYZ (Y = 1): the white of the CIELab conversion of [`cie94`].
pub const D65_WHITE: [f64; 3] = [0.95047, 1.0, 1.08883];

/// Luminance `Y` of a linear RGB image ([`LUMA`] weights).
pub fn luminance(img: &Image<[f32; 3]>) -> Image<f32> {
    img.map(|c| LUMA[0] * c[0] + LUMA[1] * c[1] + LUMA[2] * c[2])
}

/// CIELab (D65 white, [`D65_WHITE`]) of one linear sRGB colour.
pub fn linear_rgb_to_lab(c: [f32; 3]) -> [f64; 3] {
    let rgb = [c[0] as f64, c[1] as f64, c[2] as f64];
    let mut xyz = [0.0; 3];
    for (o, row) in xyz.iter_mut().zip(RGB_TO_XYZ.iter()) {
        *o = row[0] * rgb[0] + row[1] * rgb[1] + row[2] * rgb[2];
    }
    let f = |t: f64| {
        const D: f64 = 6.0 / 29.0;
        if t > D * D * D {
            t.cbrt()
        } else {
            t / (3.0 * D * D) + 4.0 / 29.0
        }
    };
    let (fx, fy, fz) = (f(xyz[0] / D65_WHITE[0]), f(xyz[1] / D65_WHITE[1]), f(xyz[2] / D65_WHITE[2]));
    [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
}

/// CIE 1994 colour difference `Delta E*_94` of two CIELab colours, graphic-arts weights
/// (`k_L = k_C = k_H = 1`, `K_1 = 0.045`, `K_2 = 0.015`); `reference` is the standard whose
/// chroma sets `S_C` and `S_H` (the formula is not symmetric).
pub fn cie94(reference: [f64; 3], sample: [f64; 3]) -> f64 {
    let dl = reference[0] - sample[0];
    let c1 = (reference[1] * reference[1] + reference[2] * reference[2]).sqrt();
    let c2 = (sample[1] * sample[1] + sample[2] * sample[2]).sqrt();
    let dc = c1 - c2;
    let (da, db) = (reference[1] - sample[1], reference[2] - sample[2]);
    let dh2 = (da * da + db * db - dc * dc).max(0.0);
    let (sc, sh) = (1.0 + 0.045 * c1, 1.0 + 0.015 * c1);
    (dl * dl + (dc / sc).powi(2) + dh2 / (sh * sh)).sqrt()
}

fn check_rgb_pair(a: &Image<[f32; 3]>, b: &Image<[f32; 3]>, what: &str) -> Result<()> {
    a.check_nonempty(what)?;
    a.check_same_size(b, what)?;
    for (img, which) in [(a, "first"), (b, "second")] {
        if !img.data().par_iter().all(|c| c.iter().all(|v| v.is_finite())) {
            return Err(Error::invalid(format!("{what}: {which} image holds a non-finite value")));
        }
    }
    Ok(())
}

/// Per-pixel CIE94 difference (D65) of `test` against `reference` (linear RGB).
pub fn cie94_map(reference: &Image<[f32; 3]>, test: &Image<[f32; 3]>) -> Result<Image<f32>> {
    check_rgb_pair(reference, test, "cie94")?;
    let data: Vec<f32> = reference
        .data()
        .par_iter()
        .zip(test.data())
        .map(|(&r, &t)| cie94(linear_rgb_to_lab(r), linear_rgb_to_lab(t)) as f32)
        .collect();
    Image::from_vec(reference.width(), reference.height(), data)
}

/// Mean CIE94 difference (D65) over all pixels, or over the pixels where `mask` is `true`
/// (`NaN` if the mask selects none). seed 001 Fig. 8 reports this mean.
pub fn cie94_mean(reference: &Image<[f32; 3]>, test: &Image<[f32; 3]>, mask: Option<&Image<bool>>) -> Result<f64> {
    let m = cie94_map(reference, test)?;
    masked_mean(&m, mask)
}

/// Mean of `values` where `mask` is set (all pixels without a mask); `NaN` for an empty set.
pub fn masked_mean(values: &Image<f32>, mask: Option<&Image<bool>>) -> Result<f64> {
    if let Some(m) = mask {
        values.check_same_size(m, "masked mean")?;
    }
    let (s, n) = values
        .data()
        .par_iter()
        .enumerate()
        .filter(|(i, _)| mask.is_none_or(|m| m.data()[*i]))
        .map(|(_, &v)| (v as f64, 1usize))
        .reduce(|| (0.0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    Ok(if n == 0 { f64::NAN } else { s / n as f64 })
}

/// PSNR (dB, peak `data_range`) of the three channels of a linear RGB image separately.
pub fn psnr_channels(a: &Image<[f32; 3]>, b: &Image<[f32; 3]>, data_range: f32) -> Result<[f64; 3]> {
    check_rgb_pair(a, b, "psnr_channels")?;
    let (ca, cb) = (split_rgb(a), split_rgb(b));
    let mut out = [0.0; 3];
    for (o, (x, y)) in out.iter_mut().zip(ca.iter().zip(cb.iter())) {
        *o = psnr_from_mse(sum_sq_diff(x.data(), y.data()) / x.len() as f64, data_range)?;
    }
    Ok(out)
}

/// PSNR (dB) over the pixels where `mask` is set, all three channels (the mean of their squared
/// errors); `NaN` if the mask selects no pixel, `inf` if they agree there.
pub fn psnr_rgb_masked(a: &Image<[f32; 3]>, b: &Image<[f32; 3]>, mask: &Image<bool>, data_range: f32) -> Result<f64> {
    check_rgb_pair(a, b, "psnr_rgb_masked")?;
    a.check_same_size(mask, "psnr_rgb_masked mask")?;
    let (s, n) = a
        .data()
        .par_iter()
        .zip(b.data())
        .zip(mask.data())
        .filter(|(_, &m)| m)
        .map(|((x, y), _)| ((0..3).map(|c| (x[c] as f64 - y[c] as f64).powi(2)).sum::<f64>(), 3usize))
        .reduce(|| (0.0, 0), |p, q| (p.0 + q.0, p.1 + q.1));
    if n == 0 {
        return Ok(f64::NAN);
    }
    psnr_from_mse(s / n as f64, data_range)
}

/// Pixels per degree of visual angle FLIP assumes by default (a 0.7 m viewing distance from a
/// 0.7 m wide 4K monitor; Andersson et al. 2020).
#[cfg(feature = "flip")]
pub const FLIP_DEFAULT_PPD: f32 = nv_flip::DEFAULT_PIXELS_PER_DEGREE;

/// Result of [`flip`].
#[cfg(feature = "flip")]
#[derive(Clone, Debug)]
pub struct Flip {
    /// Mean FLIP error over the image, in `[0, 1]` (the single number the authors recommend).
    pub mean: f64,
    /// Per-pixel FLIP error in `[0, 1]`.
    pub map: Image<f32>,
}

/// NVIDIA FLIP (Andersson et al. 2020, "FLIP: A Difference Evaluator for Alternating Images",
/// LDR) of `test` against `reference`, both linear RGB: computed by the reference
/// implementation (crate `nv-flip`) on the 8-bit sRGB encoding of the two images, as the
/// reference tool compares PNG files. `ppd`: pixels per degree ([`FLIP_DEFAULT_PPD`]).
#[cfg(feature = "flip")]
pub fn flip(reference: &Image<[f32; 3]>, test: &Image<[f32; 3]>, ppd: f32) -> Result<Flip> {
    check_rgb_pair(reference, test, "flip")?;
    if !(ppd.is_finite() && ppd > 0.0) {
        return Err(Error::invalid(format!("flip: pixels per degree must be positive, got {ppd}")));
    }
    let to8 = |img: &Image<[f32; 3]>| -> Vec<u8> {
        img.data()
            .par_iter()
            .flat_map_iter(|c| c.map(|v| (zwarp_core::linear_to_srgb(v) * 255.0).round() as u8))
            .collect()
    };
    let (w, h) = reference.size();
    let r = nv_flip::FlipImageRgb8::with_data(w, h, &to8(reference));
    let t = nv_flip::FlipImageRgb8::with_data(w, h, &to8(test));
    let map = nv_flip::flip(r, t, ppd);
    let mean = nv_flip::FlipPool::from_image(&map).mean() as f64;
    Ok(Flip { mean, map: Image::from_vec(w, h, map.to_vec())? })
}

/// The colour-quality figures of one predicted frame against its reference (linear RGB, data
/// range 1): what `zwarp upsample`, `stereo` and `blur` report per row.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ColorQuality {
    /// PSNR (dB) over the three channels ([`crate::psnr_rgb`]).
    pub psnr: f64,
    /// PSNR (dB) of the luminance [`luminance`].
    pub psnr_y: f64,
    /// PSNR (dB) of R, G and B separately.
    pub psnr_channels: [f64; 3],
    /// Mean of the per-channel SSIMs ([`crate::ssim_rgb`]).
    pub ssim: f64,
    /// SSIM of the luminance.
    pub ssim_y: f64,
    /// Mean FLIP error (`NaN` without the `flip` feature).
    pub flip: f64,
    /// Mean CIE94 difference under D65.
    pub cie94: f64,
}

/// [`ColorQuality`] of `test` against `reference` (same size, at least 11x11 for SSIM).
pub fn color_quality(reference: &Image<[f32; 3]>, test: &Image<[f32; 3]>) -> Result<ColorQuality> {
    check_rgb_pair(reference, test, "color_quality")?;
    let ch = psnr_channels(reference, test, 1.0)?;
    let (ya, yb) = (luminance(reference), luminance(test));
    #[cfg(feature = "flip")]
    let flip_mean = flip(reference, test, FLIP_DEFAULT_PPD)?.mean;
    #[cfg(not(feature = "flip"))]
    let flip_mean = f64::NAN;
    Ok(ColorQuality {
        psnr: crate::psnr_rgb(reference, test, 1.0)?,
        psnr_y: crate::psnr(&ya, &yb, 1.0)?,
        psnr_channels: ch,
        ssim: crate::ssim_rgb(reference, test, 1.0)?,
        ssim_y: ssim(&ya, &yb, 1.0)?,
        flip: flip_mean,
        cie94: cie94_mean(reference, test, None)?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// colour-science's documented example of `delta_E_CIE1994` (graphic arts: 83.7792255).
    #[test]
    fn cie94_matches_the_published_example() {
        let a = [100.0, 21.57210357, 272.22819350];
        let b = [100.0, 426.67945353, 72.39590835];
        assert!((cie94(a, b) - 83.7792255).abs() < 1e-6, "{}", cie94(a, b));
        assert_eq!(cie94(a, a), 0.0);
    }

    #[test]
    fn lab_of_white_black_and_grey() {
        let w = linear_rgb_to_lab([1.0; 3]);
        assert!((w[0] - 100.0).abs() < 1e-3 && w[1].abs() < 0.01 && w[2].abs() < 0.01, "{w:?}");
        assert_eq!(linear_rgb_to_lab([0.0; 3])[0], 0.0);
        // Y = 0.18 -> L* = 116 * 0.18^(1/3) - 16 = 49.496.
        let g = linear_rgb_to_lab([0.18; 3]);
        assert!((g[0] - (116.0 * 0.18f64.cbrt() - 16.0)).abs() < 1e-3, "{g:?}");
    }

    #[test]
    fn uniform_images_have_analytic_metrics() {
        let a = Image::new(16, 16, [0.18f32; 3]);
        let b = Image::new(16, 16, [1.0f32; 3]);
        let e = cie94_mean(&a, &b, None).unwrap();
        // Neutral colours: only Delta L* counts.
        assert!((e - (100.0 - (116.0 * 0.18f64.cbrt() - 16.0))).abs() < 1e-2, "{e}");
        let mut mask = Image::new(16, 16, false);
        assert!(cie94_mean(&a, &b, Some(&mask)).unwrap().is_nan());
        *mask.get_mut(3, 3) = true;
        assert!((cie94_mean(&a, &b, Some(&mask)).unwrap() - e).abs() < 1e-4);
        let y = luminance(&b);
        assert!((y.get(0, 0) - 1.0).abs() < 1e-6);
        let ch = psnr_channels(&a, &b, 1.0).unwrap();
        let expect = 10.0 * (1.0 / (0.82f64 * 0.82)).log10();
        assert!(ch.iter().all(|p| (p - expect).abs() < 1e-4), "{ch:?}");
        let q = color_quality(&a, &a).unwrap();
        assert_eq!((q.psnr, q.ssim, q.cie94), (f64::INFINITY, 1.0, 0.0));
        assert!(psnr_rgb_masked(&a, &b, &mask, 1.0).unwrap() - expect < 1e-4);
        assert!(cie94_map(&a, &Image::new(3, 3, [0.0; 3])).is_err());
        let mut nan = a.clone();
        nan.get_mut(1, 1)[2] = f32::NAN;
        assert!(color_quality(&a, &nan).unwrap_err().to_string().contains("non-finite"));
    }

    /// LDR-FLIP of two uniform images from the paper's colour pipeline alone (for constant
    /// images the normalised CSF filters change nothing and the feature error is 0): CIELab,
    /// Hunt-adjusted (`a, b *= 0.01 L`), HyAB distance `|dL| + |(da, db)|`, raised to
    /// `q_c = 0.7` and mapped with `p_c = 0.4`, `p_t = 0.95` against the green-blue maximum.
    #[cfg(feature = "flip")]
    fn flip_uniform_expected(a: [f32; 3], b: [f32; 3]) -> f64 {
        let hunt = |c: [f32; 3]| {
            let l = linear_rgb_to_lab(c);
            [l[0], 0.01 * l[0] * l[1], 0.01 * l[0] * l[2]]
        };
        let hyab =
            |x: [f64; 3], y: [f64; 3]| (x[0] - y[0]).abs() + ((x[1] - y[1]).powi(2) + (x[2] - y[2]).powi(2)).sqrt();
        let cmax = hyab(hunt([0.0, 1.0, 0.0]), hunt([0.0, 0.0, 1.0])).powf(0.7);
        let d = hyab(hunt(a), hunt(b)).powf(0.7);
        let (pc, pt) = (0.4, 0.95);
        if d < pc * cmax {
            pt / (pc * cmax) * d
        } else {
            pt + (d - pc * cmax) / (cmax - pc * cmax) * (1.0 - pt)
        }
    }

    #[cfg(feature = "flip")]
    #[test]
    fn flip_of_identical_and_known_pairs() {
        let img =
            Image::from_fn(40, 30, |x, y| [(x % 7) as f32 / 7.0, (y % 5) as f32 / 5.0, ((x + y) % 3) as f32 / 3.0]);
        let f = flip(&img, &img, FLIP_DEFAULT_PPD).unwrap();
        assert_eq!(f.mean, 0.0);
        assert!(f.map.data().iter().all(|&v| v == 0.0));
        // Uniform pairs: the value of the paper's colour pipeline (8-bit inputs that encode the
        // colours exactly: 0, 1 and sRGB 188/255 grey).
        let grey = zwarp_core::srgb_to_linear(188.0 / 255.0);
        for (a, b) in [([0.0f32; 3], [1.0f32; 3]), ([grey; 3], [0.0; 3]), ([1.0, 0.0, 0.0], [0.0, 0.0, 1.0])] {
            let got = flip(&Image::new(32, 32, a), &Image::new(32, 32, b), FLIP_DEFAULT_PPD).unwrap().mean;
            let want = flip_uniform_expected(a, b);
            assert!((got - want).abs() < 2e-3, "{a:?} vs {b:?}: {got} vs {want}");
        }
        assert!(flip(&img, &img, 0.0).is_err());
    }
}
