//! View-frustum culling (VFC) of world-space AABBs, the first stage of WOC (seed 000 Sec. 5.2:
//! "Our approach first employs the standard VFC"; thesis seed 002 Sec. III.2).
//!
//! The six planes are extracted from the view-projection matrix (Gribb & Hartmann). The test
//! is the classic conservative "positive vertex" test: a box is culled only when it lies
//! entirely on the outer side of one plane, so boxes near frustum corners may be kept
//! (never the opposite).

use glam::{Mat4, Vec3, Vec4};
use rayon::prelude::*;
use zwarp_core::{Aabb, Camera};

use crate::AVX2;

/// Objects handed to the parallel per-object loops in runs of at least this many (one rayon
/// task per object costs more than the test of a culled one): [`Frustum::filter_map_ids`] and
/// WOC's screen-space tests.
pub(crate) const OBJECT_CHUNK: usize = 512;

/// The six clip planes of a camera as `(n, d)` with `n . x + d >= 0` inside, in world space.
///
/// Order: left, right, bottom, top, near, far. Depth follows the zwarp convention
/// (post-projection z in `[0, 1]`, glam `*_rh` projections), so the near plane is `z_clip >= 0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frustum {
    /// Plane equations, normalized so that `|n| = 1` (distance in world units).
    pub planes: [Vec4; 6],
}

impl Frustum {
    /// Planes of the view volume of `view_proj` (clip space `-w <= x, y <= w`, `0 <= z <= w`).
    pub fn from_view_proj(view_proj: &Mat4) -> Self {
        let r0 = view_proj.row(0);
        let r1 = view_proj.row(1);
        let r2 = view_proj.row(2);
        let r3 = view_proj.row(3);
        let raw = [r3 + r0, r3 - r0, r3 + r1, r3 - r1, r2, r3 - r2];
        let planes = raw.map(|p| {
            let len = p.truncate().length();
            // A degenerate plane (cannot happen for a valid camera) is turned into "always
            // inside" rather than dividing by zero, which keeps the test conservative.
            if len > 0.0 && len.is_finite() {
                p / len
            } else {
                Vec4::new(0.0, 0.0, 0.0, 1.0)
            }
        });
        Frustum { planes }
    }

    /// Planes of a [`Camera`].
    pub fn from_camera(cam: &Camera) -> Self {
        Self::from_view_proj(&cam.view_proj())
    }

    /// `true` if the box may intersect the frustum (conservative: `false` only when the box is
    /// entirely outside one plane). Empty boxes are outside; boxes with NaN are kept.
    pub fn intersects(&self, aabb: &Aabb) -> bool {
        if aabb.min.is_nan() || aabb.max.is_nan() {
            return true;
        }
        if aabb.is_empty() {
            return false;
        }
        for p in &self.planes {
            let n = p.truncate();
            // The corner farthest along the plane normal: if even it is outside, all are.
            let pv = Vec3::select(n.cmpge(Vec3::ZERO), aabb.max, aabb.min);
            let nd = n.dot(pv);
            let dist = nd + p.w;
            // Relative slack so that f32 rounding of large coordinates never culls a box that
            // touches the plane.
            if dist < -1e-6 * (nd.abs() + p.w.abs()) {
                return false;
            }
        }
        true
    }

    /// [`Self::intersects`] of eight boxes: bit `i` set where `boxes[i]` may intersect. The AVX2
    /// build (where the CPU has it) tests the eight at once with the same operations in the same
    /// order, so the same bits.
    #[inline]
    pub fn intersects8(&self, boxes: &[Aabb; 8]) -> u8 {
        #[cfg(target_arch = "x86_64")]
        if AVX2.active() {
            // SAFETY: AVX2 checked.
            return unsafe { self.intersects8_avx2(boxes) };
        }
        boxes.iter().enumerate().fold(0, |m, (i, b)| m | (self.intersects(b) as u8) << i)
    }

