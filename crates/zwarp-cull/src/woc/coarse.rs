//! Culling at a reduced resolution (`WocParams::downsample`): the coarse camera, conservative
//! max reductions of depth over each coarse texel's footprint, and the previous frame reduced
//! to the coarse grid with the item of each texel's farthest sample.

use glam::Vec2;
use rayon::prelude::*;
use zwarp_core::{Camera, Error, Image, Result, EMPTY_DEPTH, NO_ITEM};

use crate::AVX2;

/// The same view volume rendered at `1/factor` of the resolution (rounded up): projection and
/// view are unchanged, only the pixel grid is coarser.
pub fn coarse_camera(cam: &Camera, factor: u32) -> Camera {
    Camera { width: cam.width.div_ceil(factor.max(1)), height: cam.height.div_ceil(factor.max(1)), ..*cam }
}

/// Fine pixels `[lo, hi)` touched by coarse pixel `i` when `fine` pixels map onto `coarse`.
#[inline]
pub(crate) fn footprint(i: u32, fine: u32, coarse: u32) -> (u32, u32) {
    let (i, fine, coarse) = (i as u64, fine as u64, coarse as u64);
    let lo = i * fine / coarse;
    let hi = ((i + 1) * fine).div_ceil(coarse).min(fine);
    (lo as u32, hi as u32)
}

/// Conservative reduction of a depth + item buffer to `width x height` (the size of
/// [`coarse_camera`]): each coarse pixel takes the max depth over every fine pixel its
/// footprint touches, and the item of that farthest pixel (first one on ties).
pub fn downsample_max(
    depth: &Image<f32>,
    items: &Image<u32>,
    width: u32,
    height: u32,
) -> Result<(Image<f32>, Image<u32>)> {
    depth.check_nonempty("depth buffer")?;
    depth.check_same_size(items, "depth vs item buffer")?;
    if width == 0 || height == 0 || width > depth.width() || height > depth.height() {
        return Err(Error::invalid(format!("cannot reduce {}x{} to {width}x{height}", depth.width(), depth.height())));
    }
    let r = reduce_prev(depth, items, (width, height), None);
    Ok((r.depth, r.items))
}

/// A fine pixel of a coarse footprint: depth, item, x, y.
pub(crate) type Px = (f32, u32, u32, u32);

/// The previous frame at the culling resolution ([`reduce_prev`]).
pub(crate) struct CoarsePrev {
    /// [`downsample_max`]'s depth.
    pub(crate) depth: Image<f32>,
    /// [`downsample_max`]'s items.
    pub(crate) items: Image<u32>,
    /// The coarse texels (row-major index, ascending) whose nearest and farthest non-empty fine
    /// pixels belong to two different objects (ids below the object count given), the nearer
    /// strictly nearer, with those two pixels (input of [`coarse_internal_openings`]); empty
    /// unless asked for. Listed sparsely: most texels lie on one object.
    pub(crate) pairs: Vec<TexelPair>,
    /// A fine depth was NaN.
    pub(crate) nan: bool,
}

/// What [`reduce_prev`] gathers over one coarse texel's footprint: the farthest pixel (depth,
/// item) and the nearest and farthest pixels of objects (depth, fine x, fine y), each the first
/// in row-major order.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Acc {
    best: (f32, u32),
    near: (f32, u32, u32),
    far: (f32, u32, u32),
}

/// An [`Acc`] before any pixel.
const EMPTY_ACC: Acc =
    Acc { best: (f32::NEG_INFINITY, NO_ITEM), near: (f32::INFINITY, 0, 0), far: (f32::NEG_INFINITY, 0, 0) };

