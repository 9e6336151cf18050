//! Motion field (seed 000, Sec. 3.1): `v(q) = C P^-1 q - q` in pixels, object motion included,
//! with each sample's depth in the target view. Used by the renderer (pixel-accurate motion
//! buffers), by the warps and by culling: one implementation.

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec2};
use rayon::prelude::*;

use crate::{camera::project_with, camera::unproject_with, Camera, Image, Result, NO_ITEM};

/// One motion-buffer sample: where the source pixel's surface point moves to (in pixels,
/// `v`) and its depth in the target view (Sec. 3.1: "the render target also stores the new
/// depths"). A warp writes `depth`, never the source depth.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Default, Pod, Zeroable)]
pub struct Motion {
    /// Motion in pixels, source -> target: the point at `q` lands at `q + v`.
    pub v: Vec2,
    /// Depth of the moved point in the target view, `[0, 1]`; may fall outside when it leaves
    /// the target's near/far range; `1.0` for empty source pixels.
    pub depth: f32,
}

/// A motion field that is a function of the stored depth alone: a view moved within its image
/// plane (the sample eyes of an area light's rig, seed 000 Sec. 6; a lateral stereo offset)
/// moves the point at linear view depth `z` by `shift * g(z)` pixels, `g(z) = 1 / z` for a
/// translated perspective eye and `g(z) = z - pivot` for a directional light's shear about the
/// pivot depth; every point keeps its stored depth (each such view measures the same view
/// depth). Empty pixels (`d >= 1`) do not move and keep the empty depth.
///
/// [`ParallaxMotion::motion`] is the field's value: what `motion_field` computes between the
/// two cameras up to rounding, at a multiply-add per texel. The warp's preparation evaluates it
/// in its own pass (`zwarp_warp::PreparedLayer::new_parallax`) instead of reading a buffer of
/// it, bit for bit the same samples.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParallaxMotion {
    /// The pixel shift of a point at `g(z) = 1`.
    pub shift: Vec2,
    /// Near and far plane distances of the view (its stored depth -> linear depth).
    pub near: f32,
    /// See `near`.
    pub far: f32,
    /// `true` for a perspective view (`Camera::linear_depth`'s two projections).
    pub perspective: bool,
    /// `None`: `g(z) = 1 / z`; `Some(z0)`: `g(z) = z - z0`.
    pub pivot: Option<f32>,
}

impl ParallaxMotion {
    /// The field of `camera`'s view (its near / far / projection) for `shift` and `pivot`.
    pub fn of_camera(camera: &Camera, shift: Vec2, pivot: Option<f32>) -> Self {
        let perspective = matches!(camera.projection, crate::Projection::Perspective { .. });
        ParallaxMotion { shift, near: camera.near, far: camera.far, perspective, pivot }
    }

    /// Linear view depth of stored depth `d` (`Camera::linear_depth`, the same operations).
    #[inline]
    pub fn linear_depth(&self, d: f32) -> f32 {
        crate::camera::linear_depth_of(self.perspective, self.near, self.far, d)
    }

    /// The depth parameter `g(z)` of linear depth `z`: `1 / z`, or `z - pivot`.
    #[inline]
    pub fn depth_param(&self, z: f32) -> f32 {
        match self.pivot {
            None => 1.0 / z,
            Some(z0) => z - z0,
        }
    }

    /// The motion sample of a pixel with stored depth `d`.
    #[inline]
    pub fn motion(&self, d: f32) -> Motion {
        if d < crate::EMPTY_DEPTH {
            Motion { v: self.shift * self.depth_param(self.linear_depth(d)), depth: d }
        } else {
            Motion { v: Vec2::ZERO, depth: crate::EMPTY_DEPTH }
        }
    }
}

/// Reprojects source pixel centre `(x + 0.5, y + 0.5)` with stored depth `d` to the target:
/// returns the [`Motion`] sample. `inv_a` = inverse view-projection of the source camera,
/// `m` = `VP_b * object_delta`. Empty pixels (`d >= 1`) are treated as points on the source far
/// plane that do not move with any object (background at the far plane); their depth is 1.
#[inline]
pub fn reproject_pixel(inv_a: &Mat4, m: &Mat4, a: (u32, u32), b: (u32, u32), x: u32, y: u32, d: f32) -> Motion {
    let (px, py) = (x as f32 + 0.5, y as f32 + 0.5);
    let w = unproject_with(inv_a, a.0, a.1, px, py, d.min(1.0));
    match project_with(m, b.0, b.1, w) {
        Some(s) => Motion { v: Vec2::new(s.x - px, s.y - py), depth: if d >= 1.0 { 1.0 } else { s.z } },
        // Behind the target eye: it cannot be seen there; send it far off-screen so no
        // fixed-point search converges to it.
        None => Motion { v: Vec2::splat(1.0e9), depth: 1.0 },
    }
}

