//! The AVX2 builds of the forward warps' row passes, eight source pixels per step, each
//! bit-identical to its portable twin in `super` (same operations in the same order, no FMA):
//! the validating row check, AFW's splats and VFW's quads.
//!
//! VFW: each lane's quad is tested against the pixel centres of a 3 x 3 window at its bounding
//! box (a smooth surface's expanded quad covers 2 x 2 to 3 x 3); lanes whose box is larger, and
//! the image's border pixels, take the portable path.

use std::arch::x86_64::*;

use super::{
    row_check as row_check_portable, sample_at, valid, vfw_pixel, Band, Motion, WarpLayer, AFW_HALF_SIZE,
    CONTINUITY_PX, EMPTY_DEPTH, FORWARD_SUPPORT_EXPANSION, VFW_ROW_REACH,
};
use crate::simd::avx2::load_motion8;

/// Eight consecutive samples of one row: motion and validity (`super::valid`).
#[derive(Clone, Copy)]
struct Samples {
    vx: __m256,
    vy: __m256,
    z: __m256,
    ok: __m256,
}

/// A corner or a point for eight lanes.
#[derive(Clone, Copy)]
struct P8 {
    x: __m256,
    y: __m256,
}

#[inline(always)]
unsafe fn ps(v: f32) -> __m256 {
    _mm256_set1_ps(v)
}

/// Lanes of `v` that are finite.
#[inline(always)]
unsafe fn finite(v: __m256) -> __m256 {
    _mm256_cmp_ps::<_CMP_LT_OQ>(_mm256_andnot_ps(ps(-0.0), v), ps(f32::INFINITY))
}

/// The first pixel whose centre lies strictly after `v`: `floor(v - 0.5) + 1`.
#[inline(always)]
unsafe fn first_after(v: __m256) -> __m256 {
    _mm256_add_ps(_mm256_round_ps::<{ _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC }>(_mm256_sub_ps(v, ps(0.5))), ps(1.0))
}

/// The last pixel whose centre lies strictly before `v`: `ceil(v - 0.5) - 1`.
#[inline(always)]
unsafe fn last_before(v: __m256) -> __m256 {
    _mm256_sub_ps(_mm256_round_ps::<{ _MM_FROUND_TO_POS_INF | _MM_FROUND_NO_EXC }>(_mm256_sub_ps(v, ps(0.5))), ps(1.0))
}

/// [`super::valid`] for eight lanes.
#[inline(always)]
unsafe fn valid8(d: __m256, vx: __m256, vy: __m256, mz: __m256) -> __m256 {
    _mm256_and_ps(
        _mm256_and_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(d, ps(EMPTY_DEPTH)), _mm256_cmp_ps::<_CMP_GE_OQ>(mz, ps(0.0))),
        _mm256_and_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(mz, ps(1.0)), _mm256_and_ps(finite(vx), finite(vy))),
    )
}

/// One source row of a layer in planes (motion x, y, target depth and the validity mask), so the
/// 3 x 3 neighbourhoods of VFW's quads are plain loads at any column, not a deinterleave of the
/// motion per neighbour.
#[derive(Default)]
struct RowPlanes {
    /// `(layer, row)` held, if any.
    tag: Option<(usize, usize)>,
    vx: Vec<f32>,
    vy: Vec<f32>,
    z: Vec<f32>,
    /// [`valid8`] / `super::valid` per sample: all bits set or clear.
    ok: Vec<f32>,
}

/// A band task's last three source rows in planes ([`RowPlanes`], row `y` in slot `y % 3`): the
/// band visits a layer's rows in order, so each row is converted once per band instead of once
/// per neighbour that reads it.
#[derive(Default)]
pub(super) struct RowCache {
    rows: [RowPlanes; 3],
}

