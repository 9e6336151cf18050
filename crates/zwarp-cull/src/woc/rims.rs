//! Opening rims (sub-pixel disocclusions) and erosion of the occluders (thesis Sec. IV.1,
//! Fig. 4): the warped depth is pushed far where a surface may open between source samples.

use crate::maxdepth::erode_max;
use glam::Vec2;
use rayon::prelude::*;
use zwarp_core::{Error, Image, Result, EMPTY_DEPTH, NO_ITEM};
use zwarp_warp::{PixelState, SourcePos};

/// The 8 neighbour offsets `(dx, dy)` of [`opening_rim_dirs`]; bit `k` of a direction mask
/// stands for `NEIGHBOURS[k]`.
pub const NEIGHBOURS: [(i32, i32); 8] = [(-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1)];

/// How far (pixels, along the unit neighbour direction) behind a rim texel's centre a preimage
/// still counts as "outer" in [`open_rims_in_target`]. A rim texel's centre is covered by its
/// object; for a locally straight edge with outward normal `n`, the uncovered part of the
/// texel lies in `(q - c) . n > 0`. The nearest of the 8 neighbour directions `d` is within
/// 22.5 degrees of `n` (and that neighbour is not covered), so over the texel
/// (`|q - c| <= 0.71`) the uncovered part satisfies `(q - c) . d >= -0.71 sin 22.5 = -0.27`.
pub const RIM_MARGIN: f32 = 0.3;

/// Opening-rim directions of the previous frame (seed 000 Sec. 5, "depth holes are
/// conservatively kept at the far-clipping depth", applied to sub-pixel holes): for every
/// texel `c`, bit `k` is set when its neighbour `c' = c + NEIGHBOURS[k]` shows a different,
/// farther object (both non-empty) and their motions separate them by more than
/// `min_separation` pixels per frame, `(v(c) - v(c')) . (c - c') > min_separation`.
///
/// Why: the backward warp accepts a source texel whose forward position is within half a
/// pixel of a target pixel centre, i.e. every texel carries a 1x1 footprint. Where a near
/// object `A` slides away from a farther object `B` by less than a pixel per frame, the strip
/// between them is a disocclusion (what is behind is unknown: `B`'s hidden part or anything
/// farther), but the footprint of `A`'s rim texel still covers it, so the warp fills it with
/// `A`'s depth and no hole appears; the 1-pixel erosion cannot reopen it because both sides are
/// near. (`B`'s rim texel's footprint starts where `B`'s visible part starts, so only the near
/// side needs care.) Boundaries against empty pixels need nothing (the empty side is already a
/// far hole that the erosion widens), and closing boundaries (`A` moving over `B`) reveal
/// nothing.
///
/// Errors: sizes differ, negative or non-finite threshold.
pub fn opening_rim_dirs(
    depth: &Image<f32>,
    items: &Image<u32>,
    motion: &Image<zwarp_core::Motion>,
    min_separation: f32,
) -> Result<Image<u8>> {
    if !(min_separation.is_finite() && min_separation >= 0.0) {
        return Err(Error::invalid(format!("rim separation threshold must be >= 0 pixels, got {min_separation}")));
    }
    depth.check_same_size(items, "depth vs item buffer")?;
    depth.check_same_size(motion, "depth vs motion buffer")?;
    let (w, h) = depth.size();
    let (dd, it, mv) = (depth.data(), items.data(), motion.data());
    let wu = w as usize;
    let mut out = vec![0u8; dd.len()];
    out.par_chunks_mut(wu).enumerate().for_each(|(y, row)| {
        let interior_row = y > 0 && y + 1 < h as usize;
        let mut x = 0;
        // Most texels lie inside an object: eight at a time, a group whose texels all have
        // their item on every side (which no rim direction can take) is skipped whole; the
        // compares have no early exit, so they vectorise.
        if interior_row && wu > 9 {
            let (up, mid, down) =
                (&it[(y - 1) * wu..y * wu], &it[y * wu..(y + 1) * wu], &it[(y + 1) * wu..(y + 2) * wu]);
            x = 1;
            while x + 8 < wu {
                let mut other = false;
                for l in x..x + 8 {
                    let id = mid[l];
                    other |= (up[l - 1] != id)
                        | (up[l] != id)
                        | (up[l + 1] != id)
                        | (mid[l - 1] != id)
                        | (mid[l + 1] != id)
                        | (down[l - 1] != id)
                        | (down[l] != id)
                        | (down[l + 1] != id);
                }
                if other {
                    for (l, o) in row.iter_mut().enumerate().skip(x).take(8) {
                        *o = rim_mask(dd, it, mv, (w, h), (l, y), min_separation);
                    }
                }
                x += 8;
            }
            row[0] = rim_mask(dd, it, mv, (w, h), (0, y), min_separation);
        }
        for (l, o) in row.iter_mut().enumerate().skip(x) {
            *o = rim_mask(dd, it, mv, (w, h), (l, y), min_separation);
        }
    });
    Image::from_vec(w, h, out)
}

