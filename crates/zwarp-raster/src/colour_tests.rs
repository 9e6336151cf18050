//! Colour resolve tests: textures at analytic UVs, perspective-correct interpolation, the
//! triplanar pattern (deterministic, seam-free), vertex normals, bad input.

use std::sync::Arc;

use super::*;
use glam::{Mat4, Vec2};
use zwarp_core::{Animation, Material, Mesh, Texture, Wrap};

/// Quad `p0, p0 + u, p0 + u + v, p0 + v` with UVs `(0, 1), (1, 1), (1, 0), (0, 0)` (so `p0 + v`
/// is the image's top-left corner).
fn uv_quad(p0: Vec3, u: Vec3, v: Vec3) -> Mesh {
    Mesh::new(vec![p0, p0 + u, p0 + u + v, p0 + v], vec![[0, 1, 2], [0, 2, 3]])
        .unwrap()
        .with_uvs(vec![Vec2::new(0.0, 1.0), Vec2::new(1.0, 1.0), Vec2::new(1.0, 0.0), Vec2::new(0.0, 0.0)])
        .unwrap()
}

fn one_object(mesh: Mesh, albedo: Vec3) -> Scene {
    let mut s = Scene { name: "colour".into(), ..Default::default() };
    let m = s.add_mesh(mesh);
    s.add_instance(m, Mat4::IDENTITY, albedo, Animation::Static, false);
    s
}

fn colour(s: &Scene, cam: &Camera) -> (Frame, Image<[f32; 3]>) {
    let f = render_frame(s, cam, 0.0, &FrameOptions { color: true, objects: None }).unwrap();
    let c = f.color.clone().unwrap();
    (f, c)
}

/// Lambert factor of a surface facing the camera of a view looking down -z.
fn facing_k() -> f32 {
    shading::AMBIENT + (1.0 - shading::AMBIENT) * shading::LIGHT_DIR_VIEW.normalize().z
}

#[test]
fn textured_quad_facing_the_camera_shows_each_texel_at_its_pixel() {
    let (w, h) = (12u32, 8u32);
    // Texel (i, j): a distinct linear colour.
    let img = Image::from_fn(w, h, |i, j| [i as f32 / 16.0, j as f32 / 8.0, 0.25 + ((i + j) % 3) as f32 * 0.25, 1.0]);
    let tex = Arc::new(Texture::new(img.clone(), Wrap::Repeat, Wrap::Repeat).unwrap());
    // The quad fills the orthographic view exactly: pixel centre (x + 0.5, y + 0.5) has
    // uv = ((x + 0.5) / w, (y + 0.5) / h), the centre of texel (x, y).
    let q = uv_quad(Vec3::new(-6.0, -4.0, 0.0), Vec3::new(12.0, 0.0, 0.0), Vec3::new(0.0, 8.0, 0.0))
        .with_material(Material::textured(Vec3::new(1.0, 0.5, 1.0), tex));
    let s = one_object(q, Vec3::ONE);
    let cam = Camera::orthographic(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, Vec3::Y, 4.0, 1.0, 100.0, w, h).unwrap();
    let (f, c) = colour(&s, &cam);
    let k = facing_k();
    for y in 0..h {
        for x in 0..w {
            assert_eq!(*f.items.get(x, y), 0);
            let t = img.get(x, y);
            let want = [t[0] * k, t[1] * 0.5 * k, t[2] * k];
            let got = c.get(x, y);
            for ch in 0..3 {
                assert!((got[ch] - want[ch]).abs() < 1e-5, "({x},{y}): {got:?} vs {want:?}");
            }
        }
    }
}

