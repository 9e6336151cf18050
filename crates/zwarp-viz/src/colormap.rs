//! Colour maps from zwarp buffers to 8-bit RGB images for people to look at (the depth,
//! motion and difference panels of seed 000 Fig. 1 / Fig. 8 and seed 002 Fig. 8).

use rayon::prelude::*;
use zwarp_core::{is_surface, Camera, Error, Image, Motion, Result, NO_ITEM};

/// Google's Turbo colour map (Mikhailov 2019), polynomial approximation of the published
/// 256-entry table, for `x` in `[0, 1]` (clamped; NaN -> black). Low = blue-violet, high = dark
/// red. Returns display-referred (sRGB) bytes.
pub fn turbo(x: f32) -> [u8; 3] {
    if x.is_nan() {
        return [0, 0, 0];
    }
    const R4: [f64; 4] = [0.13572138, 4.61539260, -42.66032258, 132.13108234];
    const G4: [f64; 4] = [0.09140261, 2.19418839, 4.84296658, -14.18503333];
    const B4: [f64; 4] = [0.10667330, 12.64194608, -60.58204836, 110.36276771];
    const R2: [f64; 2] = [-152.94239396, 59.28637943];
    const G2: [f64; 2] = [4.27729857, 2.82956604];
    const B2: [f64; 2] = [-89.90310912, 27.34824973];
    let x = x.clamp(0.0, 1.0) as f64;
    let v4 = [1.0, x, x * x, x * x * x];
    let v2 = [v4[2] * v4[2], v4[3] * v4[2]];
    let ch = |c4: &[f64; 4], c2: &[f64; 2]| {
        let v = c4.iter().zip(&v4).map(|(c, v)| c * v).sum::<f64>() + c2[0] * v2[0] + c2[1] * v2[1];
        (v.clamp(0.0, 1.0) * 255.0).round() as u8
    };
    [ch(&R4, &R2), ch(&G4, &G2), ch(&B4, &B2)]
}

/// Lowest turbo coordinate used for surfaces in [`depth_to_rgb8`]: turbo's darkest 5 % is
/// skipped so the farthest surface (blue-violet) never looks like an empty (black) pixel.
pub const DEPTH_TURBO_MIN: f32 = 0.05;

/// The colour key of a stored depth: linear view depth with a camera, the stored value without.
#[inline]
fn depth_key(d: f32, cam: Option<&Camera>) -> f32 {
    cam.map_or(d, |c| c.linear_depth(d.max(0.0)))
}

/// Nearest and farthest surface of a depth buffer in the units [`depth_to_rgb8`] colours by:
/// linear view depth with a camera, stored depth without. Empty (`>= 1`) and non-finite pixels
/// are ignored; `None` when there is no surface. Pass the *reference* frame's range to
/// [`depth_to_rgb8_in_range`] to colour a prediction and its reference comparably.
pub fn depth_range(depth: &Image<f32>, cam: Option<&Camera>) -> Option<(f32, f32)> {
    let (lo, hi) = depth
        .data()
        .iter()
        .filter(|d| is_surface(**d) && d.is_finite())
        .map(|&d| depth_key(d, cam))
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
    (lo <= hi).then_some((lo, hi))
}

/// Depth buffer -> turbo colours: **nearest surface dark red, farthest surface blue-violet**,
/// empty pixels (stored depth `>= 1`, the paper's `s.z < 1` test fails) and NaN black.
///
/// With a camera the colours follow *linear* view depth (so equal colour steps are equal
/// distances; stored perspective depth crowds near 1, ARCHITECTURE.md "Conventions"); without
/// one they follow the stored value. The range is the image's own nearest..farthest surface
/// ([`depth_range`]); a buffer with a single depth maps every surface to the nearest colour. To
/// compare a warped buffer with its reference, use [`depth_to_rgb8_in_range`] with the
/// reference's range.
pub fn depth_to_rgb8(depth: &Image<f32>, cam: Option<&Camera>) -> Image<[u8; 3]> {
    let range = depth_range(depth, cam).unwrap_or((0.0, 0.0));
    depth_to_rgb8_in_range(depth, cam, range)
}

