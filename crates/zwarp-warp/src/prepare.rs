//! The preparation of one source layer in one streaming pass (seed 000 Sec. 3.3): validated
//! samples, the level-1 min-max motion texels (axis-aligned and, when the PCA frame is a
//! candidate, oriented) with their min target depths, and the motion range of the layer's
//! surfaces that the background hole fill needs ([`crate::holes::BackgroundLimits`]).
//!
//! Why a pass of its own: it is the one place where the whole layer is read, so everything that
//! needs every sample is reduced here (one read of depth and motion, one write of the samples,
//! a quarter-size write of level 1). The loop body is branch-free (selects instead of
//! `continue`), so the compiler vectorizes it; an AVX2 build is chosen at run time on x86-64
//! (same arithmetic, bit-identical: min / max and selects only).

use glam::Vec2;
use rayon::prelude::*;
use zwarp_core::{Error, Image, Motion, ParallaxMotion, Result, EMPTY_DEPTH};

use crate::bounds::{pca_frame_by, BlockExtent, Bound, BoundFrame, ImageClip, MotionPyramid, MotionScales};
use crate::gradient::{GradientMip, OneSeedTest, UNIQUE_GRADIENT};
use crate::sampling::{LayerSampler, SamplePlanes, Sampling};
use crate::simd::{fmax, fmin};
use crate::{BoundKind, WarpLayer, WarpParams};

/// What one pair of image rows (one row of level-1 texels) reduces to besides its texels.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RowStats {
    /// Bit 0: a source depth is NaN or infinite; bit 1: a motion vector or target depth is NaN;
    /// bit 2: a motion vector is infinite.
    pub flags: u8,
    /// Component-wise min / max of the motion of the surfaces (source depth `< 1`) of the rows,
    /// whatever their target depth (the reach of the background fill's border strips).
    pub surf_lo: Vec2,
    /// See `surf_lo`.
    pub surf_hi: Vec2,
    /// Union of the row's axis-aligned level-1 texels (its part of the global bound).
    pub aab: Bound,
    /// Union of the row's oriented level-1 texels (empty when not computed).
    pub ob: Bound,
}

impl RowStats {
    pub(crate) const EMPTY: RowStats = RowStats {
        flags: 0,
        surf_lo: Vec2::splat(f32::INFINITY),
        surf_hi: Vec2::splat(f32::NEG_INFINITY),
        aab: Bound::EMPTY,
        ob: Bound::EMPTY,
    };

    pub(crate) fn merge(self, o: RowStats) -> RowStats {
        RowStats {
            flags: self.flags | o.flags,
            surf_lo: self.surf_lo.min(o.surf_lo),
            surf_hi: self.surf_hi.max(o.surf_hi),
            aab: self.aab.union(&o.aab),
            ob: self.ob.union(&o.ob),
        }
    }
}

/// Inputs of one level-1 row: the layer's buffers, the earlier layers' depths (a sample that
/// repeats an earlier layer's depth at its pixel stays a sample but does not enter the
/// mipmap), the image width, the frame of the oriented texels and whether the oriented global
/// bound is wanted (the oriented frame is a candidate).
pub(crate) struct RowInput<'a> {
    pub depth: &'a [f32],
    pub motion: MotionIn<'a>,
    pub earlier: &'a [&'a [f32]],
    pub w: usize,
    pub frame: BoundFrame,
    pub with_ob: bool,
    /// The image clip of the axis-aligned texels and of the oriented ones (in `frame`).
    pub clip: ImageClip,
    pub clip_ob: ImageClip,
}

/// Where a layer's motion comes from: a buffer, or a field of the depth alone evaluated in the
/// pass ([`PreparedLayer::new_parallax`]).
#[derive(Clone, Copy)]
pub(crate) enum MotionIn<'a> {
    Buffer(&'a [Motion]),
    Parallax(ParallaxMotion),
}

impl MotionIn<'_> {
    /// The motion of pixel `i`, whose source depth is `d`.
    #[inline(always)]
    fn at(&self, i: usize, d: f32) -> Motion {
        match self {
            MotionIn::Buffer(m) => m[i],
            MotionIn::Parallax(p) => p.motion(d),
        }
    }
}

/// Outputs of one level-1 row `ty`: the two image rows of samples, the axis-aligned texels and
/// the oriented ones where wanted (a frame whose texels are not written still gets its global
/// bound in [`RowStats`] when it is a candidate) and the min depths.
pub(crate) struct RowOutput<'a> {
    /// Motion x, motion y and target depth of the two image rows.
    pub vx: &'a mut [f32],
    pub vy: &'a mut [f32],
    pub z: &'a mut [f32],
    pub aab: Option<&'a mut [[f32; 4]]>,
    pub ob: Option<&'a mut [[f32; 4]]>,
    pub zmin: &'a mut [f32],
}

/// Reduces level-1 row `ty` (image rows `2 ty` and `2 ty + 1`, the second possibly missing).
#[inline]
pub(crate) fn row(input: &RowInput<'_>, ty: usize, out: RowOutput<'_>) -> RowStats {
    #[cfg(target_arch = "x86_64")]
    if crate::simd::has_avx2() {
        // SAFETY: only taken when the CPU reports AVX2.
        return unsafe { avx2::row(input, ty, out) };
    }
    row_impl(input, ty, out, 0)
}

