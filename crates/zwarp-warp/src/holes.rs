//! Hole policies for pixels where no fixed-point search converged (seed 000 Sec. 3.4 "Handling
//! Degenerate Cases", Fig. 8; Sec. 5.3 AWOC).

use glam::Vec2;
use rayon::prelude::*;
use zwarp_core::{Error, Image, Motion, Result, EMPTY_DEPTH};

use crate::sampling::{MotionSource, Sample};
use crate::search::{fixed_point_search, SearchParams};
use crate::{PixelState, WarpLayer, WarpOutput};

/// What the warp writes where no search converged. Selectable per call.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum HolePolicy {
    /// Conservative: the far depth `1.0` ([`PixelState::Hole`]). Never nearer than any surface,
    /// so occlusion culling against the warped buffer stays safe (Sec. 5: "depth holes are
    /// conservatively kept at the far-clipping depth").
    #[default]
    FarDepth,
    /// Fig. 8: a hole surrounded by converged pixels (a converged pixel within `radius` on both
    /// sides along all four directions: horizontal, vertical, both diagonals) takes the depth of
    /// its nearest converged neighbour ([`PixelState::Filled`]); ties between equally near
    /// neighbours take the farther depth. Other holes stay far.
    Dilate {
        /// Search radius in pixels (1..=64).
        radius: u32,
    },
    /// AWOC (Sec. 5.3): fill with the nearest target depth among the samples at the extrema of
    /// the local search bound (the four corners of the tight search region, all layers). These
    /// samples did not converge; it is an approximation that keeps culling effective under
    /// rapid motion ([`PixelState::Filled`]).
    Awoc,
    /// Sec. 4 protocol for single-layer quality ("the single-layer solution keeps holes (filled
    /// with the background depth)"): a hole bracketed by converged pixels within `radius` on both
    /// sides of at least one of the four directions takes the depth of the *farther* sides of
    /// the directions that cross it — bracketed within [`BRACKET_SPAN_RATIO`] times its
    /// narrowest bracket: the mean of those within [`FAR_SIDE_SPREAD`] of the farthest, weighted
    /// by inverse distance ([`PixelState::Filled`]). A disocclusion sliver lies between the
    /// occluder and the surface it uncovers; the uncovered surface is the farther side (a probe
    /// along a long crack runs on to unrelated surfaces). Holes wider than `2 radius` (and sky)
    /// stay far. Not conservative: for quality, never
    /// for culling. This is the part of the protocol that needs only the warped buffer (the
    /// WGSL twin does the same); the complete protocol, which also keeps sky seen through a hole
    /// far and fills the strips a moving camera uncovers at the image border, needs the source
    /// layers: warp with [`HolePolicy::FarDepth`], then call [`fill_background`].
    Background {
        /// Search radius in pixels (1..=64).
        radius: u32,
    },
}

impl HolePolicy {
    /// The hole protocol of seed 000 Sec. 4 as `zwarp eval` and the `zwarp` facade run it:
    /// [`HolePolicy::Background`] with a 64-pixel radius (see [`fill_background`]).
    pub const PAPER: HolePolicy = HolePolicy::Background { radius: 64 };
}

/// Which converged neighbour fills a hole in [`fill_holes`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FillRule {
    /// [`HolePolicy::Dilate`]: surrounded in all four directions, nearest neighbour wins.
    Nearest,
    /// [`HolePolicy::Background`]: bracketed in one direction; the far sides of the directions
    /// bracketed within [`BRACKET_SPAN_RATIO`] times the narrowest bracket, averaged over
    /// those within [`FAR_SIDE_SPREAD`] of the farthest (inverse-distance weights).
    Background,
}

/// Dilation of Fig. 8 over a warped buffer: fills [`PixelState::Hole`] pixels surrounded by
/// [`PixelState::Converged`] ones (see [`HolePolicy::Dilate`]). Only converged pixels are read,
/// so the result does not depend on the processing order.
pub fn dilate_holes(depth: &mut Image<f32>, state: &mut Image<PixelState>, radius: u32) {
    fill_holes(depth, state, radius, FillRule::Nearest)
}

/// Fills [`PixelState::Hole`] pixels from the nearest [`PixelState::Converged`] pixel along each
/// of the eight directions within `radius` ([`FillRule`] says which holes and which neighbour).
/// Only converged pixels are read, so the result does not depend on the processing order.
pub fn fill_holes(depth: &mut Image<f32>, state: &mut Image<PixelState>, radius: u32, rule: FillRule) {
    let holes = hole_list(state);
    fill_holes_listed(depth, state, &holes, radius, rule);
}

/// The [`PixelState::Hole`] pixels of `state` (row-major indices, ascending).
pub(crate) fn hole_list(state: &Image<PixelState>) -> Vec<u32> {
    let band = state.width().max(1) as usize * HOLE_BAND_ROWS;
    let lists: Vec<Vec<u32>> =
        state.data().par_chunks(band).enumerate().map(|(b, chunk)| holes_in(chunk, (b * band) as u32)).collect();
    lists.concat()
}

/// Rows per parallel band of the hole passes ([`hole_list`], [`fill_background_with`]).
const HOLE_BAND_ROWS: usize = 16;

/// The [`PixelState::Hole`] pixels of `states`, a run of states starting at pixel index `base`,
/// ascending. Holes are sparse: blocks of 64 states are tested with a branch-free (vectorised)
/// fold first and only blocks holding a hole are listed pixel by pixel.
fn holes_in(states: &[PixelState], base: u32) -> Vec<u32> {
    let mut list = Vec::new();
    for (b, block) in states.chunks(64).enumerate() {
        if block.iter().fold(false, |a, s| a | (*s == PixelState::Hole)) {
            let b0 = base + (b * 64) as u32;
            for (i, s) in block.iter().enumerate() {
                if *s == PixelState::Hole {
                    list.push(b0 + i as u32);
                }
            }
        }
    }
    list
}

/// [`fill_holes`] of the listed holes (a superset of nothing else: every listed pixel must be a
/// hole): the fills are decided from the unchanged buffers (only converged pixels are read,
/// only holes are written, so the order does not matter), then written.
fn fill_holes_listed(
    depth: &mut Image<f32>,
    state: &mut Image<PixelState>,
    holes: &[u32],
    radius: u32,
    rule: FillRule,
) {
    let (w, h) = depth.size();
    if w == 0 || h == 0 || holes.is_empty() {
        return;
    }
    let r = radius as i64;
    let (dd, sd) = (depth.data(), state.data());
    let runs = hole_runs(holes, w, h);
    let fills: Vec<(u32, f32)> = holes
        .par_chunks(1024)
        .zip(runs.par_chunks(1024))
        .flat_map_iter(|(chunk, runs)| {
            chunk.iter().zip(runs).filter_map(|(&i, run)| {
                let (x, y) = ((i % w) as i64, (i / w) as i64);
                // Nearest converged pixel along +d and -d within the radius. The listed holes
                // next to the pixel along d are skipped at once (`run`); a pixel after them
                // that is neither converged nor listed (filled by an earlier pass) continues
                // the walk step by step, as does a saturated run.
                let probe = |dx: i64, dy: i64| -> Option<(i64, f32)> {
                    let skip = run[probe_slot(dx, dy)];
                    let first = if skip == u8::MAX { 1 } else { skip as i64 + 1 };
                    for k in first..=r {
                        let (xx, yy) = (x + dx * k, y + dy * k);
                        if xx < 0 || yy < 0 || xx >= w as i64 || yy >= h as i64 {
                            return None;
                        }
                        let j = yy as usize * w as usize + xx as usize;
                        if sd[j] == PixelState::Converged {
                            return Some((k, dd[j]));
                        }
                    }
                    None
                };
                hole_fill(rule, probe).map(|z| (i, z))
            })
        })
        .collect();
    let (dd, sd) = (depth.data_mut(), state.data_mut());
    for (i, z) in fills {
        dd[i as usize] = z;
        sd[i as usize] = PixelState::Filled;
    }
}

