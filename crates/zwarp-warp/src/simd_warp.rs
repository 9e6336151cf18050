//! The AVX2 build of the single-seed search (x86-64, chosen at run time): eight target pixels
//! in lock step through [`crate::search::fixed_point_search`] with one seed each, for the pixels
//! of a resolved tile (seed 000 Sec. 3.3: a bound within one pixel, one seed at the centre of
//! the pixel's region) — most of the pixels of every warp.
//!
//! Every operation is the portable one's, in the same order and without FMA (the region and
//! seed of `stratified_seeds`, glam's clamp / lerp / dot, the adaptive bilinear-or-nearest
//! fetch of `LayerSampler`, the Newton step of `newton_step`), so each lane computes bit for bit
//! what the scalar kernel computes for its pixel; lanes the build does not cover (more than one
//! seed after rounding) are reported back and go through the scalar kernel. Texels are read
//! with gathers from the sample planes.

#![cfg(target_arch = "x86_64")]

use std::arch::x86_64::*;

use crate::bounds::{Bound, BoundFrame};

/// One layer's sample planes.
#[derive(Clone, Copy)]
pub(crate) struct Planes<'a> {
    pub vx: &'a [f32],
    pub vy: &'a [f32],
    pub z: &'a [f32],
}

/// What the lane search needs of the layers and the warp's parameters.
pub(crate) struct LaneSearch<'a> {
    /// Every layer's planes, nearest first.
    pub layers: Vec<Planes<'a>>,
    /// Source size.
    pub w: u32,
    pub h: u32,
    pub max_q: glam::Vec2,
    pub thr2: f32,
    pub iterations: u32,
    /// `SearchParams::extra_iterations`.
    pub extra_iterations: u32,
    pub accelerate: bool,
    /// Cross-layer seeding (Fig. 6): an empty landing of layer k borrows once from the layers
    /// above.
    pub cross: bool,
    /// N, the most seeds per pixel.
    pub n_seeds: u32,
    /// `CandidateChoice::FirstConverged`: a lane stops at its first converged seed.
    pub first_converged: bool,
    /// `Sampling::Nearest`: every fetch takes the texel under `q` (the adaptive fetch's
    /// non-smooth branch), never the bilinear one.
    pub nearest: bool,
    /// The walks run their AVX-512 build ([`crate::simd::has_avx512`]).
    pub avx512: bool,
    /// `WarpParams::motion_scale` where it is not one: every texel's motion is scaled as it is
    /// read, before it is interpolated (`LayerSampler::with_scale`, the same products).
    pub scale: Option<(f32, f32)>,
}

/// Results of eight lanes of one layer's search.
#[derive(Clone, Copy)]
pub(crate) struct Lanes {
    /// Converged lanes (all bits set per lane).
    pub converged: __m256,
    /// Depth of the converged sample per lane.
    pub depth: __m256,
    /// Converged source position per lane.
    pub qx: __m256,
    pub qy: __m256,
    /// Layer of the converged sample (its tag: the layer itself or the one it borrowed from).
    pub tag: __m256i,
    /// Closest approach of the lane's walks: the smallest squared residual of any smooth sampled
    /// iterate (`+inf` if none), and that sample's depth, as `search::fixed_point_search_closest`
    /// returns them.
    pub closest: __m256,
    pub closest_depth: __m256,
    /// The largest depth of any sample of the lane's walks after their first step (`-inf` if
    /// none), as `search::Approach::farthest`.
    pub farthest: __m256,
    /// `search::Approach::straddle` of the lane's walks (`+inf` if none).
    pub straddle: __m256,
}

/// The nearer of two closest approaches `(r2, depth)` per lane (the first on ties, as the
/// scalar walk keeps its first minimum).
#[inline(always)]
unsafe fn nearer(a: (__m256, __m256), b: (__m256, __m256)) -> (__m256, __m256) {
    let take = _mm256_cmp_ps::<_CMP_LT_OQ>(b.0, a.0);
    (_mm256_blendv_ps(a.0, b.0, take), _mm256_blendv_ps(a.1, b.1, take))
}

#[inline(always)]
unsafe fn splat(v: f32) -> __m256 {
    _mm256_set1_ps(v)
}

/// The target positions of pixels `(xi[i], yi[i])`: `(x + 0.5, y + 0.5) * m`
/// (`Kernel::target_pos`).
#[inline]
#[target_feature(enable = "avx2")]
pub(crate) unsafe fn positions(m: f32, xi: __m256i, yi: __m256i) -> (__m256, __m256) {
    let (half, m) = (splat(0.5), splat(m));
    (
        _mm256_mul_ps(_mm256_add_ps(_mm256_cvtepi32_ps(xi), half), m),
        _mm256_mul_ps(_mm256_add_ps(_mm256_cvtepi32_ps(yi), half), m),
    )
}

/// `MotionPyramid::region` per lane: `c = p` (identity frame) or `to_frame(p)`, then
/// `[c - hi, c - lo]`, for the per-lane bounds `[lo.x, lo.y, hi.x, hi.y]`.
#[inline]
#[target_feature(enable = "avx2")]
pub(crate) unsafe fn region8(frame: BoundFrame, px: __m256, py: __m256, b: &[__m256; 4]) -> [__m256; 4] {
    let (fc, fs, nfs) = (splat(frame.axis.x), splat(frame.axis.y), splat(-frame.axis.y));
    let (cx, cy) = if frame.is_identity() {
        (px, py)
    } else {
        (
            _mm256_add_ps(_mm256_mul_ps(fc, px), _mm256_mul_ps(fs, py)),
            _mm256_add_ps(_mm256_mul_ps(nfs, px), _mm256_mul_ps(fc, py)),
        )
    };
    [_mm256_sub_ps(cx, b[2]), _mm256_sub_ps(cy, b[3]), _mm256_sub_ps(cx, b[0]), _mm256_sub_ps(cy, b[1])]
}

/// A bound broadcast to eight lanes.
#[inline]
#[target_feature(enable = "avx2")]
pub(crate) unsafe fn splat_bound(b: &Bound) -> [__m256; 4] {
    [splat(b.lo.x), splat(b.lo.y), splat(b.hi.x), splat(b.hi.y)]
}

/// Eight samples of [`crate::sampling::LayerSampler`] (adaptive, its motion scale): where the lane has
/// one, its motion, depth and Jacobian (zero for nearest samples).
struct Smp8 {
    has: __m256,
    vx: __m256,
    vy: __m256,
    z: __m256,
    /// Jacobian columns dv/dx, dv/dy.
    dxx: __m256,
    dxy: __m256,
    dyx: __m256,
    dyy: __m256,
    /// Bilinear samples of a smooth neighbourhood (`Sample::smooth`).
    smooth: __m256,
}

/// Four texels' motion component times the factor `s` where there is one (`LayerSampler`'s
/// `scale * m.v` per texel, before interpolation).
#[inline(always)]
unsafe fn scaled(s: Option<f32>, t: [__m256; 4]) -> [__m256; 4] {
    match s {
        None => t,
        Some(s) => {
            let f = _mm256_set1_ps(s);
            t.map(|v| _mm256_mul_ps(f, v))
        }
    }
}

/// `LayerSampler::fetch_inside_scaled` (scaled by `scale` where given, adaptive or, with `nearest`, nearest
/// sampling) for the `live` lanes, whose `q` lies inside the image. Part of [`walk8`]'s body
/// (inlined into each of its builds, no target feature of its own).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
unsafe fn fetch8(
    pl: &Planes<'_>,
    w: u32,
    h: u32,
    nearest: bool,
    scale: Option<(f32, f32)>,
    qx: __m256,
    qy: __m256,
    live: __m256,
) -> Smp8 {
    let live_i = _mm256_castps_si256(live);
    let (half, one, zero) = (splat(0.5), splat(1.0), _mm256_setzero_ps());
    let wm = _mm256_set1_epi32(w as i32 - 1);
    let hm = _mm256_set1_epi32(h as i32 - 1);
    let wv = _mm256_set1_epi32(w as i32);
    let (ione, izero) = (_mm256_set1_epi32(1), _mm256_setzero_si256());
    let tx = _mm256_add_ps(qx, half);
    let ty = _mm256_add_ps(qy, half);
    let ix = _mm256_and_si256(_mm256_cvttps_epi32(tx), live_i);
    let iy = _mm256_and_si256(_mm256_cvttps_epi32(ty), live_i);
    let ax = _mm256_sub_ps(tx, _mm256_cvtepi32_ps(ix));
    let ay = _mm256_sub_ps(ty, _mm256_cvtepi32_ps(iy));
    let x0 = _mm256_min_epi32(_mm256_max_epi32(_mm256_sub_epi32(ix, ione), izero), wm);
    let y0 = _mm256_min_epi32(_mm256_max_epi32(_mm256_sub_epi32(iy, ione), izero), hm);
    let x1 = _mm256_min_epi32(ix, wm);
    let y1 = _mm256_min_epi32(iy, hm);
    let r0 = _mm256_mullo_epi32(y0, wv);
    let r1 = _mm256_mullo_epi32(y1, wv);
    let (i00, i10) = (_mm256_add_epi32(r0, x0), _mm256_add_epi32(r0, x1));
    let (i01, i11) = (_mm256_add_epi32(r1, x0), _mm256_add_epi32(r1, x1));
    let g = |p: &[f32], i: __m256i| _mm256_i32gather_ps::<4>(p.as_ptr(), i);
    let [vx00, vx10, vx01, vx11] =
        scaled(scale.map(|s| s.0), [g(pl.vx, i00), g(pl.vx, i10), g(pl.vx, i01), g(pl.vx, i11)]);
    let [vy00, vy10, vy01, vy11] =
        scaled(scale.map(|s| s.1), [g(pl.vy, i00), g(pl.vy, i10), g(pl.vy, i01), g(pl.vy, i11)]);
    let (z00, z10, z01, z11) = (g(pl.z, i00), g(pl.z, i10), g(pl.z, i01), g(pl.z, i11));
    let valid = |z: __m256| _mm256_and_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(z, zero), _mm256_cmp_ps::<_CMP_LT_OQ>(z, one));
    let all_valid = _mm256_and_ps(_mm256_and_ps(valid(z00), valid(z10)), _mm256_and_ps(valid(z01), valid(z11)));
    // Vec2 min / max chains of the portable fetch: s00.min(s10).min(s01.min(s11)).
    let lo_x = _mm256_min_ps(_mm256_min_ps(vx00, vx10), _mm256_min_ps(vx01, vx11));
    let lo_y = _mm256_min_ps(_mm256_min_ps(vy00, vy10), _mm256_min_ps(vy01, vy11));
    let hi_x = _mm256_max_ps(_mm256_max_ps(vx00, vx10), _mm256_max_ps(vx01, vx11));
    let hi_y = _mm256_max_ps(_mm256_max_ps(vy00, vy10), _mm256_max_ps(vy01, vy11));
    // max_element(hi - lo): `if x > y { x } else { y }`.
    let rmax = _mm256_max_ps(_mm256_sub_ps(hi_x, lo_x), _mm256_sub_ps(hi_y, lo_y));
    let smooth = if nearest { zero } else { _mm256_and_ps(all_valid, continuous8(rmax, [z00, z10, z01, z11])) };
    // bilinear(): glam lerp a * (1 - s) + b * s, depths a + (b - a) * s.
    let lerp =
        |a: __m256, b: __m256, s: __m256| _mm256_add_ps(_mm256_mul_ps(a, _mm256_sub_ps(one, s)), _mm256_mul_ps(b, s));
    let top_vx = lerp(vx00, vx10, ax);
    let top_vy = lerp(vy00, vy10, ax);
    let bot_vx = lerp(vx01, vx11, ax);
    let bot_vy = lerp(vy01, vy11, ax);
    let top_d = _mm256_add_ps(z00, _mm256_mul_ps(_mm256_sub_ps(z10, z00), ax));
    let bot_d = _mm256_add_ps(z01, _mm256_mul_ps(_mm256_sub_ps(z11, z01), ax));
    let dxx = lerp(_mm256_sub_ps(vx10, vx00), _mm256_sub_ps(vx11, vx01), ay);
    let dxy = lerp(_mm256_sub_ps(vy10, vy00), _mm256_sub_ps(vy11, vy01), ay);
    let dyx = _mm256_sub_ps(bot_vx, top_vx);
    let dyy = _mm256_sub_ps(bot_vy, top_vy);
    let bvx = lerp(top_vx, bot_vx, ay);
    let bvy = lerp(top_vy, bot_vy, ay);
    let bz = _mm256_add_ps(top_d, _mm256_mul_ps(_mm256_sub_ps(bot_d, top_d), ay));
    let (vx, vy, z, has) = adaptive8(
        (qx, qy),
        live,
        (x0, y0),
        (wm, hm),
        smooth,
        (bvx, bvy, bz),
        [[vx00, vx10, vx01, vx11], [vy00, vy10, vy01, vy11], [z00, z10, z01, z11]],
    );
    Smp8 {
        has,
        vx,
        vy,
        z,
        dxx: _mm256_and_ps(smooth, dxx),
        dxy: _mm256_and_ps(smooth, dxy),
        dyx: _mm256_and_ps(smooth, dyx),
        dyy: _mm256_and_ps(smooth, dyy),
        smooth: _mm256_and_ps(live, smooth),
    }
}

