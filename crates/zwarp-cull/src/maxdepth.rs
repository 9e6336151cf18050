//! Max-depth structures over a (predicted) depth buffer `Z^` for screen-space occlusion queries
//! (seed 000 Sec. 5.2; thesis seed 002 Sec. III.2 and IV.1).
//!
//! Every structure answers "what is (an upper bound of) the maximum depth over this pixel
//! rectangle?" and hence `is_occluded(rect, nearest)`: the occludee is hidden when even the
//! farthest occluder pixel in its rectangle is strictly in front of its nearest point.
//!
//! - [`MaxMipmap`]: hierarchical occlusion map (HOM) — a max mipmap; cheap, but "too
//!   approximate" (Sec. 5.2) because a rect is covered by whole power-of-two texels.
//! - [`NBuffer`]: Décoret's N-buffers — level `i` holds at each texel the max over the
//!   `2^i x 2^i` square starting there; any rect is answered *exactly*.
//! - [`YMap`]: Schwarz & Stamminger's Y-maps — a mipmap for the first levels and an N-buffer
//!   above ("Y-Maps with two mipmap levels lead to a lower construction time without
//!   sacrificing much precision").
//!
//! Depth follows the zwarp convention: `[0, 1]`, 0 = near, 1 = far / no surface. Holes of a
//! warped buffer are at 1 and therefore never occlude anything.

use rayon::prelude::*;
use zwarp_core::{Error, Image, Result, EMPTY_DEPTH};

use crate::screen::PixelRect;

/// A structure answering max-depth queries over pixel rectangles of a depth buffer.
pub trait MaxDepthQuery: Sync {
    /// `(width, height)` of the depth buffer it was built from.
    fn size(&self) -> (u32, u32);

    /// An upper bound of the maximum depth over every pixel of `rect` (exact for
    /// [`NBuffer`]). The rect is clamped to the image; if nothing is left the answer is
    /// [`EMPTY_DEPTH`] (nothing known, never occludes).
    fn max_depth(&self, rect: PixelRect) -> f32;

    /// `true` when the max depth over `rect` is strictly smaller than `nearest` (the minimum
    /// depth of the occludee's proxy): every pixel the object could cover already holds a
    /// surface in front of it.
    fn is_occluded(&self, rect: PixelRect, nearest: f32) -> bool {
        self.max_depth(rect) < nearest
    }
}

/// Rejects buffers a max-depth structure cannot be built on.
fn check_depth(depth: &Image<f32>) -> Result<()> {
    depth.check_nonempty("depth buffer")?;
    if let Some(i) = depth.data().iter().position(|d| d.is_nan()) {
        let (x, y) = (i as u32 % depth.width(), i as u32 / depth.width());
        return Err(Error::invalid(format!("depth buffer holds NaN at pixel ({x}, {y})")));
    }
    Ok(())
}

/// Exact maximum over `rect` by brute force (the reference the structures are tested against;
/// also the ideal screen-space test). Clamps like [`MaxDepthQuery::max_depth`].
pub fn max_in_rect(depth: &Image<f32>, rect: PixelRect) -> f32 {
    let Some(r) = rect.clamped(depth.width(), depth.height()) else { return EMPTY_DEPTH };
    let mut m = f32::NEG_INFINITY;
    for y in r.y0..r.y1 {
        for &d in &depth.row(y)[r.x0 as usize..r.x1 as usize] {
            m = m.max(d);
        }
    }
    m
}

