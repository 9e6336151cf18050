//! Figure layout: panels side by side, as in the paper figures (seed 000 Fig. 1, 10, 11).

use zwarp_core::{Error, Image, Result};

/// Width in pixels of the gap between panels in [`side_by_side`].
pub const GAP: u32 = 4;
/// Colour of the gaps and of the padding below panels shorter than the tallest one (white, so
/// the black "empty" pixels of depth maps stay distinguishable from the frame).
pub const GAP_COLOR: [u8; 3] = [255, 255, 255];

/// Places `images` left to right, top-aligned, separated by [`GAP`] pixels of [`GAP_COLOR`].
/// The result is `sum(widths) + GAP * (n - 1)` wide and `max(heights)` tall; shorter panels are
/// padded below with [`GAP_COLOR`]. Errors on an empty list or a zero-size panel.
pub fn side_by_side(images: &[&Image<[u8; 3]>]) -> Result<Image<[u8; 3]>> {
    if images.is_empty() {
        return Err(Error::invalid("side_by_side: no images given"));
    }
    for (i, img) in images.iter().enumerate() {
        img.check_nonempty(&format!("side_by_side panel {i}"))?;
    }
    let width = images.iter().map(|i| i.width()).sum::<u32>() + GAP * (images.len() as u32 - 1);
    let height = images.iter().map(|i| i.height()).max().unwrap_or(0);
    let mut out = Image::new(width, height, GAP_COLOR);
    let mut x0 = 0u32;
    for img in images {
        for y in 0..img.height() {
            let w = img.width() as usize;
            let start = out.index(x0, y);
            out.data_mut()[start..start + w].copy_from_slice(img.row(y));
        }
        x0 += img.width() + GAP;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_gap_layout() {
        let a = Image::new(3, 2, [1u8, 0, 0]);
        let b = Image::new(2, 4, [0u8, 2, 0]);
        let c = Image::new(1, 1, [0u8, 0, 3]);
        let s = side_by_side(&[&a, &b, &c]).unwrap();
        assert_eq!(s.size(), (3 + 4 + 2 + 4 + 1, 4));
        let g = GAP_COLOR;
        #[rustfmt::skip]
        let expect_row = |y: u32| -> Vec<[u8; 3]> {
            let pa = if y < 2 { [1, 0, 0] } else { g };
            let pc = if y < 1 { [0, 0, 3] } else { g };
            vec![pa, pa, pa, g, g, g, g, [0, 2, 0], [0, 2, 0], g, g, g, g, pc]
        };
        for y in 0..4 {
            assert_eq!(s.row(y), expect_row(y).as_slice(), "row {y}");
        }
        // A single panel is returned unchanged.
        assert_eq!(side_by_side(&[&b]).unwrap(), b);
    }

    #[test]
    fn bad_input_is_an_error() {
        assert!(side_by_side(&[]).unwrap_err().to_string().contains("no images"));
        let z = Image::new(0, 3, [0u8; 3]);
        assert!(side_by_side(&[&z]).unwrap_err().to_string().contains("zero-size"));
    }
}