/// The AVX2 build of the motion field (on by default where the CPU has it); [`set_simd`]
/// turns it off for tests and timing.
static AVX2: crate::SimdSwitch = crate::SimdSwitch::avx2();

/// Turns the AVX2 build of [`motion_field`] on (default) or off; both give the same bits.
pub fn set_simd(enabled: bool) {
    AVX2.set(enabled);
}

/// Validates the inputs of a motion-field computation (shared by the CPU function and its GPU
/// twin): a non-empty, finite depth buffer of the source camera's size and a matching item buffer.
pub fn check_motion_inputs(depth: &Image<f32>, items: Option<&Image<u32>>, cam_a: &Camera) -> Result<()> {
    depth.check_nonempty("depth buffer")?;
    if let Some(it) = items {
        depth.check_same_size(it, "depth vs item buffer")?;
    }
    if depth.size() != (cam_a.width, cam_a.height) {
        return Err(crate::Error::invalid(format!(
            "depth buffer is {}x{} but the source camera renders {}x{}",
            depth.width(),
            depth.height(),
            cam_a.width,
            cam_a.height
        )));
    }
    if !depth.all_finite() {
        return Err(crate::Error::invalid("depth buffer holds NaN or infinite values"));
    }
    Ok(())
}

/// Computes the motion buffer from a source depth buffer, its item buffer and the two cameras.
///
/// `object_deltas[id]` is the world-space motion `M(t_b) * M(t_a)^-1` of object `id` (see
/// [`crate::Scene::object_deltas`]); pass an empty slice for a static scene. Pixels with
/// [`NO_ITEM`] or ids beyond the slice move with the camera only, as do objects whose delta is
/// the identity (skipped: a static scene's deltas cost nothing).
pub fn motion_field(
    depth: &Image<f32>,
    items: Option<&Image<u32>>,
    cam_a: &Camera,
    cam_b: &Camera,
    object_deltas: &[Mat4],
) -> Result<Image<Motion>> {
    let mut out = Image::new(0, 0, Motion::default());
    motion_field_into(depth, items, cam_a, cam_b, object_deltas, &mut out)?;
    Ok(out)
}

/// [`motion_field`] into `out`, reusing its allocation when it has the depth buffer's size
/// (an engine's steady state: no fresh pages to fault in every frame).
pub fn motion_field_into(
    depth: &Image<f32>,
    items: Option<&Image<u32>>,
    cam_a: &Camera,
    cam_b: &Camera,
    object_deltas: &[Mat4],
    out: &mut Image<Motion>,
) -> Result<()> {
    Pass::of_deltas(depth, items, cam_a, cam_b, object_deltas)?.records(out);
    Ok(())
}

/// [`motion_field`] with each object's motion given by functions: `moving(id)` says whether
/// object `id` moves on its own, `delta(id)` is then its world-space motion `M(t_b) *
/// M(t_a)^-1`. Only the moving ids that appear on a surface pixel of the item buffer are
/// looked up, each once, so a frame costs nothing per object it does not show (a scene of a
/// million objects needs no per-frame array of matrices). Bit-identical to [`motion_field`]
/// with the full slice of deltas.
pub fn motion_field_with(
    depth: &Image<f32>,
    items: Option<&Image<u32>>,
    cam_a: &Camera,
    cam_b: &Camera,
    moving: impl Fn(u32) -> bool + Sync,
    delta: impl Fn(u32) -> Mat4 + Sync,
) -> Result<Image<Motion>> {
    let mut out = Image::new(0, 0, Motion::default());
    motion_field_with_into(depth, items, cam_a, cam_b, moving, delta, &mut out)?;
    Ok(out)
}

