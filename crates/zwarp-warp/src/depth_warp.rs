//! Single- and multi-layer backward depth warping (seed 000 Sec. 3.2-3.4, Fig. 3-6).
//!
//! For every target pixel and every layer: tighten the search bound in that layer's motion
//! mipmap (skipping the layer at once when its region holds no valid sample — hidden layers are
//! mostly empty), place seeds, run [`fixed_point_search`], and keep the candidate of minimal
//! target depth over all layers. Layers are the peeled depth layers of the source view, nearest
//! first; the ground / background is best passed as a separate **last** layer (Sec. 3.4: it
//! widens the connected search area at negligible cost).
//!
//! Cross-layer seeding (Fig. 6), when [`WarpParams::cross_layer`] is set: when an iterate of
//! layer k lands on an empty texel, the walk borrows the sample of the nearest non-empty layer
//! above (towards the camera) at the same position; landing in empty space a second time makes
//! the seed non-convergent. In addition, the converged position of an earlier layer seeds the
//! search of the later ones (it replaces the last stratified seed when it lies in the region).
//!
//! Pruning: once a layer converged, a later layer is searched only if the min-depth mipmap says
//! some sample of its search region is nearer than the best candidate (exact for the layer's
//! own samples; a later layer's cross-layer borrowing from earlier layers is then skipped too,
//! which only drops duplicates of what those layers' own searches could find).

use glam::Vec2;
use rayon::prelude::*;
use std::mem::MaybeUninit;
use zwarp_core::{Error, Image, Motion, Result, EMPTY_DEPTH};

use crate::bounds::{pca_frame_by, Bound, BoundFrame, MotionPyramid, TightBound};
use crate::holes::{awoc_depth, fill_holes, FillRule, HolePolicy};
use crate::search::{
    effective_seeds, fixed_point_search, seed_key, stratified_seeds, LayerSampler, MotionSource, Sample, SeedStrategy,
};
use crate::{BoundKind, PixelState, SourcePos, WarpOutput, WarpParams, MAX_SEEDS};

/// One peeled source layer: its depth buffer (`1.0` = empty) and motion buffer (motion to the
/// target and target depth per pixel, e.g. from `zwarp_core::motion_field`).
#[derive(Clone, Copy, Debug)]
pub struct WarpLayer<'a> {
    /// Source depth of the layer (`[0, 1]`, 1 = no surface).
    pub depth: &'a Image<f32>,
    /// Motion of the layer's samples to the target view.
    pub motion: &'a Image<Motion>,
}

/// A layer ready to be warped: validated samples (empty ones marked with an infinite target
/// depth) and the min-max motion mipmap in the frame chosen for the bound kind. Build once per
/// source/target pair and reuse across calls with different N, T, hole policies.
pub struct PreparedLayer {
    w: u32,
    h: u32,
    samples: Vec<Motion>,
    pyramid: MotionPyramid,
    bound: BoundKind,
}

impl PreparedLayer {
    /// Validates `layer` (non-zero size, equal sizes, no NaN/infinite depth, no NaN motion) and
    /// builds its mipmap for `bound` (Oriented: AAB or PCA frame, whichever global bound is
    /// smaller). A sample is valid iff its source depth is `< 1` and its target depth is in
    /// `[0, 1)` (see [`crate::bounds`]).
    pub fn new(layer: &WarpLayer<'_>, bound: BoundKind) -> Result<Self> {
        Self::prepare(layer, &[], bound, Spare::default())
    }

