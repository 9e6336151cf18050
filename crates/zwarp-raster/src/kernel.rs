//! Tile back end: rasterizes the binned triangles of each screen tile into a tile-local buffer
//! (L1-resident), in parallel over bands of tiles (no locks: every band owns its output rows).
//!
//! Inner loop: 8 pixels per step with incremental i32 edge functions and an f32 depth plane,
//! written so LLVM vectorizes it; an AVX2 build of the same code is selected at run time on x86.

use rayon::prelude::*;
use zwarp_core::{Image, NO_ITEM};

use crate::setup::{clamp_depth, Binned, Tri, TILE_H, TILE_W};
use crate::simd::has_avx2;

const TILE_PIX: usize = TILE_W * TILE_H;
/// Triangles rasterized between two refreshes of a tile's conservative max depth.
const ZMAX_REFRESH: u32 = 32;
/// Clamp for the per-row i32 edge values: |a| < 2^23 (guard band, `setup.rs`) so 64 |a| < 2^29;
/// a clamped value keeps its sign over a whole tile row and never overflows i32.
const EDGE_CLAMP: i64 = 1 << 29;

/// Rasterization mode of a pass.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Mode {
    /// Depth test `z < stored`, write depth (and ids if requested).
    Depth,
    /// Depth peeling: additionally `z > threshold[pixel]` (strictly behind the previous layer).
    Peel,
    /// Test helper: count covered pixel centres into the id buffer, no depth test.
    Count,
}

struct TileBuf {
    depth: Vec<f32>,
    ids: Vec<u32>,
    thr: Vec<f32>,
}

/// The per-triangle tile kernel.
///
/// `tx0, ty0` = tile origin in pixels. Pixels outside the image but inside the tile buffer are
/// harmless padding (never written back).
#[inline(always)]
fn raster_tri<const IDS: bool, const PEEL: bool, const COUNT: bool, const AVX2: bool>(
    t: &Tri,
    handle: u32,
    tx0: u32,
    ty0: u32,
    buf: &mut TileBuf,
) {
    let x0 = (t.x0 as u32).max(tx0) - tx0;
    let x1 = (t.x1 as u32).min(tx0 + TILE_W as u32 - 1) - tx0;
    let y0 = (t.y0 as u32).max(ty0) - ty0;
    let y1 = (t.y1 as u32).min(ty0 + TILE_H as u32 - 1) - ty0;
    let xs = x0 & !7;
    let zx = t.zx as f32;
    let mut oa = [[0i32; 8]; 3];
    for (row, &a) in oa.iter_mut().zip(&t.a) {
        for (k, o) in row.iter_mut().enumerate() {
            *o = a * k as i32;
        }
    }
    let step = [t.a[0] * 8, t.a[1] * 8, t.a[2] * 8];
    let depth = &mut buf.depth[..];
    let ids = &mut buf.ids[..];
    let thr = &buf.thr[..];
    let gx = (tx0 + xs) as i64;
    let mut erow = [0i64; 3];
    for (i, er) in erow.iter_mut().enumerate() {
        *er = t.edge_at(i, gx, (ty0 + y0) as i64);
    }
    for y in y0..=y1 {
        let mut e = [0i32; 3];
        for i in 0..3 {
            e[i] = erow[i].clamp(-EDGE_CLAMP, EDGE_CLAMP) as i32;
            erow[i] += t.b[i] as i64;
        }
        let zrow = t.row_depth(tx0, ty0 + y);
        let row = y as usize * TILE_W;
        let mut xb = xs;
        while xb <= x1 {
            let i = row + xb as usize;
            let mut ee = [0i32; 8];
            for k in 0..8 {
                ee[k] = (e[0] + oa[0][k]) | (e[1] + oa[1][k]) | (e[2] + oa[2][k]);
            }
            // Sign-bit mask of the 8 lanes (LLVM turns this into one movmskps); all set <=> no
            // lane covered: skip the chunk.
            if !all_negative::<AVX2>(&ee) {
                let id8: &mut [u32; 8] = (&mut ids[i..i + 8]).try_into().unwrap();
                if COUNT {
                    for k in 0..8 {
                        id8[k] += (ee[k] >= 0) as u32;
                    }
                } else {
                    let d8: &mut [f32; 8] = (&mut depth[i..i + 8]).try_into().unwrap();
                    let th8: &[f32; 8] = if PEEL { (&thr[i..i + 8]).try_into().unwrap() } else { &[0.0; 8] };
                    let xbf = xb as f32;
                    // Branch-free lanes (bitwise `&` on bools) so LLVM emits compares + blends.
                    // Lane masks first, then bitwise selects: this shape vectorizes in every
                    // mode (a combined conditional update with the peeling threshold did not).
                    let mut m = [0u32; 8];
                    let mut zz = [0f32; 8];
                    for k in 0..8 {
                        let z = clamp_depth(zrow + zx * (xbf + LANE[k]));
                        let mut pass = (ee[k] >= 0) & (z < d8[k]);
                        if PEEL {
                            pass &= z > th8[k];
                        }
                        m[k] = (pass as u32).wrapping_neg();
                        zz[k] = z;
                    }
                    for k in 0..8 {
                        d8[k] = f32::from_bits((zz[k].to_bits() & m[k]) | (d8[k].to_bits() & !m[k]));
                    }
                    if IDS {
                        // Separate bitwise select (mixing the f32 and u32 selects in one loop made
                        // LLVM scalarize both).
                        for k in 0..8 {
                            id8[k] = (handle & m[k]) | (id8[k] & !m[k]);
                        }
                    }
                }
            }
            e[0] += step[0];
            e[1] += step[1];
            e[2] += step[2];
            xb += 8;
        }
    }
}