/// The portable reduction of columns `xs..w` of level-1 row `ty` (`xs` even): the whole row,
/// or the columns right of the AVX2 build's multiple of 8.
fn row_impl(input: &RowInput<'_>, ty: usize, out: RowOutput<'_>, xs: usize) -> RowStats {
    let RowOutput { vx, vy, z: zs, aab, ob, zmin } = out;
    let w = input.w;
    let (inf, ninf) = (f32::INFINITY, f32::NEG_INFINITY);
    let empty = [inf, inf, ninf, ninf];
    let ts = xs / 2;
    let lw = zmin.len();
    // The texels of a frame that is not written still make its global bound: reduced in a
    // buffer of the row's own.
    let (mut own_a, mut own_o) = (Vec::new(), Vec::new());
    let aab: &mut [[f32; 4]] = match aab {
        Some(a) => a,
        None => {
            own_a.resize(lw, empty);
            &mut own_a
        }
    };
    let ob: &mut [[f32; 4]] = match (ob, input.with_ob) {
        (Some(o), _) => o,
        (None, true) => {
            own_o.resize(lw, empty);
            &mut own_o
        }
        (None, false) => &mut [],
    };
    aab[ts..].fill(empty);
    if input.with_ob {
        ob[ts..].fill(empty);
    }
    let fold = |t: &mut [f32; 4], (lx, ly, hx, hy): (f32, f32, f32, f32)| {
        *t = [fmin(t[0], lx), fmin(t[1], ly), fmax(t[2], hx), fmax(t[3], hy)];
    };
    zmin[ts..].fill(inf);
    let (c, s) = (input.frame.axis.x, input.frame.axis.y);
    let rows = zs.len() / w;
    let (mut flags, mut slo, mut shi) = (0u8, [inf; 2], [ninf; 2]);
    // Per image row: validate and copy the samples, and fold each pixel into its texel
    // (texel x >> 1) with selects: an invalid or repeated sample contributes +inf / -inf.
    for dy in 0..rows {
        let base = (2 * ty + dy) * w;
        for x in xs..w {
            let d = input.depth[base + x];
            let m = input.motion.at(base + x, d);
            let finite_v = m.v.x.is_finite() & m.v.y.is_finite();
            flags |= (!d.is_finite()) as u8
                | ((m.v.x.is_nan() | m.v.y.is_nan() | m.depth.is_nan()) as u8) << 1
                | ((!finite_v) as u8) << 2;
            let surface = d < EMPTY_DEPTH;
            // The motion range of the surfaces (for the border fill), finite motion only (an
            // infinite one is reported through the flags).
            let sv = surface & finite_v;
            slo = [fmin(slo[0], if sv { m.v.x } else { inf }), fmin(slo[1], if sv { m.v.y } else { inf })];
            shi = [fmax(shi[0], if sv { m.v.x } else { ninf }), fmax(shi[1], if sv { m.v.y } else { ninf })];
            let valid = surface & (m.depth >= 0.0) & (m.depth < 1.0) & finite_v;
            let o = dy * w + x;
            vx[o] = if valid { m.v.x } else { 0.0 };
            vy[o] = if valid { m.v.y } else { 0.0 };
            zs[o] = if valid { m.depth } else { inf };
            let repeat = input.earlier.iter().any(|e| e[base + x] == d);
            let fresh = valid & !repeat;
            let a = if fresh { (m.v.x, m.v.y, m.v.x, m.v.y) } else { (inf, inf, ninf, ninf) };
            fold(&mut aab[x >> 1], a);
            let z = &mut zmin[x >> 1];
            *z = fmin(*z, if fresh { m.depth } else { inf });
            if input.with_ob {
                // `BoundFrame::to_frame`: the same products and sums.
                let u = Vec2::new(c * m.v.x + s * m.v.y, -s * m.v.x + c * m.v.y);
                let o = if fresh { (u.x, u.y, u.x, u.y) } else { (inf, inf, ninf, ninf) };
                fold(&mut ob[x >> 1], o);
            }
        }
    }
    // The image clip of each texel (none under MotionScales::Any: skip its arithmetic), then
    // the frame's part of the global bound.
    let clip_union = |texels: &mut [[f32; 4]], clip: ImageClip, frame: BoundFrame| {
        let ext = BlockExtent::new(frame);
        let mut u = empty;
        for (tx, t) in texels.iter_mut().enumerate().skip(ts) {
            if clip != ImageClip::NONE {
                let (rq_lo, rq_hi) = ImageClip::block_centres(frame, &ext, tx, ty);
                *t = clip.clip_texel(rq_lo, rq_hi, *t);
            }
            u = [fmin(u[0], t[0]), fmin(u[1], t[1]), fmax(u[2], t[2]), fmax(u[3], t[3])];
        }
        Bound { lo: Vec2::new(u[0], u[1]), hi: Vec2::new(u[2], u[3]) }
    };
    let aab = clip_union(aab, input.clip, BoundFrame::IDENTITY);
    let ob = if input.with_ob { clip_union(ob, input.clip_ob, input.frame) } else { Bound::EMPTY };
    RowStats { flags, surf_lo: Vec2::from(slo), surf_hi: Vec2::from(shi), aab, ob }
}

