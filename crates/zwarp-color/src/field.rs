//! Warp fields (seed 001 Sec. 3.1): temporal `t M` (eq. 2), second-order temporal
//! `t M + t^2 / 2 A` (eq. 3), spatial for a lateral camera offset (eq. 4) and their linear
//! combinations (Sec. 4: "a linear combination of the warps introduced in Section 3.1").
//!
//! A [`WarpBasis`] holds the per-source-texel terms once per source frame (motion `M`,
//! acceleration `A`, the unit spatial shift `S`, the source depth that orders candidates); a
//! [`Field`] is the basis evaluated at parameters `(t, u, v)` ([`FieldParams`]) without copying
//! a plane: `V(q) = t M(q) + t^2 / 2 A(q) + (u S_x(q), v S_y(q))`, every term sampled at the same
//! texels. Units: pixels of the source image, source -> target (ARCHITECTURE.md "Motion").

use glam::Vec2;
use rayon::prelude::*;
use zwarp_core::{Camera, Error, Image, Motion, Projection, Result};

/// Two planes (x and y components, one value per source texel, row-major).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Planes {
    /// x component per texel.
    pub x: Vec<f32>,
    /// y component per texel.
    pub y: Vec<f32>,
}

/// Texels per parallel task of the per-texel passes.
const CHUNK: usize = 1 << 14;

impl Planes {
    /// The planes of `f` over texels `0..n`: both written in one parallel pass.
    fn from_fn(n: usize, f: impl Fn(usize) -> Vec2 + Sync + Send) -> Self {
        let mut p = Planes { x: vec![0.0; n], y: vec![0.0; n] };
        p.x.par_chunks_mut(CHUNK).zip(p.y.par_chunks_mut(CHUNK)).enumerate().for_each(|(c, (xs, ys))| {
            for (k, (x, y)) in xs.iter_mut().zip(ys).enumerate() {
                let v = f(c * CHUNK + k);
                (*x, *y) = (v.x, v.y);
            }
        });
        p
    }
}

/// `true` if `pred` holds for some element of `v` (a parallel fold without early exit, so
/// each task's scan vectorizes).
fn any_par<T: Sync>(v: &[T], pred: impl Fn(&T) -> bool + Sync) -> bool {
    v.par_chunks(CHUNK).any(|c| c.iter().fold(false, |a, t| a | pred(t)))
}

/// Parameters at which a [`WarpBasis`] is evaluated (seed 001 Sec. 3.1): time offset `t` in
/// units of the basis' motion (eq. 2, 3) and the lateral camera offset `(u, v)` in world units
/// along the source camera's right and up axes (eq. 4).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FieldParams {
    /// Time offset (eq. 2, 3): `t = 1` is the frame the motion `M` points to.
    pub t: f32,
    /// Camera offset along its right axis (eq. 4), world units.
    pub u: f32,
    /// Camera offset along its up axis (eq. 4), world units.
    pub v: f32,
}

impl FieldParams {
    /// Pure temporal reprojection by `t` (eq. 2 / 3).
    pub fn temporal(t: f32) -> Self {
        FieldParams { t, u: 0.0, v: 0.0 }
    }
    /// Pure spatial reprojection by `(u, v)` (eq. 4).
    pub fn spatial(u: f32, v: f32) -> Self {
        FieldParams { t: 0.0, u, v }
    }
    /// Errors unless every parameter is finite.
    pub fn check(&self) -> Result<()> {
        if self.t.is_finite() && self.u.is_finite() && self.v.is_finite() {
            Ok(())
        } else {
            Err(Error::invalid(format!("warp field parameters must be finite, got {self:?}")))
        }
    }
}

