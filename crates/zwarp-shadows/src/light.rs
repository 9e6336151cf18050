//! Area lights, their stratified samples and the per-sample shadow-map cameras (seed 000, Sec. 6).
//!
//! Every light sample gets its own shadow map. All sample cameras share the centre camera's
//! frustum orientation (image plane parallel to the emitter, axis = the light's normal), so the
//! centre map and a sample map differ by a pure parallax, which is what makes warping the centre
//! map to the S sample views cheap and accurate:
//!
//! - **local lights** (perspective maps): the eye is shifted by the sample offset `o` inside the
//!   emitter plane, `view_i = translate(-o) * view_c`. A point at view depth `z` moves by
//!   `-f o / z` pixels (parallax proportional to inverse depth);
//! - **directional lights** (orthographic maps): a sample is a *direction* (the emitter seen from
//!   `target`, at distance `D = |target - center|`); the projection is sheared,
//!   `x' = x + (o_x / D) (z - z_0)`, so a point moves by `f o (z - z_0) / D` pixels.
//!
//! In both cases the view depth of a point is the same in every sample map. [`LightRig`] keeps the
//! per-sample pixel shift `K_i` so the visibility pass can project a receiver into map `i` with
//! two multiply-adds: `p_i = p_c + K_i g`, `g = 1/z` (perspective) or `z - z_0` (orthographic).

use std::path::Path;

use glam::{DVec3, Mat4, Vec2, Vec3, Vec4};
use rayon::prelude::*;
use zwarp_core::{
    Aabb, AreaLight, Camera, Error, Image, LightShape, Motion, ParallaxMotion, Projection, Result, Scene,
};
use zwarp_raster::{UmbraPeeling, ViewRegion};

/// Largest number of light samples S accepted (memory and time guard).
pub const MAX_SAMPLES: u32 = 4096;

/// Checks an area light: finite positions, centre != target, up not parallel to the axis,
/// positive finite emitter size.
pub fn validate_light(light: &AreaLight) -> Result<()> {
    if !(light.center.is_finite() && light.target.is_finite() && light.up.is_finite()) {
        return Err(Error::invalid("light center/target/up must be finite"));
    }
    let axis = light.target - light.center;
    if axis.length_squared() < 1e-20 {
        return Err(Error::invalid("light center and target coincide"));
    }
    if axis.normalize().cross(light.up.normalize_or_zero()).length_squared() < 1e-10 {
        return Err(Error::invalid("light up vector is parallel to the light axis"));
    }
    match light.shape {
        LightShape::Rect { width, height } => {
            if !(width.is_finite() && height.is_finite() && width >= 0.0 && height >= 0.0) {
                return Err(Error::invalid(format!("rect light needs finite sizes >= 0, got {width} x {height}")));
            }
        }
        LightShape::Disc { radius } => {
            if !(radius.is_finite() && radius >= 0.0) {
                return Err(Error::invalid(format!("disc light needs a finite radius >= 0, got {radius}")));
            }
        }
    }
    Ok(())
}

/// Parses an area light from JSON (the serde form of [`AreaLight`]):
/// `{"center": [x,y,z], "target": [x,y,z], "up": [x,y,z], "shape": {"kind": "disc", "radius": r}
/// | {"kind": "rect", "width": w, "height": h}, "directional": false}` and validates it.
pub fn light_from_json_str(text: &str) -> Result<AreaLight> {
    light_from_json_str_at(text, DVec3::ZERO)
}

/// [`light_from_json_str`] for a light written in the coordinates of the file of a scene whose
/// [`origin`](zwarp_core::Scene::origin) is `origin`: `center` and `target` are read in `f64`
/// and moved by `-origin` before they become `f32`.
pub fn light_from_json_str_at(text: &str, origin: DVec3) -> Result<AreaLight> {
    let bad = |e: serde_json::Error| Error::invalid(format!("bad light JSON: {e}"));
    let mut v: serde_json::Value = serde_json::from_str(text).map_err(bad)?;
    for key in ["center", "target"] {
        if let Some(a) = v.get_mut(key).and_then(|p| p.as_array_mut()).filter(|a| a.len() == 3) {
            for (x, o) in a.iter_mut().zip(origin.to_array()) {
                if let Some(f) = x.as_f64() {
                    *x = serde_json::json!(f - o);
                }
            }
        }
    }
    let light: AreaLight = serde_json::from_value(v).map_err(bad)?;
    validate_light(&light)?;
    Ok(light)
}