/// The AVX2 build of [`row`]: eight pixels of both image rows per step (four texels), the
/// motion deinterleaved from `Motion`'s (x, y, depth) layout with permutes, every operation
/// the portable one's (compare-select min / max, the same products and sums), so the results
/// are bit-identical; the columns past the last multiple of 8 go to [`row_impl`].
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::*;
    use std::arch::x86_64::*;

    /// Compare-select min / max (`a < b ? a : b`), as `minps` / `maxps` compute them.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn vmin(a: __m256, b: __m256) -> __m256 {
        _mm256_min_ps(a, b)
    }
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn vmax(a: __m256, b: __m256) -> __m256 {
        _mm256_max_ps(a, b)
    }

    /// [`ParallaxMotion::motion`] of eight source depths `d` as (x, y, depth) planes: the same
    /// operations in the same order.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn parallax8(p: &ParallaxMotion, d: __m256) -> (__m256, __m256, __m256) {
        let (n, f) = (p.near, p.far);
        let one = _mm256_set1_ps(EMPTY_DEPTH);
        let surface = _mm256_cmp_ps::<_CMP_LT_OQ>(d, one);
        let step = _mm256_mul_ps(d, _mm256_set1_ps(f - n));
        let z = if p.perspective {
            _mm256_div_ps(_mm256_set1_ps(f * n), _mm256_sub_ps(_mm256_set1_ps(f), step))
        } else {
            _mm256_add_ps(_mm256_set1_ps(n), step)
        };
        let g = match p.pivot {
            None => _mm256_div_ps(_mm256_set1_ps(1.0), z),
            Some(z0) => _mm256_sub_ps(z, _mm256_set1_ps(z0)),
        };
        let zero = _mm256_setzero_ps();
        (
            _mm256_blendv_ps(zero, _mm256_mul_ps(_mm256_set1_ps(p.shift.x), g), surface),
            _mm256_blendv_ps(zero, _mm256_mul_ps(_mm256_set1_ps(p.shift.y), g), surface),
            _mm256_blendv_ps(one, d, surface),
        )
    }

    /// [`ImageClip::clip_texel`] of the texels `t` (`[lo.x, lo.y, hi.x, hi.y]`, one per lane)
    /// whose blocks' first sample centres are `(r0x, r0y)` in the clip's frame: the same sums,
    /// compare-select max then min, empty texels kept.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn clip_texels8(
        clip: &ImageClip,
        ext: &BlockExtent,
        r0x: __m256,
        r0y: __m256,
        t: [__m256; 4],
    ) -> [__m256; 4] {
        let (lo_x, lo_y) = (_mm256_add_ps(r0x, _mm256_set1_ps(ext.lo.x)), _mm256_add_ps(r0y, _mm256_set1_ps(ext.lo.y)));
        let (hi_x, hi_y) = (_mm256_add_ps(r0x, _mm256_set1_ps(ext.hi.x)), _mm256_add_ps(r0y, _mm256_set1_ps(ext.hi.y)));
        let clamp = |v: __m256, side_lo: f32, side_hi: f32, rq: __m256| {
            let a = _mm256_sub_ps(_mm256_set1_ps(side_lo), rq);
            let b = _mm256_sub_ps(_mm256_set1_ps(side_hi), rq);
            vmin(vmax(v, a), b)
        };
        let c = [
            clamp(t[0], clip.lo.x, clip.hi.x, hi_x),
            clamp(t[1], clip.lo.y, clip.hi.y, hi_y),
            clamp(t[2], clip.lo.x, clip.hi.x, lo_x),
            clamp(t[3], clip.lo.y, clip.hi.y, lo_y),
        ];
        let nonempty = _mm256_cmp_ps::<_CMP_LE_OQ>(t[0], t[2]);
        [0, 1, 2, 3].map(|k| _mm256_blendv_ps(t[k], c[k], nonempty))
    }

    /// One image row's eight pixels: the texel contributions (lx, ly, hx, hy, z) of the
    /// axis-aligned and oriented frames, the plane values written, the flags and surface range.
    struct Px {
        aab: [__m256; 4],
        ob: [__m256; 4],
        z: __m256,
    }

    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn row(input: &RowInput<'_>, ty: usize, out: RowOutput<'_>) -> RowStats {
        let w = input.w;
        let w8 = w & !7;
        if w8 == 0 {
            return row_impl(input, ty, out, 0);
        }
        let RowOutput { vx, vy, z: zs, mut aab, mut ob, zmin } = out;
        let rows = zs.len() / w;
        let inf = _mm256_set1_ps(f32::INFINITY);
        let ninf = _mm256_set1_ps(f32::NEG_INFINITY);
        let zero = _mm256_setzero_ps();
        let one = _mm256_set1_ps(1.0);
        let absmask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fff_ffff));
        let (c, s) = (_mm256_set1_ps(input.frame.axis.x), _mm256_set1_ps(input.frame.axis.y));
        let ns = _mm256_set1_ps(-input.frame.axis.y);
        let with_ob = input.with_ob;
        let (mut flag_bad_d, mut flag_nan, mut flag_inf) = (zero, zero, zero);
        let (mut slox, mut sloy, mut shix, mut shiy) = (inf, inf, ninf, ninf);
        let mut gl = [inf, inf, ninf, ninf];
        let mut go = [inf, inf, ninf, ninf];
        // The first sample centres of the blocks of each lane pair (exact small integers plus a
        // half, as ImageClip::block_centres computes them), in both frames.
        let centres = _mm256_setr_ps(0.5, 0.5, 2.5, 2.5, 4.5, 4.5, 6.5, 6.5);
        let qy0 = _mm256_set1_ps((2 * ty) as f32 + 0.5);
        let (ext, ext_ob) = (BlockExtent::new(BoundFrame::IDENTITY), BlockExtent::new(input.frame));
        // No clip (MotionScales::Any) leaves every texel as it is: skip its arithmetic.
        let clipping = input.clip != ImageClip::NONE;
        let empty_px = Px { aab: [inf, inf, ninf, ninf], ob: [inf, inf, ninf, ninf], z: inf };
        let pixels = |dy: usize,
                      x: usize,
                      flag_bad_d: &mut __m256,
                      flag_nan: &mut __m256,
                      flag_inf: &mut __m256,
                      surf: &mut [__m256; 4],
                      vx: &mut [f32],
                      vy: &mut [f32],
                      zs: &mut [f32]|
         -> Px {
            let i = (2 * ty + dy) * w + x;
            let d = _mm256_loadu_ps(input.depth.as_ptr().add(i));
            let (mx, my, mz) = match input.motion {
                MotionIn::Buffer(m) => crate::simd::avx2::load_motion8(m.as_ptr().add(i)),
                MotionIn::Parallax(p) => parallax8(&p, d),
            };
            let fin = |v: __m256| _mm256_cmp_ps::<_CMP_LT_OQ>(_mm256_and_ps(v, absmask), inf);
            let finite_v = _mm256_and_ps(fin(mx), fin(my));
            *flag_bad_d = _mm256_or_ps(*flag_bad_d, _mm256_cmp_ps::<_CMP_NLT_UQ>(_mm256_and_ps(d, absmask), inf));
            let nan = _mm256_or_ps(
                _mm256_or_ps(_mm256_cmp_ps::<_CMP_UNORD_Q>(mx, mx), _mm256_cmp_ps::<_CMP_UNORD_Q>(my, my)),
                _mm256_cmp_ps::<_CMP_UNORD_Q>(mz, mz),
            );
            *flag_nan = _mm256_or_ps(*flag_nan, nan);
            *flag_inf = _mm256_or_ps(*flag_inf, _mm256_andnot_ps(finite_v, _mm256_castsi256_ps(_mm256_set1_epi32(-1))));
            let surface = _mm256_cmp_ps::<_CMP_LT_OQ>(d, one);
            let sv = _mm256_and_ps(surface, finite_v);
            surf[0] = vmin(surf[0], _mm256_blendv_ps(inf, mx, sv));
            surf[1] = vmin(surf[1], _mm256_blendv_ps(inf, my, sv));
            surf[2] = vmax(surf[2], _mm256_blendv_ps(ninf, mx, sv));
            surf[3] = vmax(surf[3], _mm256_blendv_ps(ninf, my, sv));
            let valid = _mm256_and_ps(
                _mm256_and_ps(surface, finite_v),
                _mm256_and_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(mz, zero), _mm256_cmp_ps::<_CMP_LT_OQ>(mz, one)),
            );
            let o = dy * w + x;
            _mm256_storeu_ps(vx.as_mut_ptr().add(o), _mm256_and_ps(valid, mx));
            _mm256_storeu_ps(vy.as_mut_ptr().add(o), _mm256_and_ps(valid, my));
            _mm256_storeu_ps(zs.as_mut_ptr().add(o), _mm256_blendv_ps(inf, mz, valid));
            let mut repeat = zero;
            for e in input.earlier {
                repeat = _mm256_or_ps(repeat, _mm256_cmp_ps::<_CMP_EQ_OQ>(_mm256_loadu_ps(e.as_ptr().add(i)), d));
            }
            let fresh = _mm256_andnot_ps(repeat, valid);
            let aab = [
                _mm256_blendv_ps(inf, mx, fresh),
                _mm256_blendv_ps(inf, my, fresh),
                _mm256_blendv_ps(ninf, mx, fresh),
                _mm256_blendv_ps(ninf, my, fresh),
            ];
            let obv = if with_ob {
                let ux = _mm256_add_ps(_mm256_mul_ps(c, mx), _mm256_mul_ps(s, my));
                let uy = _mm256_add_ps(_mm256_mul_ps(ns, mx), _mm256_mul_ps(c, my));
                [
                    _mm256_blendv_ps(inf, ux, fresh),
                    _mm256_blendv_ps(inf, uy, fresh),
                    _mm256_blendv_ps(ninf, ux, fresh),
                    _mm256_blendv_ps(ninf, uy, fresh),
                ]
            } else {
                [inf, inf, ninf, ninf]
            };
            Px { aab, ob: obv, z: _mm256_blendv_ps(inf, mz, fresh) }
        };
        // The four texels of a pair of rows: min / max over the rows, then over lane pairs
        // (each pair's value lands in both lanes), then transposed into [lo.x, lo.y, hi.x, hi.y].
        let pair_min = |v: __m256| vmin(v, _mm256_permute_ps::<0b10_11_00_01>(v));
        let pair_max = |v: __m256| vmax(v, _mm256_permute_ps::<0b10_11_00_01>(v));
        let store_texels = |t: [__m256; 4], out: *mut f32| {
            let a = _mm256_unpacklo_ps(t[0], t[1]); // lx0 ly0 lx0 ly0 | lx2 ly2 ..
            let b = _mm256_unpacklo_ps(t[2], t[3]);
            let c = _mm256_unpackhi_ps(t[0], t[1]); // lx1 ly1 .. | lx3 ly3 ..
            let d = _mm256_unpackhi_ps(t[2], t[3]);
            let s0 = _mm256_shuffle_ps::<0b01_00_01_00>(a, b); // t0 | t2
            let s1 = _mm256_shuffle_ps::<0b01_00_01_00>(c, d); // t1 | t3
            _mm256_storeu_ps(out, _mm256_permute2f128_ps::<0x20>(s0, s1));
            _mm256_storeu_ps(out.add(8), _mm256_permute2f128_ps::<0x31>(s0, s1));
        };
        let even = _mm256_setr_epi32(0, 2, 4, 6, 0, 2, 4, 6);
        let mut surf = [slox, sloy, shix, shiy];
        for x in (0..w8).step_by(8) {
            let p0 = pixels(0, x, &mut flag_bad_d, &mut flag_nan, &mut flag_inf, &mut surf, vx, vy, zs);
            let p1 = if rows > 1 {
                pixels(1, x, &mut flag_bad_d, &mut flag_nan, &mut flag_inf, &mut surf, vx, vy, zs)
            } else {
                Px { ..empty_px }
            };
            // Both rows per lane; then, where the frame's texels are written, per lane pair.
            // The oriented frame below repeats this inline: a shared helper measured 5 % slower.
            let a = [
                vmin(p0.aab[0], p1.aab[0]),
                vmin(p0.aab[1], p1.aab[1]),
                vmax(p0.aab[2], p1.aab[2]),
                vmax(p0.aab[3], p1.aab[3]),
            ];
            // The blocks' first sample centres (frame coordinates: `BoundFrame::to_frame`'s
            // products and sums).
            let qx0 = _mm256_add_ps(_mm256_set1_ps(x as f32), centres);
            let texels = |t: [__m256; 4], clip: &ImageClip, ext: &BlockExtent, rotated: bool| {
                if !clipping {
                    return t;
                }
                let (r0x, r0y) = if rotated {
                    (
                        _mm256_add_ps(_mm256_mul_ps(c, qx0), _mm256_mul_ps(s, qy0)),
                        _mm256_add_ps(_mm256_mul_ps(ns, qx0), _mm256_mul_ps(c, qy0)),
                    )
                } else {
                    (qx0, qy0)
                };
                clip_texels8(clip, ext, r0x, r0y, t)
            };
            // The frame's texels where written or clipped (the global bound is their union),
            // else the lanes themselves (the same minima and maxima).
            let t = if aab.is_some() || clipping {
                let t = [pair_min(a[0]), pair_min(a[1]), pair_max(a[2]), pair_max(a[3])];
                texels(t, &input.clip, &ext, false)
            } else {
                a
            };
            if let Some(out) = aab.as_deref_mut() {
                store_texels(t, out.as_mut_ptr().add(x / 2) as *mut f32);
            }
            gl = [vmin(gl[0], t[0]), vmin(gl[1], t[1]), vmax(gl[2], t[2]), vmax(gl[3], t[3])];
            let zt = pair_min(vmin(p0.z, p1.z));
            _mm_storeu_ps(zmin.as_mut_ptr().add(x / 2), _mm256_castps256_ps128(_mm256_permutevar8x32_ps(zt, even)));
            if with_ob {
                let o = [
                    vmin(p0.ob[0], p1.ob[0]),
                    vmin(p0.ob[1], p1.ob[1]),
                    vmax(p0.ob[2], p1.ob[2]),
                    vmax(p0.ob[3], p1.ob[3]),
                ];
                let t = if ob.is_some() || clipping {
                    let t = [pair_min(o[0]), pair_min(o[1]), pair_max(o[2]), pair_max(o[3])];
                    texels(t, &input.clip_ob, &ext_ob, true)
                } else {
                    o
                };
                if let Some(out) = ob.as_deref_mut() {
                    store_texels(t, out.as_mut_ptr().add(x / 2) as *mut f32);
                }
                go = [vmin(go[0], t[0]), vmin(go[1], t[1]), vmax(go[2], t[2]), vmax(go[3], t[3])];
            }
        }
        [slox, sloy, shix, shiy] = surf;
        let hmin = |v: __m256| {
            let a: [f32; 8] = std::mem::transmute(v);
            a.into_iter().fold(f32::INFINITY, fmin)
        };
        let hmax = |v: __m256| {
            let a: [f32; 8] = std::mem::transmute(v);
            a.into_iter().fold(f32::NEG_INFINITY, fmax)
        };
        let bits = |v: __m256| _mm256_movemask_ps(v) != 0;
        let flags = bits(flag_bad_d) as u8 | (bits(flag_nan) as u8) << 1 | (bits(flag_inf) as u8) << 2;
        let bound =
            |g: [__m256; 4]| Bound { lo: Vec2::new(hmin(g[0]), hmin(g[1])), hi: Vec2::new(hmax(g[2]), hmax(g[3])) };
        let mut stats = RowStats {
            flags,
            surf_lo: Vec2::new(hmin(slox), hmin(sloy)),
            surf_hi: Vec2::new(hmax(shix), hmax(shiy)),
            aab: bound(gl),
            ob: if with_ob { bound(go) } else { Bound::EMPTY },
        };
        if w8 < w {
            let tail = row_impl(input, ty, RowOutput { vx, vy, z: zs, aab, ob, zmin }, w8);
            stats = stats.merge(tail);
        }
        stats
    }
}