    /// Prepares a stack of layers (nearest first). Like [`PreparedLayer::new`] per layer, except
    /// that the mipmap of layer `k > 0` leaves out samples that repeat an earlier layer's sample
    /// at the same pixel (same source depth): a separately rendered ground layer (Sec. 3.4)
    /// repeats every ground pixel that layer 0 already shows. Those samples stay in the layer
    /// (walks may cross them) but no longer widen its bounds or stop the pruning, so the later
    /// layer is searched only where it holds something new — the hidden ground. Any solution on
    /// a repeated sample is also a solution of the earlier layer, which searches it itself.
    pub fn prepare_stack(layers: &[WarpLayer<'_>], bound: BoundKind) -> Result<Vec<Self>> {
        Self::prepare_stack_recycling(layers, bound, Vec::new())
    }

    /// [`Self::prepare_stack`] into the buffers of `recycled` (an earlier frame's stack, layer
    /// k's buffers for layer k): an engine's steady state. The result is the same bit for bit;
    /// what it saves is the kernel faulting in and zeroing fresh pages for the samples and the
    /// level-1 mipmap every frame, which profiled at a fifth of a multisampled preparation
    /// (`WarpParams::multisample`: m^2 times the samples). Buffers too small for this frame's
    /// layers are replaced.
    pub fn prepare_stack_recycling(
        layers: &[WarpLayer<'_>],
        bound: BoundKind,
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
            out.push(Self::prepare(layer, &earlier, bound, spares.next().unwrap_or_default())?);
        }
        Ok(out)
    }

    /// Validation, sample copy and mipmap of one layer in ONE pass over its buffers (Sec. 3.3).
    /// Per pair of rows: check for NaN, write the validated samples (empty ones with an
    /// infinite depth, as [`validated_samples`]) and reduce the mipmap's level 1 over the
    /// samples that do not repeat an `earlier` layer, in the axis-aligned frame and, when the
    /// PCA frame is a candidate, in that frame too; the global bounds of both then come from
    /// the level-1 texels and pick the frame ([`crate::BoundKind::Oriented`]). Bit for bit the
    /// samples, frame and mipmap of separate passes (min / max are exact), at a fraction of the
    /// memory traffic: the separate passes read the motion buffer five times and allocated
    /// three copies of it (their page faults were a visible part of the preparation).
    fn prepare(layer: &WarpLayer<'_>, earlier: &[&[f32]], bound: BoundKind, spare: Spare) -> Result<Self> {
        layer.depth.check_nonempty("layer depth")?;
        layer.depth.check_same_size(layer.motion, "layer depth vs motion")?;
        let (w, h) = layer.depth.size();
        let (depth, motion) = (layer.depth.data(), layer.motion.data());
        let valid = |i: usize| {
            let (d, m) = (depth[i], &motion[i]);
            d < EMPTY_DEPTH && m.depth >= 0.0 && m.depth < 1.0 && m.v.is_finite()
        };
        // A sample enters the mipmap if valid and not a repeat of an earlier layer's sample.
        let fresh = |i: usize| valid(i) && !earlier.iter().any(|e| e[i] == depth[i]);
        let ob = match bound {
            BoundKind::Oriented => pca_frame_by(w, h, 64, |i| fresh(i).then_some(motion[i].v)),
            BoundKind::Global | BoundKind::Tight => BoundFrame::IDENTITY,
        };
        let need_ob = !ob.is_identity();
        let (wu, lw, lh) = (w as usize, w.div_ceil(2) as usize, h.div_ceil(2) as usize);
        // Huge-page backed buffers (`pages`), or the recycled ones: the samples are written
        // below, every one, and so is every level-1 texel (each row starts with a fill).
        let n = wu * h as usize;
        let mut samples = spare.samples;
        if samples.capacity() >= n {
            samples.clear();
        } else {
            samples = crate::pages::uninit::<Motion>(n);
        }
        let empty = Bound::EMPTY.to_texel_pub();
        let reuse = |mut v: Vec<[f32; 4]>| {
            if v.len() >= lw * lh {
                v.truncate(lw * lh);
                v
            } else {
                crate::pages::filled(lw * lh, empty)
            }
        };
        let mut aab = reuse(spare.level1);
        let mut obd = if need_ob { crate::pages::filled(lw * lh, empty) } else { Vec::new() };
        let mut zmin = spare.zmin;
        zmin.resize(lw * lh, 0.0);
        // One level-1 row (two image rows): returns error flags (1: bad depth, 2: NaN motion).
        let row = |ty: usize,
                   s: &mut [MaybeUninit<Motion>],
                   a: &mut [[f32; 4]],
                   mut o: Option<&mut [[f32; 4]]>,
                   z: &mut [f32]| {
            let mut flags = 0u8;
            a.fill(Bound::EMPTY.to_texel_pub());
            if let Some(o) = o.as_deref_mut() {
                o.fill(Bound::EMPTY.to_texel_pub());
            }
            z.fill(f32::INFINITY);
            for (dy, srow) in s.chunks_mut(wu).enumerate() {
                let base = (2 * ty + dy) * wu;
                for (x, out) in srow.iter_mut().enumerate() {
                    let i = base + x;
                    let (d, m) = (depth[i], motion[i]);
                    flags |= (!d.is_finite()) as u8 | ((m.v.is_nan() || m.depth.is_nan()) as u8) << 1;
                    if !valid(i) {
                        out.write(Motion { v: Vec2::ZERO, depth: f32::INFINITY });
                        continue;
                    }
                    out.write(m);
                    if earlier.iter().any(|e| e[i] == d) {
                        continue;
                    }
                    let t = &mut a[x >> 1];
                    *t = [t[0].min(m.v.x), t[1].min(m.v.y), t[2].max(m.v.x), t[3].max(m.v.y)];
                    if let Some(o) = o.as_deref_mut() {
                        let u = ob.to_frame(m.v);
                        let t = &mut o[x >> 1];
                        *t = [t[0].min(u.x), t[1].min(u.y), t[2].max(u.x), t[3].max(u.y)];
                    }
                    z[x >> 1] = z[x >> 1].min(m.depth);
                }
            }
            flags
        };
        let flags = if need_ob {
            samples.spare_capacity_mut()[..n]
                .par_chunks_mut(2 * wu)
                .zip(aab.par_chunks_mut(lw))
                .zip(obd.par_chunks_mut(lw))
                .zip(zmin.par_chunks_mut(lw))
                .enumerate()
                .map(|(ty, (((s, a), o), z))| row(ty, s, a, Some(o), z))
                .reduce(|| 0, |a, b| a | b)
        } else {
            samples.spare_capacity_mut()[..n]
                .par_chunks_mut(2 * wu)
                .zip(aab.par_chunks_mut(lw))
                .zip(zmin.par_chunks_mut(lw))
                .enumerate()
                .map(|(ty, ((s, a), z))| row(ty, s, a, None, z))
                .reduce(|| 0, |a, b| a | b)
        };
        // SAFETY: the pass above wrote every one of the `n` samples (each row writes every
        // pixel, valid or not, and the chunks cover `0..n`).
        unsafe { samples.set_len(n) };
        if flags & 1 != 0 {
            return Err(Error::invalid("layer depth holds NaN or infinite values"));
        }
        if flags & 2 != 0 {
            return Err(Error::invalid("motion buffer holds NaN values"));
        }
        // Oriented: the PCA frame if its global bound has the smaller (ex + 1)(ey + 1)
        // (`choose_frame`), the global bounds being the union of the level-1 texels.
        let global = |d: &[[f32; 4]]| {
            d.par_iter()
                .map(|t| Bound { lo: Vec2::new(t[0], t[1]), hi: Vec2::new(t[2], t[3]) })
                .reduce(|| Bound::EMPTY, |a, b| a.union(&b))
        };
        let use_ob = need_ob && global(&obd).pixel_area() < global(&aab).pixel_area();
        let pyramid = if use_ob {
            MotionPyramid::from_level1(w, h, ob, obd, zmin)
        } else {
            MotionPyramid::from_level1(w, h, BoundFrame::IDENTITY, aab, zmin)
        };
        Ok(PreparedLayer { w, h, samples, pyramid, bound })
    }

    /// Image size.
    pub fn size(&self) -> (u32, u32) {
        (self.w, self.h)
    }

    /// The large buffers, for [`Self::prepare_stack_recycling`].
    fn into_spare(self) -> Spare {
        let (level1, zmin) = self.pyramid.into_level1();
        Spare { samples: self.samples, level1, zmin }
    }
    /// The layer's motion mipmap.
    pub fn pyramid(&self) -> &MotionPyramid {
        &self.pyramid
    }
    /// The bound kind the mipmap was built for.
    pub fn bound_kind(&self) -> BoundKind {
        self.bound
    }
    /// Validated samples (empty ones have an infinite depth).
    pub fn samples(&self) -> &[Motion] {
        &self.samples
    }
    fn sampler(&self, params: &WarpParams, tag: u32) -> LayerSampler<'_> {
        LayerSampler::new(&self.samples, self.w, self.h, params.sampling, tag).with_scale(params.motion_scale)
    }
}