/// The opening-rim directions of texel `(x, y)` ([`opening_rim_dirs`]).
#[inline]
pub(super) fn rim_mask(
    dd: &[f32],
    it: &[u32],
    mv: &[zwarp_core::Motion],
    (w, h): (u32, u32),
    (x, y): (usize, usize),
    min_separation: f32,
) -> u8 {
    let (wi, hi) = (w as i64, h as i64);
    let (x, y) = (x as i64, y as i64);
    let i = (y * wi + x) as usize;
    let (d, id) = (dd[i], it[i]);
    if d >= EMPTY_DEPTH || id == NO_ITEM {
        return 0;
    }
    let v = mv[i].v;
    let mut mask = 0u8;
    for (k, &(dx, dy)) in NEIGHBOURS.iter().enumerate() {
        let (xx, yy) = (x + dx as i64, y + dy as i64);
        if !(0..wi).contains(&xx) || !(0..hi).contains(&yy) {
            continue;
        }
        let j = (yy * wi + xx) as usize;
        let (dn, idn) = (dd[j], it[j]);
        if idn == NO_ITEM || idn == id || dn >= EMPTY_DEPTH || dn <= d {
            continue;
        }
        // c - c' = (-dx, -dy): positive when c moves away from c' relative to it.
        let rel = v - mv[j].v;
        if -(rel.x * dx as f32 + rel.y * dy as f32) > min_separation {
            mask |= 1 << k;
        }
    }
    mask
}

/// `depth` with every texel that has an opening-rim direction set to [`EMPTY_DEPTH`].
pub(crate) fn blank_rims(depth: &Image<f32>, dirs: &Image<u8>) -> Image<f32> {
    let data = depth.data().par_iter().zip(dirs.data().par_iter()).map(|(&d, &m)| if m != 0 { EMPTY_DEPTH } else { d });
    Image::from_vec(depth.width(), depth.height(), data.collect()).expect("same size as depth")
}

/// Source-side opening rims ([`RimMode::Source`](super::RimMode::Source)): `depth` with every texel that has an
/// opening-rim direction ([`opening_rim_dirs`]) set to [`EMPTY_DEPTH`], so the warp leaves a
/// hole over its whole footprint.
///
/// Errors: sizes differ, negative or non-finite threshold.
pub fn opening_rims(
    depth: &Image<f32>,
    items: &Image<u32>,
    motion: &Image<zwarp_core::Motion>,
    min_separation: f32,
) -> Result<Image<f32>> {
    let dirs = opening_rim_dirs(depth, items, motion, min_separation)?;
    Ok(blank_rims(depth, &dirs))
}