/// `true` if all 8 edge values are negative (no lane covered). The AVX2 instantiation (only
/// ever called from the `target_feature(enable = "avx2")` build) uses one `vmovmskps`; the
/// portable one builds the same sign mask with scalar ops.
#[inline(always)]
fn all_negative<const AVX2: bool>(ee: &[i32; 8]) -> bool {
    #[cfg(target_arch = "x86_64")]
    if AVX2 {
        use std::arch::x86_64::*;
        // SAFETY: AVX2 = true only inside `raster_tile_avx2`, which runs after a run-time AVX2
        // check; the load reads exactly the 32 bytes of `ee`.
        return unsafe { _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_loadu_si256(ee.as_ptr().cast()))) == 0xff };
    }
    let mut neg = 0u32;
    for (k, &v) in ee.iter().enumerate() {
        neg |= ((v < 0) as u32) << k;
    }
    neg == 0xff
}

/// Lane offsets as f32 (exact small integers: `xbf + LANE[k]` equals `(xb + k) as f32`).
const LANE: [f32; 8] = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0];

/// Bin entries between a prefetch and its use.
const PREFETCH_AHEAD: usize = 4;

#[inline(always)]
fn prefetch(t: &Tri) {
    #[cfg(target_arch = "x86_64")]
    {
        let p = t as *const Tri as *const i8;
        // SAFETY: prefetch is a hint and never faults; both addresses lie within `*t`.
        unsafe {
            std::arch::x86_64::_mm_prefetch(p, std::arch::x86_64::_MM_HINT_T0);
            std::arch::x86_64::_mm_prefetch(p.add(std::mem::size_of::<Tri>() - 1), std::arch::x86_64::_MM_HINT_T0);
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = t;
}

/// Max depth of a tile buffer (for the early-z reject).
#[inline(always)]
fn tile_max(depth: &[f32]) -> f32 {
    let mut m = [0f32; 8];
    for c in depth.chunks_exact(8) {
        for k in 0..8 {
            // Compare + select, not f32::max (no NaN handling needed: depths are never NaN).
            m[k] = if c[k] > m[k] { c[k] } else { m[k] };
        }
    }
    m.iter().fold(0f32, |a, &b| a.max(b))
}

/// Rasterizes every binned triangle of tile `tile` (origin `tx0, ty0`) into `buf`.
#[inline(always)]
fn raster_tile_impl<const IDS: bool, const PEEL: bool, const COUNT: bool, const AVX2: bool>(
    binned: &Binned,
    handles: bool,
    tile: usize,
    tx0: u32,
    ty0: u32,
    buf: &mut TileBuf,
) {
    let mut zmax = if COUNT { f32::INFINITY } else { tile_max(&buf.depth) };
    let thr_min = if PEEL { buf.thr.iter().fold(f32::INFINITY, |m, &v| if v < m { v } else { m }) } else { 0.0 };
    let mut since = 0u32;
    for (ci, chunk) in binned.chunks.iter().enumerate() {
        let bin = chunk.bin(tile);
        for (j, &li) in bin.iter().enumerate() {
            // The set-up triangles of a chunk do not fit in cache; fetch a few entries ahead
            // (a Tri spans two cache lines).
            if let Some(&ahead) = bin.get(j + PREFETCH_AHEAD) {
                prefetch(&chunk.tris[ahead as usize]);
            }
            let t = &chunk.tris[li as usize];
            // Early-z: the whole triangle is at or behind everything stored in this tile.
            if !COUNT && t.zmin >= zmax {
                continue;
            }
            // Peeling: the whole triangle is at or in front of the previous layer everywhere.
            if PEEL && t.zmax <= thr_min {
                continue;
            }
            // Id written per pixel: the instance id directly, or (for colour) a handle to the
            // triangle's compact per-chunk colour/instance entry, resolved at write-back.
            let id = if handles { ((ci as u32) << 16) | li as u32 } else { t.inst };
            raster_tri::<IDS, PEEL, COUNT, AVX2>(t, id, tx0, ty0, buf);
            since += 1;
            if !COUNT && since >= ZMAX_REFRESH {
                since = 0;
                zmax = tile_max(&buf.depth);
            }
        }
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn raster_tile_avx2<const IDS: bool, const PEEL: bool, const COUNT: bool>(
    binned: &Binned,
    handles: bool,
    tile: usize,
    tx0: u32,
    ty0: u32,
    buf: &mut TileBuf,
) {
    raster_tile_impl::<IDS, PEEL, COUNT, true>(binned, handles, tile, tx0, ty0, buf)
}

fn raster_tile_generic<const IDS: bool, const PEEL: bool, const COUNT: bool>(
    binned: &Binned,
    handles: bool,
    tile: usize,
    tx0: u32,
    ty0: u32,
    buf: &mut TileBuf,
) {
    raster_tile_impl::<IDS, PEEL, COUNT, false>(binned, handles, tile, tx0, ty0, buf)
}

fn raster_tile_dispatch<const IDS: bool, const PEEL: bool, const COUNT: bool>(
    avx2: bool,
    binned: &Binned,
    handles: bool,
    tile: usize,
    tx0: u32,
    ty0: u32,
    buf: &mut TileBuf,
) {
    #[cfg(target_arch = "x86_64")]
    if avx2 {
        // SAFETY: only taken when the CPU reports AVX2 (checked by `has_avx2`).
        unsafe { raster_tile_avx2::<IDS, PEEL, COUNT>(binned, handles, tile, tx0, ty0, buf) };
        return;
    }
    let _ = avx2;
    raster_tile_generic::<IDS, PEEL, COUNT>(binned, handles, tile, tx0, ty0, buf)
}

/// Output buffers of one pass. `depth` is both input (when `load`) and output.
pub(crate) struct Targets<'a> {
    pub depth: &'a mut Image<f32>,
    /// Item buffer (instance ids). Written where a fragment won; elsewhere kept (load) or NO_ITEM.
    pub items: Option<&'a mut Image<u32>>,
    /// Visibility buffer for the colour resolve (`shade.rs`): the triangle handle
    /// (`chunk << 16 | index`, see [`Binned::meta`]) where a fragment won; elsewhere kept
    /// (load) or [`NO_ITEM`].
    pub handles: Option<&'a mut Image<u32>>,
    /// Peeling threshold (stored depth); fragments must be strictly behind it.
    pub threshold: Option<&'a Image<f32>>,
    /// Start from the current contents of `depth` (and keep `items`/`color` where nothing is
    /// drawn) instead of clearing to empty.
    pub load: bool,
}

/// Runs one raster pass of `binned` into `targets` with `mode`. Sizes are checked by callers.
pub(crate) fn run_pass(binned: &Binned, mode: Mode, targets: Targets) {
    let vp = binned.vp;
    let (w, h) = (vp.width as usize, vp.height as usize);
    let tiles_x = vp.tiles_x();
    let avx2 = has_avx2();
    let want_ids = targets.items.is_some() || targets.handles.is_some() || mode == Mode::Count;
    let handles = targets.handles.is_some();
    let band = w * TILE_H;
    let load = targets.load;
    let thr_img = targets.threshold;
    let mut items_bands: Vec<Option<&mut [u32]>> = match targets.items {
        Some(it) => it.data_mut().chunks_mut(band).map(Some).collect(),
        None => (0..vp.tiles_y()).map(|_| None).collect(),
    };
    let mut handle_bands: Vec<Option<&mut [u32]>> = match targets.handles {
        Some(c) => c.data_mut().chunks_mut(band).map(Some).collect(),
        None => (0..vp.tiles_y()).map(|_| None).collect(),
    };
    targets
        .depth
        .data_mut()
        .par_chunks_mut(band)
        .zip(items_bands.par_iter_mut())
        .zip(handle_bands.par_iter_mut())
        .enumerate()
        .for_each(|(ty, ((dband, iband), cband))| {
            let mut buf = TileBuf {
                depth: vec![1.0; TILE_PIX],
                ids: vec![NO_ITEM; TILE_PIX],
                thr: vec![f32::INFINITY; TILE_PIX],
            };
            let ty0 = ty * TILE_H;
            let rows = (h - ty0).min(TILE_H);
            for tx in 0..tiles_x {
                let tx0 = tx * TILE_W;
                let cols = (w - tx0).min(TILE_W);
                // Initialize the tile.
                if mode == Mode::Count {
                    buf.ids.fill(0);
                } else {
                    buf.depth.fill(1.0);
                    if want_ids {
                        buf.ids.fill(NO_ITEM);
                    }
                    if load {
                        for r in 0..rows {
                            buf.depth[r * TILE_W..r * TILE_W + cols]
                                .copy_from_slice(&dband[r * w + tx0..r * w + tx0 + cols]);
                        }
                    }
                    if let Some(th) = thr_img {
                        buf.thr.fill(f32::INFINITY);
                        for r in 0..rows {
                            let gy = ty0 + r;
                            buf.thr[r * TILE_W..r * TILE_W + cols]
                                .copy_from_slice(&th.data()[gy * w + tx0..gy * w + tx0 + cols]);
                        }
                    }
                }
                let tile = ty * tiles_x + tx;
                let (x0, y0) = (tx0 as u32, ty0 as u32);
                match (mode, want_ids) {
                    (Mode::Count, _) => {
                        raster_tile_dispatch::<true, false, true>(avx2, binned, handles, tile, x0, y0, &mut buf)
                    }
                    (Mode::Depth, false) => {
                        raster_tile_dispatch::<false, false, false>(avx2, binned, handles, tile, x0, y0, &mut buf)
                    }
                    (Mode::Depth, true) => {
                        raster_tile_dispatch::<true, false, false>(avx2, binned, handles, tile, x0, y0, &mut buf)
                    }
                    (Mode::Peel, false) => {
                        raster_tile_dispatch::<false, true, false>(avx2, binned, handles, tile, x0, y0, &mut buf)
                    }
                    (Mode::Peel, true) => {
                        raster_tile_dispatch::<true, true, false>(avx2, binned, handles, tile, x0, y0, &mut buf)
                    }
                }
                // Write back.
                for r in 0..rows {
                    let (o, s) = (r * w + tx0, r * TILE_W);
                    if mode != Mode::Count {
                        dband[o..o + cols].copy_from_slice(&buf.depth[s..s + cols]);
                    }
                    if mode != Mode::Count && !load {
                        // Every pixel takes the tile's value (ids as they are, or no item):
                        // plain copies, the common case of a fresh render.
                        if let Some(ib) = iband.as_deref_mut() {
                            if handles {
                                for (o, &hnd) in ib[o..o + cols].iter_mut().zip(&buf.ids[s..s + cols]) {
                                    *o = if hnd != NO_ITEM { binned.meta(hnd).0 } else { NO_ITEM };
                                }
                            } else {
                                ib[o..o + cols].copy_from_slice(&buf.ids[s..s + cols]);
                            }
                        }
                        if let Some(hb) = cband.as_deref_mut() {
                            hb[o..o + cols].copy_from_slice(&buf.ids[s..s + cols]);
                        }
                        continue;
                    }
                    if let Some(ib) = iband.as_deref_mut() {
                        for c in 0..cols {
                            let hnd = buf.ids[s + c];
                            if mode == Mode::Count {
                                ib[o + c] = hnd;
                            } else if hnd != NO_ITEM {
                                ib[o + c] = if handles { binned.meta(hnd).0 } else { hnd };
                            } else if !load {
                                ib[o + c] = NO_ITEM;
                            }
                        }
                    }
                    if let Some(hb) = cband.as_deref_mut() {
                        for c in 0..cols {
                            let hnd = buf.ids[s + c];
                            if hnd != NO_ITEM || !load {
                                hb[o + c] = hnd;
                            }
                        }
                    }
                }
            }
        });
}
