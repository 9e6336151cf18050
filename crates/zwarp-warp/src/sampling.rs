//! How the search samples a layer's motion between texel centres (seed 001 Sec. 3.2-3.4,
//! Fig. 4): the [`MotionSource`] interface of [`crate::search`] and the sampler of a prepared
//! layer's [`SamplePlanes`].
//!
//! **Sampling of v** ([`Sampling`]). Bilinear interpolation of motion across a depth edge
//! creates artificial fixed points in disocclusions (Bowles Sec. 3.2, Fig. 1e: a "rubber sheet"
//! with depths between foreground and background — nearer than the truth, i.e. unsafe for
//! culling); pure nearest sampling has no such solutions but cracks where a surface stretches
//! (neighbouring texels move apart by more than the threshold). [`Sampling::Adaptive`] follows
//! Bowles Sec. 3.4 / Fig. 4: bilinear between the four texels around `q` when all are valid and
//! their motions differ by less than one pixel (the convergence condition `rho < 1` between
//! neighbours) or their depths by less than [`SURFACE_DEPTH_STEP`] (one surface, magnified:
//! the Newton step converges where plain iteration would not), nearest otherwise. It is the
//! default.
//!
//! A sample carries what the search needs besides the motion: the target depth (the candidate
//! choice), the Jacobian where the neighbourhood is smooth (the Newton step) and a tag (the
//! layer).

use glam::Vec2;
use zwarp_core::Motion;

/// One sample of the motion buffer at a continuous position.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Motion source -> target in pixels.
    pub v: Vec2,
    /// The sampled point's depth in the target view.
    pub depth: f32,
    /// Free tag set by the source (the layer index for layered sources).
    pub tag: u32,
    /// Jacobian of the motion at `q`, `(dv/dx, dv/dy)` in pixels per pixel, where the source
    /// knows it (bilinear sampling of a smooth neighbourhood); zero otherwise. Used by the
    /// Newton step of [`crate::search::fixed_point_search`].
    pub dv: [Vec2; 2],
    /// Gradient of the target depth at `q`, `(dz/dx, dz/dy)` per pixel, where the source knows
    /// it (with `dv`); zero otherwise. The converged depth follows the last Newton step with it.
    pub dz: Vec2,
    /// `true` for a bilinear sample of a smooth neighbourhood (`dv` and `dz` are its exact
    /// derivatives), `false` for a nearest one.
    pub smooth: bool,
}

/// Anything the fixed-point search can sample: a motion buffer, a stack of peeled layers with
/// cross-layer look-up, a colour warp's flow field...
pub trait MotionSource {
    /// Per-seed walk state (e.g. how often the walk landed in empty space); reset per seed.
    type Walk: Default;
    /// The sample at continuous position `q`, or `None` if there is none (outside the image,
    /// empty), which fails the current seed.
    fn sample(&self, q: Vec2, walk: &mut Self::Walk) -> Option<Sample>;
}

/// How the motion buffer is sampled between texel centres (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Sampling {
    /// The texel containing `q` (`floor(q)`).
    Nearest,
    /// Bilinear where the 2x2 neighbourhood is valid and continuous ([`continuous_cell`]:
    /// motion range < 1 px or a depth step below [`SURFACE_DEPTH_STEP`], no large depth step),
    /// nearest elsewhere (Bowles Fig. 4).
    #[default]
    Adaptive,
}

impl Sampling {
    /// Half-width in pixels of the texel footprint a sample at `q` reads beyond `floor(q)`; the
    /// bound look-ups grow the search region by it so they stay conservative.
    #[inline]
    pub fn footprint(self) -> f32 {
        match self {
            Sampling::Nearest => 0.0,
            Sampling::Adaptive => 0.5,
        }
    }
}

/// Motion difference (pixels, per component) between neighbouring texels above which they
/// are treated as a discontinuity and not interpolated (Bowles' `rho < 1`).
pub const CONTINUITY_PX: f32 = 1.0;

