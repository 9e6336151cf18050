//! Small procedural test scenes (sphere field, box city) and the meshes they are built from,
//! used by this crate's tests and by other crates' tests (zwarp-gpu, zwarp-cull, zwarp-shadows):
//! tiny, fast to build and with a fixed camera. The benchmark and the timing tools (`tools/`)
//! render the real scenes through `zwarp-scene` (the file loaders and the paper's generators).

use glam::{Mat4, Vec3};
use zwarp_core::{Animation, Camera, Mesh, Result, Scene};

/// UV sphere mesh with `seg` segments around and `seg / 2` rings.
pub fn uv_sphere(radius: f32, seg: u32) -> Mesh {
    let rings = (seg / 2).max(2);
    let mut pos = Vec::new();
    for r in 0..=rings {
        let th = std::f32::consts::PI * r as f32 / rings as f32;
        for s in 0..seg {
            let ph = std::f32::consts::TAU * s as f32 / seg as f32;
            pos.push(Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()) * radius);
        }
    }
    let mut idx = Vec::new();
    for r in 0..rings {
        for s in 0..seg {
            let a = r * seg + s;
            let b = r * seg + (s + 1) % seg;
            let c = a + seg;
            let d = b + seg;
            if r > 0 {
                idx.push([a, b, d]);
            }
            if r + 1 < rings {
                idx.push([a, d, c]);
            }
        }
    }
    Mesh::new(pos, idx).expect("valid sphere")
}

/// Closed box mesh.
pub fn box_mesh(min: Vec3, max: Vec3) -> Mesh {
    let c = zwarp_core::Aabb::new(min, max).corners();
    let idx = vec![
        [0, 2, 1],
        [1, 2, 3],
        [4, 5, 6],
        [5, 7, 6],
        [0, 1, 4],
        [1, 5, 4],
        [2, 6, 3],
        [3, 6, 7],
        [0, 4, 2],
        [2, 4, 6],
        [1, 3, 5],
        [3, 7, 5],
    ];
    Mesh::new(c.to_vec(), idx).expect("valid box")
}

/// "spheres": a `n x n` field of UV spheres (`seg` segments) on a ground quad (Z up), high
/// depth complexity: a YR-like stand-in. Returns the scene and a camera looking across it.
pub fn sphere_field(n: u32, seg: u32, width: u32, height: u32) -> Result<(Scene, Camera)> {
    let mut s = Scene { name: format!("spheres{n}x{n}"), up: Vec3::Z, ..Default::default() };
    let sphere = s.add_mesh(uv_sphere(0.45, seg));
    let ground = s.add_mesh(box_mesh(Vec3::new(-1.0, -1.0, -0.6), Vec3::new(n as f32, n as f32, -0.5)));
    s.add_instance(ground, Mat4::IDENTITY, Vec3::splat(0.5), Animation::Static, true);
    for j in 0..n {
        for i in 0..n {
            let p = Vec3::new(i as f32, j as f32, 0.0);
            let col = Vec3::new(0.3 + 0.7 * (i as f32 / n as f32), 0.5, 0.3 + 0.7 * (j as f32 / n as f32));
            s.add_instance(sphere, Mat4::from_translation(p), col, Animation::Static, false);
        }
    }
    let nf = n as f32;
    let cam = Camera::perspective(
        Vec3::new(-3.0, -3.0, 2.5),
        Vec3::new(nf * 0.6, nf * 0.6, 0.0),
        Vec3::Z,
        60f32.to_radians(),
        0.1,
        100.0,
        width,
        height,
    )?;
    Ok((s, cam))
}

/// "city": a `n x n` grid of boxes of varying heights (12 triangles each) on a ground: many small
/// objects, a CB-like stand-in. Returns the scene and a street-level camera.
pub fn box_city(n: u32, width: u32, height: u32) -> Result<(Scene, Camera)> {
    let mut s = Scene { name: format!("city{n}x{n}"), up: Vec3::Z, ..Default::default() };
    let unit = s.add_mesh(box_mesh(Vec3::new(-0.35, -0.35, 0.0), Vec3::new(0.35, 0.35, 1.0)));
    let ground = s.add_mesh(box_mesh(Vec3::new(-1.0, -1.0, -0.1), Vec3::new(n as f32, n as f32, 0.0)));
    s.add_instance(ground, Mat4::IDENTITY, Vec3::splat(0.5), Animation::Static, true);
    let mut h = 12345u32;
    for j in 0..n {
        for i in 0..n {
            h = h.wrapping_mul(1664525).wrapping_add(1013904223);
            let height = 0.5 + (h >> 8) as f32 / (1u32 << 24) as f32 * 4.0;
            let m = Mat4::from_translation(Vec3::new(i as f32, j as f32, 0.0))
                * Mat4::from_scale(Vec3::new(1.0, 1.0, height));
            s.add_instance(unit, m, Vec3::new(0.7, 0.65, 0.6), Animation::Static, false);
        }
    }
    let nf = n as f32;
    let cam = Camera::perspective(
        Vec3::new(nf * 0.5 + 0.5, -2.0, 1.7),
        Vec3::new(nf * 0.5 + 0.5, nf, 1.0),
        Vec3::Z,
        60f32.to_radians(),
        0.1,
        100.0,
        width,
        height,
    )?;
    Ok((s, cam))
}
