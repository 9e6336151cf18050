//! The per-pixel warp over all layers (seed 000 Sec. 3.2-3.4) and the tile stage of the bound
//! tightening that feeds it (Sec. 3.3, Fig. 5 applied to a box of pixels).
//!
//! **Tile stage.** Fig. 5 tightens the bound of one pixel from the global bound. Neighbouring
//! pixels share most of that work, so it runs per 4x4 *tile* of target pixels first (from the
//! global bound, over the union of the tile's search regions), and each pixel then tightens
//! from its tile's bound — or, where the tile's bound is already within one pixel in both axes
//! ("resolved") and no earlier layer converged, takes one seed at the centre of its region
//! under the tile's bound without tightening. The tile stage is conservative (a pixel's
//! solutions lie in the tile's region), so it changes no solution. A tile with no valid sample
//! in its region removes the layer for its 16 pixels. Layers `k > 0` also get the min target
//! depth over the tile's final region, the first test of their pruning.
//!
//! Tile bounds are pure functions of the tile and the layer, computed on demand ([`TileBounds`]),
//! so a dense warp, a sparse one ([`crate::warp_pixels`]) and the WGSL twin compute the same.
//!
//! **Lanes.** On AVX2 CPUs eight pixels go through the layers in lock step
//! ([`Kernel::lanes_core`], the scalar [`Kernel::pixel`]'s steps per lane): a dense warp's 4x2
//! groups share one tile's stages, a sparse warp's listed pixels each bring their own.

use glam::Vec2;
use zwarp_core::EMPTY_DEPTH;

use crate::bounds::{Bound, BoundFrame, TightBound};
use crate::holes::{awoc_depth, HolePolicy};
use crate::prepare::PreparedLayer;
use crate::sampling::{LayerSampler, MotionSource, Sample};
use crate::search::{effective_seeds, fixed_point_search_closest, seed_key, stratified_seeds, Candidate, SeedStrategy};
use crate::{BoundKind, PixelState, SourcePos, WarpParams, MAX_SEEDS};

/// The states of four pixels from four converged bits: `Converged` where set, `Hole` elsewhere.
#[cfg(target_arch = "x86_64")]
const STATE4: [[u8; 4]; 16] = {
    let mut t = [[PixelState::Hole as u8; 4]; 16];
    let mut b = 0;
    while b < 16 {
        let mut i = 0;
        while i < 4 {
            if b >> i & 1 != 0 {
                t[b][i] = PixelState::Converged as u8;
            }
            i += 1;
        }
        b += 1;
    }
    t
};

/// Side of a tile of the tile stage (target pixels).
pub const TILE: u32 = 4;

/// Smallest determinant of `I + J` (the front surface's motion Jacobian) for which
/// [`Kernel::continuation_covers`] extends the surface: below it the surface folds or
/// compresses so strongly that its linear extension says nothing.
const CONTINUATION_MIN_DET: f32 = 0.25;

/// Samples layer k with the cross-layer fallback of Fig. 6.
pub(crate) struct StackSampler<'a> {
    pub layers: &'a [LayerSampler<'a>],
    pub k: usize,
    pub cross: bool,
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
        // Under the adaptive fetch only a bilinear sample is borrowed: a nearest one sits on the
        // front layer's silhouette, where its texel lands within the threshold of pixels that see
        // past the edge (a layer-0 sliver "found" by layer k over the sky the reference shows).
        self.layers[..self.k]
            .iter()
            .rev()
            .find_map(|l| l.fetch(q).map(|s| (s, l.sampling())))
            .filter(|(s, sampling)| s.smooth || *sampling == crate::Sampling::Nearest)
            .map(|(s, _)| s)
    }
}

/// The bound one stage gives a box of pixels for one layer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct StageBound {
    /// Motion bound (frame coordinates) containing every solution of every pixel of the box.
    pub motion: Bound,
    /// Layers `k > 0`: min target depth of the valid samples over the box's final region
    /// (`-inf` for layer 0, where it is not used).
    pub min_depth: f32,
    /// Layer 0 of a box not [`Self::resolved`]: every pixel's region holds at most one
    /// solution, which one seed at the region's centre finds wherever it converges
    /// ([`crate::PreparedLayer::unique_solution`]); `false` elsewhere.
    pub unique: bool,
}

/// Where the eight lanes of [`Kernel::lanes_core`] find their tiles' stages: one tile for all
/// (the dense warp's 4x2 groups), or one per lane (a sparse warp's listed pixels).
#[cfg(target_arch = "x86_64")]
enum LaneStages<'a> {
    /// `stages[k][t]`: tile `t` of a band, every lane.
    Tile(&'a [Vec<Option<StageBound>>], usize),
    /// `stages[k][i]`: lane `i`'s tile.
    Lanes(&'a [[Option<StageBound>; 8]]),
}

/// One layer's stages of eight lanes as vectors: the lanes that have one, their min depths,
/// bounds (`[lo.x, lo.y, hi.x, hi.y]`), and which are one-solution and resolved tiles.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
struct LaneStage {
    present: u8,
    min_depth: std::arch::x86_64::__m256,
    bound: [std::arch::x86_64::__m256; 4],
    unique: u8,
    resolved: u8,
}

#[cfg(target_arch = "x86_64")]
impl LaneStages<'_> {
    /// Lane `i`'s stage of layer `k`.
    fn lane(&self, k: usize, i: usize) -> Option<StageBound> {
        match self {
            LaneStages::Tile(s, t) => s[k][*t],
            LaneStages::Lanes(s) => s[k][i],
        }
    }

    /// Layer `k`'s stages as vectors, `None` where no lane has one.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[target_feature(enable = "avx2")]
    unsafe fn layer(&self, k: usize) -> Option<LaneStage> {
        use std::arch::x86_64::*;
        match self {
            LaneStages::Tile(s, t) => s[k][*t].map(|sk| LaneStage {
                present: 0xff,
                min_depth: _mm256_set1_ps(sk.min_depth),
                bound: crate::simd_warp::splat_bound(&sk.motion),
                unique: if sk.unique { 0xff } else { 0 },
                resolved: if sk.resolved() { 0xff } else { 0 },
            }),
            LaneStages::Lanes(s) => {
                let (mut present, mut unique, mut resolved) = (0u8, 0u8, 0u8);
                let mut v = [[0f32; 8]; 5];
                for (i, st) in s[k].iter().enumerate() {
                    let Some(st) = st else { continue };
                    present |= 1 << i;
                    unique |= (st.unique as u8) << i;
                    resolved |= (st.resolved() as u8) << i;
                    let b = &st.motion;
                    for (row, x) in v.iter_mut().zip([st.min_depth, b.lo.x, b.lo.y, b.hi.x, b.hi.y]) {
                        row[i] = x;
                    }
                }
                (present != 0).then(|| {
                    let l = |r: &[f32; 8]| _mm256_loadu_ps(r.as_ptr());
                    LaneStage {
                        present,
                        min_depth: l(&v[0]),
                        bound: [l(&v[1]), l(&v[2]), l(&v[3]), l(&v[4])],
                        unique,
                        resolved,
                    }
                })
            }
        }
    }
}

impl StageBound {
    /// Within one pixel in both axes: no finer stage is computed below it.
    #[inline]
    pub fn resolved(&self) -> bool {
        let e = self.motion.extent();
        e.x <= 1.0 && e.y <= 1.0
    }
}

/// The tile stage of one tile for every layer, computed on demand (`None`: no valid sample
/// of the layer can move to any pixel of the tile).
pub(crate) struct TileBounds {
    /// Tile origin (target pixels).
    x0: u32,
    y0: u32,
    valid: bool,
    memo: Vec<Option<Option<StageBound>>>,
}