/// One pass over the fine previous buffers for the coarse culling resolution (seed 002
/// Sec. VI): [`downsample_max`]'s conservative reduction, the near/far object pairs of
/// [`coarse_internal_openings`] when `pairs_below` gives the object count, and the NaN check,
/// reading each fine pixel once (separate passes cost ~1.5 ms per 0.5 Mpx frame, more than the
/// coarse warp itself). Ties keep the first pixel in row-major order.
pub(crate) fn reduce_prev(
    depth: &Image<f32>,
    items: &Image<u32>,
    (cw, ch): (u32, u32),
    pairs_below: Option<usize>,
) -> CoarsePrev {
    let (fw, fh) = depth.size();
    let xs: Vec<(u32, u32)> = (0..cw).map(|cx| footprint(cx, fw, cw)).collect();
    let (cwu, n) = (cw as usize, cw as usize * ch as usize);
    let mut out_d = vec![0.0f32; n];
    let mut out_i = vec![NO_ITEM; n];
    let limit = pairs_below.unwrap_or(0);
    // Per coarse column of one coarse row: farthest pixel (depth, item) and, for the pairs,
    // the nearest and farthest valid pixel (depth, fine x, fine y). The fine rows are walked
    // whole, so consecutive pixels update different columns' accumulators: no loop-carried
    // dependency through one running max (the per-texel loop was latency-bound, ~7 cycles per
    // fine pixel). Ties keep the first pixel in row-major order (strict comparisons).
    // Footprints four fine columns wide, one after another: the AVX2 build takes the coarse
    // texels two at a time (eight fine columns per row load), the same bits.
    let lanes = AVX2.active() && fw == 4 * cw && limit <= NO_ITEM as usize;
    let row = |cy: usize, od: &mut [f32], oi: &mut [u32], op: Option<&mut Vec<TexelPair>>| -> bool {
        let (y0, y1) = footprint(cy as u32, fh, ch);
        let mut acc = vec![EMPTY_ACC; xs.len()];
        let mut nan = false;
        let mut from = 0;
        #[cfg(target_arch = "x86_64")]
        if lanes {
            // SAFETY: AVX2 checked; the rows hold `4 * acc.len()` fine pixels.
            nan = unsafe { avx2::reduce_pairs(depth, items, (y0, y1), limit, &mut acc) };
            from = acc.len() & !1;
        }
        for y in y0..y1 {
            let (ds, is) = (depth.row(y), items.row(y));
            for (a, &(x0, x1)) in acc.iter_mut().zip(&xs).skip(from) {
                for x in x0..x1 {
                    let (d, id) = (ds[x as usize], is[x as usize]);
                    nan |= d.is_nan();
                    if d > a.best.0 {
                        a.best = (d, id);
                    }
                    // `NO_ITEM` is never below the object count.
                    if d < EMPTY_DEPTH && (id as usize) < limit {
                        if d < a.near.0 {
                            a.near = (d, x, y);
                        }
                        if d > a.far.0 {
                            a.far = (d, x, y);
                        }
                    }
                }
            }
        }
        for (cx, a) in acc.iter().enumerate() {
            od[cx] = a.best.0;
            oi[cx] = a.best.1;
        }
        if let Some(p) = op {
            for (cx, a) in acc.iter().enumerate().filter(|(_, a)| a.near.0 < a.far.0) {
                let near = (a.near.0, *items.get(a.near.1, a.near.2), a.near.1, a.near.2);
                let far = (a.far.0, *items.get(a.far.1, a.far.2), a.far.1, a.far.2);
                if near.1 != far.1 {
                    p.push(((cy * cwu + cx) as u32, near, far));
                }
            }
        }
        nan
    };
    let mut out_p = Vec::new();
    let nan = if pairs_below.is_some() {
        let rows: Vec<(bool, Vec<TexelPair>)> = out_d
            .par_chunks_mut(cwu)
            .zip(out_i.par_chunks_mut(cwu))
            .enumerate()
            .map(|(cy, (od, oi))| {
                let mut p = Vec::new();
                (row(cy, od, oi, Some(&mut p)), p)
            })
            .collect();
        out_p = rows.iter().flat_map(|(_, p)| p.iter().copied()).collect();
        rows.iter().any(|(nan, _)| *nan)
    } else {
        out_d
            .par_chunks_mut(cwu)
            .zip(out_i.par_chunks_mut(cwu))
            .enumerate()
            .map(|(cy, (od, oi))| row(cy, od, oi, None))
            .reduce(|| false, |a, b| a || b)
    };
    CoarsePrev {
        depth: Image::from_vec(cw, ch, out_d).expect("cw x ch values"),
        items: Image::from_vec(cw, ch, out_i).expect("cw x ch values"),
        pairs: out_p,
        nan,
    }
}

/// A coarse texel of [`CoarsePrev::pairs`]: its row-major index, its nearest and farthest fine
/// pixels of objects.
pub(crate) type TexelPair = (u32, Px, Px);