/// [`depth_to_rgb8`] with an explicit `(nearest, farthest)` range in the same units (linear
/// view depth with a camera, stored depth without): surfaces outside it clamp to the end
/// colours; a degenerate range (`farthest <= nearest`) maps every surface to the nearest colour.
pub fn depth_to_rgb8_in_range(depth: &Image<f32>, cam: Option<&Camera>, range: (f32, f32)) -> Image<[u8; 3]> {
    let (lo, hi) = range;
    let span = hi - lo;
    let data = depth
        .data()
        .par_iter()
        .map(|&d| {
            if !(is_surface(d) && d.is_finite()) {
                return [0, 0, 0];
            }
            let t = if span > 0.0 { ((depth_key(d, cam) - lo) / span).clamp(0.0, 1.0) } else { 0.0 };
            // t = 0 nearest -> top of turbo (red); t = 1 farthest -> DEPTH_TURBO_MIN.
            turbo(1.0 - t * (1.0 - DEPTH_TURBO_MIN))
        })
        .collect();
    Image::from_vec(depth.width(), depth.height(), data).expect("same size")
}

/// Depth spans wider than this ratio (farthest / nearest surface) read better on a logarithmic
/// scale: on a linear one a street or a court seen to the horizon is one colour near the camera.
pub const LOG_DEPTH_RATIO: f32 = 10.0;

/// Whether [`depth_to_rgb8_scaled`] colours `range` (linear view depth, metres) on a log scale.
pub fn depth_scale_is_log(range: (f32, f32)) -> bool {
    range.0 > 0.0 && range.1 > LOG_DEPTH_RATIO * range.0
}

/// [`depth_to_rgb8_in_range`] with a camera, on a logarithmic scale of linear view depth when
/// the range spans more than [`LOG_DEPTH_RATIO`] ([`depth_scale_is_log`]), so equal colour steps
/// are equal depth *ratios*; on the linear scale otherwise.
pub fn depth_to_rgb8_scaled(depth: &Image<f32>, cam: &Camera, range: (f32, f32)) -> Image<[u8; 3]> {
    if !depth_scale_is_log(range) {
        return depth_to_rgb8_in_range(depth, Some(cam), range);
    }
    let (lo, hi) = (range.0.ln(), range.1.ln());
    let data = depth
        .data()
        .par_iter()
        .map(|&d| {
            if !(is_surface(d) && d.is_finite()) {
                return [0, 0, 0];
            }
            let t = ((cam.linear_depth(d.max(0.0)).max(range.0).ln() - lo) / (hi - lo)).clamp(0.0, 1.0);
            turbo(1.0 - t * (1.0 - DEPTH_TURBO_MIN))
        })
        .collect();
    Image::from_vec(depth.width(), depth.height(), data).expect("same size")
}

/// Scalar map (e.g. `zwarp_metrics::ssim_map` SSIM maps, error magnitudes, iteration counts) ->
/// turbo colours, `lo` -> blue-violet end, `hi` -> red end, clamped; NaN black. Errors when
/// `lo`/`hi` are not finite or `hi <= lo`.
pub fn scalar_to_rgb8(values: &Image<f32>, lo: f32, hi: f32) -> Result<Image<[u8; 3]>> {
    if !(lo.is_finite() && hi.is_finite() && hi > lo) {
        return Err(Error::invalid(format!("scalar_to_rgb8: need finite lo < hi, got lo={lo} hi={hi}")));
    }
    let inv = 1.0 / (hi - lo);
    Ok(values.map(|&v| if v.is_nan() { [0, 0, 0] } else { turbo((v - lo) * inv) }))
}

/// Converts HSV (`h` in turns, `s`, `v` in `[0, 1]`) to 8-bit RGB.
fn hsv(h: f32, s: f32, v: f32) -> [u8; 3] {
    let h6 = (h.rem_euclid(1.0)) * 6.0;
    let c = |n: f32| {
        let k = (n + h6) % 6.0;
        let f = v - v * s * (k.min(4.0 - k).clamp(0.0, 1.0));
        (f * 255.0).round() as u8
    };
    [c(5.0), c(3.0), c(1.0)]
}

/// murmur3's 32-bit finalizer: decorrelates consecutive ids so neighbouring objects get
/// unrelated colours.
fn mix32(mut h: u32) -> u32 {
    h ^= h >> 16;
    h = h.wrapping_mul(0x85eb_ca6b);
    h ^= h >> 13;
    h = h.wrapping_mul(0xc2b2_ae35);
    h ^ (h >> 16)
}