/// Level-1 rows per task of the preparation.
const TASK_ROWS: usize = 8;

/// A layer ready to be warped: its validated samples ([`SamplePlanes`], empty ones with an
/// infinite target depth) and the min-max motion mipmap in the frame chosen for the bound kind
/// (seed 000 Sec. 3.3). Build once per source/target pair and reuse across calls with different
/// N, T, hole policies.
pub struct PreparedLayer {
    w: u32,
    h: u32,
    planes: SamplePlanes,
    pyramid: MotionPyramid,
    /// The gradient mipmap of the first layer of a stack (computed where looked up).
    gradient: Option<GradientMip>,
    bound: BoundKind,
    /// The motion scales its bounds serve.
    scales: MotionScales,
    /// The level-1 buffer of the frame not chosen (kept for the next preparation).
    oriented: Vec<[f32; 4]>,
    surfaces: SurfaceMotion,
}

/// The motion range of a layer's surfaces (source depth `< 1`, whatever their target depth),
/// measured by the preparation for the background hole fill's limits
/// ([`crate::holes::BackgroundLimits`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceMotion {
    /// Component-wise minimum motion of the surfaces (`+inf` if there are none).
    pub lo: Vec2,
    /// Component-wise maximum (`-inf` if there are none).
    pub hi: Vec2,
    /// `true` if every motion vector of the layer (surfaces and empty pixels) is finite.
    pub all_finite: bool,
}

