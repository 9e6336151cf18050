//! Figure layout: panels side by side, as in the paper figures (seed 000 Fig. 1, 10, 11).

use zwarp_core::{Error, Image, Result};

use crate::text::{draw_text, GLYPH};

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

/// Places `images` top to bottom, left-aligned, with no gap (a panel and its legend); narrower
/// images are padded on the right with [`GAP_COLOR`]. Errors on an empty list or a zero-size
/// image.
pub fn stacked(images: &[&Image<[u8; 3]>]) -> Result<Image<[u8; 3]>> {
    if images.is_empty() {
        return Err(Error::invalid("stacked: no images given"));
    }
    for (i, img) in images.iter().enumerate() {
        img.check_nonempty(&format!("stacked image {i}"))?;
    }
    let width = images.iter().map(|i| i.width()).max().unwrap_or(0);
    let height = images.iter().map(|i| i.height()).sum::<u32>();
    let mut out = Image::new(width, height, GAP_COLOR);
    let mut y0 = 0u32;
    for img in images {
        for y in 0..img.height() {
            let w = img.width() as usize;
            let start = out.index(0, y0 + y);
            out.data_mut()[start..start + w].copy_from_slice(img.row(y));
        }
        y0 += img.height();
    }
    Ok(out)
}

/// `image` with `label` written above it (black on white, text scale `scale`, a bar as wide as
/// the image). Errors on a zero-size image.
pub fn labelled(image: &Image<[u8; 3]>, label: &str, scale: u32) -> Result<Image<[u8; 3]>> {
    image.check_nonempty("labelled image")?;
    let s = scale.max(1);
    let mut bar = Image::new(image.width(), (GLYPH + 6) * s, GAP_COLOR);
    draw_text(&mut bar, 3 * s as i64, 3 * s as i64, label, s, [0; 3]);
    stacked(&[&bar, image])
}

/// Box-filtered reduction of `image` by the integer factor that brings its width to at most
/// `max_width` (unchanged if it is already narrow enough): figure strips of full-HD panels stay a
/// readable size. Errors on a zero-size image or `max_width == 0`.
pub fn fit_width(image: &Image<[u8; 3]>, max_width: u32) -> Result<Image<[u8; 3]>> {
    image.check_nonempty("fit_width image")?;
    if max_width == 0 {
        return Err(Error::invalid("fit_width: max_width must be positive"));
    }
    let k = image.width().div_ceil(max_width).max(1);
    if k == 1 {
        return Ok(image.clone());
    }
    let (w, h) = (image.width() / k, image.height() / k);
    if w == 0 || h == 0 {
        return Err(Error::invalid(format!("fit_width: {}x{} reduced by {k} is empty", image.width(), image.height())));
    }
    let mut data = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            let mut sum = [0u32; 3];
            for dy in 0..k {
                for dx in 0..k {
                    let p = image.get(x * k + dx, y * k + dy);
                    for c in 0..3 {
                        sum[c] += p[c] as u32;
                    }
                }
            }
            let n = k * k;
            data.push(sum.map(|v| ((v + n / 2) / n) as u8));
        }
    }
    Image::from_vec(w, h, data)
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
    fn stacked_labelled_and_fitted() {
        let a = Image::new(3, 2, [1u8, 0, 0]);
        let b = Image::new(2, 1, [0u8, 2, 0]);
        let s = stacked(&[&a, &b]).unwrap();
        assert_eq!(s.size(), (3, 3));
        assert_eq!(s.row(2), &[[0, 2, 0], [0, 2, 0], GAP_COLOR]);
        let l = labelled(&a, "ab", 1).unwrap();
        assert_eq!(l.size(), (3, GLYPH + 6 + 2));
        assert_eq!(l.row(GLYPH + 6), a.row(0));
        // 4x4 of alternating 0 / 200 reduced to width 2: the mean of each 2x2 block.
        let c = Image::from_vec(4, 4, (0..16).map(|i| [if i % 2 == 0 { 0 } else { 200 }, 7, 9]).collect()).unwrap();
        let f = fit_width(&c, 2).unwrap();
        assert_eq!(f.size(), (2, 2));
        assert!(f.data().iter().all(|p| *p == [100, 7, 9]));
        assert_eq!(fit_width(&c, 10).unwrap(), c);
    }

    #[test]
    fn bad_input_is_an_error() {
        assert!(stacked(&[]).is_err());
        assert!(fit_width(&Image::new(4, 1, [0u8; 3]), 1).unwrap_err().to_string().contains("empty"));
        assert!(fit_width(&Image::new(4, 4, [0u8; 3]), 0).is_err());
        assert!(side_by_side(&[]).unwrap_err().to_string().contains("no images"));
        let z = Image::new(0, 3, [0u8; 3]);
        assert!(side_by_side(&[&z]).unwrap_err().to_string().contains("zero-size"));
    }
}