/// The per-texel terms of the warp fields of one source frame (seed 001 Sec. 3.1, 4).
/// `Default` is the empty basis (0x0, no term), for [`WarpBasis::set_temporal`] to fill.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct WarpBasis {
    width: u32,
    height: u32,
    /// Source depth per texel (`[0, 1]`, 1 = empty/sky): the ordering key of candidates.
    depth: Vec<f32>,
    /// Motion `M` (eq. 2), pixels per unit `t`.
    motion: Option<Planes>,
    /// Acceleration `A` (eq. 3), pixels per unit `t^2`.
    accel: Option<Planes>,
    /// Unit spatial shift `S` (eq. 4): the field of `(u, v) = (1, 1)`.
    spatial: Option<Planes>,
}

fn check_motion(depth: &Image<f32>, m: &Image<Motion>, what: &str) -> Result<()> {
    depth.check_nonempty("warp basis depth")?;
    depth.check_same_size(m, what)?;
    if any_par(m.data(), |s| s.v.is_nan()) {
        return Err(Error::invalid(format!("{what}: motion holds NaN")));
    }
    Ok(())
}

/// Motion vector of a sample, with the "behind the target eye" marker (`1e9`) kept finite.
#[inline]
fn mv(m: &Motion) -> Vec2 {
    if m.v.is_finite() {
        m.v
    } else {
        Vec2::splat(1.0e9)
    }
}

impl WarpBasis {
    /// A basis with only the source depth (add terms with the `with_*` methods). Errors on an
    /// empty or non-finite depth buffer.
    pub fn new(depth: &Image<f32>) -> Result<Self> {
        depth.check_nonempty("warp basis depth")?;
        if !depth.all_finite() {
            return Err(Error::invalid("warp basis: depth buffer holds NaN or infinite values"));
        }
        Ok(WarpBasis {
            width: depth.width(),
            height: depth.height(),
            depth: depth.data().par_iter().map(|d| d.clamp(0.0, 1.0)).collect(),
            motion: None,
            accel: None,
            spatial: None,
        })
    }

    /// Temporal reprojection (eq. 2): `M` = the motion field `m` of the source frame towards
    /// the frame at `t = 1` (`zwarp_core::motion_field`: camera and per-object motion). Pass the
    /// field towards the previous frame and `t < 0`... or any other frame: `t` counts in its
    /// units. Replaces any motion and acceleration terms.
    pub fn temporal(depth: &Image<f32>, m: &Image<Motion>) -> Result<Self> {
        let mut b = WarpBasis::default();
        b.set_temporal(depth, m)?;
        Ok(b)
    }

    /// [`Self::temporal`] into this basis, reusing its buffers (an engine's steady state, one
    /// basis per generated frame: fresh 1080p planes cost more than the pass that fills them).
    /// Replaces every term; on error the basis holds none (and, once the motion is in, no
    /// depth: a 0x0 basis).
    pub fn set_temporal(&mut self, depth: &Image<f32>, m: &Image<Motion>) -> Result<()> {
        self.set_temporal_with(depth, |x, y| {
            depth.check_same_size(m, "temporal warp field")?;
            let n = m.data().len();
            *x = zwarp_core::pages::reuse(std::mem::take(x), n, 0.0);
            *y = zwarp_core::pages::reuse(std::mem::take(y), n, 0.0);
            x.par_chunks_mut(CHUNK).zip(y.par_chunks_mut(CHUNK)).zip(m.data().par_chunks(CHUNK)).for_each(
                |((xs, ys), ms)| {
                    for ((x, y), s) in xs.iter_mut().zip(ys).zip(ms) {
                        (*x, *y) = s.v.into();
                    }
                },
            );
            Ok(())
        })
    }

