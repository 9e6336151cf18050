//! Sampling a [`Field`] and its colour image between texel centres (seed 001 Sec. 3.4,
//! "Sampling Strategy", Fig. 4): bilinear where the four texels around `q` satisfy the
//! convergence condition, nearest where they do not, for the warp field and the colour alike —
//! "bilinear colour sampling on surfaces, nearest across discontinuities".
//!
//! The condition is tested in one of two ways ([`Continuity`]): the heuristic warp uses the
//! cheap local proxy of the shared search (`zwarp_warp::sampling::CONTINUITY_PX`: the four motions
//! differ by less than a pixel per component), the robust warp the convergence term `rho` of the
//! cell (Appendix A, [`crate::robust::rho_cells`]).
//!
//! [`ColorSampler`] implements `zwarp_warp::sampling::MotionSource`, so every colour warp runs
//! the one fixed-point search of the project (`zwarp_warp::search::fixed_point_search`).

use std::cell::Cell;

use glam::Vec2;
use zwarp_warp::sampling::{MotionSource, Sample, CONTINUITY_PX};

use crate::field::Field;

/// How [`ColorSampler`] decides between bilinear and nearest sampling in a cell (the square
/// between four texel centres).
#[derive(Clone, Copy, Debug)]
pub enum Continuity<'a> {
    /// Bilinear where the cell's four motions differ by less than `CONTINUITY_PX` (one pixel)
    /// per component (the shared search's proxy for `rho < 1`).
    Range,
    /// Bilinear where the cell's convergence term `rho` (one value per cell, `(w - 1) x (h - 1)`
    /// row-major, [`crate::robust::rho_cells`]) is below 1 (seed 001 Sec. 3.4).
    Rho(&'a [f32]),
}

/// Samples a warp field and a colour image (seed 001 Sec. 3.4 / Fig. 4). The sample's `tag`
/// is 1 for a bilinear sample, 0 for a nearest one; `depth` is the source depth (sky = 1, a
/// valid sample: the colour warp moves the sky too).
#[derive(Clone, Copy, Debug)]
pub struct ColorSampler<'a> {
    field: Field<'a>,
    continuity: Continuity<'a>,
    w: u32,
    h: u32,
    size: Vec2,
}

/// The four texels around a position and the bilinear weights.
#[derive(Clone, Copy, Debug)]
struct Loc {
    i: [usize; 4],
    ax: f32,
    ay: f32,
    /// Cell index (`None` in the half-texel border strip, which is always nearest).
    cell: Option<usize>,
    /// Texel containing the position.
    near: usize,
}

impl<'a> ColorSampler<'a> {
    /// A sampler of `field` deciding continuity by `continuity`. Panics if a `Rho` plane does
    /// not have `(w - 1) (h - 1)` cells (internal callers build it from the same field).
    pub fn new(field: Field<'a>, continuity: Continuity<'a>) -> Self {
        let (w, h) = field.size();
        if let Continuity::Rho(r) = continuity {
            assert_eq!(r.len(), (w.saturating_sub(1) * h.saturating_sub(1)) as usize, "rho plane size");
        }
        ColorSampler { field, continuity, w, h, size: Vec2::new(w as f32, h as f32) }
    }