/// 1-pixel erosion of the occluders (thesis Sec. IV.1, Fig. 4): each pixel takes the maximum
/// of itself and its 8 neighbours (neighbours outside the image are ignored). This pushes
/// occluder silhouettes back by one pixel so that the 1-2 pixel boundary errors of warping
/// cannot cull an object that is visible next to a silhouette.
pub fn erode_max(depth: &Image<f32>) -> Image<f32> {
    let (w, h) = depth.size();
    if depth.is_empty() {
        return depth.clone();
    }
    let wu = w as usize;
    // Separable: a 3-wide horizontal max, then a 3-tall vertical max of that. The interior is
    // written as max over shifted slices so that it vectorizes; the edges ignore the missing
    // neighbour (clamping to the edge pixel gives the same max).
    let mut horiz = Image::new(w, h, 0.0f32);
    horiz.data_mut().par_chunks_mut(wu).enumerate().for_each(|(y, out)| {
        let src = depth.row(y as u32);
        if wu < 3 {
            let m = src.iter().copied().fold(f32::NEG_INFINITY, fmax);
            out.fill(m);
            return;
        }
        out[0] = fmax(src[0], src[1]);
        out[wu - 1] = fmax(src[wu - 2], src[wu - 1]);
        for (((o, &a), &b), &c) in out[1..wu - 1].iter_mut().zip(&src[..wu - 2]).zip(&src[1..wu - 1]).zip(&src[2..]) {
            *o = fmax(fmax(a, b), c);
        }
    });
    let mut out = Image::new(w, h, 0.0f32);
    out.data_mut().par_chunks_mut(wu).enumerate().for_each(|(y, row)| {
        let lo = y.saturating_sub(1) as u32;
        let hi = (y + 1).min(h as usize - 1) as u32;
        let (a, b, c) = (horiz.row(lo), horiz.row(y as u32), horiz.row(hi));
        for (((o, &a), &b), &c) in row.iter_mut().zip(a).zip(b).zip(c) {
            *o = fmax(fmax(a, b), c);
        }
    });
    out
}

