//! THE fixed-point search (seed 000 Fig. 3; Bowles et al. 2012, seed 001 Sec. 3.2), one
//! generic kernel for every backward warp (depth now; colour warping and AWOC reuse it).
//!
//! For a target position `p`, iterate `q_{i+1} = p - v(q_i)` from each seed for at most T
//! iterations; a seed *converges* at `q_i` when `|q_{i+1} - q_i| < threshold`, i.e. when
//! `|q_i + v(q_i) - p| < threshold`; the candidate is then the sample at `q_i` (its target
//! depth). Among converged seeds the [`CandidateChoice`] picks one (paper: minimal depth, which
//! resolves overlaps in favour of the visible surface). A seed fails when an iterate leaves the
//! image or lands on an empty sample (Fig. 3's `s.z < 1` loop condition), or after T
//! iterations without convergence. What a sample is and how a layer's motion is sampled between
//! texel centres is [`crate::sampling`].
//!
//! The kernel is allocation-free: seeds come in a caller-owned slice (stack buffer), the
//! per-seed walk state is a `Default` value of the source's choosing.

use glam::Vec2;

use crate::bounds::{Bound, BoundFrame};
use crate::sampling::{MotionSource, Sample};

/// Which converged seed wins.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum CandidateChoice {
    /// Minimal target depth among converged seeds (seed 000 Sec. 3.2: the visible surface).
    #[default]
    MinDepth,
    /// The first converged seed (Bowles' heuristic single-seed warps; cheapest).
    FirstConverged,
}

/// How seeds are placed (Sec. 3.2/3.3; Bowles Sec. 3.3). Cross-layer seeds (Fig. 6) are given
/// positions, passed directly in the seed slice of [`fixed_point_search`].
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub enum SeedStrategy {
    /// N seeds stratified in the (tight) search region: a Cranley-Patterson-rotated R2
    /// sequence with a per-pixel hash, so any N stratifies any aspect ratio. One seed at the
    /// region centre where the bound is narrower than a pixel.
    #[default]
    Stratified,
    /// One seed at the target pixel itself (`q_0 = p`).
    Pixel,
    /// One seed at a fixed offset from the pixel (`q_0 = p + offset`, Bowles' stereo heuristic).
    Offset(Vec2),
}

/// Parameters of one fixed-point search.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SearchParams {
    /// T: iterations per seed.
    pub iterations: u32,
    /// Up to this many iterations after the T-th for a walk that is still contracting: each
    /// one only while the last smooth step shrank to at most half the one before
    /// ([`EXTRA_STEP_RATIO`]); 0 runs exactly T.
    pub extra_iterations: u32,
    /// Convergence threshold in pixels.
    pub threshold: f32,
    /// Candidate choice among converged seeds.
    pub choice: CandidateChoice,
    /// Newton steps where the sample carries a Jacobian (see [`fixed_point_search`]).
    pub accelerate: bool,
}

/// A converged search.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Candidate {
    /// Converged source position: `|q + v(q) - p| < threshold`.
    pub q: Vec2,
    /// Target depth of the sample at `q`.
    pub depth: f32,
    /// The sample's tag (layer index for layered sources).
    pub tag: u32,
    /// Index of the seed that converged.
    pub seed: u32,
}

/// The fixed-point search of Fig. 3 for target position `p` from each of `seeds`: at most
/// `params.iterations` (T) samples per seed (and up to `params.extra_iterations` more while the
/// walk's steps keep halving, [`EXTRA_STEP_RATIO`]), converged when `|q_{i+1} - q_i| <
/// threshold`; the
/// candidate is the sample at `q_i` (no extra "polishing" sample: measured neutral for quality
/// on the procedural scenes and ~10 % of the warp's cost).
///
/// With `params.accelerate` (a zwarp addition to Fig. 3, Bowles' "future work"), the next
/// iterate is the Newton step `q + (I + Dv)^-1 (p - v(q) - q)` where the sample has a Jacobian
/// (smooth bilinear neighbourhood), instead of `p - v(q)`: plain fixed-point iteration
/// contracts only by `rho` per step and diverges where the warp magnifies 2x or more (Bowles'
/// convergence condition), which is why the paper needs T > 8 at 8x motion (Fig. 11). The
/// residual test and the returned sample are unchanged.
/// Returns the chosen candidate, or `None` if no seed converged.
#[inline]
pub fn fixed_point_search<S: MotionSource + ?Sized>(
    src: &S,
    p: Vec2,
    seeds: &[Vec2],
    params: &SearchParams,
) -> Option<Candidate> {
    fixed_point_search_closest(src, p, seeds, params).0
}