/// Relative depth step across a 2x2 cell above which it is a discontinuity although its
/// motions agree: two surfaces far apart in depth, both so far away that they move alike (a
/// facade 15 m away in front of one at 50 m). The step is measured in target depth `z` as
/// `(z_max - z_min) / (1 - z_max)`, which is the relative step of the linear depth `Δd / d_near`
/// for surfaces well before the far plane: 2 separates surfaces whose distances differ by
/// more than a factor 3, and keeps interpolating every surface seen at up to ~89° from
/// its normal (a few percent per texel).
pub const DEPTH_CONTINUITY: f32 = 2.0;

/// Relative depth step across a 2x2 cell (measured as for [`DEPTH_CONTINUITY`]) below which the
/// cell is one surface whatever its motion range. A surface near the camera under fast motion is
/// magnified (`|dv/dq| >= 1`: neighbouring texels move apart by a pixel or more); sampled
/// nearest, each texel would cover its own 1x1 footprint and leave the pixels between the
/// footprints without a fixed point (a camera skimming a wall 0.5 m away at 0.55 m per frame
/// converged on 30 % of the wall it saw), while its bilinear interpolant has one that the
/// Newton step reaches. 5 % keeps interpolating planes seen up to ~88° from their normal at
/// 960 px (a grazing plane's step per texel is the pixel angle times `tan` of that angle) and
/// stops at most object edges; an edge whose sides lie within 5 % in depth and move apart by
/// a pixel or more is read as one stretched surface (its sliver gets a depth between them).
pub const SURFACE_DEPTH_STEP: f32 = 0.05;

/// Whether a 2x2 cell of valid texels is one surface, so that the adaptive fetch interpolates
/// it (Bowles Fig. 4): its motions differ by less than [`CONTINUITY_PX`] (the convergence
/// condition `rho < 1`) or its depths by less than [`SURFACE_DEPTH_STEP`] (a magnified surface),
/// and its depths by less than [`DEPTH_CONTINUITY`] (relative; the geometric test of Mark et
/// al. that Bowles Sec. 3.4 cites, for what motion alone cannot see). `motion_range` is the
/// larger per-axis range of the four motions, `z_lo` / `z_hi` the smallest / largest target
/// depth. Scalar twin of the AVX2 and WGSL fetches.
#[inline(always)]
pub fn continuous_cell(motion_range: f32, z_lo: f32, z_hi: f32) -> bool {
    let (step, room) = (z_hi - z_lo, 1.0 - z_hi);
    ((motion_range < CONTINUITY_PX) | (step < SURFACE_DEPTH_STEP * room)) & (step < DEPTH_CONTINUITY * room)
}

/// Validated samples of one layer as three planes (structure of arrays, so that a row of
/// texels is one contiguous load per component): motion x, motion y and target depth, the
/// depth `+inf` where the sample is empty (source depth `>= 1`, target depth outside `[0, 1)` or
/// infinite motion; such texels carry zero motion). Built by the layer preparation
/// (`PreparedLayer`), read by every fetch.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SamplePlanes {
    /// Motion x per texel (0 where empty).
    pub vx: Vec<f32>,
    /// Motion y per texel (0 where empty).
    pub vy: Vec<f32>,
    /// Target depth per texel, `+inf` where empty.
    pub z: Vec<f32>,
}

impl SamplePlanes {
    /// The planes of a row-major motion buffer whose empty samples are marked by a target depth
    /// outside `[0, 1)` (the convention of [`LayerSampler`]).
    pub fn from_motion(samples: &[Motion]) -> Self {
        let valid = |m: &Motion| (m.depth >= 0.0) & (m.depth < 1.0);
        SamplePlanes {
            vx: samples.iter().map(|m| if valid(m) { m.v.x } else { 0.0 }).collect(),
            vy: samples.iter().map(|m| if valid(m) { m.v.y } else { 0.0 }).collect(),
            z: samples.iter().map(|m| if valid(m) { m.depth } else { f32::INFINITY }).collect(),
        }
    }
    /// Number of texels.
    pub fn len(&self) -> usize {
        self.z.len()
    }
    /// `true` if there are no texels.
    pub fn is_empty(&self) -> bool {
        self.z.is_empty()
    }
    /// Texel `i` as a [`Motion`] (depth `+inf` where empty).
    #[inline]
    pub fn get(&self, i: usize) -> Motion {
        Motion { v: Vec2::new(self.vx[i], self.vy[i]), depth: self.z[i] }
    }
}