/// The eight probe directions of [`hole_fill`]: [`FILL_DIRECTIONS`] and their opposites.
const PROBE_DIRECTIONS: [(i64, i64); 8] = {
    let f = FILL_DIRECTIONS;
    [f[0], f[1], f[2], f[3], (-f[0].0, -f[0].1), (-f[1].0, -f[1].1), (-f[2].0, -f[2].1), (-f[3].0, -f[3].1)]
};

/// [`probe_slot`]'s table: the index in [`PROBE_DIRECTIONS`] of `(dx, dy)` at `3 (dx + 1) + dy + 1`.
const PROBE_SLOTS: [usize; 9] = {
    let mut t = [0; 9];
    let mut s = 0;
    while s < PROBE_DIRECTIONS.len() {
        let (dx, dy) = PROBE_DIRECTIONS[s];
        t[(3 * (dx + 1) + dy + 1) as usize] = s;
        s += 1;
    }
    t
};

/// The index of the direction `(dx, dy)` in [`PROBE_DIRECTIONS`].
#[inline]
fn probe_slot(dx: i64, dy: i64) -> usize {
    PROBE_SLOTS[(3 * (dx + 1) + dy + 1) as usize]
}

/// For each of the listed holes (row-major indices, ascending) of a `w x h` image and each of
/// the [`PROBE_DIRECTIONS`]: how many listed holes follow it along that direction before the
/// first pixel that is not one (saturating at `u8::MAX`). A hole's run is one more than its
/// neighbour's: two passes over the list, forwards for the directions whose neighbour comes
/// earlier in it and backwards for the others (in parallel), with a cursor per direction on
/// the neighbour (its index moves monotonically).
fn hole_runs(holes: &[u32], w: u32, h: u32) -> Vec<[u8; 8]> {
    debug_assert!(holes.windows(2).all(|p| p[0] < p[1]), "hole lists are ascending");
    let n = holes.len();
    // The directions whose neighbour comes earlier in the list (visited forwards) and later
    // (visited backwards), each pass filling its own half of the slots.
    let off = |s: usize| PROBE_DIRECTIONS[s].1 * w as i64 + PROBE_DIRECTIONS[s].0;
    let (earlier, later): (Vec<usize>, Vec<usize>) = (0..8).partition(|&s| off(s) < 0);
    let pass = |forward: bool, slots: &[usize]| -> Vec<[u8; 8]> {
        let mut runs = vec![[0u8; 8]; n];
        let mut cursor = [if forward { 0 } else { n.saturating_sub(1) }; 8];
        let mut visit = |t: usize| {
            let i = holes[t];
            let (x, y) = (i % w, i / w);
            for (j, &slot) in cursor.iter_mut().zip(slots) {
                let (dx, dy) = PROBE_DIRECTIONS[slot];
                let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                if nx < 0 || nx >= w as i64 || ny < 0 || ny >= h as i64 {
                    continue;
                }
                let nb = (ny * w as i64 + nx) as u32;
                // The cursor: the first entry at or past the neighbour in the visiting order
                // (the neighbours of successive holes move monotonically).
                if forward {
                    while holes[*j] < nb {
                        *j += 1;
                    }
                } else {
                    while holes[*j] > nb {
                        *j -= 1;
                    }
                }
                if holes[*j] == nb {
                    runs[t][slot] = runs[*j][slot].saturating_add(1);
                }
            }
        };
        if forward {
            (0..n).for_each(&mut visit);
        } else {
            (0..n).rev().for_each(&mut visit);
        }
        runs
    };
    let (mut runs, back) = rayon::join(|| pass(true, &earlier), || pass(false, &later));
    for (r, b) in runs.iter_mut().zip(&back) {
        for &s in &later {
            r[s] = b[s];
        }
    }
    runs
}

/// [`FillRule::Background`] takes the farthest side among the directions bracketed within this
/// many times the narrowest bracket of the hole.
pub const BRACKET_SPAN_RATIO: f32 = 4.0;

/// [`FillRule::Background`] averages the far sides that lie within this relative step of the
/// farthest one, `(z_far - z) <= FAR_SIDE_SPREAD (1 - z_far)`: within a factor 1.25 in linear
/// depth (the step form of [`crate::sampling::DEPTH_CONTINUITY`]), i.e. on the uncovered surface.
pub const FAR_SIDE_SPREAD: f32 = 0.25;

/// The four probe directions of [`fill_holes`] (each probed both ways): horizontal, vertical and
/// both diagonals.
pub const FILL_DIRECTIONS: [(i64, i64); 4] = [(1, 0), (0, 1), (1, 1), (1, -1)];

/// The [`FillRule`] decision for one hole: `probe(dx, dy)` returns the nearest converged pixel
/// along `(dx, dy)` within the radius as `(steps, depth)`. Shared by [`fill_holes`] and sparse
/// callers (soft shadows fill only the texels they look up), so both apply the same rule.
pub fn hole_fill(rule: FillRule, probe: impl Fn(i64, i64) -> Option<(i64, f32)>) -> Option<f32> {
    match rule {
        FillRule::Nearest => {
            let mut best: Option<(f32, f32)> = None; // (distance, depth)
            for (dx, dy) in FILL_DIRECTIONS {
                let step = if dx != 0 && dy != 0 { std::f32::consts::SQRT_2 } else { 1.0 };
                let (Some(a), Some(b)) = (probe(dx, dy), probe(-dx, -dy)) else {
                    return None; // not surrounded
                };
                for (k, z) in [a, b] {
                    let d = k as f32 * step;
                    best = match best {
                        Some((bd, bz)) if bd < d || (bd == d && bz >= z) => Some((bd, bz)),
                        _ => Some((d, z)),
                    };
                }
            }
            best.map(|(_, z)| z)
        }
        FillRule::Background => {
            // The far sides of the directions that cross the hole: those bracketed within
            // BRACKET_SPAN_RATIO times the narrowest bracket. A probe that runs much farther
            // goes along the hole (a crack between two layers' samples, a long sliver) to
            // surfaces the hole does not separate. Per direction (span, far side's depth, its
            // distance).
            let mut spans = [(f32::INFINITY, 0.0f32, 0.0f32); 4];
            for (i, (dx, dy)) in FILL_DIRECTIONS.into_iter().enumerate() {
                let step = if dx != 0 && dy != 0 { std::f32::consts::SQRT_2 } else { 1.0 };
                if let (Some(a), Some(b)) = (probe(dx, dy), probe(-dx, -dy)) {
                    let far = if a.1 >= b.1 { a } else { b };
                    spans[i] = ((a.0 + b.0) as f32 * step, far.1, far.0 as f32 * step);
                }
            }
            let narrowest = spans.iter().map(|s| s.0).fold(f32::INFINITY, f32::min);
            let crossing = spans.iter().filter(|s| s.0.is_finite() && s.0 <= BRACKET_SPAN_RATIO * narrowest);
            let farthest = crossing.clone().map(|s| s.1).reduce(f32::max)?;
            // The uncovered surface is the farthest side; the far sides on that surface (within
            // FAR_SIDE_SPREAD) are averaged, nearer ones weighing more, so the fill follows the
            // surface across the hole instead of copying one direction's pixel in streaks. As
            // offsets from the farthest, so that equal sides give their depth exactly.
            let (mut num, mut den) = (0.0f32, 0.0f32);
            for s in crossing.filter(|s| farthest - s.1 <= FAR_SIDE_SPREAD * (1.0 - farthest)) {
                num += (farthest - s.1) / s.2;
                den += 1.0 / s.2;
            }
            Some(farthest - num / den)
        }
    }
}