/// Buffers of an earlier preparation handed back for reuse (empty: allocate).
#[derive(Default)]
struct Spare {
    samples: Vec<Motion>,
    level1: Vec<[f32; 4]>,
    zmin: Vec<f32>,
}

/// Validates a layer and returns its samples with empty ones (source depth `>= 1`, target
/// depth outside `[0, 1)`, infinite motion) marked by an infinite target depth.
pub(crate) fn validated_samples(layer: &WarpLayer<'_>) -> Result<Vec<Motion>> {
    layer.depth.check_nonempty("layer depth")?;
    layer.depth.check_same_size(layer.motion, "layer depth vs motion")?;
    // Parallel scans: at 1080p each is a 2-8 MB pass that showed up in the prepare time.
    if layer.depth.data().par_iter().any(|d| !d.is_finite()) {
        return Err(Error::invalid("layer depth holds NaN or infinite values"));
    }
    if layer.motion.data().par_iter().any(|m| m.v.is_nan() || m.depth.is_nan()) {
        return Err(Error::invalid("motion buffer holds NaN values"));
    }
    Ok(layer
        .depth
        .data()
        .par_iter()
        .zip(layer.motion.data().par_iter())
        .map(|(&d, m)| {
            if d < EMPTY_DEPTH && m.depth >= 0.0 && m.depth < 1.0 && m.v.is_finite() {
                *m
            } else {
                Motion { v: Vec2::ZERO, depth: f32::INFINITY }
            }
        })
        .collect())
}

/// Samples layer k with the cross-layer fallback of Fig. 6.
struct StackSampler<'a> {
    layers: &'a [LayerSampler<'a>],
    k: usize,
    cross: bool,
}

impl MotionSource for StackSampler<'_> {
    /// Number of empty landings so far.
    type Walk = u8;
    #[inline(always)]
    fn sample(&self, q: Vec2, empties: &mut u8) -> Option<Sample> {
        let own = &self.layers[self.k];
        if !own.inside(q) {
            return None;
        }
        if let Some(s) = own.fetch_inside(q) {
            return Some(s);
        }
        if !self.cross || self.k == 0 {
            return None;
        }
        *empties += 1;
        if *empties >= 2 {
            return None;
        }
        self.layers[..self.k].iter().rev().find_map(|l| l.fetch(q))
    }
}