impl RowCache {
    /// Makes sure the slot of row `y` of layer `k` (`l`, width `w`) holds it.
    #[target_feature(enable = "avx2")]
    unsafe fn fill(&mut self, l: &WarpLayer<'_>, k: usize, w: usize, y: usize) {
        let r = &mut self.rows[y % 3];
        if r.tag == Some((k, y)) {
            return;
        }
        r.tag = Some((k, y));
        for v in [&mut r.vx, &mut r.vy, &mut r.z, &mut r.ok] {
            v.resize(w, 0.0);
        }
        let (d, m) = (&l.depth.data()[y * w..(y + 1) * w], &l.motion.data()[y * w..(y + 1) * w]);
        let w8 = w & !7;
        for x in (0..w8).step_by(8) {
            let dv = _mm256_loadu_ps(d.as_ptr().add(x));
            let (vx, vy, z) = load_motion8(m.as_ptr().add(x));
            _mm256_storeu_ps(r.vx.as_mut_ptr().add(x), vx);
            _mm256_storeu_ps(r.vy.as_mut_ptr().add(x), vy);
            _mm256_storeu_ps(r.z.as_mut_ptr().add(x), z);
            _mm256_storeu_ps(r.ok.as_mut_ptr().add(x), valid8(dv, vx, vy, z));
        }
        for x in w8..w {
            let s = &m[x];
            (r.vx[x], r.vy[x], r.z[x]) = (s.v.x, s.v.y, s.depth);
            r.ok[x] = if super::valid(d[x], s) { f32::from_bits(!0) } else { 0.0 };
        }
    }

    /// The eight samples of row `y` (filled) starting at column `x`, all inside the row.
    #[inline(always)]
    unsafe fn load(&self, x: usize, y: usize) -> Samples {
        let r = &self.rows[y % 3];
        debug_assert!(r.tag.is_some_and(|t| t.1 == y) && x + 8 <= r.vx.len());
        Samples {
            vx: _mm256_loadu_ps(r.vx.as_ptr().add(x)),
            vy: _mm256_loadu_ps(r.vy.as_ptr().add(x)),
            z: _mm256_loadu_ps(r.z.as_ptr().add(x)),
            ok: _mm256_loadu_ps(r.ok.as_ptr().add(x)),
        }
    }
}

/// `super::vfw_quad`'s corner: at pixel corner `c`, the mean motion of the neighbours (in the
/// portable order) that are valid and move within `CONTINUITY_PX` of `own`, pushed out by `out`.
#[inline(always)]
unsafe fn corner(c: P8, nb: [&Samples; 4], own: &Samples, out: (f32, f32)) -> P8 {
    let (mut sx, mut sy, mut n) = (ps(0.0), ps(0.0), ps(0.0));
    let abs = ps(-0.0);
    for s in nb {
        let dx = _mm256_andnot_ps(abs, _mm256_sub_ps(s.vx, own.vx));
        let dy = _mm256_andnot_ps(abs, _mm256_sub_ps(s.vy, own.vy));
        let near = _mm256_cmp_ps::<_CMP_LT_OQ>(_mm256_max_ps(dx, dy), ps(CONTINUITY_PX));
        let take = _mm256_and_ps(s.ok, near);
        // Adding +0.0 for a neighbour left out keeps the sum bit for bit (it never is -0.0).
        sx = _mm256_add_ps(sx, _mm256_and_ps(take, s.vx));
        sy = _mm256_add_ps(sy, _mm256_and_ps(take, s.vy));
        n = _mm256_add_ps(n, _mm256_and_ps(take, ps(1.0)));
    }
    let e = FORWARD_SUPPORT_EXPANSION;
    P8 {
        x: _mm256_add_ps(_mm256_add_ps(c.x, _mm256_div_ps(sx, n)), ps(out.0 * e)),
        y: _mm256_add_ps(_mm256_add_ps(c.y, _mm256_div_ps(sy, n)), ps(out.1 * e)),
    }
}

/// `super::edge(a, b, p)` for eight lanes.
#[inline(always)]
unsafe fn edge(a: P8, b: P8, p: P8) -> __m256 {
    let (bx, by) = (_mm256_sub_ps(b.x, a.x), _mm256_sub_ps(b.y, a.y));
    let (px, py) = (_mm256_sub_ps(p.x, a.x), _mm256_sub_ps(p.y, a.y));
    _mm256_sub_ps(_mm256_mul_ps(bx, py), _mm256_mul_ps(by, px))
}

/// A triangle set up as `super::raster_triangle` does: its vertices, the sign of its area, its
/// clamped pixel box `[x0, x1] x [y0, y1]` (floats) and whether it is drawn at all.
struct Tri {
    t: [P8; 3],
    s: __m256,
    x0: __m256,
    x1: __m256,
    y0: __m256,
    y1: __m256,
    ok: __m256,
}