/// Item buffer -> one hashed, never-black colour per object id (hue from the hash, saturation
/// 0.55-1, value 0.65-1); [`NO_ITEM`] (no object) is black. Deterministic across runs.
pub fn items_to_rgb8(items: &Image<u32>) -> Image<[u8; 3]> {
    items.map(|&id| {
        if id == NO_ITEM {
            return [0, 0, 0];
        }
        let h = mix32(id.wrapping_add(0x9e37_79b9));
        let hue = (h & 0xffff) as f32 / 65536.0;
        let sat = 0.55 + 0.45 * ((h >> 16) & 0xff) as f32 / 255.0;
        let val = 0.65 + 0.35 * (h >> 24) as f32 / 255.0;
        hsv(hue, sat, val)
    })
}

/// The Middlebury optical-flow colour wheel (Baker et al. 2011, `colorcode.cpp`): 55 colours,
/// red -> yellow -> green -> cyan -> blue -> magenta (segments 15, 6, 4, 11, 13, 6).
pub const FLOW_WHEEL: [[u8; 3]; 55] = flow_wheel();

const fn flow_wheel() -> [[u8; 3]; 55] {
    let mut w = [[0u8; 3]; 55];
    let segs = [15u32, 6, 4, 11, 13, 6];
    let mut k = 0;
    let mut s = 0;
    while s < 6 {
        let n = segs[s];
        let mut i = 0;
        while i < n {
            let up = (255 * i / n) as u8;
            let down = 255 - up;
            w[k] = match s {
                0 => [255, up, 0],   // red -> yellow
                1 => [down, 255, 0], // yellow -> green
                2 => [0, 255, up],   // green -> cyan
                3 => [0, down, 255], // cyan -> blue
                4 => [up, 0, 255],   // blue -> magenta
                _ => [255, 0, down], // magenta -> red
            };
            k += 1;
            i += 1;
        }
        s += 1;
    }
    w
}

/// Motion samples the motion field marks as invisible (behind the target eye, `1e9` pixels) or
/// corrupt are drawn black and excluded from the automatic scale.
const MOTION_INVALID: f32 = 1.0e8;

/// Motion buffer -> Middlebury flow colours (seed 000 Sec. 3.1 motion `v`, pixels): hue = the
/// direction of `v` (right red, down yellow, left cyan, up blue; row 0 is the top), saturation
/// = magnitude relative to `max` (zero motion white, `|v| = max` fully saturated, beyond `max`
/// darkened to 75 %, as Middlebury's `computeColor`).
///
/// `max = None` (or a non-positive / non-finite value) uses the largest valid magnitude in the
/// image. Samples with non-finite or `>= 1e8`-pixel motion (the motion field's "behind the
/// target eye" marker) are black. The target depth in [`Motion::depth`] is not shown; use
/// [`depth_to_rgb8`] on it.
pub fn motion_to_rgb8(motion: &Image<Motion>, max: Option<f32>) -> Image<[u8; 3]> {
    let valid = |m: &Motion| m.v.is_finite() && m.v.x.abs() < MOTION_INVALID && m.v.y.abs() < MOTION_INVALID;
    let max = match max {
        Some(m) if m.is_finite() && m > 0.0 => m,
        _ => motion.data().iter().filter(|m| valid(m)).map(|m| m.v.length()).fold(0.0f32, f32::max),
    };
    let n = FLOW_WHEEL.len();
    let data = motion
        .data()
        .par_iter()
        .map(|m| {
            if !valid(m) {
                return [0, 0, 0];
            }
            if max <= 0.0 {
                return [255, 255, 255];
            }
            let (u, v) = (m.v.x as f64 / max as f64, m.v.y as f64 / max as f64);
            let rad = (u * u + v * v).sqrt();
            let a = (-v).atan2(-u) / std::f64::consts::PI;
            let fk = (a + 1.0) / 2.0 * (n - 1) as f64;
            let k0 = (fk.floor() as usize).min(n - 1);
            let k1 = (k0 + 1) % n;
            let f = fk - k0 as f64;
            let mut out = [0u8; 3];
            for (c, o) in out.iter_mut().enumerate() {
                let col = (1.0 - f) * FLOW_WHEEL[k0][c] as f64 / 255.0 + f * FLOW_WHEEL[k1][c] as f64 / 255.0;
                let col = if rad <= 1.0 { 1.0 - rad * (1.0 - col) } else { col * 0.75 };
                *o = (255.0 * col).floor().clamp(0.0, 255.0) as u8;
            }
            out
        })
        .collect();
    Image::from_vec(motion.width(), motion.height(), data).expect("same size")
}