#[test]
fn uvs_are_interpolated_perspective_correctly_on_a_slanted_quad() {
    // Texture whose red / green channels are u / v (clamped ramps; blue = 1 to divide out the
    // shading): bilinear filtering reproduces u and v exactly between the outer texel centres.
    let n = 64u32;
    let img = Image::from_fn(n, n, |i, j| [(i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32, 1.0, 1.0]);
    let tex = Arc::new(Texture::new(img, Wrap::Clamp, Wrap::Clamp).unwrap());
    // A 4 x 4 quad in the plane y = 0 (receding from the camera), seen from above and in front.
    let (p0, u, v) = (Vec3::new(-2.0, 0.0, 0.0), Vec3::new(4.0, 0.0, 0.0), Vec3::new(0.0, 0.0, -4.0));
    let s = one_object(uv_quad(p0, u, v).with_material(Material::textured(Vec3::ONE, tex)), Vec3::ONE);
    let (w, h) = (64u32, 48u32);
    let cam = Camera::perspective(Vec3::new(0.0, 1.5, 1.5), Vec3::new(0.0, 0.0, -2.0), Vec3::Y, 1.0, 0.1, 50.0, w, h)
        .unwrap();
    let (f, c) = colour(&s, &cam);
    let inv = cam.view_proj().inverse();
    let (mut checked, mut worst) = (0, 0.0f32);
    for y in 0..h {
        for x in 0..w {
            if *f.items.get(x, y) != 0 {
                continue;
            }
            // Ray through the pixel centre intersected with y = 0.
            let (nx, ny) = cam.pixel_to_ndc(x as f32 + 0.5, y as f32 + 0.5);
            let a = inv.project_point3(Vec3::new(nx, ny, 0.0));
            let b = inv.project_point3(Vec3::new(nx, ny, 0.5));
            let p = a + (b - a) * (a.y / (a.y - b.y));
            let (su, sv) = ((p.x - p0.x) / 4.0, (p.z - p0.z) / -4.0);
            // uv of the point: u = su, v = 1 - sv (see uv_quad).
            let (tu, tv) = (su, 1.0 - sv);
            let px = c.get(x, y);
            let (gu, gv) = (px[0] / px[2], px[1] / px[2]);
            let lim = 1.5 / n as f32;
            if tu > lim && tu < 1.0 - lim && tv > lim && tv < 1.0 - lim {
                worst = worst.max((gu - tu).abs()).max((gv - tv).abs());
                checked += 1;
            }
        }
    }
    assert!(checked > 500, "only {checked} pixels checked");
    assert!(worst < 2e-4, "uv error {worst}");
    // The view is strongly perspective: along the image's vertical, v is far from affine.
    let rows: Vec<u32> = (0..h).filter(|&y| *f.items.get(w / 2, y) == 0).collect();
    let (r0, r1) = (rows[0] + 1, rows[rows.len() - 1] - 1);
    let (t0, t1) = (uv_at_row(&f, &c, w, r0), uv_at_row(&f, &c, w, r1));
    let mid = uv_at_row(&f, &c, w, (r0 + r1) / 2);
    assert!((mid - 0.5 * (t0 + t1)).abs() > 0.02, "{t0} {mid} {t1}");
}

fn uv_at_row(f: &Frame, c: &Image<[f32; 3]>, w: u32, y: u32) -> f32 {
    assert_eq!(*f.items.get(w / 2, y), 0, "row {y} misses the quad");
    let p = c.get(w / 2, y);
    p[1] / p[2]
}

#[test]
fn pattern_is_a_seam_free_function_of_world_position() {
    // A fronto-parallel quad (two triangles sharing the diagonal) with the default pattern: every
    // pixel equals albedo * pattern(world point) * k, on both sides of the shared edge.
    let (w, h) = (96u32, 64u32);
    let albedo = Vec3::new(0.9, 0.7, 0.5);
    let q = Mesh::new(
        vec![
            Vec3::new(-0.6, -0.4, 0.0),
            Vec3::new(0.6, -0.4, 0.0),
            Vec3::new(0.6, 0.4, 0.0),
            Vec3::new(-0.6, 0.4, 0.0),
        ],
        vec![[0, 1, 2], [0, 2, 3]],
    )
    .unwrap();
    let s = one_object(q, albedo);
    let cam = Camera::orthographic(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 0.4, 1.0, 10.0, w, h).unwrap();
    let (_, c) = colour(&s, &cam);
    let k = facing_k();
    let mut worst = 0.0f32;
    for y in 0..h {
        for x in 0..w {
            let p = cam.unproject(x as f32 + 0.5, y as f32 + 0.5, 0.5);
            let p = Vec3::new(p.x, p.y, 0.0);
            let want = albedo * shading::pattern(p, Vec3::Z, 0) * k;
            let got = Vec3::from_array(*c.get(x, y));
            worst = worst.max((got - want).abs().max_element());
        }
    }
    assert!(worst < 2e-5, "pattern differs from its world-space function by {worst}");
    // Detail at a few pixels: neighbouring pixels (1/80 m apart) differ visibly somewhere,
    // and the image is far from flat.
    let lum: Vec<f32> = c.data().iter().map(|p| p[0] + p[1] + p[2]).collect();
    let (lo, hi) = lum.iter().fold((f32::MAX, f32::MIN), |(a, b), &v| (a.min(v), b.max(v)));
    assert!(hi - lo > 0.3, "pattern range {lo}..{hi}");
}

#[test]
fn pattern_is_continuous_and_deterministic() {
    let mut r = 0x1234_5678u32;
    let mut next = || {
        r ^= r << 13;
        r ^= r >> 17;
        r ^= r << 5;
        r as f32 / u32::MAX as f32
    };
    for _ in 0..2000 {
        let p = Vec3::new(next() * 40.0 - 20.0, next() * 40.0 - 20.0, next() * 10.0);
        let n = Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5);
        let id = (next() * 1000.0) as u32;
        let a = shading::pattern(p, n, id);
        assert_eq!(a, shading::pattern(p, n, id));
        assert!(a.min_element() > 0.3 && a.max_element() < 1.4, "{a}");
        // Lipschitz in position (finest scale: 32 cycles per metre) and in the normal.
        let d = Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5) * 2e-4;
        let b = shading::pattern(p + d, n, id);
        assert!((a - b).abs().max_element() < 40.0 * d.length() + 1e-5, "{a} {b}");
        let c = shading::pattern(p, n + d, id);
        assert!((a - c).abs().max_element() < 200.0 * d.length() / n.length() + 1e-5, "{a} {c}");
    }
    // Different objects get different tints.
    assert_ne!(shading::tint(1, 0), shading::tint(2, 0));
}

