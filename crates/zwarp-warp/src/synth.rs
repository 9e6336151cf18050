//! An analytic test scene for the warp's tests and benchmarks: a square ground plane (`y = 0`)
//! plus axis-aligned boxes, ray cast per pixel centre, with exact depth peeling (seed 000
//! Sec. 3.4: layer k = the (k+1)-th surface along the ray; optionally the ground alone as the
//! last layer). Boxes may translate linearly in time (object motion through the item buffer).
//! Not a renderer: no triangles, no culling — only exact reference depth for small scenes.

use glam::{Mat4, Vec3};
use rayon::prelude::*;
use zwarp_core::{Aabb, Camera, Image, Motion, EMPTY_DEPTH, NO_ITEM};

/// A box of the synthetic scene moving with constant velocity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SynthBox {
    /// Box at `t = 0`.
    pub aabb: Aabb,
    /// World units per second.
    pub velocity: Vec3,
}

/// Ground plane `y = 0` of half size `ground_half` (0 = no ground) plus boxes. Object ids: box
/// `i` has id `i`, the ground has id `boxes.len()`.
#[derive(Clone, Debug, PartialEq)]
pub struct SynthScene {
    /// Half size of the square ground around the origin (0 disables the ground).
    pub ground_half: f32,
    /// The boxes.
    pub boxes: Vec<SynthBox>,
}

/// Peeled layers of one view: depth (1 = empty) and item ids ([`NO_ITEM`] = empty).
#[derive(Clone, Debug, PartialEq)]
pub struct SynthLayers {
    /// Depth per layer, nearest first.
    pub depth: Vec<Image<f32>>,
    /// Item buffer per layer.
    pub items: Vec<Image<u32>>,
}

impl SynthScene {
    /// A deterministic "city block": ground of half size 40 and a grid of `n x n` boxes of
    /// varying heights (spacing 4, footprint 2) centred on the origin.
    pub fn city(n: u32) -> Self {
        let mut boxes = Vec::new();
        for i in 0..n {
            for j in 0..n {
                let x = (i as f32 - (n as f32 - 1.0) * 0.5) * 4.0;
                let z = (j as f32 - (n as f32 - 1.0) * 0.5) * 4.0;
                let hgt = 1.0 + ((i * 7 + j * 13) % 5) as f32 * 0.8;
                boxes.push(SynthBox {
                    aabb: Aabb::new(Vec3::new(x - 1.0, 0.0, z - 1.0), Vec3::new(x + 1.0, hgt, z + 1.0)),
                    velocity: Vec3::ZERO,
                });
            }
        }
        SynthScene { ground_half: 40.0, boxes }
    }

    /// A wall (box 0: 40 m long, 5 m high, 0.4 m thick, its front face the plane `z = 0`) with
    /// six boxes of growing size 2.5-9 m behind it, on a ground of half size 40. With
    /// [`SynthScene::near_wall_camera`] the camera walks along the wall 1.2 m in front of it at
    /// a grazing angle: most of the view is wall whose nearest part magnifies strongly, and the
    /// deeper layers see its back face and the boxes behind.
    pub fn near_wall() -> Self {
        let mut boxes = vec![SynthBox {
            aabb: Aabb::new(Vec3::new(-20.0, 0.0, -0.4), Vec3::new(20.0, 5.0, 0.0)),
            velocity: Vec3::ZERO,
        }];
        for i in 0..6 {
            let (x, k) = (-10.0 + 4.0 * i as f32, i as f32);
            boxes.push(SynthBox {
                aabb: Aabb::new(Vec3::new(x, 0.0, -4.0 - k), Vec3::new(x + 1.5, 3.0 + k * 0.5, -2.5 - k)),
                velocity: Vec3::ZERO,
            });
        }
        SynthScene { ground_half: 40.0, boxes }
    }

    /// The camera of [`SynthScene::near_wall`] after walking `x` metres along the wall: eye at
    /// height 1.6 m, 1.2 m from the wall, looking 3 m ahead and 1.8 m across (60 deg vertical
    /// field of view, near 0.1, far 100).
    pub fn near_wall_camera(x: f32, w: u32, h: u32) -> zwarp_core::Result<Camera> {
        Camera::perspective(Vec3::new(x, 1.6, 1.2), Vec3::new(x + 3.0, 1.5, -0.6), Vec3::Y, 1.05, 0.1, 100.0, w, h)
    }

