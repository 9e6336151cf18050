//! `Image<T>`: the one 2-D buffer type (width, height, flat row-major `Vec`).

use crate::{Error, Result};

/// A 2-D buffer: `data[y * width + x]`, row 0 at the top (ARCHITECTURE.md "Conventions").
/// Depth buffers, item buffers, motion buffers, mip levels and N-buffer levels are all `Image`s.
#[derive(Clone, Debug, PartialEq)]
pub struct Image<T> {
    width: u32,
    height: u32,
    data: Vec<T>,
}

impl<T: Clone> Image<T> {
    /// A `width x height` image filled with `value`. Zero-size images are allowed here (they are
    /// rejected where a stage needs pixels, see [`Image::check_nonempty`]).
    pub fn new(width: u32, height: u32, value: T) -> Self {
        Image { width, height, data: vec![value; width as usize * height as usize] }
    }
}

impl<T: Copy + Send + Sync> Image<T> {
    /// [`Image::new`] for a per-frame target: filled in parallel, and large buffers advised for
    /// transparent huge pages before their first write ([`crate::pages`]), so a fresh render
    /// target costs a few 2 MiB page faults instead of one per 4 KiB.
    pub fn filled(width: u32, height: u32, value: T) -> Self {
        Image { width, height, data: crate::pages::filled(width as usize * height as usize, value) }
    }

    /// Makes this image a copy of `src`: in place, in parallel chunks, where the sizes match (an
    /// engine's per-frame source copy: no fresh pages), else as a fresh clone.
    pub fn copy_from(&mut self, src: &Image<T>) {
        use rayon::prelude::*;
        if self.size() != src.size() {
            *self = src.clone();
            return;
        }
        const CHUNK: usize = 1 << 16;
        self.data.par_chunks_mut(CHUNK).zip(src.data.par_chunks(CHUNK)).for_each(|(d, s)| d.copy_from_slice(s));
    }
}

impl Image<f32> {
    /// `true` if no value is NaN or infinite: the input check of every stage that reads depth.
    /// A branch-free fold per parallel chunk, so the common (all finite) case vectorizes.
    pub fn all_finite(&self) -> bool {
        use rayon::prelude::*;
        self.data.par_chunks(1 << 16).all(|c| c.iter().fold(true, |ok, v| ok & v.is_finite()))
    }
}

impl<T> Image<T> {
    /// Wraps `data` (row-major) as a `width x height` image; errors if the length does not match.
    pub fn from_vec(width: u32, height: u32, data: Vec<T>) -> Result<Self> {
        if data.len() != width as usize * height as usize {
            return Err(Error::invalid(format!(
                "image data has {} elements, expected {}x{} = {}",
                data.len(),
                width,
                height,
                width as usize * height as usize
            )));
        }
        Ok(Image { width, height, data })
    }

    /// Builds an image by evaluating `f(x, y)` at every pixel.
    pub fn from_fn(width: u32, height: u32, mut f: impl FnMut(u32, u32) -> T) -> Self {
        let mut data = Vec::with_capacity(width as usize * height as usize);
        for y in 0..height {
            for x in 0..width {
                data.push(f(x, y));
            }
        }
        Image { width, height, data }
    }

    /// Width in pixels.
    #[inline]
    pub fn width(&self) -> u32 {
        self.width
    }
    /// Height in pixels.
    #[inline]
    pub fn height(&self) -> u32 {
        self.height
    }
    /// `(width, height)`.
    #[inline]
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }
    /// Number of pixels.
    #[inline]
    pub fn len(&self) -> usize {
        self.data.len()
    }
    /// `true` when the image has no pixels.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }
    /// Errors with a clear message if the image has no pixels.
    pub fn check_nonempty(&self, what: &str) -> Result<()> {
        if self.is_empty() {
            Err(Error::invalid(format!("{what} is a zero-size image ({}x{})", self.width, self.height)))
        } else {
            Ok(())
        }
    }
    /// Errors with a clear message if `other` does not have the same size.
    pub fn check_same_size<U>(&self, other: &Image<U>, what: &str) -> Result<()> {
        if self.size() != other.size() {
            Err(Error::invalid(format!(
                "{what}: size mismatch {}x{} vs {}x{}",
                self.width, self.height, other.width, other.height
            )))
        } else {
            Ok(())
        }
    }
    /// Flat index of pixel `(x, y)`.
    #[inline]
    pub fn index(&self, x: u32, y: u32) -> usize {
        y as usize * self.width as usize + x as usize
    }
    /// The pixel at `(x, y)` (panics when out of bounds, like slice indexing).
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> &T {
        &self.data[self.index(x, y)]
    }
    /// Mutable pixel at `(x, y)`.
    #[inline]
    pub fn get_mut(&mut self, x: u32, y: u32) -> &mut T {
        let i = self.index(x, y);
        &mut self.data[i]
    }
    /// The pixel at `(x, y)` with coordinates clamped to the image (edge extension).
    #[inline]
    pub fn get_clamped(&self, x: i64, y: i64) -> &T {
        let cx = x.clamp(0, self.width as i64 - 1) as u32;
        let cy = y.clamp(0, self.height as i64 - 1) as u32;
        self.get(cx, cy)
    }
    /// Row `y` as a slice.
    #[inline]
    pub fn row(&self, y: u32) -> &[T] {
        let w = self.width as usize;
        &self.data[y as usize * w..(y as usize + 1) * w]
    }
    /// Row `y` as a mutable slice.
    #[inline]
    pub fn row_mut(&mut self, y: u32) -> &mut [T] {
        let w = self.width as usize;
        &mut self.data[y as usize * w..(y as usize + 1) * w]
    }
    /// All pixels, row-major.
    #[inline]
    pub fn data(&self) -> &[T] {
        &self.data
    }
    /// All pixels, row-major, mutable.
    #[inline]
    pub fn data_mut(&mut self) -> &mut [T] {
        &mut self.data
    }
    /// Consumes the image, returning its pixels.
    pub fn into_vec(self) -> Vec<T> {
        self.data
    }
    /// Applies `f` to every pixel, producing a new image of the same size.
    pub fn map<U>(&self, f: impl FnMut(&T) -> U) -> Image<U> {
        Image { width: self.width, height: self.height, data: self.data.iter().map(f).collect() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// In place across several parallel chunks where the sizes match, a fresh copy where not.
    #[test]
    fn copy_from_gives_the_source() {
        let src = Image::from_fn(301, 257, |x, y| x * 1000 + y);
        let mut same = Image::new(301, 257, 0u32);
        let before = same.data().as_ptr();
        same.copy_from(&src);
        assert_eq!(same, src);
        assert_eq!(same.data().as_ptr(), before, "copied in place");
        let mut other = Image::new(3, 2, 7u32);
        other.copy_from(&src);
        assert_eq!(other, src);
    }

    /// A single NaN or infinity anywhere (also past the first parallel chunk) is found.
    #[test]
    fn all_finite_finds_any_bad_value() {
        let mut img = Image::from_fn(700, 300, |x, y| (x + y) as f32 * 0.001);
        assert!(img.all_finite());
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            let mut b = img.clone();
            *b.get_mut(650, 290) = bad;
            assert!(!b.all_finite(), "{bad}");
        }
        *img.get_mut(0, 0) = f32::NAN;
        assert!(!img.all_finite());
    }
}