/// Reads a light file (see [`light_from_json_str`]); errors name the file.
pub fn load_light(path: impl AsRef<Path>) -> Result<AreaLight> {
    load_light_at(path, DVec3::ZERO)
}

/// Reads a light file in the coordinates of a scene's file (see [`light_from_json_str_at`]).
pub fn load_light_at(path: impl AsRef<Path>, origin: DVec3) -> Result<AreaLight> {
    let path = path.as_ref();
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    light_from_json_str_at(&text, origin).map_err(|e| match e {
        Error::Invalid(msg) => Error::parse(path, msg),
        other => other,
    })
}

/// Pretty JSON of a light (the format [`light_from_json_str`] reads).
pub fn light_to_json(light: &AreaLight) -> String {
    // Plain f32 / Vec3 fields: serialization cannot fail.
    serde_json::to_string_pretty(light).unwrap_or_default()
}

/// Two unit vectors perpendicular to `n` and to each other.
fn perpendiculars(n: Vec3) -> (Vec3, Vec3) {
    let n = n.normalize_or(Vec3::Z);
    // Pick the world axis least aligned with n.
    let a = n.abs();
    let helper = if a.x <= a.y && a.x <= a.z {
        Vec3::X
    } else if a.y <= a.z {
        Vec3::Y
    } else {
        Vec3::Z
    };
    let p1 = n.cross(helper).normalize();
    let p2 = n.cross(p1).normalize();
    (p1, p2)
}

/// A local disc light placed from the scene bounds (seed 000, Sec. 6 uses one area light per
/// scene): above the scene (along [`Scene::up`]) at one bounding-box diagonal and to one side at
/// 0.6 diagonals, facing the bounds centre, with a radius of 6% of the diagonal so penumbrae are
/// clearly visible (a 2 m tall object 100 m from the light casts a ~0.5 m wide penumbra per 10 m
/// diagonal... scaled with the scene). Errors on an empty scene.
pub fn default_light(scene: &Scene) -> Result<AreaLight> {
    scene.check_nonempty()?;
    let b = scene.bounds();
    if b.is_empty() || !b.min.is_finite() || !b.max.is_finite() {
        return Err(Error::invalid("scene bounds are empty or not finite"));
    }
    let up = scene.up.normalize_or(Vec3::Z);
    let diag = b.extent().length().max(1e-3);
    let c = b.center();
    let (p1, p2) = perpendiculars(up);
    let side = (p1 + 0.5 * p2).normalize();
    let top = b.corners().iter().map(|k| (*k - c).dot(up)).fold(0.0f32, f32::max);
    let center = c + up * (top + diag) + side * (0.6 * diag);
    let axis = (c - center).normalize();
    // Up hint: the horizontal direction perpendicular to `side` (never parallel to the axis).
    let hint = up.cross(side).normalize();
    let hint = if hint.cross(axis).length_squared() < 1e-6 { up } else { hint };
    Ok(AreaLight { center, target: c, up: hint, shape: LightShape::Disc { radius: 0.06 * diag }, directional: false })
}

/// Deterministic 64-bit mixer (SplitMix64) for the jitter of stratified samples.
fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn unit_f32(h: u64) -> f32 {
    (h >> 40) as f32 / (1u64 << 24) as f32
}

/// Grid factorization `(a, b)` of `s` with `a * b = s`, `a <= b` and `a` as large as possible
/// (a perfect square gives a square grid; a prime gives `1 x s` strips, still stratified).
fn grid_dims(s: u32) -> (u32, u32) {
    let mut a = (s as f64).sqrt() as u32;
    while a > 1 && !s.is_multiple_of(a) {
        a -= 1;
    }
    let a = a.max(1);
    (a, s / a)
}

/// Shirley-Chiu concentric map of the unit square `[0,1]^2` to the unit disc (area preserving,
/// so strata of the square stay equal-area strata of the disc).
fn concentric_disc(u: Vec2) -> Vec2 {
    let a = 2.0 * u - Vec2::ONE;
    if a.x == 0.0 && a.y == 0.0 {
        return Vec2::ZERO;
    }
    let (r, phi) = if a.x.abs() > a.y.abs() {
        (a.x, std::f32::consts::FRAC_PI_4 * (a.y / a.x))
    } else {
        (a.y, std::f32::consts::FRAC_PI_2 - std::f32::consts::FRAC_PI_4 * (a.x / a.y))
    };
    Vec2::new(r * phi.cos(), r * phi.sin())
}

