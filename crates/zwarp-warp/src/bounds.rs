//! Search-region bounds for the fixed-point search (seed 000, Sec. 3.3, Fig. 5).
//!
//! A solution `q` of `q + v(q) = p` lies in `p - [v_min, v_max]` where `[v_min, v_max]` bounds
//! the motion of every sample that could be the solution. The min-max motion mipmap gives such
//! bounds over square pixel blocks; iterative tightening (Fig. 5) starts from the global bound
//! (top texel), looks up the mipmap at the level matching the current search region with four
//! corner look-ups, and shrinks the region, `bound_iterations` times.
//!
//! **Which samples contribute.** Only *valid* samples: target depth `Motion::depth` in
//! `[0, 1)` (and, for warp layers, a source depth `< 1`). Empty source pixels carry the far
//! plane's motion, which can be large under rotation and would inflate every bound; but a
//! search that lands on an empty sample fails anyway (Fig. 3: `s.z < 1`), so an empty sample
//! can never be a solution and excluding it keeps the bound conservative. Points that leave the
//! target's depth range (behind the far plane or in front of the near plane, or behind the eye,
//! which `zwarp_core::motion_field` marks with depth 1) are invisible in the target and are
//! excluded for the same reason.
//!
//! **Samples that leave the image.** A sample whose target lies beyond the image can be no
//! pixel's solution, but its motion still widens every bound over it: a wall or floor beside a
//! camera moving forward moves hundreds to thousands of pixels off the view, and the bounds of
//! the pixels that see the rest of that surface grow to match (the seeds scatter over the whole
//! image and the search fails). A preparation for [`MotionScales::AtLeastOne`] therefore enters
//! such a sample into the mipmap as if it landed [`clip_margin`] px beyond the image
//! ([`ImageClip`]); the bounds stay exact for every solution in the image (see there).
//!
//! **Odd sizes.** Level `l` has `ceil(w / 2^l) x ceil(h / 2^l)` texels; texel `(i, j)` covers the
//! pixels `[i 2^l, (i+1) 2^l) x [j 2^l, (j+1) 2^l)` clipped to the image, so every pixel is
//! covered at every level, for every image size (no edge row or column is dropped).
//!
//! **Oriented bounds.** Bounds are kept in a [`BoundFrame`]: `u = R v` for a rotation `R`
//! (identity = axis-aligned bound, AAB). [`pca_frame`] aligns `R` with the principal axis of ~64
//! sampled motion vectors (oriented bound, OB); the mipmap stores min/max of the rotated motion,
//! and reading a bound back means rotating by `R^T` (paper: "reversing the motion coordinates").

use glam::{Vec2, Vec4};
use rayon::prelude::*;
use zwarp_core::{Error, Image, Motion, Result};

use crate::simd::{fmax, fmin};

/// `true` if a motion sample can be a warp solution: target depth in `[0, 1)` and finite
/// motion (see the module docs on which samples contribute).
#[inline]
pub fn is_valid_sample(m: &Motion) -> bool {
    m.depth >= 0.0 && m.depth < 1.0 && m.v.is_finite()
}

/// A rotation of the motion plane in which bounds are axis-aligned: `u = R v` with
/// `R = [[c, s], [-s, c]]` (rows), i.e. `u.x` is the component along `(c, s)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoundFrame {
    /// Unit principal axis `(c, s)`; `(1, 0)` for the axis-aligned frame.
    pub axis: Vec2,
}

impl Default for BoundFrame {
    fn default() -> Self {
        BoundFrame::IDENTITY
    }
}

impl BoundFrame {
    /// The axis-aligned frame (AAB).
    pub const IDENTITY: BoundFrame = BoundFrame { axis: Vec2::X };

    /// A frame whose first axis points along `angle` radians from +x.
    pub fn from_angle(angle: f32) -> Self {
        BoundFrame { axis: Vec2::new(angle.cos(), angle.sin()) }
    }
    /// `true` for the axis-aligned frame (enables the cheaper code path).
    #[inline]
    pub fn is_identity(&self) -> bool {
        self.axis == Vec2::X
    }
    /// Image/motion coordinates -> frame coordinates (`R v`).
    #[inline]
    pub fn to_frame(&self, v: Vec2) -> Vec2 {
        let (c, s) = (self.axis.x, self.axis.y);
        Vec2::new(c * v.x + s * v.y, -s * v.x + c * v.y)
    }
    /// Frame coordinates -> image/motion coordinates (`R^T u`).
    #[inline]
    pub fn from_frame(&self, u: Vec2) -> Vec2 {
        let (c, s) = (self.axis.x, self.axis.y);
        Vec2::new(c * u.x - s * u.y, s * u.x + c * u.y)
    }
}

/// How far beyond a `w x h` image, in source samples, a sample's target may lie and still
/// enter the motion bounds as it is ([`ImageClip`]): a 64th of the larger side (30 px at 1080p),
/// at least [`CLIP_MARGIN`]. Any margin of two samples or more keeps the bounds exact. A wider
/// one leaves the bounds (and the seeds) of surfaces that leave the view at ordinary speeds as
/// they are and acts where samples leave it by hundreds or thousands of pixels, the case that
/// scatters the seeds; with 4 px at 1080p the warp of the procedural `mo` scene was 10 % slower
/// (measured, not explained), with 30 px it is within 3 % (the preparation's clip).
pub fn clip_margin(w: u32, h: u32) -> f32 {
    (w.max(h) as f32 / 64.0).max(CLIP_MARGIN)
}

/// The smallest margin of [`clip_margin`], in source samples.
pub const CLIP_MARGIN: f32 = 4.0;

/// The motion scales ([`crate::WarpParams::motion_scale`]) a preparation serves, which decides
/// whether its motion bounds clip the samples that leave the image (module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MotionScales {
    /// `motion_scale >= 1` on both axes: the motion as given (depth prediction, culling, VR,
    /// colour warps) or extrapolated. Samples whose target lies more than [`clip_margin`] beyond
    /// the image enter the bounds at that margin ([`ImageClip`]).
    #[default]
    AtLeastOne,
    /// Any scale, e.g. one preparation shared by the soft-shadow samples' warps of one field
    /// scaled by factors of either sign: the bounds of the motion as it is.
    Any,
}

impl MotionScales {
    /// The range a preparation for warps with `motion_scale` needs: [`Self::AtLeastOne`] where
    /// both factors are `>= 1`, else [`Self::Any`].
    pub fn for_scale(motion_scale: Vec2) -> Self {
        if motion_scale.x >= 1.0 && motion_scale.y >= 1.0 {
            MotionScales::AtLeastOne
        } else {
            MotionScales::Any
        }
    }

    /// `true` if a preparation for this range serves warps with `motion_scale`.
    pub fn serves(self, motion_scale: Vec2) -> bool {
        self == MotionScales::Any || Self::for_scale(motion_scale) == MotionScales::AtLeastOne
    }
}

/// Where the motion bounds of one [`BoundFrame`] clip a sample's target: the frame-coordinate
/// box of a `w x h` image widened by [`clip_margin`] (or everything, [`Self::NONE`]).
///
/// The mipmap clips each level-1 texel as a whole ([`Self::clip_texel`]) rather than each of
/// its samples: a quarter of the work in the preparation's one pass, and a bound that contains
/// the per-sample clip of the texel's samples, so exact by the argument below.
///
/// Exactness, per frame axis: a solution `q` of `q + v(q) = p`, `p` in the image, lies in a cell
/// whose texels `i` (centres `q_i = q + d_i`, `|d_i| <= 1` per image axis, `<= sqrt 2` per
/// frame axis) have targets `t_i = q_i + v_i`, and
/// `p = sum w_i (t_i - d_i)` with convex weights (bilinear; a nearest sample is one texel), so
/// some texel has `t_i - d_i >= p`. Clipping replaces a `t_i` beyond the box's far side by the
/// side itself (`>= p + margin`; the margin also covers a converged point's 0.5 px residual),
/// one beyond the near side likewise: the largest `t_i - d_i`
/// stays `>= p` and the smallest `<= p`, so `p - q` stays within the clipped texels' motion
/// range, which is what the bound needs. At a scale `s >= 1` a clipped target `q_i + s v_i` is
/// still beyond the same side (the scaled bounds stay exact); below 1 it may not be.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ImageClip {
    pub lo: Vec2,
    pub hi: Vec2,
}

impl ImageClip {
    /// No clip ([`MotionScales::Any`]).
    pub const NONE: ImageClip = ImageClip { lo: Vec2::NEG_INFINITY, hi: Vec2::INFINITY };

    /// The clip of a `w x h` image in `frame` for `scales`.
    pub fn new(w: u32, h: u32, frame: BoundFrame, scales: MotionScales) -> Self {
        if scales == MotionScales::Any {
            return Self::NONE;
        }
        let (wf, hf) = (w as f32, h as f32);
        let corners =
            [Vec2::ZERO, Vec2::new(wf, 0.0), Vec2::new(0.0, hf), Vec2::new(wf, hf)].map(|c| frame.to_frame(c));
        let lo = corners.iter().fold(Vec2::INFINITY, |a, &c| a.min(c));
        let hi = corners.iter().fold(Vec2::NEG_INFINITY, |a, &c| a.max(c));
        let m = clip_margin(w, h);
        ImageClip { lo: lo - m, hi: hi + m }
    }

    /// The motion `u` (frame coordinates) of the sample whose pixel centre is `rq` (frame
    /// coordinates) as the exactness argument clips it: unchanged unless its target `rq + u`
    /// lies beyond the box, then the motion to the box's side. The mipmap clips whole texels
    /// ([`Self::clip_texel`], which contains this).
    #[cfg(test)]
    pub fn clip(&self, rq: Vec2, u: Vec2) -> Vec2 {
        let t = rq + u;
        let axis = |t: f32, u: f32, q: f32, lo: f32, hi: f32| {
            if t > hi {
                hi - q
            } else if t < lo {
                lo - q
            } else {
                u
            }
        };
        Vec2::new(axis(t.x, u.x, rq.x, self.lo.x, self.hi.x), axis(t.y, u.y, rq.y, self.lo.y, self.hi.y))
    }