/// [`motion_field_with`] into `out` (its allocation reused when it has the right size).
///
/// Per row, runs of eight pixels that move with one matrix (the camera's, or one object's) take
/// the AVX2 build (the same operations in the same order as [`reproject_pixel`], no FMA: the
/// same bits), the others [`reproject_pixel`] each (consecutive pixels of one object share one
/// look-up).
pub fn motion_field_with_into(
    depth: &Image<f32>,
    items: Option<&Image<u32>>,
    cam_a: &Camera,
    cam_b: &Camera,
    moving: impl Fn(u32) -> bool + Sync,
    delta: impl Fn(u32) -> Mat4 + Sync,
    out: &mut Image<Motion>,
) -> Result<()> {
    Pass::new(depth, items, cam_a, cam_b, moving, delta)?.records(out);
    Ok(())
}

/// [`motion_field`]'s motion vectors alone, as two planes (x and y components, row-major, each
/// resized to the depth buffer's size, allocations reused): the same bits as the `v` of
/// [`motion_field_into`]'s samples, without their target depth, for consumers that read
/// planes (a colour warp's field, seed 001) and would otherwise split the records in a second
/// pass.
pub fn motion_planes_into(
    depth: &Image<f32>,
    items: Option<&Image<u32>>,
    cam_a: &Camera,
    cam_b: &Camera,
    object_deltas: &[Mat4],
    (vx, vy): (&mut Vec<f32>, &mut Vec<f32>),
) -> Result<()> {
    Pass::of_deltas(depth, items, cam_a, cam_b, object_deltas)?.planes(vx, vy);
    Ok(())
}

/// Where a motion-field pass writes one row: [`Motion`] records, or the motion's x and y planes
/// alone ([`PlaneRow`]).
trait RowOut {
    /// Pixel `x`'s sample.
    fn put(&mut self, x: usize, m: Motion);
    /// Pixels `x..x + 8`: motion x, motion y and target depth per lane.
    ///
    /// # Safety
    /// The CPU must support AVX2; the row holds eight pixels from `x`.
    #[cfg(target_arch = "x86_64")]
    unsafe fn put8(&mut self, x: usize, v: [std::arch::x86_64::__m256; 3]);
}

impl RowOut for &mut [Motion] {
    #[inline(always)]
    fn put(&mut self, x: usize, m: Motion) {
        self[x] = m;
    }
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn put8(&mut self, x: usize, v: [std::arch::x86_64::__m256; 3]) {
        crate::simd::avx2::store3x8(self[x..x + 8].as_mut_ptr() as *mut f32, v);
    }
}

/// One row of [`motion_planes_into`]'s planes.
struct PlaneRow<'a> {
    x: &'a mut [f32],
    y: &'a mut [f32],
}

impl RowOut for PlaneRow<'_> {
    #[inline(always)]
    fn put(&mut self, i: usize, m: Motion) {
        (self.x[i], self.y[i]) = (m.v.x, m.v.y);
    }
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn put8(&mut self, i: usize, [vx, vy, _]: [std::arch::x86_64::__m256; 3]) {
        use std::arch::x86_64::_mm256_storeu_ps;
        _mm256_storeu_ps(self.x[i..i + 8].as_mut_ptr(), vx);
        _mm256_storeu_ps(self.y[i..i + 8].as_mut_ptr(), vy);
    }
}

/// What every row of one motion-field pass shares: the cameras' matrices, the on-screen moving
/// objects' matrices, and the source's NDC x per column.
struct Pass<'a> {
    depth: &'a Image<f32>,
    items: Option<&'a Image<u32>>,
    /// The moving ids on screen (sorted, unique) and their `VP_b * delta`.
    ids: Vec<u32>,
    mats: Vec<Mat4>,
    vp_b: Mat4,
    inv_a: Mat4,
    a: (u32, u32),
    b: (u32, u32),
    /// The AVX2 build runs ([`set_simd`] on and the CPU has it).
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    simd: bool,
    /// unproject_with's x in NDC per column (the same operations, so the same bits): the AVX2
    /// build reads it instead of dividing every row again; the divisions bound that build.
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    ndc_x: Vec<f32>,
}

