//! Screen-space bounds of an occludee proxy (seed 000 Sec. 5.2, thesis seed 002 Sec. III.2 and
//! Fig. 3): the 8 corners of a world AABB are projected; the pixel rectangle they span and the
//! nearest corner depth are what the max-depth query tests ("when the minimum depth of the
//! proxy corners exceeds the maximum of the screen-space depth, we can safely cull").

use glam::{Mat4, Vec2, Vec3, Vec4};
use zwarp_core::round::{ceil, floor};
use zwarp_core::{Aabb, Camera, Error, Result};

/// A non-empty, half-open pixel rectangle `[x0, x1) x [y0, y1)` (row 0 at the top).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PixelRect {
    /// First column.
    pub x0: u32,
    /// First row.
    pub y0: u32,
    /// One past the last column.
    pub x1: u32,
    /// One past the last row.
    pub y1: u32,
}

impl PixelRect {
    /// The rectangle `[x0, x1) x [y0, y1)`; errors when it is empty.
    pub fn new(x0: u32, y0: u32, x1: u32, y1: u32) -> Result<Self> {
        if x0 >= x1 || y0 >= y1 {
            return Err(Error::invalid(format!("empty pixel rectangle [{x0}, {x1}) x [{y0}, {y1})")));
        }
        Ok(PixelRect { x0, y0, x1, y1 })
    }
    /// The whole `width x height` image.
    pub fn full(width: u32, height: u32) -> Result<Self> {
        Self::new(0, 0, width, height)
    }
    /// Number of columns (`a` in the N-buffer papers).
    #[inline]
    pub fn width(&self) -> u32 {
        self.x1 - self.x0
    }
    /// Number of rows (`b`).
    #[inline]
    pub fn height(&self) -> u32 {
        self.y1 - self.y0
    }
    /// Number of pixels.
    #[inline]
    pub fn area(&self) -> u64 {
        self.width() as u64 * self.height() as u64
    }
    /// The part inside a `width x height` image, `None` if nothing is left.
    pub fn clamped(&self, width: u32, height: u32) -> Option<Self> {
        let (x1, y1) = (self.x1.min(width), self.y1.min(height));
        (self.x0 < x1 && self.y0 < y1).then_some(PixelRect { x0: self.x0, y0: self.y0, x1, y1 })
    }
}

/// Result of projecting a box (see [`screen_rect`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ScreenRect {
    /// A corner lies behind the eye or in front of the near plane: the projected bound is
    /// unreliable, the object must be treated as visible.
    CrossesNear,
    /// The box projects entirely outside the image or beyond the far plane (nothing to draw).
    Outside,
    /// The pixels the box can touch (clamped to the image) and its nearest depth.
    Rect {
        /// Every pixel the projected box can cover.
        rect: PixelRect,
        /// Minimum stored depth over the 8 corners (the box's nearest point: depth is
        /// monotonic in view distance, and a box's minimum view distance is at a corner).
        nearest: f32,
    },
}

/// Slack in pixels added on each side of the projected bound so that f32 rounding of the
/// projection can never shrink the rectangle below what the rasterizer covers.
const PIXEL_SLACK: f32 = 1e-3;

/// Projects the 8 corners of `aabb` with `cam` (see [`ScreenRect`]).
pub fn screen_rect(aabb: &Aabb, cam: &Camera) -> ScreenRect {
    screen_rect_with(aabb, &cam.view_proj(), cam.width, cam.height)
}

/// The 8 projected corners of a box in lanes: corner `4 h + k` (in [`Aabb::corners`] order:
/// bit 0 = x, bit 1 = y, bit 2 = z) is lane `k` of half `h` (see [`project_corner_lanes`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CornerLanes {
    /// Pixel x of the corners.
    pub x: [Vec4; 2],
    /// Pixel y (row 0 at the top).
    pub y: [Vec4; 2],
    /// Stored depth.
    pub z: [Vec4; 2],
}