    /// The frame-coordinate box `(lo, hi)` of the sample centres of level-1 block `(tx, ty)`
    /// (image pixels `2 tx + {0, 1}`, `2 ty + {0, 1}`, also where the block is cut by the
    /// image's edge): the first centre in the frame plus the frame's extent of the unit
    /// square ([`BlockExtent`]). Every build computes it with these operations.
    #[inline(always)]
    pub fn block_centres(frame: BoundFrame, ext: &BlockExtent, tx: usize, ty: usize) -> (Vec2, Vec2) {
        let r0 = frame.to_frame(Vec2::new(2.0 * tx as f32 + 0.5, 2.0 * ty as f32 + 0.5));
        (r0 + ext.lo, r0 + ext.hi)
    }

    /// The level-1 texel `[lo.x, lo.y, hi.x, hi.y]` (frame coordinates, the unclipped minima
    /// and maxima of its samples' motion) as it enters the mipmap, for a block whose sample
    /// centres lie in `[rq_lo, rq_hi]`: `lo` clamped to `[self.lo - rq_hi, self.hi - rq_hi]`,
    /// `hi` to `[self.lo - rq_lo, self.hi - rq_lo]` (compare-select max then min); an empty
    /// texel stays empty. Contains the per-sample clip of the same samples: `clip` is monotone
    /// in the motion and in `-rq`, so the min over the samples of `clip(rq_i, u_i)` is at least
    /// the clamp of `min u_i` to the box seen from the largest centre, and likewise for `hi`.
    #[inline(always)]
    pub fn clip_texel(&self, rq_lo: Vec2, rq_hi: Vec2, t: [f32; 4]) -> [f32; 4] {
        if t[0] > t[2] {
            return t;
        }
        let clamp = |v: f32, a: f32, b: f32| fmin(fmax(v, a), b);
        [
            clamp(t[0], self.lo.x - rq_hi.x, self.hi.x - rq_hi.x),
            clamp(t[1], self.lo.y - rq_hi.y, self.hi.y - rq_hi.y),
            clamp(t[2], self.lo.x - rq_lo.x, self.hi.x - rq_lo.x),
            clamp(t[3], self.lo.y - rq_lo.y, self.hi.y - rq_lo.y),
        ]
    }
}

/// The frame-coordinate extent of the unit square `[0, 1]^2` in a [`BoundFrame`]: what the
/// centres of a 2x2 block of samples span beyond its first one ([`ImageClip::block_centres`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct BlockExtent {
    pub lo: Vec2,
    pub hi: Vec2,
}

impl BlockExtent {
    /// The extent in `frame`: per frame axis, the sums of the negative (positive) parts of the
    /// axis' two components (`(0, 0)` and `(1, 1)` in the identity frame).
    pub fn new(frame: BoundFrame) -> Self {
        let (c, s) = (frame.axis.x, frame.axis.y);
        let (rx, ry) = ([c, s], [-s, c]);
        let neg = |r: [f32; 2]| fmin(r[0], 0.0) + fmin(r[1], 0.0);
        let pos = |r: [f32; 2]| fmax(r[0], 0.0) + fmax(r[1], 0.0);
        BlockExtent { lo: Vec2::new(neg(rx), neg(ry)), hi: Vec2::new(pos(rx), pos(ry)) }
    }
}

/// An axis-aligned box `[lo, hi]` of motion vectors in a [`BoundFrame`]. The empty bound has
/// `lo = +inf`, `hi = -inf`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bound {
    /// Component-wise minimum.
    pub lo: Vec2,
    /// Component-wise maximum.
    pub hi: Vec2,
}

impl Bound {
    /// The bound containing no motion.
    pub const EMPTY: Bound = Bound { lo: Vec2::splat(f32::INFINITY), hi: Vec2::splat(f32::NEG_INFINITY) };

    /// `true` if no motion lies in the bound.
    #[inline]
    pub fn is_empty(&self) -> bool {
        !(self.lo.x <= self.hi.x && self.lo.y <= self.hi.y)
    }
    /// Grows the bound to contain `u`.
    #[inline]
    pub fn include(&mut self, u: Vec2) {
        self.lo = self.lo.min(u);
        self.hi = self.hi.max(u);
    }
    /// Union of two bounds.
    #[inline]
    pub fn union(&self, o: &Bound) -> Bound {
        Bound { lo: self.lo.min(o.lo), hi: self.hi.max(o.hi) }
    }
    /// Intersection of two bounds (may be empty).
    #[inline]
    pub fn intersect(&self, o: &Bound) -> Bound {
        Bound { lo: self.lo.max(o.lo), hi: self.hi.min(o.hi) }
    }
    /// `hi - lo` (negative for the empty bound).
    #[inline]
    pub fn extent(&self) -> Vec2 {
        self.hi - self.lo
    }
    /// `true` if `u` lies in the bound (inclusive).
    #[inline]
    pub fn contains(&self, u: Vec2) -> bool {
        u.x >= self.lo.x && u.x <= self.hi.x && u.y >= self.lo.y && u.y <= self.hi.y
    }
    /// Area of the search region in pixels, counted as `(ex + 1)(ey + 1)` so that a degenerate
    /// (zero-extent) bound still compares by its other side; used to pick AAB vs OB.
    pub fn pixel_area(&self) -> f32 {
        if self.is_empty() {
            return 0.0;
        }
        let e = self.extent();
        (e.x + 1.0) * (e.y + 1.0)
    }
    /// The bound of `{s * u : u in self}` (component-wise product): `[s lo, s hi]` per axis,
    /// with lo and hi swapped where `s < 0`. Because rounding is monotone, scaling a min-max
    /// bound gives bit for bit the min-max of the scaled vectors (the mipmap of a scaled motion
    /// buffer, in the identity frame). Empty stays empty (no `0 * inf` NaN).
    #[inline]
    pub fn scaled(&self, s: Vec2) -> Bound {
        if self.is_empty() {
            return Bound::EMPTY;
        }
        let (a, b) = (s * self.lo, s * self.hi);
        let neg = s.cmplt(Vec2::ZERO);
        Bound { lo: Vec2::select(neg, b, a), hi: Vec2::select(neg, a, b) }
    }
    #[inline]
    fn from_texel(t: &[f32; 4]) -> Bound {
        Bound { lo: Vec2::new(t[0], t[1]), hi: Vec2::new(t[2], t[3]) }
    }
    #[inline]
    fn to_texel(self) -> [f32; 4] {
        [self.lo.x, self.lo.y, self.hi.x, self.hi.y]
    }
    /// The mipmap texel layout `[lo.x, lo.y, hi.x, hi.y]`.
    #[inline]
    pub(crate) fn to_texel_pub(self) -> [f32; 4] {
        self.to_texel()
    }
}

/// The tight bound of one target pixel: the motion bound (in the pyramid's frame) and the
/// search region it implies, `R p - [lo, hi]` in frame coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TightBound {
    /// Motion bound in frame coordinates.
    pub motion: Bound,
    /// Search region in frame coordinates: `[R p - motion.hi, R p - motion.lo]`.
    pub region: Bound,
    /// Lower bound of the target depth of every valid sample the region's look-up covers: no
    /// solution in the region is nearer. The multi-layer warp skips a layer whose `min_depth`
    /// is not below the best candidate found so far.
    pub min_depth: f32,
}

/// The texels of one mip level, the input of the next level's reduction.
struct LevelTexels<'a> {
    w: usize,
    h: usize,
    data: &'a [[f32; 4]],
    zmin: &'a [f32],
}