impl<'a> Pass<'a> {
    /// [`Pass::new`] for a slice of per-object deltas (as [`motion_field`] takes them).
    fn of_deltas(
        depth: &'a Image<f32>,
        items: Option<&'a Image<u32>>,
        cam_a: &Camera,
        cam_b: &Camera,
        object_deltas: &[Mat4],
    ) -> Result<Self> {
        let n = object_deltas.len();
        let moving = |id: u32| (id as usize) < n && object_deltas[id as usize] != Mat4::IDENTITY;
        // Without a moving object the item buffer is not read at all (its size is still checked).
        if let Some(it) = items {
            depth.check_same_size(it, "depth vs item buffer")?;
        }
        let items = items.filter(|_| object_deltas.iter().any(|m| *m != Mat4::IDENTITY));
        Pass::new(depth, items, cam_a, cam_b, moving, |id| object_deltas[id as usize])
    }

    /// The field as [`Motion`] records into `out` (resized to the depth's size if needed).
    fn records(&self, out: &mut Image<Motion>) {
        let (w, h) = self.a;
        if out.size() != (w, h) {
            *out = Image::new(w, h, Motion::default());
        }
        out.data_mut().par_chunks_mut(w as usize).enumerate().for_each(|(y, mut row)| self.row(y, &mut row));
    }

    /// The field's vectors as x / y planes (resized to the depth's size).
    fn planes(&self, vx: &mut Vec<f32>, vy: &mut Vec<f32>) {
        let (wu, len) = (self.a.0 as usize, self.a.0 as usize * self.a.1 as usize);
        for v in [&mut *vx, &mut *vy] {
            *v = crate::pages::reuse(std::mem::take(v), len, 0.0);
        }
        vx.par_chunks_mut(wu).zip(vy.par_chunks_mut(wu)).enumerate().for_each(|(y, (x, yv))| {
            self.row(y, &mut PlaneRow { x, y: yv });
        });
    }

    fn new(
        depth: &'a Image<f32>,
        items: Option<&'a Image<u32>>,
        cam_a: &Camera,
        cam_b: &Camera,
        moving: impl Fn(u32) -> bool + Sync,
        delta: impl Fn(u32) -> Mat4 + Sync,
    ) -> Result<Self> {
        check_motion_inputs(depth, items, cam_a)?;
        let (w, h) = depth.size();
        let wu = w as usize;
        // The moving ids on screen, sorted and unique (empty pixels move with the camera,
        // whatever their id).
        let mut ids: Vec<u32> = match items {
            Some(items) => items
                .data()
                .par_chunks(wu)
                .zip(depth.data().par_chunks(wu))
                .flat_map_iter(|(ir, dr)| {
                    // `moving` asked once per run of one id; NO_ITEM never moves.
                    let (mut last, mut last_moving, mut pushed) = (NO_ITEM, false, NO_ITEM);
                    let mut seen = Vec::new();
                    for (&id, &d) in ir.iter().zip(dr) {
                        if id != last {
                            last = id;
                            last_moving = id != NO_ITEM && moving(id);
                        }
                        if last_moving && d < 1.0 && id != pushed {
                            seen.push(id);
                            pushed = id;
                        }
                    }
                    seen
                })
                .collect(),
            None => Vec::new(),
        };
        ids.sort_unstable();
        ids.dedup();
        let vp_b = cam_b.view_proj();
        let mats: Vec<Mat4> = ids.par_iter().map(|&id| vp_b * delta(id)).collect();
        let simd = AVX2.active();
        let ndc_x = if simd { (0..w).map(|x| (x as f32 + 0.5) / w as f32 * 2.0 - 1.0).collect() } else { Vec::new() };
        Ok(Pass {
            depth,
            items: items.filter(|_| !ids.is_empty()),
            ids,
            mats,
            vp_b,
            inv_a: cam_a.view_proj().inverse(),
            a: (w, h),
            b: (cam_b.width, cam_b.height),
            simd,
            ndc_x,
        })
    }

    /// Row `y` of the field into `row`.
    fn row(&self, y: usize, row: &mut impl RowOut) {
        #[cfg(target_arch = "x86_64")]
        if self.simd {
            // SAFETY: `simd` says the CPU has AVX2.
            return unsafe { self.row_avx2(y, row) };
        }
        self.row_with(y, row, false)
    }

    /// [`Self::row`] compiled with AVX2, so that the eight-pixel build inlines into the loop.
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn row_avx2(&self, y: usize, row: &mut impl RowOut) {
        self.row_with(y, row, true)
    }

