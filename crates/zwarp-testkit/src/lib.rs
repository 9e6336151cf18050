//! Test scenes and an independent brute-force reference rasterizer (per-pixel fragment lists,
//! exact fixed-point coverage with 8 sub-pixel bits and the top-left rule, depth from the plane
//! through the *unsnapped* screen-space vertices in f64, as GPUs and zwarp-raster do: snapping
//! the plane too would shift steep depth planes by up to 1/512 px times their slope), used to
//! check the GPU renderer and its depth peeling independently of zwarp-raster; the GPU tests of
//! the stage crates (`zwarp-warp`, `zwarp-cull`) use its scene, cameras, [`rng`] and
//! [`agreement`]. A dev-dependency of the workspace's tests, not published.
#![deny(missing_docs)]

use glam::{Mat4, Quat, Vec3, Vec4};
use zwarp_core::{Animation, Camera, Image, Mesh, Scene, EMPTY_DEPTH, NO_ITEM};

/// Width of the test views.
pub const W: u32 = 128;

/// Deterministic uniform numbers in `[0, 1)` (xorshift64, 24-bit mantissa) for the tests'
/// random inputs: reproducible without a dependency, the same sequence on every platform.
pub fn rng(seed: u64) -> impl FnMut() -> f32 {
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 40) as f32 / (1u64 << 24) as f32
    }
}
/// Height of the test views.
pub const H: u32 = 96;

/// A unit cube centred at the origin (12 triangles).
pub fn box_mesh() -> Mesh {
    let c = Vec3::splat(-0.5);
    let positions: Vec<Vec3> =
        (0..8).map(|i| c + Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32)).collect();
    let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
    let indices = quads.iter().flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]).collect();
    Mesh::new(positions, indices).unwrap()
}

/// A UV sphere of radius 1 centred at the origin, `rings` x `segments` quads.
pub fn sphere_mesh(rings: u32, segments: u32) -> Mesh {
    let mut positions = Vec::new();
    for r in 0..=rings {
        let th = std::f32::consts::PI * r as f32 / rings as f32;
        for s in 0..segments {
            let ph = std::f32::consts::TAU * s as f32 / segments as f32;
            positions.push(Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()));
        }
    }
    let mut indices = Vec::new();
    for r in 0..rings {
        for s in 0..segments {
            let a = r * segments + s;
            let b = r * segments + (s + 1) % segments;
            let (c, d) = (a + segments, b + segments);
            indices.push([a, c, b]);
            indices.push([b, c, d]);
        }
    }
    Mesh::new(positions, indices).unwrap()
}

/// The square `[-1, 1]^2` in the plane z = 0 (two triangles).
pub fn quad_mesh() -> Mesh {
    Mesh::new(
        vec![
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(-1.0, 1.0, 0.0),
        ],
        vec![[0, 1, 2], [0, 2, 3]],
    )
    .unwrap()
}