/// S stratified sample offsets on the emitter, in the light's (right, up) plane coordinates
/// (seed 000, Sec. 6: "depth maps generated for each area-light sample").
///
/// The unit square is split into an `a x b` grid (`a * b = S`, as square as possible, the longer
/// side of a rectangle gets more strata); with `jitter` each stratum gets one uniformly jittered
/// point (deterministic from `seed`), otherwise its centre. Rectangles scale the square, discs map
/// it with the concentric map. `S = 1` is always the emitter centre (the hard-shadow limit).
pub fn light_samples(shape: &LightShape, s: u32, seed: u64, jitter: bool) -> Result<Vec<Vec2>> {
    if s == 0 || s > MAX_SAMPLES {
        return Err(Error::invalid(format!("number of light samples S must be in 1..={MAX_SAMPLES}, got {s}")));
    }
    if s == 1 {
        return Ok(vec![Vec2::ZERO]);
    }
    let (a, b) = grid_dims(s);
    // Columns along x: give the longer emitter side the larger count.
    let (cols, rows) = match *shape {
        LightShape::Rect { width, height } if height > width => (a, b),
        _ => (b, a),
    };
    let mut out = Vec::with_capacity(s as usize);
    for j in 0..rows {
        for i in 0..cols {
            let k = (j * cols + i) as u64;
            let (jx, jy) = if jitter {
                let h = splitmix64(seed ^ splitmix64(k));
                (unit_f32(h), unit_f32(splitmix64(h)))
            } else {
                (0.5, 0.5)
            };
            let u = Vec2::new((i as f32 + jx) / cols as f32, (j as f32 + jy) / rows as f32);
            out.push(match *shape {
                LightShape::Rect { width, height } => (u - Vec2::splat(0.5)) * Vec2::new(width, height),
                LightShape::Disc { radius } => concentric_disc(u) * radius,
            });
        }
    }
    Ok(out)
}

/// Half extents of the emitter along the light's right / up axes.
pub fn half_extents(shape: &LightShape) -> Vec2 {
    match *shape {
        LightShape::Rect { width, height } => Vec2::new(width, height) * 0.5,
        LightShape::Disc { radius } => Vec2::splat(radius),
    }
}

/// The shadow-map cameras of one area light: the centre camera and one camera per light sample,
/// all with the same orientation (see the module docs), covering the scene bounds at time `t`
/// from every sample.
#[derive(Clone, Debug)]
pub struct LightRig {
    /// The light.
    pub light: AreaLight,
    /// The light's frame: right, up, axis (unit, right-handed view frame: the camera looks along
    /// `axis`).
    pub frame: [Vec3; 3],
    /// Centre shadow-map camera (the emitter centre; source view of the warps).
    pub center: Camera,
    /// Sample offsets in the emitter plane (right, up), world units.
    pub offsets: Vec<Vec2>,
    /// One shadow-map camera per sample.
    pub cameras: Vec<Camera>,
    /// Per-sample pixel shift `K_i`: a receiver at centre-map pixel `p_c` and depth parameter `g`
    /// lies at `p_c + K_i g` in map `i` (see [`LightRig::depth_param`]).
    pub shifts: Vec<Vec2>,
    /// Shear pivot depth `z_0` of directional lights (0 for local lights).
    pub pivot: f32,
    /// Distance `D = |target - center|` (angular scale of directional lights).
    pub distance: f32,
}