    /// The loop of [`Self::row`]; `simd`: runs of eight pixels take the AVX2 build.
    #[inline(always)]
    #[cfg_attr(not(target_arch = "x86_64"), allow(unused_variables))]
    fn row_with(&self, y: usize, row: &mut impl RowOut, simd: bool) {
        let (wu, h) = (self.a.0 as usize, self.a.1);
        let dr = &self.depth.data()[y * wu..(y + 1) * wu];
        let ir = self.items.map(|i| &i.data()[y * wu..(y + 1) * wu]);
        let (ids, mats, vp_b) = (&self.ids, &self.mats, &self.vp_b);
        // The matrix of pixel x: its object's where it is a surface of a moving object.
        let (mut last, mut last_m) = (NO_ITEM, vp_b);
        let ndc_y = 1.0 - (y as f32 + 0.5) / h as f32 * 2.0;
        let mut matrix = |x: usize| -> &Mat4 {
            match ir {
                Some(ir) if dr[x] < 1.0 => {
                    if ir[x] != last {
                        last = ir[x];
                        last_m = ids.binary_search(&last).map_or(vp_b, |k| &mats[k]);
                    }
                    last_m
                }
                _ => vp_b,
            }
        };
        let mut x = 0;
        while x < wu {
            #[cfg(target_arch = "x86_64")]
            if simd && x + 8 <= wu {
                let m = matrix(x);
                // The run of pixels from x that share m: eight take the AVX2 build, a shorter
                // one is done here (each pixel's matrix is looked up once).
                let end = (x + 1..x + 8).find(|&i| !std::ptr::eq(matrix(i), m)).unwrap_or(x + 8);
                if end == x + 8 {
                    // SAFETY: `simd` says the CPU has AVX2; the slices hold eight elements from x.
                    unsafe {
                        avx2::eight(
                            &self.inv_a,
                            m,
                            self.b,
                            (x as u32, y as u32),
                            &self.ndc_x[x..x + 8],
                            ndc_y,
                            &dr[x..x + 8],
                            row,
                        )
                    };
                } else {
                    for (i, &d) in dr.iter().enumerate().take(end).skip(x) {
                        row.put(i, reproject_pixel(&self.inv_a, m, self.a, self.b, i as u32, y as u32, d));
                    }
                }
                x = end;
                continue;
            }
            row.put(x, reproject_pixel(&self.inv_a, matrix(x), self.a, self.b, x as u32, y as u32, dr[x]));
            x += 1;
        }
    }
}

/// The AVX2 build of [`reproject_pixel`] for eight pixels of one row.
#[cfg(target_arch = "x86_64")]
mod avx2 {
    use std::arch::x86_64::*;

    use glam::Mat4;

    use super::RowOut;
    use crate::simd::avx2::mat4_mul8;