    /// [`Self::set_temporal`] with the motion `M` written by `fill` straight into the basis'
    /// planes (x and y, resized by `fill` to the depth's size; their earlier allocations
    /// reused), e.g. by [`zwarp_core::motion_planes_into`]: no motion records to write and
    /// split. Then one pass validates (NaN motion, non-finite depth), clamps the depth to
    /// `[0, 1]` and keeps non-finite motion (behind the target eye) finite.
    pub fn set_temporal_with(
        &mut self,
        depth: &Image<f32>,
        fill: impl FnOnce(&mut Vec<f32>, &mut Vec<f32>) -> Result<()>,
    ) -> Result<()> {
        (self.accel, self.spatial) = (None, None);
        let mut p = self.motion.take().unwrap_or_default();
        depth.check_nonempty("warp basis depth")?;
        fill(&mut p.x, &mut p.y)?;
        let n = depth.data().len();
        if p.x.len() != n || p.y.len() != n {
            return Err(Error::invalid(format!(
                "temporal warp field: motion planes hold {} and {} values, the depth {n}",
                p.x.len(),
                p.y.len()
            )));
        }
        self.depth = zwarp_core::pages::reuse(std::mem::take(&mut self.depth), n, 0.0);
        let src = depth.data();
        // (some motion is NaN, some depth is not finite)
        let (nan_motion, bad_depth) = self
            .depth
            .par_chunks_mut(CHUNK)
            .zip(p.x.par_chunks_mut(CHUNK).zip(p.y.par_chunks_mut(CHUNK)))
            .zip(src.par_chunks(CHUNK))
            .map(|((ds, (xs, ys)), src)| {
                let (mut nan, mut bad) = (false, false);
                for (((d, out), x), y) in src.iter().zip(ds).zip(xs).zip(ys) {
                    bad |= !d.is_finite();
                    *out = d.clamp(0.0, 1.0);
                    nan |= x.is_nan() | y.is_nan();
                    // `mv`: written only where it changes the value.
                    if !(x.is_finite() && y.is_finite()) {
                        (*x, *y) = (1.0e9, 1.0e9);
                    }
                }
                (nan, bad)
            })
            .reduce(|| (false, false), |a, b| (a.0 | b.0, a.1 | b.1));
        if nan_motion || bad_depth {
            // The depth was overwritten: keep no half-filled basis.
            self.depth.clear();
            (self.width, self.height) = (0, 0);
            return Err(Error::invalid(if nan_motion {
                "temporal warp field: motion holds NaN"
            } else {
                "warp basis: depth buffer holds NaN or infinite values"
            }));
        }
        (self.width, self.height) = (depth.width(), depth.height());
        self.motion = Some(p);
        Ok(())
    }

    /// Second-order temporal reprojection (eq. 3) from three frames: the source frame (its
    /// `depth`) and its motion fields `m1`, `m2` towards the frames at times `t1`, `t2` (in frame
    /// units, distinct and non-zero, e.g. `-1, -2` for the two previous frames or `1, -1` for
    /// the neighbours). `M` and `A` are the quadratic through the three positions of every
    /// point (second-order finite differences): `V(t1) = m1`, `V(t2) = m2`, `V(0) = 0`.
    pub fn second_order(
        depth: &Image<f32>,
        (t1, m1): (f32, &Image<Motion>),
        (t2, m2): (f32, &Image<Motion>),
    ) -> Result<Self> {
        check_motion(depth, m1, "second-order warp field")?;
        check_motion(depth, m2, "second-order warp field")?;
        let det = t1 * t2 * (t2 - t1);
        if !(det.is_finite() && det.abs() > 1e-12) {
            return Err(Error::invalid(format!(
                "second-order warp field: times {t1}, {t2} must be distinct and non-zero"
            )));
        }
        let mut b = Self::new(depth)?;
        let (d1, d2) = (m1.data(), m2.data());
        // V(t) = a t + c t^2 through (t1, d1), (t2, d2): a = (d1 t2^2 - d2 t1^2) / det,
        // c = (t1 d2 - t2 d1) / det; M = a, A = 2 c.
        b.motion = Some(Planes::from_fn(d1.len(), |i| (mv(&d1[i]) * (t2 * t2) - mv(&d2[i]) * (t1 * t1)) / det));
        b.accel = Some(Planes::from_fn(d1.len(), |i| 2.0 * (mv(&d2[i]) * t1 - mv(&d1[i]) * t2) / det));
        Ok(b)
    }