/// Row `ty` of the next coarser level from `below` (Sec. 3.3's min-max mipmap, and the min
/// depth mipmap beside it): each texel is the union of the (up to) 2x2 texels
/// under it, folded from empty in the order upper-left, upper-right, lower-left, lower-right.
/// `simd` takes the AVX2 build for the full 2x2 blocks (same compare-selects in the same
/// order: the same bits).
fn level_row(below: &LevelTexels<'_>, ty: usize, row: &mut [[f32; 4]], zrow: &mut [f32], simd: bool) {
    let (pw, y0) = (below.w, ty * 2);
    let y1 = (y0 + 2).min(below.h);
    // Full 2x2 blocks first, then the texels at the right and bottom borders.
    let full = if y1 == y0 + 2 { pw / 2 } else { 0 };
    let mut done = 0;
    #[cfg(target_arch = "x86_64")]
    if simd && full > 0 {
        // SAFETY: `simd` is only set where the CPU has AVX2 (or by tests that check it).
        done = unsafe { level_row_avx2::blocks(below, y0, &mut row[..full], &mut zrow[..full]) };
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = simd;
    for tx in done..row.len() {
        let (x0, x1) = (tx * 2, (tx * 2 + 2).min(pw));
        let (mut b, mut z) = (Bound::EMPTY, f32::INFINITY);
        for y in y0..y1 {
            for i in y * pw + x0..y * pw + x1 {
                b = b.union(&Bound::from_texel(&below.data[i]));
                z = fmin(z, below.zmin[i]);
            }
        }
        (row[tx], zrow[tx]) = (b.to_texel(), z);
    }
}

/// The AVX2 build of [`level_row`]'s full 2x2 blocks.
#[cfg(target_arch = "x86_64")]
mod level_row_avx2 {
    use super::LevelTexels;
    use std::arch::x86_64::*;

    /// The full blocks of a row pair from `y0` (both rows present, `row.len() <= w / 2`):
    /// min-max texels two at a time and min depths eight at a time; returns
    /// how many texels it wrote (a multiple of eight; the rest is left to the portable loop).
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn blocks(b: &LevelTexels<'_>, y0: usize, row: &mut [[f32; 4]], zrow: &mut [f32]) -> usize {
        let pw = b.w;
        // Multiples of eight texels: the min depths go eight at a time.
        let texels = row.len() / 8 * 8;
        debug_assert!(2 * row.len() <= pw && y0 + 1 < b.h);
        let (up, lo) = (y0 * pw, (y0 + 1) * pw);
        // `acc < next ? acc : next` / `acc > next ? acc : next`, as glam's and fmin / fmax's
        // compare-selects (the fold starts at the first texel: the union with empty is it).
        let fold4 = |a, b, c, d| {
            let mn = _mm256_min_ps(_mm256_min_ps(_mm256_min_ps(a, b), c), d);
            let mx = _mm256_max_ps(_mm256_max_ps(_mm256_max_ps(a, b), c), d);
            (mn, mx)
        };
        // Min-max texels [lo.x, lo.y, hi.x, hi.y]: two outputs per step.
        let data = b.data.as_ptr() as *const f32;
        for tx in (0..texels).step_by(2) {
            let ld = |r: usize| {
                let u0 = _mm256_loadu_ps(data.add(4 * (r + 2 * tx)));
                let u1 = _mm256_loadu_ps(data.add(4 * (r + 2 * tx + 2)));
                (_mm256_permute2f128_ps::<0x20>(u0, u1), _mm256_permute2f128_ps::<0x31>(u0, u1))
            };
            let ((a, bb), (c, d)) = (ld(up), ld(lo));
            let (mn, mx) = fold4(a, bb, c, d);
            _mm256_storeu_ps(row.as_mut_ptr().add(tx) as *mut f32, _mm256_blend_ps::<0b1100_1100>(mn, mx));
        }
        // Min depths: eight outputs per step (even / odd columns; one lane permutation for all).
        let z = b.zmin.as_ptr();
        for tx in (0..texels).step_by(8) {
            let eo = |r: usize| {
                let v0 = _mm256_loadu_ps(z.add(r + 2 * tx));
                let v1 = _mm256_loadu_ps(z.add(r + 2 * tx + 8));
                (_mm256_shuffle_ps::<0b10_00_10_00>(v0, v1), _mm256_shuffle_ps::<0b11_01_11_01>(v0, v1))
            };
            let ((a, bb), (c, d)) = (eo(up), eo(lo));
            let (mn, _) = fold4(a, bb, c, d);
            let mn = _mm256_castpd_ps(_mm256_permute4x64_pd::<0b11_01_10_00>(_mm256_castps_pd(mn)));
            _mm256_storeu_ps(zrow.as_mut_ptr().add(tx), mn);
        }
        texels
    }
}

/// One mip level: its size and where its texels start in the pyramid's buffers.
#[derive(Clone, Copy, Debug)]
struct Level {
    w: u32,
    h: u32,
    off: usize,
}

/// Min-max motion mipmap (Sec. 3.3) of one motion buffer in a [`BoundFrame`]. Levels `1..=top`
/// are stored (level 1 = 2x2 blocks); look-ups never go below level 1, which only makes a bound
/// coarser (still conservative) for regions of at most two pixels, where the search uses a
/// single seed anyway, and halves memory and build traffic.
pub struct MotionPyramid {
    width: u32,
    height: u32,
    frame: BoundFrame,
    /// `levels[i]` is mip level `i + 1`.
    levels: Vec<Level>,
    /// Min-max motion per texel, `[lo.x, lo.y, hi.x, hi.y]`, all levels one after the other
    /// (level 1 first): one buffer, so one preparation's allocation serves the next.
    data: Vec<[f32; 4]>,
    /// Minimal target depth of the valid samples per texel (`+inf` if none), same layout. Kept
    /// apart: only the pruning of later layers reads it.
    zmin: Vec<f32>,
}

/// `ceil(log2(n))` for `n >= 1`, 0 for `n <= 1`.
#[inline]
fn ceil_log2(n: u32) -> u32 {
    if n <= 1 {
        0
    } else {
        32 - (n - 1).leading_zeros()
    }
}

/// [`MotionPyramid::raw`]: the texels of every level and their layout.
pub(crate) type RawPyramid<'a, L> = (&'a [[f32; 4]], &'a [f32], L);

impl MotionPyramid {
    /// Builds the axis-aligned pyramid of `motion` (valid samples as in [`is_valid_sample`]).
    /// Errors on a zero-size buffer or NaN motion / depth.
    pub fn build(motion: &Image<Motion>) -> Result<Self> {
        Self::build_in_frame(motion, BoundFrame::IDENTITY)
    }

    /// Builds the pyramid of the motion rotated into `frame` (oriented bounds, Sec. 3.3).
    pub fn build_in_frame(motion: &Image<Motion>, frame: BoundFrame) -> Result<Self> {
        motion.check_nonempty("motion buffer")?;
        if motion.data().iter().any(|m| m.v.is_nan() || m.depth.is_nan()) {
            return Err(Error::invalid("motion buffer holds NaN values"));
        }
        if !frame.axis.is_finite() || (frame.axis.length() - 1.0).abs() > 1e-3 {
            return Err(Error::invalid(format!("bound frame axis must be a unit vector, got {:?}", frame.axis)));
        }
        Ok(Self::from_samples(motion.data(), motion.width(), motion.height(), frame, ImageClip::NONE))
    }

    /// Builds from raw samples (already validated, `w * h` long, `w, h >= 1`), their motion
    /// clipped by `clip` (in `frame`).
    pub(crate) fn from_samples(samples: &[Motion], w: u32, h: u32, frame: BoundFrame, clip: ImageClip) -> Self {
        debug_assert_eq!(samples.len(), w as usize * h as usize);
        // Level 1 straight from the samples (2x2 blocks, partial at odd edges).
        let (lw, lh) = (w.div_ceil(2), h.div_ceil(2));
        // Motion min-max and min depth in one pass over the samples (one read of the buffer).
        let mut data = vec![Bound::EMPTY.to_texel(); lw as usize * lh as usize];
        let mut zmin = vec![f32::INFINITY; lw as usize * lh as usize];
        let blocks = Level1Blocks::new(samples, w, h, frame, clip);
        data.par_chunks_mut(lw as usize).zip(zmin.par_chunks_mut(lw as usize)).enumerate().for_each(
            |(ty, (row, zrow))| {
                for (tx, (out, zout)) in row.iter_mut().zip(zrow.iter_mut()).enumerate() {
                    (*out, *zout) = blocks.texel(tx, ty);
                }
            },
        );
        Self::from_level1(w, h, frame, data, zmin)
    }

    /// The texel buffers (every level), for reuse by the next preparation.
    pub(crate) fn into_buffers(self) -> (Vec<[f32; 4]>, Vec<f32>) {
        (self.data, self.zmin)
    }

    /// Builds levels `2..=top` over a given level 1 (the first `ceil(w / 2) x ceil(h / 2)`
    /// min-max texels of `data` in `frame` and their min depths; anything
    /// after them is overwritten), e.g. from the fused pass of `PreparedLayer::prepare_stack`
    /// that validates the samples and reduces them at once.
    pub(crate) fn from_level1(w: u32, h: u32, frame: BoundFrame, mut data: Vec<[f32; 4]>, mut zmin: Vec<f32>) -> Self {
        let top = ceil_log2(w.max(h)).max(1);
        let (lw, lh) = (w.div_ceil(2), h.div_ceil(2));
        let n1 = lw as usize * lh as usize;
        debug_assert!(data.len() >= n1 && zmin.len() >= n1);
        let mut levels: Vec<Level> = Vec::with_capacity(top as usize);
        levels.push(Level { w: lw, h: lh, off: 0 });
        let mut total = n1;
        for _ in 1..top {
            let prev = *levels.last().expect("level 1 exists");
            let (lw, lh) = (prev.w.div_ceil(2), prev.h.div_ceil(2));
            levels.push(Level { w: lw, h: lh, off: total });
            total += lw as usize * lh as usize;
        }
        data.resize(total, Bound::EMPTY.to_texel());
        zmin.resize(total, f32::INFINITY);
        for k in 1..levels.len() {
            let (prev, cur) = (levels[k - 1], levels[k]);
            let n = cur.w as usize * cur.h as usize;
            let (below, above) = data.split_at_mut(cur.off);
            let (zbelow, zabove) = zmin.split_at_mut(cur.off);
            let below = LevelTexels {
                w: prev.w as usize,
                h: prev.h as usize,
                data: &below[prev.off..],
                zmin: &zbelow[prev.off..],
            };
            let cw = cur.w as usize;
            above[..n]
                .par_chunks_mut(cw)
                .zip(zabove[..n].par_chunks_mut(cw))
                .enumerate()
                .for_each(|(ty, (row, zrow))| level_row(&below, ty, row, zrow, crate::simd::has_avx2()));
        }
        debug_assert!(levels.last().map(|l| l.w == 1 && l.h == 1).unwrap_or(false));
        MotionPyramid { width: w, height: h, frame, levels, data, zmin }
    }

    /// The raw layout for the AVX2 tightening: min-max texels, min-depth texels, and per level
    /// (1..=top) its width, height and first texel.
    pub(crate) fn raw(&self) -> RawPyramid<'_, impl Iterator<Item = (u32, u32, usize)> + '_> {
        (&self.data, &self.zmin, self.levels.iter().map(|l| (l.w, l.h, l.off)))
    }

    /// Image size the pyramid was built for.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }
    /// The frame the bounds are expressed in.
    pub fn frame(&self) -> BoundFrame {
        self.frame
    }
    /// Highest mip level (its single texel is the global bound).
    pub fn top_level(&self) -> u32 {
        self.levels.len() as u32
    }
    /// Size in texels of mip level `level` (`1..=top_level`).
    pub fn level_size(&self, level: u32) -> (u32, u32) {
        let l = &self.levels[(level.clamp(1, self.top_level()) - 1) as usize];
        (l.w, l.h)
    }
    /// The texel `(tx, ty)` of mip level `level` (`1..=top_level`), as a bound.
    pub fn texel(&self, level: u32, tx: u32, ty: u32) -> Bound {
        let l = &self.levels[(level.clamp(1, self.top_level()) - 1) as usize];
        Bound::from_texel(&self.data[l.off + ty as usize * l.w as usize + tx as usize])
    }
    /// The global bound of all valid motion (top texel, Fig. 5 `texture(vec2(0), MAX_LOD)`);
    /// empty if no sample is valid.
    pub fn global(&self) -> Bound {
        self.texel(self.top_level(), 0, 0)
    }

    /// The mip level used for an inclusive pixel range (Fig. 5's `ceil(log2(max(a, b)))`, in
    /// integer form): the smallest level at which the range spans at most two texels per axis,
    /// so four corner look-ups cover it; clamped to `1..=top_level`.
    pub fn level_for_range(&self, ix0: u32, iy0: u32, ix1: u32, iy1: u32) -> u32 {
        // A run of e + 1 pixels spans at most ceil(e / 2^l) + 1 texels at level l.
        let e = (ix1 - ix0).max(iy1 - iy0);
        ceil_log2(e).clamp(1, self.top_level())
    }

    /// Min-max of the valid motion over the inclusive pixel range, from the four corner
    /// look-ups at [`Self::level_for_range`] (conservative: covers every pixel of the range).
    #[inline]
    pub fn lookup_range(&self, ix0: u32, iy0: u32, ix1: u32, iy1: u32) -> Bound {
        let level = self.level_for_range(ix0, iy0, ix1, iy1);
        let l = &self.levels[(level - 1) as usize];
        // At this level the range spans at most 2x2 texels (see `level_for_range`; the top
        // level has one texel), so four direct reads cover it (duplicates are harmless for a
        // union): the hot path of every tightening step, without the generic loop.
        let (tx0, tx1) = ((ix0 >> level).min(l.w - 1) as usize, (ix1 >> level).min(l.w - 1) as usize);
        let (ty0, ty1) = ((iy0 >> level).min(l.h - 1) as usize, (iy1 >> level).min(l.h - 1) as usize);
        debug_assert!(tx1 - tx0 <= 1 && ty1 - ty0 <= 1);
        let lw = l.w as usize;
        let data = &self.data[l.off..l.off + lw * l.h as usize];
        // SAFETY: tx0, tx1 <= l.w - 1 and ty0, ty1 <= l.h - 1 (clamped above), and `data` is
        // the level's `l.w * l.h` texels.
        let t = |x: usize, y: usize| Vec4::from_array(unsafe { *data.get_unchecked(y * lw + x) });
        let (a, b, c, d) = (t(tx0, ty0), t(tx1, ty0), t(tx0, ty1), t(tx1, ty1));
        crate::stats::count(crate::stats::Counter::MipTexels, 4);
        // Four lanes at once: lanes 0-1 (lo) take the min, lanes 2-3 (hi) the max. Texels hold
        // no NaN (NaN motion is rejected, empty texels are +-inf), where the compare-select
        // `min`/`max` equal `f32::min`/`f32::max` (up to the sign of a zero, which no bound
        // comparison or region sees).
        let (lo, hi) = (a.min(b).min(c.min(d)), a.max(b).max(c.max(d)));
        Bound { lo: Vec2::new(lo.x, lo.y), hi: Vec2::new(hi.z, hi.w) }
    }

    /// Like [`Self::lookup_range`] at an explicit level (clamped to `1..=top_level`); at levels
    /// finer than [`Self::level_for_range`] it reads every texel the range touches.
    #[inline]
    pub fn lookup_range_at(&self, level: u32, ix0: u32, iy0: u32, ix1: u32, iy1: u32) -> Bound {
        let level = level.clamp(1, self.top_level());
        let l = &self.levels[(level - 1) as usize];
        let (tx0, tx1) = (ix0 >> level, (ix1 >> level).min(l.w - 1));
        let (ty0, ty1) = (iy0 >> level, (iy1 >> level).min(l.h - 1));
        let mut b = Bound::EMPTY;
        for ty in ty0..=ty1 {
            let row = &self.data[l.off + ty as usize * l.w as usize..];
            for t in &row[tx0 as usize..=tx1 as usize] {
                b = b.union(&Bound::from_texel(t));
            }
        }
        b
    }

    /// The level [`Self::level_for_range`] picks for an inclusive pixel range and the texels
    /// `[tx0, ty0, tx1, ty1]` (inclusive) the range touches there: what the look-ups of the
    /// min-depth and gradient mipmaps (same layout) read.
    #[inline]
    pub(crate) fn texels_of_range(&self, ix0: u32, iy0: u32, ix1: u32, iy1: u32) -> (u32, [u32; 4]) {
        let level = self.level_for_range(ix0, iy0, ix1, iy1);
        let l = &self.levels[(level - 1) as usize];
        (level, [ix0 >> level, iy0 >> level, (ix1 >> level).min(l.w - 1), (iy1 >> level).min(l.h - 1)])
    }

    /// Minimal target depth of the valid samples over the inclusive pixel range (same four
    /// corner look-ups as [`Self::lookup_range`]); `+inf` if none.
    #[inline]
    pub fn lookup_min_depth(&self, ix0: u32, iy0: u32, ix1: u32, iy1: u32) -> f32 {
        let (level, [tx0, ty0, tx1, ty1]) = self.texels_of_range(ix0, iy0, ix1, iy1);
        let l = &self.levels[(level - 1) as usize];
        let mut z = f32::INFINITY;
        crate::stats::count(crate::stats::Counter::DepthTexels, ((tx1 - tx0 + 1) * (ty1 - ty0 + 1)) as u64);
        for ty in ty0..=ty1 {
            let row = &self.zmin[l.off + ty as usize * l.w as usize..];
            for t in &row[tx0 as usize..=tx1 as usize] {
                z = z.min(*t);
            }
        }
        z
    }

    /// The box of target positions `p_lo..=p_hi` in frame coordinates (the bounding box of its
    /// rotated corners).
    #[inline]
    pub(crate) fn frame_box(&self, p_lo: Vec2, p_hi: Vec2) -> (Vec2, Vec2) {
        if self.frame.is_identity() {
            (p_lo, p_hi)
        } else if p_lo == p_hi {
            let c = self.frame.to_frame(p_lo);
            (c, c)
        } else {
            let f = &self.frame;
            let c = [
                f.to_frame(p_lo),
                f.to_frame(p_hi),
                f.to_frame(Vec2::new(p_lo.x, p_hi.y)),
                f.to_frame(Vec2::new(p_hi.x, p_lo.y)),
            ];
            (c[0].min(c[1]).min(c[2]).min(c[3]), c[0].max(c[1]).max(c[2]).max(c[3]))
        }
    }

    /// Search region of target pixel position `p` under motion bound `b`, in frame coordinates.
    #[inline]
    pub fn region(&self, p: Vec2, b: &Bound) -> Bound {
        let c = if self.frame.is_identity() { p } else { self.frame.to_frame(p) };
        Bound { lo: c - b.hi, hi: c - b.lo }
    }

    /// Inclusive pixel range covered by a search region (frame coordinates), grown by `expand`
    /// pixels (the sampling footprint: 0.5 for bilinear), clipped to the image; `None` if the
    /// region misses the image (no source sample can move to `p`).
    #[inline]
    pub fn pixel_range(&self, region: &Bound, expand: f32) -> Option<(u32, u32, u32, u32)> {
        let (mut lo, mut hi) = (region.lo, region.hi);
        if !self.frame.is_identity() {
            // Image-space AABB of the rotated box, `from_frame` of the extreme corner per output
            // component: x = c u.x - s u.y is smallest at (c >= 0 ? lo.x : hi.x, s >= 0 ? hi.y :
            // lo.y), y = s u.x + c u.y at (s >= 0 ? lo.x : hi.x, c >= 0 ? lo.y : hi.y). Rounding
            // is monotone, so this picks bit for bit the min / max of the four rotated corners
            // (same products and sums as `from_frame`) for a fraction of the work.
            let (c, s) = (self.frame.axis.x, self.frame.axis.y);
            let (xa, xb) = if c >= 0.0 { (lo.x, hi.x) } else { (hi.x, lo.x) };
            let (ya, yb) = if s >= 0.0 { (hi.y, lo.y) } else { (lo.y, hi.y) };
            let (sa, sb) = if s >= 0.0 { (lo.x, hi.x) } else { (hi.x, lo.x) };
            let (ca, cb) = if c >= 0.0 { (lo.y, hi.y) } else { (hi.y, lo.y) };
            lo = Vec2::new(c * xa - s * ya, s * sa + c * ca);
            hi = Vec2::new(c * xb - s * yb, s * sb + c * cb);
        }
        lo -= Vec2::splat(expand);
        hi += Vec2::splat(expand);
        let (w, h) = (self.width as f32, self.height as f32);
        if !(hi.x >= 0.0 && hi.y >= 0.0 && lo.x < w && lo.y < h) {
            return None;
        }
        // Past the test no coordinate is NaN, `lo < (w, h)` and `hi >= 0`: the clamped values
        // lie in `[0, w - 1]` x `[0, h - 1]`, where compare-select clamps equal `f32::max/min`
        // and truncation needs no saturation.
        let cl = |v: f32, m: f32| {
            if v < 0.0 {
                0.0
            } else if v > m {
                m
            } else {
                v
            }
        };
        // SAFETY: each argument lies in [0, w - 1] or [0, h - 1] (see above): in u32 range.
        let u = |v: f32| -> u32 { unsafe { v.to_int_unchecked() } };
        let ix0 = u(cl(lo.x, w - 1.0)).min(self.width - 1);
        let iy0 = u(cl(lo.y, h - 1.0)).min(self.height - 1);
        let ix1 = u(cl(hi.x, w - 1.0)).min(self.width - 1);
        let iy1 = u(cl(hi.y, h - 1.0)).min(self.height - 1);
        Some((ix0, iy0, ix1, iy1))
    }

    /// Iterative bound tightening of Fig. 5 for target position `p`: start from the global
    /// bound, then `iterations` times look up the mipmap over the current search region and
    /// intersect. Returns `None` when no valid sample can be a solution (the region misses the
    /// image or holds no valid motion — "usually background"), which lets the warp skip the
    /// pixel. `expand` is the sampling footprint in pixels (0.5 for bilinear, 0 for nearest).
    ///
    /// Conservative by induction: every solution's motion lies in the current bound, so the
    /// solution lies in the region, so its motion is in the look-up over the region; the
    /// intersection of both therefore still contains it.
    #[inline]
    pub fn tight_bound(&self, p: Vec2, iterations: u32, expand: f32) -> Option<TightBound> {
        self.tight_bound_box(p, p, self.global(), iterations, expand)
    }

    /// [`Self::tight_bound`] for every target position in the box `[p_lo, p_hi]` at once,
    /// starting from `start` (which must contain the motion of every solution, e.g. the global
    /// bound or the bound of an enclosing box). The search region is the union over the box,
    /// `[c_lo - hi, c_hi - lo]` with `[c_lo, c_hi]` the frame bounds of the box, so the result
    /// is a valid start for any pixel inside it: the warp tightens per 4x4 tile first, then per
    /// pixel from the tile's bound, which gives the same per-pixel bound for a fraction of the
    /// look-ups. Stops early at the fixed point of the tightening. `min_depth` is left at
    /// `-inf` (unknown); see [`Self::tight_bound_box_with_depth`].
    #[inline]
    pub fn tight_bound_box(
        &self,
        p_lo: Vec2,
        p_hi: Vec2,
        start: Bound,
        iterations: u32,
        expand: f32,
    ) -> Option<TightBound> {
        self.tight_bound_box_scaled(p_lo, p_hi, start, iterations, expand, Vec2::ONE)
    }

    /// [`Self::tight_bound_box`] for the motion field `scale * v` (component-wise, see
    /// [`crate::WarpParams::motion_scale`]): every mipmap look-up is scaled with
    /// [`Bound::scaled`] before the intersection; `start` must already be a bound of the scaled
    /// motion (e.g. `global().scaled(scale)`). In the identity frame this is bit for bit the
    /// tightening in the mipmap of the scaled buffer; in a rotated frame only a uniform scale is
    /// meaningful (`R (s v) = s R v`).
    #[inline]
    pub fn tight_bound_box_scaled(
        &self,
        p_lo: Vec2,
        p_hi: Vec2,
        start: Bound,
        iterations: u32,
        expand: f32,
        scale: Vec2,
    ) -> Option<TightBound> {
        let unit = scale == Vec2::ONE;
        crate::stats::count(crate::stats::Counter::Tightenings, 1);
        let mut b = start;
        if b.is_empty() {
            return None;
        }
        let (c_lo, c_hi) = self.frame_box(p_lo, p_hi);
        let region_of = |b: &Bound| Bound { lo: c_lo - b.hi, hi: c_hi - b.lo };
        let mut region = region_of(&b);
        let mut range = self.pixel_range(&region, expand)?;
        for _ in 0..iterations {
            let mut m = self.lookup_range(range.0, range.1, range.2, range.3);
            if !unit {
                m = m.scaled(scale);
            }
            let nb = b.intersect(&m);
            if nb.is_empty() {
                return None;
            }
            if nb == b {
                // Fixed point of the tightening: further look-ups return the same texels.
                break;
            }
            b = nb;
            region = region_of(&b);
            let next = self.pixel_range(&region, expand)?;
            if next == range {
                // Same texels again: the next look-up returns `m` and `b ∩ m == b` (b already
                // lies in m), i.e. the fixed point; skip that look-up.
                break;
            }
            range = next;
        }
        Some(TightBound { motion: b, region, min_depth: f32::NEG_INFINITY })
    }

    /// [`Self::tight_bound_box`] plus [`TightBound::min_depth`] over the final region (one more
    /// four-texel look-up).
    #[inline]
    pub fn tight_bound_box_with_depth(
        &self,
        p_lo: Vec2,
        p_hi: Vec2,
        start: Bound,
        iterations: u32,
        expand: f32,
    ) -> Option<TightBound> {
        self.tight_bound_box_with_depth_scaled(p_lo, p_hi, start, iterations, expand, Vec2::ONE)
    }

    /// [`Self::tight_bound_box_with_depth`] for the scaled motion field (see
    /// [`Self::tight_bound_box_scaled`]); the min-depth look-up is unaffected by the scale.
    #[inline]
    pub fn tight_bound_box_with_depth_scaled(
        &self,
        p_lo: Vec2,
        p_hi: Vec2,
        start: Bound,
        iterations: u32,
        expand: f32,
        scale: Vec2,
    ) -> Option<TightBound> {
        let mut tb = self.tight_bound_box_scaled(p_lo, p_hi, start, iterations, expand, scale)?;
        let r = self.pixel_range(&tb.region, expand)?;
        tb.min_depth = self.lookup_min_depth(r.0, r.1, r.2, r.3);
        Some(tb)
    }
}

/// Global bound of the valid samples of a `w`-wide image in `frame`, their level-1 texels
/// clipped by `clip` ([`ImageClip::clip_texel`]; one parallel pass): the union of the texels
/// the fused preparation (`PreparedLayer::prepare_stack_for`) writes, which is tested against
/// it.
#[cfg(any(test, feature = "gpu"))]
pub(crate) fn global_bound(samples: &[Motion], w: u32, frame: BoundFrame, clip: ImageClip) -> Bound {
    let h = (samples.len() / w as usize) as u32;
    let blocks = Level1Blocks::new(samples, w, h, frame, clip);
    (0..h.div_ceil(2) as usize)
        .into_par_iter()
        .map(|ty| {
            (0..w.div_ceil(2) as usize).fold(Bound::EMPTY, |g, tx| g.union(&Bound::from_texel(&blocks.texel(tx, ty).0)))
        })
        .reduce(|| Bound::EMPTY, |a, b| a.union(&b))
}

/// The level-1 texels of a `w x h` buffer of raw samples in `frame`, clipped by `clip`: what
/// the fused preparation computes in its pass, for the builders that start from a `Motion`
/// buffer ([`MotionPyramid::from_samples`], [`global_bound`]).
struct Level1Blocks<'a> {
    samples: &'a [Motion],
    w: usize,
    h: usize,
    frame: BoundFrame,
    ext: BlockExtent,
    clip: ImageClip,
}