/// Buffers of an earlier preparation handed back for reuse (empty: allocate), and whether it
/// chose the oriented frame (`None`: no earlier preparation).
#[derive(Default)]
struct Spare {
    planes: SamplePlanes,
    level1: Vec<[f32; 4]>,
    oriented: Vec<[f32; 4]>,
    zmin: Vec<f32>,
    gradient: Option<GradientMip>,
    hint: Option<bool>,
}

/// [`zwarp_core::pages::reuse`] for a mipmap buffer: at least `n` texels (level 1, overwritten
/// by the caller), capacity for `all` (every level). A recycled buffer keeps its length: the
/// coarser levels after level 1 are overwritten too ([`MotionPyramid::from_level1`]), so they are not filled
/// again every frame.
fn reuse_mip<T: Copy + Send + Sync>(mut v: Vec<T>, n: usize, all: usize, fill: T) -> Vec<T> {
    if v.capacity() < all {
        v = zwarp_core::pages::uninit(all);
    }
    if v.len() < n {
        v.resize(n, fill);
    }
    v
}

impl PreparedLayer {
    /// Validates `layer` (non-zero size, equal sizes, no NaN/infinite depth, no NaN motion) and
    /// builds its mipmap for `bound` (Oriented: AAB or PCA frame, whichever global bound is
    /// smaller). A sample is valid iff its source depth is `< 1`, its target depth is in
    /// `[0, 1)` and its motion is finite (see [`crate::bounds`]). Serves
    /// [`MotionScales::AtLeastOne`] (the motion as given).
    pub fn new(layer: &WarpLayer<'_>, bound: BoundKind) -> Result<Self> {
        Self::new_for(layer, bound, MotionScales::AtLeastOne)
    }

    /// [`Self::new`] for the motion scales `scales` (see [`crate::bounds`] on samples that
    /// leave the image).
    pub fn new_for(layer: &WarpLayer<'_>, bound: BoundKind, scales: MotionScales) -> Result<Self> {
        layer.depth.check_same_size(layer.motion, "layer depth vs motion")?;
        Self::prepare(layer.depth, MotionIn::Buffer(layer.motion.data()), &[], bound, scales, Spare::default())
    }