/// The adaptive sample (`LayerSampler`) of the `live` lanes from their cell's texels (motion x,
/// motion y, target depth; each `[(x0, y0), (x1, y0), (x0, y1), (x1, y1)]`): the bilinear
/// `(vx, vy, z)` where the cell is `smooth`, the nearest texel `floor(q)` elsewhere; and the
/// live lanes with a sample (smooth, or a valid nearest texel). Where every live lane is smooth
/// (surfaces away from edges) the nearest texel is not picked at all.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
unsafe fn adaptive8(
    (qx, qy): (__m256, __m256),
    live: __m256,
    (x0, y0): (__m256i, __m256i),
    (wm, hm): (__m256i, __m256i),
    smooth: __m256,
    (bvx, bvy, bz): (__m256, __m256, __m256),
    [v_x, v_y, v_z]: [[__m256; 4]; 3],
) -> (__m256, __m256, __m256, __m256) {
    if _mm256_movemask_ps(_mm256_andnot_ps(smooth, live)) == 0 {
        return (bvx, bvy, bz, live);
    }
    let live_i = _mm256_castps_si256(live);
    // The texel floor(q), always one of the four read.
    let xn = _mm256_min_epi32(_mm256_and_si256(_mm256_cvttps_epi32(qx), live_i), wm);
    let yn = _mm256_min_epi32(_mm256_and_si256(_mm256_cvttps_epi32(qy), live_i), hm);
    let left = _mm256_castsi256_ps(_mm256_cmpeq_epi32(xn, x0));
    let top = _mm256_castsi256_ps(_mm256_cmpeq_epi32(yn, y0));
    let pick = |[a00, a10, a01, a11]: [__m256; 4]| {
        let t = _mm256_blendv_ps(a10, a00, left);
        let b = _mm256_blendv_ps(a11, a01, left);
        _mm256_blendv_ps(b, t, top)
    };
    let nz = pick(v_z);
    let valid = _mm256_and_ps(
        _mm256_cmp_ps::<_CMP_GE_OQ>(nz, _mm256_setzero_ps()),
        _mm256_cmp_ps::<_CMP_LT_OQ>(nz, splat(1.0)),
    );
    (
        _mm256_blendv_ps(pick(v_x), bvx, smooth),
        _mm256_blendv_ps(pick(v_y), bvy, smooth),
        _mm256_blendv_ps(nz, bz, smooth),
        _mm256_and_ps(live, _mm256_or_ps(smooth, valid)),
    )
}

/// [`crate::sampling::continuous_cell`] per lane, from the cell's motion range and its four
/// target depths (the same min / max chains and IEEE operations).
#[inline(always)]
unsafe fn continuous8(rmax: __m256, [z00, z10, z01, z11]: [__m256; 4]) -> __m256 {
    let z_lo = _mm256_min_ps(_mm256_min_ps(z00, z10), _mm256_min_ps(z01, z11));
    let z_hi = _mm256_max_ps(_mm256_max_ps(z00, z10), _mm256_max_ps(z01, z11));
    let step = _mm256_sub_ps(z_hi, z_lo);
    let room = _mm256_sub_ps(splat(1.0), z_hi);
    let limit = _mm256_mul_ps(splat(crate::sampling::DEPTH_CONTINUITY), room);
    let surface = _mm256_mul_ps(splat(crate::sampling::SURFACE_DEPTH_STEP), room);
    _mm256_and_ps(
        _mm256_or_ps(
            _mm256_cmp_ps::<_CMP_LT_OQ>(rmax, splat(crate::sampling::CONTINUITY_PX)),
            _mm256_cmp_ps::<_CMP_LT_OQ>(step, surface),
        ),
        _mm256_cmp_ps::<_CMP_LT_OQ>(step, limit),
    )
}

/// `search::hash_u32` per lane (wrapping products, as the portable one).
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn hash8(v: __m256i) -> __m256i {
    let state = _mm256_add_epi32(
        _mm256_mullo_epi32(v, _mm256_set1_epi32(747796405u32 as i32)),
        _mm256_set1_epi32(2891336453u32 as i32),
    );
    let shift = _mm256_add_epi32(_mm256_srli_epi32::<28>(state), _mm256_set1_epi32(4));
    let word =
        _mm256_mullo_epi32(_mm256_xor_si256(_mm256_srlv_epi32(state, shift), state), _mm256_set1_epi32(277803737));
    _mm256_xor_si256(_mm256_srli_epi32::<22>(word), word)
}