/// Backward depth warp of `layers` (nearest first, ground last if separate) to the target view
/// the motion buffers point to. Single-layer warping is `layers.len() == 1`.
///
/// Errors ([`Error::Invalid`]): empty layer list, zero-size or mismatched buffers, NaN depth or
/// motion, invalid parameters.
pub fn warp_depth(layers: &[WarpLayer<'_>], params: &WarpParams) -> Result<WarpOutput> {
    params.validate()?;
    if layers.is_empty() {
        return Err(Error::invalid("warp_depth needs at least one layer"));
    }
    let prepared = PreparedLayer::prepare_stack(layers, params.bound)?;
    warp_prepared(&prepared, params)
}

/// [`warp_depth`] on layers prepared once ([`PreparedLayer::prepare_stack`], or
/// [`PreparedLayer::new`] per layer). The bound *frame* (AAB or
/// OB) is fixed when a layer is prepared; `params.bound == Global` disables the per-pixel
/// tightening, any other kind tightens in the prepared frame.
pub fn warp_prepared(layers: &[PreparedLayer], params: &WarpParams) -> Result<WarpOutput> {
    params.validate()?;
    let first = layers.first().ok_or_else(|| Error::invalid("warp_depth needs at least one layer"))?;
    let (w, h) = first.size();
    if let Some((i, l)) = layers.iter().enumerate().find(|(_, l)| l.size() != (w, h)) {
        return Err(Error::invalid(format!("layer {i} is {}x{} but layer 0 is {w}x{h}", l.size().0, l.size().1)));
    }
    if layers.len() > u32::MAX as usize - 1 {
        return Err(Error::invalid("too many layers"));
    }
    check_motion_scale(layers, params)?;
    let (tw, th) = target_size(w, h, params.multisample)?;
    let samplers: Vec<LayerSampler<'_>> = layers.iter().enumerate().map(|(i, l)| l.sampler(params, i as u32)).collect();
    let kernel = Kernel::new(layers, &samplers, params, (w, h), (tw, th));
    let (w, h) = (tw, th);

    let n = w as usize * h as usize;
    let mut depth = crate::pages::filled(n, EMPTY_DEPTH);
    let mut state = crate::pages::filled(n, PixelState::Hole);
    let mut source = if params.record_source { vec![SourcePos::default(); n] } else { Vec::new() };
    // Bands of TILE rows: tiles of TILE x TILE pixels share a first tightening stage.
    let band = (w * TILE) as usize;
    if params.record_source {
        depth
            .par_chunks_mut(band)
            .zip(state.par_chunks_mut(band))
            .zip(source.par_chunks_mut(band))
            .enumerate()
            .for_each(|(ty, ((d, s), src))| kernel.band(ty as u32, d, s, Some(src)));
    } else {
        depth
            .par_chunks_mut(band)
            .zip(state.par_chunks_mut(band))
            .enumerate()
            .for_each(|(ty, (d, s))| kernel.band(ty as u32, d, s, None));
    }
    let mut depth = Image::from_vec(w, h, depth)?;
    let mut state = Image::from_vec(w, h, state)?;
    match params.holes {
        HolePolicy::Dilate { radius } => fill_holes(&mut depth, &mut state, radius, FillRule::Nearest),
        HolePolicy::Background { radius } => fill_holes(&mut depth, &mut state, radius, FillRule::Background),
        HolePolicy::FarDepth | HolePolicy::Awoc => {}
    }
    let source = if params.record_source { Some(Image::from_vec(w, h, source)?) } else { None };
    Ok(WarpOutput { depth, state, source })
}

/// The warp of exactly the listed target pixels (row-major indices `y * w + x`): for each one
/// the `(depth, state)` that [`warp_prepared`] writes there, bit for bit (seed 000 Sec. 3 per
/// pixel, with the same 4x4 tile-bound stage of Sec. 3.3 / Fig. 5: the tile bound of each
/// pixel's tile is computed, and reused while consecutive listed pixels share a tile). For
/// sparse consumers (soft shadows warp only the receivers' pixels). Parallel over chunks of
/// the list; output order = input order. Pixels may repeat.
///
/// Errors ([`Error::Invalid`]): everything [`warp_prepared`] rejects, a pixel index `>= w * h`,
/// and [`HolePolicy::Dilate`] / [`HolePolicy::Background`] (they fill a hole from its converged
/// neighbours, which a sparse warp does not compute).
pub fn warp_pixels(layers: &[PreparedLayer], params: &WarpParams, pixels: &[u32]) -> Result<Vec<(f32, PixelState)>> {
    params.validate()?;
    if let HolePolicy::Dilate { .. } | HolePolicy::Background { .. } = params.holes {
        return Err(Error::invalid(
            "warp_pixels does not support HolePolicy::Dilate/Background (they need the neighbouring pixels)",
        ));
    }
    let first = layers.first().ok_or_else(|| Error::invalid("warp_pixels needs at least one layer"))?;
    let (w, h) = first.size();
    if let Some((i, l)) = layers.iter().enumerate().find(|(_, l)| l.size() != (w, h)) {
        return Err(Error::invalid(format!("layer {i} is {}x{} but layer 0 is {w}x{h}", l.size().0, l.size().1)));
    }
    check_motion_scale(layers, params)?;
    let (tw, th) = target_size(w, h, params.multisample)?;
    let n = tw as u64 * th as u64;
    if let Some(&bad) = pixels.iter().find(|&&i| i as u64 >= n) {
        return Err(Error::invalid(format!("pixel index {bad} is outside the {tw}x{th} image")));
    }
    let samplers: Vec<LayerSampler<'_>> = layers.iter().enumerate().map(|(i, l)| l.sampler(params, i as u32)).collect();
    let kernel = Kernel::new(layers, &samplers, params, (w, h), (tw, th));
    let w = tw;
    // Chunks of a few tiles' worth of pixels: large enough to amortise the tile stage when the
    // list is sorted, small enough to balance sparse, unevenly costly lists.
    const CHUNK: usize = 256;
    Ok(pixels
        .par_chunks(CHUNK)
        .flat_map_iter(|chunk| {
            let mut tile: Option<(u32, u32)> = None;
            let mut tile_bounds: Vec<Option<TileBound>> = vec![None; layers.len()];
            let mut seeds = [Vec2::ZERO; MAX_SEEDS as usize];
            chunk
                .iter()
                .map(|&i| {
                    let (x, y) = (i % w, i / w);
                    let t = (x / TILE, y / TILE);
                    if tile != Some(t) {
                        kernel.tile_bounds(t.0 * TILE, t.1 * TILE, &mut tile_bounds);
                        tile = Some(t);
                    }
                    let (z, st, _) = kernel.pixel(x, y, &tile_bounds, &mut seeds);
                    (z, st)
                })
                .collect::<Vec<_>>()
        })
        .collect())
}

/// The target image of a warp from `w x h` source layers with [`WarpParams::multisample`] = `m`:
/// `(w / m, h / m)`; the source must hold exactly `m x m` samples per target pixel, else a
/// one-line [`Error::Invalid`]. The one rule of both twins (the WGSL warp's host code calls it).
pub fn target_size(w: u32, h: u32, m: u32) -> Result<(u32, u32)> {
    if m == 0 || !w.is_multiple_of(m) || !h.is_multiple_of(m) {
        return Err(Error::invalid(format!(
            "multisample {m}: the {w}x{h} source layers must hold {m}x{m} samples per target pixel (sizes divisible by {m})"
        )));
    }
    Ok((w / m, h / m))
}

/// A non-uniform [`WarpParams::motion_scale`] does not commute with the rotation of an
/// oriented bound frame, so the prepared mipmap would not bound the scaled motion.
fn check_motion_scale(layers: &[PreparedLayer], params: &WarpParams) -> Result<()> {
    let s = params.motion_scale;
    if s.x != s.y {
        if let Some(k) = layers.iter().position(|l| !l.pyramid.frame().is_identity()) {
            return Err(Error::invalid(format!(
                "non-uniform motion_scale {s} needs axis-aligned bounds, but layer {k} has an oriented frame (use BoundKind::Tight)"
            )));
        }
    }
    Ok(())
}

/// The first-stage bound of one 4x4 tile and layer: the motion bound every pixel of the tile
/// starts its own tightening from, and (layers after the first) the min target depth over the
/// tile's search region (`-inf` for layer 0, where it is not used).
#[derive(Clone, Copy, Debug)]
struct TileBound {
    motion: Bound,
    min_depth: f32,
}

struct Kernel<'a> {
    layers: &'a [PreparedLayer],
    samplers: &'a [LayerSampler<'a>],
    params: &'a WarpParams,
    /// Source layer size (the space of `q`, the motion and the mipmaps).
    w: u32,
    h: u32,
    /// Target image size: the source size divided by [`WarpParams::multisample`].
    tw: u32,
    th: u32,
    /// Source samples per target pixel and axis, as a float: target pixel `(x, y)` is the
    /// source position `m * (x + 0.5, y + 0.5)` (exact for `m = 1`).
    m: f32,
}

