//! The quality comparisons of a prediction against the view rendered directly (ARCHITECTURE.md
//! "Evaluation protocol"): one function per kind of image, and the mean of each over the frames
//! of a row.

use anyhow::Result;
use serde::Serialize;
use zwarp_core::{Camera, Image};
use zwarp_warp::PixelState;

use crate::output::ser_f64;

/// Quality of one predicted colour image (JSON fields of every colour row, means over the
/// frames).
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct Quality {
    /// PSNR (dB) on linear RGB, all channels.
    #[serde(serialize_with = "ser_f64")]
    pub psnr: f64,
    /// PSNR (dB) of the luminance.
    #[serde(serialize_with = "ser_f64")]
    pub psnr_y: f64,
    /// PSNR (dB) of R, G, B.
    pub psnr_rgb: [f64; 3],
    /// Mean per-channel SSIM on linear RGB.
    pub ssim: f64,
    /// SSIM of the luminance.
    pub ssim_y: f64,
    /// Mean FLIP error (LDR, sRGB encoding of the linear colour).
    pub flip: f64,
    /// Mean CIE94 difference under D65 (seed 001 Fig. 8).
    pub cie94: f64,
    /// Fraction of pixels the method reports converged (its confidence output).
    pub converged: f64,
    /// Fraction of target pixels the source did not see (disocclusions, border strips).
    pub disocc_fraction: f64,
    /// PSNR (dB) over those pixels.
    #[serde(serialize_with = "ser_f64")]
    pub disocc_psnr: f64,
    /// Mean CIE94 over those pixels.
    #[serde(serialize_with = "ser_f64")]
    pub disocc_cie94: f64,
    /// Mean FLIP over those pixels.
    #[serde(serialize_with = "ser_f64")]
    pub disocc_flip: f64,
}

/// Which figures [`compare_color`] computes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Figures {
    /// What every colour row reports: PSNR, SSIM and FLIP, and over the unseen pixels their
    /// share and PSNR; the others are NaN (not computed: CIE94 and the second SSIM cost time).
    Headline,
    /// Every field of [`Quality`].
    All,
}

/// The quality of the colour `pred` against the rendered `reference`; `converged` is the
/// method's own confidence (a fraction of its pixels, carried into the row as it is) and
/// `unseen` marks the pixels the source did not see (their figures are NaN without it).
pub fn compare_color(
    reference: &Image<[f32; 3]>,
    pred: &Image<[f32; 3]>,
    converged: f64,
    unseen: Option<&Image<bool>>,
    figures: Figures,
) -> Result<Quality> {
    use zwarp_metrics as zm;
    let all = figures == Figures::All;
    // `zm::color_quality`'s figures, FLIP computed once for its mean and, over the unseen
    // pixels, its map (it costs more than all the other figures together).
    let flip = zm::flip(reference, pred, zm::FLIP_DEFAULT_PPD)?;
    let lum = all.then(|| (zm::luminance(reference), zm::luminance(pred)));
    let mut q = Quality {
        psnr: zm::psnr_rgb(reference, pred, 1.0)?,
        psnr_y: f64::NAN,
        psnr_rgb: [f64::NAN; 3],
        ssim: zm::ssim_rgb(reference, pred, 1.0)?,
        ssim_y: f64::NAN,
        flip: flip.mean,
        cie94: f64::NAN,
        converged,
        disocc_fraction: 0.0,
        disocc_psnr: f64::NAN,
        disocc_cie94: f64::NAN,
        disocc_flip: f64::NAN,
    };
    if let Some((ya, yb)) = &lum {
        q.psnr_y = zm::psnr(ya, yb, 1.0)?;
        q.psnr_rgb = zm::psnr_channels(reference, pred, 1.0)?;
        q.ssim_y = zm::ssim(ya, yb, 1.0)?;
        q.cie94 = zm::cie94_mean(reference, pred, None)?;
    }
    if let Some(m) = unseen {
        q.disocc_fraction = m.data().iter().filter(|&&v| v).count() as f64 / m.len() as f64;
        q.disocc_psnr = zm::psnr_rgb_masked(reference, pred, m, 1.0)?;
        if all {
            q.disocc_cie94 = zm::cie94_mean(reference, pred, Some(m))?;
            q.disocc_flip = zm::masked_mean(&flip.map, Some(m))?;
        }
    }
    Ok(q)
}

