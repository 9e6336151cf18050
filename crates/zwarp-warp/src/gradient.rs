//! The gradient mipmap of a layer's sample planes, built lazily (the one-seed test of the
//! warp's tile stage, [`crate::PreparedLayer::unique_solution`]).
//!
//! Seed 000 Sec. 3.2 spreads N seeds over a search region because it may hold several
//! solutions of `q + v(q) = p`; where the region provably holds one, one seed finds it. Each
//! texel holds, over the bilinear cells whose top-left texel it covers, the largest of the
//! cell's bound that the preparation's test needs ([`OneSeedTest`]): the squared row norms of
//! the motion's Jacobian ([`cell_gradient`], a contraction test) or its fold
//! ([`cell_fold`], a monotonicity test). Only the first layer's tiles whose bound spans more
//! than a pixel ask, and the share of the image their regions cover varies from none (a street
//! walked along: every tile bound is sub-pixel) to about 40 % (the procedural scenes at 1080p):
//! so texels are computed when first looked up, never before. Levels `1..=4` are computed a
//! block at a time (a level-4 texel: 16 x 16 pixels, with AVX2 in registers from the cells to
//! the block's texel), each texel of a coarser level from its four children. Look-ups from
//! several threads share the work: the first to claim a block (or a coarser texel) computes it,
//! the others wait for it (a few microseconds; a block never waits for anything, a coarser
//! texel only for finer ones).

use std::cell::UnsafeCell;
use std::sync::atomic::{AtomicU8, Ordering};

use crate::sampling::SamplePlanes;
use crate::simd::{fmax, fmin};

/// Squared norms of the rows of the Jacobian of the adaptive fetch's bilinear interpolant over
/// the cell of texels `a b / c d` (each `[vx, vy, z]`, `z = +inf` for an empty texel), bounded
/// per entry by the larger of the cell's two differences along its axis (the bilinear
/// derivative lies between them): `[|dvx/dq|^2, |dvy/dq|^2]`. `+inf` where the depths alone
/// stop the fetch from interpolating (an empty texel or a depth step,
/// [`crate::sampling::continuous_cell`]). The motion part of that test depends on the motion
/// scale, and a small gradient implies it ([`crate::PreparedLayer::unique_solution`]).
#[inline(always)]
pub fn cell_gradient(a: [f32; 3], b: [f32; 3], c: [f32; 3], d: [f32; 3]) -> [f32; 2] {
    let mut g = [0f32; 2];
    for (i, g) in g.iter_mut().enumerate() {
        let dx = fmax((b[i] - a[i]).abs(), (d[i] - c[i]).abs());
        let dy = fmax((c[i] - a[i]).abs(), (d[i] - b[i]).abs());
        *g = dx * dx + dy * dy;
    }
    let z_lo = fmin(fmin(a[2], b[2]), fmin(c[2], d[2]));
    let z_hi = fmax(fmax(a[2], b[2]), fmax(c[2], d[2]));
    if (z_hi - z_lo) < crate::sampling::DEPTH_CONTINUITY * (1.0 - z_hi) {
        g
    } else {
        [f32::INFINITY; 2]
    }
}

/// An upper bound of the fold `|dvx/dy + dvy/dx| / 2 - min(dvx/dx, dvy/dy)` of the adaptive
/// fetch's bilinear interpolant over the cell of texels `a b / c d` (each `[vx, vy, z]`,
/// `z = +inf` for an empty texel): each derivative lies between the cell's two differences
/// along its axis, and the sum's magnitude is largest at the ends of its range. By Gershgorin's
/// theorem the symmetric part of `S^-1 + Dv` is positive definite for a positive diagonal scale
/// `S` with `max(sx, sy) fold < 1`, so `q -> q + S v(q)` is strictly monotone for the inner
/// product weighted by `S^-1` ([`crate::PreparedLayer::unique_solution`]). That needs the fetch
/// to interpolate the cell: always where its depths lie within
/// [`crate::sampling::SURFACE_DEPTH_STEP`], elsewhere (within
/// [`crate::sampling::DEPTH_CONTINUITY`]) only while its scaled motion range stays below
/// [`crate::sampling::CONTINUITY_PX`] (one pixel), so the fold is then at least the cell's
/// motion range; `+inf` across a larger depth step or at an empty texel.
#[inline(always)]
pub fn cell_fold(a: [f32; 3], b: [f32; 3], c: [f32; 3], d: [f32; 3]) -> f32 {
    let (axx, bxx) = (b[0] - a[0], d[0] - c[0]);
    let (ayy, byy) = (c[1] - a[1], d[1] - b[1]);
    let (axy, bxy) = (c[0] - a[0], d[0] - b[0]);
    let (ayx, byx) = (b[1] - a[1], d[1] - c[1]);
    let shear_lo = fmin(axy, bxy) + fmin(ayx, byx);
    let shear_hi = fmax(axy, bxy) + fmax(ayx, byx);
    let fold = 0.5 * fmax(shear_lo.abs(), shear_hi.abs()) - fmin(fmin(axx, bxx), fmin(ayy, byy));
    let z_lo = fmin(fmin(a[2], b[2]), fmin(c[2], d[2]));
    let z_hi = fmax(fmax(a[2], b[2]), fmax(c[2], d[2]));
    let (step, room) = (z_hi - z_lo, 1.0 - z_hi);
    if step < crate::sampling::SURFACE_DEPTH_STEP * room {
        fold
    } else if step < crate::sampling::DEPTH_CONTINUITY * room {
        // The per-axis motion range, as the fetch measures it (`continuous_cell`).
        let range = |i: usize| fmax(fmax(a[i], b[i]), fmax(c[i], d[i])) - fmin(fmin(a[i], b[i]), fmin(c[i], d[i]));
        fmax(fold, fmax(range(0), range(1)))
    } else {
        f32::INFINITY
    }
}