/// Linear-light value -> 8-bit sRGB (IEC 61966-2-1 transfer curve, the one
/// [`zwarp_core::linear_to_srgb`]), clamped to `[0, 1]`; NaN -> 0.
pub fn linear_to_srgb8(v: f32) -> u8 {
    (zwarp_core::linear_to_srgb(v) * 255.0).round() as u8
}

/// Linear RGB colour buffer (the renderer's / colour warp's output, seed 001) -> 8-bit sRGB.
pub fn color_to_rgb8(color: &Image<[f32; 3]>) -> Image<[u8; 3]> {
    color.map(|c| [linear_to_srgb8(c[0]), linear_to_srgb8(c[1]), linear_to_srgb8(c[2])])
}

/// Signed difference heat map of `predicted - reference` (depth: 0 = near), the culling-safety
/// view of seed 002 Sec. V.1 / Fig. 8: **red = predicted nearer** (unsafe for culling),
/// **blue = predicted farther** (safe over-estimation, e.g. far-plane hole fills), black =
/// equal. Intensity is `|difference| / scale`, saturating at `scale`. Pixels where either
/// value is NaN/infinite are magenta.
///
/// Errors on a size mismatch or a non-positive / non-finite `scale`.
pub fn diff_heatmap(predicted: &Image<f32>, reference: &Image<f32>, scale: f32) -> Result<Image<[u8; 3]>> {
    predicted.check_same_size(reference, "diff_heatmap")?;
    if !(scale.is_finite() && scale > 0.0) {
        return Err(Error::invalid(format!("diff_heatmap: scale must be finite and > 0, got {scale}")));
    }
    let data = predicted
        .data()
        .par_iter()
        .zip(reference.data().par_iter())
        .map(|(&p, &r)| {
            let d = p - r;
            if !d.is_finite() {
                return [255, 0, 255];
            }
            heat_color(d / scale)
        })
        .collect();
    Image::from_vec(predicted.width(), predicted.height(), data)
}

/// The colour of [`diff_heatmap`] for a difference of `v` full scales: red for `v < 0`
/// (predicted nearer), blue for `v > 0`, intensity `|v|` saturating at 1, black at 0.
pub fn heat_color(v: f32) -> [u8; 3] {
    let i = (v.abs().min(1.0) * 255.0).round() as u8;
    if v < 0.0 {
        [i, 0, 0]
    } else {
        [0, 0, i]
    }
}