#[test]
fn colour_does_not_depend_on_the_thread_count() {
    let (s, cam) = scenes::sphere_field(3, 12, 80, 60).unwrap();
    let opts = FrameOptions { color: true, objects: None };
    let many = render_frame(&s, &cam, 0.0, &opts).unwrap();
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let single = one.install(|| render_frame(&s, &cam, 0.0, &opts).unwrap());
    assert_eq!(many, single);
}

#[test]
fn vertex_normals_shade_and_flip_to_the_eye() {
    // A camera-facing quad whose vertex normals all lean by the same angle: the Lambert term
    // follows the vertex normal, not the flat one, from either side.
    let n = Vec3::new(0.6, 0.0, 0.8);
    let q = Mesh::new(
        vec![
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(-1.0, 1.0, 0.0),
        ],
        vec![[0, 1, 2], [0, 2, 3]],
    )
    .unwrap()
    .with_normals(vec![n * 3.0; 4])
    .unwrap()
    .with_material(Material::uniform(Vec3::ONE));
    let s = one_object(q, Vec3::ONE);
    let l = shading::LIGHT_DIR_VIEW.normalize();
    for (eye, want_n) in [(Vec3::new(0.0, 0.0, 5.0), n), (Vec3::new(0.0, 0.0, -5.0), -n)] {
        let cam = Camera::orthographic(eye, Vec3::ZERO, Vec3::Y, 2.0, 1.0, 10.0, 16, 16).unwrap();
        let (_, c) = colour(&s, &cam);
        // Light direction in world space for this camera.
        let lw = cam.view.inverse().transform_vector3(l).normalize();
        let k = shading::AMBIENT + (1.0 - shading::AMBIENT) * want_n.dot(lw).max(0.0);
        let got = c.get(8, 8)[0];
        assert!((got - k).abs() < 1e-5, "eye {eye}: {got} vs {k}");
    }
}

#[test]
fn broken_attributes_are_one_line_errors() {
    let mut s =
        one_object(uv_quad(Vec3::ZERO, Vec3::X, Vec3::Y).with_material(Material::pattern(Vec3::ONE)), Vec3::ONE);
    let cam = Camera::orthographic(Vec3::new(0.5, 0.5, 5.0), Vec3::new(0.5, 0.5, 0.0), Vec3::Y, 1.0, 1.0, 10.0, 8, 8)
        .unwrap();
    s.meshes[0].uvs.as_mut().unwrap().pop();
    let e = render_frame(&s, &cam, 0.0, &FrameOptions { color: true, objects: None }).unwrap_err().to_string();
    assert_eq!(e, "invalid input: mesh 0: mesh has 3 uvs for 4 vertices (need one per vertex)");
    // Depth and ids do not read the attributes.
    assert!(render_frame(&s, &cam, 0.0, &FrameOptions::default()).is_ok());
    s.meshes[0].uvs = None;
    s.meshes[0].normals = Some(vec![Vec3::Z, Vec3::Z, Vec3::NAN, Vec3::Z]);
    let e = render_frame(&s, &cam, 0.0, &FrameOptions { color: true, objects: None }).unwrap_err().to_string();
    assert_eq!(e, "invalid input: mesh 0: normal 2 is not finite");
}