/// The source's empty background as a [`MotionSource`]: a sample exists only on texels where
/// no layer has a surface (all depths `1.0`), nearest sampled, with the motion the motion field
/// gives them (`zwarp_core::motion_field` moves an empty pixel as the point on the far plane,
/// i.e. with the camera's rotation and, negligibly, its translation) and the far depth.
struct EmptyBackground<'a> {
    layers: &'a [WarpLayer<'a>],
    motion: &'a [Motion],
    w: u32,
    h: u32,
}

impl MotionSource for EmptyBackground<'_> {
    type Walk = ();
    #[inline]
    fn sample(&self, q: Vec2, _walk: &mut ()) -> Option<Sample> {
        if !(q.x >= 0.0 && q.y >= 0.0 && q.x < self.w as f32 && q.y < self.h as f32) {
            return None;
        }
        let i = (q.y as u32).min(self.h - 1) as usize * self.w as usize + (q.x as u32).min(self.w - 1) as usize;
        self.layers.iter().all(|l| l.depth.data()[i] >= EMPTY_DEPTH).then_some(Sample {
            v: self.motion[i].v,
            depth: EMPTY_DEPTH,
            tag: 0,
            dv: [Vec2::ZERO; 2],
            dz: Vec2::ZERO,
            smooth: false,
        })
    }
}

/// How wide the holes of a warp from `layers` can be, for [`fill_background`]'s steps 2 and 3
/// (and their WGSL twin, which gets them from here).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BackgroundLimits {
    /// Bracket radius of step 2: the motion range of the source surfaces (largest minus
    /// smallest motion, per axis, the larger) plus one pixel, at most the caller's radius — no
    /// disocclusion opens wider than the motions of its two sides differ.
    pub bracket: u32,
    /// Reach of step 3: the largest motion of a source surface plus one pixel (at most the
    /// image size) — no border strip is wider.
    pub reach: u32,
}