/// Which bound of the motion's Jacobian a gradient mipmap holds, i.e. how the one-seed test
/// ([`crate::PreparedLayer::unique_solution`]) proves that a region holds one solution.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OneSeedTest {
    /// `[gx, gy]` of [`cell_gradient`]: the scaled motion a contraction. Its test scales with
    /// the motion per axis (any factors, either sign), for preparations shared by scaled warps
    /// ([`crate::bounds::MotionScales::Any`]).
    Contraction,
    /// `[fold, fold]` of [`cell_fold`]: `q + S v(q)` monotone, for positive scales (the
    /// preparations of [`crate::bounds::MotionScales::AtLeastOne`]). It holds wherever the
    /// contraction does at a uniform scale (a contracting cell's fold is below `sqrt(3) / 2`)
    /// and also on magnified surfaces (a walk toward a wall, the ground under a moving camera).
    Monotone,
}

impl OneSeedTest {
    /// The texel value of one cell.
    #[inline(always)]
    fn cell(self, a: [f32; 3], b: [f32; 3], c: [f32; 3], d: [f32; 3]) -> [f32; 2] {
        match self {
            OneSeedTest::Contraction => cell_gradient(a, b, c, d),
            OneSeedTest::Monotone => [cell_fold(a, b, c, d); 2],
        }
    }
}

/// Bound on the squared Frobenius norm of the motion's Jacobian below which a search region
/// holds one solution at most ([`crate::PreparedLayer::unique_solution`]).
pub const UNIQUE_GRADIENT: f32 = 0.5;

/// The level whose texels are computed as a block (16 x 16 pixels), or the top level of a
/// smaller image.
const BLOCK_LEVEL: u32 = 4;

/// The lazily computed gradient mipmap of one `w x h` layer: levels `1..=top` laid out as the
/// layer's [`crate::MotionPyramid`] (level 1 = 2 x 2 pixels); a texel is valid once its block
/// (levels up to [`BLOCK_LEVEL`]) or itself (coarser levels) is done.
pub(crate) struct GradientMip {
    w: u32,
    h: u32,
    /// Per level `1..=top`: width, height, first texel in `values`.
    levels: Vec<(u32, u32, usize)>,
    /// `[gx, gy]` per texel, written once per preparation by the one look-up that claimed its
    /// block or texel ([`State`]).
    values: Box<[UnsafeCell<[f32; 2]>]>,
    /// The level computed a block at a time: `min(BLOCK_LEVEL, top)`.
    block_level: u32,
    /// A [`State`] per texel of `block_level`: its block of texels at levels `1..=block_level`.
    blocks: Vec<AtomicU8>,
    /// A [`State`] per texel of the levels above `block_level`, from `high_base` in `values`.
    highs: Vec<AtomicU8>,
    high_base: usize,
    /// Blocks take the AVX2 build where it applies (`crate::simd::has_avx2` at creation).
    simd: bool,
    /// The bound its texels hold.
    test: OneSeedTest,
}

// SAFETY: `values` is written only by the thread that moved a block's or a texel's state from
// FREE to CLAIMED, in that block or texel alone, and read only after its state is DONE (stored
// with Release by the writer after its writes, loaded with Acquire by the reader).
unsafe impl Sync for GradientMip {}

/// The states of a block or a coarser texel.
struct State;

impl State {
    const FREE: u8 = 0;
    const CLAIMED: u8 = 1;
    const DONE: u8 = 2;

    /// Makes `s` DONE: by running `compute` if this thread claims it, else by waiting for the
    /// thread that did.
    #[inline]
    fn ensure(s: &AtomicU8, compute: impl FnOnce()) {
        if s.load(Ordering::Acquire) == State::DONE {
            return;
        }
        if s.compare_exchange(State::FREE, State::CLAIMED, Ordering::Acquire, Ordering::Acquire).is_ok() {
            compute();
            s.store(State::DONE, Ordering::Release);
        } else {
            while s.load(Ordering::Acquire) != State::DONE {
                std::hint::spin_loop();
            }
        }
    }
}