/// Coarse texels whose footprint holds an *internal opening*: two different objects (the
/// nearest and the farthest fine pixel of the footprint) whose own screen motions, from
/// `prev_cam` to `cam` with each object's world-space motion `delta(id)`, in fine pixels, pull
/// them apart by more than
/// `min_separation` px/frame. Returns one flag per coarse texel (row-major, `cw x ch` of
/// [`coarse_camera`]).
///
/// Why: [`downsample_max`] keeps the farthest fine pixel of a footprint and that pixel's item,
/// so a coarse texel straddling a near object `A` and a farther `B` moves rigidly with `B`.
/// Where `A` slides away from `B` inside the footprint, the strip it uncovers (what is behind
/// `A`: `B`'s hidden part, or anything farther when `B` ends there too) gets `B`'s depth, and
/// the coarse opening-rim test never sees the boundary (it is inside one texel). Blanking these
/// texels is the coarse analogue of [`RimMode::Source`]. The separation direction is taken from
/// the far pixel to the near one; any relative motion within 120 degrees of it counts, so a
/// boundary running obliquely through the footprint is still caught. `pairs` comes from
/// [`reduce_prev`] (fine pixel coordinates in a `fw x fh` image).
pub(crate) fn coarse_internal_openings(
    delta: impl Fn(u32) -> glam::Mat4 + Sync,
    pairs: &[TexelPair],
    texels: usize,
    (fw, fh): (u32, u32),
    prev_cam: &Camera,
    cam: &Camera,
    min_separation: f32,
) -> Vec<bool> {
    // Object matrices of the items involved, computed once each: the ids marked in a bit set
    // (ids are below the object count), listed in increasing order.
    let words = pairs.iter().map(|(_, a, b)| a.1.max(b.1) as usize / 64 + 1).max().unwrap_or(0);
    let mut seen = vec![0u64; words];
    for (_, a, b) in pairs {
        for id in [a.1, b.1] {
            seen[id as usize / 64] |= 1 << (id % 64);
        }
    }
    let ids: Vec<u32> = seen
        .iter()
        .enumerate()
        .flat_map(|(k, &w)| (0..64).filter(move |b| w >> b & 1 != 0).map(move |b| (k * 64 + b) as u32))
        .collect();
    let vp_b = cam.view_proj();
    let mats: Vec<glam::Mat4> = ids.par_iter().map(|&id| vp_b * delta(id)).collect();
    let mat = |id: u32| &mats[ids.binary_search(&id).expect("collected above")];
    let inv_a = prev_cam.view_proj().inverse();
    let motion = |p: &Px| {
        zwarp_core::motion::reproject_pixel(&inv_a, mat(p.1), (fw, fh), (cam.width, cam.height), p.2, p.3, p.0).v
    };
    let open: Vec<u32> = pairs
        .par_iter()
        .filter(|(_, near, far)| {
            let rel = motion(near) - motion(far);
            let dir = Vec2::new(near.2 as f32 - far.2 as f32, near.3 as f32 - far.3 as f32).normalize();
            let len = rel.length();
            len > min_separation && rel.dot(dir) > -0.5 * len
        })
        .map(|(i, _, _)| *i)
        .collect();
    let mut flags = vec![false; texels];
    for i in open {
        flags[i as usize] = true;
    }
    flags
}