impl LightRig {
    /// Builds the rig for `light` over the bounds of `scene` at time `t`: S stratified samples
    /// ([`light_samples`]), square `sm_size` maps, near/far fitted to the bounds.
    ///
    /// Errors: invalid light, S or map size out of range, empty scene, or a local light whose
    /// emitter is not entirely in front of the scene (some bounds corner at or behind the emitter
    /// plane: a single perspective shadow map cannot cover it).
    pub fn new(
        scene: &Scene,
        t: f32,
        light: &AreaLight,
        samples: u32,
        sm_size: u32,
        seed: u64,
        jitter: bool,
    ) -> Result<Self> {
        validate_light(light)?;
        scene.check_nonempty()?;
        if sm_size == 0 || sm_size > 16384 {
            return Err(Error::invalid(format!("shadow-map size must be in 1..=16384, got {sm_size}")));
        }
        let offsets = light_samples(&light.shape, samples, seed, jitter)?;
        let boxes: Vec<Aabb> =
            (0..scene.instances.len() as u32).map(|i| scene.instance_aabb_at(i, t)).filter(|b| !b.is_empty()).collect();
        let bounds = boxes.iter().fold(Aabb::EMPTY, |b, i| b.union(*i));
        if bounds.is_empty() || !bounds.min.is_finite() || !bounds.max.is_finite() {
            return Err(Error::invalid("scene bounds are empty or not finite"));
        }
        let axis = (light.target - light.center).normalize();
        let distance = (light.target - light.center).length();
        let right = axis.cross(light.up).normalize();
        let upv = right.cross(axis).normalize();
        let half = half_extents(&light.shape);
        let n = sm_size;
        // Corners of every object's bounds (tighter than the corners of the union box, which
        // would waste texels) in the centre light's view frame: (x, y, depth along the axis).
        let rel: Vec<Vec3> = boxes
            .iter()
            .flat_map(|b| b.corners())
            .map(|k| {
                let d = k - light.center;
                Vec3::new(d.dot(right), d.dot(upv), d.dot(axis))
            })
            .collect();
        let zmin = rel.iter().map(|r| r.z).fold(f32::INFINITY, f32::min);
        let zmax = rel.iter().map(|r| r.z).fold(f32::NEG_INFINITY, f32::max);
        let diag = bounds.extent().length().max(1e-6);
        let (center, pivot);
        if !light.directional {
            if zmin <= 1e-4 * diag {
                return Err(Error::invalid(format!(
                    "local light at {:?} is not in front of the whole scene (bounds reach {:.3} units behind its \
                     plane): move it outside the scene bounds or make it directional",
                    light.center, -zmin
                )));
            }
            // The frustum must contain every corner seen from every shifted eye: |x - o_x| <= |x| + half.x.
            let tan_half =
                rel.iter().map(|r| ((r.x.abs() + half.x) / r.z).max((r.y.abs() + half.y) / r.z)).fold(0.0f32, f32::max)
                    * 1.02;
            let fov = (2.0 * tan_half.atan()).min(170f32.to_radians());
            let near = 0.95 * zmin;
            let far = 1.02 * zmax;
            center = Camera::perspective(light.center, light.center + axis, upv, fov, near, far, n, n)?;
            pivot = 0.0;
        } else {
            // Orthographic: the eye sits on the axis far enough back that the whole scene is in
            // front; depth is measured from there, the shear pivots at the bounds' mid depth so
            // the sheared maps stay centred.
            let back = (-zmin).max(0.0) + 0.05 * diag;
            let eye = light.center - axis * back;
            let (zmin, zmax) = (zmin + back, zmax + back);
            pivot = 0.5 * (zmin + zmax);
            let ang = half / distance;
            let hh = rel
                .iter()
                .map(|r| {
                    let dz = (r.z + back - pivot).abs();
                    (r.x.abs() + ang.x * dz).max(r.y.abs() + ang.y * dz)
                })
                .fold(0.0f32, f32::max)
                * 1.02;
            let near = (zmin - 0.02 * diag).max(1e-3 * diag);
            let far = zmax + 0.02 * diag;
            center = Camera::orthographic(eye, eye + axis, upv, hh.max(1e-6), near, far, n, n)?;
        }
        let mut rig = LightRig {
            light: *light,
            frame: [right, upv, axis],
            center,
            offsets: Vec::new(),
            cameras: Vec::with_capacity(offsets.len()),
            shifts: Vec::with_capacity(offsets.len()),
            pivot,
            distance,
        };
        for o in &offsets {
            let (cam, k) = rig.offset_camera(*o);
            rig.cameras.push(cam);
            rig.shifts.push(k);
        }
        rig.offsets = offsets;
        Ok(rig)
    }

    /// The shadow-map camera of an emitter point at offset `o` (right, up) from the centre and
    /// its pixel shift `K` (a point with depth parameter `g` moves by `K g` pixels from the
    /// centre map): a shifted eye for local lights, a sheared projection for directional ones.
    pub fn offset_camera(&self, o: Vec2) -> (Camera, Vec2) {
        let c = &self.center;
        let (p00, p11) = (c.proj.x_axis.x, c.proj.y_axis.y);
        let (hw, hh) = (0.5 * c.width as f32, 0.5 * c.height as f32);
        if !self.light.directional {
            let view = Mat4::from_translation(-Vec3::new(o.x, o.y, 0.0)) * c.view;
            // px_i = px_c - (W/2) P00 o_x / z ; py_i = py_c + (H/2) P11 o_y / z.
            (Camera { view, ..*c }, Vec2::new(-hw * p00 * o.x, hh * p11 * o.y))
        } else {
            let (sx, sy) = (o.x / self.distance, o.y / self.distance);
            // x' = x + s_x (depth - z_0) with view-space z = -depth.
            let shear = Mat4::from_cols(
                Vec4::new(1.0, 0.0, 0.0, 0.0),
                Vec4::new(0.0, 1.0, 0.0, 0.0),
                Vec4::new(-sx, -sy, 1.0, 0.0),
                Vec4::new(-sx * self.pivot, -sy * self.pivot, 0.0, 1.0),
            );
            (Camera { view: shear * c.view, ..*c }, Vec2::new(hw * p00 * sx, -hh * p11 * sy))
        }
    }