    /// The AVX2 build of [`Self::intersects8`].
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn intersects8_avx2(&self, boxes: &[Aabb; 8]) -> u8 {
        use std::arch::x86_64::*;
        // The boxes as six lanes of eight (min x, y, z, max x, y, z), built in registers: eight
        // scalar stores read back by one vector load would stall store forwarding.
        let lane = |f: fn(&Aabb) -> f32| {
            let b = boxes;
            _mm256_setr_ps(f(&b[0]), f(&b[1]), f(&b[2]), f(&b[3]), f(&b[4]), f(&b[5]), f(&b[6]), f(&b[7]))
        };
        let v = [
            lane(|b| b.min.x),
            lane(|b| b.min.y),
            lane(|b| b.min.z),
            lane(|b| b.max.x),
            lane(|b| b.max.y),
            lane(|b| b.max.z),
        ];
        let [lx, ly, lz, hx, hy, hz] = v;
        let nan = v.iter().fold(_mm256_setzero_ps(), |a, &x| _mm256_or_ps(a, _mm256_cmp_ps::<_CMP_UNORD_Q>(x, x)));
        let empty = _mm256_or_ps(
            _mm256_or_ps(_mm256_cmp_ps::<_CMP_GT_OQ>(lx, hx), _mm256_cmp_ps::<_CMP_GT_OQ>(ly, hy)),
            _mm256_cmp_ps::<_CMP_GT_OQ>(lz, hz),
        );
        let abs = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fff_ffff));
        let mut out = _mm256_andnot_ps(empty, _mm256_castsi256_ps(_mm256_set1_epi32(-1)));
        for p in &self.planes {
            // The positive vertex per axis (the plane's sign is the same for every lane).
            let pv = |n: f32, lo: __m256, hi: __m256| if n >= 0.0 { hi } else { lo };
            let nd = _mm256_add_ps(
                _mm256_add_ps(
                    _mm256_mul_ps(_mm256_set1_ps(p.x), pv(p.x, lx, hx)),
                    _mm256_mul_ps(_mm256_set1_ps(p.y), pv(p.y, ly, hy)),
                ),
                _mm256_mul_ps(_mm256_set1_ps(p.z), pv(p.z, lz, hz)),
            );
            let dist = _mm256_add_ps(nd, _mm256_set1_ps(p.w));
            let slack =
                _mm256_mul_ps(_mm256_set1_ps(-1e-6), _mm256_add_ps(_mm256_and_ps(nd, abs), _mm256_set1_ps(p.w.abs())));
            out = _mm256_andnot_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(dist, slack), out);
        }
        _mm256_movemask_ps(_mm256_or_ps(nan, out)) as u8
    }

    /// `then(id, box)` for every id in `0..n` whose box `box_of(id)` may intersect the frustum,
    /// in parallel, eight boxes per [`Self::intersects8`]; the `Some` results in increasing id
    /// order. The per-object loop of VFC and of WOC's first pass.
    pub fn filter_map_ids<T: Send>(
        &self,
        n: u32,
        box_of: impl Fn(u32) -> Aabb + Sync,
        then: impl Fn(u32, Aabb) -> Option<T> + Sync,
    ) -> Vec<T> {
        // One task per OBJECT_CHUNK ids, each filling its own list (a per-chunk iterator handed
        // to rayon costs more than the eight tests it wraps).
        let task = OBJECT_CHUNK as u32;
        let lists: Vec<Vec<T>> = (0..n.div_ceil(task))
            .into_par_iter()
            .map(|t| {
                let mut out = Vec::new();
                let end = (t * task + task).min(n);
                for c0 in (t * task..end).step_by(8) {
                    let ids = c0..(c0 + 8).min(end);
                    let mut boxes = [Aabb::EMPTY; 8];
                    for (b, id) in boxes.iter_mut().zip(ids.clone()) {
                        *b = box_of(id);
                    }
                    let mask = self.intersects8(&boxes);
                    for (i, id) in ids.enumerate() {
                        if mask >> i & 1 != 0 {
                            out.extend(then(id, boxes[i]));
                        }
                    }
                }
                out
            })
            .collect();
        let mut all = Vec::with_capacity(lists.iter().map(Vec::len).sum());
        for l in lists {
            all.extend(l);
        }
        all
    }
}