/// Max of two depths that are never NaN (checked when a structure is built): a plain compare
/// lets the compiler emit a single vector max instead of `f32::max`'s NaN handling.
#[inline(always)]
fn fmax(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// One max-reduction step of a mipmap: `ceil(w/2) x ceil(h/2)`, each texel the max of the (up
/// to) 2x2 texels below it. Rounding the size *up* makes an odd last row/column its own texel,
/// so no texel of the finer level is ever dropped (the Bevy downsampler pitfall of
/// ARCHITECTURE.md "Pitfalls of public implementations").
pub fn reduce_max_2x2(src: &Image<f32>) -> Image<f32> {
    let (w, h) = src.size();
    let (nw, nh) = (w.div_ceil(2).max(1), h.div_ceil(2).max(1));
    let mut out = Image::new(nw, nh, 0.0f32);
    out.data_mut().par_chunks_mut(nw as usize).enumerate().for_each(|(y, row)| {
        let y0 = (2 * y as u32).min(h - 1);
        let y1 = (2 * y as u32 + 1).min(h - 1);
        let (r0, r1) = (src.row(y0), src.row(y1));
        for (x, o) in row.iter_mut().enumerate() {
            let x0 = (2 * x).min(w as usize - 1);
            let x1 = (2 * x + 1).min(w as usize - 1);
            *o = fmax(fmax(r0[x0], r0[x1]), fmax(r1[x0], r1[x1]));
        }
    });
    out
}

/// Max mipmap / hierarchical occlusion map. Level `k` texel `(x, y)` holds the max over pixels
/// `[x 2^k, (x+1) 2^k) x [y 2^k, (y+1) 2^k)` clipped to the image; the last level is 1x1.
#[derive(Clone, Debug)]
pub struct MaxMipmap {
    levels: Vec<Image<f32>>,
}

impl MaxMipmap {
    /// Builds every level down to 1x1 (rayon-parallel per level). Errors on an empty buffer or
    /// NaN depths.
    pub fn build(depth: &Image<f32>) -> Result<Self> {
        check_depth(depth)?;
        Ok(Self::build_levels(depth.clone(), u32::MAX))
    }

    /// Levels `0..=max_level` (or down to 1x1, whichever comes first); input already checked.
    fn build_levels(depth: Image<f32>, max_level: u32) -> Self {
        let mut levels = vec![depth];
        while (levels.len() as u32) <= max_level {
            let last = levels.last().expect("level 0 exists");
            if last.size() == (1, 1) {
                break;
            }
            let next = reduce_max_2x2(last);
            levels.push(next);
        }
        MaxMipmap { levels }
    }

    /// The levels, finest (the depth buffer itself) first.
    pub fn levels(&self) -> &[Image<f32>] {
        &self.levels
    }

    /// The finest level at which `rect` spans at most 2x2 texels (a fixed, tiny number of
    /// reads however large the rect is).
    pub fn query_level(&self, rect: PixelRect) -> u32 {
        let (x0, y0, x1, y1) = (rect.x0, rect.y0, rect.x1 - 1, rect.y1 - 1);
        let mut k = 0u32;
        while (k as usize) + 1 < self.levels.len() && ((x1 >> k) - (x0 >> k) > 1 || (y1 >> k) - (y0 >> k) > 1) {
            k += 1;
        }
        k
    }

    /// Max over the texels of level `k` that contain `rect` (already clamped).
    fn max_at_level(&self, rect: PixelRect, k: u32) -> f32 {
        let lvl = &self.levels[k as usize];
        let (tx0, ty0) = (rect.x0 >> k, rect.y0 >> k);
        let tx1 = ((rect.x1 - 1) >> k).min(lvl.width() - 1);
        let ty1 = ((rect.y1 - 1) >> k).min(lvl.height() - 1);
        let mut m = f32::NEG_INFINITY;
        for ty in ty0..=ty1 {
            for &d in &lvl.row(ty)[tx0 as usize..=tx1 as usize] {
                m = m.max(d);
            }
        }
        m
    }
}

impl MaxDepthQuery for MaxMipmap {
    fn size(&self) -> (u32, u32) {
        self.levels[0].size()
    }
    fn max_depth(&self, rect: PixelRect) -> f32 {
        let (w, h) = self.size();
        let Some(r) = rect.clamped(w, h) else { return EMPTY_DEPTH };
        self.max_at_level(r, self.query_level(r))
    }
}

/// Starts of the `ceil((hi - lo) / s)` tiles of side `s` that cover `[lo, hi)` exactly with
/// every tile inside it (the last one is pulled back to end at `hi`). Needs `s <= hi - lo`.
#[inline]
fn tile_starts(lo: u32, hi: u32, s: u32) -> impl Iterator<Item = u32> {
    let n = (hi - lo).div_ceil(s);
    (0..n).map(move |i| (lo + i * s).min(hi - s))
}

/// `floor(log2(v))` for `v >= 1`.
#[inline]
fn floor_log2(v: u32) -> u32 {
    31 - v.leading_zeros()
}

/// N-buffer (Décoret 2005): levels of identical resolution; texel `p` of level `i` holds the
/// max over the `2^i x 2^i` square whose top-left corner is `p`, clipped to the image.
/// Levels `0..=floor(log2(min(w, h)))` exist: no query rect needs a larger square.
#[derive(Clone, Debug)]
pub struct NBuffer {
    levels: Vec<Image<f32>>,
}

impl NBuffer {
    /// Builds all levels (level `i+1` from 4 lookups in level `i`, rayon-parallel per row).
    /// Errors on an empty buffer or NaN depths.
    pub fn build(depth: &Image<f32>) -> Result<Self> {
        check_depth(depth)?;
        Ok(Self::build_owned(depth.clone()))
    }

    /// Builds on an already checked buffer, taking ownership of it as level 0.
    fn build_owned(depth: Image<f32>) -> Self {
        let (w, h) = depth.size();
        let top = floor_log2(w.min(h));
        let mut levels = Vec::with_capacity(top as usize + 1);
        levels.push(depth);
        for i in 0..top {
            let prev = levels.last().expect("level 0 exists");
            let s = 1usize << i;
            let (wu, hu) = (w as usize, h as usize);
            let mut next = Image::new(w, h, 0.0f32);
            next.data_mut().par_chunks_mut(wu).enumerate().for_each(|(y, row)| {
                // The square [x, x + 2s) is the union of the squares at x and x + s; when x + s
                // leaves the image the clipped square is the one at x alone, and clamping to the
                // last column/row reads a square inside it, so clamping stays exact.
                let r0 = prev.row(y as u32);
                let r1 = prev.row((y + s).min(hu - 1) as u32);
                // Interior (x + s inside the image): straight shifted-slice max, vectorizable.
                let split = wu.saturating_sub(s);
                for ((((o, &a), &b), &c), &d) in
                    row[..split].iter_mut().zip(&r0[..split]).zip(&r0[s..]).zip(&r1[..split]).zip(&r1[s..])
                {
                    *o = fmax(fmax(a, b), fmax(c, d));
                }
                let (la, lb) = (r0[wu - 1], r1[wu - 1]);
                for (x, o) in row.iter_mut().enumerate().skip(split) {
                    *o = fmax(fmax(r0[x], la), fmax(r1[x], lb));
                }
            });
            levels.push(next);
        }
        NBuffer { levels }
    }

    /// The levels, level 0 (the depth buffer) first.
    pub fn levels(&self) -> &[Image<f32>] {
        &self.levels
    }

    /// Number of texel reads a query of `rect` makes: `ceil(a / 2^m) * ceil(b / 2^m)` with
    /// `m = floor(log2(min(a, b)))` (4 for squares, more along the longer side of thin rects).
    pub fn lookups(rect: PixelRect) -> u64 {
        let s = 1u32 << floor_log2(rect.width().min(rect.height()));
        rect.width().div_ceil(s) as u64 * rect.height().div_ceil(s) as u64
    }

    /// Exact max over an already clamped rect.
    fn max_exact(&self, r: PixelRect) -> f32 {
        let m = floor_log2(r.width().min(r.height())).min(self.levels.len() as u32 - 1);
        let s = 1u32 << m;
        let lvl = &self.levels[m as usize];
        let mut best = f32::NEG_INFINITY;
        for ty in tile_starts(r.y0, r.y1, s) {
            let row = lvl.row(ty);
            for tx in tile_starts(r.x0, r.x1, s) {
                best = best.max(row[tx as usize]);
            }
        }
        best
    }
}

impl MaxDepthQuery for NBuffer {
    fn size(&self) -> (u32, u32) {
        self.levels[0].size()
    }
    fn max_depth(&self, rect: PixelRect) -> f32 {
        let (w, h) = self.size();
        match rect.clamped(w, h) {
            Some(r) => self.max_exact(r),
            None => EMPTY_DEPTH,
        }
    }
}

/// Y-map (Schwarz & Stamminger 2008, thesis Sec. III.2): mipmap levels `0..switch` and an
/// N-buffer built on mip level `switch`. Small rects are answered by the mipmap (<= 2x2 texels
/// at a level below `switch`), larger ones by an exact N-buffer query over the level-`switch`
/// texels that contain the rect. `switch = 0` is a plain N-buffer; the thesis uses 2.
#[derive(Clone, Debug)]
pub struct YMap {
    mip: MaxMipmap,
    nbuf: NBuffer,
    switch: u32,
}

/// Largest accepted Y-map switch level (2^16 pixels per texel is already beyond any image).
pub const MAX_YMAP_SWITCH: u32 = 16;

impl YMap {
    /// Builds the Y-map with `switch` mipmap levels. Errors on an empty buffer, NaN depths or
    /// `switch > MAX_YMAP_SWITCH`.
    pub fn build(depth: &Image<f32>, switch: u32) -> Result<Self> {
        check_depth(depth)?;
        if switch > MAX_YMAP_SWITCH {
            return Err(Error::invalid(format!("Y-map switch level {switch} exceeds {MAX_YMAP_SWITCH}")));
        }
        let mut mip = MaxMipmap::build_levels(depth.clone(), switch);
        // When the image reaches 1x1 before `switch`, the top level is the switch level.
        let switch = mip.levels.len() as u32 - 1;
        let top = mip.levels.pop().expect("at least level 0");
        let nbuf = NBuffer::build_owned(top);
        Ok(YMap { mip, nbuf, switch })
    }

    /// The mipmap/N-buffer switch level actually used (clamped to the mip chain's length).
    pub fn switch(&self) -> u32 {
        self.switch
    }

    /// The mip levels below the switch (level 0 first; empty when `switch == 0`).
    pub fn mip_levels(&self) -> &[Image<f32>] {
        self.mip.levels()
    }

    /// The N-buffer over mip level `switch`.
    pub fn nbuffer(&self) -> &NBuffer {
        &self.nbuf
    }
}

impl MaxDepthQuery for YMap {
    fn size(&self) -> (u32, u32) {
        let (w, h) = self.nbuf.size();
        match self.mip.levels.first() {
            Some(l0) => l0.size(),
            None => (w, h),
        }
    }
    fn max_depth(&self, rect: PixelRect) -> f32 {
        let (w, h) = self.size();
        let Some(r) = rect.clamped(w, h) else { return EMPTY_DEPTH };
        let k = self.switch;
        // Finest mip level (below the switch) where the rect spans <= 2x2 texels.
        let (x1, y1) = (r.x1 - 1, r.y1 - 1);
        for j in 0..k {
            if (x1 >> j) - (r.x0 >> j) <= 1 && (y1 >> j) - (r.y0 >> j) <= 1 {
                return self.mip.max_at_level(r, j);
            }
        }
        // Texels of the switch level containing the rect, queried exactly.
        let t = PixelRect { x0: r.x0 >> k, y0: r.y0 >> k, x1: (x1 >> k) + 1, y1: (y1 >> k) + 1 };
        self.nbuf.max_exact(t)
    }
}

/// Which max-depth structure to build (see [`MaxDepthMap`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum MaxDepthKind {
    /// Max mipmap (HOM).
    Mipmap,
    /// N-buffer (exact).
    NBuffer,
    /// Y-map with the given number of mipmap levels before the N-buffer.
    YMap {
        /// Switch level (thesis: 2).
        switch: u32,
    },
    /// The thesis' choice: a Y-map with two mipmap levels.
    #[default]
    Default,
}