impl<'a> Level1Blocks<'a> {
    fn new(samples: &'a [Motion], w: u32, h: u32, frame: BoundFrame, clip: ImageClip) -> Self {
        Level1Blocks { samples, w: w as usize, h: h as usize, frame, ext: BlockExtent::new(frame), clip }
    }

    /// Texel `(tx, ty)` (`[lo.x, lo.y, hi.x, hi.y]`, the 2x2 block's valid motions in the frame,
    /// [`ImageClip::clip_texel`]) and the block's min target depth.
    #[inline]
    fn texel(&self, tx: usize, ty: usize) -> ([f32; 4], f32) {
        let identity = self.frame.is_identity();
        let (x0, x1) = (2 * tx, (2 * tx + 2).min(self.w));
        let mut b = Bound::EMPTY;
        let mut z = f32::INFINITY;
        for y in 2 * ty..(2 * ty + 2).min(self.h) {
            for m in &self.samples[y * self.w + x0..y * self.w + x1] {
                if is_valid_sample(m) {
                    b.include(if identity { m.v } else { self.frame.to_frame(m.v) });
                    z = z.min(m.depth);
                }
            }
        }
        let (rq_lo, rq_hi) = ImageClip::block_centres(self.frame, &self.ext, tx, ty);
        (self.clip.clip_texel(rq_lo, rq_hi, b.to_texel()), z)
    }
}

