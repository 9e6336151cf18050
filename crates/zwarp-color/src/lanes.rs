//! AVX2 lanes of the heuristic warp (seed 001 Sec. 4: "a minimal and high performance
//! reprojection kernel"): eight target pixels of a row at once, the same operations in the same
//! order as the portable path (`heuristic_pixel`: the seed, `zwarp_warp::search::
//! fixed_point_search` with one seed, the orbit in-painting, the colour look-up), so the output
//! is bit-identical (no FMA; `min`/`max`/comparisons with the semantics of glam's). Chosen at
//! run time where the CPU has AVX2 ([`set_simd`] switches it off for tests and timing); the
//! heuristic rows and the robust warp's quads also have an AVX-512-enabled build of the same
//! code ([`set_avx512`]).

use zwarp_core::SimdSwitch;

static AVX2: SimdSwitch = SimdSwitch::avx2();
static AVX512: SimdSwitch = SimdSwitch::avx512();

/// Enables (default) or disables the AVX2 lanes of the colour warps (results are identical).
pub fn set_simd(enabled: bool) {
    AVX2.set(enabled);
}

/// `true` if the AVX2 lanes run: switched on and the CPU has AVX2.
pub fn simd_enabled() -> bool {
    AVX2.active()
}

/// Enables (default) or disables the AVX-512-enabled build of the heuristic rows and the robust
/// warp's quads (the same AVX2 code with 32 registers and mask registers; results identical).
pub fn set_avx512(enabled: bool) {
    AVX512.set(enabled);
}

/// `true` if the AVX-512-enabled build runs: the lanes run, it is switched on and the CPU has
/// AVX-512 F, VL, BW and DQ.
pub fn avx512_enabled() -> bool {
    simd_enabled() && AVX512.active()
}

#[cfg(target_arch = "x86_64")]
pub(crate) mod avx2 {
    use std::arch::x86_64::*;

    use crate::field::Field;
    use zwarp_core::simd::avx2::{interleave3x8, load3x8, pick, store3x8};

    use crate::params::{HeuristicParams, Seed};

    /// Planes of the field as raw pointers (at most three terms).
    struct Planes {
        n: usize,
        x: [*const f32; 3],
        y: [*const f32; 3],
        sx: [__m256; 3],
        sy: [__m256; 3],
        depth: *const f32,
    }

    impl Planes {
        /// The planes of `f` and its terms' factors broadcast.
        #[inline(always)]
        unsafe fn of(f: &Field<'_>) -> Self {
            let terms = f.terms();
            let mut pl = Planes {
                n: terms.len(),
                x: [std::ptr::null(); 3],
                y: [std::ptr::null(); 3],
                sx: [_mm256_setzero_ps(); 3],
                sy: [_mm256_setzero_ps(); 3],
                depth: f.depth().as_ptr(),
            };
            for (k, t) in terms.iter().enumerate() {
                pl.x[k] = t.x.as_ptr();
                pl.y[k] = t.y.as_ptr();
                pl.sx[k] = _mm256_set1_ps(t.scale.x);
                pl.sy[k] = _mm256_set1_ps(t.scale.y);
            }
            pl
        }
    }