    /// [`super::reproject_pixel`] of pixels `x..x + 8` of row `y`, all moving with matrix `m`
    /// (the target's view-projection, times an object's motion): `unproject_with` (from the
    /// pixels' NDC `ndc_x`, `ndc_y`, which it computes first), `project_with` and the motion
    /// sample, operation for operation.
    ///
    /// # Safety
    /// The CPU must support AVX2; `ndc_x` and `d` hold eight elements, `row` eight pixels from
    /// `x`; the samples go to `row`.
    #[inline]
    #[target_feature(enable = "avx2")]
    #[allow(clippy::too_many_arguments)]
    pub(super) unsafe fn eight(
        inv_a: &Mat4,
        m: &Mat4,
        b: (u32, u32),
        (x, y): (u32, u32),
        ndc_x: &[f32],
        ndc_y: f32,
        d: &[f32],
        row: &mut impl RowOut,
    ) {
        let (one, half) = (_mm256_set1_ps(1.0), _mm256_set1_ps(0.5));
        let px = _mm256_add_ps(
            _mm256_cvtepi32_ps(_mm256_add_epi32(
                _mm256_set1_epi32(x as i32),
                _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7),
            )),
            half,
        );
        let py = _mm256_set1_ps(y as f32 + 0.5);
        let dv = _mm256_loadu_ps(d.as_ptr());
        // unproject_with(inv_a, a, px, py, d.min(1.0))
        let (nx, ny) = (_mm256_loadu_ps(ndc_x.as_ptr()), _mm256_set1_ps(ndc_y));
        let p = mat4_mul8(inv_a, [nx, ny, _mm256_min_ps(dv, one), one]);
        let world = [_mm256_div_ps(p[0], p[3]), _mm256_div_ps(p[1], p[3]), _mm256_div_ps(p[2], p[3])];
        // project_with(m, b, world)
        let c = mat4_mul8(m, [world[0], world[1], world[2], one]);
        let behind = _mm256_cmp_ps::<_CMP_LE_OQ>(c[3], _mm256_setzero_ps());
        let inv_w = _mm256_div_ps(one, c[3]);
        let (sx, sy, sz) = (_mm256_mul_ps(c[0], inv_w), _mm256_mul_ps(c[1], inv_w), _mm256_mul_ps(c[2], inv_w));
        let sx = _mm256_mul_ps(_mm256_mul_ps(_mm256_add_ps(sx, one), half), _mm256_set1_ps(b.0 as f32));
        let sy = _mm256_mul_ps(_mm256_mul_ps(_mm256_sub_ps(one, sy), half), _mm256_set1_ps(b.1 as f32));
        // The sample: behind the target eye far off-screen, empty pixels at depth 1.
        let far = _mm256_set1_ps(1.0e9);
        let vx = _mm256_blendv_ps(_mm256_sub_ps(sx, px), far, behind);
        let vy = _mm256_blendv_ps(_mm256_sub_ps(sy, py), far, behind);
        let empty = _mm256_or_ps(behind, _mm256_cmp_ps::<_CMP_GE_OQ>(dv, one));
        let depth = _mm256_blendv_ps(sz, one, empty);
        row.put8(x as usize, [vx, vy, depth]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// The per-id form gives the slice form's field bit for bit: moving and static objects,
    /// ids beyond the slice, `NO_ITEM` and empty pixels.
    #[test]
    fn motion_by_id_equals_the_slice_of_deltas() {
        let (w, h) = (23, 17);
        let a = Camera::perspective(Vec3::new(0.0, 1.0, 6.0), Vec3::ZERO, Vec3::Y, 1.0, 0.1, 50.0, w, h).unwrap();
        let b = Camera::perspective(Vec3::new(0.3, 1.1, 5.8), Vec3::X * 0.1, Vec3::Y, 1.0, 0.1, 50.0, w, h).unwrap();
        let depth = Image::from_fn(w, h, |x, y| if (x + y) % 7 == 0 { 1.0 } else { 0.9 + 0.004 * x as f32 });
        let items = Image::from_fn(w, h, |x, y| match (x / 5 + y) % 5 {
            4 => NO_ITEM,
            k => k,
        });
        let deltas = [Mat4::IDENTITY, Mat4::from_translation(Vec3::new(0.2, 0.0, -0.1)), Mat4::from_rotation_y(0.05)];
        let by_slice = motion_field(&depth, Some(&items), &a, &b, &deltas).unwrap();
        let by_id =
            motion_field_with(&depth, Some(&items), &a, &b, |id| id == 1 || id == 2, |id| deltas[id as usize]).unwrap();
        let bits =
            |m: &Image<Motion>| m.data().iter().map(|s| [s.v.x, s.v.y, s.depth].map(f32::to_bits)).collect::<Vec<_>>();
        assert_eq!(bits(&by_id), bits(&by_slice));
        // Object 1 moves on its own: its pixels differ from the camera-only field.
        let still = motion_field(&depth, Some(&items), &a, &b, &[]).unwrap();
        let i = items.data().iter().zip(depth.data()).position(|(&id, &d)| id == 1 && d < 1.0).unwrap();
        assert_ne!(by_id.data()[i], still.data()[i]);
    }

    /// The AVX2 build gives the portable field bit for bit: runs of one moving object, of the
    /// camera, NO_ITEM, empty pixels, points behind the target eye, a row that is no multiple of
    /// eight; identity deltas are the static field.
    #[test]
    fn the_avx2_field_is_the_portable_field() {
        let (w, h) = (45, 13);
        let a = Camera::perspective(Vec3::new(0.0, 0.5, 6.0), Vec3::ZERO, Vec3::Y, 1.0, 0.1, 50.0, w, h).unwrap();
        // Its eye 3.5 m ahead of a's: the nearest points are behind it.
        let b = Camera::perspective(Vec3::new(0.3, 0.6, 2.5), Vec3::X * 0.2, Vec3::Y, 1.1, 0.1, 50.0, w, h).unwrap();
        let depth =
            Image::from_fn(w, h, |x, y| if (x + 3 * y) % 11 == 0 { 1.0 } else { 0.02 * y as f32 + 0.02 * x as f32 });
        let items = Image::from_fn(w, h, |x, y| match (x / 9 + y) % 4 {
            3 => NO_ITEM,
            k => k,
        });
        let deltas = [Mat4::IDENTITY, Mat4::from_translation(Vec3::new(0.2, 0.0, -0.1)), Mat4::from_rotation_y(0.05)];
        let bits =
            |m: &Image<Motion>| m.data().iter().map(|s| [s.v.x, s.v.y, s.depth].map(f32::to_bits)).collect::<Vec<_>>();
        let field = |simd: bool, d: &[Mat4]| {
            set_simd(simd);
            let f = motion_field(&depth, Some(&items), &a, &b, d).unwrap();
            set_simd(true);
            f
        };
        let portable = field(false, &deltas);
        assert!(portable.data().iter().any(|s| s.v.x == 1.0e9), "no point behind the target eye");
        assert_eq!(bits(&field(true, &deltas)), bits(&portable));
        assert_eq!(bits(&field(true, &[Mat4::IDENTITY; 3])), bits(&field(false, &[])));
        // A wrong-size item buffer is an error even when nothing moves.
        let small = Image::new(w - 1, h, 0u32);
        assert!(motion_field(&depth, Some(&small), &a, &b, &[]).is_err());
        assert!(motion_field(&depth, Some(&small), &a, &b, &[Mat4::IDENTITY; 3]).is_err());
        // Into a buffer of another size: resized, same field.
        let mut out = Image::new(3, 2, Motion::default());
        motion_field_into(&depth, Some(&items), &a, &b, &deltas, &mut out).unwrap();
        assert_eq!(bits(&out), bits(&portable));
        // The planes are the samples' motion, in both builds, into vectors of another length.
        for simd in [false, true] {
            set_simd(simd);
            let (mut vx, mut vy) = (vec![7.0; 5], Vec::new());
            motion_planes_into(&depth, Some(&items), &a, &b, &deltas, (&mut vx, &mut vy)).unwrap();
            set_simd(true);
            let split = |c: fn(&Motion) -> f32| portable.data().iter().map(|s| c(s).to_bits()).collect::<Vec<_>>();
            assert_eq!(vx.iter().map(|v| v.to_bits()).collect::<Vec<_>>(), split(|s| s.v.x), "simd {simd}");
            assert_eq!(vy.iter().map(|v| v.to_bits()).collect::<Vec<_>>(), split(|s| s.v.y), "simd {simd}");
        }
        let (mut vx, mut vy) = (Vec::new(), Vec::new());
        assert!(motion_planes_into(&depth, Some(&small), &a, &b, &[], (&mut vx, &mut vy)).is_err());
    }

    #[test]
    fn zero_motion_for_identical_cameras() {
        let cam = Camera::perspective(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 1.0, 0.1, 100.0, 16, 8).unwrap();
        let depth = Image::new(16, 8, 0.95f32);
        let m = motion_field(&depth, None, &cam, &cam, &[]).unwrap();
        for s in m.data() {
            assert!(s.v.length() < 1e-3, "{:?}", s);
            assert!((s.depth - 0.95).abs() < 1e-5);
        }
    }

    #[test]
    fn camera_translation_parallel_to_image_plane_gives_analytic_shift() {
        // Camera moves +x by dx at distance z; a point at depth z shifts by -dx * f / z pixels.
        let (w, h) = (64, 64);
        let fov = 1.0f32;
        let a =
            Camera::perspective(Vec3::new(0.0, 0.0, 10.0), Vec3::new(0.0, 0.0, 0.0), Vec3::Y, fov, 0.1, 100.0, w, h)
                .unwrap();
        let b =
            Camera::perspective(Vec3::new(0.5, 0.0, 10.0), Vec3::new(0.5, 0.0, 0.0), Vec3::Y, fov, 0.1, 100.0, w, h)
                .unwrap();
        let d = a.stored_depth(10.0);
        let depth = Image::new(w, h, d);
        let m = motion_field(&depth, None, &a, &b, &[]).unwrap();
        let focal = h as f32 * 0.5 / (fov * 0.5).tan();
        let expect = -0.5 * focal / 10.0;
        for s in m.data() {
            assert!((s.v.x - expect).abs() < 1e-2 && s.v.y.abs() < 1e-2, "{:?} vs {expect}", s.v);
            assert!((s.depth - d).abs() < 1e-5);
        }
    }
}