#[inline(always)]
unsafe fn setup(t: [P8; 3], lim: &Limits) -> Tri {
    let area = edge(t[0], t[1], t[2]);
    let ok = _mm256_and_ps(
        _mm256_cmp_ps::<_CMP_NEQ_OQ>(area, ps(0.0)),
        _mm256_cmp_ps::<_CMP_LT_OQ>(_mm256_andnot_ps(ps(-0.0), area), ps(f32::INFINITY)),
    );
    let s = _mm256_or_ps(ps(1.0), _mm256_and_ps(area, ps(-0.0)));
    let lo = P8 {
        x: _mm256_min_ps(_mm256_min_ps(t[0].x, t[1].x), t[2].x),
        y: _mm256_min_ps(_mm256_min_ps(t[0].y, t[1].y), t[2].y),
    };
    let hi = P8 {
        x: _mm256_max_ps(_mm256_max_ps(t[0].x, t[1].x), t[2].x),
        y: _mm256_max_ps(_mm256_max_ps(t[0].y, t[1].y), t[2].y),
    };
    let (x0, x1, y0, y1) = lim.bounds(lo, hi);
    let nonempty = _mm256_and_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(x0, x1), _mm256_cmp_ps::<_CMP_LE_OQ>(y0, y1));
    Tri { t, s, x0, x1, y0, y1, ok: _mm256_and_ps(ok, nonempty) }
}

/// The image and band limits of the pixel boxes.
struct Limits {
    w1: __m256,
    h1: __m256,
    clip0: __m256,
    clip1: __m256,
}

impl Limits {
    /// `super::raster_triangle`'s box of the centres strictly right of / below `lo` and left of /
    /// above `hi`, clamped to the image and the band.
    #[inline(always)]
    unsafe fn bounds(&self, lo: P8, hi: P8) -> (__m256, __m256, __m256, __m256) {
        (
            _mm256_max_ps(first_after(lo.x), ps(0.0)),
            _mm256_min_ps(last_before(hi.x), self.w1),
            _mm256_max_ps(_mm256_max_ps(first_after(lo.y), ps(0.0)), self.clip0),
            _mm256_min_ps(_mm256_min_ps(last_before(hi.y), self.h1), self.clip1),
        )
    }
}

/// Triangle `t`'s tests over the 3 x 3 window of centres starting at pixel `(wx, wy)`, with the
/// portable build's operations shared between the centres: `edge(a, b, p)` is
/// `(b - a).x * (p - a).y - (b - a).y * (p - a).x`, whose two products depend on one coordinate
/// of `p` each, so they are formed per window column and row and only subtracted per centre.
struct WindowTests {
    /// Per edge (`t0 -> t1`, `t1 -> t2`, `t2 -> t0`) and window row: `s (b - a).x (p - a).y`.
    ey: [[__m256; 3]; 3],
    /// Per edge and window column: `s (b - a).y (p - a).x`.
    ex: [[__m256; 3]; 3],
    /// Per window column / row: inside the triangle's pixel box (and the triangle drawn).
    col: [__m256; 3],
    row: [__m256; 3],
}