    /// The field.
    pub fn field(&self) -> &Field<'a> {
        &self.field
    }

    /// `true` if `q` lies in the source image `[0, w) x [0, h)`.
    #[inline(always)]
    pub fn inside(&self, q: Vec2) -> bool {
        (q.x >= 0.0) & (q.y >= 0.0) & (q.x < self.size.x) & (q.y < self.size.y)
    }

    /// `q` clamped into the image (for the colour look-up of positions just outside).
    #[inline(always)]
    pub fn clamp(&self, q: Vec2) -> Vec2 {
        q.clamp(Vec2::ZERO, self.size - Vec2::splat(1.0e-3))
    }

    #[inline(always)]
    fn locate(&self, q: Vec2) -> Loc {
        debug_assert!(self.inside(q));
        let (wm, hm) = (self.w - 1, self.h - 1);
        // Texel-centre coordinates t = q - 0.5 >= -0.5: floor(t) = trunc(t + 1) - 1.
        let (tx, ty) = (q.x + 0.5, q.y + 0.5);
        let (ix, iy) = (tx as u32, ty as u32);
        let (ax, ay) = (tx - ix as f32, ty - iy as f32);
        let x0 = ix.saturating_sub(1).min(wm);
        let y0 = iy.saturating_sub(1).min(hm);
        let (x1, y1) = (ix.min(wm), iy.min(hm));
        let wu = self.w as usize;
        let cell = ((x0 != x1) & (y0 != y1)).then(|| y0 as usize * wm as usize + x0 as usize);
        // The texel containing q: x0 when frac(q + 0.5) < 0.5, else x1 (equal to
        // `floor(q)` clamped into the image, and to what the AVX2 lanes select).
        let (nx, ny) = (if ax >= 0.5 { x1 } else { x0 }, if ay >= 0.5 { y1 } else { y0 });
        let near = ny as usize * wu + nx as usize;
        let (r0, r1) = (y0 as usize * wu, y1 as usize * wu);
        Loc { i: [r0 + x0 as usize, r0 + x1 as usize, r1 + x0 as usize, r1 + x1 as usize], ax, ay, cell, near }
    }

    /// The field sample at `q` (inside the image), and whether it is bilinear.
    #[inline(always)]
    fn fetch_at(&self, q: Vec2) -> (Sample, bool) {
        let l = self.locate(q);
        let f = &self.field;
        let d = f.depth();
        // SAFETY: `locate` clamps every index into the image; planes hold w * h texels.
        let v = unsafe { [f.v_unchecked(l.i[0]), f.v_unchecked(l.i[1]), f.v_unchecked(l.i[2]), f.v_unchecked(l.i[3])] };
        let smooth = match self.continuity {
            Continuity::Range => {
                let lo = v[0].min(v[1]).min(v[2].min(v[3]));
                let hi = v[0].max(v[1]).max(v[2].max(v[3]));
                (hi - lo).max_element() < CONTINUITY_PX
            }
            Continuity::Rho(r) => l.cell.is_some_and(|c| r[c] < 1.0),
        };
        if smooth {
            let z = [d[l.i[0]], d[l.i[1]], d[l.i[2]], d[l.i[3]]];
            let top = v[0].lerp(v[1], l.ax);
            let bot = v[2].lerp(v[3], l.ax);
            let zt = z[0] + (z[1] - z[0]) * l.ax;
            let zb = z[2] + (z[3] - z[2]) * l.ax;
            let dvdx = (v[1] - v[0]).lerp(v[3] - v[2], l.ay);
            let dvdy = bot - top;
            let dzdx = (z[1] - z[0]) + ((z[3] - z[2]) - (z[1] - z[0])) * l.ay;
            let s = Sample {
                v: top.lerp(bot, l.ay),
                depth: zt + (zb - zt) * l.ay,
                tag: 1,
                dv: [dvdx, dvdy],
                dz: Vec2::new(dzdx, zb - zt),
                smooth: true,
            };
            (s, true)
        } else {
            // SAFETY: as above.
            let vn = unsafe { f.v_unchecked(l.near) };
            let s = Sample { v: vn, depth: d[l.near], tag: 0, dv: [Vec2::ZERO; 2], dz: Vec2::ZERO, smooth: false };
            (s, false)
        }
    }

    /// The field sample at `q`, `None` outside the image.
    #[inline(always)]
    pub fn fetch(&self, q: Vec2) -> Option<Sample> {
        self.inside(q).then(|| self.fetch_at(q).0)
    }

    /// The colour at `q` (clamped into the image): bilinear where the field is continuous
    /// around `q` (the same decision as [`Self::fetch`]), the containing texel otherwise.
    /// `color` holds `w * h` texels. Panics on a size mismatch.
    #[inline(always)]
    pub fn color(&self, color: &[[f32; 3]], q: Vec2) -> [f32; 3] {
        assert_eq!(color.len(), self.field.depth().len(), "colour plane size");
        let q = self.clamp(q);
        let l = self.locate(q);
        let smooth = match self.continuity {
            Continuity::Range => {
                let f = &self.field;
                // SAFETY: indices clamped by `locate`.
                let v = unsafe {
                    [f.v_unchecked(l.i[0]), f.v_unchecked(l.i[1]), f.v_unchecked(l.i[2]), f.v_unchecked(l.i[3])]
                };
                let lo = v[0].min(v[1]).min(v[2].min(v[3]));
                let hi = v[0].max(v[1]).max(v[2].max(v[3]));
                (hi - lo).max_element() < CONTINUITY_PX
            }
            Continuity::Rho(r) => l.cell.is_some_and(|c| r[c] < 1.0),
        };
        if smooth {
            let c = [color[l.i[0]], color[l.i[1]], color[l.i[2]], color[l.i[3]]];
            let mut o = [0.0; 3];
            for (k, ok) in o.iter_mut().enumerate() {
                let top = c[0][k] + (c[1][k] - c[0][k]) * l.ax;
                let bot = c[2][k] + (c[3][k] - c[2][k]) * l.ax;
                *ok = top + (bot - top) * l.ay;
            }
            o
        } else {
            color[l.near]
        }
    }

    /// The source depth at texel containing `q` (clamped into the image).
    #[inline]
    pub fn depth_near(&self, q: Vec2) -> f32 {
        self.field.depth()[self.locate(self.clamp(q)).near]
    }
}

