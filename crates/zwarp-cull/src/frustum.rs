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
}

/// View-frustum culling of many boxes (in parallel): ids (indices into `aabbs`) of the boxes
/// that may be visible, in increasing order.
pub fn vfc(aabbs: &[Aabb], cam: &Camera) -> Vec<u32> {
    let f = Frustum::from_camera(cam);
    aabbs.par_iter().enumerate().filter(|(_, b)| f.intersects(b)).map(|(i, _)| i as u32).collect()
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
}