impl WindowTests {
    #[inline(always)]
    unsafe fn new(t: &Tri, wx: __m256, wy: __m256) -> Self {
        let mut ey = [[ps(0.0); 3]; 3];
        let mut ex = [[ps(0.0); 3]; 3];
        let (mut col, mut row) = ([ps(0.0); 3], [ps(0.0); 3]);
        for e in 0..3 {
            let (a, b) = (t.t[e], t.t[(e + 1) % 3]);
            let (bx, by) = (_mm256_sub_ps(b.x, a.x), _mm256_sub_ps(b.y, a.y));
            for d in 0..3 {
                let px = _mm256_add_ps(_mm256_add_ps(wx, ps(d as f32)), ps(0.5));
                let py = _mm256_add_ps(_mm256_add_ps(wy, ps(d as f32)), ps(0.5));
                // s (bx py' - by px') == s bx py' - s by px' exactly: s is +-1.
                ey[e][d] = _mm256_mul_ps(t.s, _mm256_mul_ps(bx, _mm256_sub_ps(py, a.y)));
                ex[e][d] = _mm256_mul_ps(t.s, _mm256_mul_ps(by, _mm256_sub_ps(px, a.x)));
            }
        }
        for d in 0..3 {
            let tx = _mm256_add_ps(wx, ps(d as f32));
            let ty = _mm256_add_ps(wy, ps(d as f32));
            col[d] = _mm256_and_ps(
                t.ok,
                _mm256_and_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(tx, t.x0), _mm256_cmp_ps::<_CMP_LE_OQ>(tx, t.x1)),
            );
            row[d] = _mm256_and_ps(_mm256_cmp_ps::<_CMP_GE_OQ>(ty, t.y0), _mm256_cmp_ps::<_CMP_LE_OQ>(ty, t.y1));
        }
        WindowTests { ey, ex, col, row }
    }

    /// Whether the window's centre `(dx, dy)` is drawn by the triangle (`super::raster_triangle`'s
    /// test: strictly inside the outer edges, on or inside the diagonal `t2 -> t0`, in the box).
    #[inline(always)]
    unsafe fn covers(&self, dx: usize, dy: usize) -> __m256 {
        let e0 = _mm256_sub_ps(self.ey[0][dy], self.ex[0][dx]);
        let e1 = _mm256_sub_ps(self.ey[1][dy], self.ex[1][dx]);
        let e2 = _mm256_sub_ps(self.ey[2][dy], self.ex[2][dx]);
        let inside = _mm256_and_ps(
            _mm256_and_ps(_mm256_cmp_ps::<_CMP_GT_OQ>(e0, ps(0.0)), _mm256_cmp_ps::<_CMP_GT_OQ>(e1, ps(0.0))),
            _mm256_cmp_ps::<_CMP_GE_OQ>(e2, ps(0.0)),
        );
        _mm256_and_ps(inside, _mm256_and_ps(self.col[dx], self.row[dy]))
    }
}

/// Per lane, `z` where the window's centre `(dx, dy)` is drawn by either triangle of the quad,
/// else far depth (which the depth test leaves unwritten).
#[inline(always)]
unsafe fn drawn(a: &WindowTests, b: &WindowTests, dx: usize, dy: usize, z: __m256) -> __m256 {
    _mm256_blendv_ps(ps(EMPTY_DEPTH), z, _mm256_or_ps(a.covers(dx, dy), b.covers(dx, dy)))
}