/// Component-wise [`fmax`].
#[inline]
fn max2(a: [f32; 2], b: [f32; 2]) -> [f32; 2] {
    [fmax(a[0], b[0]), fmax(a[1], b[1])]
}

impl GradientMip {
    /// An empty (nothing computed) mipmap of a `w x h` layer whose levels `1..=top` have the
    /// given sizes and offsets, in the storage of `recycled` (an earlier frame's) where it is
    /// large enough.
    pub(crate) fn new(
        w: u32,
        h: u32,
        levels: Vec<(u32, u32, usize)>,
        test: OneSeedTest,
        recycled: Option<GradientMip>,
    ) -> Self {
        let total = levels.last().map_or(0, |&(lw, lh, off)| off + lw as usize * lh as usize);
        let top = levels.len() as u32;
        let block_level = BLOCK_LEVEL.min(top);
        let (bw, bh, _) = levels[block_level as usize - 1];
        let high_base = levels.get(block_level as usize).map_or(total, |l| l.2);
        let (mut values, mut blocks, mut highs) = match recycled {
            Some(r) => (r.values, r.blocks, r.highs),
            None => (Box::default(), Vec::new(), Vec::new()),
        };
        if values.len() < total {
            values = (0..total).map(|_| UnsafeCell::new([0.0; 2])).collect();
        }
        let reset = |states: &mut Vec<AtomicU8>, n: usize| {
            states.truncate(n);
            states.iter_mut().for_each(|s| *s.get_mut() = State::FREE);
            states.resize_with(n, || AtomicU8::new(State::FREE));
        };
        reset(&mut blocks, bw as usize * bh as usize);
        reset(&mut highs, total - high_base);
        let simd = crate::simd::has_avx2();
        GradientMip { w, h, levels, values, block_level, blocks, highs, high_base, simd, test }
    }

    /// The bound its texels hold.
    pub(crate) fn test(&self) -> OneSeedTest {
        self.test
    }