    /// [`Self::new`] for a layer whose motion is a field of its depth alone (`motion`, e.g. a
    /// light rig's parallax, seed 000 Sec. 6): the field is evaluated in the preparation's own
    /// pass instead of being read from a buffer, so no motion buffer is written or read. The
    /// result equals [`Self::prepare_stack_for`] of one layer on the buffer of `motion.motion(d)`
    /// per pixel, bit for bit, for the same `scales` (a field shared by scaled warps, like the
    /// soft-shadow samples', needs [`MotionScales::Any`]).
    /// Errors: an empty depth buffer, NaN or infinite depths, a non-finite shift or planes.
    pub fn new_parallax(
        depth: &Image<f32>,
        motion: &ParallaxMotion,
        bound: BoundKind,
        scales: MotionScales,
    ) -> Result<Self> {
        let finite = [motion.near, motion.far, motion.pivot.unwrap_or(0.0)].iter().all(|v| v.is_finite());
        if !motion.shift.is_finite() || !finite {
            return Err(Error::invalid(format!("parallax motion must be finite, got {motion:?}")));
        }
        Self::prepare(depth, MotionIn::Parallax(*motion), &[], bound, scales, Spare::default())
    }

    /// Prepares a stack of layers (nearest first). Like [`PreparedLayer::new`] per layer, except
    /// that the mipmap of layer `k > 0` leaves out samples that repeat an earlier layer's sample
    /// at the same pixel (same source depth): a separately rendered ground layer (Sec. 3.4)
    /// repeats every ground pixel that layer 0 already shows. Those samples stay in the layer
    /// (walks may cross them) but do not widen its bounds or stop the pruning, so the later
    /// layer is searched only where it holds something new — the hidden ground. Any solution on
    /// a repeated sample is also a solution of the earlier layer, which searches it itself.
    /// Only layer 0 gets the gradient mipmap (the warp's one-seed tiles are on the first layer,
    /// [`Self::unique_solution`]); the later layers' gradient look-ups are `+inf`. Serves
    /// [`MotionScales::AtLeastOne`] (the motion as given).
    pub fn prepare_stack(layers: &[WarpLayer<'_>], bound: BoundKind) -> Result<Vec<Self>> {
        Self::prepare_stack_recycling(layers, bound, Vec::new())
    }

    /// [`Self::prepare_stack`] into the buffers of `recycled` (an earlier frame's stack, layer
    /// k's buffers for layer k): an engine's steady state. The result is the same bit for bit;
    /// what it saves is faulting in and zeroing fresh pages every frame and, under
    /// [`BoundKind::Oriented`], the texels of the frame layer k did not choose last time.
    /// Buffers too small for this frame's layers are replaced. Serves
    /// [`MotionScales::AtLeastOne`].
    pub fn prepare_stack_recycling(
        layers: &[WarpLayer<'_>],
        bound: BoundKind,
        recycled: Vec<PreparedLayer>,
    ) -> Result<Vec<Self>> {
        Self::prepare_stack_for(layers, bound, MotionScales::AtLeastOne, recycled)
    }

    /// [`Self::prepare_stack_recycling`] for the motion scales `scales`
    /// ([`crate::WarpParams::motion_scale`] of the warps that will read it; see
    /// [`crate::bounds`] on samples that leave the image).
    pub fn prepare_stack_for(
        layers: &[WarpLayer<'_>],
        bound: BoundKind,
        scales: MotionScales,
        recycled: Vec<PreparedLayer>,
    ) -> Result<Vec<Self>> {
        let mut spares = recycled.into_iter().map(PreparedLayer::into_spare);
        let mut out: Vec<PreparedLayer> = Vec::with_capacity(layers.len());
        for (k, layer) in layers.iter().enumerate() {
            if k > 0 {
                let (w, h) = layer.depth.size();
                if (w, h) != out[0].size() {
                    return Err(Error::invalid(format!(
                        "layer {k} is {w}x{h} but layer 0 is {}x{}",
                        out[0].w, out[0].h
                    )));
                }
            }
            let earlier: Vec<&[f32]> = layers[..k].iter().map(|l| l.depth.data()).collect();
            layer.depth.check_same_size(layer.motion, "layer depth vs motion")?;
            let motion = MotionIn::Buffer(layer.motion.data());
            out.push(Self::prepare(layer.depth, motion, &earlier, bound, scales, spares.next().unwrap_or_default())?);
        }
        Ok(out)
    }

    /// Validation, sample planes and mipmap level 1 of one layer in ONE pass over its buffers
    /// ([`row`] per pair of image rows), then the coarser levels from level 1. The oriented
    /// frame (when a candidate) is reduced in the same pass and chosen by the global bounds of
    /// both frames ([`crate::BoundKind::Oriented`]). Only the chosen frame's texels are kept:
    /// where `spare` remembers the last choice, the pass writes that frame's texels and only
    /// the other's global bound (a choice that changes takes a second pass writing both).
    fn prepare(
        depth: &Image<f32>,
        motion: MotionIn<'_>,
        earlier: &[&[f32]],
        bound: BoundKind,
        scales: MotionScales,
        spare: Spare,
    ) -> Result<Self> {
        depth.check_nonempty("layer depth")?;
        let (w, h) = depth.size();
        let depth = depth.data();
        // A sample enters the mipmap if valid and not a repeat of an earlier layer's sample.
        let fresh = |i: usize| {
            let (d, m) = (depth[i], motion.at(i, depth[i]));
            d < EMPTY_DEPTH
                && m.depth >= 0.0
                && m.depth < 1.0
                && m.v.is_finite()
                && !earlier.iter().any(|e| e[i] == depth[i])
        };
        let ob = match bound {
            BoundKind::Oriented => pca_frame_by(w, h, 64, |i| fresh(i).then_some(motion.at(i, depth[i]).v)),
            BoundKind::Global | BoundKind::Tight => BoundFrame::IDENTITY,
        };
        let need_ob = !ob.is_identity();
        let (wu, lw, lh) = (w as usize, w.div_ceil(2) as usize, h.div_ceil(2) as usize);
        let n = wu * h as usize;
        let Spare { planes, level1, oriented, zmin, gradient, hint } = spare;
        // The pass writes every sample: fresh planes are not filled first.
        let mut vx = zwarp_core::pages::reuse(planes.vx, n, 0.0);
        let mut vy = zwarp_core::pages::reuse(planes.vy, n, 0.0);
        let mut z = zwarp_core::pages::reuse(planes.z, n, 0.0);
        let empty = Bound::EMPTY.to_texel_pub();
        // The mip buffers get room for every level (a third more than level 1).
        let all = lw * lh + (lw * lh).div_ceil(2) + 64;
        let mut aab = reuse_mip(level1, lw * lh, all, empty);
        let mut obd = if need_ob { reuse_mip(oriented, lw * lh, all, empty) } else { oriented };
        let mut zmin = reuse_mip(zmin, lw * lh, all, 0.0);
        let input = RowInput {
            depth,
            motion,
            earlier,
            w: wu,
            frame: ob,
            with_ob: need_ob,
            clip: ImageClip::new(w, h, BoundFrame::IDENTITY, scales),
            clip_ob: ImageClip::new(w, h, ob, scales),
        };
        let (cw, cl) = (TASK_ROWS * 2 * wu, TASK_ROWS * lw);
        let task = |c: usize,
                    [vx, vy, z]: [&mut [f32]; 3],
                    mut aab: Option<&mut [[f32; 4]]>,
                    zmin: &mut [f32],
                    mut ob: Option<&mut [[f32; 4]]>| {
            let pairs = zmin.len() / lw;
            let mut st = RowStats::EMPTY;
            for j in 0..pairs {
                let (p, t) = (j * 2 * wu..((j + 1) * 2 * wu).min(vx.len()), j * lw..(j + 1) * lw);
                let out = RowOutput {
                    vx: &mut vx[p.clone()],
                    vy: &mut vy[p.clone()],
                    z: &mut z[p.clone()],
                    aab: aab.as_deref_mut().map(|a| &mut a[t.clone()]),
                    ob: ob.as_deref_mut().map(|o| &mut o[t.clone()]),
                    zmin: &mut zmin[t],
                };
                st = st.merge(row(&input, c * TASK_ROWS + j, out));
            }
            st
        };
        // Which frames' texels the pass writes: both where the oriented frame is a candidate,
        // unless the recycled preparation chose one (an engine's next frame mostly chooses the
        // same): then that one, and the other's global bound only; a different choice writes
        // both in a second pass. The result is the same whichever way it is reached.
        let mut write = match (need_ob, hint) {
            (false, _) => (true, false),
            (true, Some(ob_chosen)) => (!ob_chosen, ob_chosen),
            (true, None) => (true, true),
        };
        let (stats, use_ob) = loop {
            let rows = vx
                .par_chunks_mut(cw)
                .zip(vy.par_chunks_mut(cw))
                .zip(z.par_chunks_mut(cw))
                .zip(aab[..lw * lh].par_chunks_mut(cl))
                .zip(zmin[..lw * lh].par_chunks_mut(cl));
            let (wa, wo) = write;
            let stats = if need_ob {
                rows.zip(obd[..lw * lh].par_chunks_mut(cl))
                    .enumerate()
                    .map(|(c, (((((vx, vy), z), aab), zmin), o))| {
                        task(c, [vx, vy, z], wa.then_some(aab), zmin, wo.then_some(o))
                    })
                    .reduce(|| RowStats::EMPTY, RowStats::merge)
            } else {
                rows.enumerate()
                    .map(|(c, ((((vx, vy), z), aab), zmin))| task(c, [vx, vy, z], Some(aab), zmin, None))
                    .reduce(|| RowStats::EMPTY, RowStats::merge)
            };
            if stats.flags & 1 != 0 {
                return Err(Error::invalid("layer depth holds NaN or infinite values"));
            }
            if stats.flags & 2 != 0 {
                return Err(Error::invalid("motion buffer holds NaN values"));
            }
            // Oriented: the PCA frame if its global bound has the smaller (ex + 1)(ey + 1), the
            // global bounds being the unions of the level-1 texels.
            let use_ob = need_ob && stats.ob.pixel_area() < stats.aab.pixel_area();
            if (write.0 || use_ob) && (write.1 || !use_ob) {
                break (stats, use_ob);
            }
            write = (true, true);
        };
        let (pyramid, oriented) = if use_ob {
            (MotionPyramid::from_level1(w, h, ob, obd, zmin), aab)
        } else {
            (MotionPyramid::from_level1(w, h, BoundFrame::IDENTITY, aab, zmin), obd)
        };
        // The gradient mipmap serves the first layer's one-seed tiles only: the layers behind
        // it go without, and it is computed where the warp looks it up.
        let gradient = earlier.is_empty().then(|| {
            let levels = pyramid.raw().2.collect();
            let test = match scales {
                MotionScales::AtLeastOne => OneSeedTest::Monotone,
                MotionScales::Any => OneSeedTest::Contraction,
            };
            GradientMip::new(w, h, levels, test, gradient)
        });
        let surfaces = SurfaceMotion { lo: stats.surf_lo, hi: stats.surf_hi, all_finite: stats.flags & 4 == 0 };
        Ok(PreparedLayer {
            w,
            h,
            planes: SamplePlanes { vx, vy, z },
            pyramid,
            gradient,
            bound,
            scales,
            oriented,
            surfaces,
        })
    }

    /// Image size.
    pub fn size(&self) -> (u32, u32) {
        (self.w, self.h)
    }

    /// The motion scales ([`crate::WarpParams::motion_scale`]) its bounds serve.
    pub fn scales(&self) -> MotionScales {
        self.scales
    }
    /// The large buffers, for [`Self::prepare_stack_recycling`].
    fn into_spare(self) -> Spare {
        let hint = Some(!self.pyramid.frame().is_identity());
        let (level1, zmin) = self.pyramid.into_buffers();
        Spare { planes: self.planes, level1, oriented: self.oriented, zmin, gradient: self.gradient, hint }
    }
    /// The motion range of the layer's surfaces (see [`SurfaceMotion`]).
    pub fn surfaces(&self) -> SurfaceMotion {
        self.surfaces
    }
    /// The layer's motion mipmap.
    pub fn pyramid(&self) -> &MotionPyramid {
        &self.pyramid
    }

    /// Component-wise largest cell bound of the layer's [`OneSeedTest`]
    /// ([`crate::gradient::cell_gradient`] or [`crate::gradient::cell_fold`]) over the cells a
    /// fetch at any point of the inclusive pixel range can interpolate (the texels of [`MotionPyramid::level_for_range`]
    /// that cover it, as [`MotionPyramid::lookup_min_depth`] reads them); `+inf` for the layers
    /// after the first of [`Self::prepare_stack`], which have no gradient mipmap (the warp
    /// shortcuts only the first layer's seeds).
    pub fn lookup_gradient(&self, ix0: u32, iy0: u32, ix1: u32, iy1: u32) -> [f32; 2] {
        let Some(grad) = &self.gradient else { return [f32::INFINITY; 2] };
        let (level, [tx0, ty0, tx1, ty1]) = self.pyramid.texels_of_range(ix0, iy0, ix1, iy1);
        let mut g = [f32::NEG_INFINITY; 2];
        for ty in ty0..=ty1 {
            for tx in tx0..=tx1 {
                let t = grad.texel(&self.planes, level, tx, ty);
                g = [fmax(g[0], t[0]), fmax(g[1], t[1])];
            }
        }
        g
    }

    /// `true` if every target position `p` of the box `p_lo..=p_hi` has at most one solution of
    /// `q + S v(q) = p` in its search region under motion bound `b` (frame coordinates), for the
    /// warp of `S v` (`S = diag(scale)`, `WarpParams::motion_scale`), so that a walk from one seed
    /// that converges has found the surface N seeds would find (seed 000 Sec. 3.2's seeds exist
    /// for regions with several solutions). Every cell the region's fetches read must be
    /// continuous in depth, and the motion, with the bounds of the layer's [`OneSeedTest`]:
    ///
    /// - [`OneSeedTest::Monotone`] (preparations of the motion as given,
    ///   [`MotionScales::AtLeastOne`]): `max(sx, sy) max fold < 1` over the region
    ///   ([`crate::gradient::cell_fold`]) makes the symmetric part of `S^-1 + Dv` positive
    ///   definite (Gershgorin), so `(x - y) . S^-1 (F(x) - F(y)) > 0` for `F(q) = q + S v(q)`
    ///   along any segment of the (convex) region: `F` is one-to-one there. The fold also keeps
    ///   every cell interpolated by the fetch at that scale. This holds for magnified surfaces (a
    ///   walk toward a wall, the ground under a moving camera), where a walk from one seed may
    ///   fail to converge: the warp then searches that pixel in full.
    /// - [`OneSeedTest::Contraction`] (a preparation shared by scaled warps of either sign,
    ///   [`MotionScales::Any`]): `sx^2 max|dvx/dq|^2 + sy^2 max|dvy/dq|^2 < 1/2`
    ///   ([`crate::gradient::cell_gradient`]) bounds the Frobenius, hence the spectral, norm of
    ///   the Jacobian of `S v` below `1/sqrt(2)`, so `q -> p - S v(q)` maps the region into
    ///   itself (every motion there lies in `b`) with exactly one fixed point (Banach); it also
    ///   keeps every cell's motion range below [`crate::sampling::CONTINUITY_PX`] (at most
    ///   `|dv/dx| + |dv/dy| < 1` per component), so the fetch interpolates them all. The test
    ///   scales with the motion per axis, so each warp of the preparation is that of its
    ///   explicitly scaled buffer.
    ///
    /// `false` on the layers after the first of a stack.
    pub fn unique_solution(&self, p_lo: Vec2, p_hi: Vec2, b: &Bound, scale: Vec2) -> bool {
        let Some(grad) = &self.gradient else { return false };
        let (c_lo, c_hi) = self.pyramid.frame_box(p_lo, p_hi);
        let region = Bound { lo: c_lo - b.hi, hi: c_hi - b.lo };
        let Some((x0, y0, x1, y1)) = self.pyramid.pixel_range(&region, Sampling::Adaptive.footprint()) else {
            return false;
        };
        let [gx, gy] = self.lookup_gradient(x0, y0, x1, y1);
        match grad.test() {
            OneSeedTest::Monotone => scale.x > 0.0 && scale.y > 0.0 && fmax(scale.x, scale.y) * gx < 1.0,
            OneSeedTest::Contraction => scale.x * scale.x * gx + scale.y * scale.y * gy < UNIQUE_GRADIENT,
        }
    }
    /// The bound kind the mipmap was built for.
    pub fn bound_kind(&self) -> BoundKind {
        self.bound
    }
    /// The validated samples (empty ones have an infinite depth).
    pub fn planes(&self) -> &SamplePlanes {
        &self.planes
    }
    /// A sampler of the validated samples with `params`' sampling and motion scale.
    pub fn sampler(&self, params: &WarpParams, tag: u32) -> LayerSampler<'_> {
        LayerSampler::new(&self.planes, self.w, self.h, params.sampling, tag).with_scale(params.motion_scale)
    }
}

/// Validates a layer and returns its samples with empty ones (source depth `>= 1`, target
/// depth outside `[0, 1)`, infinite motion) marked by an infinite target depth: the reference
/// the input of the forward baselines, and the reference the one-pass preparation is tested
/// against.
#[cfg(test)]
pub(crate) fn validated_samples(layer: &WarpLayer<'_>) -> Result<Vec<Motion>> {
    layer.depth.check_nonempty("layer depth")?;
    layer.depth.check_same_size(layer.motion, "layer depth vs motion")?;
    if layer.depth.data().iter().any(|d| !d.is_finite()) {
        return Err(Error::invalid("layer depth holds NaN or infinite values"));
    }
    if layer.motion.data().iter().any(|m| m.v.is_nan() || m.depth.is_nan()) {
        return Err(Error::invalid("motion buffer holds NaN values"));
    }
    Ok(layer
        .depth
        .data()
        .iter()
        .zip(layer.motion.data())
        .map(|(&d, m)| {
            if d < EMPTY_DEPTH && m.depth >= 0.0 && m.depth < 1.0 && m.v.is_finite() {
                *m
            } else {
                Motion { v: Vec2::ZERO, depth: f32::INFINITY }
            }
        })
        .collect())
}