/// Sampler of one layer's [`SamplePlanes`]. Samples whose depth is not in `[0, 1)` are empty
/// (see [`crate::bounds`] for why).
#[derive(Clone, Copy)]
pub struct LayerSampler<'a> {
    vx: &'a [f32],
    vy: &'a [f32],
    z: &'a [f32],
    w: u32,
    h: u32,
    sampling: Sampling,
    tag: u32,
    /// Component-wise factor on every fetched motion (`WarpParams::motion_scale`).
    scale: Vec2,
    /// `(w, h)` as floats (the `inside` test of every sample).
    size: Vec2,
}

impl<'a> LayerSampler<'a> {
    /// Wraps the `w x h` planes. Panics if a plane's length does not match (internal callers
    /// validate sizes first).
    pub fn new(planes: &'a SamplePlanes, w: u32, h: u32, sampling: Sampling, tag: u32) -> Self {
        let n = w as usize * h as usize;
        assert!(planes.vx.len() == n && planes.vy.len() == n && planes.z.len() == n, "sample plane size");
        LayerSampler {
            vx: &planes.vx,
            vy: &planes.vy,
            z: &planes.z,
            w,
            h,
            sampling,
            tag,
            scale: Vec2::ONE,
            size: Vec2::new(w as f32, h as f32),
        }
    }

    /// The same sampler for the motion field `scale * v` (component-wise; see
    /// `WarpParams::motion_scale`): every texel's motion is scaled before it is interpolated,
    /// tested for continuity or differentiated, so a fetch equals the fetch from the
    /// explicitly scaled buffer bit for bit. Depths are unchanged.
    pub fn with_scale(self, scale: Vec2) -> Self {
        LayerSampler { scale, ..self }
    }

    /// The planes (motion x, motion y, depth) and the image size.
    #[inline]
    pub(crate) fn planes(&self) -> (&'a [f32], &'a [f32], &'a [f32], u32, u32) {
        (self.vx, self.vy, self.z, self.w, self.h)
    }
    /// How the planes are sampled between texel centres.
    #[inline]
    pub fn sampling(&self) -> Sampling {
        self.sampling
    }

    /// `true` if `q` lies inside the image `[0, w) x [0, h)`.
    #[inline]
    pub fn inside(&self, q: Vec2) -> bool {
        (q.x >= 0.0) & (q.y >= 0.0) & (q.x < self.size.x) & (q.y < self.size.y)
    }

    #[inline]
    fn at(&self, x: u32, y: u32) -> Motion {
        // Callers clamp the indices; slice indexing still bounds-checks.
        let i = y as usize * self.w as usize + x as usize;
        Motion { v: Vec2::new(self.vx[i], self.vy[i]), depth: self.z[i] }
    }