/// Searches layer `k` for the `active` lanes at target positions `(px, py)` (target pixels
/// `(xi, yi)`) with the seeds `stratified_seeds` places in each lane's search region
/// `[lo.x, lo.y, hi.x, hi.y]` (frame coordinates of `frame`): one at the centre where the
/// region is within one pixel, else `effective_seeds` of them (of at most `n_seeds`) (corners first, then the
/// jittered R2 points), plus, with cross-layer seeding, an earlier layer's converged position
/// `prev` where the lane has one (`prev_has`) inside its region (appended, or in place of the
/// last seed when there are N); the candidate of minimal depth wins in seed order. The walk
/// samples layer `k` with the cross-layer fallback of `StackSampler` (the first empty landing
/// borrows the nearest non-empty layer above unless the adaptive fetch gave a nearest sample
/// there, the second fails).
///
/// # Safety
/// The CPU must support AVX2; the planes must be `w * h` long.
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn search8(
    ls: &LaneSearch<'_>,
    k: usize,
    frame: BoundFrame,
    px: __m256,
    py: __m256,
    xi: __m256i,
    yi: __m256i,
    active: u8,
    region: &[__m256; 4],
    prev: Option<(__m256, __m256, __m256)>,
    n_seeds: u32,
) -> Lanes {
    let zero = _mm256_setzero_ps();
    let one = splat(1.0);
    let inf = splat(f32::INFINITY);
    let act = lane_mask(active);
    let half = splat(0.5);
    let (fc, fs) = (splat(frame.axis.x), splat(frame.axis.y));
    let [lox, loy, hix, hiy] = *region;
    let ex = _mm256_sub_ps(hix, lox);
    let ey = _mm256_sub_ps(hiy, loy);
    // effective_seeds: one seed iff both extents <= 1, else min(N, ceil((ex + 1)(ey + 1))).
    let single = _mm256_and_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(ex, one), _mm256_cmp_ps::<_CMP_LE_OQ>(ey, one));
    let area = _mm256_ceil_ps(_mm256_mul_ps(_mm256_add_ps(ex, one), _mm256_add_ps(ey, one)));
    let nf = splat(n_seeds as f32);
    let nsel = _mm256_blendv_ps(nf, area, _mm256_cmp_ps::<_CMP_LT_OQ>(area, nf));
    let ne = _mm256_blendv_epi8(_mm256_cvttps_epi32(nsel), _mm256_set1_epi32(1), _mm256_castps_si256(single));
    let ne = _mm256_and_si256(ne, _mm256_castps_si256(act));
    // The cross-layer seed: to_frame(q) inside the region (inclusive).
    let (pqx, pqy, prev_in) = match prev {
        Some((pqx, pqy, phas)) if ls.cross => {
            let ux = _mm256_add_ps(_mm256_mul_ps(fc, pqx), _mm256_mul_ps(fs, pqy));
            let uy = _mm256_add_ps(_mm256_mul_ps(splat(-frame.axis.y), pqx), _mm256_mul_ps(fc, pqy));
            let inside = _mm256_and_ps(
                _mm256_and_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(ux, lox), _mm256_cmp_ps::<_CMP_LE_OQ>(ux, hix)),
                _mm256_and_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(uy, loy), _mm256_cmp_ps::<_CMP_LE_OQ>(uy, hiy)),
            );
            (pqx, pqy, _mm256_and_ps(_mm256_and_ps(phas, inside), act))
        }
        _ => (zero, zero, zero),
    };
    let prev_in_i = _mm256_castps_si256(prev_in);
    // Seeds in use: ne, or ne + 1 with the cross-layer seed when ne < N; that seed's index.
    let room = _mm256_and_si256(prev_in_i, _mm256_cmpgt_epi32(_mm256_set1_epi32(ls.n_seeds as i32), ne));
    let ntot = _mm256_sub_epi32(ne, room);
    let prev_at = _mm256_sub_epi32(ntot, _mm256_set1_epi32(1));
    let (mxq, myq) = (splat(ls.max_q.x), splat(ls.max_q.y));
    if _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(ntot, _mm256_set1_epi32(1)))) == 0 {
        // One seed per lane (most pixels): from_frame(lo + 0.5 * e), or the cross-layer seed in
        // its place when N = 1.
        let ux = _mm256_add_ps(lox, _mm256_mul_ps(half, ex));
        let uy = _mm256_add_ps(loy, _mm256_mul_ps(half, ey));
        let mut qx = _mm256_sub_ps(_mm256_mul_ps(fc, ux), _mm256_mul_ps(fs, uy));
        let mut qy = _mm256_add_ps(_mm256_mul_ps(fs, ux), _mm256_mul_ps(fc, uy));
        qx = _mm256_blendv_ps(qx, pqx, prev_in);
        qy = _mm256_blendv_ps(qy, pqy, prev_in);
        qx = _mm256_min_ps(_mm256_max_ps(qx, zero), mxq);
        qy = _mm256_min_ps(_mm256_max_ps(qy, zero), myq);
        // The first iteration alone (most lanes converge in it); the others walk again from
        // their seed with the complete step.
        let (now, depth, more, (closest, closest_depth)) = first8(ls, k, px, py, qx, qy, act);
        // Lanes that stop after the first iterate without converging had no sample.
        let farthest = splat(f32::NEG_INFINITY);
        let tag = _mm256_set1_epi32(k as i32);
        let straddle = inf;
        let mut out = Lanes { converged: now, depth, qx, qy, tag, closest, closest_depth, farthest, straddle };
        if _mm256_movemask_ps(more) != 0 {
            let (c2, d2, qx2, qy2, t2, a2, f2, s2) = walk8(ls, k, px, py, qx, qy, more);
            // The walk repeats the first iterate: its approach is the lane's whole approach.
            out.closest = _mm256_blendv_ps(out.closest, a2.0, more);
            out.closest_depth = _mm256_blendv_ps(out.closest_depth, a2.1, more);
            out.farthest = _mm256_blendv_ps(out.farthest, f2, more);
            out.straddle = _mm256_blendv_ps(out.straddle, s2, more);
            out.converged = _mm256_or_ps(out.converged, c2);
            out.depth = _mm256_blendv_ps(out.depth, d2, c2);
            out.qx = _mm256_blendv_ps(out.qx, qx2, c2);
            out.qy = _mm256_blendv_ps(out.qy, qy2, c2);
            out.tag = _mm256_blendv_epi8(out.tag, t2, _mm256_castps_si256(c2));
        }
        return out;
    }
    let mut nes = [0i32; 8];
    _mm256_storeu_si256(nes.as_mut_ptr() as *mut __m256i, ntot);
    let max_n = nes.iter().copied().max().unwrap_or(0).min(ls.n_seeds as i32);
    // stratified_seeds for n >= 2: nc = min(n / 2, distinct corners) corners, then R2 points
    // lo + fract(r + R2 i) e jittered by seed_key(x, y, k); `map` rotates back unless identity.
    let two = _mm256_set1_epi32(2);
    let px_pos = _mm256_cmp_ps::<_CMP_GT_OQ>(ex, zero);
    let py_pos = _mm256_cmp_ps::<_CMP_GT_OQ>(ey, zero);
    let both = _mm256_castps_si256(_mm256_and_ps(px_pos, py_pos));
    let none =
        _mm256_castps_si256(_mm256_andnot_ps(_mm256_or_ps(px_pos, py_pos), _mm256_castsi256_ps(_mm256_set1_epi32(-1))));
    let distinct = _mm256_blendv_epi8(_mm256_blendv_epi8(two, _mm256_set1_epi32(4), both), _mm256_set1_epi32(1), none);
    let nc = _mm256_min_epi32(_mm256_srli_epi32::<1>(ne), distinct);
    let key = hash8(_mm256_xor_si256(xi, hash8(_mm256_xor_si256(yi, hash8(_mm256_set1_epi32(k as i32))))));
    let inv = splat(1.0 / 65536.0);
    let rx = _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_and_si256(key, _mm256_set1_epi32(0xffff))), inv);
    let ry = _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_srli_epi32::<16>(key)), inv);
    let map = |ux: __m256, uy: __m256| {
        if frame.is_identity() {
            (ux, uy)
        } else {
            (
                _mm256_sub_ps(_mm256_mul_ps(fc, ux), _mm256_mul_ps(fs, uy)),
                _mm256_add_ps(_mm256_mul_ps(fs, ux), _mm256_mul_ps(fc, uy)),
            )
        }
    };
    // Seed j's position and lanes (`None`: no lane walks it).
    let seed = |j: i32, has: __m256| -> Option<(__m256, __m256, __m256)> {
        let ji = _mm256_set1_epi32(j);
        let in_use = _mm256_castsi256_ps(_mm256_cmpgt_epi32(ntot, ji));
        let mut live = _mm256_and_ps(act, in_use);
        if ls.first_converged {
            live = _mm256_andnot_ps(has, live);
        }
        if _mm256_movemask_ps(live) == 0 {
            return None;
        }
        let (mut qx, mut qy) = if max_n == 1 {
            // One seed: from_frame(lo + 0.5 * e) (stratified_seeds, n == 1).
            let ux = _mm256_add_ps(lox, _mm256_mul_ps(half, ex));
            let uy = _mm256_add_ps(loy, _mm256_mul_ps(half, ey));
            (
                _mm256_sub_ps(_mm256_mul_ps(fc, ux), _mm256_mul_ps(fs, uy)),
                _mm256_add_ps(_mm256_mul_ps(fs, ux), _mm256_mul_ps(fc, uy)),
            )
        } else {
            let ux = _mm256_add_ps(lox, _mm256_mul_ps(half, ex));
            let uy = _mm256_add_ps(loy, _mm256_mul_ps(half, ey));
            let centre = (
                _mm256_sub_ps(_mm256_mul_ps(fc, ux), _mm256_mul_ps(fs, uy)),
                _mm256_add_ps(_mm256_mul_ps(fs, ux), _mm256_mul_ps(fc, uy)),
            );
            // Corner j: lo, hi, (lo.x, hi.y), (hi.x, lo.y).
            let (cx, cy) = match j {
                0 => (lox, loy),
                1 => (hix, hiy),
                2 => (lox, hiy),
                _ => (hix, loy),
            };
            let corner = map(cx, cy);
            // R2 point i = j - nc.
            let i = _mm256_cvtepi32_ps(_mm256_sub_epi32(ji, nc));
            let sxr = _mm256_add_ps(rx, _mm256_mul_ps(splat(0.754_877_7), i));
            let syr = _mm256_add_ps(ry, _mm256_mul_ps(splat(0.569_840_3), i));
            let sx = _mm256_sub_ps(sxr, _mm256_round_ps::<{ _MM_FROUND_TO_ZERO | _MM_FROUND_NO_EXC }>(sxr));
            let sy = _mm256_sub_ps(syr, _mm256_round_ps::<{ _MM_FROUND_TO_ZERO | _MM_FROUND_NO_EXC }>(syr));
            let r2p = map(_mm256_add_ps(lox, _mm256_mul_ps(sx, ex)), _mm256_add_ps(loy, _mm256_mul_ps(sy, ey)));
            let is_corner = _mm256_castsi256_ps(_mm256_cmpgt_epi32(nc, ji));
            let is_single = _mm256_castsi256_ps(_mm256_cmpeq_epi32(ne, _mm256_set1_epi32(1)));
            let qx = _mm256_blendv_ps(_mm256_blendv_ps(r2p.0, corner.0, is_corner), centre.0, is_single);
            let qy = _mm256_blendv_ps(_mm256_blendv_ps(r2p.1, corner.1, is_corner), centre.1, is_single);
            (qx, qy)
        };
        let is_prev = _mm256_castsi256_ps(_mm256_and_si256(prev_in_i, _mm256_cmpeq_epi32(prev_at, ji)));
        qx = _mm256_blendv_ps(qx, pqx, is_prev);
        qy = _mm256_blendv_ps(qy, pqy, is_prev);
        // glam clamp: max(0) then min(max_q) (compare-selects, as maxps / minps).
        qx = _mm256_min_ps(_mm256_max_ps(qx, zero), mxq);
        qy = _mm256_min_ps(_mm256_max_ps(qy, zero), myq);
        Some((qx, qy, live))
    };
    // MinDepth in seed order: the first candidate, then strictly nearer ones.
    let reduce = |acc: &mut Lanes, live: __m256, w: Walk8| {
        let (now, z, wqx, wqy, wtag, wa, wf, ws) = w;
        let c = nearer((acc.closest, acc.closest_depth), wa);
        (acc.closest, acc.closest_depth) = c;
        acc.farthest = _mm256_max_ps(acc.farthest, wf);
        acc.straddle = _mm256_min_ps(acc.straddle, _mm256_blendv_ps(inf, ws, live));
        let has = acc.converged;
        let take = _mm256_and_ps(
            now,
            _mm256_or_ps(
                _mm256_andnot_ps(has, now),
                _mm256_cmp_ps::<_CMP_LT_OQ>(z, _mm256_blendv_ps(inf, acc.depth, has)),
            ),
        );
        acc.depth = _mm256_blendv_ps(acc.depth, z, take);
        acc.qx = _mm256_blendv_ps(acc.qx, wqx, take);
        acc.qy = _mm256_blendv_ps(acc.qy, wqy, take);
        acc.tag = _mm256_blendv_epi8(acc.tag, wtag, _mm256_castps_si256(take));
        acc.converged = _mm256_or_ps(has, now);
    };
    let mut acc = Lanes {
        converged: zero,
        depth: one,
        qx: zero,
        qy: zero,
        tag: _mm256_setzero_si256(),
        closest: inf,
        closest_depth: inf,
        farthest: splat(f32::NEG_INFINITY),
        straddle: inf,
    };
    // Under MinDepth the seeds' walks are independent (only the reduction is in seed order):
    // seeds go in pairs, both walks issued before either is reduced, so that the out-of-order
    // core overlaps their dependent fetch chains (larger batches spill registers).
    let pair = !ls.first_converged;
    let mut j = 0;
    while j < max_n {
        if pair && j + 1 < max_n {
            let (a, b) = (seed(j, acc.converged), seed(j + 1, acc.converged));
            let wa = a.map(|(qx, qy, live)| walk8(ls, k, px, py, qx, qy, live));
            let wb = b.map(|(qx, qy, live)| walk8(ls, k, px, py, qx, qy, live));
            if let (Some((_, _, live)), Some(w)) = (a, wa) {
                reduce(&mut acc, live, w);
            }
            if let (Some((_, _, live)), Some(w)) = (b, wb) {
                reduce(&mut acc, live, w);
            }
            j += 2;
        } else {
            if let Some((qx, qy, live)) = seed(j, acc.converged) {
                reduce(&mut acc, live, walk8(ls, k, px, py, qx, qy, live));
            }
            j += 1;
        }
    }
    acc
}