    /// The `active` lanes whose position `q` lies in the image `[0, w) x [0, h)`, and the
    /// positions to sample: `q` there, a safe texel centre (0.5, 0.5) in the lanes that are done.
    #[inline(always)]
    unsafe fn in_image(qx: __m256, qy: __m256, wf: __m256, hf: __m256, active: __m256) -> (__m256, __m256, __m256) {
        let zero = _mm256_setzero_ps();
        let inside = _mm256_and_ps(
            _mm256_and_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(qx, zero), _mm256_cmp_ps::<_CMP_GE_OQ>(qy, zero)),
            _mm256_and_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(qx, wf), _mm256_cmp_ps::<_CMP_LT_OQ>(qy, hf)),
        );
        let active = _mm256_and_ps(active, inside);
        let half = _mm256_set1_ps(0.5);
        (active, _mm256_blendv_ps(half, qx, active), _mm256_blendv_ps(half, qy, active))
    }

    /// What both walks read the field through: its planes and the image's size as the lanes
    /// need it.
    struct Grid {
        pl: Planes,
        wi: i32,
        len: usize,
        /// Largest texel column / row.
        wm: __m256i,
        hm: __m256i,
        /// Image width / height.
        wf: __m256,
        hf: __m256,
        /// Largest colour look-up position (just inside the image).
        cx: __m256,
        cy: __m256,
    }

    impl Grid {
        #[inline(always)]
        unsafe fn of(f: &Field<'_>) -> Self {
            let (w, h) = f.size();
            Grid {
                pl: Planes::of(f),
                wi: w as i32,
                len: w as usize * h as usize,
                wm: _mm256_set1_epi32(w as i32 - 1),
                hm: _mm256_set1_epi32(h as i32 - 1),
                wf: _mm256_set1_ps(w as f32),
                hf: _mm256_set1_ps(h as f32),
                cx: _mm256_set1_ps(w as f32 - 1.0e-3),
                cy: _mm256_set1_ps(h as f32 - 1.0e-3),
            }
        }

        /// One iterate of a walk: the `active` lanes left in the image (updated in place) and, if
        /// any, their cells and the cells' texels (motion, depth).
        #[inline(always)]
        unsafe fn fetch(&self, qx: __m256, qy: __m256, active: &mut __m256) -> Option<(Loc, [V2; 4], [__m256; 4])> {
            let (sx, sy);
            (*active, sx, sy) = in_image(qx, qy, self.wf, self.hf, *active);
            if _mm256_movemask_ps(*active) == 0 {
                return None;
            }
            let l = locate(sx, sy, self.wi, self.wm, self.hm);
            let (v4, z4) = cell_texels(&self.pl, &l, *active, self.wi, self.len);
            Some((l, v4, z4))
        }
    }

    /// One recorded iterate per lane: position `q`, the field sample `v` there and its depth (the
    /// heuristic walk's farthest visit, the robust walk's converged iterate).
    #[derive(Clone, Copy)]
    struct Visit {
        qx: __m256,
        qy: __m256,
        vx: __m256,
        vy: __m256,
        z: __m256,
    }

    impl Visit {
        /// Nothing recorded yet: zeros and depth `z`.
        #[inline(always)]
        unsafe fn empty(z: f32) -> Self {
            let zero = _mm256_setzero_ps();
            Visit { qx: zero, qy: zero, vx: zero, vy: zero, z: _mm256_set1_ps(z) }
        }

        /// Takes `(q, v, z)` in the lanes of `mask`.
        #[inline(always)]
        unsafe fn keep(&mut self, mask: __m256, (qx, qy): (__m256, __m256), (vx, vy): (__m256, __m256), z: __m256) {
            self.qx = _mm256_blendv_ps(self.qx, qx, mask);
            self.qy = _mm256_blendv_ps(self.qy, qy, mask);
            self.vx = _mm256_blendv_ps(self.vx, vx, mask);
            self.vy = _mm256_blendv_ps(self.vy, vy, mask);
            self.z = _mm256_blendv_ps(self.z, z, mask);
        }
    }

    /// The fixed-point step of each lane at iterate `q` with sample `v` for target `p`: the next
    /// iterate `w = p - v`, the step `w - q`, and the `active` lanes that converged
    /// (`|w - q|^2 < thr2`).
    #[inline(always)]
    unsafe fn fixed_point_step(
        (px, py): (__m256, __m256),
        (vx, vy): (__m256, __m256),
        (qx, qy): (__m256, __m256),
        active: __m256,
        thr2: __m256,
    ) -> (__m256, __m256, __m256, __m256, __m256) {
        let (wx, wy) = (_mm256_sub_ps(px, vx), _mm256_sub_ps(py, vy));
        let (stx, sty) = (_mm256_sub_ps(wx, qx), _mm256_sub_ps(wy, qy));
        let r2 = _mm256_add_ps(_mm256_mul_ps(stx, stx), _mm256_mul_ps(sty, sty));
        (wx, wy, stx, sty, _mm256_and_ps(active, _mm256_cmp_ps::<_CMP_LT_OQ>(r2, thr2)))
    }

    /// The field sample of each lane's cell: bilinear where `sm`, the nearest texel elsewhere —
    /// `(vx, vy, depth)` and the bilinear rows `[top.x, top.y, bottom.x, bottom.y]` (the
    /// Jacobian's finite differences). Only the `used` lanes' values are defined.
    #[inline(always)]
    unsafe fn sample_cell(
        l: &Loc,
        v4: &[V2; 4],
        z4: &[__m256; 4],
        sm: __m256,
        used: __m256,
    ) -> (__m256, __m256, __m256, [__m256; 4]) {
        let tx = lerp(v4[0].x, v4[1].x, l.ax);
        let ty = lerp(v4[0].y, v4[1].y, l.ax);
        let bx = lerp(v4[2].x, v4[3].x, l.ax);
        let by = lerp(v4[2].y, v4[3].y, l.ax);
        let (vx, vy) = (lerp(tx, bx, l.ay), lerp(ty, by, l.ay));
        let bz = mix(mix(z4[0], z4[1], l.ax), mix(z4[2], z4[3], l.ax), l.ay);
        if all_smooth(sm, used) {
            return (vx, vy, bz, [tx, ty, bx, by]);
        }
        let vx = _mm256_blendv_ps(near(l, [v4[0].x, v4[1].x, v4[2].x, v4[3].x]), vx, sm);
        let vy = _mm256_blendv_ps(near(l, [v4[0].y, v4[1].y, v4[2].y, v4[3].y]), vy, sm);
        (vx, vy, _mm256_blendv_ps(near(l, *z4), bz, sm), [tx, ty, bx, by])
    }

    /// `true` where every `used` lane is smooth: the bilinear value is the sample, the nearest
    /// texel need not be picked.
    #[inline(always)]
    unsafe fn all_smooth(sm: __m256, used: __m256) -> bool {
        _mm256_movemask_ps(_mm256_andnot_ps(sm, used)) == 0
    }

    /// The colour of each lane's cell (per channel its four texels): bilinear where `sm`, the
    /// nearest texel elsewhere. Only the `used` lanes' values are defined.
    #[inline(always)]
    unsafe fn cell_color(l: &Loc, cells: [[__m256; 4]; 3], sm: __m256, used: __m256) -> [__m256; 3] {
        // No closures: they would not take the caller's AVX2.
        let mut rgb = [_mm256_setzero_ps(); 3];
        for (o, c) in rgb.iter_mut().zip(&cells) {
            *o = mix(mix(c[0], c[1], l.ax), mix(c[2], c[3], l.ax), l.ay);
        }
        if !all_smooth(sm, used) {
            for (o, c) in rgb.iter_mut().zip(&cells) {
                *o = _mm256_blendv_ps(near(l, *c), *o, sm);
            }
        }
        rgb
    }

    #[derive(Clone, Copy)]
    struct V2 {
        x: __m256,
        y: __m256,
    }

    #[inline(always)]
    unsafe fn v_at(p: &Planes, idx: __m256i) -> V2 {
        let mut vx = _mm256_setzero_ps();
        let mut vy = _mm256_setzero_ps();
        for k in 0..p.n {
            let gx = _mm256_i32gather_ps::<4>(p.x[k], idx);
            let gy = _mm256_i32gather_ps::<4>(p.y[k], idx);
            vx = _mm256_add_ps(vx, _mm256_mul_ps(p.sx[k], gx));
            vy = _mm256_add_ps(vy, _mm256_mul_ps(p.sy[k], gy));
        }
        V2 { x: vx, y: vy }
    }

    /// The four texel indices, weights, and the nearest-texel selectors of `ColorSampler::locate`.
    struct Loc {
        i: [__m256i; 4],
        ax: __m256,
        ay: __m256,
        hx: __m256,
        hy: __m256,
        /// Cell index `y0 (w - 1) + x0` (0 where the cell does not exist) and its existence.
        cell: __m256i,
        has_cell: __m256,
    }

    #[inline(always)]
    unsafe fn locate(qx: __m256, qy: __m256, w: i32, wm: __m256i, hm: __m256i) -> Loc {
        let half = _mm256_set1_ps(0.5);
        let tx = _mm256_add_ps(qx, half);
        let ty = _mm256_add_ps(qy, half);
        let ix = _mm256_cvttps_epi32(tx);
        let iy = _mm256_cvttps_epi32(ty);
        let ax = _mm256_sub_ps(tx, _mm256_cvtepi32_ps(ix));
        let ay = _mm256_sub_ps(ty, _mm256_cvtepi32_ps(iy));
        let one = _mm256_set1_epi32(1);
        let zero = _mm256_setzero_si256();
        let x0 = _mm256_min_epi32(_mm256_max_epi32(_mm256_sub_epi32(ix, one), zero), wm);
        let y0 = _mm256_min_epi32(_mm256_max_epi32(_mm256_sub_epi32(iy, one), zero), hm);
        let x1 = _mm256_min_epi32(ix, wm);
        let y1 = _mm256_min_epi32(iy, hm);
        let wv = _mm256_set1_epi32(w);
        let r0 = _mm256_mullo_epi32(y0, wv);
        let r1 = _mm256_mullo_epi32(y1, wv);
        let has = _mm256_andnot_si256(
            _mm256_or_si256(_mm256_cmpeq_epi32(x0, x1), _mm256_cmpeq_epi32(y0, y1)),
            _mm256_set1_epi32(-1),
        );
        let cell = _mm256_and_si256(_mm256_add_epi32(_mm256_mullo_epi32(y0, _mm256_sub_epi32(wv, one)), x0), has);
        Loc {
            cell,
            has_cell: _mm256_castsi256_ps(has),
            i: [_mm256_add_epi32(r0, x0), _mm256_add_epi32(r0, x1), _mm256_add_epi32(r1, x0), _mm256_add_epi32(r1, x1)],
            ax,
            ay,
            hx: _mm256_cmp_ps::<_CMP_GE_OQ>(ax, half),
            hy: _mm256_cmp_ps::<_CMP_GE_OQ>(ay, half),
        }
    }

    /// Where the `live` lanes' cells of `l` all lie in one window of eight texels (their first
    /// texels `i[0]` within `m..m + 8`, each cell `i[0], i[0] + 1, i[0] + w, i[0] + w + 1`, and
    /// `m + w + 8` inside the `len`-texel planes): `m` and each lane's offset in the window
    /// (0 for dead lanes). Smooth motion moves neighbouring pixels' cells together, so this is
    /// the common case; the texels are then read with row loads and permutes instead of gathers.
    #[inline(always)]
    unsafe fn window(l: &Loc, live: __m256, w: i32, len: usize) -> Option<(usize, __m256i)> {
        let live_i = _mm256_castps_si256(live);
        let i0 = _mm256_blendv_epi8(_mm256_set1_epi32(i32::MAX), l.i[0], live_i);
        let m1 = _mm256_min_epi32(i0, _mm256_permute2x128_si256::<1>(i0, i0));
        let m2 = _mm256_min_epi32(m1, _mm256_shuffle_epi32::<0b0100_1110>(m1));
        let m3 = _mm256_min_epi32(m2, _mm256_shuffle_epi32::<0b1011_0001>(m2));
        let m = _mm256_cvtsi256_si32(m3);
        let d = _mm256_and_si256(_mm256_sub_epi32(l.i[0], _mm256_set1_epi32(m)), live_i);
        let one = _mm256_set1_epi32(1);
        let cell = _mm256_and_si256(
            _mm256_and_si256(
                _mm256_cmpeq_epi32(l.i[1], _mm256_add_epi32(l.i[0], one)),
                _mm256_cmpeq_epi32(l.i[2], _mm256_add_epi32(l.i[0], _mm256_set1_epi32(w))),
            ),
            _mm256_cmpeq_epi32(l.i[3], _mm256_add_epi32(l.i[2], one)),
        );
        let bad = _mm256_or_si256(_mm256_cmpgt_epi32(d, _mm256_set1_epi32(7)), _mm256_andnot_si256(cell, live_i));
        if m < 0 || _mm256_movemask_epi8(bad) != 0 || m as usize + w as usize + 8 > len {
            return None;
        }
        Some((m as usize, d))
    }

    /// The four texels of each lane's cell from plane `p` through a [`window`].
    #[inline(always)]
    unsafe fn window_texels(p: *const f32, (m, d): (usize, __m256i), w: usize) -> [__m256; 4] {
        [
            _mm256_permutevar8x32_ps(_mm256_loadu_ps(p.add(m)), d),
            _mm256_permutevar8x32_ps(_mm256_loadu_ps(p.add(m + 1)), d),
            _mm256_permutevar8x32_ps(_mm256_loadu_ps(p.add(m + w)), d),
            _mm256_permutevar8x32_ps(_mm256_loadu_ps(p.add(m + w + 1)), d),
        ]
    }

    /// The motion and depth texels of the cells of `l` for the `live` lanes (others: unspecified).
    #[inline(always)]
    unsafe fn cell_texels(p: &Planes, l: &Loc, live: __m256, w: i32, len: usize) -> ([V2; 4], [__m256; 4]) {
        if let Some(win) = window(l, live, w, len) {
            let wu = w as usize;
            let zero = _mm256_setzero_ps();
            let mut v = [V2 { x: zero, y: zero }; 4];
            for k in 0..p.n {
                let (tx, ty) = (window_texels(p.x[k], win, wu), window_texels(p.y[k], win, wu));
                for j in 0..4 {
                    v[j].x = _mm256_add_ps(v[j].x, _mm256_mul_ps(p.sx[k], tx[j]));
                    v[j].y = _mm256_add_ps(v[j].y, _mm256_mul_ps(p.sy[k], ty[j]));
                }
            }
            return (v, window_texels(p.depth, win, wu));
        }
        (
            [v_at(p, l.i[0]), v_at(p, l.i[1]), v_at(p, l.i[2]), v_at(p, l.i[3])],
            [
                _mm256_i32gather_ps::<4>(p.depth, l.i[0]),
                _mm256_i32gather_ps::<4>(p.depth, l.i[1]),
                _mm256_i32gather_ps::<4>(p.depth, l.i[2]),
                _mm256_i32gather_ps::<4>(p.depth, l.i[3]),
            ],
        )
    }

    /// A lane mask spread over the three vectors of `interleave3x8` (lane k covers floats
    /// 3k..3k + 3).
    #[inline(always)]
    unsafe fn spread_mask3(m: __m256) -> [__m256; 3] {
        [pick(m, [0, 0, 0, 1, 1, 1, 2, 2]), pick(m, [2, 3, 3, 3, 4, 4, 4, 5]), pick(m, [5, 5, 6, 6, 6, 7, 7, 7])]
    }

    /// The colour texels of each lane's cell (per channel the four texels) for the `live`
    /// lanes: through a [`window`] (each row's texels `m..m + 8` and `m + 1..m + 9`
    /// transposed to channel vectors, a lane's texel picked by a permute), else with gathers.
    #[inline(always)]
    unsafe fn cell_rgb(color: &[[f32; 3]], l: &Loc, live: __m256, w: i32, len: usize) -> [[__m256; 4]; 3] {
        let base = color.as_ptr() as *const f32;
        let three = _mm256_set1_epi32(3);
        let wu = w as usize;
        let mut out = [[_mm256_setzero_ps(); 4]; 3];
        match window(l, live, w, len) {
            Some((m, d)) if m + wu + 9 <= len => {
                // The robust warp walks a quad's pixel rows downwards, so the texel row below
                // this cell is read next: fetching it now hides that miss (~10 % of the robust
                // warp at 720p).
                if m + 2 * wu + 9 <= len {
                    let n = base.add(3 * (m + 2 * wu)) as *const i8;
                    _mm_prefetch::<_MM_HINT_T0>(n);
                    _mm_prefetch::<_MM_HINT_T0>(n.add(64));
                    _mm_prefetch::<_MM_HINT_T0>(n.add(107));
                }
                let rows = [
                    load3x8(base.add(3 * m)),
                    load3x8(base.add(3 * (m + 1))),
                    load3x8(base.add(3 * (m + wu))),
                    load3x8(base.add(3 * (m + wu + 1))),
                ];
                for (ch, o) in out.iter_mut().enumerate() {
                    *o = [
                        _mm256_permutevar8x32_ps(rows[0][ch], d),
                        _mm256_permutevar8x32_ps(rows[1][ch], d),
                        _mm256_permutevar8x32_ps(rows[2][ch], d),
                        _mm256_permutevar8x32_ps(rows[3][ch], d),
                    ];
                }
            }
            _ => {
                for (ch, o) in out.iter_mut().enumerate() {
                    let off = _mm256_set1_epi32(ch as i32);
                    for (t, &i) in o.iter_mut().zip(&l.i) {
                        *t = _mm256_i32gather_ps::<4>(base, _mm256_add_epi32(_mm256_mullo_epi32(i, three), off));
                    }
                }
            }
        }
        out
    }

    /// Selects texel `k` of the four by the nearest-texel masks.
    #[inline(always)]
    unsafe fn near(l: &Loc, a: [__m256; 4]) -> __m256 {
        let top = _mm256_blendv_ps(a[0], a[1], l.hx);
        let bot = _mm256_blendv_ps(a[2], a[3], l.hx);
        _mm256_blendv_ps(top, bot, l.hy)
    }

    /// glam's `a.lerp(b, s)`: `a * (1 - s) + b * s`.
    #[inline(always)]
    unsafe fn lerp(a: __m256, b: __m256, s: __m256) -> __m256 {
        let one = _mm256_set1_ps(1.0);
        _mm256_add_ps(_mm256_mul_ps(a, _mm256_sub_ps(one, s)), _mm256_mul_ps(b, s))
    }

    /// `a + (b - a) * s` (the scalar depth and colour interpolation).
    #[inline(always)]
    unsafe fn mix(a: __m256, b: __m256, s: __m256) -> __m256 {
        _mm256_add_ps(a, _mm256_mul_ps(_mm256_sub_ps(b, a), s))
    }

    #[inline(always)]
    unsafe fn smooth(v: &[V2; 4]) -> __m256 {
        let lox = _mm256_min_ps(_mm256_min_ps(v[0].x, v[1].x), _mm256_min_ps(v[2].x, v[3].x));
        let loy = _mm256_min_ps(_mm256_min_ps(v[0].y, v[1].y), _mm256_min_ps(v[2].y, v[3].y));
        let hix = _mm256_max_ps(_mm256_max_ps(v[0].x, v[1].x), _mm256_max_ps(v[2].x, v[3].x));
        let hiy = _mm256_max_ps(_mm256_max_ps(v[0].y, v[1].y), _mm256_max_ps(v[2].y, v[3].y));
        let d = _mm256_max_ps(_mm256_sub_ps(hix, lox), _mm256_sub_ps(hiy, loy));
        _mm256_cmp_ps::<_CMP_LT_OQ>(d, _mm256_set1_ps(zwarp_warp::sampling::CONTINUITY_PX))
    }

    zwarp_core::avx2_or_avx512! {
        /// The heuristic warp of row `y`, eight pixels at a time ([`heuristic8`]) while eight
        /// remain: returns where the portable path takes over. AVX-512-enabled where the CPU
        /// has it.
        pub(crate) unsafe fn heuristic_row(
            f: &Field<'_>,
            color: &[[f32; 3]],
            params: &HeuristicParams,
            y: usize,
            oc: &mut [[f32; 3]],
            od: &mut [f32],
            or: &mut [f32],
        ) -> usize where wide = super::avx512_enabled(); {
            let mut x0 = 0;
            while x0 + 8 <= oc.len() {
                heuristic8(f, color, params, x0, y, &mut oc[x0..x0 + 8], &mut od[x0..x0 + 8], &mut or[x0..x0 + 8]);
                x0 += 8;
            }
            x0
        }
    }

    /// The heuristic warp of pixels `x0..x0 + 8` of row `y` (all inside the image); inlined into
    /// [`heuristic_row`], whose loop keeps the set-up out of the per-group work.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    unsafe fn heuristic8(
        f: &Field<'_>,
        color: &[[f32; 3]],
        params: &HeuristicParams,
        x0: usize,
        y: usize,
        oc: &mut [[f32; 3]],
        od: &mut [f32],
        or: &mut [f32],
    ) {
        let g = Grid::of(f);
        let (pl, w) = (&g.pl, f.size().0);
        let zero = _mm256_setzero_ps();
        let lane = _mm256_setr_ps(0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0);
        let px = _mm256_add_ps(_mm256_set1_ps(x0 as f32 + 0.5), lane);
        // x0 + 0.5 + lane equals (x0 + lane) + 0.5 exactly for image-sized coordinates.
        let py = _mm256_set1_ps(y as f32 + 0.5);
        // Seed.
        let (mut qx, mut qy) = match params.seed {
            Seed::Pixel => (px, py),
            Seed::Offset(d) => (_mm256_add_ps(px, _mm256_set1_ps(d.x)), _mm256_add_ps(py, _mm256_set1_ps(d.y))),
            Seed::Upstream(k) => {
                // At a pixel centre both samplings return texel (x, y) (bilinear weights are 0;
                // `v0 * 1 + v1 * 0` is `v0` up to the sign of a zero, which `p - k v` drops).
                let i = (y * w as usize + x0) as isize;
                let mut vx = zero;
                let mut vy = zero;
                for t in 0..pl.n {
                    vx = _mm256_add_ps(vx, _mm256_mul_ps(pl.sx[t], _mm256_loadu_ps(pl.x[t].offset(i))));
                    vy = _mm256_add_ps(vy, _mm256_mul_ps(pl.sy[t], _mm256_loadu_ps(pl.y[t].offset(i))));
                }
                let kk = _mm256_set1_ps(k);
                (_mm256_sub_ps(px, _mm256_mul_ps(kk, vx)), _mm256_sub_ps(py, _mm256_mul_ps(kk, vy)))
            }
        };
        // Clamp into the image (glam: max then min).
        qx = _mm256_min_ps(_mm256_max_ps(qx, zero), g.cx);
        qy = _mm256_min_ps(_mm256_max_ps(qy, zero), g.cy);
        let thr2 = _mm256_set1_ps(params.threshold * params.threshold);
        let all = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
        let mut active = all;
        let mut conv = zero;
        // Converged lanes: colour position, depth, residual.
        let (mut cqx, mut cqy, mut cz, mut cr) = (zero, zero, zero, zero);
        // The converged iteration's cell (first and last texel) and its continuity.
        let (mut ci0, mut ci3, mut csm) = (_mm256_set1_epi32(-1), _mm256_set1_epi32(-1), zero);
        // Orbit: the farthest visit (ties: the later one).
        let mut far = Visit::empty(f32::NEG_INFINITY);
        let mut visited = zero;
        for _ in 0..params.iterations {
            let Some((l, v4, z4)) = g.fetch(qx, qy, &mut active) else { break };
            let sm = smooth(&v4);
            let (vx, vy, z, _) = sample_cell(&l, &v4, &z4, sm, active);
            // Record the visit (the orbit's farthest sample).
            let better = _mm256_and_ps(
                active,
                _mm256_or_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(z, far.z), _mm256_andnot_ps(visited, all)),
            );
            far.keep(better, (qx, qy), (vx, vy), z);
            visited = _mm256_or_ps(visited, active);
            let (wx, wy, _, _, now) = fixed_point_step((px, py), (vx, vy), (qx, qy), active, thr2);
            // Residual |q + v - p| and the colour position p - v.
            let ex = _mm256_sub_ps(_mm256_add_ps(qx, vx), px);
            let ey = _mm256_sub_ps(_mm256_add_ps(qy, vy), py);
            let res = _mm256_sqrt_ps(_mm256_add_ps(_mm256_mul_ps(ex, ex), _mm256_mul_ps(ey, ey)));
            cqx = _mm256_blendv_ps(cqx, wx, now);
            cqy = _mm256_blendv_ps(cqy, wy, now);
            cz = _mm256_blendv_ps(cz, z, now);
            cr = _mm256_blendv_ps(cr, res, now);
            let nowi = _mm256_castps_si256(now);
            ci0 = _mm256_blendv_epi8(ci0, l.i[0], nowi);
            ci3 = _mm256_blendv_epi8(ci3, l.i[3], nowi);
            csm = _mm256_blendv_ps(csm, sm, now);
            conv = _mm256_or_ps(conv, now);
            active = _mm256_andnot_ps(now, active);
            qx = _mm256_blendv_ps(qx, wx, active);
            qy = _mm256_blendv_ps(qy, wy, active);
        }
        // Not converged: the farthest visit (every lane visited its clamped seed).
        let bex = _mm256_sub_ps(_mm256_add_ps(far.qx, far.vx), px);
        let bey = _mm256_sub_ps(_mm256_add_ps(far.qy, far.vy), py);
        let bres = _mm256_sqrt_ps(_mm256_add_ps(_mm256_mul_ps(bex, bex), _mm256_mul_ps(bey, bey)));
        let colx = _mm256_blendv_ps(far.qx, cqx, conv);
        let coly = _mm256_blendv_ps(far.qy, cqy, conv);
        let outz = _mm256_blendv_ps(far.z, cz, conv);
        let outr = _mm256_blendv_ps(bres, cr, conv);
        // Colour at (colx, coly), clamped (ColorSampler::color).
        let qx = _mm256_min_ps(_mm256_max_ps(colx, zero), g.cx);
        let qy = _mm256_min_ps(_mm256_max_ps(coly, zero), g.cy);
        let l = locate(qx, qy, g.wi, g.wm, g.hm);
        // The continuity of a cell depends only on its texels: where every lane's colour cell
        // is the cell it converged in, the mask is known (the common case: q and p - V(q)
        // less than the threshold apart).
        let same = _mm256_and_si256(_mm256_cmpeq_epi32(l.i[0], ci0), _mm256_cmpeq_epi32(l.i[3], ci3));
        let sm = if _mm256_movemask_epi8(same) == -1 {
            csm
        } else {
            let v4 = [v_at(pl, l.i[0]), v_at(pl, l.i[1]), v_at(pl, l.i[2]), v_at(pl, l.i[3])];
            smooth(&v4)
        };
        let rgb = cell_color(&l, cell_rgb(color, &l, all, g.wi, g.len), sm, all);
        debug_assert!(oc.len() == 8);
        store3x8(oc.as_mut_ptr() as *mut f32, rgb);
        _mm256_storeu_ps(od.as_mut_ptr(), outz);
        _mm256_storeu_ps(or.as_mut_ptr(), outr);
    }

    /// Continuity of the cells of `l` by their `rho` (seed 001 Sec. 3.4): `rho < 1` where the
    /// cell exists.
    #[inline(always)]
    unsafe fn smooth_rho(l: &Loc, rho: *const f32) -> __m256 {
        let r = _mm256_i32gather_ps::<4>(rho, l.cell);
        _mm256_and_ps(l.has_cell, _mm256_cmp_ps::<_CMP_LT_OQ>(r, _mm256_set1_ps(1.0)))
    }

    /// One warped quad of the robust warp as the lanes need it (see `robust::Warped`).
    pub(crate) struct Quad {
        pub dst_lo: [f32; 2],
        pub dst_ext: [f32; 2],
        pub src_lo: [f32; 2],
        pub src_ext: [f32; 2],
        /// Footprint `[x0, x1) x [y0, y1)`.
        pub foot: [f32; 4],
    }

    /// The target rows [`robust_rows`] writes into: a band of whole rows of the output
    /// buffers, `width` pixels each, the first one image row `y0`.
    pub(crate) struct BandOut<'a> {
        pub depth: &'a mut [f32],
        pub color: &'a mut [[f32; 3]],
        pub residual: &'a mut [f32],
        pub width: usize,
        pub y0: i32,
    }

    zwarp_core::avx2_or_avx512! {
        /// The robust warp's search for pixels `px0..px1` of rows `py0..py1` from quad `q`,
        /// eight at a time: the interpolated seed, the shared search's walk (Newton steps with
        /// `accelerate`), the footprint test and the colour at `p - V(q)` — the portable loop's
        /// arithmetic. An accepted lane nearer than what `band` holds at its pixel replaces
        /// depth, colour and residual there (the portable loop's depth test, eight pixels per
        /// masked store); the set-up (planes, sizes) is done once per quad. AVX-512-enabled
        /// where the CPU has it.
        #[allow(clippy::too_many_arguments)]
        pub(crate) unsafe fn robust_rows(
            f: &Field<'_>,
            rho: &[f32],
            color: &[[f32; 3]],
            q: &Quad,
            pixels: (i32, i32, i32, i32),
            iterations: u32,
            threshold: f32,
            accelerate: bool,
            band: BandOut<'_>,
        ) where wide = super::avx512_enabled(); {
            let (px0, px1, py0, py1) = pixels;
            let g = Grid::of(f);
            let rp = rho.as_ptr();
            let zero = _mm256_setzero_ps();
            let one = _mm256_set1_ps(1.0);
            let sign = _mm256_set1_ps(-0.0);
            let lane_i = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
            let thr2 = _mm256_set1_ps(threshold * threshold);
            // The seed (Warped::seed): the pixel's relative position in the warped box mapped into
            // the source box, clamped to the footprint.
            let rel = |p: __m256, k: usize| {
                if q.dst_ext[k] > 1e-6 {
                    _mm256_div_ps(_mm256_sub_ps(p, _mm256_set1_ps(q.dst_lo[k])), _mm256_set1_ps(q.dst_ext[k]))
                } else {
                    _mm256_set1_ps(0.5)
                }
            };
            let seed = |rel: __m256, k: usize| {
                let s = _mm256_add_ps(_mm256_set1_ps(q.src_lo[k]), _mm256_mul_ps(rel, _mm256_set1_ps(q.src_ext[k])));
                let (lo, hi) = (q.src_lo[k] - 0.5, (q.src_lo[k] + q.src_ext[k]) + 0.499);
                _mm256_min_ps(_mm256_max_ps(s, _mm256_set1_ps(lo)), _mm256_set1_ps(hi))
            };
            let bw = band.width;
            for py in py0..py1 {
                let row = (py - band.y0) as usize * bw;
                let (od, oc, or) =
                    (&mut band.depth[row..row + bw], &mut band.color[row..row + bw], &mut band.residual[row..row + bw]);
                let ppy = _mm256_set1_ps(py as f32 + 0.5);
                let sy = seed(rel(ppy, 1), 1);
                let mut px = px0;
                while px < px1 {
                    let n = ((px1 - px) as usize).min(8);
                    let valid = _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(n as i32), lane_i));
                    let ppx = _mm256_add_ps(
                        _mm256_cvtepi32_ps(_mm256_add_epi32(_mm256_set1_epi32(px), lane_i)),
                        _mm256_set1_ps(0.5),
                    );
                    let (mut qx, mut qy) = (seed(rel(ppx, 0), 0), sy);
                    let mut active = valid;
                    let mut conv = zero;
                    let mut c = Visit::empty(0.0);
                    for _ in 0..iterations {
                        let Some((l, v4, z4)) = g.fetch(qx, qy, &mut active) else { break };
                        let sm = smooth_rho(&l, rp);
                        let (vx, vy, z, [tx, ty, bx, by]) = sample_cell(&l, &v4, &z4, sm, active);
                        let (wx, wy, stx, sty, now) = fixed_point_step((ppx, ppy), (vx, vy), (qx, qy), active, thr2);
                        c.keep(now, (qx, qy), (vx, vy), z);
                        conv = _mm256_or_ps(conv, now);
                        active = _mm256_andnot_ps(now, active);
                        let (mut nx, mut ny) = (wx, wy);
                        if accelerate {
                            // newton_step with the bilinear Jacobian (zero for nearest samples).
                            let dxx = _mm256_and_ps(
                                sm,
                                lerp(_mm256_sub_ps(v4[1].x, v4[0].x), _mm256_sub_ps(v4[3].x, v4[2].x), l.ay),
                            );
                            let dxy = _mm256_and_ps(
                                sm,
                                lerp(_mm256_sub_ps(v4[1].y, v4[0].y), _mm256_sub_ps(v4[3].y, v4[2].y), l.ay),
                            );
                            let dyx = _mm256_and_ps(sm, _mm256_sub_ps(bx, tx));
                            let dyy = _mm256_and_ps(sm, _mm256_sub_ps(by, ty));
                            let m00 = _mm256_add_ps(one, dxx);
                            let m01 = dyx;
                            let m10 = dxy;
                            let m11 = _mm256_add_ps(one, dyy);
                            let det = _mm256_sub_ps(_mm256_mul_ps(m00, m11), _mm256_mul_ps(m01, m10));
                            let ok = _mm256_cmp_ps::<_CMP_GT_OQ>(_mm256_andnot_ps(sign, det), _mm256_set1_ps(0.05));
                            let ddx = _mm256_div_ps(_mm256_sub_ps(_mm256_mul_ps(m11, stx), _mm256_mul_ps(m01, sty)), det);
                            let ddy = _mm256_div_ps(
                                _mm256_add_ps(_mm256_mul_ps(_mm256_xor_ps(m10, sign), stx), _mm256_mul_ps(m00, sty)),
                                det,
                            );
                            nx = _mm256_blendv_ps(wx, _mm256_add_ps(qx, ddx), ok);
                            ny = _mm256_blendv_ps(wy, _mm256_add_ps(qy, ddy), ok);
                        }
                        qx = _mm256_blendv_ps(qx, nx, active);
                        qy = _mm256_blendv_ps(qy, ny, active);
                    }
                    let foot = _mm256_and_ps(
                        _mm256_and_ps(
                            _mm256_cmp_ps::<_CMP_GE_OQ>(c.qx, _mm256_set1_ps(q.foot[0])),
                            _mm256_cmp_ps::<_CMP_LT_OQ>(c.qx, _mm256_set1_ps(q.foot[1])),
                        ),
                        _mm256_and_ps(
                            _mm256_cmp_ps::<_CMP_GE_OQ>(c.qy, _mm256_set1_ps(q.foot[2])),
                            _mm256_cmp_ps::<_CMP_LT_OQ>(c.qy, _mm256_set1_ps(q.foot[3])),
                        ),
                    );
                    let acc = _mm256_and_ps(conv, foot);
                    // Accepted and nearer than what the row holds (`<`: the portable depth test).
                    let x = px as usize;
                    let whole = x + 8 <= bw;
                    let old_z = if whole { _mm256_loadu_ps(od.as_ptr().add(x)) } else { _mm256_set1_ps(f32::INFINITY) };
                    let win = _mm256_and_ps(acc, _mm256_cmp_ps::<_CMP_LT_OQ>(c.z, old_z));
                    if _mm256_movemask_ps(if whole { win } else { acc }) == 0 {
                        px += 8;
                        continue;
                    }
                    let ex = _mm256_sub_ps(_mm256_add_ps(c.qx, c.vx), ppx);
                    let ey = _mm256_sub_ps(_mm256_add_ps(c.qy, c.vy), ppy);
                    let res = _mm256_sqrt_ps(_mm256_add_ps(_mm256_mul_ps(ex, ex), _mm256_mul_ps(ey, ey)));
                    // Colour at p - V(q), clamped, continuity by rho (ColorSampler::color).
                    let colx = _mm256_blendv_ps(_mm256_set1_ps(0.5), _mm256_sub_ps(ppx, c.vx), acc);
                    let coly = _mm256_blendv_ps(_mm256_set1_ps(0.5), _mm256_sub_ps(ppy, c.vy), acc);
                    let qx = _mm256_min_ps(_mm256_max_ps(colx, zero), g.cx);
                    let qy = _mm256_min_ps(_mm256_max_ps(coly, zero), g.cy);
                    let l = locate(qx, qy, g.wi, g.wm, g.hm);
                    let sm = smooth_rho(&l, rp);
                    let rgb = cell_color(&l, cell_rgb(color, &l, acc, g.wi, g.len), sm, acc);
                    if whole {
                        _mm256_storeu_ps(od.as_mut_ptr().add(x), _mm256_blendv_ps(old_z, c.z, win));
                        let rp = or.as_mut_ptr().add(x);
                        _mm256_storeu_ps(rp, _mm256_blendv_ps(_mm256_loadu_ps(rp), res, win));
                        let cp = oc.as_mut_ptr().add(x) as *mut f32;
                        for ((k, v), m) in interleave3x8(rgb).into_iter().enumerate().zip(spread_mask3(win)) {
                            let q = cp.add(8 * k);
                            _mm256_storeu_ps(q, _mm256_blendv_ps(_mm256_loadu_ps(q), v, m));
                        }
                    } else {
                        // The row's last pixels: lane by lane.
                        let (mut z8, mut r8, mut c8) = ([0f32; 8], [0f32; 8], [[0f32; 3]; 8]);
                        _mm256_storeu_ps(z8.as_mut_ptr(), c.z);
                        _mm256_storeu_ps(r8.as_mut_ptr(), res);
                        store3x8(c8.as_mut_ptr() as *mut f32, rgb);
                        let mut m = _mm256_movemask_ps(acc) as u32;
                        while m != 0 {
                            let k = m.trailing_zeros() as usize;
                            m &= m - 1;
                            if z8[k] < od[x + k] {
                                (od[x + k], oc[x + k], or[x + k]) = (z8[k], c8[k], r8[k]);
                            }
                        }
                    }
                    px += 8;
                }
            }
        }
    }

    /// `spectral_radius(dx, dy)` of eight cells (same operations as the scalar function).
    #[inline(always)]
    unsafe fn radius8(dxx: __m256, dxy: __m256, dyx: __m256, dyy: __m256) -> __m256 {
        // a = dx.x, b = dy.x, c = dx.y, d = dy.y
        let tr = _mm256_add_ps(dxx, dyy);
        let det = _mm256_sub_ps(_mm256_mul_ps(dxx, dyy), _mm256_mul_ps(dyx, dxy));
        let disc = _mm256_sub_ps(_mm256_mul_ps(_mm256_mul_ps(_mm256_set1_ps(0.25), tr), tr), det);
        let real = _mm256_add_ps(
            _mm256_mul_ps(_mm256_set1_ps(0.5), _mm256_andnot_ps(_mm256_set1_ps(-0.0), tr)),
            _mm256_sqrt_ps(disc),
        );
        let complex = _mm256_sqrt_ps(_mm256_max_ps(det, _mm256_setzero_ps()));
        _mm256_blendv_ps(complex, real, _mm256_cmp_ps::<_CMP_GE_OQ>(disc, _mm256_setzero_ps()))
    }

    /// `rho` of the cells of one row from the field on its two texel rows (`a`: top, `b`:
    /// bottom; `cw + 1` values each), eight cells at a time; returns how many cells it wrote
    /// (the rest is left to the portable loop).
    #[target_feature(enable = "avx2")]
    pub(crate) unsafe fn rho_row(ax: &[f32], ay: &[f32], bx: &[f32], by: &[f32], out: &mut [f32]) -> usize {
        let cw = out.len();
        let mut cx = 0;
        while cx + 8 <= cw {
            let l = |s: &[f32], o: usize| _mm256_loadu_ps(s.as_ptr().add(cx + o));
            let (vax, vay, vbx, vby) = (l(ax, 0), l(ay, 0), l(ax, 1), l(ay, 1));
            let (vcx, vcy, vdx, vdy) = (l(bx, 0), l(by, 0), l(bx, 1), l(by, 1));
            // dxt = vb - va, dxb = vd - vc, dyl = vc - va, dyr = vd - vb
            let (dxtx, dxty) = (_mm256_sub_ps(vbx, vax), _mm256_sub_ps(vby, vay));
            let (dxbx, dxby) = (_mm256_sub_ps(vdx, vcx), _mm256_sub_ps(vdy, vcy));
            let (dylx, dyly) = (_mm256_sub_ps(vcx, vax), _mm256_sub_ps(vcy, vay));
            let (dyrx, dyry) = (_mm256_sub_ps(vdx, vbx), _mm256_sub_ps(vdy, vby));
            let r = _mm256_max_ps(
                _mm256_max_ps(
                    _mm256_max_ps(radius8(dxtx, dxty, dylx, dyly), radius8(dxtx, dxty, dyrx, dyry)),
                    radius8(dxbx, dxby, dylx, dyly),
                ),
                radius8(dxbx, dxby, dyrx, dyry),
            );
            _mm256_storeu_ps(out.as_mut_ptr().add(cx), r);
            cx += 8;
        }
        cx
    }
}
