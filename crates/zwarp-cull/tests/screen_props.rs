//! Property tests of the conservative proxy tests (seed 000 Sec. 5.2): for random boxes and
//! cameras, every point of a box that lands in the view volume is (a) inside the frustum test's
//! "may intersect" answer and (b) inside the box's screen rectangle, not nearer than its
//! nearest depth.

use glam::Vec3;
use proptest::prelude::*;
use zwarp_core::{Aabb, Camera};
use zwarp_cull::{screen_rect, Frustum, ScreenRect};

fn camera() -> impl Strategy<Value = Camera> {
    (-5.0f32..5.0, -5.0f32..5.0, 4.0f32..12.0, -2.0f32..2.0, -2.0f32..2.0, 0.4f32..1.6, 1u32..90, 1u32..70).prop_map(
        |(ex, ey, ez, tx, ty, fov, w, h)| {
            Camera::perspective(Vec3::new(ex, ey, ez), Vec3::new(tx, ty, 0.0), Vec3::Y, fov, 0.5, 40.0, w, h).unwrap()
        },
    )
}

fn aabb() -> impl Strategy<Value = Aabb> {
    (-8.0f32..8.0, -8.0f32..8.0, -30.0f32..12.0, 0.01f32..6.0, 0.01f32..6.0, 0.01f32..6.0)
        .prop_map(|(x, y, z, dx, dy, dz)| Aabb::new(Vec3::new(x, y, z), Vec3::new(x + dx, y + dy, z + dz)))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, max_global_rejects: 100_000, ..ProptestConfig::default() })]

    #[test]
    fn frustum_and_screen_rect_are_conservative(cam in camera(), b in aabb()) {
        // Cases where the whole box is out of view check nothing; keep those that matter.
        prop_assume!(Frustum::from_camera(&cam).intersects(&b));
        let inside_frustum = Frustum::from_camera(&cam).intersects(&b);
        let sr = screen_rect(&b, &cam);
        let vp = cam.view_proj();
        for i in 0..=6 {
            for j in 0..=6 {
                for k in 0..=6 {
                    let p = b.min + b.extent() * Vec3::new(i as f32, j as f32, k as f32) / 6.0;
                    let c = vp * p.extend(1.0);
                    if c.w <= 0.0 {
                        continue;
                    }
                    let n = c.truncate() / c.w;
                    let in_volume = n.x.abs() <= 1.0 && n.y.abs() <= 1.0 && (0.0..=1.0).contains(&n.z);
                    if !in_volume {
                        continue;
                    }
                    prop_assert!(inside_frustum, "point {p:?} is in view but the box was frustum-culled");
                    let s = cam.project(p).unwrap();
                    match sr {
                        ScreenRect::CrossesNear => {}
                        ScreenRect::Outside => prop_assert!(false, "point {p:?} in view but box reported outside"),
                        ScreenRect::Rect { rect, nearest } => {
                            let (px, py) = (s.x.floor().min(cam.width as f32 - 1.0), s.y.floor().min(cam.height as f32 - 1.0));
                            prop_assert!(px >= rect.x0 as f32 && px < rect.x1 as f32, "x {px} not in {rect:?}");
                            prop_assert!(py >= rect.y0 as f32 && py < rect.y1 as f32, "y {py} not in {rect:?}");
                            prop_assert!(s.z >= nearest - 1e-6, "depth {} nearer than {nearest}", s.z);
                        }
                    }
                }
            }
        }
    }
}

/// The per-row silhouette extent of the hull test picks exactly the pixel squares that the
/// separating-axis test accepts (random convex hulls from projected random boxes).
#[test]
fn hull_row_extent_matches_the_square_test() {
    use glam::{Mat4, Vec3};
    use zwarp_core::{Aabb, Camera};
    use zwarp_cull::{hull_x_range_in_strip, screen_hull_with, square_meets_hull};
    let cam = Camera::perspective(Vec3::new(3.0, 4.0, 9.0), Vec3::ZERO, Vec3::Y, 1.0, 0.1, 100.0, 40, 30).unwrap();
    let vp: Mat4 = cam.view_proj();
    let mut st = 7u64;
    let mut rnd = || {
        st = st.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((st >> 33) as f32) / (1u64 << 31) as f32
    };
    let mut checked = 0;
    for _ in 0..200 {
        let c = Vec3::new(rnd() * 6.0 - 3.0, rnd() * 4.0 - 2.0, rnd() * 6.0 - 3.0);
        let e = Vec3::new(0.05 + rnd() * 2.0, 0.05 + rnd() * 2.0, 0.05 + rnd() * 2.0);
        let Some((hull, n)) = screen_hull_with(&Aabb::new(c - e, c + e), &vp, 40, 30) else { continue };
        if n < 3 {
            continue;
        }
        for slack in [0.01f32, -0.49] {
            for y in -2..32 {
                let r = hull_x_range_in_strip(&hull, n, y as f32 - slack, y as f32 + 1.0 + slack);
                for x in -2..42 {
                    let (xf, yf) = (x as f32, y as f32);
                    let by_row = r.is_some_and(|(a, b)| xf - slack <= b && xf + 1.0 + slack >= a);
                    let by_sat = square_meets_hull(xf, yf, slack, &hull, n);
                    // Allow disagreement only within f32 rounding of a touching edge.
                    if by_row != by_sat {
                        assert!(
                            square_meets_hull(xf, yf, slack + 1e-3, &hull, n)
                                && !square_meets_hull(xf, yf, slack - 1e-3, &hull, n),
                            "({x}, {y}) slack {slack}: row {by_row} vs SAT {by_sat}"
                        );
                    }
                    checked += 1;
                }
            }
        }
    }
    assert!(checked > 100_000);
}