/// The first iteration of [`walk8`] for one seed per lane (the lanes' own layer only, no
/// Jacobian): the lanes that converged at their seed and the sample's depth, and the lanes that
/// have a sample but did not converge (they need the complete walk; lanes without a sample — outside
/// the image, or an empty texel that layer 0 cannot borrow for — are done), and the squared
/// residual of the lanes with a smooth sample (`+inf` elsewhere: the closest approach so far). Where the eight
/// lanes are two rows of four consecutive pixels whose texels are consecutive and inside the
/// image (the seeds of a resolved tile), the texels are read with row loads instead of gathers.
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn first8(
    ls: &LaneSearch<'_>,
    k: usize,
    px: __m256,
    py: __m256,
    qx: __m256,
    qy: __m256,
    live: __m256,
) -> (__m256, __m256, __m256, (__m256, __m256)) {
    let zero = _mm256_setzero_ps();
    let (half, one) = (splat(0.5), splat(1.0));
    let (wf, hf) = (splat(ls.w as f32), splat(ls.h as f32));
    let inside = _mm256_and_ps(
        _mm256_and_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(qx, zero), _mm256_cmp_ps::<_CMP_GE_OQ>(qy, zero)),
        _mm256_and_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(qx, wf), _mm256_cmp_ps::<_CMP_LT_OQ>(qy, hf)),
    );
    let live = _mm256_and_ps(live, inside);
    if _mm256_movemask_ps(live) == 0 {
        return (zero, one, zero, (splat(f32::INFINITY), splat(f32::INFINITY)));
    }
    let pl = &ls.layers[k];
    let live_i = _mm256_castps_si256(live);
    let wm = _mm256_set1_epi32(ls.w as i32 - 1);
    let hm = _mm256_set1_epi32(ls.h as i32 - 1);
    let ione = _mm256_set1_epi32(1);
    let tx = _mm256_add_ps(qx, half);
    let ty = _mm256_add_ps(qy, half);
    let ix = _mm256_and_si256(_mm256_cvttps_epi32(tx), live_i);
    let iy = _mm256_and_si256(_mm256_cvttps_epi32(ty), live_i);
    let ax = _mm256_sub_ps(tx, _mm256_cvtepi32_ps(ix));
    let ay = _mm256_sub_ps(ty, _mm256_cvtepi32_ps(iy));
    let x0 = _mm256_min_epi32(_mm256_max_epi32(_mm256_sub_epi32(ix, ione), _mm256_setzero_si256()), wm);
    let y0 = _mm256_min_epi32(_mm256_max_epi32(_mm256_sub_epi32(iy, ione), _mm256_setzero_si256()), hm);
    let x1 = _mm256_min_epi32(ix, wm);
    let y1 = _mm256_min_epi32(iy, hm);
    // Row loads where every lane is live, x0 runs by one within each row of four, y0 is shared
    // by each row of four, and no index was clamped (x1 = x0 + 1, y1 = y0 + 1).
    let firsts = _mm256_setr_epi32(0, 0, 0, 0, 4, 4, 4, 4);
    let run = _mm256_add_epi32(_mm256_permutevar8x32_epi32(x0, firsts), _mm256_setr_epi32(0, 1, 2, 3, 0, 1, 2, 3));
    let row = _mm256_permutevar8x32_epi32(y0, firsts);
    let contiguous = _mm256_movemask_ps(live) == 0xff
        && _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_and_si256(
            _mm256_and_si256(_mm256_cmpeq_epi32(x0, run), _mm256_cmpeq_epi32(y0, row)),
            _mm256_and_si256(
                _mm256_cmpeq_epi32(x1, _mm256_add_epi32(x0, ione)),
                _mm256_cmpeq_epi32(y1, _mm256_add_epi32(y0, ione)),
            ),
        ))) == 0xff;
    let w = ls.w as usize;
    let (a, b) = if contiguous {
        let xa = _mm256_extract_epi32::<0>(x0) as usize;
        let xb = _mm256_extract_epi32::<4>(x0) as usize;
        let ya = _mm256_extract_epi32::<0>(y0) as usize;
        let yb = _mm256_extract_epi32::<4>(y0) as usize;
        (ya * w + xa, yb * w + xb)
    } else {
        (0, 0)
    };
    let at = Texels { contiguous, a, b, w, x0, x1, y0, y1, wv: _mm256_set1_epi32(ls.w as i32) };
    let [vx00, vx10, vx01, vx11] = scaled(ls.scale.map(|s| s.0), at.read(pl.vx));
    let [vy00, vy10, vy01, vy11] = scaled(ls.scale.map(|s| s.1), at.read(pl.vy));
    let [z00, z10, z01, z11] = at.read(pl.z);
    // From here on the arithmetic of fetch8, without the Jacobian.
    let valid = |z: __m256| _mm256_and_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(z, zero), _mm256_cmp_ps::<_CMP_LT_OQ>(z, one));
    let all_valid = _mm256_and_ps(_mm256_and_ps(valid(z00), valid(z10)), _mm256_and_ps(valid(z01), valid(z11)));
    let lo_x = _mm256_min_ps(_mm256_min_ps(vx00, vx10), _mm256_min_ps(vx01, vx11));
    let lo_y = _mm256_min_ps(_mm256_min_ps(vy00, vy10), _mm256_min_ps(vy01, vy11));
    let hi_x = _mm256_max_ps(_mm256_max_ps(vx00, vx10), _mm256_max_ps(vx01, vx11));
    let hi_y = _mm256_max_ps(_mm256_max_ps(vy00, vy10), _mm256_max_ps(vy01, vy11));
    let rmax = _mm256_max_ps(_mm256_sub_ps(hi_x, lo_x), _mm256_sub_ps(hi_y, lo_y));
    let smooth = if ls.nearest { zero } else { _mm256_and_ps(all_valid, continuous8(rmax, [z00, z10, z01, z11])) };
    let lerp =
        |a: __m256, b: __m256, s: __m256| _mm256_add_ps(_mm256_mul_ps(a, _mm256_sub_ps(one, s)), _mm256_mul_ps(b, s));
    let bvx = lerp(lerp(vx00, vx10, ax), lerp(vx01, vx11, ax), ay);
    let bvy = lerp(lerp(vy00, vy10, ax), lerp(vy01, vy11, ax), ay);
    let top_d = _mm256_add_ps(z00, _mm256_mul_ps(_mm256_sub_ps(z10, z00), ax));
    let bot_d = _mm256_add_ps(z01, _mm256_mul_ps(_mm256_sub_ps(z11, z01), ax));
    let bz = _mm256_add_ps(top_d, _mm256_mul_ps(_mm256_sub_ps(bot_d, top_d), ay));
    let (vx, vy, z, own) = adaptive8(
        (qx, qy),
        live,
        (x0, y0),
        (wm, hm),
        smooth,
        (bvx, bvy, bz),
        [[vx00, vx10, vx01, vx11], [vy00, vy10, vy01, vy11], [z00, z10, z01, z11]],
    );
    let stx = _mm256_sub_ps(_mm256_sub_ps(px, vx), qx);
    let sty = _mm256_sub_ps(_mm256_sub_ps(py, vy), qy);
    let r2 = _mm256_add_ps(_mm256_mul_ps(stx, stx), _mm256_mul_ps(sty, sty));
    let now = _mm256_and_ps(own, _mm256_cmp_ps::<_CMP_LT_OQ>(r2, splat(ls.thr2)));
    // More iterations: own sample but not converged; or, on a later layer with cross-layer
    // seeding, an empty texel (the walk borrows).
    let mut more = if ls.iterations > 1 { _mm256_andnot_ps(now, own) } else { zero };
    if ls.cross && k > 0 {
        more = _mm256_or_ps(more, _mm256_andnot_ps(own, live));
    }
    let inf = splat(f32::INFINITY);
    let smooth_own = _mm256_and_ps(own, smooth);
    (
        now,
        _mm256_blendv_ps(one, z, now),
        more,
        (_mm256_blendv_ps(inf, r2, smooth_own), _mm256_blendv_ps(inf, z, smooth_own)),
    )
}

/// Where [`first8`] reads the four texels of its lanes: row loads at `a` (lanes 0-3) and `b`
/// (lanes 4-7) when `contiguous`, gathers at the per-lane indices otherwise.
struct Texels {
    contiguous: bool,
    a: usize,
    b: usize,
    w: usize,
    x0: __m256i,
    x1: __m256i,
    y0: __m256i,
    y1: __m256i,
    wv: __m256i,
}

impl Texels {
    /// The texels (x0, y0), (x1, y0), (x0, y1), (x1, y1) of plane `p` per lane.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn read(&self, p: &[f32]) -> [__m256; 4] {
        let ptr = p.as_ptr();
        if self.contiguous {
            let (a, b, w) = (self.a, self.b, self.w);
            [
                _mm256_loadu2_m128(ptr.add(b), ptr.add(a)),
                _mm256_loadu2_m128(ptr.add(b + 1), ptr.add(a + 1)),
                _mm256_loadu2_m128(ptr.add(b + w), ptr.add(a + w)),
                _mm256_loadu2_m128(ptr.add(b + w + 1), ptr.add(a + w + 1)),
            ]
        } else {
            let r0 = _mm256_mullo_epi32(self.y0, self.wv);
            let r1 = _mm256_mullo_epi32(self.y1, self.wv);
            [
                _mm256_i32gather_ps::<4>(ptr, _mm256_add_epi32(r0, self.x0)),
                _mm256_i32gather_ps::<4>(ptr, _mm256_add_epi32(r0, self.x1)),
                _mm256_i32gather_ps::<4>(ptr, _mm256_add_epi32(r1, self.x0)),
                _mm256_i32gather_ps::<4>(ptr, _mm256_add_epi32(r1, self.x1)),
            ]
        }
    }
}