impl TileBounds {
    pub fn new(layers: usize) -> Self {
        TileBounds { x0: 0, y0: 0, valid: false, memo: vec![None; layers] }
    }
    /// Forgets everything and moves to the tile at `(x0, y0)`.
    pub fn reset(&mut self, x0: u32, y0: u32) {
        self.x0 = x0;
        self.y0 = y0;
        self.valid = true;
        self.memo.fill(None);
    }
    /// `true` if the memo holds the tile containing pixel `(x, y)`.
    pub fn holds(&self, x: u32, y: u32) -> bool {
        self.valid && x / TILE * TILE == self.x0 && y / TILE * TILE == self.y0
    }
}

/// Two output rows of a band (the second absent at the band's end), for the lanes.
pub(crate) struct Rows<'a> {
    pub depth: [&'a mut [f32]; 2],
    pub state: [&'a mut [PixelState]; 2],
    pub source: [Option<&'a mut [SourcePos]>; 2],
    pub two: bool,
    /// The image row of `depth[0]`.
    pub y: u32,
    /// Where the pixels converged on a layer after the first are listed (global indices).
    pub revealed: &'a mut Vec<u32>,
}

/// The warp kernel over prepared layers: the bound hierarchy and the per-pixel search.
pub(crate) struct Kernel<'a> {
    pub layers: &'a [PreparedLayer],
    pub samplers: &'a [LayerSampler<'a>],
    pub params: &'a WarpParams,
    /// Source layer size (the space of `q`, the motion and the mipmaps).
    pub w: u32,
    pub h: u32,
    /// Target image size: the source size divided by [`WarpParams::multisample`].
    pub tw: u32,
    pub th: u32,
    /// Source samples per target pixel and axis, as a float: target pixel `(x, y)` is the
    /// source position `m * (x + 0.5, y + 0.5)` (exact for `m = 1`).
    pub m: f32,
}