zwarp_core::avx2_or_avx512! {
    /// The VFW quads of source row `y` of layer `k` (`l`) into the band of target rows starting
    /// at `y0` (see [`super::vfw_row`]), its neighbour rows read through the band task's `rows`;
    /// AVX-512-enabled where the CPU has it.
    #[allow(clippy::too_many_arguments)]
    pub(super) unsafe fn vfw_row(
        l: &WarpLayer<'_>,
        k: usize,
        w: u32,
        h: u32,
        band: &mut [f32],
        y0: usize,
        y: usize,
        rows: &mut RowCache,
    ) where wide = crate::simd::has_avx512(); {
        let wu = w as usize;
        let mut band = Band::new(band, w, h, y0);
        let clip = band.clip();
        // The portable path of one pixel (image border, lanes whose quad needs a bigger window).
        let scalar = |band: &mut Band<'_>, x: usize| {
            if let Some(m) = sample_at(l, w, h, x as i64, y as i64) {
                vfw_pixel(l, band, x, y, m);
            }
        };
        // Groups of eight whose 3 x 10 neighbourhood lies inside the image.
        let inner = y >= 1 && y + 1 < h as usize && wu >= 10;
        let (gx0, gx1) = if inner { (1, 1 + (wu - 2) / 8 * 8) } else { (0, 0) };
        for x in (0..gx0).chain(gx1..wu) {
            scalar(&mut band, x);
        }
        let lim = Limits { w1: ps(w as f32 - 1.0), h1: ps(h as f32 - 1.0), clip0: ps(clip.0), clip1: ps(clip.1) };
        let lanes = _mm256_setr_ps(0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0);
        let cy = ps(y as f32 + 0.5);
        let wv = _mm256_set1_epi32(wu as i32);
        if gx0 < gx1 {
            for r in y - 1..=y + 1 {
                rows.fill(l, k, wu, r);
            }
        }
        let rows = &*rows;
        for x in (gx0..gx1).step_by(8) {
            let own = rows.load(x, y);
            // Quads that cannot reach the band are skipped (`vfw_pixel`'s test), whole groups first.
            let c = _mm256_add_ps(cy, own.vy);
            let far = _mm256_or_ps(
                _mm256_cmp_ps::<_CMP_LT_OQ>(_mm256_add_ps(c, ps(VFW_ROW_REACH)), lim.clip0),
                _mm256_cmp_ps::<_CMP_GT_OQ>(_mm256_sub_ps(c, ps(VFW_ROW_REACH)), lim.clip1),
            );
            let live = _mm256_andnot_ps(far, own.ok);
            if _mm256_movemask_ps(live) == 0 {
                continue;
            }
            let nb = [
                [rows.load(x - 1, y - 1), rows.load(x, y - 1), rows.load(x + 1, y - 1)],
                [rows.load(x - 1, y), own, rows.load(x + 1, y)],
                [rows.load(x - 1, y + 1), rows.load(x, y + 1), rows.load(x + 1, y + 1)],
            ];
            let px = _mm256_add_ps(ps(x as f32), lanes);
            let px1 = _mm256_add_ps(px, ps(1.0));
            let (py, py1) = (ps(y as f32), ps(y as f32 + 1.0));
            let q = [
                corner(P8 { x: px, y: py }, [&nb[0][0], &nb[0][1], &nb[1][0], &nb[1][1]], &own, (-1.0, -1.0)),
                corner(P8 { x: px1, y: py }, [&nb[0][1], &nb[0][2], &nb[1][1], &nb[1][2]], &own, (1.0, -1.0)),
                corner(P8 { x: px1, y: py1 }, [&nb[1][1], &nb[1][2], &nb[2][1], &nb[2][2]], &own, (1.0, 1.0)),
                corner(P8 { x: px, y: py1 }, [&nb[1][0], &nb[1][1], &nb[2][0], &nb[2][1]], &own, (-1.0, 1.0)),
            ];
            let a = setup([q[0], q[1], q[2]], &lim);
            let b = setup([q[0], q[2], q[3]], &lim);
            // The quad's box: the window of 3 x 3 centres starting at its first column and row.
            let lo = P8 {
                x: _mm256_min_ps(_mm256_min_ps(q[0].x, q[1].x), _mm256_min_ps(q[2].x, q[3].x)),
                y: _mm256_min_ps(_mm256_min_ps(q[0].y, q[1].y), _mm256_min_ps(q[2].y, q[3].y)),
            };
            let hi = P8 {
                x: _mm256_max_ps(_mm256_max_ps(q[0].x, q[1].x), _mm256_max_ps(q[2].x, q[3].x)),
                y: _mm256_max_ps(_mm256_max_ps(q[0].y, q[1].y), _mm256_max_ps(q[2].y, q[3].y)),
            };
            let (wx0, wx1, wy0, wy1) = lim.bounds(lo, hi);
            let fits = _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_LE_OQ>(_mm256_sub_ps(wx1, wx0), ps(2.0)),
                _mm256_cmp_ps::<_CMP_LE_OQ>(_mm256_sub_ps(wy1, wy0), ps(2.0)),
            );
            let fast = _mm256_and_ps(live, fits);
            let slow = _mm256_movemask_ps(_mm256_andnot_ps(fits, live)) as u32;
            let z = _mm256_add_ps(own.z, ps(0.0));
            let mut zs = [0f32; 8];
            _mm256_storeu_ps(zs.as_mut_ptr(), z);
            // Window origin as an index into the band (only used for fast lanes, whose box is
            // inside the image and the band).
            let base = _mm256_add_epi32(
                _mm256_mullo_epi32(_mm256_cvttps_epi32(_mm256_sub_ps(_mm256_max_ps(wy0, lim.clip0), lim.clip0)), wv),
                _mm256_cvttps_epi32(_mm256_max_ps(wx0, ps(0.0))),
            );
            let mut at = [0i32; 8];
            _mm256_storeu_si256(at.as_mut_ptr() as *mut __m256i, base);
            let (ta, tb) = (WindowTests::new(&a, wx0, wy0), WindowTests::new(&b, wx0, wy0));
            let wx0i = _mm256_cvttps_epi32(_mm256_max_ps(wx0, ps(0.0)));
            let first = _mm256_permutevar8x32_epi32(wx0i, _mm256_setzero_si256());
            let row0 = _mm256_permutevar8x32_ps(wy0, _mm256_setzero_si256());
            let c0 = _mm256_extract_epi32::<0>(wx0i);
            let lined_up = _mm256_and_ps(
                _mm256_castsi256_ps(_mm256_cmpeq_epi32(
                    wx0i,
                    _mm256_add_epi32(first, _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7)),
                )),
                _mm256_cmp_ps::<_CMP_EQ_OQ>(wy0, row0),
            );
            if _mm256_movemask_ps(_mm256_and_ps(fast, lined_up)) == 0xff && c0 as usize + 9 < wu {
                // The eight windows start on one row at consecutive columns (a smooth surface): a
                // window row's ten target pixels take, per column, the min over the lanes and
                // window columns that land there, formed with lane shifts, one vector min per row.
                let shift1 = _mm256_setr_epi32(0, 0, 1, 2, 3, 4, 5, 6);
                let shift2 = _mm256_setr_epi32(0, 0, 0, 1, 2, 3, 4, 5);
                let far = ps(EMPTY_DEPTH);
                let wy = _mm256_cvtss_f32(wy0);
                for dy in 0..3 {
                    if wy + dy as f32 > clip.1 {
                        break;
                    }
                    let (v0, v1, v2) = (drawn(&ta, &tb, 0, dy, z), drawn(&ta, &tb, 1, dy, z), drawn(&ta, &tb, 2, dy, z));
                    let s1 = _mm256_blend_ps::<0b0000_0001>(_mm256_permutevar8x32_ps(v1, shift1), far);
                    let s2 = _mm256_blend_ps::<0b0000_0011>(_mm256_permutevar8x32_ps(v2, shift2), far);
                    let m = _mm256_min_ps(v0, _mm256_min_ps(s1, s2));
                    let mut hi = [0f32; 8];
                    _mm256_storeu_ps(hi.as_mut_ptr(), _mm256_min_ps(v1, _mm256_permutevar8x32_ps(v2, shift1)));
                    let mut last = [0f32; 8];
                    _mm256_storeu_ps(last.as_mut_ptr(), v2);
                    let at = ((wy - clip.0) as usize + dy) * wu + c0 as usize;
                    let row = &mut band.rows[at..at + 10];
                    _mm256_storeu_ps(row.as_mut_ptr(), _mm256_min_ps(m, _mm256_loadu_ps(row.as_ptr())));
                    // Column 8: lane 7's window column 1, lane 6's column 2; column 9: lane 7's column 2.
                    row[8] = if hi[7] < row[8] { hi[7] } else { row[8] };
                    row[9] = if last[7] < row[9] { last[7] } else { row[9] };
                }
            } else {
                // Per lane, bit `3 dy + dx` marks a drawn centre of its window.
                let mut drawn = _mm256_setzero_si256();
                for dy in 0..3 {
                    for dx in 0..3 {
                        let hit = _mm256_castps_si256(_mm256_or_ps(ta.covers(dx, dy), tb.covers(dx, dy)));
                        drawn = _mm256_or_si256(drawn, _mm256_and_si256(hit, _mm256_set1_epi32(1 << (3 * dy + dx))));
                    }
                }
                let mut masks = [0u32; 8];
                _mm256_storeu_si256(masks.as_mut_ptr() as *mut __m256i, drawn);
                let offsets = [0, 1, 2, wu, wu + 1, wu + 2, 2 * wu, 2 * wu + 1, 2 * wu + 2];
                let mut lanes_left = _mm256_movemask_ps(fast) as u32;
                while lanes_left != 0 {
                    let k = lanes_left.trailing_zeros() as usize;
                    lanes_left &= lanes_left - 1;
                    let (mut m, z, at) = (masks[k], zs[k], at[k] as usize);
                    while m != 0 {
                        let o = &mut band.rows[at + offsets[m.trailing_zeros() as usize]];
                        m &= m - 1;
                        *o = if z < *o { z } else { *o };
                    }
                }
            }
            let mut bits = slow;
            while bits != 0 {
                let k = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                scalar(&mut band, x + k);
            }
        }
    }
}