zwarp_core::avx2_or_avx512! {
/// One seed per lane through the walk of `fixed_point_search` on layer `k` (with the
/// cross-layer fallback): the lanes that converged, their sample's depth, position and tag, the
/// walk's closest approach (smallest squared residual of a smooth sampled iterate and its depth,
/// `+inf` if none), its farthest sample's depth after the first step (`-inf` if none) and, for
/// the lanes that failed, its straddle depth (`search::Approach::straddle`, `+inf` if none).
///
/// Most of a warp's time on scenes with many multi-seed pixels: where the CPU has AVX-512 the
/// walk runs a build with it enabled ([`LaneSearch::avx512`]), else the AVX2 build.
unsafe fn walk8(
    ls: &LaneSearch<'_>,
    k: usize,
    px: __m256,
    py: __m256,
    qx: __m256,
    qy: __m256,
    live: __m256,
) -> Walk8 where wide = ls.avx512; {
    walk8_lanes(ls, k, px, py, qx, qy, live)
}
}

/// What [`walk8`] returns: converged lanes, their depth, position and tag, the closest approach
/// (squared residual, depth), the farthest sample's depth and the straddle depth.
type Walk8 = (__m256, __m256, __m256, __m256, __m256i, (__m256, __m256), __m256, __m256);

/// The body of [`walk8`], compiled into each build (no target feature of its own).
#[inline(always)]
unsafe fn walk8_lanes(
    ls: &LaneSearch<'_>,
    k: usize,
    px: __m256,
    py: __m256,
    mut qx: __m256,
    mut qy: __m256,
    mut live: __m256,
) -> Walk8 {
    let zero = _mm256_setzero_ps();
    let one = splat(1.0);
    let inf = splat(f32::INFINITY);
    let (wf, hf) = (splat(ls.w as f32), splat(ls.h as f32));
    let mut farthest = splat(f32::NEG_INFINITY);
    // search::fixed_point_search_closest's straddle state: the previous iterate's smooth sample
    // (lanes `prev_ok`: residual, depth) and the last two samples' straddle depth.
    let (mut prev_ok, mut psx, mut psy, mut pz) = (zero, zero, zero, zero);
    let mut pair = inf;
    let thr2 = splat(ls.thr2);
    let absmask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fff_ffff));
    let mut conv = zero;
    let mut depth = one;
    let (mut cqx, mut cqy) = (zero, zero);
    let mut ctag = _mm256_setzero_si256();
    let mut closest = (splat(f32::INFINITY), splat(f32::INFINITY));
    // Whether the walk already borrowed once (StackSampler's count of empty landings).
    let mut borrowed = zero;
    // The squared step of the previous smooth sample (0: none), for the extra iterations.
    let mut last_r2 = zero;
    let ratio = splat(crate::search::EXTRA_STEP_RATIO);
    for it in 0..ls.iterations + ls.extra_iterations {
        pair = _mm256_blendv_ps(pair, inf, live);
        // StackSampler: outside the image fails the seed.
        let inside = _mm256_and_ps(
            _mm256_and_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(qx, zero), _mm256_cmp_ps::<_CMP_GE_OQ>(qy, zero)),
            _mm256_and_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(qx, wf), _mm256_cmp_ps::<_CMP_LT_OQ>(qy, hf)),
        );
        live = _mm256_and_ps(live, inside);
        if _mm256_movemask_ps(live) == 0 {
            break;
        }
        let mut s = fetch8(&ls.layers[k], ls.w, ls.h, ls.nearest, ls.scale, qx, qy, live);
        let mut tag = _mm256_set1_epi32(k as i32);
        if ls.cross && k > 0 {
            // Empty landing: the second one fails; the first borrows the nearest non-empty layer
            // above at the same position.
            let empty = _mm256_andnot_ps(s.has, live);
            live = _mm256_andnot_ps(_mm256_and_ps(empty, borrowed), live);
            let mut need = _mm256_andnot_ps(borrowed, empty);
            borrowed = _mm256_or_ps(borrowed, empty);
            for j in (0..k).rev() {
                if _mm256_movemask_ps(need) == 0 {
                    break;
                }
                let b = fetch8(&ls.layers[j], ls.w, ls.h, ls.nearest, ls.scale, qx, qy, need);
                let take = b.has;
                s.vx = _mm256_blendv_ps(s.vx, b.vx, take);
                s.vy = _mm256_blendv_ps(s.vy, b.vy, take);
                s.z = _mm256_blendv_ps(s.z, b.z, take);
                s.dxx = _mm256_blendv_ps(s.dxx, b.dxx, take);
                s.dxy = _mm256_blendv_ps(s.dxy, b.dxy, take);
                s.dyx = _mm256_blendv_ps(s.dyx, b.dyx, take);
                s.dyy = _mm256_blendv_ps(s.dyy, b.dyy, take);
                s.smooth = _mm256_blendv_ps(s.smooth, b.smooth, take);
                // StackSampler under the adaptive fetch borrows bilinear samples only: a nearest
                // one fails the seed.
                let usable = if ls.nearest { take } else { _mm256_and_ps(take, b.smooth) };
                s.has = _mm256_or_ps(s.has, usable);
                tag = _mm256_blendv_epi8(tag, _mm256_set1_epi32(j as i32), _mm256_castps_si256(take));
                need = _mm256_andnot_ps(take, need);
            }
        }
        live = _mm256_and_ps(live, s.has);
        if _mm256_movemask_ps(live) == 0 {
            break;
        }
        if it > 0 {
            farthest = _mm256_max_ps(farthest, _mm256_blendv_ps(splat(f32::NEG_INFINITY), s.z, live));
        }
        // fixed_point_search: w = p - v, step = w - q, converged if |step|^2 < thr^2.
        let wx = _mm256_sub_ps(px, s.vx);
        let wy = _mm256_sub_ps(py, s.vy);
        let stx = _mm256_sub_ps(wx, qx);
        let sty = _mm256_sub_ps(wy, qy);
        let r2 = _mm256_add_ps(_mm256_mul_ps(stx, stx), _mm256_mul_ps(sty, sty));
        closest = nearer(closest, (_mm256_blendv_ps(splat(f32::INFINITY), r2, _mm256_and_ps(live, s.smooth)), s.z));
        // search::straddles of the previous and this smooth sample.
        let smooth = _mm256_and_ps(live, s.smooth);
        let (lo, hi) = (_mm256_min_ps(pz, s.z), _mm256_max_ps(pz, s.z));
        let (dx, dy) = (_mm256_sub_ps(psx, stx), _mm256_sub_ps(psy, sty));
        let cross = _mm256_cmp_ps::<_CMP_LT_OQ>(_mm256_add_ps(_mm256_mul_ps(psx, stx), _mm256_mul_ps(psy, sty)), zero);
        let span = _mm256_cmp_ps::<_CMP_LT_OQ>(
            _mm256_add_ps(_mm256_mul_ps(dx, dx), _mm256_mul_ps(dy, dy)),
            splat(crate::search::STRADDLE_SPAN * crate::search::STRADDLE_SPAN),
        );
        let one_surface = _mm256_cmp_ps::<_CMP_LT_OQ>(
            _mm256_sub_ps(one, lo),
            _mm256_mul_ps(splat(crate::search::STRADDLE_DEPTH_RATIO), _mm256_sub_ps(one, hi)),
        );
        let straddling =
            _mm256_and_ps(_mm256_and_ps(_mm256_and_ps(smooth, prev_ok), cross), _mm256_and_ps(span, one_surface));
        pair = _mm256_blendv_ps(pair, lo, straddling);
        prev_ok = smooth;
        psx = _mm256_blendv_ps(psx, stx, smooth);
        psy = _mm256_blendv_ps(psy, sty, smooth);
        pz = _mm256_blendv_ps(pz, s.z, smooth);
        let now = _mm256_and_ps(live, _mm256_cmp_ps::<_CMP_LT_OQ>(r2, thr2));
        depth = _mm256_blendv_ps(depth, s.z, now);
        cqx = _mm256_blendv_ps(cqx, qx, now);
        cqy = _mm256_blendv_ps(cqy, qy, now);
        ctag = _mm256_blendv_epi8(ctag, tag, _mm256_castps_si256(now));
        conv = _mm256_or_ps(conv, now);
        live = _mm256_andnot_ps(now, live);
        if _mm256_movemask_ps(live) == 0 {
            break;
        }
        // After T: only the walks whose smooth step at least halved go on.
        if it + 1 >= ls.iterations {
            live = _mm256_and_ps(
                live,
                _mm256_and_ps(smooth, _mm256_cmp_ps::<_CMP_LT_OQ>(r2, _mm256_mul_ps(ratio, last_r2))),
            );
            if _mm256_movemask_ps(live) == 0 {
                break;
            }
        }
        last_r2 = _mm256_and_ps(smooth, r2);
        // Next iterate: w, or the Newton step where |det(I + Dv)| > 0.05 (newton_step).
        let (mut nx, mut ny) = (wx, wy);
        if ls.accelerate {
            let m00 = _mm256_add_ps(one, s.dxx);
            let m01 = s.dyx;
            let m10 = s.dxy;
            let m11 = _mm256_add_ps(one, s.dyy);
            let det = _mm256_sub_ps(_mm256_mul_ps(m00, m11), _mm256_mul_ps(m01, m10));
            let ok = _mm256_cmp_ps::<_CMP_GT_OQ>(_mm256_and_ps(det, absmask), splat(0.05));
            let neg_m10 = _mm256_xor_ps(m10, splat(-0.0));
            let dx = _mm256_div_ps(_mm256_sub_ps(_mm256_mul_ps(m11, stx), _mm256_mul_ps(m01, sty)), det);
            let dy = _mm256_div_ps(_mm256_add_ps(_mm256_mul_ps(neg_m10, stx), _mm256_mul_ps(m00, sty)), det);
            nx = _mm256_blendv_ps(wx, _mm256_add_ps(qx, dx), ok);
            ny = _mm256_blendv_ps(wy, _mm256_add_ps(qy, dy), ok);
        }
        qx = nx;
        qy = ny;
    }
    (conv, depth, cqx, cqy, ctag, closest, farthest, _mm256_blendv_ps(pair, inf, conv))
}

/// A lane mask (all bits set per active lane) from the low 8 bits of `bits`.
#[inline(always)]
pub(crate) unsafe fn lane_mask(bits: u8) -> __m256 {
    let b = _mm256_set1_epi32(bits as i32);
    let sel = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
    _mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_and_si256(b, sel), sel))
}