    /// Adds the spatial term (eq. 4) of the source camera `cam`: moving the viewpoint by
    /// `(u, v)` along the camera's right and up axes shifts a surface at view depth `z` by
    /// `(-u lambda_u, -v lambda_v) / z` in NDC, i.e. `(-u P00 w / 2, +v P11 h / 2) (1 / z - 1 / z_f)`
    /// pixels (row 0 at the top). `focus`: distance `z_f` of the plane that stays put (defocus
    /// with a thin lens: the sample cameras are sheared so that plane maps to itself); `None`
    /// for parallel cameras (stereo). Orthographic cameras shift every point equally. Sky
    /// pixels (depth 1) sit on the far plane.
    pub fn with_spatial(mut self, cam: &Camera, focus: Option<f32>) -> Result<Self> {
        if (cam.width, cam.height) != (self.width, self.height) {
            return Err(Error::invalid(format!(
                "spatial warp field: camera renders {}x{} but the source is {}x{}",
                cam.width, cam.height, self.width, self.height
            )));
        }
        let inv_f = match focus {
            None => 0.0,
            Some(f) if f.is_finite() && f > 0.0 => 1.0 / f,
            Some(f) => {
                return Err(Error::invalid(format!("spatial warp field: focus distance must be positive, got {f}")))
            }
        };
        let (kx, ky) = (-cam.proj.x_axis.x * cam.width as f32 * 0.5, cam.proj.y_axis.y * cam.height as f32 * 0.5);
        let depth = &self.depth;
        let c = *cam;
        self.spatial = Some(Planes::from_fn(depth.len(), |i| {
            let g = match c.projection {
                Projection::Perspective { .. } => 1.0 / c.linear_depth(depth[i]) - inv_f,
                Projection::Orthographic { .. } => 1.0,
            };
            Vec2::new(kx * g, ky * g)
        }));
        Ok(self)
    }

    /// Source image size.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }
    /// Source depth per texel (clamped to `[0, 1]`).
    pub fn depth(&self) -> &[f32] {
        &self.depth
    }
    /// `true` if the basis has a motion term.
    pub fn has_motion(&self) -> bool {
        self.motion.is_some()
    }
    /// `true` if the basis has an acceleration term.
    pub fn has_acceleration(&self) -> bool {
        self.accel.is_some()
    }
    /// `true` if the basis has a spatial term.
    pub fn has_spatial(&self) -> bool {
        self.spatial.is_some()
    }

    /// The field at `params` (no copy: the terms with a non-zero factor, referenced). Errors on
    /// non-finite parameters or a parameter whose term the basis lacks.
    pub fn field(&self, params: FieldParams) -> Result<Field<'_>> {
        params.check()?;
        let mut f = Field {
            width: self.width,
            height: self.height,
            depth: &self.depth,
            terms: [Term::EMPTY; MAX_TERMS],
            n: 0,
            params,
        };
        fn push<'b>(f: &mut Field<'b>, planes: &'b Option<Planes>, s: Vec2, what: &str) -> Result<()> {
            if s == Vec2::ZERO {
                return Ok(());
            }
            let p = planes.as_ref().ok_or_else(|| {
                Error::invalid(format!("warp field: {what} requested but the basis has no {what} term"))
            })?;
            f.terms[f.n] = Term { x: &p.x, y: &p.y, scale: s };
            f.n += 1;
            Ok(())
        }
        push(&mut f, &self.motion, Vec2::splat(params.t), "motion (t)")?;
        if self.accel.is_some() {
            push(&mut f, &self.accel, Vec2::splat(0.5 * params.t * params.t), "acceleration")?;
        }
        push(&mut f, &self.spatial, Vec2::new(params.u, params.v), "spatial (u, v)")?;
        Ok(f)
    }

    /// The field at each of `params` (see [`Self::field`]).
    pub fn fields(&self, params: &[FieldParams]) -> Result<Vec<Field<'_>>> {
        params.iter().map(|p| self.field(*p)).collect()
    }
}