/// Any of the max-depth structures, chosen at run time.
#[derive(Clone, Debug)]
pub enum MaxDepthMap {
    /// See [`MaxMipmap`].
    Mipmap(MaxMipmap),
    /// See [`NBuffer`].
    NBuffer(NBuffer),
    /// See [`YMap`].
    YMap(YMap),
}

impl MaxDepthMap {
    /// Builds the structure `kind` over `depth`.
    pub fn build(kind: MaxDepthKind, depth: &Image<f32>) -> Result<Self> {
        Ok(match kind {
            MaxDepthKind::Mipmap => MaxDepthMap::Mipmap(MaxMipmap::build(depth)?),
            MaxDepthKind::NBuffer => MaxDepthMap::NBuffer(NBuffer::build(depth)?),
            MaxDepthKind::YMap { switch } => MaxDepthMap::YMap(YMap::build(depth, switch)?),
            MaxDepthKind::Default => MaxDepthMap::YMap(YMap::build(depth, 2)?),
        })
    }
}

impl MaxDepthQuery for MaxDepthMap {
    fn size(&self) -> (u32, u32) {
        match self {
            MaxDepthMap::Mipmap(m) => m.size(),
            MaxDepthMap::NBuffer(m) => m.size(),
            MaxDepthMap::YMap(m) => m.size(),
        }
    }
    fn max_depth(&self, rect: PixelRect) -> f32 {
        match self {
            MaxDepthMap::Mipmap(m) => m.max_depth(rect),
            MaxDepthMap::NBuffer(m) => m.max_depth(rect),
            MaxDepthMap::YMap(m) => m.max_depth(rect),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(w: u32, h: u32) -> Image<f32> {
        Image::from_fn(w, h, |x, y| ((x * 7 + y * 13) % 31) as f32 / 31.0)
    }

    #[test]
    fn mipmap_sizes_round_up_and_keep_the_last_column() {
        let mut d = Image::new(5, 3, 0.1f32);
        *d.get_mut(4, 2) = 0.9; // the odd corner texel
        let m = MaxMipmap::build(&d).unwrap();
        let sizes: Vec<_> = m.levels().iter().map(|l| l.size()).collect();
        assert_eq!(sizes, vec![(5, 3), (3, 2), (2, 1), (1, 1)]);
        assert_eq!(*m.levels()[1].get(2, 1), 0.9);
        assert_eq!(*m.levels()[3].get(0, 0), 0.9);
        assert_eq!(m.max_depth(PixelRect::new(4, 2, 5, 3).unwrap()), 0.9);
    }

    #[test]
    fn nbuffer_levels_match_definition() {
        let d = ramp(9, 6);
        let nb = NBuffer::build(&d).unwrap();
        assert_eq!(nb.levels().len(), 3, "levels 0..=floor(log2 6)");
        for (i, lvl) in nb.levels().iter().enumerate() {
            let s = 1u32 << i;
            for y in 0..6 {
                for x in 0..9 {
                    let r = PixelRect::new(x, y, (x + s).min(9), (y + s).min(6)).unwrap();
                    assert_eq!(*lvl.get(x, y), max_in_rect(&d, r), "level {i} at ({x}, {y})");
                }
            }
        }
        assert_eq!(NBuffer::lookups(PixelRect::new(0, 0, 5, 5).unwrap()), 4);
        assert_eq!(NBuffer::lookups(PixelRect::new(0, 0, 9, 2).unwrap()), 5);
    }

    #[test]
    fn ymap_small_rect_uses_mip_and_large_rect_is_bounded() {
        let d = ramp(13, 11);
        let y = YMap::build(&d, 2).unwrap();
        assert_eq!(y.switch(), 2);
        assert_eq!(y.mip_levels().len(), 2);
        assert_eq!(y.nbuffer().size(), (4, 3));
        let one = PixelRect::new(6, 5, 7, 6).unwrap();
        assert_eq!(y.max_depth(one), *d.get(6, 5), "a single pixel is read at level 0");
        let big = PixelRect::new(1, 1, 12, 10).unwrap();
        assert!(y.max_depth(big) >= max_in_rect(&d, big));
        // Switch beyond the chain clamps to the 1x1 level.
        assert_eq!(YMap::build(&d, 9).unwrap().switch(), 4);
    }

    #[test]
    fn occlusion_is_strict() {
        let d = Image::new(4, 4, 0.5f32);
        let nb = NBuffer::build(&d).unwrap();
        let r = PixelRect::new(0, 0, 4, 4).unwrap();
        assert!(nb.is_occluded(r, 0.6));
        assert!(!nb.is_occluded(r, 0.5), "equal depth is not strictly behind");
        // Outside the image: nothing known, never occluded.
        assert_eq!(nb.max_depth(PixelRect::new(7, 7, 9, 9).unwrap()), EMPTY_DEPTH);
    }

    #[test]
    fn bad_input_is_an_error() {
        let e = NBuffer::build(&Image::new(0, 3, 0.0f32)).unwrap_err().to_string();
        assert!(e.contains("zero-size"), "{e}");
        let mut d = Image::new(3, 3, 0.5f32);
        *d.get_mut(1, 2) = f32::NAN;
        let e = MaxMipmap::build(&d).unwrap_err().to_string();
        assert!(e.contains("NaN at pixel (1, 2)"), "{e}");
        assert!(YMap::build(&Image::new(3, 3, 0.5), 17).is_err());
    }

    #[test]
    fn erosion_takes_the_3x3_max() {
        let mut d = Image::new(5, 4, 0.2f32);
        *d.get_mut(0, 0) = 1.0;
        *d.get_mut(3, 2) = 0.7;
        let e = erode_max(&d);
        let expect = [
            [1.0, 1.0, 0.2, 0.2, 0.2],
            [1.0, 1.0, 0.7, 0.7, 0.7],
            [0.2, 0.2, 0.7, 0.7, 0.7],
            [0.2, 0.2, 0.7, 0.7, 0.7],
        ];
        for y in 0..4 {
            for x in 0..5 {
                assert_eq!(*e.get(x, y), expect[y as usize][x as usize], "({x}, {y})");
            }
        }
        assert_eq!(erode_max(&Image::new(1, 1, 0.3f32)).data(), &[0.3]);
    }
}