impl CornerLanes {
    /// The corners as points (pixel x, pixel y, depth), in [`Aabb::corners`] order.
    pub fn points(&self) -> [Vec3; 8] {
        std::array::from_fn(|i| {
            let (h, k) = (i >> 2, i & 3);
            Vec3::new(self.x[h][k], self.y[h][k], self.z[h][k])
        })
    }
}

/// The 8 corners of `aabb` projected to pixel coordinates + stored depth, or `None` when one
/// is behind the eye, in front of the near plane or not finite (the box then crosses the near
/// plane and must be kept).
///
/// Bit-identical to [`zwarp_core::camera::project_with`] on each corner, at a fraction of the
/// cost: glam's `Mat4 * Vec4` sums `x_axis * x + y_axis * y + z_axis * z + w_axis` in that
/// order, and a box corner takes each coordinate from `min` or `max`, so each clip component
/// of four corners is one lane-parallel evaluation of that same sum (the screen-space tests of
/// seed 000 Sec. 5.2 project every box in the frustum once per frame).
#[inline]
pub fn project_corner_lanes(aabb: &Aabb, view_proj: &Mat4, width: u32, height: u32) -> Option<CornerLanes> {
    let (a, b) = (aabb.min, aabb.max);
    let m = view_proj;
    let px = Vec4::new(a.x, b.x, a.x, b.x);
    let py = Vec4::new(a.y, a.y, b.y, b.y);
    let comp = |c: usize| -> [Vec4; 2] {
        let xy = Vec4::splat(m.x_axis[c]) * px + Vec4::splat(m.y_axis[c]) * py;
        let w = Vec4::splat(m.w_axis[c]);
        [xy + Vec4::splat(m.z_axis[c] * a.z) + w, xy + Vec4::splat(m.z_axis[c] * b.z) + w]
    };
    let (cx, cy, cz, cw) = (comp(0), comp(1), comp(2), comp(3));
    if cw[0].cmple(Vec4::ZERO).any() || cw[1].cmple(Vec4::ZERO).any() {
        return None;
    }
    let (w, h) = (Vec4::splat(width as f32), Vec4::splat(height as f32));
    let half = Vec4::splat(0.5);
    let mut out = CornerLanes { x: [Vec4::ZERO; 2], y: [Vec4::ZERO; 2], z: [Vec4::ZERO; 2] };
    for k in 0..2 {
        let inv_w = Vec4::ONE / cw[k];
        let (nx, ny, nz) = (cx[k] * inv_w, cy[k] * inv_w, cz[k] * inv_w);
        out.x[k] = (nx + Vec4::ONE) * half * w;
        out.y[k] = (Vec4::ONE - ny) * half * h;
        out.z[k] = nz;
        if !(nz.cmpge(Vec4::ZERO).all() && out.x[k].is_finite() && out.y[k].is_finite() && nz.is_finite()) {
            return None;
        }
    }
    Some(out)
}

/// [`project_corner_lanes`] as points, in [`Aabb::corners`] order.
#[inline]
pub fn project_corners(aabb: &Aabb, view_proj: &Mat4, width: u32, height: u32) -> Option<[Vec3; 8]> {
    project_corner_lanes(aabb, view_proj, width, height).map(|l| l.points())
}

/// Hot-loop form of [`screen_rect`] with a precomputed view-projection matrix.
pub fn screen_rect_with(aabb: &Aabb, view_proj: &Mat4, width: u32, height: u32) -> ScreenRect {
    if aabb.min.is_nan() || aabb.max.is_nan() || !aabb.min.is_finite() && !aabb.is_empty() {
        // Unbounded proxy: nothing sensible can be tested.
        return ScreenRect::CrossesNear;
    }
    if aabb.is_empty() || width == 0 || height == 0 {
        return ScreenRect::Outside;
    }
    match project_corner_lanes(aabb, view_proj, width, height) {
        Some(c) => rect_of_corners(&c, width, height),
        // Behind the eye (w <= 0) or closer than the near plane (z < 0).
        None => ScreenRect::CrossesNear,
    }
}