/// Most terms a [`Field`] combines (motion, acceleration, spatial).
pub const MAX_TERMS: usize = 3;

/// One term of a [`Field`]: two planes times a per-component factor.
#[derive(Clone, Copy, Debug)]
pub struct Term<'a> {
    /// x component per texel.
    pub x: &'a [f32],
    /// y component per texel.
    pub y: &'a [f32],
    /// Component-wise factor.
    pub scale: Vec2,
}

impl Term<'_> {
    const EMPTY: Term<'static> = Term { x: &[], y: &[], scale: Vec2::ZERO };
}

/// A warp field `V` at source texels (seed 001 eq. 1: `x_w = x_s + V(x_s)`), the sum of up to
/// [`MAX_TERMS`] scaled plane pairs, with the source depth of every texel (the candidate order:
/// Sec. 3.1 "we take the one with the minimum depth"). Cheap to copy; borrows a [`WarpBasis`]
/// or caller planes ([`Field::from_planes`]).
#[derive(Clone, Copy, Debug)]
pub struct Field<'a> {
    width: u32,
    height: u32,
    depth: &'a [f32],
    terms: [Term<'a>; MAX_TERMS],
    n: usize,
    params: FieldParams,
}

impl<'a> Field<'a> {
    /// The field `scale * (x, y)` over caller planes (e.g. an engine's motion vectors), with the
    /// source `depth` (`[0, 1]`, 1 = sky). Errors on size mismatches.
    pub fn from_planes(
        width: u32,
        height: u32,
        depth: &'a [f32],
        x: &'a [f32],
        y: &'a [f32],
        scale: Vec2,
    ) -> Result<Self> {
        let n = width as usize * height as usize;
        if n == 0 || depth.len() != n || x.len() != n || y.len() != n {
            return Err(Error::invalid(format!("warp field: planes do not hold {width}x{height} texels")));
        }
        let mut terms = [Term::EMPTY; MAX_TERMS];
        terms[0] = Term { x, y, scale };
        Ok(Field { width, height, depth, terms, n: 1, params: FieldParams { t: scale.x, u: 0.0, v: 0.0 } })
    }