    /// Texel `(tx, ty)` of level `level` (`1..=top`) of the gradient mipmap of `planes` (the
    /// layer's samples this mipmap was made for), computed on first use.
    pub(crate) fn texel(&self, planes: &SamplePlanes, level: u32, tx: u32, ty: u32) -> [f32; 2] {
        let (lw, _, off) = self.levels[level as usize - 1];
        let i = off + ty as usize * lw as usize + tx as usize;
        if level <= self.block_level {
            let s = self.block_level - level;
            let bw = self.levels[self.block_level as usize - 1].0;
            let (bx, by) = (tx >> s, ty >> s);
            State::ensure(&self.blocks[by as usize * bw as usize + bx as usize], || {
                // SAFETY: this thread claimed the block.
                unsafe { self.compute_block(planes, bx, by) }
            });
        } else {
            State::ensure(&self.highs[i - self.high_base], || {
                // The union of the (up to) 2 x 2 texels below, upper-left, upper-right,
                // lower-left, lower-right (the order of the min-max mipmap's fold).
                let (cw, ch, _) = self.levels[level as usize - 2];
                let mut g = [f32::NEG_INFINITY; 2];
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let (cx, cy) = (2 * tx + dx, 2 * ty + dy);
                    if cx < cw && cy < ch {
                        g = max2(g, self.texel(planes, level - 1, cx, cy));
                    }
                }
                // SAFETY: this thread claimed the texel.
                unsafe { *self.values[i].get() = g };
            });
        }
        // SAFETY: the texel's block or state is DONE (Acquire): written and never again.
        unsafe { *self.values[i].get() }
    }

    /// Writes the texels of levels `1..=block_level` under texel `(bx, by)` of `block_level`.
    ///
    /// # Safety
    /// The calling thread must have claimed the block.
    unsafe fn compute_block(&self, planes: &SamplePlanes, bx: u32, by: u32) {
        const SIDE: usize = 1 << (BLOCK_LEVEL - 1);
        let (w, h) = (self.w as usize, self.h as usize);
        let side = 1usize << (self.block_level - 1);
        let (l1w, l1h, _) = self.levels[0];
        let (tx0, ty0) = (bx as usize * side, by as usize * side);
        let (tx1, ty1) = ((tx0 + side).min(l1w as usize), (ty0 + side).min(l1h as usize));
        let (x0, x1) = (2 * tx0, (2 * tx1).min(w));
        #[cfg(target_arch = "x86_64")]
        if side == SIDE && x0 + 2 * SIDE < w && self.simd {
            // SAFETY: AVX2 checked; the block's 16 columns have right neighbours.
            unsafe { self.block_avx2(planes, x0, tx0, ty0, ty1) };
            return;
        }
        // Level 1: per texel the largest cell of its (up to) 2 x 2 pixels, rows 2 ty and
        // 2 ty + 1 (where inside the image), left cell first.
        let mut cells = [[[f32::NEG_INFINITY; 2]; 2 * SIDE]; 2];
        let mut tex = [[[f32::NEG_INFINITY; 2]; SIDE]; SIDE];
        for ty in ty0..ty1 {
            for (r, row) in cells.iter_mut().enumerate() {
                let y = 2 * ty + r;
                row.fill([f32::NEG_INFINITY; 2]);
                if y < h {
                    cell_row(planes, w, h, y, x0, &mut row[..x1 - x0], self.simd, self.test);
                }
            }
            for tx in tx0..tx1 {
                let c = 2 * (tx - tx0);
                let m =
                    |k: usize| fmax(fmax(cells[0][c][k], cells[0][c + 1][k]), fmax(cells[1][c][k], cells[1][c + 1][k]));
                tex[ty - ty0][tx - tx0] = [m(0), m(1)];
            }
        }
        self.store(1, tx0, ty0, tx1 - tx0, ty1 - ty0, &tex);
        // Levels 2..=block_level inside the block: the fold of the 2 x 2 texels below.
        let (mut n_x, mut n_y, mut ox, mut oy) = (tx1 - tx0, ty1 - ty0, tx0, ty0);
        for level in 2..=self.block_level {
            let (lw, lh, _) = self.levels[level as usize - 1];
            let (px, py) = (ox / 2, oy / 2);
            let (mx, my) = ((px + n_x.div_ceil(2)).min(lw as usize) - px, (py + n_y.div_ceil(2)).min(lh as usize) - py);
            let mut up = [[[f32::NEG_INFINITY; 2]; SIDE]; SIDE];
            for (j, row) in up.iter_mut().enumerate().take(my) {
                for (i, t) in row.iter_mut().enumerate().take(mx) {
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        let (cx, cy) = (2 * i + dx, 2 * j + dy);
                        if cx < n_x && cy < n_y {
                            *t = max2(*t, tex[cy][cx]);
                        }
                    }
                }
            }
            self.store(level, px, py, mx, my, &up);
            (tex, n_x, n_y, ox, oy) = (up, mx, my, px, py);
        }
    }

    /// Writes `n_x x n_y` texels of `level` from `(tx0, ty0)`.
    ///
    /// # Safety
    /// The calling thread must have claimed the block they lie in.
    unsafe fn store<const S: usize>(
        &self,
        level: u32,
        tx0: usize,
        ty0: usize,
        n_x: usize,
        n_y: usize,
        t: &[[[f32; 2]; S]; S],
    ) {
        let (lw, _, off) = self.levels[level as usize - 1];
        for (j, row) in t.iter().enumerate().take(n_y) {
            let base = off + (ty0 + j) * lw as usize + tx0;
            for (i, g) in row.iter().enumerate().take(n_x) {
                // SAFETY: the caller claimed the block.
                unsafe { *self.values[base + i].get() = *g };
            }
        }
    }

    /// [`Self::compute_block`] of a full-width 16-column block (`x0 + 16 < w`: every cell has
    /// its right neighbour) with AVX2, `ty0..ty1` its level-1 rows (up to eight): the cells
    /// eight at a time as [`cells8`] computes them, every level's texels in registers (the
    /// largest of children is exact in any order: gradients are `>= +0` or `+inf`, never NaN).
    ///
    /// # Safety
    /// The CPU must support AVX2; the calling thread must have claimed the block.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn block_avx2(&self, planes: &SamplePlanes, x0: usize, tx0: usize, ty0: usize, ty1: usize) {
        use std::arch::x86_64::*;
        let (w, h) = (self.w as usize, self.h as usize);
        let ninf = _mm256_set1_pd(f64::from_bits(pack_ninf()));
        let ninf = _mm256_castpd_ps(ninf);
        // Cells of rows (r0, r1) at columns x..x + 8, as [gx, gy] pairs: texel pairs 0-3 and 4-7.
        let cells = |r0: usize, r1: usize, x: usize| -> (__m256, __m256) {
            let ld = |p: &[f32]| {
                let at = |r: usize, dx: usize| _mm256_loadu_ps(p.as_ptr().add(r * w + x + dx));
                [at(r0, 0), at(r0, 1), at(r1, 0), at(r1, 1)]
            };
            let [a, b] = interleave(cell_lanes(ld(&planes.vx), ld(&planes.vy), ld(&planes.z), self.test));
            (a, b)
        };
        // Largest of adjacent [gx, gy] pairs (0, 1), (2, 3): the even pairs hold it.
        let pairs = |v: __m256| _mm256_max_ps(v, _mm256_castpd_ps(_mm256_permute_pd::<0b0101>(_mm256_castps_pd(v))));
        // The even pairs of a and b, in order: [a0, a2, b0, b2].
        let evens = |a: __m256, b: __m256| {
            let u = _mm256_castpd_ps(_mm256_unpacklo_pd(_mm256_castps_pd(a), _mm256_castps_pd(b)));
            _mm256_castpd_ps(_mm256_permute4x64_pd::<0b11_01_10_00>(_mm256_castps_pd(u)))
        };
        let at = |level: usize, tx: usize, ty: usize| {
            let (lw, _, off) = self.levels[level - 1];
            self.values[off + ty * lw as usize + tx].get() as *mut f32
        };
        // Level 1 (eight rows of eight texels: two vectors each), level 2 (four rows of four).
        let mut l2 = [ninf; 4];
        for (j, l2) in l2.iter_mut().enumerate() {
            let mut rows = [[ninf; 2]; 2];
            for (k, row) in rows.iter_mut().enumerate() {
                let ty = ty0 + 2 * j + k;
                if ty >= ty1 {
                    continue;
                }
                let (ya, yb, yc) = (2 * ty, (2 * ty + 1).min(h - 1), (2 * ty + 2).min(h - 1));
                for (half, t) in row.iter_mut().enumerate() {
                    let x = x0 + 8 * half;
                    let (a0, a1) = cells(ya, yb, x);
                    let (b0, b1) = if 2 * ty + 1 < h { cells(yb, yc, x) } else { (ninf, ninf) };
                    let (c0, c1) = (pairs(_mm256_max_ps(a0, b0)), pairs(_mm256_max_ps(a1, b1)));
                    *t = evens(c0, c1);
                    _mm256_storeu_ps(at(1, tx0 + 4 * half, ty), *t);
                }
            }
            let v = [_mm256_max_ps(rows[0][0], rows[1][0]), _mm256_max_ps(rows[0][1], rows[1][1])];
            *l2 = evens(pairs(v[0]), pairs(v[1]));
            if ty0 + 2 * j < ty1 {
                _mm256_storeu_ps(at(2, tx0 / 2, ty0 / 2 + j), *l2);
            }
        }
        // Level 3 (two rows of two: pairs 0 and 2 of each vector), level 4 (one texel).
        let l3 = [pairs(_mm256_max_ps(l2[0], l2[1])), pairs(_mm256_max_ps(l2[2], l2[3]))];
        let pick = |v: __m256| {
            let u = _mm256_castps_pd(v);
            [_mm256_castpd256_pd128(u), _mm256_extractf128_pd::<1>(u)]
        };
        for (j, v) in l3.iter().enumerate() {
            if ty0 + 4 * j < ty1 {
                let [a, b] = pick(*v);
                let p = at(3, tx0 / 4, ty0 / 4 + j) as *mut f64;
                _mm_storel_pd(p, a);
                _mm_storel_pd(p.add(1), b);
            }
        }
        let l4 = pairs(_mm256_max_ps(l3[0], l3[1]));
        let [a, b] = pick(l4);
        let m = _mm_max_ps(_mm_castpd_ps(a), _mm_castpd_ps(b));
        _mm_storel_pd(at(4, tx0 / 8, ty0 / 8) as *mut f64, _mm_castps_pd(m));
    }
}