/// The mipmap as the AVX2 tightening reads it.
pub(crate) struct PyramidView<'a> {
    /// Texels of every level as floats (`[lo.x, lo.y, hi.x, hi.y]` per texel).
    data: &'a [f32],
    /// Min target depth per texel, same layout.
    zmin: &'a [f32],
    /// Per level - 1 (up to 16 levels): width - 1, height - 1, first texel.
    wm: [i32; 16],
    hm: [i32; 16],
    off: [i32; 16],
    top: i32,
    /// Image size.
    w: u32,
    h: u32,
    frame: BoundFrame,
    /// `WarpParams::motion_scale` applied to every looked-up bound (`None`: unit).
    scale: Option<(f32, f32)>,
}

impl<'a> PyramidView<'a> {
    /// The view of the mipmap of the motion scaled by `s`: every look-up's bound scaled as
    /// `Bound::scaled` scales it, as `MotionPyramid::tight_bound_box_scaled` does.
    pub fn with_scale(self, s: glam::Vec2) -> Self {
        PyramidView { scale: (s != glam::Vec2::ONE).then_some((s.x, s.y)), ..self }
    }

    /// The view of `pyr`, or `None` if it is too deep or too large for 32-bit gathers.
    pub fn new(pyr: &'a crate::bounds::MotionPyramid) -> Option<Self> {
        let (data, zmin, levels) = pyr.raw();
        if data.len() >= (i32::MAX as usize) / 4 || pyr.top_level() > 16 {
            return None;
        }
        let (mut wm, mut hm, mut off) = ([0i32; 16], [0i32; 16], [0i32; 16]);
        for (i, (lw, lh, o)) in levels.enumerate() {
            wm[i] = lw as i32 - 1;
            hm[i] = lh as i32 - 1;
            off[i] = o as i32;
        }
        // SAFETY: [f32; 4] is four f32s without padding.
        let data = unsafe { std::slice::from_raw_parts(data.as_ptr() as *const f32, data.len() * 4) };
        let (w, h) = pyr.size();
        Some(PyramidView {
            data,
            zmin,
            wm,
            hm,
            off,
            top: pyr.top_level() as i32,
            w,
            h,
            frame: pyr.frame(),
            scale: None,
        })
    }
}

/// Per-lane table look-up `t[i - 1]` for `i` in `1..=16`.
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn table(t: &[i32; 16], level: __m256i) -> __m256i {
    let idx = _mm256_sub_epi32(level, _mm256_set1_epi32(1));
    let lo = _mm256_permutevar8x32_epi32(_mm256_loadu_si256(t.as_ptr() as *const __m256i), idx);
    let hi = _mm256_permutevar8x32_epi32(_mm256_loadu_si256(t.as_ptr().add(8) as *const __m256i), idx);
    let high = _mm256_cmpgt_epi32(idx, _mm256_set1_epi32(7));
    _mm256_blendv_epi8(lo, hi, high)
}

/// `MotionPyramid::pixel_range` per lane: the inclusive pixel range `[x0, y0, x1, y1]` of the
/// regions grown by `expand` and clipped, and the lanes whose region misses the image.
#[inline]
#[target_feature(enable = "avx2")]
pub(crate) unsafe fn pixel_range8(pv: &PyramidView<'_>, region: &[__m256; 4], expand: f32) -> ([__m256i; 4], __m256) {
    let [mut lox, mut loy, mut hix, mut hiy] = *region;
    if !pv.frame.is_identity() {
        // The image-space AABB of the rotated box, as `pixel_range` picks its corners.
        let (c, s) = (pv.frame.axis.x, pv.frame.axis.y);
        let (xa, xb) = if c >= 0.0 { (lox, hix) } else { (hix, lox) };
        let (ya, yb) = if s >= 0.0 { (hiy, loy) } else { (loy, hiy) };
        let (sa, sb) = if s >= 0.0 { (lox, hix) } else { (hix, lox) };
        let (ca, cb) = if c >= 0.0 { (loy, hiy) } else { (hiy, loy) };
        let (cv, sv) = (splat(c), splat(s));
        let nlox = _mm256_sub_ps(_mm256_mul_ps(cv, xa), _mm256_mul_ps(sv, ya));
        let nloy = _mm256_add_ps(_mm256_mul_ps(sv, sa), _mm256_mul_ps(cv, ca));
        let nhix = _mm256_sub_ps(_mm256_mul_ps(cv, xb), _mm256_mul_ps(sv, yb));
        let nhiy = _mm256_add_ps(_mm256_mul_ps(sv, sb), _mm256_mul_ps(cv, cb));
        (lox, loy, hix, hiy) = (nlox, nloy, nhix, nhiy);
    }
    let e = splat(expand);
    lox = _mm256_sub_ps(lox, e);
    loy = _mm256_sub_ps(loy, e);
    hix = _mm256_add_ps(hix, e);
    hiy = _mm256_add_ps(hiy, e);
    let (w, h) = (splat(pv.w as f32), splat(pv.h as f32));
    let zero = _mm256_setzero_ps();
    let hit = _mm256_and_ps(
        _mm256_and_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(hix, zero), _mm256_cmp_ps::<_CMP_GE_OQ>(hiy, zero)),
        _mm256_and_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(lox, w), _mm256_cmp_ps::<_CMP_LT_OQ>(loy, h)),
    );
    // cl(v, m) = v < 0 ? 0 : (v > m ? m : v), then truncation and min(size - 1).
    let (wm1, hm1) = (splat(pv.w as f32 - 1.0), splat(pv.h as f32 - 1.0));
    let cl = |v: __m256, m: __m256| {
        let v2 = _mm256_blendv_ps(v, m, _mm256_cmp_ps::<_CMP_GT_OQ>(v, m));
        _mm256_blendv_ps(v2, zero, _mm256_cmp_ps::<_CMP_LT_OQ>(v, zero))
    };
    let hit_i = _mm256_castps_si256(hit);
    let wmi = _mm256_set1_epi32(pv.w as i32 - 1);
    let hmi = _mm256_set1_epi32(pv.h as i32 - 1);
    let u = |v: __m256, m: __m256i| _mm256_min_epi32(_mm256_and_si256(_mm256_cvttps_epi32(v), hit_i), m);
    ([u(cl(lox, wm1), wmi), u(cl(loy, hm1), hmi), u(cl(hix, wm1), wmi), u(cl(hiy, hm1), hmi)], hit)
}

/// The (at most 2x2) texels `level_for_range` picks for each lane's range: their indices
/// (texel units) in the pyramid's buffers, dead lanes at texel 0.
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn texels8(pv: &PyramidView<'_>, r: &[__m256i; 4], live: __m256i) -> [__m256i; 4] {
    let one = _mm256_set1_epi32(1);
    // level_for_range: ceil_log2(max(x1 - x0, y1 - y0)) clamped to 1..=top; ceil_log2(e) for
    // e >= 2 is floor_log2(e - 1) + 1, the float exponent of e - 1 (exact below 2^24).
    let e = _mm256_max_epi32(_mm256_sub_epi32(r[2], r[0]), _mm256_sub_epi32(r[3], r[1]));
    let n = _mm256_max_epi32(_mm256_sub_epi32(e, one), one);
    let exp =
        _mm256_sub_epi32(_mm256_srli_epi32::<23>(_mm256_castps_si256(_mm256_cvtepi32_ps(n))), _mm256_set1_epi32(127));
    let ceil = _mm256_blendv_epi8(
        _mm256_add_epi32(exp, one),
        _mm256_setzero_si256(),
        _mm256_cmpgt_epi32(_mm256_set1_epi32(2), e),
    );
    let level = _mm256_min_epi32(_mm256_max_epi32(ceil, one), _mm256_set1_epi32(pv.top));
    let level = _mm256_blendv_epi8(one, level, live);
    let (wm, hm, off) = (table(&pv.wm, level), table(&pv.hm, level), table(&pv.off, level));
    let tx0 = _mm256_min_epi32(_mm256_srlv_epi32(r[0], level), wm);
    let tx1 = _mm256_min_epi32(_mm256_srlv_epi32(r[2], level), wm);
    let ty0 = _mm256_min_epi32(_mm256_srlv_epi32(r[1], level), hm);
    let ty1 = _mm256_min_epi32(_mm256_srlv_epi32(r[3], level), hm);
    let lw = _mm256_add_epi32(wm, one);
    let row0 = _mm256_add_epi32(off, _mm256_mullo_epi32(ty0, lw));
    let row1 = _mm256_add_epi32(off, _mm256_mullo_epi32(ty1, lw));
    let f = |row: __m256i, tx: __m256i| _mm256_and_si256(_mm256_add_epi32(row, tx), live);
    [f(row0, tx0), f(row0, tx1), f(row1, tx0), f(row1, tx1)]
}