impl<'a> Kernel<'a> {
    pub fn new(
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
    pub fn target_pos(&self, x: u32, y: u32) -> Vec2 {
        Vec2::new(x as f32 + 0.5, y as f32 + 0.5) * self.m
    }

    /// Number of tightening steps (0 for the global bound).
    #[inline]
    pub fn bound_iterations(&self) -> u32 {
        if self.params.bound == BoundKind::Global {
            0
        } else {
            self.params.bound_iterations
        }
    }

    /// The tile stage of layer `k` for the memo's tile: Fig. 5 over the union of the tile's
    /// search regions (clipped to the image), from the global bound.
    pub fn start(&self, t: &mut TileBounds, k: usize) -> Option<StageBound> {
        if let Some(s) = t.memo[k] {
            return s;
        }
        let (x1, y1) = ((t.x0 + TILE).min(self.tw) - 1, (t.y0 + TILE).min(self.th) - 1);
        let pyr = self.layers[k].pyramid();
        let (p_lo, p_hi) = (self.target_pos(t.x0, t.y0), self.target_pos(x1, y1));
        let (iters, expand, scale) =
            (self.bound_iterations(), self.params.sampling.footprint(), self.params.motion_scale);
        let start = pyr.global().scaled(scale);
        let s = if k == 0 {
            pyr.tight_bound_box_scaled(p_lo, p_hi, start, iters, expand, scale).map(|t| StageBound {
                motion: t.motion,
                min_depth: f32::NEG_INFINITY,
                unique: self.unique_solution(p_lo, p_hi, &t.motion),
            })
        } else {
            pyr.tight_bound_box_with_depth_scaled(p_lo, p_hi, start, iters, expand, scale).map(|t| StageBound {
                motion: t.motion,
                min_depth: t.min_depth,
                unique: false,
            })
        };
        t.memo[k] = Some(s);
        s
    }

    /// [`StageBound::unique`] for layer 0's tile bound `motion` over the box `p_lo..=p_hi`:
    /// only for a bound wider than a pixel, stratified seeds and the adaptive fetch.
    fn unique_solution(&self, p_lo: Vec2, p_hi: Vec2, motion: &Bound) -> bool {
        let e = motion.extent();
        let p = self.params;
        !(e.x <= 1.0 && e.y <= 1.0)
            && p.seeding == SeedStrategy::Stratified
            && p.sampling == crate::Sampling::Adaptive
            && self.layers[0].unique_solution(p_lo, p_hi, motion, p.motion_scale)
    }

    /// The warp of one target pixel over all layers, from layer `k0` on with the state the
    /// layers before it left (`best`, `prev_q`: the accelerated builds hand over here).
    ///
    /// `seeds` is scratch space owned by the caller (zeroing a 64-seed array per pixel is a
    /// measurable cost).
    #[allow(clippy::too_many_arguments)]
    pub fn pixel_from(
        &self,
        x: u32,
        y: u32,
        b: &mut TileBounds,
        seeds: &mut [Vec2; MAX_SEEDS as usize],
        k0: usize,
        mut best: Option<Candidate>,
        mut prev_q: Option<Vec2>,
    ) -> (f32, PixelState, SourcePos) {
        let params = self.params;
        let p = self.target_pos(x, y);
        let expand = params.sampling.footprint();
        let scale = params.motion_scale;
        let max_q = self.max_q();
        let mut awoc: Option<(BoundFrame, TightBound)> = None;
        let cover2 = params.cover_radius * params.cover_radius;
        // The nearest depth of a layer that, before any candidate, failed with a walk within the
        // coverage radius of p or one that cycled across p on one surface.
        let mut cover = f32::INFINITY;
        // The farthest sample of the failed walks of the layers searched before any candidate
        // (WarpParams::ground_layer).
        let mut farthest = f32::NEG_INFINITY;
        for k in k0..self.layers.len() {
            let pyr = self.layers[k].pyramid();
            // No valid sample can move to p from this layer: skip it (cheap for sparse layers).
            let Some(start) = self.start(b, k) else { continue };
            if start.unique && best.is_none() {
                // One solution at most in the pixel's region under the tile's bound: one seed at
                // its centre finds it without tightening; where that walk fails, the pixel takes
                // the complete search below.
                let tb = TightBound {
                    motion: start.motion,
                    region: pyr.region(p, &start.motion),
                    min_depth: f32::NEG_INFINITY,
                };
                if let (Some(c), _) = self.search_layer(k, x, y, p, &tb, None, 1, seeds) {
                    prev_q = Some(c.q);
                    best = Some(c);
                    continue;
                }
            }
            let tb = if start.resolved() && best.is_none() {
                // The tile's bound is already narrower than a pixel: one seed at the centre of
                // this pixel's region, whatever further tightening would give.
                TightBound { motion: start.motion, region: pyr.region(p, &start.motion), min_depth: f32::NEG_INFINITY }
            } else if k > 0 && best.is_some() {
                // A later layer only matters if it can beat the best candidate so far: skip it
                // when no sample of its search region is nearer (min-depth mipmap look-ups),
                // first over the tile's region (computed once per tile), then over the pixel's
                // region under the tile's bound, before any tightening (exact: the tightened
                // region lies inside it), then over the tightened region.
                if best.is_some_and(|b| start.min_depth >= b.depth) {
                    continue;
                }
                let Some(r) = pyr.pixel_range(&pyr.region(p, &start.motion), expand) else { continue };
                if best.is_some_and(|b| pyr.lookup_min_depth(r.0, r.1, r.2, r.3) >= b.depth) {
                    continue;
                }
                let Some(tb) =
                    pyr.tight_bound_box_with_depth_scaled(p, p, start.motion, self.bound_iterations(), expand, scale)
                else {
                    continue;
                };
                if best.is_some_and(|b| tb.min_depth >= b.depth) {
                    continue;
                }
                tb
            } else {
                let Some(tb) = pyr.tight_bound_box_scaled(p, p, start.motion, self.bound_iterations(), expand, scale)
                else {
                    continue;
                };
                tb
            };
            if params.holes == HolePolicy::Awoc && awoc.is_none() {
                awoc = Some((pyr.frame(), tb));
            }
            match self.search_layer(k, x, y, p, &tb, prev_q, params.n_seeds, seeds) {
                (Some(c), _) => {
                    prev_q = Some(c.q);
                    if best.is_none_or(|b| c.depth < b.depth) {
                        best = Some(c);
                    }
                }
                (None, a) => {
                    if best.is_none() {
                        // Covered without a candidate: a walk within the coverage radius, or one
                        // that cycled across p on one surface (search::Approach::straddle).
                        if a.r2 < cover2 {
                            cover = cover.min(a.depth);
                        }
                        cover = cover.min(a.straddle);
                        farthest = farthest.max(a.farthest);
                    }
                }
            }
        }
        // A deeper layer's candidate behind a front surface that covers p is hidden
        // (WarpParams::cover_radius): the pixel goes to the hole policy.
        if best.is_some_and(|c| crate::hidden_behind(c.depth, cover)) {
            best = None;
        }
        if let Some(c) = best {
            if let Some(f) = self.retry_front(x, y, p, &c, farthest, |k| self.start(b, k), seeds) {
                best = Some(f);
            }
        }
        if best.is_some_and(|c| self.covered_at_source(&c, p)) {
            best = None;
        }
        // A ground layer's candidate behind the far side of the front layers' failed walks.
        if best.is_some_and(|c| self.behind_ground_disocclusion(&c, farthest)) {
            best = None;
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

    /// A deeper candidate `c` that lies [`crate::hidden_behind`] `farthest` (the far side of the
    /// failed walks of the layers in front of it), or whose front layers' walks sampled nothing
    /// after their first step (`farthest = -inf`: every seed left the image or landed empty at
    /// once, no sign of a disocclusion at all), is the surface behind a disocclusion only if
    /// the front layers really have nothing at `p` (in the latter case: nothing nearer than
    /// `c`): they search again, from their tightened bound under their tile stage (`stage(k)`,
    /// [`Self::start`]) with [`crate::RETRY_SEED_FACTOR`] times N seeds (at most
    /// [`MAX_SEEDS`]), and the nearest front candidate found replaces `c`. Rare (disocclusion
    /// pixels behind a far side); `None` when nothing was searched or found.
    #[allow(clippy::too_many_arguments)]
    pub fn retry_front(
        &self,
        x: u32,
        y: u32,
        p: Vec2,
        c: &Candidate,
        farthest: f32,
        mut stage: impl FnMut(usize) -> Option<StageBound>,
        seeds: &mut [Vec2; MAX_SEEDS as usize],
    ) -> Option<Candidate> {
        // Without front walk samples there is no sign of a front surface either: a front
        // candidate must then also be nearer than c.
        let unseen = farthest == f32::NEG_INFINITY;
        if c.tag == 0 || !(unseen || crate::hidden_behind(c.depth, farthest)) {
            return None;
        }
        let n = (self.params.n_seeds * crate::RETRY_SEED_FACTOR).min(MAX_SEEDS);
        let (expand, scale) = (self.params.sampling.footprint(), self.params.motion_scale);
        let mut found: Option<Candidate> = None;
        for k in 0..(c.tag as usize).min(self.layers.len()) {
            let Some(s) = stage(k) else { continue };
            let pyr = self.layers[k].pyramid();
            let Some(tb) = pyr.tight_bound_box_scaled(p, p, s.motion, self.bound_iterations(), expand, scale) else {
                continue;
            };
            if let (Some(f), _) = self.search_layer(k, x, y, p, &tb, None, n, seeds) {
                if found.is_none_or(|g| f.depth < g.depth) && (!unseen || f.depth < c.depth) {
                    found = Some(f);
                }
            }
        }
        found
    }

    /// `true` if `c` comes from the ground layer of [`crate::WarpParams::ground_layer`] and lies
    /// [`crate::hidden_behind`] `farthest`, the farthest sample of the walks that failed before
    /// it (`-inf`: no such sample, nothing known in front: kept).
    #[inline]
    pub fn behind_ground_disocclusion(&self, c: &Candidate, farthest: f32) -> bool {
        self.params.ground_layer
            && c.tag as usize + 1 == self.layers.len()
            && farthest > f32::NEG_INFINITY
            && crate::hidden_behind(c.depth, farthest)
    }

    /// `true` if a layer in front of candidate `c`'s own (its tag) has, at `c`'s source position,
    /// a surface that lands within the coverage radius of `p` ([`crate::WarpParams::cover_radius`])
    /// and that `c` lies [`crate::hidden_behind`]: the front surface still covers `p` at the very
    /// place the deeper layer is seen from, so `c` is hidden (its own search only missed, e.g. on
    /// a crack between two layers' samples). Decided from the source alone (seed 000 Sec. 3.4:
    /// a deeper layer fills what the front layer disoccludes, nothing else).
    ///
    /// Each front surface at `c.q` is also followed one fixed-point step (`q' = p - v(c.q)`,
    /// inside the image):
    /// if a front layer's sample at `q'`, or one of the texels of the cell around `q'` (from its
    /// centre: where the cell is a discontinuity the fetch gives only one of them), lands within
    /// the coverage radius of `p` and `c` lies behind it, the front layers have a surface at `p`
    /// that their own seeds missed — typically a sliver a texel wide in one layer at the seam
    /// between two layers' views of one wall — and `c`, seen through the seam, is hidden.
    #[inline]
    pub fn covered_at_source(&self, c: &Candidate, p: Vec2) -> bool {
        let cover2 = self.params.cover_radius * self.params.cover_radius;
        // A front sample `f` at `q` that lands near p and that `c` lies behind.
        let hides =
            |q: Vec2, f: &Sample| ((q + f.v) - p).length_squared() < cover2 && crate::hidden_behind(c.depth, f.depth);
        let front = &self.samplers[..(c.tag as usize).min(self.samplers.len())];
        front.iter().any(|s| {
            let Some(f) = s.fetch(c.q) else { return false };
            let q = p - f.v;
            hides(c.q, &f)
                || self.continuation_covers(front, c, &f, p)
                || (self.samplers[0].inside(q)
                    && front.iter().any(|t| {
                        t.fetch(q).is_some_and(|g| hides(q, &g))
                            || t.cell_texels(q).any(|(centre, g)| hides(centre, &g))
                    }))
        })
    }

    /// `true` if the front surface `f` at candidate `c`'s source position, continued past it
    /// with its own motion Jacobian to the point `q*` that lands on `p`, may still be there: `c`
    /// (behind `f`) is then hidden at `p`. It is there where a front layer sees `f`'s depth at
    /// `q*` (within [`crate::COVER_DEPTH_RATIO`] both ways), and may be where all of them see
    /// nearer (it can run on behind an occluder of the source view); the peeled layers show
    /// that it ended before `q*` where they go past `f`'s depth without meeting it (one sees
    /// something behind `f` there, or nothing) and none sees it (seed 000 Sec. 3.4: a
    /// deeper layer is taken where the front layers disocclude it, and a surface that moved away
    /// from `p` disoccludes it only if it does not reach it). A `q*` beyond the image border is
    /// judged at the border texel nearest to it. Off with the coverage test
    /// ([`crate::WarpParams::cover_radius`] 0).
    #[inline]
    fn continuation_covers(&self, front: &[LayerSampler<'_>], c: &Candidate, f: &Sample, p: Vec2) -> bool {
        // Part of the coverage test, which a zero radius disables.
        if !(self.params.cover_radius > 0.0 && crate::hidden_behind(c.depth, f.depth)) {
            return false;
        }
        // (I + J) d = p - (q + v): one Newton step on the front surface's linear extension.
        let [jx, jy] = f.dv;
        let (a, b, e, d) = (1.0 + jx.x, jy.x, jx.y, 1.0 + jy.y);
        let det = a * d - b * e;
        if det.is_nan() || det <= CONTINUATION_MIN_DET {
            return false;
        }
        let r = p - (c.q + f.v);
        let q = c.q + Vec2::new(d * r.x - b * r.y, a * r.y - e * r.x) / det;
        // Beyond the border: whether the surface reaches the border texel nearest `q*`.
        let q = q.clamp(Vec2::ZERO, self.max_q());
        let mut all_near = true;
        for t in front {
            let near = t.fetch(q).filter(|g| !crate::hidden_behind(g.depth, f.depth));
            if near.is_some_and(|g| !crate::hidden_behind(f.depth, g.depth)) {
                return true; // f itself seen there: it runs on (its own search missed p)
            }
            all_near &= near.is_some();
        }
        all_near
    }

    /// Seeds (`n_seeds` in the region `tb`, plus an earlier layer's converged position) and the
    /// fixed-point search of layer `k` for pixel `(x, y)` at source position `p`.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn search_layer(
        &self,
        k: usize,
        x: u32,
        y: u32,
        p: Vec2,
        tb: &TightBound,
        prev_q: Option<Vec2>,
        n_seeds: u32,
        seeds: &mut [Vec2; MAX_SEEDS as usize],
    ) -> (Option<Candidate>, crate::search::Approach) {
        let params = self.params;
        let frame = self.layers[k].pyramid().frame();
        let mut n = match params.seeding {
            SeedStrategy::Stratified => {
                let ne = effective_seeds(n_seeds, tb.region.extent());
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
                // Fig. 6: an earlier layer's converged position seeds this layer.
                let u = frame.to_frame(q);
                if tb.region.contains(u) {
                    if (n as u32) < params.n_seeds {
                        n += 1;
                    }
                    seeds[n - 1] = q;
                }
            }
        }
        let max_q = self.max_q();
        for s in &mut seeds[..n] {
            *s = s.clamp(Vec2::ZERO, max_q);
        }
        let src = StackSampler { layers: self.samplers, k, cross: params.cross_layer };
        fixed_point_search_closest(&src, p, &seeds[..n], &params.search())
    }

    /// The largest seed position: seeds are clamped into `[0, max_q]`, just inside the image.
    #[inline]
    pub fn max_q(&self) -> Vec2 {
        Vec2::new(self.w as f32, self.h as f32) * (1.0 - f32::EPSILON) - Vec2::splat(1e-3)
    }

    /// The warp of one target pixel over all layers (see [`Self::pixel_from`]).
    #[inline]
    pub fn pixel(
        &self,
        x: u32,
        y: u32,
        b: &mut TileBounds,
        seeds: &mut [Vec2; MAX_SEEDS as usize],
    ) -> (f32, PixelState, SourcePos) {
        self.pixel_from(x, y, b, seeds, 0, None, None)
    }

    /// The warp of the listed target pixels (row-major indices; any order, repeats allowed)
    /// appended to `out` in list order: [`Self::pixel`]'s `(depth, state)` for each, bit for
    /// bit. Consecutive pixels of one tile share its tile stage; with AVX2 the stages of up to
    /// eight such runs in one row of tiles are computed together ([`Self::stage_runs`]) and their
    /// pixels go through the lanes eight at a time ([`Self::listed_lanes`]).
    pub fn pixels(&self, list: &[u32], out: &mut Vec<(f32, PixelState)>) {
        let mut memo = TileBounds::new(self.layers.len());
        let mut seeds = [Vec2::ZERO; MAX_SEEDS as usize];
        #[cfg(target_arch = "x86_64")]
        if crate::simd::has_avx2() {
            if let Some(pvs) = self.pyramid_views() {
                // The listed pixels go through the dense warp's lanes eight at a time, each
                // lane with its own tile's stages, where the warp uses what they implement.
                let ls = self.lanes_apply().then(|| self.lane_search());
                let mut lanes = Vec::new();
                let mut i = 0;
                while i < list.len() {
                    // SAFETY: AVX2 checked above.
                    i = unsafe { self.stage_runs(&pvs, ls.as_ref(), list, i, &mut memo, &mut seeds, &mut lanes, out) };
                }
                return;
            }
        }
        for &i in list {
            let (x, y) = (i % self.tw, i / self.tw);
            if !memo.holds(x, y) {
                memo.reset(x / TILE * TILE, y / TILE * TILE);
            }
            let (z, st, _) = self.pixel(x, y, &mut memo, &mut seeds);
            out.push((z, st));
        }
    }

    /// From `list[i]` on, up to eight runs of consecutive pixels in distinct tiles of one row of
    /// tiles: their tile stages of every layer eight at a time ([`crate::simd_warp::tile_stage8`],
    /// the dense warp's), then each run's pixels one by one with the stages in the memo.
    /// Returns the index after the last run.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[allow(clippy::too_many_arguments)]
    unsafe fn stage_runs(
        &self,
        pvs: &[crate::simd_warp::PyramidView<'_>],
        ls: Option<&crate::simd_warp::LaneSearch<'_>>,
        list: &[u32],
        i: usize,
        memo: &mut TileBounds,
        seeds: &mut [Vec2; MAX_SEEDS as usize],
        lanes: &mut Vec<[Option<StageBound>; 8]>,
        out: &mut Vec<(f32, PixelState)>,
    ) -> usize {
        let tile_of = |p: u32| ((p % self.tw) / TILE * TILE, (p / self.tw) / TILE * TILE);
        let y0 = tile_of(list[i]).1;
        // (first, end, tile x0) of each run.
        let mut runs = [(0usize, 0usize, 0u32); 8];
        let (mut n, mut j) = (0, i);
        while n < 8 && j < list.len() {
            let (x0, ty) = tile_of(list[j]);
            if ty != y0 {
                break;
            }
            let first = j;
            while j < list.len() && tile_of(list[j]) == (x0, y0) {
                j += 1;
            }
            runs[n] = (first, j, x0);
            n += 1;
        }
        let y1 = (y0 + TILE).min(self.th) - 1;
        let (mut lx, mut hx) = ([0f32; 8], [0f32; 8]);
        for (r, &(_, _, x0)) in runs[..n].iter().enumerate() {
            lx[r] = self.target_pos(x0, y0).x;
            hx[r] = self.target_pos((x0 + TILE).min(self.tw) - 1, y0).x;
        }
        let (ly, hy) = (self.target_pos(0, y0).y, self.target_pos(0, y1).y);
        let active = ((1u16 << n) - 1) as u8;
        let nl = self.layers.len();
        // stages[r * nl + k]: run r's tile, layer k (as Self::start gives it).
        let mut stages = vec![None; n * nl];
        for k in 0..nl {
            let start = self.layers[k].pyramid().global().scaled(self.params.motion_scale);
            let st = crate::simd_warp::tile_stage8(
                &pvs[k],
                &lx,
                &hx,
                ly,
                hy,
                active,
                &start,
                self.bound_iterations(),
                self.params.sampling.footprint(),
                k > 0,
            );
            for (r, s) in st.into_iter().take(n).enumerate() {
                let x0 = runs[r].2;
                stages[r * nl + k] = s.map(|(motion, z)| {
                    let x1 = (x0 + TILE).min(self.tw) - 1;
                    let unique =
                        k == 0 && self.unique_solution(self.target_pos(x0, y0), self.target_pos(x1, y1), &motion);
                    StageBound { motion, min_depth: if k > 0 { z } else { f32::NEG_INFINITY }, unique }
                });
            }
        }
        if let Some(ls) = ls {
            // The runs' pixels in list order, eight lanes at a time.
            let mut batch = [(0u32, 0usize); 8];
            let mut filled = 0;
            for (r, &(first, end, _)) in runs[..n].iter().enumerate() {
                for &p in &list[first..end] {
                    batch[filled] = (p, r);
                    filled += 1;
                    if filled == 8 {
                        self.listed_lanes(ls, pvs, &batch, &stages, lanes, out);
                        filled = 0;
                    }
                }
            }
            if filled > 0 {
                self.listed_lanes(ls, pvs, &batch[..filled], &stages, lanes, out);
            }
            return j;
        }
        for (r, &(first, end, x0)) in runs[..n].iter().enumerate() {
            memo.reset(x0, y0);
            for (m, s) in memo.memo.iter_mut().zip(&stages[r * nl..(r + 1) * nl]) {
                *m = Some(*s);
            }
            for &p in &list[first..end] {
                let (z, st, _) = self.pixel(p % self.tw, p / self.tw, memo, seeds);
                out.push((z, st));
            }
        }
        j
    }

    /// Up to eight listed pixels `(index, run)` through [`Self::lanes_core`], lane `i` with the
    /// stages of its run's tile (`stages[run * L + k]`), their `(depth, state)` appended to `out`
    /// in order: what [`Self::pixel`] gives each (converged, or a hole at the far depth).
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn listed_lanes(
        &self,
        ls: &crate::simd_warp::LaneSearch<'_>,
        pvs: &[crate::simd_warp::PyramidView<'_>],
        batch: &[(u32, usize)],
        stages: &[Option<StageBound>],
        lanes: &mut Vec<[Option<StageBound>; 8]>,
        out: &mut Vec<(f32, PixelState)>,
    ) {
        use std::arch::x86_64::*;
        let nl = self.layers.len();
        lanes.clear();
        lanes.resize(nl, [None; 8]);
        let (mut xs, mut ys) = ([0i32; 8], [0i32; 8]);
        for (i, &(p, r)) in batch.iter().enumerate() {
            (xs[i], ys[i]) = ((p % self.tw) as i32, (p / self.tw) as i32);
            for (k, l) in lanes.iter_mut().enumerate() {
                l[i] = stages[r * nl + k];
            }
        }
        let xi = _mm256_loadu_si256(xs.as_ptr() as *const __m256i);
        let yi = _mm256_loadu_si256(ys.as_ptr() as *const __m256i);
        let (px, py) = crate::simd_warp::positions(self.m, xi, yi);
        let active = ((1u16 << batch.len()) - 1) as u8;
        let (has, bz, ..) = self.lanes_core(ls, pvs, &LaneStages::Lanes(lanes), (xi, yi), active, (px, py));
        let (mut z, hasb) = ([0f32; 8], _mm256_movemask_ps(has));
        _mm256_storeu_ps(z.as_mut_ptr(), bz);
        for (i, &z) in z.iter().enumerate().take(batch.len()) {
            out.push(if hasb >> i & 1 != 0 { (z, PixelState::Converged) } else { (EMPTY_DEPTH, PixelState::Hole) });
        }
    }

    /// The AVX2 views of every layer's mipmap, look-ups scaled by the warp's motion scale; `None`
    /// if one is too deep or too large for 32-bit gathers (the scalar kernel then runs).
    #[cfg(target_arch = "x86_64")]
    fn pyramid_views(&self) -> Option<Vec<crate::simd_warp::PyramidView<'_>>> {
        self.layers
            .iter()
            .map(|l| crate::simd_warp::PyramidView::new(l.pyramid()).map(|v| v.with_scale(self.params.motion_scale)))
            .collect()
    }

    /// `true` if resolved tiles of layer 0 can take the AVX2 single-seed search
    /// ([`crate::simd_warp`]): the CPU has AVX2 and the warp uses what that build implements
    /// (stratified seeds, adaptive or nearest sampling, any motion scale, no AWOC fill).
    fn lanes_apply(&self) -> bool {
        crate::simd::has_avx2()
            && self.params.seeding == SeedStrategy::Stratified
            && self.params.holes != HolePolicy::Awoc
    }

    /// Warps the band of tile rows `ty * TILE ..` (the slices hold those rows); returns the
    /// band's pixels that converged on a layer after the first ([`crate::WarpOutput::revealed`],
    /// global indices, in no particular order).
    pub fn band(
        &self,
        ty: u32,
        depth: &mut [f32],
        state: &mut [PixelState],
        mut source: Option<&mut [SourcePos]>,
    ) -> Vec<u32> {
        let mut revealed = Vec::new();
        #[cfg(target_arch = "x86_64")]
        if self.lanes_apply() {
            if let Some(pvs) = self.pyramid_views() {
                // SAFETY: `lanes_apply` checked AVX2.
                unsafe { self.band_lanes(&self.lane_search(), &pvs, ty, depth, state, source, &mut revealed) };
                return revealed;
            }
        }
        let w = self.tw as usize;
        let rows = (depth.len() / w) as u32;
        let y0 = ty * TILE;
        let mut memo = TileBounds::new(self.layers.len());
        let mut seeds = [Vec2::ZERO; MAX_SEEDS as usize];
        for x0 in (0..self.tw).step_by(TILE as usize) {
            memo.reset(x0, y0);
            let x1 = (x0 + TILE).min(self.tw);
            for y in y0..y0 + rows {
                for x in x0..x1 {
                    let (z, st, src) = self.pixel(x, y, &mut memo, &mut seeds);
                    crate::stats::count(crate::stats::Counter::Pixels, 1);
                    let i = (y - y0) as usize * w + x as usize;
                    depth[i] = z;
                    state[i] = st;
                    if st == PixelState::Converged && src.layer > 0 {
                        revealed.push(y * self.tw + x);
                    }
                    if let Some(s) = source.as_deref_mut() {
                        s[i] = src;
                    }
                }
            }
        }
        revealed
    }

    /// [`Self::band`] with the AVX2 lanes: the tile stage of every tile of the band and layer,
    /// eight tiles at a time, then per pair of rows the tiles from left to right, two rows of
    /// four pixels at a time ([`Self::fast_lanes`], else [`Self::lanes8`]). Sweeping a row pair
    /// across the band reads each sample plane along three source rows, which the hardware
    /// prefetchers follow; tile by tile it would be five rows per plane at once.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[allow(clippy::too_many_arguments)]
    unsafe fn band_lanes(
        &self,
        ls: &crate::simd_warp::LaneSearch<'_>,
        pvs: &[crate::simd_warp::PyramidView<'_>],
        ty: u32,
        depth: &mut [f32],
        state: &mut [PixelState],
        mut source: Option<&mut [SourcePos]>,
        revealed: &mut Vec<u32>,
    ) {
        let w = self.tw as usize;
        let rows = (depth.len() / w) as u32;
        let y0 = ty * TILE;
        let stages: Vec<Vec<Option<StageBound>>> =
            (0..self.layers.len()).map(|k| self.tile_stages(&pvs[k], k, ty, rows)).collect();
        for yy in (y0..y0 + rows).step_by(2) {
            for (t, x0) in (0..self.tw).step_by(TILE as usize).enumerate() {
                let x1 = (x0 + TILE).min(self.tw);
                let r = (yy - y0) as usize * w;
                let (d0, d1) = depth[r..].split_at_mut(w);
                let (s0, s1) = state[r..].split_at_mut(w);
                let (src0, src1) = match source.as_deref_mut() {
                    Some(src) => {
                        let (a, b) = src[r..].split_at_mut(w);
                        (Some(a), Some(b))
                    }
                    None => (None, None),
                };
                let two = yy + 1 < y0 + rows;
                let out = Rows {
                    depth: [d0, d1],
                    state: [s0, s1],
                    source: [src0, src1],
                    two,
                    y: yy,
                    revealed: &mut *revealed,
                };
                match self.fast_lanes(ls, &stages, t, x0, x1, yy, two) {
                    Some((has, z, qx, qy)) => {
                        self.write_lanes(x0, x1, out, has, z, qx, qy, std::arch::x86_64::_mm256_setzero_si256())
                    }
                    None => self.lanes8(ls, pvs, &stages, t, x0, x1, yy, out),
                }
            }
        }
    }

    /// The tile stage ([`Self::start`]) of layer `k` for every tile of band `ty` (`rows` rows),
    /// with the AVX2 build eight tiles at a time.
    #[cfg(target_arch = "x86_64")]
    fn tile_stages(
        &self,
        pv: &crate::simd_warp::PyramidView<'_>,
        k: usize,
        ty: u32,
        rows: u32,
    ) -> Vec<Option<StageBound>> {
        let y0 = ty * TILE;
        let y1 = y0 + rows - 1;
        let n = self.tw.div_ceil(TILE) as usize;
        let start = self.layers[k].pyramid().global().scaled(self.params.motion_scale);
        let (ly, hy) = (self.target_pos(0, y0).y, self.target_pos(0, y1).y);
        let mut out = Vec::with_capacity(n);
        for t0 in (0..n).step_by(8) {
            let mut lx = [0f32; 8];
            let mut hx = [0f32; 8];
            let mut active = 0u8;
            for i in 0..8 {
                let t = t0 + i;
                if t < n {
                    let x0 = t as u32 * TILE;
                    let x1 = (x0 + TILE).min(self.tw) - 1;
                    lx[i] = self.target_pos(x0, y0).x;
                    hx[i] = self.target_pos(x1, y0).x;
                    active |= 1 << i;
                }
            }
            // SAFETY: `lanes_apply` checked AVX2.
            let r = unsafe {
                crate::simd_warp::tile_stage8(
                    pv,
                    &lx,
                    &hx,
                    ly,
                    hy,
                    active,
                    &start,
                    self.bound_iterations(),
                    self.params.sampling.footprint(),
                    k > 0,
                )
            };
            for (i, s) in r.into_iter().enumerate() {
                if t0 + i < n {
                    out.push(s.map(|(motion, z)| {
                        let unique = k == 0 && {
                            let x0 = (t0 + i) as u32 * TILE;
                            let x1 = (x0 + TILE).min(self.tw) - 1;
                            self.unique_solution(self.target_pos(x0, y0), self.target_pos(x1, y1), &motion)
                        };
                        StageBound { motion, min_depth: if k > 0 { z } else { f32::NEG_INFINITY }, unique }
                    }));
                }
            }
        }
        out
    }

    /// The inputs of the AVX2 single-seed search.
    #[cfg(target_arch = "x86_64")]
    fn lane_search(&self) -> crate::simd_warp::LaneSearch<'_> {
        let layers = self
            .samplers
            .iter()
            .map(|s| {
                let (vx, vy, z, _, _) = s.planes();
                crate::simd_warp::Planes { vx, vy, z }
            })
            .collect();
        crate::simd_warp::LaneSearch {
            layers,
            w: self.w,
            h: self.h,
            max_q: self.max_q(),
            thr2: self.params.threshold * self.params.threshold,
            iterations: self.params.iterations,
            extra_iterations: self.params.extra_iterations,
            accelerate: self.params.accelerate,
            cross: self.params.cross_layer,
            n_seeds: self.params.n_seeds,
            first_converged: self.params.choice == crate::CandidateChoice::FirstConverged,
            nearest: self.params.sampling == crate::Sampling::Nearest,
            avx512: crate::simd::has_avx512(),
            scale: (self.params.motion_scale != Vec2::ONE)
                .then_some((self.params.motion_scale.x, self.params.motion_scale.y)),
        }
    }

    /// The eight lanes of pixels `x0..x1` of rows `y` and, if `two`, `y + 1`: their columns and
    /// rows, the active-lane bits and their target positions.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn group8(
        &self,
        x0: u32,
        x1: u32,
        y: u32,
        two: bool,
    ) -> (
        std::arch::x86_64::__m256i,
        std::arch::x86_64::__m256i,
        u8,
        std::arch::x86_64::__m256,
        std::arch::x86_64::__m256,
    ) {
        use std::arch::x86_64::*;
        let xi = _mm256_add_epi32(_mm256_set1_epi32(x0 as i32), _mm256_setr_epi32(0, 1, 2, 3, 0, 1, 2, 3));
        let yi = _mm256_add_epi32(_mm256_set1_epi32(y as i32), _mm256_setr_epi32(0, 0, 0, 0, 1, 1, 1, 1));
        let cols = ((1u8 << (x1 - x0)) - 1) & 0xf;
        let active = cols | if two { cols << 4 } else { 0 };
        let (px, py) = crate::simd_warp::positions(self.m, xi, yi);
        (xi, yi, active, px, py)
    }

    /// The eight lanes of [`Self::lanes8`] when they take the common case in one pass
    /// ([`crate::simd_warp::fast8`]: layer 0's tile bound resolved, one seed per lane converging
    /// at once, every later layer pruned by its tile's min depth): their `(converged, depth, qx,
    /// qy)`, or `None` for the general path. Tried before the general path is set up: inside it,
    /// the common case shared that path's register pressure.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[allow(clippy::too_many_arguments, clippy::type_complexity)]
    unsafe fn fast_lanes(
        &self,
        ls: &crate::simd_warp::LaneSearch<'_>,
        stages: &[Vec<Option<StageBound>>],
        t: usize,
        x0: u32,
        x1: u32,
        y: u32,
        two: bool,
    ) -> Option<(
        std::arch::x86_64::__m256,
        std::arch::x86_64::__m256,
        std::arch::x86_64::__m256,
        std::arch::x86_64::__m256,
    )> {
        let s0 = stages[0][t].filter(StageBound::resolved)?;
        let mut later = [f32::INFINITY; 8];
        let nl = self.layers.len() - 1;
        if nl > later.len() {
            return None;
        }
        for (z, s) in later.iter_mut().zip(&stages[1..]) {
            *z = s[t].map_or(f32::INFINITY, |s| s.min_depth);
        }
        let (_, _, active, px, py) = self.group8(x0, x1, y, two);
        let frame = self.layers[0].pyramid().frame();
        crate::simd_warp::fast8(ls, frame, &s0.motion, &later[..nl], px, py, active)
    }

    /// The warp of the pixels `x0..x1` of rows `y` and `y + 1` of one tile (eight lanes) in
    /// lock step over the layers with the AVX2 single-seed search: per layer, lanes that already
    /// converged take the tile's min-depth pruning test, the others search with one seed in the
    /// region under the tile's bound (resolved tiles) or their own tightened bound. What the
    /// lanes cannot do in lock step — more than one seed, a later layer that survives the
    /// tile's pruning test — goes to [`Self::pixel_from`] from that layer on with the state so
    /// far, so every pixel gets exactly the scalar kernel's result.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[allow(clippy::too_many_arguments)]
    unsafe fn lanes8(
        &self,
        ls: &crate::simd_warp::LaneSearch<'_>,
        pvs: &[crate::simd_warp::PyramidView<'_>],
        stages: &[Vec<Option<StageBound>>],
        t: usize,
        x0: u32,
        x1: u32,
        y: u32,
        out: Rows<'_>,
    ) {
        let (xi, yi, active, px, py) = self.group8(x0, x1, y, out.two);
        let (has, bz, bqx, bqy, btag) =
            self.lanes_core(ls, pvs, &LaneStages::Tile(stages, t), (xi, yi), active, (px, py));
        self.write_lanes(x0, x1, out, has, bz, bqx, bqy, btag)
    }

    /// The body of [`Self::lanes8`] for any eight pixels (columns `xi`, rows `yi`, target
    /// positions `px, py`, the `active` lanes), each with its own tile's stages (`stages`):
    /// per lane whether it converged, its depth, source position and layer tag.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[allow(clippy::type_complexity)]
    unsafe fn lanes_core(
        &self,
        ls: &crate::simd_warp::LaneSearch<'_>,
        pvs: &[crate::simd_warp::PyramidView<'_>],
        stages: &LaneStages<'_>,
        (xi, yi): (std::arch::x86_64::__m256i, std::arch::x86_64::__m256i),
        active: u8,
        (px, py): (std::arch::x86_64::__m256, std::arch::x86_64::__m256),
    ) -> (
        std::arch::x86_64::__m256,
        std::arch::x86_64::__m256,
        std::arch::x86_64::__m256,
        std::arch::x86_64::__m256,
        std::arch::x86_64::__m256i,
    ) {
        use crate::simd_warp as sw;
        use std::arch::x86_64::*;
        let expand = self.params.sampling.footprint();
        let zero = _mm256_setzero_ps();
        let mut has = zero;
        let mut bz = _mm256_set1_ps(EMPTY_DEPTH);
        let (mut bqx, mut bqy) = (zero, zero);
        let mut btag = _mm256_setzero_si256();
        // The last converged position (cross-layer seed) and whether there is one.
        let (mut pqx, mut pqy) = (zero, zero);
        let act = sw::lane_mask(active);
        // Per lane the nearest depth of a layer that, before any candidate, failed with a walk
        // within the coverage radius (Kernel::pixel_from).
        let mut cover = _mm256_set1_ps(f32::INFINITY);
        let cover2 = _mm256_set1_ps(self.params.cover_radius * self.params.cover_radius);
        // Per lane the farthest sample of those failed walks (Kernel::behind_ground_disocclusion).
        let neg_inf = _mm256_set1_ps(f32::NEG_INFINITY);
        let mut farthest = neg_inf;
        for (k, pv) in pvs.iter().enumerate().take(self.layers.len()) {
            let Some(sk) = stages.layer(k) else { continue };
            // The lanes whose tile has a stage for this layer.
            let act = _mm256_and_ps(act, sw::lane_mask(sk.present));
            let active = active & sk.present;
            let frame = self.layers[k].pyramid().frame();
            let iters = self.bound_iterations();
            // Lanes with a candidate: the pruning tests of a later layer (min depths over the
            // tile's region, the pixel's region under the tile's bound, the tightened region),
            // then the search from the tightened bound with the cross-layer seed.
            let with_best = _mm256_and_ps(act, has);
            let mut go = _mm256_and_ps(with_best, _mm256_cmp_ps::<_CMP_LT_OQ>(sk.min_depth, bz));
            let mut later: Option<([__m256; 4], u8)> = None;
            if _mm256_movemask_ps(go) != 0 {
                let (r, hit) = sw::pixel_range8(pv, &sw::region8(frame, px, py, &sk.bound), expand);
                go = _mm256_and_ps(go, hit);
                let z1 = sw::lookup_min_depth8(pv, &r, _mm256_castps_si256(go));
                go = _mm256_and_ps(go, _mm256_cmp_ps::<_CMP_LT_OQ>(z1, bz));
                let bits = _mm256_movemask_ps(go) as u8;
                if bits != 0 {
                    let (ok, _, region) = sw::tighten8(pv, px, py, bits, &sk.bound, iters, expand);
                    let (r, hit) = sw::pixel_range8(pv, &region, expand);
                    let ok = _mm256_and_ps(sw::lane_mask(ok), hit);
                    let z2 = sw::lookup_min_depth8(pv, &r, _mm256_castps_si256(ok));
                    let ok = _mm256_and_ps(ok, _mm256_cmp_ps::<_CMP_LT_OQ>(z2, bz));
                    later = Some((region, _mm256_movemask_ps(ok) as u8));
                }
            }
            // Lanes without a candidate: the resolved tile's region, or the pixel's tightened
            // bound.
            let mut searching = active & !(_mm256_movemask_ps(has) as u8);
            let unique = searching & sk.unique;
            if unique != 0 {
                // Kernel::pixel_from: one seed at the centre of the region under the tile's bound
                // where it holds one solution at most; the lanes it fails take the complete search.
                let region = sw::region8(frame, px, py, &sk.bound);
                let r = sw::search8(ls, k, frame, px, py, xi, yi, unique, &region, None, 1);
                let now = r.converged;
                pqx = _mm256_blendv_ps(pqx, r.qx, now);
                pqy = _mm256_blendv_ps(pqy, r.qy, now);
                bz = _mm256_blendv_ps(bz, r.depth, now);
                bqx = _mm256_blendv_ps(bqx, r.qx, now);
                bqy = _mm256_blendv_ps(bqy, r.qy, now);
                btag = _mm256_blendv_epi8(btag, r.tag, _mm256_castps_si256(now));
                has = _mm256_or_ps(has, now);
                searching &= !(_mm256_movemask_ps(now) as u8);
            }
            // Resolved tiles' lanes search the region under the tile's bound, the others their
            // own tightened bound.
            let first = if searching == 0 {
                None
            } else {
                let resolved = searching & sk.resolved;
                let mut region = sw::region8(frame, px, py, &sk.bound);
                let mut bits = resolved;
                let tight = searching & !sk.resolved;
                if tight != 0 {
                    let (ok, _, r) = sw::tighten8(pv, px, py, tight, &sk.bound, iters, expand);
                    let m = sw::lane_mask(tight);
                    for (a, b) in region.iter_mut().zip(r) {
                        *a = _mm256_blendv_ps(*a, b, m);
                    }
                    bits |= ok;
                }
                Some((region, bits))
            };
            for (pass, with_prev) in [(first, false), (later, true)] {
                let Some((region, bits)) = pass else { continue };
                if bits == 0 {
                    continue;
                }
                let prev = with_prev.then_some((pqx, pqy, has));
                let r = sw::search8(ls, k, frame, px, py, xi, yi, bits, &region, prev, ls.n_seeds);
                let now = r.converged;
                if !with_prev {
                    // Kernel::pixel_from: a failed search of a lane without a candidate.
                    let near = _mm256_cmp_ps::<_CMP_LT_OQ>(r.closest, cover2);
                    let failed = _mm256_andnot_ps(now, sw::lane_mask(bits));
                    let z =
                        _mm256_blendv_ps(_mm256_set1_ps(f32::INFINITY), r.closest_depth, _mm256_and_ps(failed, near));
                    cover = _mm256_min_ps(cover, z);
                    cover = _mm256_min_ps(cover, _mm256_blendv_ps(_mm256_set1_ps(f32::INFINITY), r.straddle, failed));
                    farthest = _mm256_max_ps(farthest, _mm256_blendv_ps(neg_inf, r.farthest, failed));
                }
                // Found: the cross-layer seed of later layers; nearer than the candidate (or the
                // first): the candidate.
                pqx = _mm256_blendv_ps(pqx, r.qx, now);
                pqy = _mm256_blendv_ps(pqy, r.qy, now);
                let better = _mm256_and_ps(
                    now,
                    _mm256_or_ps(_mm256_andnot_ps(has, now), _mm256_cmp_ps::<_CMP_LT_OQ>(r.depth, bz)),
                );
                bz = _mm256_blendv_ps(bz, r.depth, better);
                bqx = _mm256_blendv_ps(bqx, r.qx, better);
                bqy = _mm256_blendv_ps(bqy, r.qy, better);
                btag = _mm256_blendv_epi8(btag, r.tag, _mm256_castps_si256(better));
                has = _mm256_or_ps(has, now);
            }
        }
        // crate::hidden_behind: (1 - z) * COVER_DEPTH_RATIO < 1 - cover.
        let one = _mm256_set1_ps(1.0);
        let hidden = _mm256_cmp_ps::<_CMP_LT_OQ>(
            _mm256_mul_ps(_mm256_sub_ps(one, bz), _mm256_set1_ps(crate::COVER_DEPTH_RATIO)),
            _mm256_sub_ps(one, cover),
        );
        has = _mm256_andnot_ps(hidden, has);
        // Kernel::covered_at_source and behind_ground_disocclusion themselves for the lanes whose
        // candidate comes from a deeper layer (few: disocclusions).
        let deep = _mm256_movemask_ps(_mm256_and_ps(
            has,
            _mm256_castsi256_ps(_mm256_cmpgt_epi32(btag, _mm256_setzero_si256())),
        )) as u8;
        if deep != 0 {
            let (mut qx, mut qy, mut z, mut far, mut tags, mut pxs, mut pys) =
                ([0f32; 8], [0f32; 8], [0f32; 8], [0f32; 8], [0i32; 8], [0f32; 8], [0f32; 8]);
            let (mut xs, mut ys) = ([0i32; 8], [0i32; 8]);
            _mm256_storeu_si256(xs.as_mut_ptr() as *mut __m256i, xi);
            _mm256_storeu_si256(ys.as_mut_ptr() as *mut __m256i, yi);
            _mm256_storeu_ps(qx.as_mut_ptr(), bqx);
            _mm256_storeu_ps(qy.as_mut_ptr(), bqy);
            _mm256_storeu_ps(z.as_mut_ptr(), bz);
            _mm256_storeu_ps(far.as_mut_ptr(), farthest);
            _mm256_storeu_si256(tags.as_mut_ptr() as *mut __m256i, btag);
            _mm256_storeu_ps(pxs.as_mut_ptr(), px);
            _mm256_storeu_ps(pys.as_mut_ptr(), py);
            let mut hidden = 0u8;
            let mut seeds = [Vec2::ZERO; MAX_SEEDS as usize];
            for i in (0..8).filter(|i| deep >> i & 1 != 0) {
                let mut c = Candidate { q: Vec2::new(qx[i], qy[i]), depth: z[i], tag: tags[i] as u32, seed: 0 };
                let p = Vec2::new(pxs[i], pys[i]);
                let (lx, ly) = (xs[i] as u32, ys[i] as u32);
                if let Some(f) = self.retry_front(lx, ly, p, &c, far[i], |k| stages.lane(k, i), &mut seeds) {
                    c = f;
                    (qx[i], qy[i], z[i], tags[i]) = (f.q.x, f.q.y, f.depth, f.tag as i32);
                }
                hidden |= ((self.covered_at_source(&c, p) || self.behind_ground_disocclusion(&c, far[i])) as u8) << i;
            }
            has = _mm256_andnot_ps(sw::lane_mask(hidden), has);
            bqx = _mm256_loadu_ps(qx.as_ptr());
            bqy = _mm256_loadu_ps(qy.as_ptr());
            bz = _mm256_loadu_ps(z.as_ptr());
            btag = _mm256_loadu_si256(tags.as_ptr() as *const __m256i);
        }
        (has, bz, bqx, bqy, btag)
    }

    /// Writes the results of eight lanes (two rows of up to four pixels from `x0`): the
    /// candidate's depth and the converged state where `has`, the far depth and a hole elsewhere,
    /// and the source positions when recorded.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    unsafe fn write_lanes(
        &self,
        x0: u32,
        x1: u32,
        out: Rows<'_>,
        has: std::arch::x86_64::__m256,
        bz: std::arch::x86_64::__m256,
        bqx: std::arch::x86_64::__m256,
        bqy: std::arch::x86_64::__m256,
        btag: std::arch::x86_64::__m256i,
    ) {
        use std::arch::x86_64::*;
        let Rows { depth, state, source, revealed, two, y: y0 } = out;
        // Depth: the candidate's, far where none; state: converged or hole.
        let fz = _mm256_blendv_ps(_mm256_set1_ps(EMPTY_DEPTH), bz, has);
        let hasb = _mm256_movemask_ps(has) as u8;
        let n = (x1 - x0) as usize;
        let x = x0 as usize;
        // Converged on a deeper layer (lane l: row l / 4, column l % 4).
        let mut deep = _mm256_movemask_ps(_mm256_and_ps(
            has,
            _mm256_castsi256_ps(_mm256_cmpgt_epi32(btag, _mm256_setzero_si256())),
        )) as u8;
        while deep != 0 {
            let l = deep.trailing_zeros();
            deep &= deep - 1;
            let (row, col) = (l / 4, l % 4);
            if (row == 0 || two) && (col as usize) < n {
                revealed.push((y0 + row) * self.tw + x0 + col);
            }
        }
        let mut zs = [0f32; 8];
        _mm256_storeu_ps(zs.as_mut_ptr(), fz);
        for (row, (drow, srow)) in depth.into_iter().zip(state).enumerate() {
            if row == 1 && !two {
                break;
            }
            let bits = hasb >> (4 * row);
            if n == 4 {
                // A fixed-size store: a variable-length copy here was a `memmove` call per row.
                let half = if row == 0 { _mm256_castps256_ps128(fz) } else { _mm256_extractf128_ps::<1>(fz) };
                _mm_storeu_ps(drow[x..x + 4].as_mut_ptr(), half);
                // SAFETY: `PixelState` is a repr(u8) enum (STATE4's bytes are its values) and the
                // slice holds four elements from `x`.
                let dst = srow[x..x + 4].as_mut_ptr() as *mut [u8; 4];
                unsafe { dst.write_unaligned(STATE4[(bits & 0xf) as usize]) };
            } else {
                drow[x..x + n].copy_from_slice(&zs[4 * row..4 * row + n]);
                for (i, st) in srow[x..x + n].iter_mut().enumerate() {
                    *st = if bits >> i & 1 != 0 { PixelState::Converged } else { PixelState::Hole };
                }
            }
        }
        if source.iter().any(|s| s.is_some()) {
            let (mut qx, mut qy) = ([0f32; 8], [0f32; 8]);
            let mut tag = [0u32; 8];
            _mm256_storeu_ps(qx.as_mut_ptr(), bqx);
            _mm256_storeu_ps(qy.as_mut_ptr(), bqy);
            _mm256_storeu_si256(tag.as_mut_ptr() as *mut __m256i, btag);
            for (row, src) in source.into_iter().enumerate() {
                let Some(src) = src else { continue };
                if row == 1 && !two {
                    break;
                }
                for i in 0..n {
                    let l = 4 * row + i;
                    src[x + i] = if hasb >> l & 1 != 0 {
                        SourcePos { q: Vec2::new(qx[l], qy[l]), layer: tag[l] }
                    } else {
                        SourcePos { q: Vec2::ZERO, layer: u32::MAX }
                    };
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{SamplePlanes, Sampling};
    use zwarp_core::Motion;

    #[test]
    fn an_empty_landing_borrows_only_a_bilinear_sample() {
        // Layer 0: a surface over columns 0..2 of a 4x4 image, empty beyond; layer 1: empty.
        let (w, h) = (4, 4);
        let surface =
            |x: usize| if x < 2 { Motion { v: Vec2::ZERO, depth: 0.5 } } else { Motion { v: Vec2::ZERO, depth: 1.0 } };
        let front = SamplePlanes::from_motion(&(0..16).map(|i| surface(i % 4)).collect::<Vec<_>>());
        let back = SamplePlanes::from_motion(&[Motion { v: Vec2::ZERO, depth: 1.0 }; 16]);
        let samplers = [
            LayerSampler::new(&front, w, h, Sampling::Adaptive, 0),
            LayerSampler::new(&back, w, h, Sampling::Adaptive, 1),
        ];
        let stack = StackSampler { layers: &samplers, k: 1, cross: true };
        // Inside the surface the 2x2 cell is valid: the bilinear sample is borrowed (tag 0).
        let inner = stack.sample(Vec2::new(1.2, 2.0), &mut 0).expect("borrowed");
        assert!(inner.smooth && inner.tag == 0 && inner.depth == 0.5);
        // On its last column the cell reaches the empty texels: the nearest sample there sits on
        // the silhouette and is not borrowed, although layer 0's own fetch returns it.
        let edge = Vec2::new(1.8, 2.0);
        assert!(samplers[0].fetch(edge).is_some_and(|s| !s.smooth));
        assert!(stack.sample(edge, &mut 0).is_none());
        // A second empty landing fails the seed whatever layer 0 holds.
        assert!(stack.sample(Vec2::new(1.2, 2.0), &mut 1).is_none());
    }
}
