//! Figure panels that read on their own: a label above, the colour-mapped buffer, its colour
//! bar with the range in metres below; and strips of such panels in one PNG (source | ours |
//! VFW | AFW | reference | error, seed 000 Fig. 1 / Fig. 10 style).

use zwarp_core::{Camera, Image, Result};

use crate::colormap::{depth_to_rgb8_scaled, diff_heatmap};
use crate::layout::{fit_width, labelled, side_by_side, stacked};
use crate::legend::{depth_colorbar, diff_colorbar};

/// Text scale of panel labels and colour-bar ticks: 8-pixel glyphs doubled on panels of at
/// least 400 pixels, single below (a label must fit its panel).
pub fn label_scale(panel_width: u32) -> u32 {
    if panel_width >= 400 {
        2
    } else {
        1
    }
}

/// A depth buffer as a labelled panel: turbo colours on linear view depth over `range`
/// (metres, nearest to farthest, log scale for wide ranges: [`depth_to_rgb8_scaled`]; use the
/// reference's range for a prediction and its reference),
/// reduced to at most `max_width` pixels, with its depth colour bar below.
pub fn depth_panel(
    label: &str,
    depth: &Image<f32>,
    cam: &Camera,
    range: (f32, f32),
    max_width: u32,
) -> Result<Image<[u8; 3]>> {
    let img = fit_width(&depth_to_rgb8_scaled(depth, cam, range), max_width)?;
    let s = label_scale(img.width());
    let bar = depth_colorbar(img.width(), s, range.0, range.1)?;
    labelled(&stacked(&[&img, &bar])?, label, s)
}

/// A signed difference `predicted - reference` as a labelled heat-map panel ([`diff_heatmap`]:
/// red = predicted nearer, blue = farther), saturating at `scale` in the buffers' units, which
/// is `scale_m` metres on the colour bar below.
pub fn diff_panel(
    label: &str,
    predicted: &Image<f32>,
    reference: &Image<f32>,
    scale: f32,
    scale_m: f32,
    max_width: u32,
) -> Result<Image<[u8; 3]>> {
    let img = fit_width(&diff_heatmap(predicted, reference, scale)?, max_width)?;
    let s = label_scale(img.width());
    let bar = diff_colorbar(img.width(), s, scale_m)?;
    labelled(&stacked(&[&img, &bar])?, label, s)
}

/// Panels left to right in one image ([`side_by_side`]).
pub fn strip(panels: &[Image<[u8; 3]>]) -> Result<Image<[u8; 3]>> {
    side_by_side(&panels.iter().collect::<Vec<_>>())
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn panels_have_label_image_and_bar() {
        let cam = Camera::perspective(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 1.0, 0.1, 100.0, 64, 32).unwrap();
        let depth = Image::new(64, 32, 0.9);
        let p = depth_panel("source", &depth, &cam, (1.0, 9.0), 32).unwrap();
        assert_eq!(p.width(), 32); // reduced by 2
        assert!(p.height() > 16 + 2 * 8); // label + image + bar
        let d = diff_panel("error", &depth, &depth, 0.05, 0.4, 64).unwrap();
        assert_eq!(d.width(), 64);
        let s = strip(&[p.clone(), d]).unwrap();
        assert_eq!(s.width(), 32 + crate::GAP + 64);
        assert!(strip(&[]).is_err());
        assert!(diff_panel("e", &depth, &Image::new(3, 3, 0.5), 0.05, 0.4, 64).is_err());
    }
}