/// Ground quad, three boxes (one spinning), two spheres (one moving): every vertex stays in
/// front of [`camera_a`] and [`camera_b`] so no near clipping is involved. No two objects share
/// a plane (the first box floats 1 cm above the ground): at exact depth ties the item id
/// depends on draw order, which differs between the CPU (front to back) and GPU (per mesh).
pub fn test_scene() -> Scene {
    let mut s = Scene { name: "gpu-test".into(), ..Default::default() };
    let quad = s.add_mesh(quad_mesh());
    let bx = s.add_mesh(box_mesh());
    let sp = s.add_mesh(sphere_mesh(12, 20));
    let ground = Mat4::from_translation(Vec3::new(0.13, 1.57, 0.0)) * Mat4::from_scale(Vec3::new(4.1, 4.3, 1.0));
    s.add_instance(quad, ground, Vec3::new(0.5, 0.6, 0.4), Animation::Static, true);
    s.add_instance(
        bx,
        Mat4::from_scale_rotation_translation(
            Vec3::new(1.0, 0.8, 1.3),
            Quat::from_rotation_z(0.4),
            Vec3::new(-1.2, 1.1, 0.66),
        ),
        Vec3::new(0.8, 0.2, 0.2),
        Animation::Static,
        false,
    );
    s.add_instance(
        bx,
        Mat4::from_scale_rotation_translation(Vec3::splat(0.7), Quat::from_rotation_x(0.3), Vec3::new(0.9, 0.3, 0.5)),
        Vec3::new(0.2, 0.8, 0.2),
        Animation::Spin { center: Vec3::new(0.9, 0.3, 0.5), axis: Vec3::Z, angular_speed: 0.8 },
        false,
    );
    s.add_instance(
        sp,
        Mat4::from_scale_rotation_translation(Vec3::splat(0.6), Quat::IDENTITY, Vec3::new(0.2, 2.6, 0.9)),
        Vec3::new(0.2, 0.3, 0.9),
        Animation::Linear { velocity: Vec3::new(0.4, 0.0, 0.1) },
        false,
    );
    s.add_instance(
        sp,
        Mat4::from_scale_rotation_translation(Vec3::splat(0.45), Quat::IDENTITY, Vec3::new(-0.4, -0.6, 0.45)),
        Vec3::new(0.9, 0.9, 0.2),
        Animation::Static,
        false,
    );
    s.add_instance(
        bx,
        Mat4::from_scale_rotation_translation(
            Vec3::new(0.5, 0.5, 1.6),
            Quat::from_rotation_z(-0.7),
            Vec3::new(1.9, 2.9, 0.8),
        ),
        Vec3::new(0.6, 0.6, 0.6),
        Animation::Static,
        false,
    );
    s
}

/// The source view of the test scene.
pub fn camera_a() -> Camera {
    Camera::perspective(
        Vec3::new(0.3, -4.2, 2.1),
        Vec3::new(0.0, 1.0, 0.4),
        Vec3::Z,
        60f32.to_radians(),
        0.1,
        100.0,
        W,
        H,
    )
    .unwrap()
}

/// The target view: [`camera_a`] moved by about half a metre.
pub fn camera_b() -> Camera {
    Camera::perspective(
        Vec3::new(0.8, -3.9, 2.3),
        Vec3::new(0.2, 1.1, 0.5),
        Vec3::Z,
        60f32.to_radians(),
        0.1,
        100.0,
        W,
        H,
    )
    .unwrap()
}