/// The bits of `[-inf, -inf]` as one `f64` lane.
#[inline]
fn pack_ninf() -> u64 {
    let n = f32::NEG_INFINITY.to_bits() as u64;
    n | n << 32
}

/// The cells of image row `y` at columns `x0..x0 + out.len()` of `w x h` planes: the cell at
/// `x` spans texels `x, x + 1` of rows `y, y + 1`, clamped to the image (the fetch clamps, so
/// the cells at the right and bottom borders repeat the border texels).
#[allow(clippy::too_many_arguments)]
fn cell_row(
    planes: &SamplePlanes,
    w: usize,
    h: usize,
    y: usize,
    x0: usize,
    out: &mut [[f32; 2]],
    simd: bool,
    test: OneSeedTest,
) {
    let y1 = (y + 1).min(h - 1);
    fn row(p: &[f32], y: usize, w: usize) -> &[f32] {
        &p[y * w..(y + 1) * w]
    }
    let row = |p, y| row(p, y, w);
    let (ax, ay, az) = (row(&planes.vx, y), row(&planes.vy, y), row(&planes.z, y));
    let (cx, cy, cz) = (row(&planes.vx, y1), row(&planes.vy, y1), row(&planes.z, y1));
    // Cells with a right neighbour: x0..min(x0 + n, w - 1).
    let inner = out.len().min(w - 1 - x0.min(w - 1));
    let mut i0 = 0;
    #[cfg(target_arch = "x86_64")]
    if simd {
        fn s(p: &[f32], from: usize, n: usize) -> &[f32] {
            &p[from..from + n]
        }
        let s = |p, d| s(p, x0 + d, inner);
        // SAFETY: AVX2 checked; every slice holds `inner` elements.
        i0 = unsafe {
            cells8(
                [s(ax, 0), s(ax, 1), s(cx, 0), s(cx, 1)],
                [s(ay, 0), s(ay, 1), s(cy, 0), s(cy, 1)],
                [s(az, 0), s(az, 1), s(cz, 0), s(cz, 1)],
                &mut out[..inner],
                test,
            )
        };
    }
    for (i, o) in out.iter_mut().enumerate().skip(i0) {
        let x = x0 + i;
        let x1 = (x + 1).min(w - 1);
        *o =
            test.cell([ax[x], ay[x], az[x]], [ax[x1], ay[x1], az[x1]], [cx[x], cy[x], cz[x]], [cx[x1], cy[x1], cz[x1]]);
    }
}

