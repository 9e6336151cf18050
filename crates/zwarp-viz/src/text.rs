//! Text drawn into images: panel labels and colour-bar ticks, so a figure PNG explains itself
//! without the page around it. Glyphs are the public-domain 8x8 bitmap font of `font8x8`
//! (printable ASCII), scaled by an integer factor.

use font8x8::UnicodeFonts;
use zwarp_core::Image;

/// Height and advance in pixels of one glyph at scale 1.
pub const GLYPH: u32 = 8;

/// Size `(width, height)` in pixels of `text` drawn at `scale` (one line, every character
/// `GLYPH * scale` wide; characters outside printable ASCII are drawn as `?`).
pub fn text_size(text: &str, scale: u32) -> (u32, u32) {
    (text.chars().count() as u32 * GLYPH * scale, GLYPH * scale)
}

/// Draws `text` with its top-left corner at `(x, y)`, each font pixel a `scale` x `scale`
/// block of `color`; what falls outside the image is clipped.
pub fn draw_text(img: &mut Image<[u8; 3]>, x: i64, y: i64, text: &str, scale: u32, color: [u8; 3]) {
    let s = scale.max(1) as i64;
    for (k, ch) in text.chars().enumerate() {
        let glyph = font8x8::BASIC_FONTS.get(ch).or_else(|| font8x8::BASIC_FONTS.get('?')).unwrap_or([0; 8]);
        let gx = x + k as i64 * GLYPH as i64 * s;
        for (row, bits) in glyph.iter().enumerate() {
            for col in 0..8 {
                // font8x8 stores the leftmost pixel in bit 0.
                if bits >> col & 1 == 0 {
                    continue;
                }
                for dy in 0..s {
                    for dx in 0..s {
                        let (px, py) = (gx + col * s + dx, y + row as i64 * s + dy);
                        if px >= 0 && py >= 0 && (px as u32) < img.width() && (py as u32) < img.height() {
                            *img.get_mut(px as u32, py as u32) = color;
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn glyph_pixels_land_where_the_font_says() {
        let mut img = Image::new(20, 10, [0u8; 3]);
        draw_text(&mut img, 1, 1, "|", 1, [255; 3]);
        let glyph = font8x8::BASIC_FONTS.get('|').unwrap();
        for (row, bits) in glyph.iter().enumerate() {
            for col in 0..8u32 {
                let on = bits >> col & 1 == 1;
                assert_eq!(*img.get(1 + col, 1 + row as u32) == [255; 3], on, "({col}, {row})");
            }
        }
        // Nothing outside the glyph box.
        assert!((9..20).all(|x| (0..10).all(|y| *img.get(x, y) == [0; 3])));
    }

    #[test]
    fn scaled_and_clipped() {
        assert_eq!(text_size("abc", 2), (48, 16));
        let mut img = Image::new(4, 4, [0u8; 3]);
        draw_text(&mut img, -100, -100, "xyz", 3, [9; 3]); // entirely outside: no panic, no pixel
        draw_text(&mut img, 2, 2, "\u{2603}", 1, [9; 3]); // unknown glyph: '?' clipped at the edge
        assert!(img.data()[..img.index(0, 2)].iter().all(|p| *p == [0; 3]));
    }
}