/// All fragments per pixel `(depth, id)` in draw order; `None` if a vertex needs clipping.
pub fn fragments(scene: &Scene, cam: &Camera, t: f32) -> Vec<Vec<(f32, u32)>> {
    let (w, h) = (cam.width as i64, cam.height as i64);
    let mut frags = vec![Vec::new(); (w * h) as usize];
    let vp = cam.view_proj();
    for (id, inst) in scene.instances.iter().enumerate() {
        let mvp = vp * inst.transform_at(t);
        let mesh = &scene.meshes[inst.mesh as usize];
        let clip: Vec<Vec4> = mesh.positions.iter().map(|p| mvp * p.extend(1.0)).collect();
        for tri in &mesh.indices {
            let mut fx = [0i64; 3];
            let mut fy = [0i64; 3];
            let mut sx = [0f64; 3];
            let mut sy = [0f64; 3];
            let mut z = [0f64; 3];
            for k in 0..3 {
                let c = clip[tri[k] as usize];
                assert!(c.w > 0.0 && c.z >= 0.0 && c.z <= c.w, "test scene needs clipping");
                let iw = 1.0 / c.w as f64;
                sx[k] = (c.x as f64 * iw + 1.0) * 0.5 * w as f64;
                sy[k] = (1.0 - c.y as f64 * iw) * 0.5 * h as f64;
                fx[k] = (sx[k] * 256.0).round() as i64;
                fy[k] = (sy[k] * 256.0).round() as i64;
                z[k] = c.z as f64 * iw;
            }
            let area = (fx[1] - fx[0]) * (fy[2] - fy[0]) - (fy[1] - fy[0]) * (fx[2] - fx[0]);
            if area == 0 {
                continue;
            }
            if area < 0 {
                fx.swap(1, 2);
                fy.swap(1, 2);
                sx.swap(1, 2);
                sy.swap(1, 2);
                z.swap(1, 2);
            }
            // Depth plane z = z0 + zx (X - sx0) + zy (Y - sy0) through the unsnapped vertices.
            let (ex1, ey1, ez1) = (sx[1] - sx[0], sy[1] - sy[0], z[1] - z[0]);
            let (ex2, ey2, ez2) = (sx[2] - sx[0], sy[2] - sy[0], z[2] - z[0]);
            let det = ex1 * ey2 - ex2 * ey1;
            if det == 0.0 {
                continue;
            }
            let (zx, zy) = ((ez1 * ey2 - ez2 * ey1) / det, (ex1 * ez2 - ex2 * ez1) / det);
            let x0 = (fx.iter().min().unwrap() / 256 - 1).max(0);
            let x1 = (fx.iter().max().unwrap() / 256 + 1).min(w - 1);
            let y0 = (fy.iter().min().unwrap() / 256 - 1).max(0);
            let y1 = (fy.iter().max().unwrap() / 256 + 1).min(h - 1);
            for py in y0..=y1 {
                for px in x0..=x1 {
                    let (cx, cy) = (px * 256 + 128, py * 256 + 128);
                    let mut e = [0i64; 3];
                    let mut inside = true;
                    for i in 0..3 {
                        let j = (i + 1) % 3;
                        let (dx, dy) = (fx[j] - fx[i], fy[j] - fy[i]);
                        e[i] = dx * (cy - fy[i]) - dy * (cx - fx[i]);
                        let top_left = (dy == 0 && dx > 0) || dy < 0;
                        if !(e[i] > 0 || (e[i] == 0 && top_left)) {
                            inside = false;
                        }
                    }
                    if inside {
                        let (pxc, pyc) = (px as f64 + 0.5, py as f64 + 0.5);
                        let d = z[0] + zx * (pxc - sx[0]) + zy * (pyc - sy[0]);
                        frags[(py * w + px) as usize].push((d as f32, id as u32));
                    }
                }
            }
        }
    }
    frags
}

/// Nearest fragment per pixel (strict less: the first drawn of equal depths wins).
pub fn reference_depth(scene: &Scene, cam: &Camera, t: f32) -> (Image<f32>, Image<u32>) {
    let frags = fragments(scene, cam, t);
    let mut depth = Image::new(cam.width, cam.height, EMPTY_DEPTH);
    let mut items = Image::new(cam.width, cam.height, NO_ITEM);
    for (i, f) in frags.iter().enumerate() {
        for &(d, id) in f {
            if d < depth.data()[i] {
                depth.data_mut()[i] = d;
                items.data_mut()[i] = id;
            }
        }
    }
    (depth, items)
}

/// Reference depth peeling: layer k holds the k-th smallest distinct fragment depth.
pub fn reference_layers(scene: &Scene, cam: &Camera, t: f32, layers: usize) -> Vec<Image<f32>> {
    let frags = fragments(scene, cam, t);
    let mut out = vec![Image::new(cam.width, cam.height, EMPTY_DEPTH); layers];
    for (i, f) in frags.iter().enumerate() {
        let mut ds: Vec<f32> = f.iter().map(|p| p.0).collect();
        ds.sort_by(f32::total_cmp);
        ds.dedup();
        for (k, d) in ds.into_iter().take(layers).enumerate() {
            out[k].data_mut()[i] = d;
        }
    }
    out
}

/// Fraction of pixels whose depths agree within `tol` (both empty counts as agreement).
pub fn agreement(a: &Image<f32>, b: &Image<f32>, tol: f32) -> f64 {
    let same = a.data().iter().zip(b.data()).filter(|(x, y)| (**x - **y).abs() < tol).count();
    same as f64 / a.len() as f64
}