/// `MotionPyramid::lookup_range` per lane: the min-max of the (at most 2x2) texels at
/// `level_for_range` of each lane's range, as `[lo.x, lo.y, hi.x, hi.y]`.
///
/// A texel's four components are 16 contiguous bytes, so each live lane reads its texels with
/// one 128-bit load each and reduces them in place (min of the `lo` half, max of the `hi` half,
/// in the order of the scalar look-up); a 4x4 transpose then hands the lanes back as four
/// vectors. That is a quarter of the loads of per-component gathers, and dead lanes read
/// nothing (their components are zero).
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn lookup8(pv: &PyramidView<'_>, r: &[__m256i; 4], live: __m256i) -> [__m256; 4] {
    let t = texels8(pv, r, live);
    let mut idx = [[0u32; 8]; 4];
    for (i, v) in idx.iter_mut().zip(t) {
        _mm256_storeu_si256(i.as_mut_ptr() as *mut __m256i, v);
    }
    let base = pv.data.as_ptr();
    // Lanes l and l + 4 in one vector: their four texels' min (lo) and max (hi) per lane with
    // 256-bit operations, then [lo.x, lo.y, hi.x, hi.y] per lane. Lanes that are not live read
    // texel 0 (texels8 masks their indices) and are not used.
    let pair = |l: usize| {
        // SAFETY: texels8 gives in-range texel indices (4 floats each).
        let ld = |j: usize| _mm256_loadu2_m128(base.add(idx[j][l + 4] as usize * 4), base.add(idx[j][l] as usize * 4));
        let (a, b, c, d) = (ld(0), ld(1), ld(2), ld(3));
        let lo = _mm256_min_ps(_mm256_min_ps(a, b), _mm256_min_ps(c, d));
        let hi = _mm256_max_ps(_mm256_max_ps(a, b), _mm256_max_ps(c, d));
        _mm256_blend_ps::<0b1100_1100>(lo, hi)
    };
    let (r0, r1, r2, r3) = (pair(0), pair(1), pair(2), pair(3));
    let t0 = _mm256_unpacklo_ps(r0, r1);
    let t1 = _mm256_unpackhi_ps(r0, r1);
    let t2 = _mm256_unpacklo_ps(r2, r3);
    let t3 = _mm256_unpackhi_ps(r2, r3);
    let b = [
        _mm256_shuffle_ps::<0x44>(t0, t2),
        _mm256_shuffle_ps::<0xEE>(t0, t2),
        _mm256_shuffle_ps::<0x44>(t1, t3),
        _mm256_shuffle_ps::<0xEE>(t1, t3),
    ];
    match pv.scale {
        None => b,
        Some((sx, sy)) => {
            // Bound::scaled: lo and hi times the factor, swapped where it is negative; an empty
            // bound (`!(lo <= hi)` on an axis) stays EMPTY (no `0 * inf` NaN).
            let nonempty =
                _mm256_and_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(b[0], b[2]), _mm256_cmp_ps::<_CMP_LE_OQ>(b[1], b[3]));
            let axis = |lo: __m256, hi: __m256, s: f32| {
                let (a, c) = (_mm256_mul_ps(splat(s), lo), _mm256_mul_ps(splat(s), hi));
                if s < 0.0 {
                    (c, a)
                } else {
                    (a, c)
                }
            };
            let (lx, hx) = axis(b[0], b[2], sx);
            let (ly, hy) = axis(b[1], b[3], sy);
            let (inf, ninf) = (splat(f32::INFINITY), splat(f32::NEG_INFINITY));
            [
                _mm256_blendv_ps(inf, lx, nonempty),
                _mm256_blendv_ps(inf, ly, nonempty),
                _mm256_blendv_ps(ninf, hx, nonempty),
                _mm256_blendv_ps(ninf, hy, nonempty),
            ]
        }
    }
}

/// `MotionPyramid::lookup_min_depth` per lane.
#[inline]
#[target_feature(enable = "avx2")]
pub(crate) unsafe fn lookup_min_depth8(pv: &PyramidView<'_>, r: &[__m256i; 4], live: __m256i) -> __m256 {
    let [a, b, c, d] = texels8(pv, r, live);
    let base = pv.zmin.as_ptr();
    let g = |i: __m256i| _mm256_i32gather_ps::<4>(base, i);
    _mm256_min_ps(_mm256_min_ps(g(a), g(b)), _mm256_min_ps(g(c), g(d)))
}

/// `MotionPyramid::tight_bound_box_scaled` (the view's scale) for eight boxes of target positions
/// given by their frame-coordinate bounds `c = [lo.x, lo.y, hi.x, hi.y]` (a pixel: `lo = hi`),
/// from each lane's `start` bound: per lane the tightened bound and its search region, and the
/// lanes that have a bound at all (`None` lanes: the region misses the image or the
/// intersection became empty). Same steps, same early exits per lane.
///
/// # Safety
/// The CPU must support AVX2.
#[target_feature(enable = "avx2")]
unsafe fn tighten8_box(
    pv: &PyramidView<'_>,
    c: &[__m256; 4],
    active: u8,
    start: &[__m256; 4],
    iterations: u32,
    expand: f32,
) -> (u8, [__m256; 4], [__m256; 4]) {
    let region_of = |b: &[__m256; 4]| {
        [_mm256_sub_ps(c[0], b[2]), _mm256_sub_ps(c[1], b[3]), _mm256_sub_ps(c[2], b[0]), _mm256_sub_ps(c[3], b[1])]
    };
    let mut b = *start;
    let mut region = region_of(&b);
    let (mut range, hit) = pixel_range8(pv, &region, expand);
    let mut ok = _mm256_and_ps(lane_mask(active), hit);
    let mut running = ok;
    for _ in 0..iterations {
        if _mm256_movemask_ps(running) == 0 {
            break;
        }
        let run_i = _mm256_castps_si256(running);
        let m = lookup8(pv, &range, run_i);
        // Bound::intersect: lo = max(lo), hi = min(hi).
        let nb = [
            _mm256_max_ps(b[0], m[0]),
            _mm256_max_ps(b[1], m[1]),
            _mm256_min_ps(b[2], m[2]),
            _mm256_min_ps(b[3], m[3]),
        ];
        let nonempty =
            _mm256_and_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(nb[0], nb[2]), _mm256_cmp_ps::<_CMP_LE_OQ>(nb[1], nb[3]));
        // Empty: the lane has no bound.
        ok = _mm256_andnot_ps(_mm256_andnot_ps(nonempty, running), ok);
        running = _mm256_and_ps(running, nonempty);
        // nb == b: fixed point, the lane stops with its bound.
        let same = _mm256_and_ps(
            _mm256_and_ps(_mm256_cmp_ps::<_CMP_EQ_OQ>(nb[0], b[0]), _mm256_cmp_ps::<_CMP_EQ_OQ>(nb[1], b[1])),
            _mm256_and_ps(_mm256_cmp_ps::<_CMP_EQ_OQ>(nb[2], b[2]), _mm256_cmp_ps::<_CMP_EQ_OQ>(nb[3], b[3])),
        );
        running = _mm256_andnot_ps(same, running);
        for i in 0..4 {
            b[i] = _mm256_blendv_ps(b[i], nb[i], running);
        }
        let nregion = region_of(&b);
        for i in 0..4 {
            region[i] = _mm256_blendv_ps(region[i], nregion[i], running);
        }
        let (next, hit) = pixel_range8(pv, &region, expand);
        // The new region misses the image: no bound.
        ok = _mm256_andnot_ps(_mm256_andnot_ps(hit, running), ok);
        running = _mm256_and_ps(running, hit);
        let eq = _mm256_and_si256(
            _mm256_and_si256(_mm256_cmpeq_epi32(next[0], range[0]), _mm256_cmpeq_epi32(next[1], range[1])),
            _mm256_and_si256(_mm256_cmpeq_epi32(next[2], range[2]), _mm256_cmpeq_epi32(next[3], range[3])),
        );
        running = _mm256_andnot_ps(_mm256_castsi256_ps(eq), running);
        let run_i = _mm256_castps_si256(running);
        for i in 0..4 {
            range[i] = _mm256_blendv_epi8(range[i], next[i], run_i);
        }
    }
    (_mm256_movemask_ps(ok) as u8, b, region)
}

/// [`tighten8_box`] for single pixels at target positions `(px, py)`.
///
/// # Safety
/// The CPU must support AVX2.
#[target_feature(enable = "avx2")]
pub(crate) unsafe fn tighten8(
    pv: &PyramidView<'_>,
    px: __m256,
    py: __m256,
    active: u8,
    start: &[__m256; 4],
    iterations: u32,
    expand: f32,
) -> (u8, [__m256; 4], [__m256; 4]) {
    // The frame coordinates of the pixel (`tight_bound_box_scaled` with p_lo == p_hi).
    let f = pv.frame;
    let (cx, cy) = if f.is_identity() {
        (px, py)
    } else {
        let (fc, fs, nfs) = (splat(f.axis.x), splat(f.axis.y), splat(-f.axis.y));
        (
            _mm256_add_ps(_mm256_mul_ps(fc, px), _mm256_mul_ps(fs, py)),
            _mm256_add_ps(_mm256_mul_ps(nfs, px), _mm256_mul_ps(fc, py)),
        )
    };
    tighten8_box(pv, &[cx, cy, cx, cy], active, start, iterations, expand)
}

/// The tile stage of eight 4x4 tiles (`Kernel::start`): Fig. 5 over the union of each tile's
/// search regions from `start` (the global bound scaled as the view's look-ups), with the tiles'
/// corner target positions `p_lo = (lx[i], ly)`, `p_hi = (hx[i], hy)`; for layers after the first
/// (`with_depth`) also the min target depth over the final region.
///
/// # Safety
/// The CPU must support AVX2.
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn tile_stage8(
    pv: &PyramidView<'_>,
    lx: &[f32; 8],
    hx: &[f32; 8],
    ly: f32,
    hy: f32,
    active: u8,
    start: &Bound,
    iterations: u32,
    expand: f32,
    with_depth: bool,
) -> [Option<(Bound, f32)>; 8] {
    let (plx, phx) = (_mm256_loadu_ps(lx.as_ptr()), _mm256_loadu_ps(hx.as_ptr()));
    let (ply, phy) = (splat(ly), splat(hy));
    let f = pv.frame;
    let c = if f.is_identity() {
        [plx, ply, phx, phy]
    } else {
        // tight_bound_box_scaled: the four rotated corners, min / max chained c0, c1, c2, c3.
        let (fc, fs, nfs) = (splat(f.axis.x), splat(f.axis.y), splat(-f.axis.y));
        let rot = |x: __m256, y: __m256| {
            (
                _mm256_add_ps(_mm256_mul_ps(fc, x), _mm256_mul_ps(fs, y)),
                _mm256_add_ps(_mm256_mul_ps(nfs, x), _mm256_mul_ps(fc, y)),
            )
        };
        let c0 = rot(plx, ply);
        let c1 = rot(phx, phy);
        let c2 = rot(plx, phy);
        let c3 = rot(phx, ply);
        let mn = |a: __m256, b: __m256, c: __m256, d: __m256| _mm256_min_ps(_mm256_min_ps(_mm256_min_ps(a, b), c), d);
        let mx = |a: __m256, b: __m256, c: __m256, d: __m256| _mm256_max_ps(_mm256_max_ps(_mm256_max_ps(a, b), c), d);
        [mn(c0.0, c1.0, c2.0, c3.0), mn(c0.1, c1.1, c2.1, c3.1), mx(c0.0, c1.0, c2.0, c3.0), mx(c0.1, c1.1, c2.1, c3.1)]
    };
    if start.is_empty() {
        return [None; 8];
    }
    let (mut ok, b, region) = tighten8_box(pv, &c, active, &splat_bound(start), iterations, expand);
    let zmin = if with_depth {
        let (r, hit) = pixel_range8(pv, &region, expand);
        ok &= _mm256_movemask_ps(hit) as u8;
        lookup_min_depth8(pv, &r, _mm256_castps_si256(lane_mask(ok)))
    } else {
        splat(f32::NEG_INFINITY)
    };
    let mut lanes = [[0f32; 8]; 5];
    for (o, v) in lanes.iter_mut().zip([b[0], b[1], b[2], b[3], zmin]) {
        _mm256_storeu_ps(o.as_mut_ptr(), v);
    }
    std::array::from_fn(|i| {
        (ok >> i & 1 != 0).then(|| {
            (
                Bound { lo: glam::Vec2::new(lanes[0][i], lanes[1][i]), hi: glam::Vec2::new(lanes[2][i], lanes[3][i]) },
                lanes[4][i],
            )
        })
    })
}