/// Mean of finite values (NaN if none); infinities count as such when all are infinite.
pub fn mean_finite(v: &[f64]) -> f64 {
    let finite: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if finite.is_empty() {
        return v.first().copied().unwrap_or(f64::NAN);
    }
    finite.iter().sum::<f64>() / finite.len() as f64
}

/// Mean of several [`Quality`] values, field by field ([`mean_finite`]).
pub fn mean_quality(qs: &[Quality]) -> Quality {
    let m = |f: &dyn Fn(&Quality) -> f64| mean_finite(&qs.iter().map(f).collect::<Vec<_>>());
    Quality {
        psnr: m(&|q| q.psnr),
        psnr_y: m(&|q| q.psnr_y),
        psnr_rgb: [m(&|q| q.psnr_rgb[0]), m(&|q| q.psnr_rgb[1]), m(&|q| q.psnr_rgb[2])],
        ssim: m(&|q| q.ssim),
        ssim_y: m(&|q| q.ssim_y),
        flip: m(&|q| q.flip),
        cie94: m(&|q| q.cie94),
        converged: m(&|q| q.converged),
        disocc_fraction: m(&|q| q.disocc_fraction),
        disocc_psnr: m(&|q| q.disocc_psnr),
        disocc_cie94: m(&|q| q.disocc_cie94),
        disocc_flip: m(&|q| q.disocc_flip),
    }
}

/// Quality of one predicted depth buffer (`zwarp eval`'s figures).
#[derive(Clone, Copy, Debug, Default)]
pub struct DepthComparison {
    /// PSNR (dB) on linear depth normalised by the reference's surface range.
    pub psnr: f64,
    /// SSIM on the same normalised linear depth.
    pub ssim: f64,
    /// PSNR on the stored `[0,1]` buffer.
    pub psnr_buffer: f64,
    /// SSIM on the stored `[0,1]` buffer.
    pub ssim_buffer: f64,
    /// Fraction of the reference's surface pixels where the prediction holds a depth (and,
    /// with per-pixel states, the search converged).
    pub converged: f64,
    /// [`DepthComparison::converged`] over the surface pixels the source view saw.
    pub converged_seen: f64,
}

/// The quality of the depth `pred` (with its per-pixel `states` for a search, `None` for a
/// forward warp) against the `reference` rendered by `cam`; `seen` marks the target pixels
/// whose surface the source view saw.
pub fn compare_depth(
    pred: &Image<f32>,
    states: Option<&Image<PixelState>>,
    reference: &Image<f32>,
    cam: &Camera,
    seen: &Image<bool>,
) -> Result<DepthComparison> {
    let q = zwarp_metrics::depth_quality(pred, reference, cam)?;
    Ok(DepthComparison {
        psnr: q.psnr,
        ssim: q.ssim,
        psnr_buffer: q.psnr_buffer,
        ssim_buffer: q.ssim_buffer,
        converged: coverage(pred, reference, states, None),
        converged_seen: coverage(pred, reference, states, Some(seen)),
    })
}

/// Mean of several [`DepthComparison`] values, field by field: a plain mean, so one identical
/// frame (infinite PSNR) makes the mean infinite, and no frames make it NaN.
pub fn mean_depth(qs: &[DepthComparison]) -> DepthComparison {
    let m = |f: &dyn Fn(&DepthComparison) -> f64| {
        if qs.is_empty() {
            f64::NAN
        } else {
            qs.iter().map(f).sum::<f64>() / qs.len() as f64
        }
    };
    DepthComparison {
        psnr: m(&|q| q.psnr),
        ssim: m(&|q| q.ssim),
        psnr_buffer: m(&|q| q.psnr_buffer),
        ssim_buffer: m(&|q| q.ssim_buffer),
        converged: m(&|q| q.converged),
        converged_seen: m(&|q| q.converged_seen),
    }
}