    /// The valid texels of the 2x2 cell the adaptive fetch reads at `q` (inside, see
    /// [`Self::inside`]; indices clamped as the fetch clamps them): per texel its centre and its
    /// nearest sample. Where the cell is a discontinuity the fetch returns one of them; the
    /// coverage test looks at each (`Kernel::covered_at_source`).
    pub fn cell_texels(&self, q: Vec2) -> impl Iterator<Item = (Vec2, Sample)> + '_ {
        let (tx, ty) = ((q.x + 0.5) as u32, (q.y + 0.5) as u32); // floor(q - 0.5) + 1
        let (wm, hm) = (self.w - 1, self.h - 1);
        let (x0, y0, x1, y1) = (tx.saturating_sub(1).min(wm), ty.saturating_sub(1).min(hm), tx.min(wm), ty.min(hm));
        [(x0, y0), (x1, y0), (x0, y1), (x1, y1)].into_iter().filter_map(move |(x, y)| {
            self.nearest(self.at(x, y)).map(|s| (Vec2::new(x as f32 + 0.5, y as f32 + 0.5), s))
        })
    }

    /// The nearest (unsmoothed) sample of texel motion `m`, scaled; `None` if empty.
    #[inline]
    fn nearest(&self, m: Motion) -> Option<Sample> {
        ((m.depth >= 0.0) & (m.depth < 1.0)).then(|| Sample {
            v: self.scale * m.v,
            depth: m.depth,
            tag: self.tag,
            dv: [Vec2::ZERO; 2],
            dz: Vec2::ZERO,
            smooth: false,
        })
    }

    /// The sample at `q` (must be inside, see [`Self::inside`]); `None` if empty.
    #[inline(always)]
    pub fn fetch(&self, q: Vec2) -> Option<Sample> {
        if self.inside(q) {
            self.fetch_inside(q)
        } else {
            self.fetch_clamped(q)
        }
    }

    /// [`Self::fetch`] for a `q` that [`Self::inside`] accepted: the hot path of every walk.
    /// Same arithmetic as [`Self::fetch_clamped`] (bit for bit), without its saturating
    /// conversions and bounds checks, and without the multiplication by a unit scale.
    #[inline(always)]
    pub(crate) fn fetch_inside(&self, q: Vec2) -> Option<Sample> {
        debug_assert!(self.inside(q));
        if self.scale == Vec2::ONE {
            self.fetch_inside_scaled::<true>(q)
        } else {
            self.fetch_inside_scaled::<false>(q)
        }
    }

    #[inline(always)]
    fn fetch_inside_scaled<const UNIT: bool>(&self, q: Vec2) -> Option<Sample> {
        crate::stats::count(crate::stats::Counter::Fetches, 1);
        let (wm, hm) = (self.w - 1, self.h - 1);
        let wu = self.w as usize;
        // SAFETY (the `get_unchecked`s below): every index is `y * w + x` with `x <= w - 1`
        // and `y <= h - 1` (clamped by `min`), and every plane is `w * h` long (asserted in
        // `new`; the fields are private and `with_scale` keeps them).
        let at = |x: u32, y: u32| unsafe {
            let i = y as usize * wu + x as usize;
            Motion {
                v: Vec2::new(*self.vx.get_unchecked(i), *self.vy.get_unchecked(i)),
                depth: *self.z.get_unchecked(i),
            }
        };
        let sc = |m: Motion| if UNIT { m } else { Motion { v: self.scale * m.v, depth: m.depth } };
        if self.sampling == Sampling::Adaptive {
            crate::stats::count(crate::stats::Counter::MotionTexels, 4);
            // Texel-centre coordinates t = q - 0.5 >= -0.5: floor(t) = trunc(t + 1) - 1.
            let (tx, ty) = (q.x + 0.5, q.y + 0.5);
            // SAFETY: `inside(q)` means 0 <= q < (w, h) (so q is finite), hence
            // 0.5 <= t <= (w, h) + 0.5, well inside u32 after truncation.
            let (ix, iy): (u32, u32) = unsafe { (tx.to_int_unchecked(), ty.to_int_unchecked()) };
            let (ax, ay) = (tx - ix as f32, ty - iy as f32);
            let x0 = ix.saturating_sub(1).min(wm);
            let y0 = iy.saturating_sub(1).min(hm);
            let (x1, y1) = (ix.min(wm), iy.min(hm));
            let cell = [sc(at(x0, y0)), sc(at(x1, y0)), sc(at(x0, y1)), sc(at(x1, y1))];
            if let Some(s) = smooth_cell(&cell, ax, ay, self.tag) {
                return Some(s);
            }
        } else {
            crate::stats::count(crate::stats::Counter::MotionTexels, 1);
        }
        // SAFETY: as above, 0 <= q < (w, h).
        let (xn, yn): (u32, u32) = unsafe { (q.x.to_int_unchecked(), q.y.to_int_unchecked()) };
        let m = at(xn.min(wm), yn.min(hm));
        if (m.depth >= 0.0) & (m.depth < 1.0) {
            let m = sc(m);
            Some(Sample { v: m.v, depth: m.depth, tag: self.tag, dv: [Vec2::ZERO; 2], dz: Vec2::ZERO, smooth: false })
        } else {
            None
        }
    }

    /// [`Self::fetch`] for any `q`: indices clamped into the image.
    fn fetch_clamped(&self, q: Vec2) -> Option<Sample> {
        // `q >= 0` inside the image: truncation is floor. (`f32::floor` is a libm call on
        // baseline x86-64, which showed up at ~9 % of the warp in a profile.)
        let (wm, hm) = (self.w - 1, self.h - 1);
        let (xn, yn) = ((q.x as u32).min(wm), (q.y as u32).min(hm));
        crate::stats::count(crate::stats::Counter::Fetches, 1);
        let texels = if self.sampling == Sampling::Adaptive { 4 } else { 1 };
        crate::stats::count(crate::stats::Counter::MotionTexels, texels);
        if self.sampling == Sampling::Adaptive {
            // Texel-centre coordinates t = q - 0.5 >= -0.5: floor(t) = trunc(t + 1) - 1.
            let (tx, ty) = (q.x + 0.5, q.y + 0.5);
            let (ix, iy) = (tx as u32, ty as u32); // floor(t) + 1
            let (ax, ay) = (tx - ix as f32, ty - iy as f32);
            let x0 = ix.saturating_sub(1).min(wm);
            let y0 = iy.saturating_sub(1).min(hm);
            let (x1, y1) = (ix.min(wm), iy.min(hm));
            let sc = |m: Motion| Motion { v: self.scale * m.v, depth: m.depth };
            let cell = [sc(self.at(x0, y0)), sc(self.at(x1, y0)), sc(self.at(x0, y1)), sc(self.at(x1, y1))];
            if let Some(s) = smooth_cell(&cell, ax, ay, self.tag) {
                return Some(s);
            }
        }
        self.nearest(self.at(xn, yn))
    }
}