/// [`OneSeedTest::cell`] eight cells at a time (bit-identical: compare-select min / max, no
/// FMA, the same order of sums) for the cells `0..8 * floor(n / 8)` of one row, given per plane
/// the cells' four texels `a b / c d` as slices of `n`; returns how many it wrote.
///
/// # Safety
/// The CPU must support AVX2; every slice holds at least `out.len()` elements.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn cells8(vx: [&[f32]; 4], vy: [&[f32]; 4], z: [&[f32]; 4], out: &mut [[f32; 2]], test: OneSeedTest) -> usize {
    use std::arch::x86_64::*;
    let n8 = out.len() / 8 * 8;
    for i in (0..n8).step_by(8) {
        let load = |s: &[&[f32]; 4]| s.map(|s| _mm256_loadu_ps(s.as_ptr().add(i)));
        let [lo, hi] = interleave(cell_lanes(load(&vx), load(&vy), load(&z), test));
        let p = out.as_mut_ptr().add(i) as *mut f32;
        _mm256_storeu_ps(p, lo);
        _mm256_storeu_ps(p.add(8), hi);
    }
    n8
}

/// Eight cells' `(gx, gy)` as `[gx, gy]` pairs in cell order: cells 0-3, cells 4-7.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn interleave(
    (gx, gy): (std::arch::x86_64::__m256, std::arch::x86_64::__m256),
) -> [std::arch::x86_64::__m256; 2] {
    use std::arch::x86_64::*;
    let (lo, hi) = (_mm256_unpacklo_ps(gx, gy), _mm256_unpackhi_ps(gx, gy));
    [_mm256_permute2f128_ps::<0x20>(lo, hi), _mm256_permute2f128_ps::<0x31>(lo, hi)]
}