/// Step 1 of `holes::fill_background` (the search on the source's empty background) for the
/// eight target pixels `holes` (row-major indices in a `tw`-wide image, source samples per
/// pixel `mf`): bit i is set where pixel i's search converges. The same seeds, samples and
/// steps as the portable `EmptyBackground` search (nearest sampling, zero Jacobian).
///
/// # Safety
/// The CPU must support AVX2; every depth buffer and `motion` must be `w * h` long.
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn background8(
    depths: &[&[f32]],
    motion: &[zwarp_core::Motion],
    w: u32,
    h: u32,
    tw: u32,
    mf: f32,
    holes: &[u32; 8],
    search: &crate::search::SearchParams,
) -> u8 {
    // A run of eight along one row (most holes: the sky) needs one division, not eight.
    let (x0, y0) = (holes[0] % tw, holes[0] / tw);
    let (xi, yi) = if holes[7] == holes[0] + 7 && x0 + 7 < tw {
        let xi = _mm256_add_epi32(_mm256_set1_epi32(x0 as i32), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
        (xi, _mm256_set1_epi32(y0 as i32))
    } else {
        let xs: [i32; 8] = std::array::from_fn(|k| (holes[k] % tw) as i32);
        let ys: [i32; 8] = std::array::from_fn(|k| (holes[k] / tw) as i32);
        (_mm256_loadu_si256(xs.as_ptr() as *const __m256i), _mm256_loadu_si256(ys.as_ptr() as *const __m256i))
    };
    let (px, py) = positions(mf, xi, yi);
    let mp = motion.as_ptr() as *const f32;
    let wv = _mm256_set1_epi32(w as i32);
    let (wm, hm) = (_mm256_set1_epi32(w as i32 - 1), _mm256_set1_epi32(h as i32 - 1));
    let three = _mm256_set1_epi32(3);
    // back = motion[p.y as usize * w + p.x as usize].v.
    let pi = _mm256_add_epi32(_mm256_mullo_epi32(_mm256_cvttps_epi32(py), wv), _mm256_cvttps_epi32(px));
    let iota = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    // Eight consecutive samples (a run of holes along a row, smooth background motion) are read
    // with row loads instead of gathers: the same values.
    let run_start = |i: __m256i| -> Option<usize> {
        let i0 = _mm256_permutevar8x32_epi32(i, _mm256_setzero_si256());
        let run = _mm256_movemask_epi8(_mm256_cmpeq_epi32(i, _mm256_add_epi32(i0, iota))) == -1;
        run.then(|| _mm256_cvtsi256_si32(i0) as usize)
    };
    let (bx, by) = match run_start(pi) {
        Some(i0) => {
            let (vx, vy, _) = crate::simd::avx2::load_motion8(motion.as_ptr().add(i0));
            (vx, vy)
        }
        None => {
            let pi3 = _mm256_mullo_epi32(pi, three);
            (
                _mm256_i32gather_ps::<4>(mp, pi3),
                _mm256_i32gather_ps::<4>(mp, _mm256_add_epi32(pi3, _mm256_set1_epi32(1))),
            )
        }
    };
    // background_seeds: clamp into [0, (w, h) - 1e-3].
    let zero = _mm256_setzero_ps();
    let (mx, my) = (splat(w as f32 - 1e-3), splat(h as f32 - 1e-3));
    let clampx = |v: __m256| _mm256_min_ps(_mm256_max_ps(v, zero), mx);
    let clampy = |v: __m256| _mm256_min_ps(_mm256_max_ps(v, zero), my);
    let seeds = [(clampx(px), clampy(py)), (clampx(_mm256_sub_ps(px, bx)), clampy(_mm256_sub_ps(py, by)))];
    let (wf, hf) = (splat(w as f32), splat(h as f32));
    let thr2 = splat(search.threshold * search.threshold);
    let one = splat(1.0);
    let (m00, m01, m10, m11) = (one, zero, zero, one);
    let det = _mm256_sub_ps(_mm256_mul_ps(m00, m11), _mm256_mul_ps(m01, m10));
    let neg_m10 = _mm256_xor_ps(m10, splat(-0.0));
    let mut conv = zero;
    for (sx, sy) in seeds {
        let (mut qx, mut qy) = (sx, sy);
        let mut live = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
        for _ in 0..search.iterations {
            let inside = _mm256_and_ps(
                _mm256_and_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(qx, zero), _mm256_cmp_ps::<_CMP_GE_OQ>(qy, zero)),
                _mm256_and_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(qx, wf), _mm256_cmp_ps::<_CMP_LT_OQ>(qy, hf)),
            );
            live = _mm256_and_ps(live, inside);
            if _mm256_movemask_ps(live) == 0 {
                break;
            }
            let live_i = _mm256_castps_si256(live);
            let xn = _mm256_min_epi32(_mm256_and_si256(_mm256_cvttps_epi32(qx), live_i), wm);
            let yn = _mm256_min_epi32(_mm256_and_si256(_mm256_cvttps_epi32(qy), live_i), hm);
            let i = _mm256_add_epi32(_mm256_mullo_epi32(yn, wv), xn);
            // All lanes live on a run of samples: row loads (dead lanes' values are never used).
            let run = if _mm256_movemask_ps(live) == 0xff { run_start(i) } else { None };
            // A sample only where no layer has a surface.
            for d in depths {
                let z = match run {
                    Some(i0) => _mm256_loadu_ps(d.as_ptr().add(i0)),
                    None => _mm256_i32gather_ps::<4>(d.as_ptr(), i),
                };
                live = _mm256_and_ps(live, _mm256_cmp_ps::<_CMP_GE_OQ>(z, one));
            }
            if _mm256_movemask_ps(live) == 0 {
                break;
            }
            let (vx, vy) = match run {
                Some(i0) => {
                    let (vx, vy, _) = crate::simd::avx2::load_motion8(motion.as_ptr().add(i0));
                    (vx, vy)
                }
                None => {
                    let i3 = _mm256_and_si256(_mm256_mullo_epi32(i, three), _mm256_castps_si256(live));
                    (
                        _mm256_i32gather_ps::<4>(mp, i3),
                        _mm256_i32gather_ps::<4>(mp, _mm256_add_epi32(i3, _mm256_set1_epi32(1))),
                    )
                }
            };
            let wx = _mm256_sub_ps(px, vx);
            let wy = _mm256_sub_ps(py, vy);
            let stx = _mm256_sub_ps(wx, qx);
            let sty = _mm256_sub_ps(wy, qy);
            let r2 = _mm256_add_ps(_mm256_mul_ps(stx, stx), _mm256_mul_ps(sty, sty));
            let now = _mm256_and_ps(live, _mm256_cmp_ps::<_CMP_LT_OQ>(r2, thr2));
            conv = _mm256_or_ps(conv, now);
            live = _mm256_andnot_ps(now, live);
            if _mm256_movemask_ps(live) == 0 {
                break;
            }
            if search.accelerate {
                // newton_step with a zero Jacobian: q + (I^-1 step), the same products.
                let dx = _mm256_div_ps(_mm256_sub_ps(_mm256_mul_ps(m11, stx), _mm256_mul_ps(m01, sty)), det);
                let dy = _mm256_div_ps(_mm256_add_ps(_mm256_mul_ps(neg_m10, stx), _mm256_mul_ps(m00, sty)), det);
                qx = _mm256_add_ps(qx, dx);
                qy = _mm256_add_ps(qy, dy);
            } else {
                qx = wx;
                qy = wy;
            }
        }
        if _mm256_movemask_ps(conv) == 0xff {
            break;
        }
    }
    _mm256_movemask_ps(conv) as u8
}

/// The common case of a tile in one pass, without the general machinery: layer 0's tile bound
/// is resolved, every active lane has a single seed (the centre of its region) and converges at
/// it, and on every later layer the tile's min-depth test prunes it (or the layer has no bound).
/// Returns the lanes' depths and converged positions, or `None` where any lane needs more (more
/// seeds, more iterations, a later layer's search; lanes without a sample at layer 0 count as
/// decided holes only when there is one layer), and the caller takes the general path.
///
/// # Safety
/// The CPU must support AVX2; the planes must be `w * h` long.
#[inline]
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn fast8(
    ls: &LaneSearch<'_>,
    frame: BoundFrame,
    bound: &Bound,
    later_min_depth: &[f32],
    px: __m256,
    py: __m256,
    active: u8,
) -> Option<(__m256, __m256, __m256, __m256)> {
    let act = lane_mask(active);
    let region = region8(frame, px, py, &splat_bound(bound));
    let [lox, loy, hix, hiy] = region;
    let (ex, ey) = (_mm256_sub_ps(hix, lox), _mm256_sub_ps(hiy, loy));
    let one = splat(1.0);
    let single = _mm256_and_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(ex, one), _mm256_cmp_ps::<_CMP_LE_OQ>(ey, one));
    if _mm256_movemask_ps(_mm256_andnot_ps(single, act)) != 0 {
        return None;
    }
    let (fc, fs, half, zero) = (splat(frame.axis.x), splat(frame.axis.y), splat(0.5), _mm256_setzero_ps());
    let ux = _mm256_add_ps(lox, _mm256_mul_ps(half, ex));
    let uy = _mm256_add_ps(loy, _mm256_mul_ps(half, ey));
    let qx = _mm256_sub_ps(_mm256_mul_ps(fc, ux), _mm256_mul_ps(fs, uy));
    let qy = _mm256_add_ps(_mm256_mul_ps(fs, ux), _mm256_mul_ps(fc, uy));
    let qx = _mm256_min_ps(_mm256_max_ps(qx, zero), splat(ls.max_q.x));
    let qy = _mm256_min_ps(_mm256_max_ps(qy, zero), splat(ls.max_q.y));
    let (now, depth, more, _) = first8(ls, 0, px, py, qx, qy, act);
    if _mm256_movemask_ps(more) != 0 {
        return None;
    }
    if !later_min_depth.is_empty() {
        if _mm256_movemask_ps(_mm256_andnot_ps(now, act)) != 0 {
            return None;
        }
        for &z in later_min_depth {
            if _mm256_movemask_ps(_mm256_and_ps(act, _mm256_cmp_ps::<_CMP_LT_OQ>(splat(z), depth))) != 0 {
                return None;
            }
        }
    }
    Some((now, depth, qx, qy))
}
