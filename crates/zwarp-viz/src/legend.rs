//! Legends that make a colour-mapped panel readable on its own: a colour bar with its range in
//! the buffer's units (metres of linear view depth, depth error in metres), drawn below the
//! panel it explains (report figures, seed 000 Fig. 1 / Fig. 8 style strips).

use zwarp_core::{Error, Image, Result};

use crate::colormap::{depth_scale_is_log, heat_color, turbo, DEPTH_TURBO_MIN};
use crate::text::{draw_text, text_size, GLYPH};

/// Height in pixels of the gradient in a colour bar (at text scale 1).
const BAR: u32 = 10;
/// Margin around the gradient and between it and the tick labels (at text scale 1).
const PAD: u32 = 3;

/// A colour bar `width` pixels wide: the gradient `color(t)` for `t` from 0 (left) to 1 (right),
/// and below it the `ticks` `(t, label)`, each label centred on its position and kept inside the
/// bar; black text on white. `scale` multiplies the font and the bar height (1 = 8-pixel text).
/// Errors on a zero width or a tick outside `[0, 1]`.
pub fn colorbar(
    width: u32,
    scale: u32,
    color: impl Fn(f32) -> [u8; 3],
    ticks: &[(f32, String)],
) -> Result<Image<[u8; 3]>> {
    if width == 0 {
        return Err(Error::invalid("colorbar: width must be positive"));
    }
    if let Some((t, _)) = ticks.iter().find(|(t, _)| !(0.0..=1.0).contains(t)) {
        return Err(Error::invalid(format!("colorbar: tick position {t} is outside [0, 1]")));
    }
    let s = scale.max(1);
    let (bar, pad) = (BAR * s, PAD * s);
    let height = pad + bar + pad + GLYPH * s + pad;
    let mut img = Image::new(width, height, [255u8; 3]);
    let inner = width.saturating_sub(2 * pad).max(1);
    for x in 0..inner {
        let c = color(if inner > 1 { x as f32 / (inner - 1) as f32 } else { 0.0 });
        for y in pad..pad + bar {
            if pad + x < width {
                *img.get_mut(pad + x, y) = c;
            }
        }
    }
    for (t, label) in ticks {
        let cx = pad as i64 + (t * (inner - 1) as f32).round() as i64;
        for y in pad + bar..pad + bar + pad {
            if (cx as u32) < width {
                *img.get_mut(cx as u32, y) = [0; 3];
            }
        }
        let (tw, _) = text_size(label, s);
        // Inside the bar's margins, so labels of panels side by side never touch.
        let x = (cx - tw as i64 / 2).clamp(pad as i64, (width as i64 - pad as i64 - tw as i64).max(pad as i64));
        draw_text(&mut img, x, (pad + bar + pad) as i64, label, s, [0; 3]);
    }
    Ok(img)
}

/// A metre value with a precision that suits its magnitude (`0.012 m`, `3.4 m`, `120 m`).
pub fn metres(v: f32) -> String {
    let a = v.abs();
    if a >= 100.0 {
        format!("{v:.0} m")
    } else if a >= 10.0 || a == 0.0 {
        format!("{v:.1} m")
    } else if a >= 0.1 {
        format!("{v:.2} m")
    } else {
        format!("{v:.3} m")
    }
}

/// The colour bar of [`depth_to_rgb8_scaled`](crate::depth_to_rgb8_scaled): nearest surface
/// `near` metres (left, dark red) to farthest `far` (right, blue-violet), the two ends and the
/// middle labelled in metres; the middle is the geometric mean on the log scale the map uses for
/// wide ranges ([`depth_scale_is_log`]). Errors on a non-finite range.
pub fn depth_colorbar(width: u32, scale: u32, near: f32, far: f32) -> Result<Image<[u8; 3]>> {
    if !(near.is_finite() && far.is_finite()) {
        return Err(Error::invalid(format!("depth_colorbar: range must be finite, got {near}..{far}")));
    }
    let mid = if depth_scale_is_log((near, far)) { (near * far).sqrt() } else { 0.5 * (near + far) };
    let ticks = [(0.0, metres(near)), (0.5, metres(mid)), (1.0, metres(far))];
    colorbar(width, scale, |t| turbo(1.0 - t * (1.0 - DEPTH_TURBO_MIN)), &ticks)
}

/// The colour bar of [`diff_heatmap`](crate::diff_heatmap) for a difference shown in metres:
/// `-full_scale_m` (left, red: predicted nearer) through 0 (black) to `+full_scale_m` (right,
/// blue: predicted farther), where the heat map saturates. Errors on a non-positive scale.
pub fn diff_colorbar(width: u32, scale: u32, full_scale_m: f32) -> Result<Image<[u8; 3]>> {
    if !(full_scale_m.is_finite() && full_scale_m > 0.0) {
        return Err(Error::invalid(format!("diff_colorbar: scale must be finite and > 0, got {full_scale_m}")));
    }
    let ticks = [(0.0, metres(-full_scale_m)), (0.5, "0".to_string()), (1.0, format!("+{}", metres(full_scale_m)))];
    colorbar(width, scale, |t| heat_color(2.0 * t - 1.0), &ticks)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gradient_ends_and_ticks() {
        let bar = depth_colorbar(200, 1, 1.5, 40.0).unwrap();
        assert_eq!(bar.width(), 200);
        assert_eq!(bar.height(), PAD + BAR + PAD + GLYPH + PAD);
        let y = PAD + BAR / 2;
        // Left end = nearest colour of the depth map, right end = farthest.
        assert_eq!(*bar.get(PAD, y), turbo(1.0));
        assert_eq!(*bar.get(200 - PAD - 1, y), turbo(DEPTH_TURBO_MIN));
        // Labels are drawn (black pixels in the text row).
        let text_rows = PAD + BAR + PAD..bar.height();
        assert!(text_rows.clone().any(|y| (0..200).any(|x| *bar.get(x, y) == [0; 3])));
        let d = diff_colorbar(101, 1, 0.25).unwrap();
        assert_eq!(*d.get(PAD, y), heat_color(-1.0));
        assert_eq!(*d.get(101 - PAD - 1, y), heat_color(1.0));
        assert_eq!(heat_color(0.0), [0, 0, 0]);
    }

    #[test]
    fn labels_in_metres() {
        assert_eq!(metres(0.0123), "0.012 m");
        assert_eq!(metres(3.456), "3.46 m");
        assert_eq!(metres(42.0), "42.0 m");
        assert_eq!(metres(1234.0), "1234 m");
    }

    #[test]
    fn bad_input_is_an_error() {
        assert!(colorbar(0, 1, |_| [0; 3], &[]).is_err());
        assert!(colorbar(10, 1, |_| [0; 3], &[(1.5, "x".into())]).unwrap_err().to_string().contains("outside"));
        assert!(depth_colorbar(10, 1, f32::NAN, 1.0).is_err());
        assert!(diff_colorbar(10, 1, 0.0).is_err());
    }
}