/// [`OneSeedTest::cell`] of eight cells, given per plane their texels `a b / c d`
/// (bit-identical: compare-select min / max, no FMA, the same order of sums): the two
/// channels.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn cell_lanes(
    vx: [std::arch::x86_64::__m256; 4],
    vy: [std::arch::x86_64::__m256; 4],
    [a, b, c, d]: [std::arch::x86_64::__m256; 4],
    test: OneSeedTest,
) -> (std::arch::x86_64::__m256, std::arch::x86_64::__m256) {
    use std::arch::x86_64::*;
    let (one, inf, sign) = (_mm256_set1_ps(1.0), _mm256_set1_ps(f32::INFINITY), _mm256_set1_ps(-0.0));
    let z_lo = _mm256_min_ps(_mm256_min_ps(a, b), _mm256_min_ps(c, d));
    let z_hi = _mm256_max_ps(_mm256_max_ps(a, b), _mm256_max_ps(c, d));
    let (step, room) = (_mm256_sub_ps(z_hi, z_lo), _mm256_sub_ps(one, z_hi));
    let below = |f: f32| _mm256_cmp_ps::<_CMP_LT_OQ>(step, _mm256_mul_ps(_mm256_set1_ps(f), room));
    let cont = below(crate::sampling::DEPTH_CONTINUITY);
    let abs = |v: __m256| _mm256_andnot_ps(sign, v);
    match test {
        OneSeedTest::Contraction => {
            let row = |[a, b, c, d]: [__m256; 4]| {
                let dx = _mm256_max_ps(abs(_mm256_sub_ps(b, a)), abs(_mm256_sub_ps(d, c)));
                let dy = _mm256_max_ps(abs(_mm256_sub_ps(c, a)), abs(_mm256_sub_ps(d, b)));
                _mm256_blendv_ps(inf, _mm256_add_ps(_mm256_mul_ps(dx, dx), _mm256_mul_ps(dy, dy)), cont)
            };
            (row(vx), row(vy))
        }
        OneSeedTest::Monotone => {
            let along_x = |[a, b, c, d]: [__m256; 4]| (_mm256_sub_ps(b, a), _mm256_sub_ps(d, c));
            let along_y = |[a, b, c, d]: [__m256; 4]| (_mm256_sub_ps(c, a), _mm256_sub_ps(d, b));
            let (axx, bxx) = along_x(vx);
            let (ayy, byy) = along_y(vy);
            let (axy, bxy) = along_y(vx);
            let (ayx, byx) = along_x(vy);
            let shear_lo = _mm256_add_ps(_mm256_min_ps(axy, bxy), _mm256_min_ps(ayx, byx));
            let shear_hi = _mm256_add_ps(_mm256_max_ps(axy, bxy), _mm256_max_ps(ayx, byx));
            let fold = _mm256_sub_ps(
                _mm256_mul_ps(_mm256_set1_ps(0.5), _mm256_max_ps(abs(shear_lo), abs(shear_hi))),
                _mm256_min_ps(_mm256_min_ps(axx, bxx), _mm256_min_ps(ayy, byy)),
            );
            let range = |[a, b, c, d]: [__m256; 4]| {
                let hi = _mm256_max_ps(_mm256_max_ps(a, b), _mm256_max_ps(c, d));
                let lo = _mm256_min_ps(_mm256_min_ps(a, b), _mm256_min_ps(c, d));
                _mm256_sub_ps(hi, lo)
            };
            let ranged = _mm256_max_ps(fold, _mm256_max_ps(range(vx), range(vy)));
            let surface = below(crate::sampling::SURFACE_DEPTH_STEP);
            let f = _mm256_blendv_ps(_mm256_blendv_ps(inf, ranged, cont), fold, surface);
            (f, f)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::seq::SliceRandom;
    use rand::{RngExt, SeedableRng};
    use rand_pcg::Pcg32;
    use rayon::prelude::*;

    /// Random `w x h` planes: a smooth field with noise, depth steps and empty texels.
    fn planes(w: u32, h: u32, seed: u64) -> SamplePlanes {
        let mut rng = Pcg32::seed_from_u64(seed);
        let n = (w * h) as usize;
        let mut p = SamplePlanes { vx: Vec::with_capacity(n), vy: Vec::with_capacity(n), z: Vec::with_capacity(n) };
        for i in 0..n {
            let (x, y) = ((i as u32 % w) as f32, (i as u32 / w) as f32);
            let empty = rng.random_range(0..20) == 0;
            // A depth step across which the fetch never interpolates, or one within which it
            // does while the motions agree.
            let step = rng.random_range(0..15) == 0;
            let far = rng.random_range(0..2) == 0;
            p.vx.push(if empty { 0.0 } else { 0.3 * x - 0.1 * y + rng.random_range(-0.4..0.4f32) });
            p.vy.push(if empty { 0.0 } else { 0.05 * x * x / w as f32 + rng.random_range(-0.2..0.2f32) });
            p.z.push(if empty {
                f32::INFINITY
            } else if step {
                if far {
                    0.9
                } else {
                    0.53
                }
            } else {
                0.5 + 0.001 * x
            });
        }
        p
    }

    /// Over random cells of one surface, at random points of the cell, the bilinear
    /// interpolant's Jacobian `[[a, b], [c, d]]` stays within the bounds: `a^2 + b^2 <= gx`,
    /// `c^2 + d^2 <= gy` and `|b + c| / 2 - min(a, d) <= fold`. A cell with a depth step above
    /// the surface step has a fold of at least its motion range, one above the continuity step
    /// no bound at all.
    #[test]
    fn cell_bounds_hold_at_every_point_of_the_cell() {
        let mut rng = Pcg32::seed_from_u64(7);
        for _ in 0..2000 {
            let mut texel = || [rng.random_range(-3.0..3.0f32), rng.random_range(-3.0..3.0f32), 0.5];
            let [a, b, c, d] = [texel(), texel(), texel(), texel()];
            let [gx, gy] = cell_gradient(a, b, c, d);
            let fold = cell_fold(a, b, c, d);
            for _ in 0..16 {
                let (s, t) = (rng.random_range(0.0..=1.0f32), rng.random_range(0.0..=1.0f32));
                let dx = |i: usize| (1.0 - t) * (b[i] - a[i]) + t * (d[i] - c[i]);
                let dy = |i: usize| (1.0 - s) * (c[i] - a[i]) + s * (d[i] - b[i]);
                let (jxx, jxy, jyx, jyy) = (dx(0), dy(0), dx(1), dy(1));
                let eps = 1e-4;
                assert!(jxx * jxx + jxy * jxy <= gx + eps, "{a:?} {b:?} {c:?} {d:?} ({s}, {t})");
                assert!(jyx * jyx + jyy * jyy <= gy + eps, "{a:?} {b:?} {c:?} {d:?} ({s}, {t})");
                let n = 0.5 * (jxy + jyx).abs() - jxx.min(jyy);
                assert!(n <= fold + eps, "{n} > {fold}: {a:?} {b:?} {c:?} {d:?} ({s}, {t})");
            }
        }
        // dvx/dx = 1 (fold 0 - min(1, 0) = 0), motion range 1; dvx/dx = 0.5, range 0.5.
        let (a, b, half) = ([1.0, 0.0, 0.5], [2.0, 0.0, 0.5], [1.5, 0.0, 0.5]);
        assert_eq!(cell_fold(a, b, a, b), 0.0);
        // 0.55 next to 0.5: a step of 0.05 / 0.45 (continuous, more than the surface step).
        assert_eq!(cell_fold(a, b, a, [2.0, 0.0, 0.55]), 1.0);
        assert_eq!(cell_fold(a, half, a, [1.5, 0.0, 0.55]), 0.5);
        assert_eq!(cell_fold(a, b, a, [2.0, 0.0, 0.95]), f32::INFINITY);
        assert_eq!(cell_fold(a, b, a, [0.0, 0.0, f32::INFINITY]), f32::INFINITY);
    }

    /// A cell that is a contraction (`gx + gy < 1/2`) has a fold below `sqrt(3) / 2`, so the
    /// monotonicity test holds wherever the contraction test does at a uniform scale.
    #[test]
    fn a_contracting_cell_is_monotone() {
        let mut rng = Pcg32::seed_from_u64(11);
        let mut seen = 0;
        while seen < 2000 {
            let mut texel = || [rng.random_range(-0.6..0.6f32), rng.random_range(-0.6..0.6f32), 0.5];
            let [a, b, c, d] = [texel(), texel(), texel(), texel()];
            let [gx, gy] = cell_gradient(a, b, c, d);
            if gx + gy < UNIQUE_GRADIENT {
                seen += 1;
                let fold = cell_fold(a, b, c, d);
                assert!(fold < 0.8661, "{fold}: {a:?} {b:?} {c:?} {d:?}");
            }
        }
    }

    /// Texel `(tx, ty)` of `level` by brute force: the largest cell over its footprint.
    fn brute(p: &SamplePlanes, w: u32, h: u32, level: u32, tx: u32, ty: u32, test: OneSeedTest) -> [f32; 2] {
        let at = |x: u32, y: u32| {
            let i = (y * w + x) as usize;
            [p.vx[i], p.vy[i], p.z[i]]
        };
        let mut g = [f32::NEG_INFINITY; 2];
        for y in ty << level..((ty + 1) << level).min(h) {
            for x in tx << level..((tx + 1) << level).min(w) {
                let (x1, y1) = ((x + 1).min(w - 1), (y + 1).min(h - 1));
                g = max2(g, test.cell(at(x, y), at(x1, y), at(x, y1), at(x1, y1)));
            }
        }
        g
    }

    /// The mipmap of a `w x h` layer, laid out as its motion pyramid.
    fn mip(w: u32, h: u32, recycled: Option<GradientMip>, simd: bool, test: OneSeedTest) -> GradientMip {
        let m = zwarp_core::Image::new(w, h, zwarp_core::Motion { v: glam::Vec2::ZERO, depth: 0.5 });
        let levels = crate::MotionPyramid::build(&m).unwrap().raw().2.collect();
        let mut g = GradientMip::new(w, h, levels, test, recycled);
        g.simd = simd;
        g
    }

    /// Every texel of every level, asked in a random order (so blocks and coarser texels are
    /// computed from whichever look-up comes first), equals the brute-force maximum over its
    /// footprint, bit for bit: portable and AVX2 blocks (full 16-column blocks, blocks at the
    /// right and bottom borders, images smaller than a block), one thread and many, both tests,
    /// and a mipmap recycled for new planes computes them afresh.
    #[test]
    fn lazy_texels_equal_the_brute_force_maximum_over_their_footprint() {
        let mut rng = Pcg32::seed_from_u64(3);
        for (w, h) in [(1u32, 1u32), (2, 3), (5, 2), (17, 9), (33, 40), (64, 48), (97, 61), (150, 37)] {
            for (simd, test) in [false, crate::simd::has_avx2()]
                .into_iter()
                .flat_map(|s| [(s, OneSeedTest::Contraction), (s, OneSeedTest::Monotone)])
            {
                let mut old = None;
                for seed in [1u64, 2] {
                    let p = planes(w, h, seed + 10 * (w * h) as u64);
                    let g = mip(w, h, old.take(), simd, test);
                    let mut all: Vec<(u32, u32, u32)> = Vec::new();
                    for (l, &(lw, lh, _)) in g.levels.iter().enumerate() {
                        for ty in 0..lh {
                            for tx in 0..lw {
                                all.push((l as u32 + 1, tx, ty));
                            }
                        }
                    }
                    all.shuffle(&mut rng);
                    let got: Vec<[f32; 2]> = if seed == 1 {
                        all.iter().map(|&(l, tx, ty)| g.texel(&p, l, tx, ty)).collect()
                    } else {
                        all.par_iter().map(|&(l, tx, ty)| g.texel(&p, l, tx, ty)).collect()
                    };
                    for (&(l, tx, ty), got) in all.iter().zip(&got) {
                        let want = brute(&p, w, h, l, tx, ty, test);
                        assert_eq!(
                            got.map(f32::to_bits),
                            want.map(f32::to_bits),
                            "{w}x{h} simd {simd} {test:?} level {l} ({tx}, {ty})"
                        );
                    }
                    old = Some(g);
                }
            }
        }
    }
}