/// The bilinear sample of the cell `[s00, s10, s01, s11]` at fractions `(ax, ay)` if its four
/// texels are valid (invalid ones carry a depth outside `[0, 1)`) and one surface
/// ([`continuous_cell`]), else `None` (the fetch falls back to the nearest texel).
#[inline(always)]
fn smooth_cell(cell: &[Motion; 4], ax: f32, ay: f32, tag: u32) -> Option<Sample> {
    let [s00, s10, s01, s11] = cell;
    // Non-short-circuit `&`: one branch.
    let valid = |m: &Motion| (m.depth >= 0.0) & (m.depth < 1.0);
    if !(valid(s00) & valid(s10) & valid(s01) & valid(s11)) {
        return None;
    }
    let lo = s00.v.min(s10.v).min(s01.v.min(s11.v));
    let hi = s00.v.max(s10.v).max(s01.v.max(s11.v));
    let z_lo = s00.depth.min(s10.depth).min(s01.depth.min(s11.depth));
    let z_hi = s00.depth.max(s10.depth).max(s01.depth.max(s11.depth));
    continuous_cell((hi - lo).max_element(), z_lo, z_hi).then(|| bilinear(s00, s10, s01, s11, ax, ay, tag))
}

/// Bilinear sample of four valid, continuous texels at fractions `(ax, ay)` (Bowles Fig. 4),
/// with the exact Jacobian of the bilinear interpolant (per pixel) for the Newton step.
#[inline(always)]
fn bilinear(s00: &Motion, s10: &Motion, s01: &Motion, s11: &Motion, ax: f32, ay: f32, tag: u32) -> Sample {
    let top_v = s00.v.lerp(s10.v, ax);
    let bot_v = s01.v.lerp(s11.v, ax);
    let top_d = s00.depth + (s10.depth - s00.depth) * ax;
    let bot_d = s01.depth + (s11.depth - s01.depth) * ax;
    let dvdx = (s10.v - s00.v).lerp(s11.v - s01.v, ay);
    let dvdy = bot_v - top_v;
    let dzdx = (s10.depth - s00.depth) + ((s11.depth - s01.depth) - (s10.depth - s00.depth)) * ay;
    let dzdy = bot_d - top_d;
    Sample {
        v: top_v.lerp(bot_v, ay),
        depth: top_d + (bot_d - top_d) * ay,
        tag,
        dv: [dvdx, dvdy],
        dz: Vec2::new(dzdx, dzdy),
        smooth: true,
    }
}