/// Fraction of the reference's surface pixels where `predicted` holds a surface (and, with
/// `states`, the search converged); with `seen`, only over the pixels it marks.
fn coverage(
    predicted: &Image<f32>,
    reference: &Image<f32>,
    states: Option<&Image<PixelState>>,
    seen: Option<&Image<bool>>,
) -> f64 {
    let mut surf = 0usize;
    let mut hit = 0usize;
    for (i, (&p, &r)) in predicted.data().iter().zip(reference.data()).enumerate() {
        if r < 1.0 && seen.is_none_or(|s| s.data()[i]) {
            surf += 1;
            let ok = match states {
                Some(s) => s.data()[i] == PixelState::Converged,
                None => p < 1.0,
            };
            hit += ok as usize;
        }
    }
    if surf == 0 {
        1.0
    } else {
        hit as f64 / surf as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finite_mean_skips_infinities_unless_all_are() {
        assert_eq!(mean_finite(&[1.0, f64::INFINITY, 3.0]), 2.0);
        assert_eq!(mean_finite(&[f64::INFINITY, f64::INFINITY]), f64::INFINITY);
        assert!(mean_finite(&[]).is_nan());
    }

    #[test]
    fn depth_mean_is_plain() {
        let a = DepthComparison { psnr: 10.0, converged: 0.5, ..Default::default() };
        let b = DepthComparison { psnr: f64::INFINITY, converged: 1.0, ..Default::default() };
        let m = mean_depth(&[a, b]);
        assert_eq!((m.psnr, m.converged), (f64::INFINITY, 0.75));
        assert!(mean_depth(&[]).ssim.is_nan());
    }

    #[test]
    fn coverage_counts_the_reference_surfaces() {
        let reference = Image::from_vec(4, 1, vec![0.5, 0.5, 0.5, 1.0]).unwrap();
        let pred = Image::from_vec(4, 1, vec![0.5, 1.0, 0.4, 0.3]).unwrap();
        assert_eq!(coverage(&pred, &reference, None, None), 2.0 / 3.0);
        let seen = Image::from_vec(4, 1, vec![true, false, false, true]).unwrap();
        assert_eq!(coverage(&pred, &reference, None, Some(&seen)), 1.0);
        let states = Image::new(4, 1, PixelState::Hole);
        assert_eq!(coverage(&pred, &reference, Some(&states), None), 0.0);
    }

    #[test]
    fn identical_colour_is_perfect() {
        let img = Image::from_fn(16, 16, |x, y| [x as f32 / 16.0, y as f32 / 16.0, 0.5]);
        let mut unseen = Image::new(16, 16, false);
        *unseen.get_mut(2, 3) = true;
        let q = compare_color(&img, &img, 0.9, Some(&unseen), Figures::All).unwrap();
        assert_eq!((q.psnr, q.ssim, q.converged, q.disocc_fraction), (f64::INFINITY, 1.0, 0.9, 1.0 / 256.0));
        assert_eq!((q.cie94, q.disocc_cie94, q.ssim_y), (0.0, 0.0, 1.0));
        assert!(compare_color(&img, &img, 1.0, None, Figures::All).unwrap().disocc_psnr.is_nan());
        let headline = compare_color(&img, &img, 1.0, Some(&unseen), Figures::Headline).unwrap();
        assert_eq!((headline.psnr, headline.disocc_fraction), (f64::INFINITY, 1.0 / 256.0));
        assert!(headline.cie94.is_nan() && headline.disocc_flip.is_nan());
    }
}