    /// Number of samples S.
    pub fn samples(&self) -> usize {
        self.offsets.len()
    }

    /// The depth parameter `g` of the per-sample shift for a point at linear view depth `z`:
    /// `1/z` for local lights, `z - z_0` for directional ones ([`ParallaxMotion::depth_param`]).
    #[inline]
    pub fn depth_param(&self, z: f32) -> f32 {
        self.parallax(Vec2::ZERO).depth_param(z)
    }

    /// The rig's pure parallax towards the emitter point whose pixel shift is `k` (seed 000,
    /// Sec. 3.1 motion, specialised to the rig): `v = k g(z)` with `z` the linear depth of the
    /// centre map's stored depth, `g(z) = 1/z` for local lights and `z - z_0` for directional
    /// ones, every sample map measuring the same view depth.
    pub fn parallax(&self, k: Vec2) -> ParallaxMotion {
        ParallaxMotion::of_camera(&self.center, k, self.light.directional.then_some(self.pivot))
    }

    /// The motion field of a centre-map layer towards the emitter point whose pixel shift is
    /// `k` ([`LightRig::parallax`] per texel): what `zwarp_core::motion_field` computes between
    /// the two cameras up to rounding, at a multiply-add per texel. Empty texels (`d >= 1`) get
    /// zero motion and the empty depth.
    ///
    /// Errors: a map of another size than the rig's, a non-finite shift or NaN depths.
    pub fn parallax_field(&self, depth: &Image<f32>, k: Vec2) -> Result<Image<Motion>> {
        self.check_map(depth)?;
        if !k.is_finite() {
            return Err(Error::invalid(format!("parallax shift must be finite, got {k}")));
        }
        // One parallel pass writes the field into a huge-page-advised buffer (a 2048^2 map's
        // field is 48 MB: fresh 4 KiB pages made faulting it in cost more than computing it)
        // and finds NaN depths on the way.
        const CHUNK: usize = 1 << 14;
        let field = self.parallax(k);
        let src = depth.data();
        let mut data = zwarp_core::pages::uninit::<Motion>(src.len());
        let nan = data.spare_capacity_mut()[..src.len()]
            .par_chunks_mut(CHUNK)
            .zip(src.par_chunks(CHUNK))
            .map(|(out, d)| {
                let mut nan = false;
                for (o, &d) in out.iter_mut().zip(d) {
                    nan |= d.is_nan();
                    o.write(field.motion(d));
                }
                nan
            })
            .reduce(|| false, |a, b| a | b);
        // SAFETY: every element of the first `src.len()` was written above.
        unsafe { data.set_len(src.len()) };
        if nan {
            return Err(Error::invalid("layer depth holds NaN values"));
        }
        Image::from_vec(depth.width(), depth.height(), data)
    }

    /// Errors unless `depth` has the size of the rig's maps.
    pub fn check_map(&self, depth: &Image<f32>) -> Result<()> {
        if depth.size() != (self.center.width, self.center.height) {
            return Err(Error::invalid(format!(
                "layer is {}x{} but the light maps are {}x{}",
                depth.width(),
                depth.height(),
                self.center.width,
                self.center.height
            )));
        }
        Ok(())
    }

    /// World size of one shadow-map texel at linear depth `z` (the bias and PCSS unit).
    #[inline]
    pub fn texel_world(&self, z: f32) -> f32 {
        let n = self.center.height as f32;
        match self.center.projection {
            Projection::Perspective { fov_y } => 2.0 * z * (0.5 * fov_y).tan() / n,
            Projection::Orthographic { half_height } => 2.0 * half_height / n,
        }
    }

    /// Largest sample offset from the emitter centre (the umbra region's `e`).
    pub fn max_offset(&self) -> f32 {
        half_extents(&self.light.shape).length()
    }