impl MotionSource for LayerSampler<'_> {
    type Walk = ();
    #[inline]
    fn sample(&self, q: Vec2, _walk: &mut ()) -> Option<Sample> {
        if self.inside(q) {
            self.fetch(q)
        } else {
            None
        }
    }
}
#[cfg(test)]
mod tests {
    use super::*;

    /// Uniform shift field on a 16x16 image.
    fn shift(v: Vec2) -> Vec<Motion> {
        vec![Motion { v, depth: 0.5 }; 256]
    }

    #[test]
    fn cell_texels_are_the_texels_the_adaptive_fetch_reads() {
        // A motion step between columns 7 and 8 (a discontinuity: the fetch at x = 7.6 returns
        // the nearest texel, column 7) and an empty texel at (8, 4).
        let mut m = shift(Vec2::new(2.0, 0.0));
        for y in 0..16 {
            for x in 8..16 {
                m[y * 16 + x].v = Vec2::new(-3.0, 0.0);
            }
        }
        m[4 * 16 + 8].depth = 1.0;
        let planes = SamplePlanes::from_motion(&m);
        let s = LayerSampler::new(&planes, 16, 16, Sampling::Adaptive, 0);
        let q = Vec2::new(7.6, 4.2);
        assert!(s.fetch(q).is_some_and(|f| !f.smooth && f.v == Vec2::new(2.0, 0.0)));
        let cell: Vec<(Vec2, Vec2)> = s.cell_texels(q).map(|(c, t)| (c, t.v)).collect();
        assert_eq!(
            cell,
            [
                (Vec2::new(7.5, 3.5), Vec2::new(2.0, 0.0)),
                (Vec2::new(8.5, 3.5), Vec2::new(-3.0, 0.0)),
                (Vec2::new(7.5, 4.5), Vec2::new(2.0, 0.0)),
            ]
        );
        // At the image corner the indices clamp as the fetch clamps them.
        assert_eq!(s.cell_texels(Vec2::new(0.2, 0.2)).count(), 4);
        assert!(s.cell_texels(Vec2::new(0.2, 0.2)).all(|(c, _)| c == Vec2::new(0.5, 0.5)));
    }