impl BackgroundLimits {
    /// Validates the inputs of [`fill_background`] for a `w x h` warped buffer (at least one
    /// layer, every layer `w x h`, finite motion everywhere, `radius` in 1..=64) and measures the
    /// limits over the surfaces (source depth `< 1`) of every layer.
    pub fn of(layers: &[WarpLayer<'_>], w: u32, h: u32, radius: u32) -> Result<Self> {
        Self::of_multisampled(layers, w, h, 1, radius)
    }

    /// [`Self::of`] for source layers that hold `m x m` samples per pixel of the `w x h` warped
    /// buffer ([`crate::WarpParams::multisample`]): every layer is `m w x m h`, and the limits,
    /// measured in source samples, are converted to target pixels (rounded up).
    pub fn of_multisampled(layers: &[WarpLayer<'_>], w: u32, h: u32, m: u32, radius: u32) -> Result<Self> {
        if layers.is_empty() {
            return Err(Error::invalid("fill_background needs at least one source layer"));
        }
        if !(1..=64).contains(&radius) {
            return Err(Error::invalid(format!("fill_background: radius must be in 1..=64, got {radius}")));
        }
        // One parallel pass per layer: every motion finite, and the motion range of the surfaces.
        let (mut lo, mut hi) = (Vec2::INFINITY, Vec2::NEG_INFINITY);
        let (sw, sh) = (w as u64 * m as u64, h as u64 * m as u64);
        for (k, l) in layers.iter().enumerate() {
            let (dw, dh) = l.depth.size();
            let (mw, mh) = l.motion.size();
            if (dw as u64, dh as u64) != (sw, sh) || (mw, mh) != (dw, dh) {
                let per = if m == 1 { String::new() } else { format!(" with {m}x{m} samples per pixel") };
                return Err(Error::invalid(format!(
                    "fill_background: source layer {k} is {dw}x{dh} but the warped buffer is {w}x{h}{per}"
                )));
            }
            let empty = || (true, Vec2::INFINITY, Vec2::NEG_INFINITY);
            let (finite, l_lo, l_hi) = l
                .depth
                .data()
                .par_iter()
                .zip(l.motion.data())
                .fold(empty, |(ok, lo, hi), (d, m)| match (m.v.is_finite(), *d < EMPTY_DEPTH) {
                    (false, _) => (false, lo, hi),
                    (true, true) => (ok, lo.min(m.v), hi.max(m.v)),
                    (true, false) => (ok, lo, hi),
                })
                .reduce(empty, |a, b| (a.0 && b.0, a.1.min(b.1), a.2.max(b.2)));
            if !finite {
                return Err(Error::invalid(format!("fill_background: source layer {k} holds non-finite motion")));
            }
            (lo, hi) = (lo.min(l_lo), hi.max(l_hi));
        }
        Ok(Self::from_range(lo, hi, w, h, m, radius))
    }

    /// The limits from the motion range of the surfaces that the layers' preparation measured
    /// ([`crate::PreparedLayer::surfaces`]): the same values as [`Self::of_multisampled`] on the
    /// layers `prepared` was built from, without another pass over them.
    pub fn of_prepared(prepared: &[crate::PreparedLayer], w: u32, h: u32, m: u32, radius: u32) -> Result<Self> {
        if prepared.is_empty() {
            return Err(Error::invalid("fill_background needs at least one source layer"));
        }
        if !(1..=64).contains(&radius) {
            return Err(Error::invalid(format!("fill_background: radius must be in 1..=64, got {radius}")));
        }
        let (mut lo, mut hi) = (Vec2::INFINITY, Vec2::NEG_INFINITY);
        for (k, l) in prepared.iter().enumerate() {
            let (dw, dh) = l.size();
            if (dw as u64, dh as u64) != (w as u64 * m as u64, h as u64 * m as u64) {
                return Err(Error::invalid(format!(
                    "fill_background: source layer {k} is {dw}x{dh} but the warped buffer is {w}x{h}"
                )));
            }
            let s = l.surfaces();
            if !s.all_finite {
                return Err(Error::invalid(format!("fill_background: source layer {k} holds non-finite motion")));
            }
            (lo, hi) = (lo.min(s.lo), hi.max(s.hi));
        }
        Ok(Self::from_range(lo, hi, w, h, m, radius))
    }

    /// The limits from the surfaces' motion range `[lo, hi]` (source samples).
    fn from_range(lo: Vec2, hi: Vec2, w: u32, h: u32, m: u32, radius: u32) -> Self {
        // Source samples -> target pixels (m = 1: unchanged).
        let (range, largest) = if lo.x <= hi.x {
            ((hi - lo).max_element() / m as f32, lo.abs().max(hi.abs()).max_element() / m as f32)
        } else {
            (0.0, 0.0)
        };
        let bracket = (range.ceil().min(64.0) as u32 + 1).min(radius);
        let reach = (largest.ceil().min(u32::MAX as f32 - 1.0) as u32).saturating_add(1).min(w.max(h));
        BackgroundLimits { bracket, reach }
    }
}

/// The multisampling factor m of `layers` for a warped buffer `w` pixels wide, as
/// [`fill_background`] and its WGSL twin read it: the width ratio when it is a whole number,
/// else 1. A height that does not match (`m h`) is then rejected by
/// [`BackgroundLimits::of_multisampled`].
pub fn source_multisample(layers: &[WarpLayer<'_>], w: u32) -> u32 {
    let sw = layers.first().map_or(w, |l| l.depth.width());
    if w > 0 && sw.is_multiple_of(w) {
        (sw / w).max(1)
    } else {
        1
    }
}

/// Seeds of the background search for target pixel `p`: the pixel itself and the pixel moved
/// back by the motion found there (`back`; the fixed point of a smooth field lies next to
/// `p - v(p)`), both clamped into the `w x h` image.
#[inline]
pub fn background_seeds(p: Vec2, back: Vec2, w: u32, h: u32) -> [Vec2; 2] {
    let max_q = Vec2::new(w as f32, h as f32) - Vec2::splat(1e-3);
    [p.clamp(Vec2::ZERO, max_q), (p - back).clamp(Vec2::ZERO, max_q)]
}

/// Sec. 4's quality protocol for holes ("filled with the background depth"), made to hold on
/// open scenes and at the image border; the complete form of [`HolePolicy::Background`] for
/// callers that have the source layers (`layers`: the depth and motion buffers `out` was warped
/// from, nearest first; a separately peeled ground counts as a layer; a multisampled source,
/// [`crate::WarpParams::multisample`] = m, is `m` times `out`'s size on both axes, and the
/// ratio gives m). Four steps over the [`PixelState::Hole`] pixels of `out`:
///
/// 0. **Lone revealed pixels** ([`lone_revealed`]): a pixel a deeper layer revealed
///    ([`WarpOutput::revealed`]) beside a hole, farther than every converged neighbour and on
///    the surface of none, becomes a hole (and leaves `revealed`). Sec. 3.4 lets a deeper layer
///    fill what the front layers disocclude; a disocclusion is a region, on a surface that
///    continues beside it. A lone hit is a seed that found a hidden surface through a gap the
///    front layers' searches left (a surface split between two peeled layers, neither search
///    converging on its part); kept, the next step would spread it over the holes around it as
///    their far side.
/// 1. **Background seen through**: a hole whose fixed-point search (the one [`fixed_point_search`],
///    `search`'s T and threshold; seeds [`background_seeds`]) converges on texels where no
///    source layer has a surface shows the empty background the source shows there — sky: it
///    keeps the far depth and becomes [`PixelState::Converged`] (it did converge, on an empty
///    sample). Without this step a sky pixel between two surfaces would be filled with the
///    farther surface.
/// 2. **Bracketed holes**: [`fill_holes`] with [`FillRule::Background`] (disocclusion slivers
///    take the farther side) within [`BackgroundLimits::bracket`].
/// 3. **Image border**: a hole whose row (or column) runs to the image border, where the source
///    has no pixels (the strip a moving camera uncovers), takes the depth of the nearest
///    converged pixel inwards along that row or column, within [`BackgroundLimits::reach`].
///    Converged background pixels count, so sky at the border stays sky.
///
/// Not conservative (a fill may be nearer than the truth): for quality, never for culling.
/// Errors as [`BackgroundLimits::of`]. The WGSL twin is `gpu::HoleFillKernel::fill_background`.
pub fn fill_background(
    layers: &[WarpLayer<'_>],
    out: &mut WarpOutput,
    radius: u32,
    search: &SearchParams,
) -> Result<()> {
    let (w, h) = out.depth.size();
    let m = source_multisample(layers, w);
    let limits = BackgroundLimits::of_multisampled(layers, w, h, m, radius)?;
    fill_background_with(layers, out, limits, search)
}

/// [`fill_background`] with the limits already measured, e.g. by
/// [`BackgroundLimits::of_prepared`] from the layers' preparation (which read every sample
/// already): the fill then reads only the holes and their neighbourhoods. `layers` must have
/// passed [`BackgroundLimits::of_multisampled`]'s checks (sizes, finite motion).
pub fn fill_background_with(
    layers: &[WarpLayer<'_>],
    out: &mut WarpOutput,
    limits: BackgroundLimits,
    search: &SearchParams,
) -> Result<()> {
    let (w, h) = out.depth.size();
    if w == 0 || h == 0 || layers.is_empty() {
        return Ok(());
    }
    let (sw, sh) = layers[0].depth.size();
    let m = source_multisample(layers, w);
    if (sw, sh) != (w * m, h * m) || layers.iter().any(|l| l.depth.size() != (sw, sh) || l.motion.size() != (sw, sh)) {
        return Err(Error::invalid(format!(
            "fill_background: the source layers are not {m} x the {w}x{h} warped buffer on both axes"
        )));
    }
    if w as u64 * h as u64 > u32::MAX as u64 {
        return Err(Error::invalid(format!("fill_background: {w}x{h} is more than 2^32 pixels")));
    }
    check_revealed(&out.state, &out.revealed)?;
    // 0. Lone revealed pixels become holes.
    let lone = lone_revealed(&out.depth, &out.state, &out.revealed);
    if !lone.is_empty() {
        let (dd, sd) = (out.depth.data_mut(), out.state.data_mut());
        for &i in &lone {
            dd[i as usize] = EMPTY_DEPTH;
            sd[i as usize] = PixelState::Hole;
        }
        out.revealed.retain(|i| lone.binary_search(i).is_err());
    }
    // 1. Holes that see the source's empty background, decided band by band of rows: the band's
    // holes listed, searched eight at a time, marked and narrowed while its rows are in cache
    // (most holes are sky, in long runs along rows). What remains is the list of steps 2 and 3.
    let bg = EmptyBackground { layers, motion: layers[0].motion.data(), w: sw, h: sh };
    let mf = m as f32;
    let band = w as usize * HOLE_BAND_ROWS;
    let bands: Vec<Vec<u32>> = out
        .depth
        .data_mut()
        .par_chunks_mut(band)
        .zip(out.state.data_mut().par_chunks_mut(band))
        .enumerate()
        .map(|(b, (dd, sd))| {
            let base = (b * band) as u32;
            let holes = holes_in(sd, base);
            let mut rest = Vec::new();
            let mut decide = |i: u32, sky: bool| {
                if sky {
                    let j = (i - base) as usize;
                    dd[j] = EMPTY_DEPTH;
                    sd[j] = PixelState::Converged;
                } else {
                    rest.push(i);
                }
            };
            let mut done = 0;
            #[cfg(target_arch = "x86_64")]
            if crate::simd::has_avx2() && layers.len() <= 8 {
                let mut depths = [&[][..]; 8];
                for (d, l) in depths.iter_mut().zip(layers) {
                    *d = l.depth.data();
                }
                let depths = &depths[..layers.len()];
                while done + 8 <= holes.len() {
                    let idx: &[u32; 8] = holes[done..done + 8].try_into().expect("eight");
                    // SAFETY: AVX2 checked; the buffers are sw * sh long.
                    let bits = unsafe { crate::simd_warp::background8(depths, bg.motion, sw, sh, w, mf, idx, search) };
                    for (k, &i) in idx.iter().enumerate() {
                        decide(i, bits >> k & 1 != 0);
                    }
                    done += 8;
                }
            }
            for &i in &holes[done..] {
                decide(i, background_converges(&bg, i % w, i / w, mf, search));
            }
            rest
        })
        .collect();
    let mut holes = bands.concat();
    // 2. Bracketed holes.
    fill_holes_listed(&mut out.depth, &mut out.state, &holes, limits.bracket, FillRule::Background);
    // 3. Holes open to the image border.
    let state = out.state.data();
    holes.retain(|&i| state[i as usize] == PixelState::Hole);
    fill_border_listed(&mut out.depth, &mut out.state, &holes, limits.reach);
    Ok(())
}

/// Errors unless every `revealed` pixel ([`WarpOutput::revealed`]) is a converged one of
/// `state` ([`fill_background`] and its WGSL twin check alike).
pub(crate) fn check_revealed(state: &Image<PixelState>, revealed: &[u32]) -> Result<()> {
    if revealed.iter().any(|&i| state.data().get(i as usize) != Some(&PixelState::Converged)) {
        return Err(Error::invalid("fill_background: a revealed pixel is not a converged one"));
    }
    Ok(())
}

/// Step 0 of [`fill_background`]: the `revealed` pixels ([`WarpOutput::revealed`], ascending)
/// that stand alone beside a hole: an 8-neighbour is a [`PixelState::Hole`], at least one is
/// converged, and every converged one is nearer by more than [`FAR_SIDE_SPREAD`] (none lies on
/// the pixel's surface). Ascending. Decided from the unchanged buffers.
pub fn lone_revealed(depth: &Image<f32>, state: &Image<PixelState>, revealed: &[u32]) -> Vec<u32> {
    let (w, h) = depth.size();
    let (dd, sd) = (depth.data(), state.data());
    revealed
        .iter()
        .copied()
        .filter(|&i| {
            let (x, y) = (i % w, i / w);
            let z = dd[i as usize];
            let (mut hole, mut nearer) = (false, false);
            for ny in y.saturating_sub(1)..=(y + 1).min(h - 1) {
                for nx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
                    let j = (ny * w + nx) as usize;
                    if j == i as usize {
                        continue;
                    }
                    match sd[j] {
                        PixelState::Hole => hole = true,
                        PixelState::Converged if z - dd[j] <= FAR_SIDE_SPREAD * (1.0 - z) => return false,
                        PixelState::Converged => nearer = true,
                        PixelState::Filled => {}
                    }
                }
            }
            hole && nearer
        })
        .collect()
}

/// Step 1 of [`fill_background`] for target pixel `(x, y)`: does the search on the empty
/// background converge? (Its candidate is always the far depth.)
#[inline]
fn background_converges(bg: &EmptyBackground<'_>, x: u32, y: u32, mf: f32, search: &SearchParams) -> bool {
    // The target pixel's centre in source samples, and the sample it falls in.
    let p = Vec2::new(x as f32 + 0.5, y as f32 + 0.5) * mf;
    let (qx, qy) = (p.x as usize, p.y as usize);
    let seeds = background_seeds(p, bg.motion[qy * bg.w as usize + qx].v, bg.w, bg.h);
    // Exactly T iterations, as the AVX2 and WGSL builds of this test walk.
    let search = SearchParams { extra_iterations: 0, ..*search };
    fixed_point_search(bg, p, &seeds, &search).is_some()
}

/// Step 3 of [`fill_background`]: holes whose row or column reaches the image border within
/// `reach` pixels take the depth of the nearest converged pixel inwards (within `reach`);
/// the nearest of up to four such pixels wins (ties: the farther depth). Only converged pixels
/// are read, so the result does not depend on the processing order.
pub fn fill_border_holes(depth: &mut Image<f32>, state: &mut Image<PixelState>, reach: u32) {
    let holes = hole_list(state);
    fill_border_listed(depth, state, &holes, reach);
}

/// [`fill_border_holes`] of the listed holes: only a hole within `reach` of a border can be
/// filled, from a converged pixel within `reach` of it, so only the border strips `2 reach`
/// wide are scanned for each row's and column's first and last converged pixel.
fn fill_border_listed(depth: &mut Image<f32>, state: &mut Image<PixelState>, holes: &[u32], reach: u32) {
    let (w, h) = depth.size();
    let (wu, hu) = (w as usize, h as usize);
    let reach = reach as usize;
    let holes: Vec<u32> = holes
        .iter()
        .copied()
        .filter(|&i| {
            let (x, y) = ((i % w) as usize, (i / w) as usize);
            x < reach || y < reach || wu - 1 - x < reach || hu - 1 - y < reach
        })
        .collect();
    if holes.is_empty() {
        return;
    }
    let (dd, sd) = (depth.data(), state.data());
    let conv = |i: usize| sd[i] == PixelState::Converged;
    // The run from a hole to the border holds no converged pixel exactly when the hole lies
    // before the first (after the last) converged pixel of its row or column, and then that
    // pixel is the nearest converged one inwards. A usable one lies within 2 reach of the
    // border; a run that finds none there stands for "none usable". Found once per row and
    // column (the columns a row at a time, in memory order), not per hole.
    let span = (2 * reach).min(wu.max(hu));
    let (sw, sh) = (span.min(wu), span.min(hu));
    // The rows and columns that hold listed holes.
    let (mut in_row, mut in_col) = (vec![false; hu], vec![false; wu]);
    for &i in &holes {
        in_row[(i / w) as usize] = true;
        in_col[(i % w) as usize] = true;
    }
    let row_ends: Vec<(Option<usize>, Option<usize>)> = (0..hu)
        .into_par_iter()
        .map(|y| {
            if !in_row[y] {
                return (None, None);
            }
            let at = |k: usize| conv(y * wu + k);
            ((0..sw).find(|&k| at(k)), (0..sw).map(|k| wu - 1 - k).find(|&k| at(k)))
        })
        .collect();
    let cols: Vec<usize> = (0..wu).filter(|&x| in_col[x]).collect();
    let col_end = |rows: &mut dyn Iterator<Item = usize>| {
        let mut end: Vec<Option<usize>> = vec![None; wu];
        let mut left = cols.len();
        for y in rows {
            for &x in &cols {
                if end[x].is_none() && conv(y * wu + x) {
                    end[x] = Some(y);
                    left -= 1;
                }
            }
            if left == 0 {
                break;
            }
        }
        end
    };
    let (col_first, col_last) = rayon::join(|| col_end(&mut (0..sh)), || col_end(&mut (0..sh).map(|k| hu - 1 - k)));
    let fills: Vec<(u32, f32)> = holes
        .par_iter()
        .filter_map(|&i| {
            let (x, y) = ((i % w) as usize, (i / w) as usize);
            let (first_row, last_row) = row_ends[y];
            // (distance to the border, the converged pixel inwards and its distance) for the
            // left, right, top and bottom borders.
            let sides = [
                (x, first_row.filter(|&c| c > x).map(|c| (c - x, y * wu + c))),
                (wu - 1 - x, last_row.filter(|&c| c < x).map(|c| (x - c, y * wu + c))),
                (y, col_first[x].filter(|&c| c > y).map(|c| (c - y, c * wu + x))),
                (hu - 1 - y, col_last[x].filter(|&c| c < y).map(|c| (y - c, c * wu + x))),
            ];
            let mut best: Option<(usize, f32)> = None;
            for (to_border, inward) in sides {
                let Some((k, j)) = inward else { continue };
                if to_border >= reach || k > reach {
                    continue;
                }
                let z = dd[j];
                if best.is_none_or(|(bk, bz)| k < bk || (k == bk && z > bz)) {
                    best = Some((k, z));
                }
            }
            best.map(|(_, z)| (i, z))
        })
        .collect();
    let (dd, sd) = (depth.data_mut(), state.data_mut());
    for (i, z) in fills {
        dd[i as usize] = z;
        sd[i as usize] = PixelState::Filled;
    }
}

/// AWOC fill (Sec. 5.3) for one pixel: the nearest valid target depth among `fetch(q)` at the
/// four corners `corners` of the local search region (image coordinates, clamped to the image
/// by the caller). Returns `None` if none of them is a surface.
#[inline]
pub fn awoc_depth(corners: &[Vec2; 4], mut fetch: impl FnMut(Vec2) -> Option<f32>) -> Option<f32> {
    let mut best = EMPTY_DEPTH;
    for &q in corners {
        if let Some(z) = fetch(q) {
            best = best.min(z);
        }
    }
    (best < EMPTY_DEPTH).then_some(best)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(rows: &[&str]) -> (Image<f32>, Image<PixelState>) {
        let (w, h) = (rows[0].len() as u32, rows.len() as u32);
        let d = Image::from_fn(w, h, |x, y| {
            let c = rows[y as usize].as_bytes()[x as usize];
            if c == b'.' {
                1.0
            } else {
                (c - b'0') as f32 / 10.0
            }
        });
        let s = Image::from_fn(w, h, |x, y| {
            if rows[y as usize].as_bytes()[x as usize] == b'.' {
                PixelState::Hole
            } else {
                PixelState::Converged
            }
        });
        (d, s)
    }

    /// The border fill (first and last converged pixel of each row and column found once)
    /// equals its definition walked per hole: a hole within `reach` of a border whose run to
    /// that border holds no converged pixel takes the nearest converged pixel inwards within
    /// `reach` (of up to four, ties to the farther depth); random images, reaches below and
    /// above the image size, holes on every side.
    #[test]
    fn border_fill_equals_its_definition_per_hole() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_pcg::Pcg32::seed_from_u64(5);
        for (w, h, p_hole) in [(1u32, 1u32, 0.5f32), (9, 4, 0.6), (40, 30, 0.8), (300, 5, 0.95), (17, 61, 0.9)] {
            let depth = Image::from_fn(w, h, |_, _| rng.random_range(0.1..0.99f32));
            let state = Image::from_fn(w, h, |_, _| {
                if rng.random::<f32>() < p_hole {
                    PixelState::Hole
                } else {
                    PixelState::Converged
                }
            });
            for reach in [1u32, 2, 5, 40, 400] {
                let (mut d, mut s) = (depth.clone(), state.clone());
                fill_border_holes(&mut d, &mut s, reach);
                let (dd, sd) = (depth.data(), state.data());
                let (mut want, mut want_state) = (depth.clone(), state.clone());
                let conv = |x: i64, y: i64| sd[y as usize * w as usize + x as usize] == PixelState::Converged;
                for i in hole_list(&state) {
                    let (x, y) = ((i % w) as i64, (i / w) as i64);
                    let mut best: Option<(i64, f32)> = None;
                    for (dx, dy) in [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)] {
                        // Distance to the border along (dx, dy), and nothing converged on the way.
                        let to_border = (0..).take_while(|&k| {
                            let (xx, yy) = (x + dx * (k + 1), y + dy * (k + 1));
                            xx >= 0 && yy >= 0 && xx < w as i64 && yy < h as i64
                        });
                        let steps = to_border.count() as i64;
                        let open = (1..=steps).all(|k| !conv(x + dx * k, y + dy * k));
                        if steps >= reach as i64 || !open {
                            continue;
                        }
                        // The nearest converged pixel inwards, within reach.
                        let inward = (1..=reach as i64)
                            .map(|k| (k, x - dx * k, y - dy * k))
                            .take_while(|&(_, xx, yy)| xx >= 0 && yy >= 0 && xx < w as i64 && yy < h as i64)
                            .find(|&(_, xx, yy)| conv(xx, yy));
                        if let Some((k, xx, yy)) = inward {
                            let z = dd[yy as usize * w as usize + xx as usize];
                            if best.is_none_or(|(bk, bz)| k < bk || (k == bk && z > bz)) {
                                best = Some((k, z));
                            }
                        }
                    }
                    if let Some((_, z)) = best {
                        want.data_mut()[i as usize] = z;
                        want_state.data_mut()[i as usize] = PixelState::Filled;
                    }
                }
                let bits = |im: &Image<f32>| im.data().iter().map(|z| z.to_bits()).collect::<Vec<_>>();
                assert!(bits(&d) == bits(&want), "{w}x{h} reach {reach}");
                assert!(s.data() == want_state.data(), "{w}x{h} reach {reach}");
            }
        }
    }

    /// The hole fill that skips runs of listed holes gives exactly what walking every probe
    /// step by step gives: random images of converged pixels, holes (listed) and pixels filled
    /// by an earlier pass (not listed, walked over), both rules, radii below and above the
    /// runs' saturation, and long runs along every direction.
    #[test]
    fn run_skipping_fill_equals_the_step_by_step_walk() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_pcg::Pcg32::seed_from_u64(11);
        for (w, h, p_hole, p_filled) in [
            (1u32, 1u32, 0.5f32, 0.0f32),
            (7, 5, 0.5, 0.1),
            (40, 30, 0.7, 0.05),
            (300, 4, 0.97, 0.0),
            (23, 61, 0.85, 0.1),
        ] {
            let depth = Image::from_fn(w, h, |_, _| rng.random_range(0.1..0.99f32));
            let state = Image::from_fn(w, h, |_, _| {
                let u: f32 = rng.random();
                if u < p_hole {
                    PixelState::Hole
                } else if u < p_hole + p_filled {
                    PixelState::Filled
                } else {
                    PixelState::Converged
                }
            });
            for rule in [FillRule::Nearest, FillRule::Background] {
                for radius in [1u32, 3, 64, 300] {
                    let (mut d, mut s) = (depth.clone(), state.clone());
                    fill_holes(&mut d, &mut s, radius, rule);
                    // The walk of every probe from step 1.
                    let (dd, sd) = (depth.data(), state.data());
                    let (mut want, mut want_state) = (depth.clone(), state.clone());
                    for i in hole_list(&state) {
                        let (x, y) = ((i % w) as i64, (i / w) as i64);
                        let probe = |dx: i64, dy: i64| {
                            (1..=radius as i64)
                                .map(|k| (x + dx * k, y + dy * k))
                                .take_while(|&(xx, yy)| xx >= 0 && yy >= 0 && xx < w as i64 && yy < h as i64)
                                .enumerate()
                                .find_map(|(k, (xx, yy))| {
                                    let j = yy as usize * w as usize + xx as usize;
                                    (sd[j] == PixelState::Converged).then_some((k as i64 + 1, dd[j]))
                                })
                        };
                        if let Some(z) = hole_fill(rule, probe) {
                            want.data_mut()[i as usize] = z;
                            want_state.data_mut()[i as usize] = PixelState::Filled;
                        }
                    }
                    let bits = |im: &Image<f32>| im.data().iter().map(|z| z.to_bits()).collect::<Vec<_>>();
                    assert!(bits(&d) == bits(&want), "{w}x{h} {rule:?} radius {radius}");
                    assert!(s.data() == want_state.data(), "{w}x{h} {rule:?} radius {radius}");
                }
            }
        }
    }

    #[test]
    fn dilation_fills_enclosed_holes_with_nearest_neighbour_only() {
        let (mut d, mut s) = grid(&["55555", "55.55", "55555", "5....", "55555"]);
        dilate_holes(&mut d, &mut s, 1);
        // The enclosed hole at (2, 1) is filled with its neighbours' depth.
        assert_eq!(*s.get(2, 1), PixelState::Filled);
        assert_eq!(*d.get(2, 1), 0.5);
        // The open band on row 3 reaching the border stays a hole where not surrounded.
        assert_eq!(*s.get(4, 3), PixelState::Hole);
        assert_eq!(*d.get(4, 3), 1.0);
    }

    #[test]
    fn dilation_prefers_the_nearest_and_then_the_farther_depth() {
        // Hole at (2,2): left neighbour 0.3 at distance 1, right 0.7 at distance 1: tie -> 0.7.
        let (mut d, mut s) = grid(&["77777", "77777", "73.77", "77777", "77777"]);
        dilate_holes(&mut d, &mut s, 2);
        assert_eq!(*d.get(2, 2), 0.7);
        // 2-wide hole with radius 1 is not surrounded; radius 2 is.
        let (mut d, mut s) = grid(&["666666", "666666", "66..66", "666666", "666666"]);
        dilate_holes(&mut d.clone(), &mut s.clone(), 1);
        let (mut d1, mut s1) = (d.clone(), s.clone());
        dilate_holes(&mut d1, &mut s1, 1);
        assert_eq!(*s1.get(2, 2), PixelState::Hole);
        dilate_holes(&mut d, &mut s, 2);
        assert_eq!((*s.get(2, 2), *d.get(2, 2)), (PixelState::Filled, 0.6));
    }

    #[test]
    fn background_fill_takes_the_farther_side_of_a_sliver_and_leaves_open_holes() {
        // A 2-px disocclusion sliver between a near occluder (0.2) and the uncovered far surface
        // (0.8): bracketed horizontally, filled with 0.8 even though 0.2 is as near.
        let (mut d, mut s) = grid(&["22..88", "22..88", "22..88"]);
        fill_holes(&mut d, &mut s, 2, FillRule::Background);
        for y in 0..3 {
            assert_eq!((*s.get(2, y), *d.get(2, y), *d.get(3, y)), (PixelState::Filled, 0.8, 0.8));
        }
        // Radius 1 does not bracket a 2-px sliver; the Fig. 8 rule (all four directions) would
        // not fill it either.
        let (mut d1, mut s1) = grid(&["22..88", "22..88", "22..88"]);
        fill_holes(&mut d1, &mut s1, 1, FillRule::Background);
        assert_eq!((*s1.get(2, 1), *d1.get(2, 1)), (PixelState::Hole, 1.0));
        let (mut d2, mut s2) = grid(&["22..88", "22..88", "22..88"]);
        dilate_holes(&mut d2, &mut s2, 2);
        assert_eq!(*s2.get(2, 1), PixelState::Hole);
        // A hole open to the border (sky beside a surface) is never bracketed: stays far.
        let (mut d3, mut s3) = grid(&["55...", "55...", "55..."]);
        fill_holes(&mut d3, &mut s3, 4, FillRule::Background);
        assert!(s3.data().iter().filter(|&&st| st == PixelState::Filled).count() == 0);
    }

    #[test]
    fn background_fill_averages_the_far_sides_on_the_uncovered_surface() {
        // Horizontal bracket: far side 0.90 one pixel away; vertical: 0.91 two pixels away (the
        // uncovered surface, within FAR_SIDE_SPREAD of the farthest); one diagonal: 0.3 both
        // ways (the occluder side, left out); the other diagonal is not bracketed.
        let probe = |dx: i64, dy: i64| match (dx, dy) {
            (1, 0) => Some((1, 0.90)),
            (-1, 0) | (0, -1) => Some((1, 0.5)),
            (0, 1) => Some((2, 0.91)),
            (1, -1) | (-1, 1) => Some((1, 0.3)),
            _ => None,
        };
        let z = hole_fill(FillRule::Background, probe).unwrap();
        // Inverse-distance weights 1 and 1/2: 0.91 - (0.01 / 1) / (1 + 1/2).
        assert!((z - (0.91 - 0.01 / 1.5)).abs() < 1e-6, "{z}");
        // Equal far sides give their depth exactly, whatever their distances.
        let equal = |dx: i64, dy: i64| if dx == 0 { Some((1 + dy.abs(), 0.7)) } else { Some((3, 0.7)) };
        assert_eq!(hole_fill(FillRule::Background, equal), Some(0.7));
    }

    #[test]
    fn background_fill_crosses_a_crack_along_its_narrow_axis() {
        // A 1-px crack down a surface at 0.4 whose ends touch a far surface (0.9): across the
        // crack both sides are 0.4 (span 2); along it the probes reach 0.9 (span 11, more than
        // BRACKET_SPAN_RATIO times 2). The crack belongs to the surface it splits (its end rows
        // touch the far surface diagonally, within the ratio).
        let mut rows = vec!["9999999"];
        rows.extend(std::iter::repeat_n("444.444", 10));
        rows.push("9999999");
        let (mut d, mut s) = grid(&rows);
        fill_holes(&mut d, &mut s, 16, FillRule::Background);
        for y in 2..10 {
            assert_eq!((*s.get(3, y), *d.get(3, y)), (PixelState::Filled, 0.4), "row {y}");
        }
        // A short hole (span 5 along, 2 across) is crossed both ways: the farthest side wins.
        let (mut d, mut s) = grid(&["9999999", "444.444", "444.444", "444.444", "444.444", "9999999"]);
        fill_holes(&mut d, &mut s, 8, FillRule::Background);
        assert_eq!((*s.get(3, 2), *d.get(3, 2)), (PixelState::Filled, 0.9));
    }

    /// A `w x h` source layer from per-pixel `(depth, motion x)` (motion y = 0); a pixel's
    /// target depth is its source depth (pure screen-space shift).
    fn shifted_layer(w: u32, h: u32, f: impl Fn(u32, u32) -> (f32, f32)) -> (Image<f32>, Image<Motion>) {
        let d = Image::from_fn(w, h, |x, y| f(x, y).0);
        let m = Image::from_fn(w, h, |x, y| {
            let (z, vx) = f(x, y);
            Motion { v: Vec2::new(vx, 0.0), depth: z }
        });
        (d, m)
    }

    fn background_fill(d: &Image<f32>, m: &Image<Motion>) -> WarpOutput {
        let layers = [WarpLayer { depth: d, motion: m }];
        let params = crate::WarpParams { holes: HolePolicy::FarDepth, ..Default::default() };
        let mut out = crate::warp_depth(&layers, &params).unwrap();
        let search = crate::WarpParams::default().search();
        fill_background(&layers, &mut out, 4, &search).unwrap();
        out
    }

    #[test]
    fn background_fill_keeps_sky_and_extends_the_border_strip() {
        // Camera pans: everything (ground on rows >= 6, sky above, where the motion field gives
        // the far plane's motion) moves 3 px right. The 3-px strip at the left border has no
        // source pixel: on ground rows it takes the row's ground depth, on sky rows it stays sky.
        let ground = |y: u32| 0.6 + 0.01 * y as f32;
        let (d, m) = shifted_layer(24, 12, |_, y| (if y >= 6 { ground(y) } else { EMPTY_DEPTH }, 3.0));
        let out = background_fill(&d, &m);
        for y in 0..12 {
            for x in 0..24 {
                let (z, st) = (*out.depth.get(x, y), *out.state.get(x, y));
                if y < 6 {
                    // Sky: converged on the empty background (x >= 3) or filled from it.
                    assert_eq!(z, EMPTY_DEPTH, "sky at ({x},{y})");
                    assert_eq!(st, if x >= 3 { PixelState::Converged } else { PixelState::Filled });
                } else {
                    assert_eq!(z, ground(y), "ground at ({x},{y})");
                    assert_eq!(st, if x >= 3 { PixelState::Converged } else { PixelState::Filled });
                }
            }
        }
    }

    #[test]
    fn background_fill_does_not_fill_sky_between_two_objects_but_fills_a_disocclusion() {
        // Row layout (static camera): object A (0.3) on x 2..8, sky on 8..10, object B (0.5)
        // on 10..16, a ground (0.8) on 16..24 that B's motion (+2 px) uncovers on 16..18.
        let (d, m) = shifted_layer(24, 6, |x, _| match x {
            2..8 => (0.3, 0.0),
            10..16 => (0.5, 2.0),
            16..24 => (0.8, 0.0),
            _ => (EMPTY_DEPTH, 0.0),
        });
        let out = background_fill(&d, &m);
        for y in 0..6 {
            // The sky gap x 8..10 sees the empty background: far, converged. (The bracketed
            // rule alone would have filled it with B's 0.5.)
            for x in 8..10 {
                assert_eq!((*out.depth.get(x, y), *out.state.get(x, y)), (EMPTY_DEPTH, PixelState::Converged));
            }
            // B moved to 12..18: the sky it uncovers on 10..12 was hidden in the source (no
            // empty texel to converge on), a hole bracketed by sky and B: the farther side, sky.
            for x in 10..12 {
                assert_eq!((*out.depth.get(x, y), *out.state.get(x, y)), (EMPTY_DEPTH, PixelState::Filled));
            }
            for x in 12..18 {
                assert_eq!(*out.depth.get(x, y), 0.5);
            }
            for x in 18..24 {
                assert_eq!(*out.depth.get(x, y), 0.8);
            }
        }
        // A 2-px disocclusion of the ground: B (0.5) moves left by 2 over a static ground.
        let (d, m) = shifted_layer(24, 6, |x, _| match x {
            8..14 => (0.5, -2.0),
            _ => (0.8, 0.0),
        });
        let out = background_fill(&d, &m);
        for y in 0..6 {
            for x in 12..14 {
                // Bracketed by B (0.5) and the ground (0.8): the farther side.
                assert_eq!((*out.depth.get(x, y), *out.state.get(x, y)), (0.8, PixelState::Filled));
            }
        }
    }

    /// A source sampled on a 3x3 grid per pixel ([`crate::WarpParams::multisample`]) of the same
    /// pixel-aligned scenes (each pixel's value repeated on its 9 samples, motion in samples)
    /// gives the same warp and the same background fill as one sample per pixel: sky kept,
    /// border strips extended (reach converted from samples to pixels). On the disocclusion
    /// scene it gives the analytic answer in every row; with one sample per pixel, B's leading
    /// column sits on the border of its search region and some rows' seeds miss it.
    #[test]
    fn background_fill_of_a_multisampled_source_equals_one_sample_per_pixel() {
        type PixelFn = Box<dyn Fn(u32, u32) -> (f32, f32)>;
        let scenes: [(u32, u32, PixelFn); 3] = [
            (24, 12, Box::new(|_, y| (if y >= 6 { 0.6 + 0.01 * y as f32 } else { EMPTY_DEPTH }, 3.0))),
            (
                24,
                6,
                Box::new(|x, _| match x {
                    2..8 => (0.3, 0.0),
                    10..16 => (0.5, 2.0),
                    16..24 => (0.8, 0.0),
                    _ => (EMPTY_DEPTH, 0.0),
                }),
            ),
            (24, 6, Box::new(|x, _| if (8..14).contains(&x) { (0.5, -2.0) } else { (0.8, 0.0) })),
        ];
        let ms = 3u32;
        for (i, (w, h, f)) in scenes.iter().enumerate() {
            let (d, m) = shifted_layer(*w, *h, f);
            let want = background_fill(&d, &m);
            let (dm, mm) = shifted_layer(w * ms, h * ms, |x, y| {
                let (z, vx) = f(x / ms, y / ms);
                (z, vx * ms as f32)
            });
            let layers = [WarpLayer { depth: &dm, motion: &mm }];
            let params = crate::WarpParams { multisample: ms, ..Default::default() };
            let mut got = crate::warp_depth(&layers, &params).unwrap();
            let limits = BackgroundLimits::of_multisampled(&layers, *w, *h, ms, 4).unwrap();
            assert_eq!(limits, BackgroundLimits::of(&[WarpLayer { depth: &d, motion: &m }], *w, *h, 4).unwrap());
            let search = crate::WarpParams::default().search();
            fill_background(&layers, &mut got, 4, &search).unwrap();
            if i < 2 {
                assert_eq!(got, want, "scene {i}");
                continue;
            }
            // B moved to 6..12; the ground it uncovers on 12..14 is bracketed: the farther side.
            for y in 0..*h {
                for x in 0..*w {
                    let z = if (6..12).contains(&x) { 0.5 } else { 0.8 };
                    let st = if (12..14).contains(&x) { PixelState::Filled } else { PixelState::Converged };
                    assert_eq!((*got.depth.get(x, y), *got.state.get(x, y)), (z, st), "({x},{y})");
                }
            }
        }
    }

    #[test]
    fn background_fill_rejects_mismatched_layers() {
        let (d, m) = shifted_layer(8, 4, |_, _| (0.5, 0.0));
        let mut out = background_fill(&d, &m);
        let (d2, m2) = shifted_layer(7, 4, |_, _| (0.5, 0.0));
        let search = crate::WarpParams::default().search();
        let err = fill_background(&[WarpLayer { depth: &d2, motion: &m2 }], &mut out, 4, &search).unwrap_err();
        assert!(err.to_string().contains("7x4"), "{err}");
        // A multiple of the width but not of the height is no multisampled source.
        let (d3, m3) = shifted_layer(16, 4, |_, _| (0.5, 0.0));
        let err = fill_background(&[WarpLayer { depth: &d3, motion: &m3 }], &mut out, 4, &search).unwrap_err();
        assert!(err.to_string().contains("16x4 but the warped buffer is 8x4 with 2x2 samples"), "{err}");
        assert!(fill_background(&[], &mut out, 4, &search).is_err());
        let layers = [WarpLayer { depth: &d, motion: &m }];
        assert!(fill_background(&layers, &mut out, 0, &search).unwrap_err().to_string().contains("radius"));
        assert!(fill_background(&layers, &mut out, 65, &search).is_err());
        let mut m_nan = m.clone();
        m_nan.get_mut(3, 2).v.x = f32::NAN;
        let err = fill_background(&[WarpLayer { depth: &d, motion: &m_nan }], &mut out, 4, &search).unwrap_err();
        assert!(err.to_string().contains("non-finite"), "{err}");
    }

    /// The warped buffer of [`lone_revealed`]'s tests: holes (`.`) beside far pixels (`9`) on
    /// rows 2, 5 and 8 of a surface at 0.5; the far pixels of rows 2 and 5 are revealed (row 5's
    /// two lie on one surface), row 8's is a front layer's; and its one source layer (a surface
    /// everywhere, motion 0..3.6 px, so no sky and a bracket of 4 px).
    fn lone_revealed_case() -> (WarpOutput, Image<f32>, Image<Motion>) {
        let (depth, state) = grid(&[
            "5555555555",
            "5555555555",
            "5559...555",
            "5555555555",
            "5555555555",
            "5599...555",
            "5555555555",
            "5555555555",
            "5559...555",
            "5555555555",
        ]);
        let revealed = vec![2 * 10 + 3, 5 * 10 + 2, 5 * 10 + 3];
        let (d, m) = shifted_layer(10, 10, |x, _| (0.5, 0.4 * x as f32));
        (WarpOutput { depth, state, source: None, revealed }, d, m)
    }

    #[test]
    fn a_lone_revealed_pixel_joins_the_holes() {
        let (mut out, d, m) = lone_revealed_case();
        assert_eq!(lone_revealed(&out.depth, &out.state, &out.revealed), vec![23]);
        let search = crate::WarpParams::default().search();
        fill_background(&[WarpLayer { depth: &d, motion: &m }], &mut out, 64, &search).unwrap();
        // Row 2: the lone far pixel became a hole, and the row takes the surface around it.
        for x in 3..7 {
            assert_eq!((*out.state.get(x, 2), *out.depth.get(x, 2)), (PixelState::Filled, 0.5), "({x}, 2)");
        }
        // Row 5: a revealed surface two pixels wide stays, and is the far side of the holes.
        assert_eq!(out.revealed, vec![52, 53]);
        assert_eq!((*out.state.get(3, 5), *out.depth.get(3, 5)), (PixelState::Converged, 0.9));
        for x in 4..7 {
            assert_eq!((*out.state.get(x, 5), *out.depth.get(x, 5)), (PixelState::Filled, 0.9), "({x}, 5)");
        }
        // Row 8: a front layer's far pixel is not the step's business.
        assert_eq!((*out.state.get(3, 8), *out.depth.get(3, 8)), (PixelState::Converged, 0.9));
        assert_eq!(*out.depth.get(5, 8), 0.9);
        // A revealed pixel must be a converged one.
        let (mut bad, _, _) = lone_revealed_case();
        bad.revealed = vec![24];
        let err = fill_background(&[WarpLayer { depth: &d, motion: &m }], &mut bad, 64, &search).unwrap_err();
        assert!(err.to_string().contains("not a converged one"), "{err}");
    }

    #[test]
    fn awoc_takes_the_nearest_valid_corner() {
        let c = [Vec2::ZERO, Vec2::X, Vec2::Y, Vec2::ONE];
        let z = awoc_depth(&c, |q| if q == Vec2::ZERO { None } else { Some(0.9 - q.x * 0.1 - q.y * 0.2) });
        assert!((z.unwrap() - 0.6).abs() < 1e-6);
        assert_eq!(awoc_depth(&c, |_| None), None);
    }
}