    /// [`SynthScene::city`]`(3)` plus a 2 m box floating 2 m above the ground that moves at 4 m/s
    /// along +x (object motion through the item buffer).
    pub fn moving_city() -> Self {
        let mut s = SynthScene::city(3);
        s.boxes.push(SynthBox {
            aabb: Aabb::new(Vec3::new(-1.0, 2.0, 3.0), Vec3::new(1.0, 4.0, 5.0)),
            velocity: Vec3::new(4.0, 0.0, 0.0),
        });
        s
    }

    /// Two views of [`SynthScene::city`] from 8 m up, the second 0.7 m to the side and 0.8 m
    /// closer, turned slightly (1 rad vertical field of view, near 0.5, far 100).
    pub fn city_views(w: u32, h: u32) -> zwarp_core::Result<(Camera, Camera)> {
        let a =
            Camera::perspective(Vec3::new(0.0, 8.0, 10.0), Vec3::new(0.0, 0.0, -4.0), Vec3::Y, 1.0, 0.5, 100.0, w, h)?;
        let b =
            Camera::perspective(Vec3::new(0.7, 8.2, 9.2), Vec3::new(0.6, 0.0, -4.5), Vec3::Y, 1.0, 0.5, 100.0, w, h)?;
        Ok((a, b))
    }

    /// World-space motion `M(t_b) M(t_a)^-1` of every object id (for `motion_field`).
    pub fn object_deltas(&self, t_a: f32, t_b: f32) -> Vec<Mat4> {
        let mut d: Vec<Mat4> = self.boxes.iter().map(|b| Mat4::from_translation(b.velocity * (t_b - t_a))).collect();
        d.push(Mat4::IDENTITY);
        d
    }

    /// Ray casts every pixel centre of `cam` at time `t` and peels `layers` layers (>= 1). With
    /// `ground_layer`, the last layer holds the ground alone (paper: "the last layer was peeled
    /// without foreground objects") and the others peel all surfaces.
    pub fn render(&self, cam: &Camera, t: f32, layers: u32, ground_layer: bool) -> SynthLayers {
        let layers = layers.max(1) as usize;
        let (w, h) = (cam.width, cam.height);
        let inv = cam.view_proj().inverse();
        let vp = cam.view_proj();
        let boxes: Vec<Aabb> =
            self.boxes.iter().map(|b| Aabb::new(b.aabb.min + b.velocity * t, b.aabb.max + b.velocity * t)).collect();
        let ground_id = self.boxes.len() as u32;
        let peel = if ground_layer && layers > 1 { layers - 1 } else { layers };
        let per_pixel: Vec<Vec<(f32, u32)>> = (0..w as usize * h as usize)
            .into_par_iter()
            .map(|i| {
                let (px, py) = ((i % w as usize) as f32 + 0.5, (i / w as usize) as f32 + 0.5);
                let o = zwarp_core::camera::unproject_with(&inv, w, h, px, py, 0.0);
                let f = zwarp_core::camera::unproject_with(&inv, w, h, px, py, 1.0);
                let dir = f - o;
                let depth_of = |s: f32| -> Option<f32> {
                    let p = o + dir * s;
                    zwarp_core::camera::project_with(&vp, w, h, p).map(|v| v.z).filter(|z| (0.0..1.0).contains(z))
                };
                let mut hits: Vec<(f32, u32)> = Vec::new();
                if self.ground_half > 0.0 && dir.y != 0.0 {
                    let s = -o.y / dir.y;
                    let p = o + dir * s;
                    if s > 0.0 && p.x.abs() <= self.ground_half && p.z.abs() <= self.ground_half {
                        if let Some(z) = depth_of(s) {
                            hits.push((z, ground_id));
                        }
                    }
                }
                for (id, b) in boxes.iter().enumerate() {
                    let inv_d = dir.recip();
                    let t0 = (b.min - o) * inv_d;
                    let t1 = (b.max - o) * inv_d;
                    let tn = t0.min(t1).max_element();
                    let tf = t0.max(t1).min_element();
                    if tn <= tf && tf > 0.0 {
                        for s in [tn, tf] {
                            if s > 0.0 {
                                if let Some(z) = depth_of(s) {
                                    hits.push((z, id as u32));
                                }
                            }
                        }
                    }
                }
                hits.sort_by(|a, b| a.0.total_cmp(&b.0));
                hits
            })
            .collect();
        let mut depth = Vec::with_capacity(layers);
        let mut items = Vec::with_capacity(layers);
        for k in 0..peel {
            depth.push(Image::from_fn(w, h, |x, y| {
                per_pixel[(y * w + x) as usize].get(k).map_or(EMPTY_DEPTH, |hit| hit.0)
            }));
            items
                .push(Image::from_fn(w, h, |x, y| per_pixel[(y * w + x) as usize].get(k).map_or(NO_ITEM, |hit| hit.1)));
        }
        if peel < layers {
            let ground = |x: u32, y: u32| per_pixel[(y * w + x) as usize].iter().find(|hit| hit.1 == ground_id);
            depth.push(Image::from_fn(w, h, |x, y| ground(x, y).map_or(EMPTY_DEPTH, |hit| hit.0)));
            items.push(Image::from_fn(w, h, |x, y| ground(x, y).map_or(NO_ITEM, |hit| hit.1)));
        }
        SynthLayers { depth, items }
    }
}