/// The AVX2 build of [`super::row_check`], eight samples per step (the range may differ from the
/// portable one's only in the sign of a zero, which moves no band boundary).
#[target_feature(enable = "avx2")]
pub(super) unsafe fn row_check(d: &[f32], m: &[Motion]) -> (u8, f32, f32) {
    let w8 = d.len() & !7;
    let (inf, abs) = (ps(f32::INFINITY), ps(-0.0));
    let (mut bad_d, mut bad_m) = (_mm256_setzero_ps(), _mm256_setzero_ps());
    let (mut lo, mut hi) = (inf, ps(f32::NEG_INFINITY));
    for x in (0..w8).step_by(8) {
        let dv = _mm256_loadu_ps(d.as_ptr().add(x));
        let (vx, vy, mz) = load_motion8(m.as_ptr().add(x));
        bad_d = _mm256_or_ps(bad_d, _mm256_cmp_ps::<_CMP_NLT_UQ>(_mm256_andnot_ps(abs, dv), inf));
        bad_m = _mm256_or_ps(
            bad_m,
            _mm256_or_ps(_mm256_cmp_ps::<_CMP_UNORD_Q>(vx, vy), _mm256_cmp_ps::<_CMP_UNORD_Q>(mz, mz)),
        );
        let ok = valid8(dv, vx, vy, mz);
        lo = _mm256_min_ps(lo, _mm256_blendv_ps(inf, vy, ok));
        hi = _mm256_max_ps(hi, _mm256_blendv_ps(ps(f32::NEG_INFINITY), vy, ok));
    }
    let (mut l, mut h) = ([0f32; 8], [0f32; 8]);
    _mm256_storeu_ps(l.as_mut_ptr(), lo);
    _mm256_storeu_ps(h.as_mut_ptr(), hi);
    let (tf, tl, th) = row_check_portable(&d[w8..], &m[w8..]);
    let flags = (_mm256_movemask_ps(bad_d) != 0) as u8 | ((_mm256_movemask_ps(bad_m) != 0) as u8) << 1 | tf;
    (flags, l.into_iter().fold(tl, f32::min), h.into_iter().fold(th, f32::max))
}

