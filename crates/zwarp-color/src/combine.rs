//! Two-frame interpolation (seed 001 Sec. 6: "perform the reprojection from multiple input
//! images such as in two frame interpolation to reduce the number of disoccluded pixels ...
//! allowing the depth buffer to enforce depth order"): a frame at time `t` between two rendered
//! frames is warped from both, and the two predictions are merged per pixel by their
//! confidence and depth.

use rayon::prelude::*;
use zwarp_core::{Camera, Error, Image, Result};

use crate::ColorWarpOutput;

/// Relative linear-depth difference below which two converged predictions of a pixel are the
/// same surface (and are blended by time).
pub const SAME_SURFACE: f32 = 0.05;

/// Merges `a` (warped from the earlier frame, `t` after it) and `b` (from the later frame,
/// `1 - t` before it), `t` in `[0, 1]`: where both converged on the same surface (linear depths
/// within [`SAME_SURFACE`], depth of `cam`'s near/far) they are blended with weights `1 - t`
/// and `t`; where both converged on different surfaces the nearer wins; where one converged it
/// is taken (the other frame saw what this one did not); where neither did, the frame nearer in
/// time (its in-painting). Residuals follow the choice (the larger of two blended).
pub fn combine_interpolated(a: &ColorWarpOutput, b: &ColorWarpOutput, t: f32, cam: &Camera) -> Result<ColorWarpOutput> {
    if !(0.0..=1.0).contains(&t) {
        return Err(Error::invalid(format!("interpolation time must be in [0, 1], got {t}")));
    }
    a.color.check_same_size(&b.color, "combine_interpolated")?;
    let mut out = a.clone();
    let (ta, tb) = (a.threshold, b.threshold);
    out.threshold = ta.max(tb);
    out.color
        .data_mut()
        .par_iter_mut()
        .zip(out.depth.data_mut().par_iter_mut())
        .zip(out.residual.data_mut().par_iter_mut())
        .enumerate()
        .for_each(|(i, ((c, d), r))| {
            let (ra, rb) = (a.residual.data()[i], b.residual.data()[i]);
            let (ca, cb) = (ra < ta, rb < tb);
            let (za, zb) = (a.depth.data()[i], b.depth.data()[i]);
            let pick_b = match (ca, cb) {
                (true, true) => {
                    let (la, lb) = (cam.linear_depth(za.min(1.0)), cam.linear_depth(zb.min(1.0)));
                    if (la - lb).abs() <= SAME_SURFACE * la.min(lb) {
                        let (x, y) = (a.color.data()[i], b.color.data()[i]);
                        *c = [0, 1, 2].map(|k| (1.0 - t) * x[k] + t * y[k]);
                        *d = za.min(zb);
                        *r = ra.max(rb);
                        return;
                    }
                    lb < la
                }
                (true, false) => false,
                (false, true) => true,
                (false, false) => t > 0.5,
            };
            if pick_b {
                (*c, *d, *r) = (b.color.data()[i], zb, rb);
            }
        });
    Ok(out)
}

/// Converts a residual image into a `[0, 1]` confidence weight: 1 where converged
/// (`residual < threshold`), falling linearly to 0 at `4 * threshold`, 0 where no sample was
/// found. A convenience for callers that blend a prediction with other data.
pub fn confidence_weights(out: &ColorWarpOutput) -> Image<f32> {
    let t = out.threshold;
    out.residual.map(|&r| if r < t { 1.0 } else { (1.0 - (r - t) / (3.0 * t)).clamp(0.0, 1.0) })
}