/// Motion `v` px along x with target depth `depth`: the row patterns below move along x only.
fn along_x(v: f32, depth: f32) -> Motion {
    Motion { v: glam::Vec2::new(v, 0.0), depth }
}

/// One layer of a 32x4 row pattern, as depth and motion: texel `x` of every row is `f(x)`.
fn row_layer(f: impl Fn(u32) -> Motion) -> (Image<f32>, Image<Motion>) {
    let motion = Image::from_fn(32, 4, |x, _| f(x));
    (motion.map(|s| s.depth), motion)
}

/// One row pattern (32 x 4 texels, motion along x) of a wall seen by three layers around a
/// near column's silhouette, and a far surface behind everything (seed 000 Sec. 3.4's layers,
/// as depth and motion): layer 0 sees the wall (depth 0.8, moving -9.5 px) from texel 21 on,
/// layer 1 only at texel 20 — a sliver between the column's edges, absent when `sliver` is
/// false — layer 2 up to texel 19 (moving -9.6 px), layer 3 a far surface at 0.97 moving
/// -5.8 px. Target pixel 10 lies on the seam between the wall's views: only the sliver lands
/// on it, and the far layer converges there through the seam.
pub fn seam_layers(sliver: bool) -> Vec<(Image<f32>, Image<Motion>)> {
    let (column, wall, far) = (0.3, 0.8, 0.95);
    vec![
        row_layer(|x| if x >= 21 { along_x(-9.5, wall) } else { along_x(-25.0, column) }),
        row_layer(|x| match x {
            20 if sliver => along_x(-9.5, wall),
            0..20 => along_x(-25.0, column + 0.05),
            _ => along_x(-5.7, far),
        }),
        row_layer(|x| if x <= 19 { along_x(-9.6, wall) } else { along_x(-5.7, far) }),
        row_layer(|_| along_x(-5.8, far + 0.02)),
    ]
}

/// What layer 0 sees on texels `12..20` of [`continuation_layers`], beside the wall.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BesideWall {
    /// A near column (depth 0.3, moving -20 px): the wall may run on behind it.
    Column,
    /// A far surface (0.95, moving -3 px): the wall visibly ends at texel 12.
    Ends,
    /// A surface at about the wall's depth (0.63; the step is above
    /// `sampling::SURFACE_DEPTH_STEP`, so the fetch does not read the two as one stretched
    /// surface) moving -20 px: the wall, or something at its depth, is seen where its
    /// continuation would land on the gap, though none of it does.
    SameDepth,
}