/// View-frustum culling of many boxes (in parallel): ids (indices into `aabbs`) of the boxes
/// that may be visible, in increasing order.
pub fn vfc(aabbs: &[Aabb], cam: &Camera) -> Vec<u32> {
    let f = Frustum::from_camera(cam);
    f.filter_map_ids(aabbs.len() as u32, |id| aabbs[id as usize], |id, _| Some(id))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam() -> Camera {
        // Eye at z = 10 looking at the origin, 90 deg vertical fov, square image.
        Camera::perspective(
            Vec3::new(0.0, 0.0, 10.0),
            Vec3::ZERO,
            Vec3::Y,
            std::f32::consts::FRAC_PI_2,
            1.0,
            50.0,
            64,
            64,
        )
        .unwrap()
    }

    fn unit_box(c: Vec3) -> Aabb {
        Aabb::new(c - Vec3::splat(0.5), c + Vec3::splat(0.5))
    }

    #[test]
    fn planes_are_exact_for_a_known_camera() {
        let f = Frustum::from_camera(&cam());
        // Near plane: z_world = 9 facing -z; far plane z_world = -40 facing +z.
        let near = f.planes[4];
        assert!((near.truncate() - Vec3::new(0.0, 0.0, -1.0)).length() < 1e-5, "{near:?}");
        assert!((near.w - 9.0).abs() < 1e-4);
        let far = f.planes[5];
        assert!((far.truncate() - Vec3::Z).length() < 1e-5 && (far.w - 40.0).abs() < 1e-3, "{far:?}");
        // Left plane of a 90 deg frustum through the eye: normal (1, 0, -1)/sqrt2.
        let left = f.planes[0];
        let s = std::f32::consts::FRAC_1_SQRT_2;
        assert!((left.truncate() - Vec3::new(s, 0.0, -s)).length() < 1e-5, "{left:?}");
    }

    #[test]
    fn inside_outside_and_straddling_boxes() {
        let f = Frustum::from_camera(&cam());
        assert!(f.intersects(&unit_box(Vec3::ZERO)));
        // Behind the eye.
        assert!(!f.intersects(&unit_box(Vec3::new(0.0, 0.0, 12.0))));
        // Beyond the far plane (z = -40).
        assert!(!f.intersects(&unit_box(Vec3::new(0.0, 0.0, -41.0))));
        assert!(f.intersects(&unit_box(Vec3::new(0.0, 0.0, -40.2))), "straddles the far plane");
        // At distances 9.5..10.5 the half-width is 9.5..10.5: a box from x = 11 is outside.
        assert!(!f.intersects(&unit_box(Vec3::new(11.6, 0.0, 0.0))));
        assert!(f.intersects(&unit_box(Vec3::new(10.4, 0.0, 0.0))));
        assert!(!f.intersects(&unit_box(Vec3::new(0.0, -11.6, 0.0))));
        // Straddles the near plane (z = 9).
        assert!(f.intersects(&unit_box(Vec3::new(0.0, 0.0, 9.2))));
        assert!(!f.intersects(&Aabb::EMPTY));
        assert!(f.intersects(&Aabb::new(Vec3::NAN, Vec3::ONE)));
    }

    #[test]
    fn vfc_lists_visible_ids() {
        let boxes = [
            unit_box(Vec3::ZERO),
            unit_box(Vec3::new(0.0, 0.0, 20.0)),
            unit_box(Vec3::new(3.0, 2.0, -5.0)),
            Aabb::EMPTY,
        ];
        assert_eq!(vfc(&boxes, &cam()), vec![0, 2]);
    }

    #[test]
    fn orthographic_frustum() {
        let c = Camera::orthographic(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, Vec3::Y, 2.0, 1.0, 20.0, 32, 32).unwrap();
        let f = Frustum::from_camera(&c);
        assert!(f.intersects(&unit_box(Vec3::new(2.3, 0.0, 0.0))));
        assert!(!f.intersects(&unit_box(Vec3::new(2.6, 0.0, 0.0))));
        assert!(!f.intersects(&unit_box(Vec3::new(0.0, 0.0, -10.6))));
    }

    #[test]
    fn eight_boxes_at_once_equal_one_at_a_time() {
        // Boxes scattered around and across the planes of a few cameras, with empty, NaN,
        // touching and very large boxes among them: AVX2 and portable builds, bit for bit.
        let mut state = 0x9e37_79b9_u32;
        let mut unit = move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state as f32 / u32::MAX as f32
        };
        let cams = [
            cam(),
            Camera::perspective(Vec3::new(3.0, -2.0, 5.0), Vec3::new(-1.0, 0.5, -4.0), Vec3::Y, 0.7, 0.1, 80.0, 96, 54)
                .unwrap(),
        ];
        let _switch = crate::SIMD_TEST_LOCK.lock().unwrap_or_else(|e| e.into_inner());
        for c in &cams {
            let f = Frustum::from_camera(c);
            let mut boxes = Vec::new();
            for k in 0..4000 {
                let centre = Vec3::new(unit() * 60.0 - 30.0, unit() * 60.0 - 30.0, unit() * 90.0 - 60.0);
                let half = Vec3::new(unit(), unit(), unit()) * if k % 7 == 0 { 40.0 } else { 2.0 };
                boxes.push(match k % 23 {
                    0 => Aabb::EMPTY,
                    1 => Aabb::new(Vec3::new(f32::NAN, 0.0, 0.0), Vec3::ONE),
                    2 => Aabb::new(centre, centre),
                    3 => Aabb::new(centre + half, centre - half),
                    4 => Aabb::new(Vec3::splat(-1e30), Vec3::splat(1e30)),
                    // The positive vertex on (or a rounding away from) a plane: the slack decides.
                    5..=10 => {
                        let p = f.planes[k % 6];
                        let n = p.truncate();
                        // Up to twice the slack outside, so both sides of it occur.
                        let out = unit() * 2e-6 * (p.w.abs() + 30.0);
                        // From a point inside the view volume (so that the other planes keep it).
                        let ndc = Vec4::new(unit() * 1.6 - 0.8, unit() * 1.6 - 0.8, unit() * 0.6 + 0.2, 1.0);
                        let h = c.view_proj().inverse() * ndc;
                        let inner = h.truncate() / h.w;
                        let on = inner - (n.dot(inner) + p.w + out) * n;
                        let up = n.cmpge(Vec3::ZERO);
                        let half = half * 0.01;
                        Aabb::new(Vec3::select(up, on - 2.0 * half, on), Vec3::select(up, on, on + 2.0 * half))
                    }
                    _ => Aabb::new(centre - half, centre + half),
                });
            }
            let want: Vec<bool> = boxes.iter().map(|b| f.intersects(b)).collect();
            assert!(want.iter().any(|&v| v) && want.iter().any(|&v| !v));
            for simd in [true, false] {
                crate::set_simd(simd);
                for (chunk, w) in boxes.chunks(8).zip(want.chunks(8)) {
                    let mut eight = [Aabb::EMPTY; 8];
                    eight[..chunk.len()].copy_from_slice(chunk);
                    let m = f.intersects8(&eight);
                    for (i, &v) in w.iter().enumerate() {
                        assert_eq!(m >> i & 1 != 0, v, "box {:?}, simd {simd}", chunk[i]);
                    }
                }
                let ids = f.filter_map_ids(boxes.len() as u32, |id| boxes[id as usize], |id, _| Some(id));
                let expect: Vec<u32> = (0..boxes.len() as u32).filter(|&i| want[i as usize]).collect();
                assert_eq!(ids, expect);
            }
            crate::set_simd(true);
        }
    }
}