    #[test]
    fn adaptive_sampling_interpolates_smooth_motion_but_not_across_edges() {
        let m: Vec<Motion> =
            (0..256).map(|i| Motion { v: Vec2::new((i % 16) as f32 * 0.5, 0.0), depth: 0.5 }).collect();
        let planes = SamplePlanes::from_motion(&m);
        let s = LayerSampler::new(&planes, 16, 16, Sampling::Adaptive, 0);
        let a = s.fetch(Vec2::new(3.0, 3.5)).unwrap();
        assert!((a.v.x - 1.25).abs() < 1e-6, "{a:?}");
        let planes = SamplePlanes::from_motion(&m);
        let n = LayerSampler::new(&planes, 16, 16, Sampling::Nearest, 0).fetch(Vec2::new(3.0, 3.5)).unwrap();
        assert_eq!(n.v.x, 1.5);
        // A 5 px motion jump between surfaces 15 and 16 m away (an edge): no interpolation.
        let jump = |i: usize| {
            let near = i % 16 < 8;
            Motion { v: Vec2::new(if near { 5.0 } else { 0.0 }, 0.0), depth: ndc(if near { 15.0 } else { 16.0 }) }
        };
        let m: Vec<Motion> = (0..256).map(jump).collect();
        let planes = SamplePlanes::from_motion(&m);
        let s = LayerSampler::new(&planes, 16, 16, Sampling::Adaptive, 0);
        assert_eq!(s.fetch(Vec2::new(7.9, 2.5)).unwrap().v.x, 5.0);
        assert_eq!(s.fetch(Vec2::new(8.1, 2.5)).unwrap().v.x, 0.0);
        // The same motion ramp over one surface 1 % farther per texel (a wall beside a fast
        // camera, magnified): interpolated, with its Jacobian.
        let wall = |i: usize| Motion {
            v: Vec2::new((i % 16) as f32 * 1.5, 0.0),
            depth: ndc(0.5 * 1.01f32.powi((i % 16) as i32)),
        };
        let m: Vec<Motion> = (0..256).map(wall).collect();
        let planes = SamplePlanes::from_motion(&m);
        let a = LayerSampler::new(&planes, 16, 16, Sampling::Adaptive, 0).fetch(Vec2::new(8.0, 2.5)).unwrap();
        assert!(a.smooth && (a.v.x - 11.25).abs() < 1e-5 && (a.dv[0].x - 1.5).abs() < 1e-6, "{a:?}");
        // The rule: a 5 % step is where motion decides again.
        assert!(continuous_cell(7.0, ndc(10.0), ndc(10.4)));
        assert!(!continuous_cell(7.0, ndc(10.0), ndc(10.6)));
        assert!(continuous_cell(0.5, ndc(10.0), ndc(10.6)));
    }

    /// Depth of a point `d` metres away under a near 0.1 / far 1000 projection.
    fn ndc(d: f32) -> f32 {
        let (n, f) = (0.1, 1000.0);
        f / (f - n) * (1.0 - n / d)
    }

    #[test]
    fn adaptive_sampling_does_not_interpolate_across_a_depth_step_that_moves_alike() {
        // Left half a facade 15 m away, right half one 50 m away; both move by 0.3 px.
        let step = |i: usize| Motion { v: Vec2::new(0.3, 0.0), depth: ndc(if i % 16 < 8 { 15.0 } else { 50.0 }) };
        let m: Vec<Motion> = (0..256).map(step).collect();
        let planes = SamplePlanes::from_motion(&m);
        let s = LayerSampler::new(&planes, 16, 16, Sampling::Adaptive, 0);
        let a = s.fetch(Vec2::new(7.9, 2.5)).unwrap();
        assert!(!a.smooth && a.depth == ndc(15.0), "{a:?}");
        assert_eq!(s.fetch(Vec2::new(8.1, 2.5)).unwrap().depth, ndc(50.0));
        // One plane seen almost edge-on: 5 % farther per texel, interpolated.
        let ramp = |i: usize| Motion { v: Vec2::new(0.3, 0.0), depth: ndc(2.0 * 1.05f32.powi((i % 16) as i32)) };
        let m: Vec<Motion> = (0..256).map(ramp).collect();
        let planes = SamplePlanes::from_motion(&m);
        let s = LayerSampler::new(&planes, 16, 16, Sampling::Adaptive, 0);
        let a = s.fetch(Vec2::new(8.0, 2.5)).unwrap();
        assert!(a.smooth && a.depth > ndc(2.0 * 1.05f32.powi(7)) && a.depth < ndc(2.0 * 1.05f32.powi(8)), "{a:?}");
        // The rule itself: a factor 3 in distance is the edge.
        assert!(continuous_cell(0.0, ndc(15.0), ndc(43.0)));
        assert!(!continuous_cell(0.0, ndc(15.0), ndc(47.0)));
    }
}