/// Target-side opening rims ([`RimMode::Target`](super::RimMode::Target)): sets to [`EMPTY_DEPTH`] every pixel `p` of
/// `predicted` (the warped, possibly eroded depth) that converged on a source texel `c` with
/// opening-rim directions `dirs` (from [`opening_rim_dirs`]) and whose exact preimage
/// `q* = p - v(c)` lies on the outer side of `c`, `(q* - c) . d >= -RIM_MARGIN` for one of the
/// texel's unit opening directions `d`. Returns how many pixels were opened.
///
/// Why this is enough: with nearest motion sampling the texel moves rigidly by `v(c)`, so `p`
/// shows the point `q*` of texel `c`. If `q*` is covered by `c`'s object (the inner side of
/// its centre, which the object covers), `p` truly shows that object's surface moved by its
/// own motion; only preimages beyond the texel centre towards the separating neighbour can be
/// uncovered, i.e. be the disocclusion strip ([`RIM_MARGIN`] covers oblique edges). The
/// pixels opened are the strip itself, so unlike [`RimMode::Source`](super::RimMode::Source) they are set after the
/// erosion and are not widened.
///
/// Errors: sizes differ.
pub fn open_rims_in_target(
    predicted: &mut Image<f32>,
    source: &Image<SourcePos>,
    state: &Image<PixelState>,
    motion: &Image<zwarp_core::Motion>,
    dirs: &Image<u8>,
) -> Result<usize> {
    predicted.check_same_size(source, "predicted depth vs warp sources")?;
    predicted.check_same_size(state, "predicted depth vs warp states")?;
    motion.check_same_size(dirs, "motion vs rim directions")?;
    let w = predicted.width();
    let (sw, sh) = motion.size();
    let unit: [Vec2; 8] = NEIGHBOURS.map(|(dx, dy)| Vec2::new(dx as f32, dy as f32).normalize());
    let (src, st, mv, dm) = (source.data(), state.data(), motion.data(), dirs.data());
    let wu = w as usize;
    let (swf, shf) = (sw as f32, sh as f32);
    let opened: usize = predicted
        .data_mut()
        .par_chunks_mut(wu)
        .zip(src.par_chunks(wu).zip(st.par_chunks(wu)))
        .enumerate()
        .map(|(y, (row, (src_row, st_row)))| {
            let mut n = 0;
            for (x, ((d, s), state)) in row.iter_mut().zip(src_row).zip(st_row).enumerate() {
                let q = s.q;
                // The texel holding q (truncation is the floor on the image).
                if *state != PixelState::Converged
                    || *d >= EMPTY_DEPTH
                    || !(q.x >= 0.0 && q.y >= 0.0 && q.x < swf && q.y < shf)
                {
                    continue;
                }
                let (cx, cy) = (q.x as u32, q.y as u32);
                let c = cy as usize * sw as usize + cx as usize;
                let mask = dm[c];
                if mask == 0 {
                    continue;
                }
                let p = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                let local = p - mv[c].v - Vec2::new(cx as f32 + 0.5, cy as f32 + 0.5);
                if (0..8).any(|k| mask & (1 << k) != 0 && local.dot(unit[k]) >= -RIM_MARGIN) {
                    *d = EMPTY_DEPTH;
                    n += 1;
                }
            }
            n
        })
        .sum();
    Ok(opened)
}

/// Far pixels within this many pixels (Chebyshev) of a surface pixel get a static-ray bound
/// ([`WocParams::hole_bound`](super::WocParams::hole_bound)); the inside of wide far regions (sky) is not marched.
pub const HOLE_BOUND_RADIUS: usize = 4;

/// Flags the far pixels of `depth` that have a non-far pixel within `r` (Chebyshev).
pub(crate) fn near_surface(depth: &Image<f32>, r: usize) -> Vec<bool> {
    let (w, h) = (depth.width() as usize, depth.height() as usize);
    let d = depth.data();
    // Separable dilation of the surface mask: rows, then columns.
    let rows: Vec<bool> = (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            (x.saturating_sub(r)..(x + r + 1).min(w)).any(|xx| d[y * w + xx] < EMPTY_DEPTH)
        })
        .collect();
    (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            d[i] >= EMPTY_DEPTH && (y.saturating_sub(r)..(y + r + 1).min(h)).any(|yy| rows[yy * w + x])
        })
        .collect()
}

/// `radius` steps of the 3x3 max erosion ([`erode_max`]): a `(2 radius + 1)^2` max filter.
pub(crate) fn erode_n(mut depth: Image<f32>, radius: u32) -> Image<f32> {
    for _ in 0..radius {
        depth = erode_max(&depth);
    }
    depth
}