/// The closest approach of a search's walks to the target position.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Approach {
    /// The smallest squared residual `|p - v(q) - q|^2` of any smooth (bilinear) sampled iterate
    /// of any seed (`+inf` if none). Nearest samples are left out: they sit at discontinuities,
    /// where a surface's edge lands next to `p` without covering it.
    pub r2: f32,
    /// Target depth of that iterate's sample (`+inf` if none).
    pub depth: f32,
    /// The largest target depth of any sample of any seed's walk after its first step (`-inf` if
    /// none): the far side of a disocclusion the walks oscillated across, not a surface a seed
    /// happened to start on ([`crate::WarpParams::ground_layer`]).
    pub farthest: f32,
    /// The nearer target depth of the last two samples of a failed walk that ended on two smooth
    /// samples of one surface landing on opposite sides of `p` ([`straddles`]), the smallest over
    /// the walks (`+inf` if none): the walk cycled across `p` on a continuous surface, whose image
    /// therefore covers `p` although no iterate converged (a fold at a curved surface's grazing
    /// edge) — the multi-layer warp's second coverage test.
    pub straddle: f32,
}

impl Approach {
    /// No sampled iterate.
    pub const NONE: Approach =
        Approach { r2: f32::INFINITY, depth: f32::INFINITY, farthest: f32::NEG_INFINITY, straddle: f32::INFINITY };
}

/// Largest distance (pixels) between the landing points of two straddling samples
/// ([`straddles`]).
pub const STRADDLE_SPAN: f32 = 16.0;

/// Largest ratio of the linear depths of two straddling samples ([`straddles`]), in the
/// `1 - z` form of [`crate::COVER_DEPTH_RATIO`]: one surface, not two at different depths.
pub const STRADDLE_DEPTH_RATIO: f32 = 1.5;

/// Whether two consecutive smooth samples of a walk, with residuals `step_a`, `step_b`
/// (`p - v(q) - q`) and target depths `za`, `zb`, land on opposite sides of `p` (a sample at `q`
/// lands at `q + v(q) = p - step`) less than [`STRADDLE_SPAN`] apart, at depths within
/// [`STRADDLE_DEPTH_RATIO`].
#[inline(always)]
pub fn straddles(step_a: Vec2, za: f32, step_b: Vec2, zb: f32) -> bool {
    let (lo, hi) = (za.min(zb), za.max(zb));
    let d = step_a - step_b;
    step_a.dot(step_b) < 0.0
        && d.length_squared() < STRADDLE_SPAN * STRADDLE_SPAN
        && 1.0 - lo < STRADDLE_DEPTH_RATIO * (1.0 - hi)
}

/// The largest ratio of a walk's squared step to the previous smooth sample's for the walk to
/// take one more of [`SearchParams::extra_iterations`] after T: the step at least halved.
///
/// Why: on a surface the warp magnifies strongly (a wall rushing past a camera that moves along
/// it), the bound of a pixel spans hundreds of pixels and Newton's steps from a distant seed
/// need four or five iterations, each at least halving the step, where T = 3 gives up; the
/// failed front layer then lets a deeper layer's surface win the pixel (more layers, worse
/// answer). A walk that is not contracting (a disocclusion, a fold) stops at T as before.
pub const EXTRA_STEP_RATIO: f32 = 0.25;