/// The [`ScreenRect`] of corners from [`project_corner_lanes`] (all in front of the near plane).
#[inline]
pub fn rect_of_corners(c: &CornerLanes, width: u32, height: u32) -> ScreenRect {
    let (lo_x, hi_x) = (c.x[0].min(c.x[1]).min_element(), c.x[0].max(c.x[1]).max_element());
    let (lo_y, hi_y) = (c.y[0].min(c.y[1]).min_element(), c.y[0].max(c.y[1]).max_element());
    let nearest = c.z[0].min(c.z[1]).min_element();
    if nearest > 1.0 {
        return ScreenRect::Outside;
    }
    let (w, h) = (width as f32, height as f32);
    // Pixel x covers [x, x + 1): the box touches columns floor(lo) ..= ceil(hi) - 1. Clamping
    // to the image before rounding gives the same bounds as rounding first (the clamp limits
    // are integers).
    let x0 = floor((lo_x - PIXEL_SLACK).clamp(0.0, w));
    let y0 = floor((lo_y - PIXEL_SLACK).clamp(0.0, h));
    let x1 = ceil((hi_x + PIXEL_SLACK).clamp(0.0, w));
    let y1 = ceil((hi_y + PIXEL_SLACK).clamp(0.0, h));
    if x0 >= x1 || y0 >= y1 {
        return ScreenRect::Outside;
    }
    ScreenRect::Rect { rect: PixelRect { x0: x0 as u32, y0: y0 as u32, x1: x1 as u32, y1: y1 as u32 }, nearest }
}

/// The convex hull (counter-clockwise in pixel coordinates, at most 8 vertices) of the 8
/// projected corners of `aabb`, or `None` when a corner is behind the eye or in front of the
/// near plane (the box then crosses the near plane and must be kept). The exact screen
/// silhouette of the box: an object inside the box covers only pixels this polygon touches.
pub fn screen_hull_with(aabb: &Aabb, view_proj: &Mat4, width: u32, height: u32) -> Option<([Vec2; 8], usize)> {
    if aabb.is_empty() || !aabb.min.is_finite() || !aabb.max.is_finite() {
        return None;
    }
    project_corner_lanes(aabb, view_proj, width, height).map(|c| hull_of_corners(&c.points()))
}

/// The convex hull (counter-clockwise, at most 8 vertices, see [`screen_hull_with`]) of
/// projected corners from [`project_corners`].
pub fn hull_of_corners(corners: &[Vec3; 8]) -> ([Vec2; 8], usize) {
    let mut pts = corners.map(|c| c.truncate());
    // Andrew's monotone chain.
    pts.sort_unstable_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    let cross = |o: Vec2, a: Vec2, b: Vec2| (a - o).perp_dot(b - o);
    let mut hull = [Vec2::ZERO; 16];
    let mut k = 0;
    for &p in &pts {
        while k >= 2 && cross(hull[k - 2], hull[k - 1], p) <= 0.0 {
            k -= 1;
        }
        hull[k] = p;
        k += 1;
    }
    let lower = k + 1;
    for &p in pts.iter().rev().skip(1) {
        while k >= lower && cross(hull[k - 2], hull[k - 1], p) <= 0.0 {
            k -= 1;
        }
        hull[k] = p;
        k += 1;
    }
    let n = (k - 1).max(1);
    let mut out = [Vec2::ZERO; 8];
    out[..n.min(8)].copy_from_slice(&hull[..n.min(8)]);
    (out, n.min(8))
}