/// Tile size of the two-stage bound tightening (pixels per side).
const TILE: u32 = 4;

impl<'a> Kernel<'a> {
    fn new(
        layers: &'a [PreparedLayer],
        samplers: &'a [LayerSampler<'a>],
        params: &'a WarpParams,
        (w, h): (u32, u32),
        (tw, th): (u32, u32),
    ) -> Self {
        Kernel { layers, samplers, params, w, h, tw, th, m: params.multisample as f32 }
    }

    /// The source position of target pixel `(x, y)`'s centre.
    #[inline(always)]
    fn target_pos(&self, x: u32, y: u32) -> Vec2 {
        Vec2::new(x as f32 + 0.5, y as f32 + 0.5) * self.m
    }

    /// Number of tightening steps (0 for the global bound).
    fn bound_iterations(&self) -> u32 {
        if self.params.bound == BoundKind::Global {
            0
        } else {
            self.params.bound_iterations
        }
    }

    /// The first tightening stage (Fig. 5 on the union of the tile's search regions) of every
    /// layer for the tile whose top-left pixel is `(x0, y0)`, clipped to the image.
    fn tile_bounds(&self, x0: u32, y0: u32, out: &mut [Option<TileBound>]) {
        let x1 = (x0 + TILE).min(self.tw) - 1;
        let y1 = (y0 + TILE).min(self.th) - 1;
        let (p_lo, p_hi) = (self.target_pos(x0, y0), self.target_pos(x1, y1));
        let iters = self.bound_iterations();
        let expand = self.params.sampling.footprint();
        let scale = self.params.motion_scale;
        for (k, (tb, layer)) in out.iter_mut().zip(self.layers).enumerate() {
            let pyr = &layer.pyramid;
            let start = pyr.global().scaled(scale);
            // Layers after the first also get the min depth over the tile's search region: a
            // pixel whose best candidate is not farther skips the layer without tightening.
            *tb = if k == 0 {
                pyr.tight_bound_box_scaled(p_lo, p_hi, start, iters, expand, scale)
            } else {
                pyr.tight_bound_box_with_depth_scaled(p_lo, p_hi, start, iters, expand, scale)
            }
            .map(|t| TileBound { motion: t.motion, min_depth: t.min_depth });
        }
    }

    /// Warps the band of rows `ty * TILE ..`: per TILE x TILE tile, tighten the bound of every
    /// layer once for the whole tile (Fig. 5 on the union of the tile's search regions), then
    /// warp each pixel starting its own tightening from the tile's bound. Same per-pixel bounds
    /// (see [`MotionPyramid::tight_bound_box`]), a fraction of the look-ups; layers whose tile
    /// region holds no valid sample are skipped for all 16 pixels at once.
    fn band(&self, ty: u32, depth: &mut [f32], state: &mut [PixelState], mut source: Option<&mut [SourcePos]>) {
        let w = self.tw as usize;
        let rows = (depth.len() / w) as u32;
        let y0 = ty * TILE;
        let mut tile_bounds: Vec<Option<TileBound>> = vec![None; self.layers.len()];
        let mut seeds = [Vec2::ZERO; MAX_SEEDS as usize];
        for x0 in (0..self.tw).step_by(TILE as usize) {
            let x1 = (x0 + TILE).min(self.tw) - 1;
            let y1 = y0 + rows - 1;
            self.tile_bounds(x0, y0, &mut tile_bounds);
            for y in y0..=y1 {
                for x in x0..=x1 {
                    let (z, st, src) = self.pixel(x, y, &tile_bounds, &mut seeds);
                    crate::stats::count(crate::stats::Counter::Pixels, 1);
                    let i = (y - y0) as usize * w + x as usize;
                    depth[i] = z;
                    state[i] = st;
                    if let Some(s) = source.as_deref_mut() {
                        s[i] = src;
                    }
                }
            }
        }
    }

    /// The warp of one target pixel over all layers.
    #[inline]
    ///
    /// `seeds` is scratch space owned by the caller: zeroing a 64-seed stack array per pixel
    /// (512 bytes) was a measurable part of the per-pixel cost.
    fn pixel(
        &self,
        x: u32,
        y: u32,
        tile_bounds: &[Option<TileBound>],
        seeds: &mut [Vec2; MAX_SEEDS as usize],
    ) -> (f32, PixelState, SourcePos) {
        let params = self.params;
        let p = self.target_pos(x, y);
        let expand = params.sampling.footprint();
        let scale = params.motion_scale;
        let search = params.search();
        let max_q = Vec2::new(self.w as f32, self.h as f32) * (1.0 - f32::EPSILON) - Vec2::splat(1e-3);
        let mut best: Option<crate::Candidate> = None;
        let mut prev_q: Option<Vec2> = None;
        let mut awoc: Option<(BoundFrame, TightBound)> = None;
        for (k, layer) in self.layers.iter().enumerate() {
            let pyr = &layer.pyramid;
            // No valid sample can move to p from this layer: skip it (cheap for sparse layers).
            let Some(TileBound { motion: start, min_depth: tile_min_depth }) = tile_bounds[k] else { continue };
            let e = start.extent();
            let tb = if e.x <= 1.0 && e.y <= 1.0 && best.is_none() {
                // The tile's bound is already narrower than a pixel: one seed at the centre of
                // this pixel's region whatever further tightening would give, so skip it.
                TightBound { motion: start, region: pyr.region(p, &start), min_depth: f32::NEG_INFINITY }
            } else if k > 0 && best.is_some() {
                // A later layer only matters if it can beat the best candidate so far: skip it
                // when no sample of its search region is nearer (min-depth mipmap look-up),
                // first over the whole tile's region (free: computed once per tile), then over
                // the pixel's tightened region.
                if best.is_some_and(|b| tile_min_depth >= b.depth) {
                    continue;
                }
                // The same test over this pixel's region under the tile's bound, before any
                // tightening: exact, because the tightened region lies inside it and a min-depth
                // look-up over a sub-range (at a finer or equal level, whose texels nest in the
                // coarser ones read here) is never smaller. One look-up instead of a tightening.
                let Some(r) = pyr.pixel_range(&pyr.region(p, &start), expand) else { continue };
                if best.is_some_and(|b| pyr.lookup_min_depth(r.0, r.1, r.2, r.3) >= b.depth) {
                    continue;
                }
                let Some(tb) =
                    pyr.tight_bound_box_with_depth_scaled(p, p, start, self.bound_iterations(), expand, scale)
                else {
                    continue;
                };
                if best.is_some_and(|b| tb.min_depth >= b.depth) {
                    continue;
                }
                tb
            } else {
                let Some(tb) = pyr.tight_bound_box_scaled(p, p, start, self.bound_iterations(), expand, scale) else {
                    continue;
                };
                tb
            };
            if params.holes == HolePolicy::Awoc && awoc.is_none() {
                awoc = Some((pyr.frame(), tb));
            }
            let frame = pyr.frame();
            let mut n = match params.seeding {
                SeedStrategy::Stratified => {
                    let ne = effective_seeds(params.n_seeds, tb.region.extent());
                    // The key only jitters seeds 2.. (one seed sits at the region centre).
                    let key = if ne > 1 { seed_key(x, y, k as u32) } else { 0 };
                    stratified_seeds(&frame, &tb.region, ne, key, seeds)
                }
                SeedStrategy::Pixel => {
                    seeds[0] = p;
                    1
                }
                SeedStrategy::Offset(d) => {
                    seeds[0] = p + d;
                    1
                }
            };
            if params.cross_layer {
                if let Some(q) = prev_q {
                    // Fig. 6 / brief: an earlier layer's converged position seeds this layer.
                    let u = frame.to_frame(q);
                    if tb.region.contains(u) {
                        if (n as u32) < params.n_seeds {
                            n += 1;
                        }
                        seeds[n - 1] = q;
                    }
                }
            }
            for s in &mut seeds[..n] {
                *s = s.clamp(Vec2::ZERO, max_q);
            }
            let src = StackSampler { layers: self.samplers, k, cross: params.cross_layer };
            if let Some(c) = fixed_point_search(&src, p, &seeds[..n], &search) {
                prev_q = Some(c.q);
                if best.is_none_or(|b| c.depth < b.depth) {
                    best = Some(c);
                }
            }
        }
        if let Some(c) = best {
            return (c.depth, PixelState::Converged, SourcePos { q: c.q, layer: c.tag });
        }
        if let Some((frame, tb)) = awoc {
            let r = tb.region;
            let corners = [
                Vec2::new(r.lo.x, r.lo.y),
                Vec2::new(r.hi.x, r.lo.y),
                Vec2::new(r.lo.x, r.hi.y),
                Vec2::new(r.hi.x, r.hi.y),
            ]
            .map(|u| frame.from_frame(u).clamp(Vec2::ZERO, max_q));
            let fill = awoc_depth(&corners, |q| {
                self.samplers.iter().filter_map(|s| s.fetch(q)).map(|s| s.depth).reduce(f32::min)
            });
            if let Some(z) = fill {
                return (z, PixelState::Filled, SourcePos { q: Vec2::ZERO, layer: u32::MAX });
            }
        }
        (EMPTY_DEPTH, PixelState::Hole, SourcePos { q: Vec2::ZERO, layer: u32::MAX })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layer(vals: &[(f32, f32)]) -> Vec<Motion> {
        vals.iter().map(|&(vx, d)| Motion { v: Vec2::new(vx, 0.0), depth: d }).collect()
    }

    /// The fused one-pass preparation equals the separate passes it replaced (validated
    /// samples, repeat-free copy for layers k > 0, frame choice, mipmap from samples) bit for bit:
    /// samples, frame, every texel and the min-depth look-ups, for every bound kind, on layers
    /// with empty pixels, repeated ground samples, odd sizes and diagonal motion (PCA frame).
    #[test]
    fn fused_preparation_equals_separate_passes() {
        use crate::bounds::choose_frame;
        let (w, h) = (37u32, 22u32);
        let d0 = Image::from_fn(w, h, |x, y| if (x + y) % 7 == 0 { 1.0 } else { 0.3 + 0.01 * x as f32 });
        // Layer 1 repeats layer 0's depth on a third of the pixels (a ground layer).
        let d1 = Image::from_fn(w, h, |x, y| if x % 3 == 0 { *d0.get(x, y) } else { 0.8 + 0.001 * y as f32 });
        let m = |x: u32, y: u32, d: f32| {
            let t = 0.3 * x as f32 - 0.2 * y as f32;
            Motion { v: Vec2::new(t + 0.05 * (y % 3) as f32, 0.9 * t - 2.0), depth: if x == 5 { 1.5 } else { d } }
        };
        let m0 = Image::from_fn(w, h, |x, y| m(x, y, *d0.get(x, y)));
        let m1 = Image::from_fn(w, h, |x, y| m(x, y, *d1.get(x, y)));
        let layers = [WarpLayer { depth: &d0, motion: &m0 }, WarpLayer { depth: &d1, motion: &m1 }];
        for bound in [BoundKind::Global, BoundKind::Tight, BoundKind::Oriented] {
            let fused = PreparedLayer::prepare_stack(&layers, bound).unwrap();
            for (k, got) in fused.iter().enumerate() {
                let samples = validated_samples(&layers[k]).unwrap();
                let mip: Vec<Motion> = samples
                    .iter()
                    .enumerate()
                    .map(|(i, s)| {
                        if layers[..k].iter().any(|e| e.depth.data()[i] == layers[k].depth.data()[i]) {
                            Motion { v: Vec2::ZERO, depth: f32::INFINITY }
                        } else {
                            *s
                        }
                    })
                    .collect();
                let frame = choose_frame(&mip, w, h, bound);
                if bound == BoundKind::Oriented {
                    assert!(!frame.is_identity(), "the test needs a rotated frame");
                }
                let want = MotionPyramid::from_samples(&mip, w, h, frame);
                let bits = |v: &[Motion]| {
                    v.iter().map(|m| (m.v.x.to_bits(), m.v.y.to_bits(), m.depth.to_bits())).collect::<Vec<_>>()
                };
                assert_eq!(bits(got.samples()), bits(&samples), "{bound:?} layer {k}");
                assert_eq!(got.pyramid().frame(), want.frame());
                assert_eq!(got.pyramid().top_level(), want.top_level());
                for level in 1..=want.top_level() {
                    let (lw, lh) = want.level_size(level);
                    for ty in 0..lh {
                        for tx in 0..lw {
                            assert_eq!(got.pyramid().texel(level, tx, ty), want.texel(level, tx, ty));
                        }
                    }
                }
                for (x0, y0, x1, y1) in [(0, 0, 0, 0), (3, 4, 9, 6), (0, 0, w - 1, h - 1), (30, 20, 36, 21)] {
                    assert_eq!(got.pyramid().lookup_min_depth(x0, y0, x1, y1), want.lookup_min_depth(x0, y0, x1, y1));
                }
            }
        }
    }

    /// A stack prepared into recycled buffers equals a fresh one bit for bit (samples, frame,
    /// every mipmap texel and min-depth look-up), whether the recycled buffers are larger or
    /// smaller than needed, hold stale data from another scene, or are fewer than the layers.
    #[test]
    fn recycled_preparation_equals_a_fresh_one() {
        let stack = |w: u32, h: u32, seed: u32| {
            let d: Vec<Image<f32>> = (0..3)
                .map(|k| {
                    Image::from_fn(w, h, |x, y| {
                        if (x * 7 + y * 3 + seed + k).is_multiple_of(9) {
                            1.0
                        } else {
                            0.2 + 0.2 * k as f32 + 0.001 * ((x + seed) % 13) as f32
                        }
                    })
                })
                .collect();
            let m: Vec<Image<Motion>> = d
                .iter()
                .map(|dk| {
                    Image::from_fn(w, h, |x, y| {
                        let t = 0.25 * x as f32 - 0.15 * y as f32 + seed as f32;
                        Motion { v: Vec2::new(t, 0.8 * t - 1.0), depth: *dk.get(x, y) }
                    })
                })
                .collect();
            (d, m)
        };
        let same = |a: &[PreparedLayer], b: &[PreparedLayer]| {
            assert_eq!(a.len(), b.len());
            for (x, y) in a.iter().zip(b) {
                let bits = |v: &[Motion]| {
                    v.iter().map(|m| (m.v.x.to_bits(), m.v.y.to_bits(), m.depth.to_bits())).collect::<Vec<_>>()
                };
                assert_eq!(x.size(), y.size());
                assert_eq!(bits(x.samples()), bits(y.samples()));
                let (px, py) = (x.pyramid(), y.pyramid());
                assert_eq!((px.frame(), px.top_level()), (py.frame(), py.top_level()));
                for level in 1..=px.top_level() {
                    let (lw, lh) = px.level_size(level);
                    for ty in 0..lh {
                        for tx in 0..lw {
                            assert_eq!(px.texel(level, tx, ty), py.texel(level, tx, ty));
                        }
                    }
                }
                let (w, h) = x.size();
                for (x0, y0, x1, y1) in [(0, 0, 0, 0), (1, 2, 5, 4), (0, 0, w - 1, h - 1)] {
                    assert_eq!(px.lookup_min_depth(x0, y0, x1, y1), py.lookup_min_depth(x0, y0, x1, y1));
                }
            }
        };
        let mut recycled = Vec::new();
        for (i, &(w, h, n)) in [(37u32, 22u32, 3usize), (20, 11, 3), (41, 30, 2), (41, 30, 3)].iter().enumerate() {
            let (d, m) = stack(w, h, i as u32);
            let layers: Vec<WarpLayer> =
                d.iter().zip(&m).take(n).map(|(d, m)| WarpLayer { depth: d, motion: m }).collect();
            for bound in [BoundKind::Tight, BoundKind::Oriented] {
                let fresh = PreparedLayer::prepare_stack(&layers, bound).unwrap();
                let got =
                    PreparedLayer::prepare_stack_recycling(&layers, bound, std::mem::take(&mut recycled)).unwrap();
                same(&got, &fresh);
                recycled = got;
            }
        }
    }

    /// Fig. 6: an empty landing in layer k borrows the nearest non-empty layer above; the second
    /// empty landing of the same walk fails; without cross-layer seeding the first one fails.
    #[test]
    fn cross_layer_sampling_borrows_once_then_fails() {
        let inf = f32::INFINITY;
        // 4x1 images. Layer 0 valid everywhere, layer 1 empty at x = 1 and 2, layer 2 empty at
        // x = 1 only (so layer 2 borrows from layer 1? no: layer 1 is empty there too -> layer 0).
        let l0 = layer(&[(0.0, 0.1), (1.0, 0.2), (2.0, 0.3), (3.0, 0.4)]);
        let l1 = layer(&[(0.0, 0.5), (0.0, inf), (0.0, inf), (0.0, 0.6)]);
        let l2 = layer(&[(0.0, 0.7), (0.0, inf), (0.0, 0.8), (0.0, 0.9)]);
        let s: Vec<LayerSampler> = [&l0, &l1, &l2]
            .iter()
            .enumerate()
            .map(|(i, l)| LayerSampler::new(l, 4, 1, crate::Sampling::Nearest, i as u32))
            .collect();
        let q = |x: f32| Vec2::new(x, 0.5);
        let src = StackSampler { layers: &s, k: 2, cross: true };
        let mut walk = 0u8;
        assert_eq!(src.sample(q(2.5), &mut walk).unwrap().depth, 0.8);
        let b = src.sample(q(1.5), &mut walk).unwrap();
        assert_eq!((b.depth, b.tag, walk), (0.2, 0, 1));
        assert!(src.sample(q(1.5), &mut walk).is_none(), "second empty landing fails");
        // Layer 1 at x = 2 borrows from layer 0.
        let src = StackSampler { layers: &s, k: 1, cross: true };
        assert_eq!(src.sample(q(2.5), &mut 0).unwrap().tag, 0);
        // Outside the image: no borrowing.
        assert!(src.sample(q(4.5), &mut 0).is_none());
        // Without cross-layer seeding, and on the first layer, an empty landing fails at once.
        let src = StackSampler { layers: &s, k: 2, cross: false };
        assert!(src.sample(q(1.5), &mut 0).is_none());
        let e = layer(&[(0.0, inf); 4]);
        let s0 = [LayerSampler::new(&e, 4, 1, crate::Sampling::Nearest, 0)];
        assert!(StackSampler { layers: &s0, k: 0, cross: true }.sample(q(0.5), &mut 0).is_none());
    }
}