/// [`fixed_point_search`], also returning the closest approach of its walks. A failed search
/// whose walk came within a few pixels of `p` found the layer's surface mapping next to `p`:
/// the multi-layer warp's coverage test ([`crate::WarpParams::cover_radius`]).
#[inline]
pub fn fixed_point_search_closest<S: MotionSource + ?Sized>(
    src: &S,
    p: Vec2,
    seeds: &[Vec2],
    params: &SearchParams,
) -> (Option<Candidate>, Approach) {
    let thr2 = params.threshold * params.threshold;
    let mut best: Option<Candidate> = None;
    let mut closest = Approach::NONE;
    crate::stats::count(crate::stats::Counter::Seeds, seeds.len() as u64);
    for (i, &seed) in seeds.iter().enumerate() {
        let mut walk = S::Walk::default();
        let mut q = seed;
        // The previous iterate's smooth sample (residual, depth) and whether the last two
        // straddle p (the nearer depth), for Approach::straddle.
        let mut prev: Option<(Vec2, f32)> = None;
        let mut pair = f32::INFINITY;
        let mut converged = false;
        // The squared step of the previous smooth sample (0: none), for the extra iterations.
        let mut last_r2 = 0.0;
        for it in 0..params.iterations + params.extra_iterations {
            pair = f32::INFINITY;
            let Some(s) = src.sample(q, &mut walk) else { break };
            let w = p - s.v;
            let step = w - q;
            let r2 = step.length_squared();
            if s.smooth && r2 < closest.r2 {
                closest = Approach { r2, depth: s.depth, ..closest };
            }
            if s.smooth {
                if let Some((ps, pz)) = prev {
                    if straddles(ps, pz, step, s.depth) {
                        pair = pz.min(s.depth);
                    }
                }
                prev = Some((step, s.depth));
            } else {
                prev = None;
            }
            if it > 0 {
                closest.farthest = closest.farthest.max(s.depth);
            }
            if r2 < thr2 {
                // Converged: the sample at `q` (Fig. 3), no further "polishing" sample (measured
                // neutral for quality on the procedural scenes, ~10 % of the warp's cost).
                converged = true;
                let c = Candidate { q, depth: s.depth, tag: s.tag, seed: i as u32 };
                match params.choice {
                    CandidateChoice::FirstConverged => return (Some(c), closest),
                    CandidateChoice::MinDepth => {
                        if best.is_none_or(|b| c.depth < b.depth) {
                            best = Some(c);
                        }
                    }
                }
                break;
            }
            if it + 1 >= params.iterations && (!s.smooth || r2 >= EXTRA_STEP_RATIO * last_r2) {
                break;
            }
            last_r2 = if s.smooth { r2 } else { 0.0 };
            // Next iterate: the plain step `w`, or with `accelerate` the Newton step on
            // F(q) = q + v(q) - p with the sample's Jacobian, solving (I + Dv) d = p - v(q) - q.
            // Plain iteration contracts only by rho = |Dv| per step and diverges where the warp
            // magnifies by 2x or more (Bowles' rho >= 1); Newton converges quadratically on
            // smooth motion and is the plain step where Dv = 0 (translation, nearest sampling
            // at discontinuities). Near a fold (I + Dv singular) the plain step is kept.
            let mut next = w;
            if params.accelerate {
                if let Some(d) = newton_step(&s, step) {
                    next = q + d;
                }
            }
            q = next;
        }
        if !converged {
            closest.straddle = closest.straddle.min(pair);
        }
    }
    (best, closest)
}

/// The Newton step `(I + Dv)^-1 r` for the residual `r = p - v(q) - q` with the sample's
/// Jacobian, or `None` near a fold (`|det(I + Dv)| <= 0.05`).
#[inline(always)]
pub fn newton_step(s: &Sample, step: Vec2) -> Option<Vec2> {
    let [a, b] = s.dv;
    let (m00, m01, m10, m11) = (1.0 + a.x, b.x, a.y, 1.0 + b.y);
    let det = m00 * m11 - m01 * m10;
    if det.abs() > 0.05 {
        Some(Vec2::new(m11 * step.x - m01 * step.y, -m10 * step.x + m00 * step.y) / det)
    } else {
        None
    }
}

/// 32-bit integer hash (PCG output permutation): decorrelates per-pixel seed jitter and is
/// cheap to reproduce in WGSL.
#[inline]
pub fn hash_u32(v: u32) -> u32 {
    let state = v.wrapping_mul(747796405).wrapping_add(2891336453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277803737);
    (word >> 22) ^ word
}

/// Per-pixel seed key (pixel and layer), hashed for the seed jitter.
#[inline]
pub fn seed_key(x: u32, y: u32, layer: u32) -> u32 {
    hash_u32(x ^ hash_u32(y ^ hash_u32(layer)))
}