/// Depth-only twin of [`downsample_max`]: each of the `cw x ch` coarse pixels takes the max of
/// `fine` over every fine pixel its footprint touches (the bound each coarse texel of an
/// occlusion map must respect). `cw`, `ch` at least 1 and at most `fine`'s size.
pub fn max_over_footprints(fine: &Image<f32>, (cw, ch): (u32, u32)) -> Image<f32> {
    let (fw, fh) = fine.size();
    let xs: Vec<(u32, u32)> = (0..cw).map(|cx| footprint(cx, fw, cw)).collect();
    let mut out = Image::new(cw, ch, f32::NEG_INFINITY);
    out.data_mut().par_chunks_mut(cw as usize).enumerate().for_each(|(cy, row)| {
        let (y0, y1) = footprint(cy as u32, fh, ch);
        for (o, &(x0, x1)) in row.iter_mut().zip(&xs) {
            for y in y0..y1 {
                for &d in &fine.row(y)[x0 as usize..x1 as usize] {
                    *o = o.max(d);
                }
            }
        }
    });
    out
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use std::arch::x86_64::*;

    use super::{Acc, EMPTY_ACC};
    use zwarp_core::{Image, EMPTY_DEPTH, NO_ITEM};

    /// [`super::reduce_prev`]'s accumulators of fine rows `y0..y1` for the coarse texels of
    /// `acc` taken two at a time (texel `c` covers fine columns `4c..4c + 4`; an odd last one
    /// is left to the caller): per fine column the first row holding its farthest pixel and,
    /// among pixels of objects (`depth < 1`, item below `limit`), its nearest and farthest,
    /// then per texel the first of its four columns' candidates in row-major order. Returns
    /// whether a depth was NaN (NaN never wins a comparison, as in the scalar loop).
    ///
    /// # Safety
    /// The CPU must support AVX2; `depth` and `items` must have `4 * acc.len()` or more
    /// columns and rows `y0..y1`.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn reduce_pairs(
        depth: &Image<f32>,
        items: &Image<u32>,
        (y0, y1): (u32, u32),
        limit: usize,
        acc: &mut [Acc],
    ) -> bool {
        let mut nan = _mm256_setzero_ps();
        let one = _mm256_set1_ps(EMPTY_DEPTH);
        // `id < limit` as unsigned: `min(id, limit - 1) == id` (no id is below a limit of 0).
        let below = |id: __m256i| -> __m256i {
            if limit == 0 {
                _mm256_setzero_si256()
            } else {
                _mm256_cmpeq_epi32(_mm256_min_epu32(id, _mm256_set1_epi32((limit - 1) as u32 as i32)), id)
            }
        };
        for pair in 0..acc.len() / 2 {
            let x = 8 * pair;
            let mut bd = _mm256_set1_ps(f32::NEG_INFINITY);
            let mut bi = _mm256_set1_epi32(NO_ITEM as i32);
            let mut by = _mm256_setzero_si256();
            let mut nd = _mm256_set1_ps(f32::INFINITY);
            let mut ny = _mm256_setzero_si256();
            let mut fd = _mm256_set1_ps(f32::NEG_INFINITY);
            let mut fy = _mm256_setzero_si256();
            for y in y0..y1 {
                let d = _mm256_loadu_ps(depth.row(y).as_ptr().add(x));
                let id = _mm256_loadu_si256(items.row(y).as_ptr().add(x) as *const __m256i);
                let yv = _mm256_set1_epi32(y as i32);
                nan = _mm256_or_ps(nan, _mm256_cmp_ps::<_CMP_UNORD_Q>(d, d));
                let gt = _mm256_cmp_ps::<_CMP_GT_OQ>(d, bd);
                bd = _mm256_blendv_ps(bd, d, gt);
                bi = _mm256_blendv_epi8(bi, id, _mm256_castps_si256(gt));
                by = _mm256_blendv_epi8(by, yv, _mm256_castps_si256(gt));
                let valid = _mm256_and_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(d, one), _mm256_castsi256_ps(below(id)));
                let lt = _mm256_and_ps(valid, _mm256_cmp_ps::<_CMP_LT_OQ>(d, nd));
                nd = _mm256_blendv_ps(nd, d, lt);
                ny = _mm256_blendv_epi8(ny, yv, _mm256_castps_si256(lt));
                let gtv = _mm256_and_ps(valid, _mm256_cmp_ps::<_CMP_GT_OQ>(d, fd));
                fd = _mm256_blendv_ps(fd, d, gtv);
                fy = _mm256_blendv_epi8(fy, yv, _mm256_castps_si256(gtv));
            }
            let (mut bds, mut nds, mut fds) = ([0f32; 8], [0f32; 8], [0f32; 8]);
            let (mut bis, mut bys, mut nys, mut fys) = ([0u32; 8], [0u32; 8], [0u32; 8], [0u32; 8]);
            _mm256_storeu_ps(bds.as_mut_ptr(), bd);
            _mm256_storeu_ps(nds.as_mut_ptr(), nd);
            _mm256_storeu_ps(fds.as_mut_ptr(), fd);
            _mm256_storeu_si256(bis.as_mut_ptr() as *mut __m256i, bi);
            _mm256_storeu_si256(bys.as_mut_ptr() as *mut __m256i, by);
            _mm256_storeu_si256(nys.as_mut_ptr() as *mut __m256i, ny);
            _mm256_storeu_si256(fys.as_mut_ptr() as *mut __m256i, fy);
            for t in 0..2 {
                let cols = 4 * t..4 * t + 4;
                // The first in row-major order among the columns whose candidate is `better`
                // than every other's: earliest row, then leftmost column.
                let first = |v: &[f32; 8], rows: &[u32; 8], better: fn(f32, f32) -> bool| -> Option<usize> {
                    let mut pick: Option<usize> = None;
                    for c in cols.clone() {
                        pick = match pick {
                            None => Some(c),
                            Some(p) if better(v[c], v[p]) || (v[c] == v[p] && rows[c] < rows[p]) => Some(c),
                            keep => keep,
                        };
                    }
                    pick
                };
                let a = &mut acc[2 * pair + t];
                *a = EMPTY_ACC;
                let b = first(&bds, &bys, |u, v| u > v).expect("four columns");
                if bds[b] > f32::NEG_INFINITY {
                    a.best = (bds[b], bis[b]);
                }
                let n = first(&nds, &nys, |u, v| u < v).expect("four columns");
                if nds[n] < f32::INFINITY {
                    a.near = (nds[n], (x + n) as u32, nys[n]);
                }
                let f = first(&fds, &fys, |u, v| u > v).expect("four columns");
                if fds[f] > f32::NEG_INFINITY {
                    a.far = (fds[f], (x + f) as u32, fys[f]);
                }
            }
        }
        _mm256_movemask_ps(nan) != 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bits of everything [`reduce_prev`] returns.
    type Bits = (Vec<u32>, Vec<u32>, Vec<(u32, [u32; 4], [u32; 4])>, bool);

    fn bits(r: &CoarsePrev) -> Bits {
        let px = |p: &Px| [p.0.to_bits(), p.1, p.2, p.3];
        (
            r.depth.data().iter().map(|d| d.to_bits()).collect(),
            r.items.data().to_vec(),
            r.pairs.iter().map(|(i, a, b)| (*i, px(a), px(b))).collect(),
            r.nan,
        )
    }

    #[test]
    fn avx2_reduction_equals_the_scalar_one() {
        let _switch = crate::SIMD_TEST_LOCK.lock().unwrap_or_else(|e| e.into_inner());
        if !AVX2.active() {
            eprintln!("note: no AVX2 on this CPU; both runs take the scalar code");
        }
        let mut state = 0x2545_f491_u32;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state
        };
        // Widths with an even and an odd number of texels, heights with whole and partial
        // footprints (every fine row belongs to some texel either way).
        for (cw, ch, fh) in [(6u32, 3u32, 12u32), (7, 4, 14), (1, 2, 8), (10, 5, 21)] {
            let fw = 4 * cw;
            for case in 0..6 {
                // Few distinct depths and items so that ties, empty pixels and -0.0 / 0.0 occur.
                let levels = [0.25f32, 0.5, 0.5, -0.0, 0.0, EMPTY_DEPTH, 0.75, 0.125];
                let depth = Image::from_vec(
                    fw,
                    fh,
                    (0..fw * fh)
                        .map(|_| match next() % 41 {
                            0 if case == 5 => f32::NAN,
                            k => levels[k as usize % levels.len()],
                        })
                        .collect(),
                )
                .unwrap();
                let items = Image::from_vec(
                    fw,
                    fh,
                    (0..fw * fh).map(|_| if next() % 9 == 0 { NO_ITEM } else { next() % 5 }).collect(),
                )
                .unwrap();
                for pairs in [None, Some(0), Some(3), Some(5)] {
                    crate::set_simd(true);
                    let fast = reduce_prev(&depth, &items, (cw, ch), pairs);
                    crate::set_simd(false);
                    let scalar = reduce_prev(&depth, &items, (cw, ch), pairs);
                    crate::set_simd(true);
                    assert!(bits(&fast) == bits(&scalar), "{cw}x{ch} from {fw}x{fh}, case {case}, pairs {pairs:?}");
                    assert_eq!(scalar.nan, case == 5 && depth.data().iter().any(|d| d.is_nan()));
                }
            }
        }
    }
}