/// A wall beside one of [`BesideWall`] (seed 000 Sec. 3.4's layers, as depth and motion, 32x4,
/// motion along x): layer 0 sees the wall (depth 0.6, moving -10 px) on texels `0..12` and
/// `20..` and `beside` on `12..20`; layer 1 holds the wall's back face (0.62) behind it, the
/// column's back face (0.32) behind the column and a far surface (0.97, moving -3 px) behind
/// the other two; layer 2 a far surface (0.95, moving -3 px) behind the wall and one at 0.99
/// behind the rest. Target pixels
/// 2..9 are uncovered by layers 0 and 1 in every case, and layer 2's far surface, behind the
/// wall at its source position, converges there. With the column they show the wall's part
/// hidden behind it in the source, which no layer holds; where the wall ends the far surface
/// is the answer; beside a surface at the wall's depth the wall may reach them too.
pub fn continuation_layers(beside: BesideWall) -> Vec<(Image<f32>, Image<Motion>)> {
    let (wall, far) = (along_x(-10.0, 0.6), along_x(-3.0, 0.95));
    let beyond = along_x(-3.0, 0.97);
    vec![
        row_layer(|x| match (x, beside) {
            (12..20, BesideWall::Column) => along_x(-20.0, 0.3),
            (12..20, BesideWall::Ends) => far,
            (12..20, BesideWall::SameDepth) => along_x(-20.0, 0.63),
            _ => wall,
        }),
        row_layer(|x| match (x, beside) {
            (12..20, BesideWall::Column) => along_x(-20.0, 0.32),
            (12..20, _) => beyond,
            _ => along_x(-10.0, 0.62),
        }),
        row_layer(|x| match x {
            12..20 => along_x(-3.0, 0.99),
            _ => far,
        }),
    ]
}

/// A disocclusion over a separately peeled ground (seed 000 Sec. 3.4's last layer, as depth and
/// motion, 32x4): layer 0 holds a near object (depth 0.5) over texels `0..16` moving -14 px and
/// beyond it a far surface `far` that stays, so target pixels 2..16 are uncovered; the ground
/// layer lies at 0.95 everywhere and stays. On pixels 6..12 layer 0's walks oscillate between
/// both sides without coming within the default coverage radius (3.5 px) of the pixel, and the
/// ground converges. With `far` = 0.95 the far side is the ground itself.
pub fn ground_gap_layers(far: f32) -> Vec<(Image<f32>, Image<Motion>)> {
    vec![row_layer(|x| if x < 16 { along_x(-14.0, 0.5) } else { along_x(0.0, far) }), row_layer(|_| along_x(0.0, 0.95))]
}

/// A walk toward a tilted wall with a box in front (one layer, as depth and motion): the wall's
/// motion expands about the image centre `c` by `s`, `v(q) = s (q - c)`, its depth
/// `0.3 + 0.004 x + 0.003 y`; the box (pixels `[w/8, w/3) x [h/4, h/2)`, depth 0.2) moves by its
/// own `(5, -3)` px besides. The wall's tiles away from the box hold one solution per pixel
/// (`PreparedLayer::unique_solution`: `q + v(q)` is monotone for `s > -1`, a contraction where
/// `2 s^2 < 1/2`) although their bounds span pixels; the box's silhouette keeps the complete
/// search busy.
pub fn approach_field(w: u32, h: u32, s: f32) -> (Image<f32>, Image<Motion>) {
    let c = glam::Vec2::new(w as f32, h as f32) * 0.5;
    let in_box = |x: u32, y: u32| x >= w / 8 && x < w / 3 && y >= h / 4 && y < h / 2;
    let motion = Image::from_fn(w, h, |x, y| {
        let q = glam::Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
        if in_box(x, y) {
            Motion { v: s * (q - c) + glam::Vec2::new(5.0, -3.0), depth: 0.2 }
        } else {
            Motion { v: s * (q - c), depth: 0.3 + 0.004 * x as f32 + 0.003 * y as f32 }
        }
    });
    (motion.map(|m| m.depth), motion)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn peeling_orders_layers_and_ground_layer_is_ground_only() {
        let scene = SynthScene::city(3);
        let cam = Camera::perspective(Vec3::new(0.0, 6.0, 16.0), Vec3::ZERO, Vec3::Y, 1.0, 0.5, 100.0, 48, 32).unwrap();
        let l = scene.render(&cam, 0.0, 3, true);
        assert_eq!(l.depth.len(), 3);
        let ground_id = scene.boxes.len() as u32;
        for i in 0..48 * 32 {
            let (a, b) = (l.depth[0].data()[i], l.depth[1].data()[i]);
            assert!(a <= b);
            assert!(l.items[2].data()[i] == ground_id || l.items[2].data()[i] == NO_ITEM);
        }
        // The centre pixel sees a box (ids < ground id) in front of ground.
        assert!(l.items[0].get(24, 16) < &ground_id);
        assert!(l.depth[2].get(24, 16) < &1.0);
    }
}