/// Whether the closed pixel square `[x, x + 1] x [y, y + 1]`, grown by `slack` pixels, meets
/// the convex polygon `hull[..n]` (counter-clockwise; separating-axis test). Degenerate hulls
/// (a point or a segment) are treated by their bounding box, conservatively.
pub fn square_meets_hull(x: f32, y: f32, slack: f32, hull: &[Vec2], n: usize) -> bool {
    let (lo, hi) = (Vec2::new(x - slack, y - slack), Vec2::new(x + 1.0 + slack, y + 1.0 + slack));
    let h = &hull[..n];
    let (mut bmin, mut bmax) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
    for &p in h {
        bmin = bmin.min(p);
        bmax = bmax.max(p);
    }
    if bmax.x < lo.x || bmin.x > hi.x || bmax.y < lo.y || bmin.y > hi.y {
        return false;
    }
    if n < 3 {
        return true;
    }
    let corners = [lo, Vec2::new(hi.x, lo.y), hi, Vec2::new(lo.x, hi.y)];
    for i in 0..n {
        let (a, b) = (h[i], h[(i + 1) % n]);
        let e = b - a;
        // Counter-clockwise: inside is where e.perp_dot(p - a) >= 0. Separated when every
        // square corner is strictly outside this edge.
        if corners.iter().all(|&c| e.perp_dot(c - a) < 0.0) {
            return false;
        }
    }
    true
}