/// PCA frame of ~`n` motion vectors sampled on a regular grid over the image (Sec. 3.3: "a
/// small number (e.g., 64) usually suffices"). Falls back to a denser grid if fewer than 8 grid
/// samples are valid, and to the identity frame when motion is isotropic or absent.
pub fn pca_frame(samples: &[Motion], w: u32, h: u32, n: u32) -> BoundFrame {
    pca_frame_by(w, h, n, |i| {
        let m = &samples[i];
        is_valid_sample(m).then_some(m.v)
    })
}

/// [`pca_frame`] over a `w x h` image given as `motion(i)` = the motion of pixel `i` (row-major)
/// if it is a valid sample, else `None` (lets the caller validate on the fly, reading only the
/// grid pixels).
pub(crate) fn pca_frame_by(w: u32, h: u32, n: u32, motion: impl Fn(usize) -> Option<Vec2>) -> BoundFrame {
    let mut pts: Vec<Vec2> = Vec::with_capacity(n as usize);
    for grid in [(n as f32).sqrt().ceil().max(1.0) as u32, 32] {
        pts.clear();
        for j in 0..grid {
            for i in 0..grid {
                let x = (((i as f32 + 0.5) * w as f32 / grid as f32) as u32).min(w - 1);
                let y = (((j as f32 + 0.5) * h as f32 / grid as f32) as u32).min(h - 1);
                if let Some(v) = motion(y as usize * w as usize + x as usize) {
                    pts.push(v);
                }
            }
        }
        if pts.len() >= 8 {
            break;
        }
    }
    if pts.len() < 2 {
        return BoundFrame::IDENTITY;
    }
    let mean = pts.iter().copied().sum::<Vec2>() / pts.len() as f32;
    let (mut sxx, mut syy, mut sxy) = (0.0f32, 0.0f32, 0.0f32);
    for p in &pts {
        let d = *p - mean;
        sxx += d.x * d.x;
        syy += d.y * d.y;
        sxy += d.x * d.y;
    }
    // Isotropic (or constant) motion: no preferred axis.
    if (sxx - syy).abs() + 2.0 * sxy.abs() <= 1e-6 * (sxx + syy).max(1e-12) {
        return BoundFrame::IDENTITY;
    }
    BoundFrame::from_angle(0.5 * (2.0 * sxy).atan2(sxx - syy))
}