/// [`super::afw_span`] for eight lanes: the first and last target index of each lane's footprint.
#[inline(always)]
unsafe fn afw_span8(c: __m256, lo: i32, hi: i32) -> (__m256i, __m256i) {
    let (lof, hif) = (ps(lo as f32 - 1.0), ps(hi as f32 + 1.0));
    let f = _mm256_round_ps::<{ _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC }>(_mm256_sub_ps(
        _mm256_sub_ps(c, ps(AFW_HALF_SIZE)),
        ps(0.5),
    ));
    let g = _mm256_round_ps::<{ _MM_FROUND_TO_POS_INF | _MM_FROUND_NO_EXC }>(_mm256_sub_ps(
        _mm256_add_ps(c, ps(AFW_HALF_SIZE)),
        ps(0.5),
    ));
    let f = _mm256_cvttps_epi32(_mm256_min_ps(_mm256_max_ps(f, lof), hif));
    let g = _mm256_cvttps_epi32(_mm256_min_ps(_mm256_max_ps(g, lof), hif));
    (
        _mm256_max_epi32(_mm256_add_epi32(f, _mm256_set1_epi32(1)), _mm256_set1_epi32(lo)),
        _mm256_min_epi32(_mm256_sub_epi32(g, _mm256_set1_epi32(1)), _mm256_set1_epi32(hi)),
    )
}