/// The x-extent of convex polygon `hull[..n]` inside the horizontal strip `ya <= y <= yb`, or
/// `None` if they do not meet. A pixel square spanning the whole strip meets the polygon exactly
/// when its x-interval overlaps this extent (the polygon's part in the strip is convex), which
/// turns the per-pixel test of [`square_meets_hull`] into one clip per row.
pub fn hull_x_range_in_strip(hull: &[Vec2], n: usize, ya: f32, yb: f32) -> Option<(f32, f32)> {
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    let h = &hull[..n];
    for i in 0..n {
        let (a, b) = (h[i], h[(i + 1) % n]);
        // Clip the edge to the strip.
        let (p, q) = if a.y <= b.y { (a, b) } else { (b, a) };
        if q.y < ya || p.y > yb {
            continue;
        }
        let at = |y: f32| if q.y > p.y { p.x + (q.x - p.x) * ((y - p.y) / (q.y - p.y)) } else { p.x };
        let (y0, y1) = (p.y.max(ya), q.y.min(yb));
        let (x0, x1) = if q.y > p.y { (at(y0), at(y1)) } else { (p.x, q.x) };
        lo = lo.min(x0.min(x1));
        hi = hi.max(x0.max(x1));
    }
    (lo <= hi).then_some((lo, hi))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn pixel_rect_basics() {
        assert!(PixelRect::new(3, 0, 3, 5).is_err());
        let r = PixelRect::new(1, 2, 5, 4).unwrap();
        assert_eq!((r.width(), r.height(), r.area()), (4, 2, 8));
        assert_eq!(r.clamped(3, 10), Some(PixelRect { x0: 1, y0: 2, x1: 3, y1: 4 }));
        assert_eq!(r.clamped(1, 10), None);
    }

    #[test]
    fn orthographic_box_has_exact_rect_and_depth() {
        // Ortho camera: 1 world unit = 4 pixels (half height 4 over 32 pixels), depth linear.
        let c = Camera::orthographic(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, Vec3::Y, 4.0, 1.0, 21.0, 32, 32).unwrap();
        let b = Aabb::new(Vec3::new(-1.0, -0.5, -1.0), Vec3::new(1.25, 0.5, 1.0));
        match screen_rect(&b, &c) {
            ScreenRect::Rect { rect, nearest } => {
                // x in [-1, 1.25] -> pixel edges 12..21, y in [-0.5, 0.5] -> rows 14..18. The corners
                // land exactly on pixel edges, so the rounding slack widens the rect by one pixel
                // per side: conservative by design.
                assert_eq!(rect, PixelRect { x0: 11, y0: 13, x1: 22, y1: 19 });
                // Nearest face z = 1 is 9 units from the eye: depth (9 - 1) / 20 = 0.4.
                assert!((nearest - 0.4).abs() < 1e-6, "{nearest}");
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn near_plane_behind_and_outside() {
        let c = Camera::perspective(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, Vec3::Y, 1.0, 0.5, 100.0, 40, 30).unwrap();
        // Straddles the near plane (z = 9.5): crosses near even though mostly in front.
        let b = Aabb::new(Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 9.7));
        assert_eq!(screen_rect(&b, &c), ScreenRect::CrossesNear);
        // Entirely behind the eye: also reported as CrossesNear (VFC removes it earlier).
        let b = Aabb::new(Vec3::new(-1.0, -1.0, 11.0), Vec3::new(1.0, 1.0, 12.0));
        assert_eq!(screen_rect(&b, &c), ScreenRect::CrossesNear);
        // Far to the right: outside.
        let b = Aabb::new(Vec3::new(50.0, -1.0, -1.0), Vec3::new(51.0, 1.0, 1.0));
        assert_eq!(screen_rect(&b, &c), ScreenRect::Outside);
        // Beyond the far plane.
        let b = Aabb::new(Vec3::new(-1.0, -1.0, -200.0), Vec3::new(1.0, 1.0, -150.0));
        assert_eq!(screen_rect(&b, &c), ScreenRect::Outside);
        assert_eq!(screen_rect(&Aabb::EMPTY, &c), ScreenRect::Outside);
    }

    #[test]
    fn lane_projection_is_bit_identical_to_project_with() {
        let c = Camera::perspective(Vec3::new(1.0, 2.0, 10.0), Vec3::ZERO, Vec3::Y, 1.2, 0.1, 100.0, 37, 23).unwrap();
        let vp = c.view_proj();
        let mut seed = 99u32;
        let mut rnd = |lo: f32, hi: f32| {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            lo + (hi - lo) * (seed >> 8) as f32 / (1u32 << 24) as f32
        };
        let (mut some, mut none) = (0, 0);
        for _ in 0..5000 {
            let ctr = Vec3::new(rnd(-30.0, 30.0), rnd(-30.0, 30.0), rnd(-60.0, 15.0));
            let e = Vec3::new(rnd(0.0, 4.0), rnd(0.0, 4.0), rnd(0.0, 4.0));
            let b = Aabb::new(ctr - e, ctr + e);
            let scalar: Option<Vec<Vec3>> = b
                .corners()
                .iter()
                .map(|&p| zwarp_core::camera::project_with(&vp, 37, 23, p).filter(|s| s.z >= 0.0 && s.is_finite()))
                .collect();
            let lanes = project_corners(&b, &vp, 37, 23);
            match (scalar, lanes) {
                (Some(s), Some(l)) => {
                    some += 1;
                    for (p, q) in s.iter().zip(&l) {
                        assert_eq!(p.to_array().map(f32::to_bits), q.to_array().map(f32::to_bits), "{b:?}");
                    }
                }
                (None, None) => none += 1,
                (s, l) => panic!("{b:?}: {s:?} vs {l:?}"),
            }
        }
        assert!(some > 1000 && none > 200, "{some} {none}");
    }

    #[test]
    fn rect_covers_every_projected_point_and_is_clamped() {
        let c = Camera::perspective(Vec3::new(1.0, 2.0, 10.0), Vec3::ZERO, Vec3::Y, 1.2, 0.1, 100.0, 37, 23).unwrap();
        // Partly off-screen box: rect is clamped to the image.
        let b = Aabb::new(Vec3::new(-2.0, -1.0, -3.0), Vec3::new(9.0, 1.5, 1.0));
        let ScreenRect::Rect { rect, nearest } = screen_rect(&b, &c) else { panic!() };
        assert!(rect.x1 <= 37 && rect.y1 <= 23);
        assert_eq!(rect.x1, 37, "the box leaves the image on the right");
        // Sample the box densely: every on-screen point falls inside the rect and is not nearer.
        for i in 0..=10 {
            for j in 0..=10 {
                for k in 0..=10 {
                    let t = Vec3::new(i as f32, j as f32, k as f32) / 10.0;
                    let p = b.min + (b.max - b.min) * t;
                    let s = c.project(p).unwrap();
                    if s.x >= 0.0 && s.x < 37.0 && s.y >= 0.0 && s.y < 23.0 {
                        let (px, py) = (s.x.floor() as u32, s.y.floor() as u32);
                        assert!(px >= rect.x0 && px < rect.x1 && py >= rect.y0 && py < rect.y1);
                    }
                    assert!(s.z >= nearest - 1e-7);
                }
            }
        }
    }
}