/// Boolean mask (e.g. non-converged pixels, culled objects' footprints) -> white where
/// `true`, black where `false`.
pub fn mask_to_rgb8(mask: &Image<bool>) -> Image<[u8; 3]> {
    mask.map(|&m| if m { [255; 3] } else { [0; 3] })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Vec2, Vec3};

    #[test]
    fn turbo_endpoints() {
        // Values of the published polynomial at 0, 0.5 and 1.
        assert_eq!(turbo(0.0), [35, 23, 27]);
        assert_eq!(turbo(1.0), [144, 13, 0]);
        assert_eq!(turbo(-3.0), turbo(0.0));
        assert_eq!(turbo(7.0), turbo(1.0));
        assert_eq!(turbo(f32::NAN), [0, 0, 0]);
        let mid = turbo(0.5);
        assert!(mid[1] > 200 && mid[0] < 200 && mid[2] < 150, "turbo middle is green-yellow: {mid:?}");
    }

    #[test]
    fn depth_colours_follow_linear_depth() {
        let cam = Camera::perspective(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 1.0, 0.1, 100.0, 4, 1).unwrap();
        let d: Vec<f32> = [2.0f32, 3.0, 4.0].iter().map(|&l| cam.stored_depth(l)).chain([1.0]).collect();
        let depth = Image::from_vec(4, 1, d).unwrap();
        let img = depth_to_rgb8(&depth, Some(&cam));
        assert_eq!(img.data()[0], turbo(1.0), "nearest surface = top of turbo");
        assert_eq!(img.data()[2], turbo(DEPTH_TURBO_MIN), "farthest surface");
        assert_eq!(img.data()[3], [0, 0, 0], "empty pixel");
        // 3 m is halfway in linear depth.
        assert_eq!(img.data()[1], turbo(1.0 - 0.5 * (1.0 - DEPTH_TURBO_MIN)));
        assert_ne!(turbo(DEPTH_TURBO_MIN), [0, 0, 0]);
        // Without a camera the stored value is used: 3 m is then far from halfway.
        let raw = depth_to_rgb8(&depth, None);
        assert_eq!(raw.data()[0], turbo(1.0));
        assert_ne!(raw.data()[1], img.data()[1]);
        // All-empty and single-depth buffers.
        assert!(depth_to_rgb8(&Image::new(3, 2, 1.0), None).data().iter().all(|p| *p == [0, 0, 0]));
        assert!(depth_to_rgb8(&Image::new(3, 2, 0.5), None).data().iter().all(|p| *p == turbo(1.0)));
        // An explicit (reference) range: a prediction with only the 3 m and 4 m surfaces keeps
        // the reference's colours instead of stretching to its own range.
        let range = depth_range(&depth, Some(&cam)).unwrap();
        assert!((range.0 - 2.0).abs() < 1e-3 && (range.1 - 4.0).abs() < 1e-3);
        let pred = Image::from_vec(2, 1, vec![depth.data()[1], depth.data()[2]]).unwrap();
        let same = depth_to_rgb8_in_range(&pred, Some(&cam), range);
        assert_eq!(same.data(), &img.data()[1..3]);
        assert_ne!(depth_to_rgb8(&pred, Some(&cam)).data()[0], img.data()[1]);
        assert_eq!(depth_range(&Image::new(2, 2, 1.0), None), None);
    }

    #[test]
    fn item_colours() {
        let items = Image::from_fn(64, 16, |x, y| if x == 0 { NO_ITEM } else { y * 64 + x });
        let img = items_to_rgb8(&items);
        for y in 0..16 {
            assert_eq!(*img.get(0, y), [0, 0, 0]);
            for x in 1..64 {
                let p = *img.get(x, y);
                assert!(p.iter().any(|&c| c >= 165), "never dark: id {} -> {p:?}", y * 64 + x);
                if x > 1 {
                    assert_ne!(p, *img.get(x - 1, y), "neighbouring ids differ");
                }
            }
        }
        assert_eq!(items_to_rgb8(&items), img, "deterministic");
    }

    #[test]
    fn flow_wheel_matches_middlebury() {
        assert_eq!(FLOW_WHEEL[0], [255, 0, 0]);
        assert_eq!(FLOW_WHEEL[15], [255, 255, 0]);
        assert_eq!(FLOW_WHEEL[21], [0, 255, 0]);
        assert_eq!(FLOW_WHEEL[25], [0, 255, 255]);
        assert_eq!(FLOW_WHEEL[36], [0, 0, 255]);
        assert_eq!(FLOW_WHEEL[49], [255, 0, 255]);
        assert_eq!(FLOW_WHEEL[54], [255, 0, 43]);
    }

    #[test]
    fn motion_colours() {
        let m = |x: f32, y: f32| Motion { v: Vec2::new(x, y), depth: 0.5 };
        let buf = Image::from_vec(
            6,
            1,
            vec![m(0.0, 0.0), m(2.0, 0.0), m(0.0, 2.0), m(0.0, 4.0), m(1e9, 1e9), m(f32::NAN, 0.0)],
        )
        .unwrap();
        let img = motion_to_rgb8(&buf, Some(2.0));
        assert_eq!(img.data()[0], [255, 255, 255], "zero motion is white");
        assert_eq!(img.data()[1], [255, 0, 0], "rightward at full scale is red");
        // Downward: fk = 13.5, halfway between wheel[13] = (255, 221, 0) and wheel[14] = (255, 238, 0).
        assert_eq!(img.data()[2], [255, 229, 0]);
        // Beyond max: same hue, 75 %.
        assert_eq!(img.data()[3], [191, 172, 0]);
        assert_eq!(img.data()[4], [0, 0, 0], "behind-the-eye marker");
        assert_eq!(img.data()[5], [0, 0, 0]);
        // Automatic scale = largest valid magnitude (4): the downward 4-pixel motion saturates.
        let auto = motion_to_rgb8(&buf, None);
        assert_eq!(auto.data()[3], [255, 229, 0]);
        assert_eq!(motion_to_rgb8(&buf, Some(-1.0)), auto);
        // Half magnitude: half saturation.
        let half = motion_to_rgb8(&buf, Some(4.0));
        assert_eq!(half.data()[1], [255, 127, 127]);
        // All-zero motion stays white.
        assert!(motion_to_rgb8(&Image::new(2, 2, m(0.0, 0.0)), None).data().iter().all(|p| *p == [255; 3]));
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]
        #[test]
        fn motion_saturation_grows_with_magnitude(angle in 0.0f32..std::f32::consts::TAU) {
            // Along one direction, the whitest channel darkens monotonically up to |v| = max,
            // where the colour is fully saturated (every wheel entry has a 255 channel and
            // neighbours share it).
            let dir = Vec2::new(angle.cos(), angle.sin());
            let samples: Vec<Motion> = (0..=10).map(|i| Motion { v: dir * (i as f32 / 10.0), depth: 0.5 }).collect();
            // max slightly above 1: f32 rounding of dir * 1.0 may exceed 1 and trip the "beyond
            // max" darkening.
            let img = motion_to_rgb8(&Image::from_vec(11, 1, samples).unwrap(), Some(1.0001));
            let mins: Vec<u8> = img.data().iter().map(|p| *p.iter().min().unwrap()).collect();
            proptest::prop_assert!(mins.windows(2).all(|w| w[1] <= w[0]), "{:?}", mins);
            let full = img.data()[10];
            proptest::prop_assert!(*full.iter().max().unwrap() >= 254, "{:?}", full);
            proptest::prop_assert_eq!(img.data()[0], [255, 255, 255]);
        }
    }

    #[test]
    fn srgb_transfer() {
        assert_eq!(linear_to_srgb8(0.0), 0);
        assert_eq!(linear_to_srgb8(1.0), 255);
        assert_eq!(linear_to_srgb8(0.5), 188);
        assert_eq!(linear_to_srgb8(0.0031308), 10);
        assert_eq!(linear_to_srgb8(2.0), 255);
        assert_eq!(linear_to_srgb8(-1.0), 0);
        assert_eq!(linear_to_srgb8(f32::NAN), 0);
        let c = Image::new(1, 1, [0.0f32, 0.5, 1.0]);
        assert_eq!(color_to_rgb8(&c).data()[0], [0, 188, 255]);
    }

    #[test]
    fn diff_heatmap_signs() {
        let reference = Image::from_vec(5, 1, vec![0.5f32, 0.5, 0.5, 0.5, 0.5]).unwrap();
        let predicted = Image::from_vec(5, 1, vec![0.5f32, 0.375, 0.75, 0.0, f32::NAN]).unwrap();
        let h = diff_heatmap(&predicted, &reference, 0.25).unwrap();
        assert_eq!(h.data()[0], [0, 0, 0], "equal is black");
        assert_eq!(h.data()[1], [128, 0, 0], "nearer (unsafe) is red, half intensity");
        assert_eq!(h.data()[2], [0, 0, 255], "farther (safe) is blue, saturated");
        assert_eq!(h.data()[3], [255, 0, 0]);
        assert_eq!(h.data()[4], [255, 0, 255]);
        assert!(diff_heatmap(&predicted, &Image::new(4, 1, 0.0), 1.0).unwrap_err().to_string().contains("size"));
        assert!(diff_heatmap(&predicted, &reference, 0.0).unwrap_err().to_string().contains("scale"));
    }

    #[test]
    fn scalar_map() {
        let v = Image::from_vec(4, 1, vec![-1.0f32, 1.0, 0.0, f32::NAN]).unwrap();
        let img = scalar_to_rgb8(&v, -1.0, 1.0).unwrap();
        assert_eq!(img.data(), &[turbo(0.0), turbo(1.0), turbo(0.5), [0, 0, 0]]);
        assert!(scalar_to_rgb8(&v, 1.0, 1.0).is_err());
        assert!(scalar_to_rgb8(&v, 0.0, f32::INFINITY).is_err());
    }

    #[test]
    fn mask_colours() {
        let m = Image::from_vec(2, 1, vec![true, false]).unwrap();
        assert_eq!(mask_to_rgb8(&m).data(), &[[255; 3], [0; 3]]);
    }
}