impl MotionSource for ColorSampler<'_> {
    type Walk = ();
    #[inline(always)]
    fn sample(&self, q: Vec2, _walk: &mut ()) -> Option<Sample> {
        self.fetch(q)
    }
}

/// Most iterates a [`Recorder`] keeps (the orbit of seed 001 Sec. 3.3's in-painting).
pub(crate) const MAX_RECORDED: usize = 16;

/// One visited iterate of a walk: position, field and depth there.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Visit {
    pub q: Vec2,
    pub v: Vec2,
    pub depth: f32,
}

/// A [`ColorSampler`] that records the iterates of one single-seed search (interior mutability:
/// the shared search takes its source by shared reference), so that a search that did not
/// converge leaves its orbit for the in-painting of Sec. 3.3.
pub(crate) struct Recorder<'s, 'a> {
    pub sampler: &'s ColorSampler<'a>,
    pub visits: [Cell<Visit>; MAX_RECORDED],
    pub n: Cell<usize>,
}

impl<'s, 'a> Recorder<'s, 'a> {
    #[inline(always)]
    pub fn new(sampler: &'s ColorSampler<'a>) -> Self {
        Recorder { sampler, visits: Default::default(), n: Cell::new(0) }
    }
    /// The recorded iterates.
    #[inline(always)]
    pub fn visits(&self) -> impl Iterator<Item = Visit> + '_ {
        self.visits[..self.n.get()].iter().map(Cell::get)
    }
    /// The last recorded iterate.
    #[inline(always)]
    pub fn last(&self) -> Option<Visit> {
        self.n.get().checked_sub(1).map(|i| self.visits[i].get())
    }
}

impl MotionSource for Recorder<'_, '_> {
    type Walk = ();
    #[inline(always)]
    fn sample(&self, q: Vec2, _walk: &mut ()) -> Option<Sample> {
        let s = self.sampler.fetch(q)?;
        let n = self.n.get();
        if n < MAX_RECORDED {
            self.visits[n].set(Visit { q, v: s.v, depth: s.depth });
            self.n.set(n + 1);
        }
        Some(s)
    }
}