/// Picks the frame for a layer of `w x h` samples (invalid ones: not in the mipmap) under
/// `kind`: identity for Global/Tight; for Oriented the PCA frame if its global bound (clipped for
/// `scales`) has a smaller area than the axis-aligned one (per frame, Sec. 3.3).
#[cfg(any(test, feature = "gpu"))]
pub(crate) fn choose_frame(
    samples: &[Motion],
    w: u32,
    h: u32,
    kind: crate::BoundKind,
    scales: MotionScales,
) -> BoundFrame {
    match kind {
        crate::BoundKind::Global | crate::BoundKind::Tight => BoundFrame::IDENTITY,
        crate::BoundKind::Oriented => {
            let ob = pca_frame(samples, w, h, 64);
            if ob.is_identity() {
                return ob;
            }
            let area = |f: BoundFrame| global_bound(samples, w, f, ImageClip::new(w, h, f, scales)).pixel_area();
            let (a_aab, a_ob) = (area(BoundFrame::IDENTITY), area(ob));
            if a_ob < a_aab {
                ob
            } else {
                BoundFrame::IDENTITY
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg32;

    fn random_motion(w: u32, h: u32, seed: u64, empty_frac: f32) -> Image<Motion> {
        let mut rng = Pcg32::seed_from_u64(seed);
        Image::from_fn(w, h, |_, _| {
            let v = Vec2::new(rng.random_range(-40.0..40.0), rng.random_range(-40.0..40.0));
            let depth = if rng.random::<f32>() < empty_frac { 1.0 } else { rng.random_range(0.0..0.999) };
            Motion { v, depth }
        })
    }

    fn brute(m: &Image<Motion>, frame: BoundFrame, x0: u32, y0: u32, x1: u32, y1: u32) -> Bound {
        let mut b = Bound::EMPTY;
        for y in y0..=y1 {
            for x in x0..=x1 {
                let s = m.get(x, y);
                if is_valid_sample(s) {
                    b.include(frame.to_frame(s.v));
                }
            }
        }
        b
    }

    /// The AVX2 reduction of a mip level's full 2x2 blocks gives the portable fold's bits
    /// (min-max texels and min depths), on random texels with empty ones (+-inf), signed
    /// zeros and ties, at sizes that leave odd columns, odd rows and short rows to the portable
    /// loop.
    #[test]
    fn avx2_level_reduction_equals_the_portable_one() {
        if !crate::simd::has_avx2() {
            eprintln!("note: no AVX2 on this CPU; both runs take the portable code");
        }
        let mut rng = Pcg32::seed_from_u64(7);
        let v = |rng: &mut Pcg32| match rng.random_range(0..8) {
            0 => f32::INFINITY,
            1 => f32::NEG_INFINITY,
            2 => 0.0,
            3 => -0.0,
            4 => 1.5,
            _ => rng.random_range(-30.0..30.0f32),
        };
        for (w, h) in [(1usize, 1usize), (2, 2), (3, 5), (17, 9), (33, 8), (40, 41), (64, 3)] {
            let n = w * h;
            let data: Vec<[f32; 4]> = (0..n).map(|_| [v(&mut rng), v(&mut rng), v(&mut rng), v(&mut rng)]).collect();
            let zmin: Vec<f32> = (0..n).map(|_| v(&mut rng)).collect();
            let below = LevelTexels { w, h, data: &data, zmin: &zmin };
            let (cw, ch) = (w.div_ceil(2), h.div_ceil(2));
            let run = |simd: bool| {
                let (mut d, mut z) = (vec![[0f32; 4]; cw * ch], vec![0f32; cw * ch]);
                for ty in 0..ch {
                    let r = ty * cw..(ty + 1) * cw;
                    level_row(&below, ty, &mut d[r.clone()], &mut z[r], simd);
                }
                let bits = |x: &[f32]| x.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
                (bits(d.as_flattened()), bits(&z))
            };
            let (fast, portable) = (run(crate::simd::has_avx2()), run(false));
            assert!(fast == portable, "{w}x{h}");
            // And the fold is the union of the 2x2 block: spot-check the first texel.
            let (d, _) = portable;
            let mut b = Bound::EMPTY;
            for (y, x) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                if y < h && x < w {
                    b = b.union(&Bound::from_texel(&data[y * w + x]));
                }
            }
            assert_eq!(d[..4], b.to_texel().map(f32::to_bits), "{w}x{h}");
        }
    }

    /// An affine motion field `v(q) = A q + c` at depth 0.5 (`w x h`).
    fn affine(w: u32, h: u32, a: [[f32; 2]; 2], c: Vec2) -> Image<Motion> {
        Image::from_fn(w, h, |x, y| {
            let q = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            Motion { v: Vec2::new(a[0][0] * q.x + a[0][1] * q.y, a[1][0] * q.x + a[1][1] * q.y) + c, depth: 0.5 }
        })
    }

    /// A prepared layer of motion `m` over a source depth of 0.5 (every sample valid where
    /// `m` says so), for the motion as given ([`MotionScales::AtLeastOne`]: monotonicity test).
    fn prepared(m: &Image<Motion>) -> crate::PreparedLayer {
        prepared_for(m, MotionScales::AtLeastOne)
    }

    /// [`prepared`] for the motion scales `scales` ([`MotionScales::Any`]: contraction test).
    fn prepared_for(m: &Image<Motion>, scales: MotionScales) -> crate::PreparedLayer {
        let depth = Image::new(m.width(), m.height(), 0.5f32);
        let layer = crate::WarpLayer { depth: &depth, motion: m };
        crate::PreparedLayer::new_for(&layer, crate::BoundKind::Tight, scales).unwrap()
    }

    /// The gradient mipmap of an affine field `v = A q + c` holds what its one-seed test needs
    /// everywhere (bilinear interpolation of an affine field is the field): shared by scaled
    /// warps, the squared rows of `A` and the contraction test
    /// `sx^2 |row x|^2 + sy^2 |row y|^2 < 1/2`; for the motion as given, the fold
    /// `|a01 + a10| / 2 - min(a00, a11)` and monotonicity, `max(sx, sy) fold < 1`.
    #[test]
    fn gradient_of_an_affine_field_is_its_jacobian() {
        let m = affine(37, 29, [[0.3, 0.1], [0.0, -0.2]], Vec2::new(-4.0, 2.0));
        let (shared, given) = (prepared_for(&m, MotionScales::Any), prepared(&m));
        let pyr = shared.pyramid();
        let (w, h) = pyr.size();
        for (x0, y0, x1, y1) in [(0, 0, w - 1, h - 1), (3, 4, 9, 5), (20, 10, 20, 10)] {
            let [gx, gy] = shared.lookup_gradient(x0, y0, x1, y1);
            assert!((gx - 0.1).abs() < 1e-5 && (gy - 0.04).abs() < 1e-5, "{gx} {gy}");
            // |0.1 + 0| / 2 - min(0.3, -0.2).
            let [fold, again] = given.lookup_gradient(x0, y0, x1, y1);
            assert!((fold - 0.25).abs() < 1e-5 && fold == again, "{fold}");
        }
        let (p_lo, p_hi) = (Vec2::new(12.5, 10.5), Vec2::new(15.5, 13.5));
        let b = pyr.tight_bound_box(p_lo, p_hi, pyr.global(), 6, 0.5).unwrap().motion;
        let unique = |layer: &crate::PreparedLayer, s: Vec2| layer.unique_solution(p_lo, p_hi, &b, s);
        // Contraction: 0.1 + 0.04 < 0.5, 4 (0.1 + 0.04) = 0.56 >= 0.5, 0.1 + 4 * 0.04 = 0.26 < 0.5,
        // either sign.
        assert!(unique(&shared, Vec2::ONE));
        assert!(!unique(&shared, Vec2::splat(2.0)));
        assert!(unique(&shared, Vec2::new(1.0, 2.0)));
        assert!(unique(&shared, Vec2::new(-1.0, 2.0)));
        // Monotone: 2 * 0.25 < 1 (where the contraction fails), 3 * 0.25 < 1, 4 * 0.25 >= 1.
        assert!(unique(&given, Vec2::ONE));
        assert!(unique(&given, Vec2::splat(2.0)));
        assert!(unique(&given, Vec2::new(1.0, 3.0)));
        assert!(!unique(&given, Vec2::new(4.0, 1.0)));
        // A magnifying field (|Dv| = 0.6 per axis: 0.36 + 0.36 >= 0.5) is no contraction, but
        // monotone (fold -0.6); one folding along x (dvx/dx = -1.2: fold 1.2) is neither.
        let zoom = affine(37, 29, [[0.6, 0.0], [0.0, 0.6]], Vec2::ZERO);
        for (m, scales, want) in [
            (&zoom, MotionScales::Any, false),
            (&zoom, MotionScales::AtLeastOne, true),
            (&affine(37, 29, [[-1.2, 0.0], [0.0, 0.0]], Vec2::ZERO), MotionScales::AtLeastOne, false),
        ] {
            let layer = prepared_for(m, scales);
            assert_eq!(layer.unique_solution(p_lo, p_hi, &layer.pyramid().global(), Vec2::ONE), want, "{scales:?}");
        }
    }

    /// A depth step or an empty texel in the region stops the unique-solution test (the fetch
    /// does not interpolate across them); a region clear of them passes. So does, for
    /// monotonicity, a smaller step (above [`crate::sampling::SURFACE_DEPTH_STEP`]) where the
    /// motions move apart by a pixel or more (1.2 px: the fetch samples it nearest), not where
    /// they agree (0.8 px) or within the surface step.
    #[test]
    fn depth_steps_and_empty_texels_are_not_unique() {
        let (p_lo, p_hi) = (Vec2::new(4.5, 4.5), Vec2::new(7.5, 7.5));
        let bound = |pyr: &MotionPyramid| pyr.tight_bound_box(p_lo, p_hi, pyr.global(), 6, 0.5).unwrap().motion;
        // 0.9 behind 0.5 is a step of (0.9 - 0.5) / (1 - 0.9) = 4 > DEPTH_CONTINUITY; 0.55 one
        // of 0.05 / 0.45 = 0.11 (continuous, not one surface); 0.51 one of 0.02 (one surface).
        for (scales, gain, x_step, depth, want) in [
            (MotionScales::Any, 0.2, 6, 0.9, false),
            (MotionScales::Any, 0.2, 6, 1.0, false),
            (MotionScales::Any, 0.2, 30, 0.9, true),
            (MotionScales::Any, 0.2, 30, 1.0, true),
            (MotionScales::Any, 0.2, 6, 0.55, true),
            (MotionScales::AtLeastOne, 0.2, 6, 0.9, false),
            (MotionScales::AtLeastOne, 0.2, 6, 1.0, false),
            (MotionScales::AtLeastOne, 0.8, 6, 0.55, true),
            (MotionScales::AtLeastOne, 1.2, 6, 0.55, false),
            (MotionScales::AtLeastOne, 1.2, 6, 0.51, true),
            (MotionScales::AtLeastOne, 1.2, 30, 0.9, true),
        ] {
            let base = affine(40, 24, [[gain, 0.0], [0.0, gain]], Vec2::ZERO);
            let m = Image::from_fn(40, 24, |x, y| {
                let s = *base.get(x, y);
                if x == x_step && (3..=9).contains(&y) {
                    Motion { depth, ..s }
                } else {
                    s
                }
            });
            let layer = prepared_for(&m, scales);
            assert_eq!(
                layer.unique_solution(p_lo, p_hi, &bound(layer.pyramid()), Vec2::ONE),
                want,
                "{scales:?} gain {gain}, step at {x_step}, depth {depth}"
            );
        }
    }

    /// Every texel of every level equals the brute-force min-max over the pixels it covers,
    /// for sizes that are not powers of two (Bevy's non-conservative downsampler pitfall).
    #[test]
    fn mipmap_texels_cover_every_pixel_for_odd_and_prime_sizes() {
        for (w, h) in [(1, 1), (7, 3), (13, 17), (1, 9), (33, 2), (97, 61)] {
            let m = random_motion(w, h, (w * 1000 + h) as u64, 0.2);
            for frame in [BoundFrame::IDENTITY, BoundFrame::from_angle(0.7)] {
                let pyr = MotionPyramid::build_in_frame(&m, frame).unwrap();
                assert_eq!(pyr.level_size(pyr.top_level()), (1, 1), "{w}x{h}");
                for level in 1..=pyr.top_level() {
                    let (lw, lh) = pyr.level_size(level);
                    assert_eq!((lw, lh), (w.div_ceil(1 << level), h.div_ceil(1 << level)));
                    for ty in 0..lh {
                        for tx in 0..lw {
                            let x0 = tx << level;
                            let y0 = ty << level;
                            let x1 = ((tx + 1) << level).min(w) - 1;
                            let y1 = ((ty + 1) << level).min(h) - 1;
                            let got = pyr.texel(level, tx, ty);
                            let want = brute(&m, frame, x0, y0, x1, y1);
                            if want.is_empty() {
                                assert!(got.is_empty());
                            } else {
                                assert!((got.lo - want.lo).abs().max_element() < 1e-4, "{w}x{h} l{level}");
                                assert!((got.hi - want.hi).abs().max_element() < 1e-4, "{w}x{h} l{level}");
                            }
                        }
                    }
                }
                // Min depth texels against brute force at the automatic level of random ranges.
                for (x0, y0) in [(0, 0), (w / 3, h / 2), (w - 1, h - 1)] {
                    let (x1, y1) = ((x0 + 5).min(w - 1), (y0 + 3).min(h - 1));
                    let mut want = f32::INFINITY;
                    for y in y0..=y1 {
                        for x in x0..=x1 {
                            if is_valid_sample(m.get(x, y)) {
                                want = want.min(m.get(x, y).depth);
                            }
                        }
                    }
                    assert!(pyr.lookup_min_depth(x0, y0, x1, y1) <= want);
                }
                let g = brute(&m, frame, 0, 0, w - 1, h - 1);
                assert!((pyr.global().lo - g.lo).abs().max_element() < 1e-4);
                assert!((pyr.global().hi - g.hi).abs().max_element() < 1e-4);
            }
        }
    }

    #[test]
    fn full_hd_like_global_bound_and_range_lookups_are_conservative() {
        let (w, h) = (1921, 1079);
        let m = random_motion(w, h, 7, 0.1);
        let pyr = MotionPyramid::build(&m).unwrap();
        let g = brute(&m, BoundFrame::IDENTITY, 0, 0, w - 1, h - 1);
        assert_eq!(pyr.global(), g);
        let mut rng = Pcg32::seed_from_u64(3);
        for _ in 0..200 {
            let x0 = rng.random_range(0..w);
            let y0 = rng.random_range(0..h);
            let x1 = (x0 + rng.random_range(0..300)).min(w - 1);
            let y1 = (y0 + rng.random_range(0..300)).min(h - 1);
            let got = pyr.lookup_range(x0, y0, x1, y1);
            let want = brute(&m, BoundFrame::IDENTITY, x0, y0, x1, y1);
            // Conservative: the look-up contains the exact range bound.
            assert_eq!(got.union(&want), got);
        }
    }

    /// Scaling a mipmap bound equals the mipmap of the scaled motion, bit for bit (rounding is
    /// monotone), for positive, negative and zero factors; empty stays empty.
    #[test]
    fn scaled_bound_is_the_bound_of_the_scaled_motion() {
        let m = random_motion(37, 23, 5, 0.2);
        let pyr = MotionPyramid::build(&m).unwrap();
        for s in [Vec2::new(0.5, 1.7), Vec2::new(-1.0, 0.3), Vec2::new(-0.7, -2.5), Vec2::new(0.0, 1.0)] {
            let ms = m.map(|mm| Motion { v: s * mm.v, depth: mm.depth });
            let ps = MotionPyramid::build(&ms).unwrap();
            for level in 1..=pyr.top_level() {
                let (lw, lh) = pyr.level_size(level);
                for ty in 0..lh {
                    for tx in 0..lw {
                        let (a, b) = (pyr.texel(level, tx, ty).scaled(s), ps.texel(level, tx, ty));
                        // == (not bits): 0 * negative motion is -0.0, equal to +0.0.
                        assert_eq!(a, b, "s={s} level {level} ({tx},{ty})");
                    }
                }
            }
        }
        assert!(Bound::EMPTY.scaled(Vec2::ZERO).is_empty());
        let b = Bound { lo: Vec2::new(-1.0, 2.0), hi: Vec2::new(3.0, 5.0) };
        assert_eq!(b.scaled(Vec2::new(-2.0, 0.5)), Bound { lo: Vec2::new(-6.0, 1.0), hi: Vec2::new(2.0, 2.5) });
    }

    #[test]
    fn level_choice_spans_at_most_two_texels() {
        let m = Image::new(100, 37, Motion { v: Vec2::ZERO, depth: 0.5 });
        let pyr = MotionPyramid::build(&m).unwrap();
        assert_eq!(pyr.top_level(), 7);
        for x0 in 0..40u32 {
            for e in 0..60u32 {
                let x1 = (x0 + e).min(99);
                let l = pyr.level_for_range(x0, 0, x1, 0);
                assert!((x1 >> l) - (x0 >> l) <= 1, "x0={x0} x1={x1} level={l}");
            }
        }
    }

    /// Guards against the Unity-port bug (top level sampled whatever the LOD): finer levels give
    /// strictly tighter bounds on a smooth ramp.
    #[test]
    fn bound_shrinks_when_lookup_level_decreases() {
        // vx = x / 8: a smooth ramp; bound over a range at level l spans its 2^l-aligned cover.
        let m = Image::from_fn(64, 64, |x, _| Motion { v: Vec2::new(x as f32 / 8.0, 0.0), depth: 0.5 });
        let pyr = MotionPyramid::build(&m).unwrap();
        let mut prev = f32::INFINITY;
        for level in (1..=pyr.top_level()).rev() {
            let b = pyr.lookup_range_at(level, 22, 20, 23, 22);
            let ext = b.extent().x;
            assert!(ext < prev, "level {level}: extent {ext} not below {prev}");
            prev = ext;
        }
        // Level 1 covers pixels 22..=23 exactly; the automatic level for that range is 1.
        assert_eq!(pyr.level_for_range(22, 20, 23, 21), 1);
        assert_eq!(pyr.lookup_range(22, 20, 23, 21).lo.x, 22.0 / 8.0);
        assert_eq!(pyr.lookup_range(22, 20, 23, 21).hi.x, 23.0 / 8.0);
        assert_eq!(pyr.global().hi.x, 63.0 / 8.0);
    }

    #[test]
    fn tightening_shrinks_monotonically_and_contains_the_solution() {
        // Smooth motion v = (0.1 x + 3, -0.05 y): the solution of q + v(q) = p is analytic.
        let (w, h) = (128u32, 96u32);
        let v = |q: Vec2| Vec2::new(0.1 * q.x + 3.0, -0.05 * q.y);
        let m = Image::from_fn(w, h, |x, y| Motion { v: v(Vec2::new(x as f32 + 0.5, y as f32 + 0.5)), depth: 0.5 });
        let pyr = MotionPyramid::build(&m).unwrap();
        let p = Vec2::new(70.5, 40.5);
        let q = Vec2::new((p.x - 3.0) / 1.1, p.y / 0.95);
        let mut prev_area = f32::INFINITY;
        for it in 0..5 {
            let tb = pyr.tight_bound(p, it, 0.5).unwrap();
            let area = tb.motion.pixel_area();
            assert!(area <= prev_area, "iteration {it}");
            prev_area = area;
            // The solution's (texel-quantised) motion is inside the bound; q is in the region
            // up to half a pixel of texel quantisation.
            let grown = Bound { lo: tb.region.lo - Vec2::splat(0.6), hi: tb.region.hi + Vec2::splat(0.6) };
            assert!(grown.contains(q), "it {it}: {q:?} not in {:?}", tb.region);
        }
        let global = pyr.tight_bound(p, 0, 0.5).unwrap();
        let tight = pyr.tight_bound(p, 3, 0.5).unwrap();
        assert_eq!(global.motion, pyr.global());
        assert!(tight.motion.pixel_area() < 0.1 * global.motion.pixel_area(), "{tight:?} vs {global:?}");
    }

    #[test]
    fn tile_bound_contains_every_pixel_bound_and_refines_to_it() {
        let (w, h) = (96u32, 64u32);
        let m = Image::from_fn(w, h, |x, y| {
            let v = Vec2::new(0.12 * x as f32 - 4.0 + if x > 50 { 6.0 } else { 0.0 }, 0.07 * y as f32);
            Motion { v, depth: if (x + 2 * y) % 17 == 0 { 1.0 } else { 0.5 } }
        });
        for frame in [BoundFrame::IDENTITY, BoundFrame::from_angle(0.4)] {
            let pyr = MotionPyramid::build_in_frame(&m, frame).unwrap();
            for (tx, ty) in [(0u32, 0u32), (12, 3), (13, 7), (23, 15)] {
                let (lo, hi) = (Vec2::new(tx as f32 * 4.0 + 0.5, ty as f32 * 4.0 + 0.5), Vec2::ZERO);
                let hi = hi + lo + Vec2::splat(3.0);
                let tile = pyr.tight_bound_box(lo, hi, pyr.global(), 6, 0.5);
                for j in 0..4 {
                    for i in 0..4 {
                        let p = lo + Vec2::new(i as f32, j as f32);
                        let direct = pyr.tight_bound(p, 6, 0.5);
                        match (tile, direct) {
                            (None, d) => assert!(d.is_none()),
                            (Some(t), Some(d)) => {
                                // The tile bound contains the pixel's own bound ...
                                assert_eq!(t.motion.union(&d.motion), t.motion);
                                // ... and refining from it is at least as tight as from global
                                // (by induction: a sub-range's texels lie inside the range's).
                                let r = pyr.tight_bound_box(p, p, t.motion, 6, 0.5).unwrap();
                                assert_eq!(r.motion.union(&d.motion), d.motion);
                            }
                            (Some(_), None) => {}
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn empty_buffers_and_regions_give_no_bound() {
        let m = Image::new(9, 5, Motion { v: Vec2::new(1.0, 1.0), depth: 1.0 });
        let pyr = MotionPyramid::build(&m).unwrap();
        assert!(pyr.global().is_empty());
        assert!(pyr.tight_bound(Vec2::new(4.5, 2.5), 3, 0.5).is_none());
        // Uniform shift far to the right: a target pixel left of the shifted image has no source.
        let m = Image::new(9, 5, Motion { v: Vec2::new(20.0, 0.0), depth: 0.5 });
        let pyr = MotionPyramid::build(&m).unwrap();
        assert!(pyr.tight_bound(Vec2::new(4.5, 2.5), 3, 0.5).is_none());
        assert!(pyr.tight_bound(Vec2::new(24.5, 2.5), 3, 0.5).is_some());
    }

    #[test]
    fn rejects_bad_input() {
        let m: Image<Motion> = Image::new(0, 3, Motion::default());
        assert!(matches!(MotionPyramid::build(&m), Err(Error::Invalid(_))));
        let mut m = Image::new(3, 3, Motion::default());
        m.get_mut(1, 1).v.x = f32::NAN;
        assert!(matches!(MotionPyramid::build(&m), Err(Error::Invalid(_))));
        let m = Image::new(3, 3, Motion::default());
        assert!(MotionPyramid::build_in_frame(&m, BoundFrame { axis: Vec2::new(2.0, 0.0) }).is_err());
    }

    #[test]
    fn pca_aligns_with_dominant_motion_direction() {
        // Motions spread along the diagonal (1, 1): PCA axis at 45 degrees, OB area much smaller.
        let m = Image::from_fn(32, 32, |x, y| {
            let t = (x as f32 - 16.0) * 0.7 + (y as f32 % 3.0) * 0.1;
            Motion { v: Vec2::new(t, t + 0.05 * (y as f32 % 2.0)), depth: 0.5 }
        });
        let f = pca_frame(m.data(), 32, 32, 64);
        let ang = f.axis.y.atan2(f.axis.x);
        let d = (ang - std::f32::consts::FRAC_PI_4).abs().min((ang + 3.0 * std::f32::consts::FRAC_PI_4).abs());
        assert!(d < 0.05, "angle {ang}");
        let chosen = choose_frame(m.data(), 32, 32, crate::BoundKind::Oriented, MotionScales::Any);
        assert!(!chosen.is_identity());
        assert!(
            global_bound(m.data(), 32, chosen, ImageClip::NONE).pixel_area()
                < 0.5 * global_bound(m.data(), 32, BoundFrame::IDENTITY, ImageClip::NONE).pixel_area()
        );
        // Round trip of the frame.
        let u = Vec2::new(3.0, -2.0);
        assert!((f.from_frame(f.to_frame(u)) - u).length() < 1e-5);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        /// Random sizes and ranges: the four-corner look-up always contains the brute-force bound.
        #[test]
        fn corner_lookups_are_conservative(w in 1u32..40, h in 1u32..40, seed in 0u64..1000,
                                            a in 0.0f32..1.0, b in 0.0f32..1.0, c in 0.0f32..1.0, d in 0.0f32..1.0,
                                            angle in -3.2f32..3.2) {
            let m = random_motion(w, h, seed, 0.3);
            let frame = BoundFrame::from_angle(angle);
            let pyr = MotionPyramid::build_in_frame(&m, frame).unwrap();
            let (x0, x1) = { let u = (a * w as f32) as u32; let v = (b * w as f32) as u32; (u.min(v).min(w-1), u.max(v).min(w-1)) };
            let (y0, y1) = { let u = (c * h as f32) as u32; let v = (d * h as f32) as u32; (u.min(v).min(h-1), u.max(v).min(h-1)) };
            let got = pyr.lookup_range(x0, y0, x1, y1);
            let want = brute(&m, frame, x0, y0, x1, y1);
            if !want.is_empty() {
                prop_assert!(got.lo.x <= want.lo.x && got.lo.y <= want.lo.y);
                prop_assert!(got.hi.x >= want.hi.x && got.hi.y >= want.hi.y);
            }
        }

        /// The image clip keeps the bounds exact: a point `q` of a cell whose bilinear motion
        /// takes it (at a scale `s >= 1`) to within the convergence threshold of a point of
        /// the image has its motion `p - q` inside the min-max of the cell's clipped texel
        /// motions (scaled), in any frame, whatever the texels' own targets (some of them
        /// thousands of pixels away).
        #[test]
        fn the_image_clip_keeps_every_solution_in_the_bound(
            cx in 0u32..48, cy in 0u32..32, ax in 0.0f32..=1.0, ay in 0.0f32..=1.0,
            v in proptest::array::uniform8(-3000.0f32..3000.0), big in proptest::array::uniform4(0.0f32..1.0),
            angle in -3.2f32..3.2, scale in 1.0f32..3.0) {
            let (w, h) = (48u32, 32u32);
            let frame = if angle > 2.5 { BoundFrame::IDENTITY } else { BoundFrame::from_angle(angle) };
            let clip = ImageClip::new(w, h, frame, MotionScales::AtLeastOne);
            // The cell's texels (centres x + 0.5), clamped at the image border like the fetch.
            let xs = [cx.min(w - 1), (cx + 1).min(w - 1)];
            let ys = [cy.min(h - 1), (cy + 1).min(h - 1)];
            let centre = |i: usize| Vec2::new(xs[i % 2] as f32 + 0.5, ys[i / 2] as f32 + 0.5);
            // Motions of a few pixels, or (where `big`) thousands.
            let mv = |i: usize| {
                let m = Vec2::new(v[2 * i], v[2 * i + 1]);
                if big[i] < 0.5 { m / 300.0 } else { m }
            };
            let q = Vec2::new(cx as f32 + 0.5 + ax, cy as f32 + 0.5 + ay);
            let wts = [(1.0 - ax) * (1.0 - ay), ax * (1.0 - ay), (1.0 - ax) * ay, ax * ay];
            let vq = (0..4).fold(Vec2::ZERO, |a, i| a + wts[i] * mv(i));
            let p = q + scale * vq;
            let inside = |p: Vec2| p.x >= -0.5 && p.y >= -0.5 && p.x <= w as f32 + 0.5 && p.y <= h as f32 + 0.5;
            if inside(p) {
                let mut b = Bound::EMPTY;
                for i in 0..4 {
                    b.include(clip.clip(frame.to_frame(centre(i)), frame.to_frame(mv(i))));
                }
                let b = b.scaled(Vec2::splat(scale));
                let u = frame.to_frame(p - q);
                let eps = 1e-3 * (1.0 + u.abs().max_element());
                prop_assert!(u.x >= b.lo.x - eps && u.x <= b.hi.x + eps && u.y >= b.lo.y - eps && u.y <= b.hi.y + eps,
                    "p {p} q {q} u {u} bound {b:?}");
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]
        /// The texel clip of a level-1 block contains the per-sample clip of its samples (so
        /// the exactness above holds for the mipmap), in any frame, for blocks cut by the
        /// image's edge and with samples missing; an empty block stays empty.
        #[test]
        fn the_texel_clip_contains_the_sample_clips(
            tx in 0usize..25, ty in 0usize..17, v in proptest::array::uniform8(-3000.0f32..3000.0),
            big in proptest::array::uniform4(0.0f32..1.0), present in proptest::array::uniform4(proptest::bool::ANY),
            angle in -3.2f32..3.2) {
            let (w, h) = (49u32, 33u32);
            let frame = if angle > 2.5 { BoundFrame::IDENTITY } else { BoundFrame::from_angle(angle) };
            let clip = ImageClip::new(w, h, frame, MotionScales::AtLeastOne);
            let (mut per_sample, mut raw) = (Bound::EMPTY, Bound::EMPTY);
            for i in 0..4 {
                let (x, y) = (2 * tx + i % 2, 2 * ty + i / 2);
                if !present[i] || x >= w as usize || y >= h as usize {
                    continue;
                }
                let m = Vec2::new(v[2 * i], v[2 * i + 1]);
                let m = if big[i] < 0.5 { m / 300.0 } else { m };
                let rq = frame.to_frame(Vec2::new(x as f32 + 0.5, y as f32 + 0.5));
                per_sample.include(clip.clip(rq, frame.to_frame(m)));
                raw.include(frame.to_frame(m));
            }
            let (rq_lo, rq_hi) = ImageClip::block_centres(frame, &BlockExtent::new(frame), tx, ty);
            let t = Bound::from_texel(&clip.clip_texel(rq_lo, rq_hi, raw.to_texel()));
            if per_sample.is_empty() {
                prop_assert_eq!(t, Bound::EMPTY);
            } else {
                let eps = 1e-3;
                prop_assert!(t.lo.x <= per_sample.lo.x + eps && t.lo.y <= per_sample.lo.y + eps
                    && t.hi.x >= per_sample.hi.x - eps && t.hi.y >= per_sample.hi.y - eps,
                    "texel {t:?} samples {per_sample:?}");
            }
        }
    }

    /// Samples that leave the image enter the bounds at the clip's margin; the others as they are.
    #[test]
    fn the_image_clip_moves_only_targets_beyond_the_margin() {
        let clip = ImageClip::new(1000, 50, BoundFrame::IDENTITY, MotionScales::AtLeastOne);
        let q = Vec2::new(990.5, 10.5);
        assert_eq!(clip.clip(q, Vec2::new(13.0, -14.0)), Vec2::new(13.0, -14.0));
        let m = clip_margin(1000, 50);
        assert_eq!((m, clip_margin(100, 50)), (1000.0 / 64.0, CLIP_MARGIN));
        assert_eq!(clip.clip(q, Vec2::new(2500.0, -900.0)), Vec2::new(1000.0 + m - 990.5, -m - 10.5));
        // A whole texel: a block whose samples all move 2500 px right enters at the margin,
        // spanning the block's centres; one moving a few pixels is left as it is.
        let ext = BlockExtent::new(BoundFrame::IDENTITY);
        assert_eq!((ext.lo, ext.hi), (Vec2::ZERO, Vec2::ONE));
        let (rq_lo, rq_hi) = ImageClip::block_centres(BoundFrame::IDENTITY, &ext, 495, 5);
        assert_eq!((rq_lo, rq_hi), (Vec2::new(990.5, 10.5), Vec2::new(991.5, 11.5)));
        let far = clip.clip_texel(rq_lo, rq_hi, [2500.0, 3.0, 2600.0, 4.0]);
        assert_eq!(far, [1000.0 + m - 991.5, 3.0, 1000.0 + m - 990.5, 4.0]);
        assert_eq!(clip.clip_texel(rq_lo, rq_hi, [-3.0, 3.0, 8.0, 4.0]), [-3.0, 3.0, 8.0, 4.0]);
        let empty = Bound::EMPTY.to_texel();
        assert_eq!(clip.clip_texel(rq_lo, rq_hi, empty), empty);
        assert_eq!(ImageClip::new(100, 50, BoundFrame::IDENTITY, MotionScales::Any), ImageClip::NONE);
        assert_eq!(ImageClip::NONE.clip(q, Vec2::splat(1e30)), Vec2::splat(1e30));
        assert!(
            MotionScales::AtLeastOne.serves(Vec2::new(1.0, 2.5))
                && !MotionScales::AtLeastOne.serves(Vec2::new(1.0, 0.5))
        );
        assert!(MotionScales::Any.serves(Vec2::new(-1.0, 0.5)));
    }
}