/// Number of seeds actually used in a region of extent `e` (frame pixels): one when the
/// bound is narrower than a pixel in both axes (homogeneous region, Sec. 3.3's early exit),
/// otherwise N capped by the region's area in pixels, `ceil((ex + 1)(ey + 1))` (seeds closer
/// than a pixel follow nearly the same trajectory).
#[inline]
pub fn effective_seeds(n: u32, e: Vec2) -> u32 {
    if e.x <= 1.0 && e.y <= 1.0 {
        return 1;
    }
    let area = ((e.x + 1.0) * (e.y + 1.0)).ceil();
    if area < n as f32 {
        area as u32
    } else {
        n
    }
}

/// R2 low-discrepancy sequence generators (Roberts 2018): plastic-number reciprocals.
const R2: Vec2 = Vec2::new(0.754_877_7, 0.569_840_3);

/// Writes `n` seeds for `region` (frame coordinates of `frame`) into `out` (image
/// coordinates) and returns how many were written (`min(n, out.len())`). A single seed sits at
/// the region centre. Otherwise up to `n / 2` seeds (at most the number of distinct corners) go
/// to the corners of the region (`p - v` for the extreme motions; low corner first, then high,
/// then the two others), the rest are stratified inside it with an R2 sequence jittered by
/// `key`. (Measured on the synthetic city: all-corner seeding at N = 4 loses ~1 dB against
/// half corners, half stratified.)
///
/// Why corners (a zwarp choice on top of the paper's stratified sampling): the bound is the
/// min-max of actual motion vectors, so when a few rigid motions meet (an object over its
/// background), the solutions `p - v_object` sit exactly at region corners, often with only a
/// sliver of their convergence basin inside the region (a moving object's leading edge).
/// Random seeds miss such slivers; corner seeds hit them. For smooth motion a corner is as good
/// a seed as any other point of the region.
#[inline]
pub fn stratified_seeds(frame: &BoundFrame, region: &Bound, n: u32, key: u32, out: &mut [Vec2]) -> usize {
    let n = (n as usize).min(out.len());
    let e = region.extent();
    if n == 0 {
        return 0;
    }
    if n == 1 {
        out[0] = frame.from_frame(region.lo + 0.5 * e);
        return 1;
    }
    let identity = frame.is_identity();
    let map = |u: Vec2| if identity { u } else { frame.from_frame(u) };
    let (lo, hi) = (region.lo, region.hi);
    let corners = [lo, hi, Vec2::new(lo.x, hi.y), Vec2::new(hi.x, lo.y)];
    // Distinct corners: 1 for a point region, 2 for a segment, 4 for a box.
    let distinct = match (e.x > 0.0, e.y > 0.0) {
        (true, true) => 4,
        (false, false) => 1,
        _ => 2,
    };
    let nc = (n / 2).min(distinct);
    for (o, c) in out.iter_mut().zip(&corners[..nc]) {
        *o = map(*c);
    }
    let r = Vec2::new((key & 0xffff) as f32 / 65536.0, (key >> 16) as f32 / 65536.0);
    for (i, o) in out[nc..n].iter_mut().enumerate() {
        let s = (r + R2 * i as f32).fract();
        *o = map(lo + s * e);
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{LayerSampler, SamplePlanes, Sampling};
    use std::cell::Cell;
    use zwarp_core::Motion;

    /// Uniform shift field on a 16x16 image.
    fn shift(v: Vec2) -> Vec<Motion> {
        vec![Motion { v, depth: 0.5 }; 256]
    }

    fn sp(t: u32) -> SearchParams {
        SearchParams {
            iterations: t,
            extra_iterations: 0,
            threshold: 0.5,
            choice: CandidateChoice::MinDepth,
            accelerate: false,
        }
    }

    #[test]
    fn uniform_shift_converges_in_one_iteration_from_the_exact_seed() {
        let m = shift(Vec2::new(3.0, -2.0));
        for sampling in [Sampling::Nearest, Sampling::Adaptive] {
            let planes = SamplePlanes::from_motion(&m);
            let s = LayerSampler::new(&planes, 16, 16, sampling, 7);
            let p = Vec2::new(8.5, 5.5);
            let c = fixed_point_search(&s, p, &[Vec2::new(5.5, 7.5)], &sp(1)).unwrap();
            assert_eq!(c.q, Vec2::new(5.5, 7.5));
            assert_eq!((c.depth, c.tag, c.seed), (0.5, 7, 0));
            // From the pixel itself it needs a second iteration.
            assert!(fixed_point_search(&s, p, &[p], &sp(1)).is_none());
            assert_eq!(fixed_point_search(&s, p, &[p], &sp(2)).unwrap().q, Vec2::new(5.5, 7.5));
        }
    }

    #[test]
    fn leaving_the_image_or_landing_on_empty_fails() {
        let m = shift(Vec2::new(10.0, 0.0));
        let planes = SamplePlanes::from_motion(&m);
        let s = LayerSampler::new(&planes, 16, 16, Sampling::Nearest, 0);
        // p - v is outside for p.x < 10.
        assert!(fixed_point_search(&s, Vec2::new(4.5, 4.5), &[Vec2::new(8.5, 4.5)], &sp(8)).is_none());
        let mut m = shift(Vec2::ZERO);
        m[4 * 16 + 4].depth = 1.0;
        let planes = SamplePlanes::from_motion(&m);
        let s = LayerSampler::new(&planes, 16, 16, Sampling::Nearest, 0);
        assert!(fixed_point_search(&s, Vec2::new(4.5, 4.5), &[Vec2::new(4.5, 4.5)], &sp(8)).is_none());
        assert!(fixed_point_search(&s, Vec2::new(5.5, 4.5), &[Vec2::new(4.5, 4.5)], &sp(8)).is_none());
        assert!(fixed_point_search(&s, Vec2::new(5.5, 4.5), &[Vec2::new(5.2, 4.5)], &sp(8)).is_some());
    }

    #[test]
    fn min_depth_resolves_overlaps_and_first_converged_takes_the_first() {
        // Left half (x < 8) moves +4 at depth 0.3 (foreground), right half static at 0.8.
        let m: Vec<Motion> = (0..256)
            .map(|i| {
                if i % 16 < 8 {
                    Motion { v: Vec2::new(4.0, 0.0), depth: 0.3 }
                } else {
                    Motion { v: Vec2::ZERO, depth: 0.8 }
                }
            })
            .collect();
        let planes = SamplePlanes::from_motion(&m);
        let s = LayerSampler::new(&planes, 16, 16, Sampling::Adaptive, 0);
        let p = Vec2::new(10.5, 3.5); // covered by both: foreground from q=6.5, background at 10.5
        let seeds = [Vec2::new(10.5, 3.5), Vec2::new(6.5, 3.5)];
        let c = fixed_point_search(&s, p, &seeds, &sp(3)).unwrap();
        assert_eq!((c.depth, c.seed), (0.3, 1));
        let first = SearchParams { choice: CandidateChoice::FirstConverged, ..sp(3) };
        let c = fixed_point_search(&s, p, &seeds, &first).unwrap();
        assert_eq!((c.depth, c.seed), (0.8, 0));
    }

    /// Plain iteration on the linear field `v.x = a (x - 128)`: each step shrinks by `a`. From
    /// 100 px away at a = 0.4 the walk needs eight samples; T = 3 gives up, five extra
    /// iterations (each step well under half the last) finish it, three are not enough. At
    /// a = 0.6 the steps do not halve: the walk stops at T whatever the extra allowance.
    #[test]
    fn extra_iterations_finish_only_walks_whose_steps_halve() {
        let (w, h) = (256u32, 4u32);
        let field = |a: f32| -> Vec<Motion> {
            (0..w * h).map(|i| Motion { v: Vec2::new(a * ((i % w) as f32 + 0.5 - 128.0), 0.0), depth: 0.5 }).collect()
        };
        let p = Vec2::new(150.5, 1.5);
        for (a, extra, converges) in
            [(0.4, 0, false), (0.4, 3, false), (0.4, 5, true), (0.6, 5, false), (0.6, 0, false)]
        {
            let planes = SamplePlanes::from_motion(&field(a));
            let s = LayerSampler::new(&planes, w, h, Sampling::Adaptive, 0);
            let solution = (p.x + 128.0 * a) / (1.0 + a);
            let seed = Vec2::new(solution - 100.0, 1.5);
            let c = fixed_point_search(&s, p, &[seed], &SearchParams { extra_iterations: extra, ..sp(3) });
            assert_eq!(c.is_some(), converges, "a {a} extra {extra}");
            if let Some(c) = c {
                assert!((c.q.x - solution).abs() < 0.5, "{c:?}");
            }
        }
    }

    /// A source that never converges and counts its samples.
    struct Counting(Cell<u32>);
    impl MotionSource for Counting {
        type Walk = ();
        fn sample(&self, q: Vec2, _: &mut ()) -> Option<Sample> {
            self.0.set(self.0.get() + 1);
            // Jump by 10 px every step, alternating: an orbit, never converging.
            Some(Sample {
                v: Vec2::new(if q.x > 0.0 { 10.0 } else { -10.0 }, 0.0),
                depth: 0.5,
                tag: 0,
                dv: [Vec2::ZERO; 2],
                dz: Vec2::ZERO,
                smooth: false,
            })
        }
    }

    /// A smooth surface whose image jumps over p = (10, 0): left of x = 10 it moves by `-jump`,
    /// right of it by `+jump`, so a walk from x = 10 - jump cycles between 10 - jump and
    /// 10 + jump, whose samples land `2 jump` either side of p; depths `zl` (left) and `zr`
    /// (right).
    struct Fold {
        jump: f32,
        zl: f32,
        zr: f32,
    }
    impl MotionSource for Fold {
        type Walk = ();
        fn sample(&self, q: Vec2, _: &mut ()) -> Option<Sample> {
            let left = q.x < 10.0;
            Some(Sample {
                v: Vec2::new(if left { -self.jump } else { self.jump }, 0.0),
                depth: if left { self.zl } else { self.zr },
                tag: 0,
                dv: [Vec2::ZERO; 2],
                dz: Vec2::ZERO,
                smooth: true,
            })
        }
    }

    #[test]
    fn a_walk_cycling_across_p_on_one_surface_straddles_it() {
        let p = Vec2::new(10.0, 0.0);
        let search = |f: &Fold| fixed_point_search_closest(f, p, &[Vec2::new(10.0 - f.jump, 0.0)], &sp(3));
        // Landing 6 px either side of p (12 px apart) at depths within 1.5x: the nearer depth.
        let (c, a) = search(&Fold { jump: 3.0, zl: 0.5, zr: 0.52 });
        assert!(c.is_none());
        assert_eq!(a.straddle, 0.5);
        // Two surfaces (linear depths 5x apart) or landings more than STRADDLE_SPAN (16 px) apart:
        // no straddle.
        assert_eq!(search(&Fold { jump: 3.0, zl: 0.5, zr: 0.9 }).1.straddle, f32::INFINITY);
        assert_eq!(search(&Fold { jump: 3.9, zl: 0.5, zr: 0.52 }).1.straddle, 0.5);
        assert_eq!(search(&Fold { jump: 4.1, zl: 0.5, zr: 0.52 }).1.straddle, f32::INFINITY);
        assert!(straddles(Vec2::new(6.0, 0.0), 0.5, Vec2::new(-6.0, 0.0), 0.6));
        assert!(!straddles(Vec2::new(6.0, 0.0), 0.5, Vec2::new(6.0, 1.0), 0.5), "same side");
        // A walk that converges has no straddle.
        let (c, a) = search(&Fold { jump: 0.0, zl: 0.5, zr: 0.52 });
        assert!(c.is_some() && a.straddle == f32::INFINITY, "{c:?} {a:?}");
        // The WGSL twin's constants.
        let wgsl = include_str!("gpu/warp.wgsl");
        for (name, v) in [("STRADDLE_SPAN", STRADDLE_SPAN), ("STRADDLE_DEPTH_RATIO", STRADDLE_DEPTH_RATIO)] {
            assert!(wgsl.contains(&format!("const {name}: f32 = {v:?};")), "{name}");
        }
    }

    #[test]
    fn exactly_t_samples_per_seed_when_not_converging() {
        for t in [1, 2, 3, 7] {
            let c = Counting(Cell::new(0));
            let seeds = [Vec2::ZERO; 5];
            assert!(fixed_point_search(&c, Vec2::ZERO, &seeds, &sp(t)).is_none());
            assert_eq!(c.0.get(), 5 * t);
        }
    }

    #[test]
    fn stratified_seeds_lie_in_the_region_and_spread() {
        let region = Bound { lo: Vec2::new(10.0, 20.0), hi: Vec2::new(30.0, 24.0) };
        let mut out = [Vec2::ZERO; 16];
        let n = stratified_seeds(&BoundFrame::IDENTITY, &region, 16, seed_key(3, 4, 0), &mut out);
        assert_eq!(n, 16);
        let mut quadrant = [0; 4];
        for s in &out {
            assert!(region.contains(*s), "{s:?}");
            quadrant[(s.x >= 20.0) as usize * 2 + (s.y >= 22.0) as usize] += 1;
        }
        assert!(quadrant.iter().all(|&q| q >= 2), "{quadrant:?}");
        // The four corners come first, low corner first.
        assert_eq!(&out[..4], &[region.lo, region.hi, Vec2::new(10.0, 24.0), Vec2::new(30.0, 20.0)]);
        // A segment region has two distinct corners.
        let seg = Bound { lo: Vec2::new(1.0, 2.0), hi: Vec2::new(6.0, 2.0) };
        stratified_seeds(&BoundFrame::IDENTITY, &seg, 8, 5, &mut out);
        assert_eq!(&out[..2], &[seg.lo, seg.hi]);
        assert!(out[2..8].iter().all(|s| s.y == 2.0 && s.x >= 1.0 && s.x < 6.0));
        assert_eq!(stratified_seeds(&BoundFrame::IDENTITY, &region, 1, 0, &mut out), 1);
        assert_eq!(out[0], Vec2::new(20.0, 22.0));
        // Rotated frame: seeds map back into the rotated box.
        let f = BoundFrame::from_angle(0.5);
        stratified_seeds(&f, &region, 16, 99, &mut out);
        for s in &out {
            let u = f.to_frame(*s);
            assert!(u.x >= 9.999 && u.x <= 30.001 && u.y >= 19.999 && u.y <= 24.001);
        }
    }

    /// A 1.9x magnification about (32, 32): v(q) = 0.9 (q - c), rho = 0.9. Plain fixed-point
    /// iteration oscillates and crawls (error x 0.9 per step), the Newton step converges.
    #[test]
    fn newton_steps_converge_where_plain_iteration_diverges() {
        let c = Vec2::splat(32.0);
        let m: Vec<Motion> = (0..64 * 64)
            .map(|i| {
                let q = Vec2::new((i % 64) as f32 + 0.5, (i / 64) as f32 + 0.5);
                Motion { v: 0.9 * (q - c), depth: 0.5 }
            })
            .collect();
        let planes = SamplePlanes::from_motion(&m);
        let s = LayerSampler::new(&planes, 64, 64, Sampling::Adaptive, 0);
        let p = Vec2::new(40.0, 30.0);
        let exact = c + (p - c) / 1.9;
        let seed = [exact + Vec2::new(2.0, -1.5)];
        let plain = SearchParams { accelerate: false, ..sp(6) };
        assert!(fixed_point_search(&s, p, &seed, &plain).is_none());
        let newton = SearchParams { accelerate: true, ..sp(3) };
        let got = fixed_point_search(&s, p, &seed, &newton).unwrap();
        assert!((got.q - exact).length() < 0.05, "{:?} vs {exact:?}", got.q);
        // The sample's Jacobian is the bilinear one: exactly 0.9 I on this linear field.
        let smp = s.fetch(Vec2::new(20.3, 41.7)).unwrap();
        assert!((smp.dv[0] - Vec2::new(0.9, 0.0)).length() < 1e-5 && (smp.dv[1] - Vec2::new(0.0, 0.9)).length() < 1e-5);
    }

    #[test]
    fn effective_seed_count() {
        assert_eq!(effective_seeds(16, Vec2::new(0.9, 0.2)), 1);
        assert_eq!(effective_seeds(16, Vec2::new(1.5, 0.2)), 3);
        assert_eq!(effective_seeds(16, Vec2::new(5.0, 0.0)), 6);
        assert_eq!(effective_seeds(8, Vec2::new(40.0, 3.0)), 8);
    }
}