    /// Source image size.
    #[inline]
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }
    /// The parameters this field was evaluated at.
    pub fn params(&self) -> FieldParams {
        self.params
    }
    /// The terms in use.
    pub fn terms(&self) -> &[Term<'a>] {
        &self.terms[..self.n]
    }
    /// Source depth per texel.
    #[inline]
    pub fn depth(&self) -> &'a [f32] {
        self.depth
    }

    /// `V` at texel index `i` (row-major). Panics if `i` is out of range.
    #[inline(always)]
    pub fn v(&self, i: usize) -> Vec2 {
        let mut v = Vec2::ZERO;
        for t in &self.terms[..self.n] {
            v += t.scale * Vec2::new(t.x[i], t.y[i]);
        }
        v
    }

    /// [`Self::v`] without bounds checks.
    ///
    /// # Safety
    /// `i < width * height`.
    #[inline(always)]
    pub(crate) unsafe fn v_unchecked(&self, i: usize) -> Vec2 {
        let mut v = Vec2::ZERO;
        for t in self.terms.get_unchecked(..self.n) {
            v += t.scale * Vec2::new(*t.x.get_unchecked(i), *t.y.get_unchecked(i));
        }
        v
    }

    /// The field with every term's factor multiplied by `k` (e.g. `-1` to reverse it).
    pub fn scaled(mut self, k: f32) -> Self {
        for t in &mut self.terms[..self.n] {
            t.scale *= k;
        }
        self
    }

    /// The field materialised as one [`Motion`] per texel (`v`, `depth` = source depth).
    pub fn to_motion(&self) -> Image<Motion> {
        let n = self.width as usize * self.height as usize;
        let data: Vec<Motion> = (0..n).into_par_iter().map(|i| Motion { v: self.v(i), depth: self.depth[i] }).collect();
        Image::from_vec(self.width, self.height, data).expect("size matches")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn spatial_term_is_the_reprojection_of_a_lateral_camera_shift() {
        let (w, h) = (64, 48);
        let a = Camera::perspective(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, Vec3::Y, 1.0, 0.1, 100.0, w, h).unwrap();
        let (u, v) = (0.3f32, -0.2f32);
        let b =
            Camera::perspective(Vec3::new(u, v, 10.0), Vec3::new(u, v, 0.0), Vec3::Y, 1.0, 0.1, 100.0, w, h).unwrap();
        let depth = Image::from_fn(w, h, |x, y| a.stored_depth(4.0 + 0.1 * (x + y) as f32));
        let basis = WarpBasis::new(&depth).unwrap().with_spatial(&a, None).unwrap();
        let f = basis.field(FieldParams::spatial(u, v)).unwrap();
        let exact = zwarp_core::motion_field(&depth, None, &a, &b, &[]).unwrap();
        for i in 0..(w * h) as usize {
            assert!((f.v(i) - exact.data()[i].v).length() < 2e-3, "{i}: {} vs {}", f.v(i), exact.data()[i].v);
        }
        assert!(basis.field(FieldParams::temporal(1.0)).is_err());
        assert!(basis.field(FieldParams { t: 0.0, u: f32::NAN, v: 0.0 }).is_err());
    }

    /// The planes hold every texel's motion across the parallel chunks (an image of several
    /// chunks), the "behind the target eye" marker finite, the depth clamped to `[0, 1]`.
    #[test]
    fn temporal_planes_are_the_motion_of_every_texel() {
        let (w, h) = (203u32, 181u32);
        assert!((w * h) as usize > 2 * CHUNK);
        let depth = Image::from_fn(w, h, |x, y| if (x + y) % 5 == 0 { 1.0 } else { 0.001 * x as f32 });
        let m = Image::from_fn(w, h, |x, y| {
            let i = (y * w + x) as f32;
            let v = if (x * y) % 97 == 1 { Vec2::splat(f32::INFINITY) } else { Vec2::new(i, -0.5 * i) };
            Motion { v, depth: 0.5 }
        });
        let b = WarpBasis::temporal(&depth, &m).unwrap();
        let f = b.field(FieldParams::temporal(1.0)).unwrap();
        for (i, s) in m.data().iter().enumerate() {
            let want = if s.v.is_finite() { s.v } else { Vec2::splat(1.0e9) };
            assert_eq!(f.v(i), want, "texel {i}");
            assert_eq!(f.depth()[i], depth.data()[i]);
        }
        let nan = Image::from_fn(w, h, |x, y| Motion {
            v: Vec2::splat(if x * y == 30_000 { f32::NAN } else { 0.0 }),
            depth: 0.5,
        });
        assert!(WarpBasis::temporal(&depth, &nan).is_err());
    }

    #[test]
    fn second_order_terms_pass_through_the_three_positions() {
        let depth = Image::new(4, 2, 0.5f32);
        let m1 = Image::from_fn(4, 2, |x, _| Motion { v: Vec2::new(x as f32, 1.0), depth: 0.5 });
        let m2 = Image::from_fn(4, 2, |x, _| Motion { v: Vec2::new(3.0 * x as f32, -2.0), depth: 0.5 });
        let b = WarpBasis::second_order(&depth, (-1.0, &m1), (-2.0, &m2)).unwrap();
        for i in 0..8 {
            let at = |t| b.field(FieldParams::temporal(t)).unwrap().v(i);
            assert!((at(-1.0) - m1.data()[i].v).length() < 1e-5);
            assert!((at(-2.0) - m2.data()[i].v).length() < 1e-5);
        }
        assert!(b.field(FieldParams::temporal(0.0)).unwrap().terms().is_empty());
        assert!(WarpBasis::second_order(&depth, (1.0, &m1), (1.0, &m2)).is_err());
    }
}