/// The AVX2 build of [`super::afw_row`], eight source pixels per step, bit-identical. Where the eight
/// are valid, land on the same target rows and on consecutive columns, each 2 x 2 footprint
/// starting one column right of the previous one (smooth motion), a target row's nine columns
/// take the min of each lane and its left neighbour in one vector; other groups splat lane by
/// lane like the portable build.
#[target_feature(enable = "avx2")]
pub(super) unsafe fn afw_row(l: &WarpLayer<'_>, w: u32, h: u32, band: &mut [f32], y0: usize, y: usize) {
    let mut band = Band::new(band, w, h, y0);
    let wu = w as usize;
    let (depth, motion) = (&l.depth.data()[y * wu..(y + 1) * wu], &l.motion.data()[y * wu..(y + 1) * wu]);
    let cy = y as f32 + 0.5;
    let w8 = wu & !7;
    let lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    let left = _mm256_setr_epi32(0, 0, 1, 2, 3, 4, 5, 6);
    let mut x = 0;
    while x < w8 {
        let d = _mm256_loadu_ps(depth.as_ptr().add(x));
        let (vx, vy, mz) = load_motion8(motion.as_ptr().add(x));
        let ok = valid8(d, vx, vy, mz);
        let xs = _mm256_cvtepi32_ps(_mm256_add_epi32(_mm256_set1_epi32(x as i32), lanes));
        let cx = _mm256_add_ps(_mm256_add_ps(xs, ps(0.5)), vx);
        let cyv = _mm256_add_ps(ps(cy), vy);
        let (x0, x1) = afw_span8(cx, 0, wu as i32 - 1);
        let (t0, t1) = afw_span8(cyv, band.y0, band.y1);
        let x00 = _mm256_permutevar8x32_epi32(x0, _mm256_setzero_si256());
        let (t00, t10) = (
            _mm256_permutevar8x32_epi32(t0, _mm256_setzero_si256()),
            _mm256_permutevar8x32_epi32(t1, _mm256_setzero_si256()),
        );
        let same = _mm256_and_si256(
            _mm256_and_si256(_mm256_cmpeq_epi32(t0, t00), _mm256_cmpeq_epi32(t1, t10)),
            _mm256_and_si256(
                _mm256_cmpeq_epi32(x0, _mm256_add_epi32(x00, lanes)),
                _mm256_cmpeq_epi32(x1, _mm256_add_epi32(x0, _mm256_set1_epi32(1))),
            ),
        );
        let fast = _mm256_movemask_ps(_mm256_and_ps(ok, _mm256_castsi256_ps(same))) == 0xff;
        if fast {
            let (r0, r1) = (_mm256_extract_epi32::<0>(t0), _mm256_extract_epi32::<0>(t1));
            if r0 <= r1 {
                let z = _mm256_add_ps(mz, ps(0.0));
                let zl = _mm256_blend_ps::<1>(_mm256_permutevar8x32_ps(z, left), ps(EMPTY_DEPTH));
                let m = _mm256_min_ps(z, zl);
                let z7 = _mm256_cvtss_f32(_mm256_permutevar8x32_ps(z, _mm256_set1_epi32(7)));
                let c0 = _mm256_extract_epi32::<0>(x0) as usize;
                for t in [r0, r1] {
                    let row = &mut band.rows[(t - band.y0) as usize * wu + c0..][..9];
                    let p = row.as_mut_ptr();
                    _mm256_storeu_ps(p, _mm256_min_ps(m, _mm256_loadu_ps(p)));
                    row[8] = if z7 < row[8] { z7 } else { row[8] };
                }
            }
        } else {
            // Lane by lane, from the spans computed above (valid, non-empty lanes only).
            let live = _mm256_andnot_si256(
                _mm256_or_si256(_mm256_cmpgt_epi32(x0, x1), _mm256_cmpgt_epi32(t0, t1)),
                _mm256_castps_si256(ok),
            );
            let mut bits = _mm256_movemask_ps(_mm256_castsi256_ps(live)) as u32;
            let wv = _mm256_set1_epi32(wu as i32);
            let r0 = _mm256_mullo_epi32(_mm256_sub_epi32(t0, _mm256_set1_epi32(band.y0)), wv);
            let r1 = _mm256_mullo_epi32(_mm256_sub_epi32(t1, _mm256_set1_epi32(band.y0)), wv);
            let mut at = [[0i32; 8]; 4];
            for (a, v) in at.iter_mut().zip([
                _mm256_add_epi32(r0, x0),
                _mm256_add_epi32(r0, x1),
                _mm256_add_epi32(r1, x0),
                _mm256_add_epi32(r1, x1),
            ]) {
                _mm256_storeu_si256(a.as_mut_ptr() as *mut __m256i, v);
            }
            let mut zs = [0f32; 8];
            _mm256_storeu_ps(zs.as_mut_ptr(), _mm256_add_ps(mz, ps(0.0)));
            while bits != 0 {
                let k = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let z = zs[k];
                for a in &at {
                    let o = &mut band.rows[a[k] as usize];
                    *o = if z < *o { z } else { *o };
                }
            }
        }
        x += 8;
    }
    for k in w8..wu {
        let (d, m) = (depth[k], &motion[k]);
        if valid(d, m) {
            band.afw_splat(k as f32 + 0.5 + m.v.x, cy + m.v.y, m.depth);
        }
    }
}