    /// Generalized umbra culling for peeling the centre map (seed 000, Sec. 3.4, eq. (1)): the
    /// novel views are the sample eyes, a disc of radius `e` = the emitter's half diagonal in the
    /// eye plane (`c = 0`) for local lights, or directions within the emitter's angular radius for
    /// directional ones.
    pub fn umbra(&self) -> UmbraPeeling {
        let e = self.max_offset();
        let region = if self.light.directional {
            ViewRegion::Directions { max_angle: (e / self.distance).atan().min(1.5) }
        } else {
            ViewRegion::Disc { e, c: 0.0 }
        };
        UmbraPeeling { region }
    }

    /// Direction from a world point towards the light (the emitter centre for local lights, the
    /// reverse axis for directional ones), unit length.
    #[inline]
    pub fn to_light(&self, p: Vec3) -> Vec3 {
        if self.light.directional {
            -self.frame[2]
        } else {
            (self.light.center - p).normalize_or(-self.frame[2])
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stratified_samples_cover_every_stratum_once() {
        let s = light_samples(&LightShape::Rect { width: 2.0, height: 1.0 }, 8, 7, true).unwrap();
        assert_eq!(s.len(), 8);
        // 8 = 2 x 4: 4 columns over the width 2 (cells 0.5 wide), 2 rows over the height 1.
        let mut hit = [0u32; 8];
        for p in &s {
            assert!(p.x.abs() <= 1.0 && p.y.abs() <= 0.5, "{p:?}");
            let i = ((p.x + 1.0) / 0.5).floor().min(3.0) as usize;
            let j = ((p.y + 0.5) / 0.5).floor().min(1.0) as usize;
            hit[j * 4 + i] += 1;
        }
        assert_eq!(hit, [1; 8]);
        // Deterministic.
        assert_eq!(s, light_samples(&LightShape::Rect { width: 2.0, height: 1.0 }, 8, 7, true).unwrap());
        assert_ne!(s, light_samples(&LightShape::Rect { width: 2.0, height: 1.0 }, 8, 8, true).unwrap());
    }

    #[test]
    fn disc_samples_inside_with_centroid_near_centre() {
        let s = light_samples(&LightShape::Disc { radius: 3.0 }, 256, 1, true).unwrap();
        let c: Vec2 = s.iter().copied().sum::<Vec2>() / s.len() as f32;
        assert!(s.iter().all(|p| p.length() <= 3.0 + 1e-4));
        assert!(c.length() < 0.1, "{c:?}");
        // Equal-area strata: half the samples inside radius R / sqrt(2) (up to stratum jitter).
        let inner = s.iter().filter(|p| p.length() < 3.0 / 2f32.sqrt()).count();
        assert!((inner as i32 - 128).abs() <= 12, "{inner}");
        assert_eq!(light_samples(&LightShape::Disc { radius: 3.0 }, 1, 5, true).unwrap(), vec![Vec2::ZERO]);
    }

    #[test]
    fn bad_inputs_are_errors() {
        assert!(light_samples(&LightShape::Disc { radius: 1.0 }, 0, 0, true).is_err());
        assert!(light_samples(&LightShape::Disc { radius: 1.0 }, MAX_SAMPLES + 1, 0, true).is_err());
        assert!(light_from_json_str("{").is_err());
        let bad = r#"{"center":[0,0,5],"target":[0,0,5],"up":[0,1,0],"shape":{"kind":"disc","radius":1}}"#;
        assert!(light_from_json_str(bad).unwrap_err().to_string().contains("coincide"));
        let neg = r#"{"center":[0,0,5],"target":[0,0,0],"up":[0,1,0],"shape":{"kind":"disc","radius":-1}}"#;
        assert!(light_from_json_str(neg).is_err());
        let par = r#"{"center":[0,0,5],"target":[0,0,0],"up":[0,0,1],"shape":{"kind":"rect","width":1,"height":1}}"#;
        assert!(light_from_json_str(par).is_err());
        assert!(load_light("/nonexistent/light.json").is_err());
    }

    #[test]
    fn light_json_roundtrip() {
        let l = AreaLight {
            center: Vec3::new(1.0, 2.0, 3.0),
            target: Vec3::ZERO,
            up: Vec3::Z,
            shape: LightShape::Rect { width: 2.0, height: 0.5 },
            directional: true,
        };
        assert_eq!(light_from_json_str(&light_to_json(&l)).unwrap(), l);
        let text = r#"{"center":[0,0,5],"target":[0,0,0],"up":[0,1,0],"shape":{"kind":"disc","radius":1}}"#;
        assert!(!light_from_json_str(text).unwrap().directional);
    }
}
