//! Exactness tests: fill rule, analytic depth, clipping, motion, peeling, umbra culling, queries.

use super::*;
use glam::{Mat4, Vec2};
use proptest::prelude::*;
use zwarp_core::{Animation, Mesh};

/// Quad with corners `p0, p0 + u, p0 + u + v, p0 + v` (two triangles).
fn quad(p0: Vec3, u: Vec3, v: Vec3) -> Mesh {
    Mesh::new(vec![p0, p0 + u, p0 + u + v, p0 + v], vec![[0, 1, 2], [0, 2, 3]]).unwrap()
}

/// Closed axis-aligned box.
fn cube(min: Vec3, max: Vec3) -> Mesh {
    crate::scenes::box_mesh(min, max)
}

fn scene_of(meshes: Vec<(Mesh, Animation, bool)>) -> Scene {
    let mut s = Scene { name: "test".into(), ..Default::default() };
    for (m, anim, ground) in meshes {
        let id = s.add_mesh(m);
        s.add_instance(id, Mat4::IDENTITY, Vec3::new(0.8, 0.6, 0.4), anim, ground);
    }
    s
}

/// Orthographic camera where one world unit is one pixel: world (x, y) -> pixel
/// (x + W/2, H/2 - y), looking down -z from z = 10.
fn pixel_cam(w: u32, h: u32) -> Camera {
    Camera::orthographic(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, Vec3::Y, h as f32 / 2.0, 1.0, 100.0, w, h).unwrap()
}

/// World point of pixel coordinates for `pixel_cam` at z = 0.
fn px_world(w: u32, h: u32, px: f32, py: f32) -> Vec3 {
    Vec3::new(px - w as f32 / 2.0, h as f32 / 2.0 - py, 0.0)
}

#[test]
fn quad_on_pixel_boundaries_covers_exactly_those_pixels() {
    let (w, h) = (32, 24);
    let q = quad(px_world(w, h, 5.0, 19.0), Vec3::new(7.0, 0.0, 0.0), Vec3::new(0.0, 11.0, 0.0));
    let s = scene_of(vec![(q, Animation::Static, false)]);
    let f = render_frame(&s, &pixel_cam(w, h), 0.0, &FrameOptions::default()).unwrap();
    for y in 0..h {
        for x in 0..w {
            let inside = (5..12).contains(&x) && (8..19).contains(&y);
            assert_eq!(*f.items.get(x, y) == 0, inside, "pixel ({x},{y})");
            assert_eq!(*f.depth.get(x, y) < 1.0, inside, "pixel ({x},{y})");
        }
    }
}

#[test]
fn top_left_rule_on_pixel_centres() {
    // Quad edges pass exactly through pixel centres: columns 5.5 .. 10.5, rows 3.5 .. 7.5.
    // Left and top edges are included, right and bottom edges are not.
    let (w, h) = (16, 12);
    let q = quad(px_world(w, h, 5.5, 7.5), Vec3::new(5.0, 0.0, 0.0), Vec3::new(0.0, 4.0, 0.0));
    let counts = coverage_counts(
        &pixel_cam(w, h),
        &q.indices.iter().map(|t| t.map(|i| q.positions[i as usize])).collect::<Vec<_>>(),
    )
    .unwrap();
    for y in 0..h {
        for x in 0..w {
            let inside = (5..10).contains(&x) && (3..7).contains(&y);
            assert_eq!(*counts.get(x, y), inside as u32, "pixel ({x},{y})");
        }
    }
}

/// A jittered grid of vertices covering (and exceeding) the screen, triangulated with random
/// diagonals; vertices are snapped to the 1/256 grid and some land exactly on pixel centres.
fn jittered_grid(w: u32, h: u32, n: usize, seed: u64) -> Vec<[Vec3; 3]> {
    let mut rng = seed.wrapping_mul(0x9E3779B97F4A7C15) | 1;
    let mut next = move || {
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        (rng >> 11) as f64 / (1u64 << 53) as f64
    };
    let (x0, y0) = (-3.0f64, -3.0f64);
    let (sx, sy) = ((w as f64 + 6.0) / n as f64, (h as f64 + 6.0) / n as f64);
    let mut pts = vec![Vec3::ZERO; (n + 1) * (n + 1)];
    for j in 0..=n {
        for i in 0..=n {
            let border = i == 0 || j == 0 || i == n || j == n;
            let (mut px, mut py) = (x0 + i as f64 * sx, y0 + j as f64 * sy);
            if !border {
                // Jitter of at most 0.2 cells keeps every cell convex (no folds), so the
                // triangles tile the plane exactly.
                let (cx, cy) = (px.floor() + 0.5, py.floor() + 0.5);
                if next() < 0.3 && (cx - px).abs() <= 0.2 * sx && (cy - py).abs() <= 0.2 * sy {
                    // Exactly on a pixel centre.
                    px = cx;
                    py = cy;
                } else {
                    px += (next() - 0.5) * sx * 0.4;
                    py += (next() - 0.5) * sy * 0.4;
                    px = (px * 256.0).round() / 256.0;
                    py = (py * 256.0).round() / 256.0;
                }
            }
            pts[j * (n + 1) + i] = px_world(w, h, px as f32, py as f32);
        }
    }
    let mut tris = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let a = pts[j * (n + 1) + i];
            let b = pts[j * (n + 1) + i + 1];
            let c = pts[(j + 1) * (n + 1) + i];
            let d = pts[(j + 1) * (n + 1) + i + 1];
            if next() < 0.5 {
                tris.push([a, b, d]);
                tris.push([a, d, c]);
            } else {
                tris.push([a, b, c]);
                tris.push([b, d, c]);
            }
        }
    }
    tris
}

#[test]
fn shared_edges_hit_every_pixel_centre_exactly_once() {
    let (w, h) = (97, 61);
    for seed in 0..4 {
        let tris = jittered_grid(w, h, 13, seed);
        let counts = coverage_counts(&pixel_cam(w, h), &tris).unwrap();
        for (i, &c) in counts.data().iter().enumerate() {
            assert_eq!(c, 1, "seed {seed} pixel ({}, {})", i as u32 % w, i as u32 / w);
        }
    }
}

#[test]
fn fan_around_a_pixel_centre_has_no_gaps_or_overlaps() {
    // A fan of 37 triangles around a vertex exactly on a pixel centre, inside a square hull.
    let (w, h) = (40, 40);
    let c = px_world(w, h, 20.5, 20.5);
    let mut ring = Vec::new();
    for k in 0..37 {
        let a = std::f32::consts::TAU * k as f32 / 37.0;
        // Points on a big square so the fan covers the whole screen.
        let d = Vec3::new(a.cos(), a.sin(), 0.0);
        let s = 60.0 / d.x.abs().max(d.y.abs());
        ring.push(c + d * s);
    }
    let tris: Vec<[Vec3; 3]> = (0..37).map(|k| [c, ring[k], ring[(k + 1) % 37]]).collect();
    let counts = coverage_counts(&pixel_cam(w, h), &tris).unwrap();
    assert!(counts.data().iter().all(|&n| n == 1));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    #[test]
    fn prop_random_grids_cover_each_centre_once(seed in 0u64..1_000_000, n in 2usize..20, w in 5u32..70, h in 5u32..70) {
        let tris = jittered_grid(w, h, n, seed);
        let counts = coverage_counts(&pixel_cam(w, h), &tris).unwrap();
        prop_assert!(counts.data().iter().all(|&c| c == 1));
    }
}

/// Analytic stored depth of the ray through pixel centre (x, y) hitting plane n.p = k (may be
/// > 1 beyond the far plane; `None` if the hit is before the near plane or there is none).
fn analytic_depth(cam: &Camera, x: u32, y: u32, n: Vec3, k: f32) -> Option<f64> {
    let inv = cam.view_proj().inverse().as_dmat4();
    let (nx, ny) = ((x as f64 + 0.5) / cam.width as f64 * 2.0 - 1.0, 1.0 - (y as f64 + 0.5) / cam.height as f64 * 2.0);
    let a = inv.project_point3(glam::DVec3::new(nx, ny, 0.0));
    let b = inv.project_point3(glam::DVec3::new(nx, ny, 1.0));
    let dir = b - a;
    let nd = n.as_dvec3().dot(dir);
    if nd.abs() < 1e-12 {
        return None;
    }
    let t = (k as f64 - n.as_dvec3().dot(a)) / nd;
    if t < 0.0 {
        return None; // in front of the near plane
    }
    let p = a + dir * t;
    let c = cam.view_proj().as_dmat4() * p.extend(1.0);
    Some(c.z / c.w)
}

#[test]
fn tilted_plane_depth_matches_analytic() {
    let (w, h) = (80, 60);
    let cam = Camera::perspective(Vec3::new(0.3, 1.5, 4.0), Vec3::new(0.0, 0.0, -2.0), Vec3::Y, 1.1, 0.1, 100.0, w, h)
        .unwrap();
    let n = Vec3::new(0.2, 1.0, 0.3).normalize();
    let (u, v) = (n.any_orthonormal_pair().0 * 2000.0, n.any_orthonormal_pair().1 * 2000.0);
    let k = -0.4;
    let p0 = n * k - u * 0.5 - v * 0.5;
    let s = scene_of(vec![(quad(p0, u, v), Animation::Static, false)]);
    let d = render_depth(&s, &cam, 0.0).unwrap();
    let mut hits = 0;
    for y in 0..h {
        for x in 0..w {
            let got = *d.get(x, y);
            match analytic_depth(&cam, x, y, n, k) {
                Some(z) if z <= 1.0 => {
                    hits += 1;
                    assert!(((got as f64 - z) / z).abs() < 1e-6, "({x},{y}) {got} vs {z}");
                }
                _ => assert_eq!(got, 1.0, "({x},{y})"),
            }
        }
    }
    assert!(hits > 1000);
}

#[test]
fn near_plane_clipping_matches_analytic() {
    // A wall x = 0.5 running from behind the camera (z = +50) to z = -50; the camera at the
    // origin looks down -z, so the wall's triangles cross the near plane.
    let (w, h) = (64, 48);
    let cam = Camera::perspective(Vec3::ZERO, Vec3::new(0.0, 0.0, -1.0), Vec3::Y, 1.2, 0.5, 60.0, w, h).unwrap();
    let wall = quad(Vec3::new(0.5, -200.0, 50.0), Vec3::new(0.0, 0.0, -100.0), Vec3::new(0.0, 400.0, 0.0));
    let s = scene_of(vec![(wall, Animation::Static, false)]);
    let d = render_depth(&s, &cam, 0.0).unwrap();
    let mut hits = 0;
    for y in 0..h {
        for x in 0..w {
            let got = *d.get(x, y);
            match analytic_depth(&cam, x, y, Vec3::X, 0.5) {
                Some(z) if z < 1.0 => {
                    hits += 1;
                    assert!(((got as f64 - z) / z.max(1e-3)).abs() < 1e-6, "({x},{y}) {got} vs {z}");
                }
                _ => assert_eq!(got, 1.0, "({x},{y})"),
            }
        }
    }
    assert!(hits > 200, "{hits}");
}

#[test]
fn far_plane_discards_fragments_beyond_one() {
    // Ground plane y = -1 to 1000 units away; far = 30: pixels whose ground point lies beyond the
    // far plane stay empty.
    let (w, h) = (48, 48);
    let cam = Camera::perspective(Vec3::ZERO, Vec3::new(0.0, 0.0, -1.0), Vec3::Y, 1.0, 0.1, 30.0, w, h).unwrap();
    let ground = quad(Vec3::new(-500.0, -1.0, 10.0), Vec3::new(0.0, 0.0, -1000.0), Vec3::new(1000.0, 0.0, 0.0));
    let s = scene_of(vec![(ground, Animation::Static, false)]);
    let d = render_depth(&s, &cam, 0.0).unwrap();
    let (mut near_rows, mut far_rows) = (0, 0);
    for y in 0..h {
        for x in 0..w {
            let got = *d.get(x, y);
            match analytic_depth(&cam, x, y, Vec3::Y, -1.0) {
                Some(z) if z <= 1.0 => {
                    near_rows += 1;
                    assert!(((got as f64 - z) / z).abs() < 1e-6, "({x},{y}) {got} vs {z}");
                }
                Some(_) => {
                    far_rows += 1;
                    assert_eq!(got, 1.0, "beyond far ({x},{y})");
                }
                None => assert_eq!(got, 1.0),
            }
        }
    }
    assert!(near_rows > 100 && far_rows >= 48, "{near_rows} {far_rows}");
}

#[test]
fn backfaces_are_drawn_identically() {
    let (w, h) = (32, 32);
    let cam = Camera::perspective(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 1.0, 0.1, 50.0, w, h).unwrap();
    let front = quad(Vec3::new(-1.0, -1.0, 0.0), Vec3::new(2.0, 0.0, 0.0), Vec3::new(0.0, 2.0, 0.0))
        .with_material(zwarp_core::Material::uniform(Vec3::ONE));
    let mut back = front.clone();
    back.indices.iter_mut().for_each(|t| t.swap(1, 2));
    let a = render_frame(
        &scene_of(vec![(front, Animation::Static, false)]),
        &cam,
        0.0,
        &FrameOptions { color: true, objects: None },
    )
    .unwrap();
    let b = render_frame(
        &scene_of(vec![(back, Animation::Static, false)]),
        &cam,
        0.0,
        &FrameOptions { color: true, objects: None },
    )
    .unwrap();
    assert_eq!(a, b);
    assert!(a.depth.data().iter().filter(|&&d| d < 1.0).count() > 100);
    // Flat two-sided Lambert of a quad facing the camera: normal = +z in view space.
    let l = shading::LIGHT_DIR_VIEW.normalize();
    let k = shading::AMBIENT + (1.0 - shading::AMBIENT) * l.z;
    let c = a.color.as_ref().unwrap();
    let centre = c.get(16, 16);
    for (got, alb) in centre.iter().zip([0.8f32, 0.6, 0.4]) {
        assert!((got - alb * k).abs() < 1e-5);
    }
    assert_eq!(*c.get(0, 0), shading::SKY_COLOR);
}

fn focal(cam: &Camera) -> f32 {
    match cam.projection {
        zwarp_core::Projection::Perspective { fov_y } => cam.height as f32 * 0.5 / (fov_y * 0.5).tan(),
        _ => unreachable!(),
    }
}

#[test]
fn motion_matches_camera_translation_and_object_motion() {
    let (w, h) = (64, 48);
    let fov = 1.0;
    let cam_a = Camera::perspective(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, Vec3::Y, fov, 0.1, 100.0, w, h).unwrap();
    let cam_b =
        Camera::perspective(Vec3::new(0.4, 0.0, 10.0), Vec3::new(0.4, 0.0, 0.0), Vec3::Y, fov, 0.1, 100.0, w, h)
            .unwrap();
    // Static background at distance 20 and a moving card at distance 10 (covers the centre).
    let bg = quad(Vec3::new(-50.0, -50.0, -10.0), Vec3::new(100.0, 0.0, 0.0), Vec3::new(0.0, 100.0, 0.0));
    let card = quad(Vec3::new(-1.0, -1.0, 0.0), Vec3::new(2.0, 0.0, 0.0), Vec3::new(0.0, 2.0, 0.0));
    let vel = Vec3::new(1.0, 0.0, 0.0);
    let s = scene_of(vec![(bg, Animation::Static, false), (card, Animation::Linear { velocity: vel }, false)]);
    let f = focal(&cam_a);
    // Camera translation only (t_a = t_b): v.x = -dx f / z.
    let (frame, m) = render_motion(&s, &cam_a, 0.0, &cam_b, 0.0).unwrap();
    assert_eq!(*frame.items.get(32, 24), 1);
    assert_eq!(*frame.items.get(2, 2), 0);
    let mv = m.get(32, 24).v;
    assert!((mv - Vec2::new(-0.4 * f / 10.0, 0.0)).length() < 1e-3, "{mv}");
    let mv = m.get(2, 2).v;
    assert!((mv - Vec2::new(-0.4 * f / 20.0, 0.0)).length() < 1e-3, "{mv}");
    // Object motion only: card moves +0.5 in x between t = 0 and 0.5: +0.5 f / 10 pixels.
    let (_, m) = render_motion(&s, &cam_a, 0.0, &cam_a, 0.5).unwrap();
    let mv = m.get(32, 24).v;
    assert!((mv - Vec2::new(0.5 * f / 10.0, 0.0)).length() < 1e-3, "{mv}");
    assert!(m.get(2, 2).v.length() < 1e-3);
    // Rendering at t = 0.5 puts the card where the motion predicted.
    let moved = render_frame(&s, &cam_a, 0.5, &FrameOptions::default()).unwrap();
    let dx = 0.5 * f / 10.0;
    let right_edge_a = (0..w).rev().find(|&x| *frame.items.get(x, 24) == 1).unwrap() as f32;
    let right_edge_b = (0..w).rev().find(|&x| *moved.items.get(x, 24) == 1).unwrap() as f32;
    assert!((right_edge_b - right_edge_a - dx).abs() <= 1.0);
}

/// Three parallel cards at z = 0, -2, -4 (distances 10, 12, 14), shrinking in size.
fn stacked_cards() -> Scene {
    let m = |z: f32, r: f32| quad(Vec3::new(-r, -r, z), Vec3::new(2.0 * r, 0.0, 0.0), Vec3::new(0.0, 2.0 * r, 0.0));
    scene_of(vec![
        (m(0.0, 1.0), Animation::Static, false),
        (m(-2.0, 3.0), Animation::Static, false),
        (m(-4.0, 5.0), Animation::Static, false),
    ])
}

#[test]
fn peeling_layers_are_ordered_and_fill_in_order() {
    let (w, h) = (48, 36);
    let cam = Camera::perspective(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, Vec3::Y, 1.0, 0.1, 100.0, w, h).unwrap();
    let s = stacked_cards();
    let layers = render_layers(&s, &cam, 0.0, &PeelOptions { layers: 4, ..Default::default() }).unwrap();
    assert_eq!(layers.len(), 4);
    let full = render_frame(&s, &cam, 0.0, &FrameOptions::default()).unwrap();
    assert_eq!(layers[0].depth, full.depth);
    assert_eq!(layers[0].items, full.items);
    // Centre pixel: cards 0, 1, 2 in order, then empty.
    for (k, l) in layers.iter().enumerate() {
        let expect = if k < 3 { k as u32 } else { NO_ITEM };
        assert_eq!(*l.items.get(24, 18), expect, "layer {k}");
        if k < 3 {
            let lin = cam.linear_depth(*l.depth.get(24, 18));
            assert!((lin - (10.0 + 2.0 * k as f32)).abs() < 1e-3);
        }
    }
    assert_eq!(layers[3].coverage(), 0);
    for k in 1..layers.len() {
        for i in 0..layers[k].depth.len() {
            let (prev, cur) = (layers[k - 1].depth.data()[i], layers[k].depth.data()[i]);
            if cur < 1.0 {
                assert!(prev < cur, "layer {k} pixel {i}: not strictly behind");
            }
            if prev >= 1.0 {
                assert_eq!(cur, 1.0, "layers fill in order");
            }
        }
    }
}

#[test]
fn peeling_ground_layer_is_separate() {
    let (w, h) = (40, 30);
    let cam = Camera::perspective(Vec3::new(0.0, 3.0, 10.0), Vec3::ZERO, Vec3::Y, 1.0, 0.1, 100.0, w, h).unwrap();
    let ground = quad(Vec3::new(-50.0, -1.0, 50.0), Vec3::new(100.0, 0.0, 0.0), Vec3::new(0.0, 0.0, -100.0));
    let boxm = cube(Vec3::new(-1.0, -1.0, -1.0), Vec3::new(1.0, 1.0, 1.0));
    let s = scene_of(vec![(boxm, Animation::Static, false), (ground, Animation::Static, true)]);
    let layers = render_layers(&s, &cam, 0.0, &PeelOptions { layers: 2, ground_separate: true, umbra: None }).unwrap();
    assert_eq!(layers.len(), 3);
    assert!(layers[..2].iter().all(|l| l.items.data().iter().all(|&i| i == 0 || i == NO_ITEM)));
    let g = &layers[2];
    assert!(g.items.data().iter().all(|&i| i == 1 || i == NO_ITEM));
    // The ground layer equals rendering the ground alone.
    let alone = render_frame(&s, &cam, 0.0, &FrameOptions { color: false, objects: Some(&[1]) }).unwrap();
    assert_eq!(g.depth, alone.depth);
    // ... and render_ground_layer, for callers that peel the whole scene before it.
    assert_eq!(&crate::render_ground_layer(&s, &cam, 0.0).unwrap(), g);
    let no_ground = scene_of(vec![(cube(Vec3::splat(-1.0), Vec3::splat(1.0)), Animation::Static, false)]);
    assert!(crate::render_ground_layer(&no_ground, &cam, 0.0).unwrap().depth.data().iter().all(|&d| d == 1.0));
    // render_source_layers: the whole scene peeled, then the ground alone; one layer: the frame.
    let src = crate::render_source_layers(&s, &cam, 0.0, 3, None).unwrap();
    let whole = render_layers(&s, &cam, 0.0, &PeelOptions { layers: 2, ground_separate: false, umbra: None }).unwrap();
    assert_eq!((&src[..2], &src[2]), (&whole[..], g));
    assert_eq!(
        crate::render_source_layers(&s, &cam, 0.0, 1, None).unwrap()[0].depth,
        render_frame(&s, &cam, 0.0, &FrameOptions { color: false, objects: None }).unwrap().depth
    );
    // Box back faces are layer 1 where the box covers the centre.
    assert_eq!(*layers[1].items.get(20, 15), 0);
}

/// A slab (closed box) of thickness `thick` with its front face at z = 0, a background wall at
/// z = -8; camera at distance 10.
fn slab_scene(thick: f32) -> Scene {
    let slab = cube(Vec3::new(-2.0, -2.0, -thick), Vec3::new(2.0, 2.0, 0.0));
    let bg = quad(Vec3::new(-50.0, -50.0, -8.0), Vec3::new(100.0, 0.0, 0.0), Vec3::new(0.0, 100.0, 0.0));
    scene_of(vec![(slab, Animation::Static, false), (bg, Animation::Static, false)])
}

#[test]
fn umbra_culling_skips_thin_occluder_backfaces_but_not_thick_ones() {
    let (w, h) = (128, 96);
    let fov = 1.0f32;
    let cam = Camera::perspective(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, Vec3::Y, fov, 0.1, 100.0, w, h).unwrap();
    // Viewpoints within e = 1 of the eye (c = 0). For the centre pixel (h = 0) at the slab front
    // (d = 10): s = d tan(fov/2) / H and eq. (1) gives x = d s / (e - s) ~ 0.6.
    let umbra = UmbraPeeling { region: ViewRegion::Disc { e: 1.0, c: 0.0 } };
    let s_half = 10.0 * (fov * 0.5).tan() / h as f32;
    let x = umbra.umbra_extent(&cam, 64.0, 48.0, 10.0);
    assert!((x - 10.0 * s_half / (1.0 - s_half)).abs() < 1e-5, "{x}");
    assert!(x > 0.5 && x < 0.7, "{x}");
    let opts_std = PeelOptions { layers: 3, ground_separate: false, umbra: None };
    let opts_umbra = PeelOptions { umbra: Some(umbra), ..opts_std };
    // Thin slab (0.1 < x): standard peeling wastes layer 1 on the slab's back face, umbra
    // culling goes straight to the background.
    let thin = slab_scene(0.1);
    let std_l = render_layers(&thin, &cam, 0.0, &opts_std).unwrap();
    let umb_l = render_layers(&thin, &cam, 0.0, &opts_umbra).unwrap();
    assert_eq!(*std_l[1].items.get(64, 48), 0, "standard: back face of the slab");
    assert_eq!(*std_l[2].items.get(64, 48), 1, "standard: background only in layer 2");
    assert_eq!(*umb_l[1].items.get(64, 48), 1, "umbra: background already in layer 1");
    assert_eq!(*umb_l[2].items.get(64, 48), NO_ITEM);
    assert!(umb_l[2].coverage() < std_l[2].coverage());
    // Thick slab (2 > x): its back face is visible from the novel views and keeps its layer.
    let thick = slab_scene(2.0);
    let umb_l = render_layers(&thick, &cam, 0.0, &opts_umbra).unwrap();
    assert_eq!(*umb_l[1].items.get(64, 48), 0, "umbra: thick slab back face still peeled");
    assert_eq!(*umb_l[2].items.get(64, 48), 1);
    // The background (6 units behind the back face, beyond its umbra) is not culled.
    let back_lin = cam.linear_depth(*umb_l[2].depth.get(64, 48));
    assert!((back_lin - 18.0).abs() < 1e-3, "{back_lin}");
}

#[test]
fn umbra_culling_bounds_layers_when_region_is_smaller_than_the_pixel_quad() {
    // e + h < s: the pixel quad hides its whole ray from every viewpoint: one layer suffices.
    let (w, h) = (32, 24);
    let cam = Camera::perspective(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, Vec3::Y, 1.0, 0.1, 100.0, w, h).unwrap();
    let umbra = UmbraPeeling { region: ViewRegion::Disc { e: 0.0, c: 0.0 } };
    let layers = render_layers(
        &stacked_cards(),
        &cam,
        0.0,
        &PeelOptions { layers: 3, ground_separate: false, umbra: Some(umbra) },
    )
    .unwrap();
    assert_eq!(*layers[0].items.get(16, 12), 0);
    assert!(layers[0].coverage() > 0);
    assert_eq!(layers[1].coverage(), 0);
    assert_eq!(layers[2].coverage(), 0);
    // Orthographic reference + directional region: x = s / tan(angle) independent of depth.
    let ortho = Camera::orthographic(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, Vec3::Y, 4.0, 0.1, 100.0, w, h).unwrap();
    let u = UmbraPeeling { region: ViewRegion::Directions { max_angle: 0.1 } };
    let x = u.umbra_extent(&ortho, 3.0, 4.0, 7.0);
    assert!((x - (4.0 / h as f32) / 0.1f32.tan()).abs() < 1e-5);
    assert_eq!(u.umbra_extent(&ortho, 3.0, 4.0, 70.0), x);
}

#[test]
fn draw_into_matches_full_render_and_query_agrees() {
    let (w, h) = (64, 48);
    let cam = Camera::perspective(Vec3::new(1.0, 2.0, 10.0), Vec3::ZERO, Vec3::Y, 1.0, 0.1, 100.0, w, h).unwrap();
    let s = stacked_cards();
    let full = render_frame(&s, &cam, 0.0, &FrameOptions::default()).unwrap();
    let part = render_frame(&s, &cam, 0.0, &FrameOptions { color: false, objects: Some(&[2]) }).unwrap();
    let (mut d, mut it) = (part.depth.clone(), part.items.clone());
    draw_into(&mut d, Some(&mut it), &s, &cam, 0.0, &[0, 1]).unwrap();
    assert_eq!(d, full.depth);
    assert_eq!(it, full.items);
    // Occlusion query: a card fully behind card 2 is hidden; one in front is visible; card 0's own
    // triangles are not strictly in front of themselves.
    let tri_of = |m: &Mesh, dz: f32| -> Vec<[Vec3; 3]> {
        m.indices.iter().map(|t| t.map(|i| m.positions[i as usize] + Vec3::new(0.0, 0.0, dz))).collect()
    };
    let small = quad(Vec3::new(-0.5, -0.5, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0));
    assert!(!any_fragment_visible(&full.depth, &cam, &tri_of(&small, -6.0)));
    assert!(any_fragment_visible(&full.depth, &cam, &tri_of(&small, 0.5)));
    assert!(!any_fragment_visible(&full.depth, &cam, &tri_of(&s.meshes[0], 0.0)));
    assert!(any_fragment_visible(&part.depth, &cam, &tri_of(&s.meshes[0], 0.0)));
    // Wrong size: conservatively visible.
    assert!(any_fragment_visible(&Image::new(3, 3, 0.0), &cam, &tri_of(&small, -6.0)));
}

#[test]
fn render_depth_equals_frame_depth_and_items_are_instance_ids() {
    let (w, h) = (70, 50);
    let cam = Camera::perspective(Vec3::new(3.0, 4.0, 9.0), Vec3::ZERO, Vec3::Y, 0.9, 0.1, 100.0, w, h).unwrap();
    let mut s = Scene { name: "boxes".into(), ..Default::default() };
    let m = s.add_mesh(cube(Vec3::splat(-0.5), Vec3::splat(0.5)));
    for i in 0..20 {
        let p = Vec3::new((i % 5) as f32 * 1.3 - 2.6, 0.0, (i / 5) as f32 * -1.3);
        s.add_instance(m, Mat4::from_translation(p), Vec3::ONE, Animation::Static, false);
    }
    let d = render_depth(&s, &cam, 0.0).unwrap();
    let f = render_frame(&s, &cam, 0.0, &FrameOptions { color: true, objects: None }).unwrap();
    assert_eq!(d, f.depth);
    // Every covered pixel's depth equals the depth of its item's box rendered alone.
    for id in [0u32, 7, 19] {
        let alone = render_frame(&s, &cam, 0.0, &FrameOptions { color: false, objects: Some(&[id]) }).unwrap();
        for i in 0..f.items.len() {
            if f.items.data()[i] == id {
                assert_eq!(f.depth.data()[i], alone.depth.data()[i]);
            }
        }
    }
    assert!(f.items.data().contains(&19));
}

#[test]
fn bad_input_is_an_error() {
    let cam = pixel_cam(8, 8);
    let empty = Scene::default();
    assert!(matches!(render_depth(&empty, &cam, 0.0), Err(Error::Invalid(_))));
    assert!(render_frame(&empty, &cam, 0.0, &FrameOptions::default()).is_err());
    assert!(render_layers(&empty, &cam, 0.0, &PeelOptions::default()).is_err());
    let s = stacked_cards();
    assert!(render_frame(&s, &cam, 0.0, &FrameOptions { color: false, objects: Some(&[3]) }).is_err());
    assert!(render_depth(&s, &cam, f32::NAN).is_err());
    assert!(render_layers(&s, &cam, 0.0, &PeelOptions { layers: 0, ..Default::default() }).is_err());
    let bad_umbra = UmbraPeeling { region: ViewRegion::Disc { e: -1.0, c: 0.0 } };
    assert!(render_layers(&s, &cam, 0.0, &PeelOptions { layers: 2, ground_separate: false, umbra: Some(bad_umbra) })
        .is_err());
    let mut d = Image::new(4, 4, 1.0f32);
    assert!(draw_into(&mut d, None, &s, &cam, 0.0, &[0]).is_err());
    let mut d = Image::new(8, 8, 1.0f32);
    let mut it = Image::new(4, 8, NO_ITEM);
    assert!(draw_into(&mut d, Some(&mut it), &s, &cam, 0.0, &[0]).is_err());
    assert!(draw_into(&mut d, None, &s, &cam, 0.0, &[9]).is_err());
    let mut zero = cam;
    zero.width = 0;
    assert!(render_depth(&s, &zero, 0.0).is_err());
    let mut broken = stacked_cards();
    broken.meshes[0].indices.push([0, 1, 99]);
    assert!(matches!(render_depth(&broken, &cam, 0.0), Err(Error::Invalid(_))));
    let huge = cam.with_size(20000, 8).unwrap();
    assert!(render_depth(&s, &huge, 0.0).is_err());
}

#[test]
fn simd_and_portable_builds_are_bit_identical() {
    let (s, cam) = scenes::sphere_field(4, 16, 96, 64).unwrap();
    let opts = FrameOptions { color: true, objects: None };
    let a = render_frame(&s, &cam, 0.0, &opts).unwrap();
    set_simd(false);
    let b = render_frame(&s, &cam, 0.0, &opts);
    set_simd(true);
    let b = b.unwrap();
    assert_eq!(a, b);
    assert!(a.items.data().iter().filter(|&&i| i != NO_ITEM).count() > 1000);
}

#[test]
fn animated_instances_render_at_time_t() {
    let (w, h) = (32, 32);
    let cam = pixel_cam(w, h);
    let q = quad(px_world(w, h, 2.0, 10.0), Vec3::new(4.0, 0.0, 0.0), Vec3::new(0.0, 4.0, 0.0));
    let s = scene_of(vec![(q, Animation::Linear { velocity: Vec3::new(5.0, 0.0, 0.0) }, false)]);
    // At t = 2 the quad moved 10 pixels right: columns 12..16, rows 6..10.
    let f = render_frame(&s, &cam, 2.0, &FrameOptions::default()).unwrap();
    for y in 0..h {
        for x in 0..w {
            let inside = (12..16).contains(&x) && (6..10).contains(&y);
            assert_eq!(*f.items.get(x, y) == 0, inside, "({x},{y})");
        }
    }
}

#[test]
fn clipped_shared_edges_stay_watertight() {
    // A ground grid of huge cells (vertices far outside the guard band, edges crossing the near
    // plane behind and beside the camera): every pixel whose ray hits the grid is covered exactly
    // once, every other pixel zero times.
    let (w, h) = (64, 48);
    let cam = Camera::perspective(Vec3::new(0.3, 1.0, 0.2), Vec3::new(0.5, 0.7, -5.0), Vec3::Y, 1.2, 0.05, 1.0e6, w, h)
        .unwrap();
    let (n, ext) = (9usize, 1.0e4f32);
    let cell = 2.0 * ext / n as f32;
    let p = |i: usize, j: usize| {
        // Irregular offsets so edges hit the clip planes at non-trivial points.
        let jx = ((i * 7 + j * 13) % 5) as f32 * 0.037 * cell;
        let jz = ((i * 11 + j * 3) % 7) as f32 * 0.029 * cell;
        let border = i == 0 || j == 0 || i == n || j == n;
        let (dx, dz) = if border { (0.0, 0.0) } else { (jx, jz) };
        Vec3::new(-ext + i as f32 * cell + dx, 0.0, -ext + j as f32 * cell + dz)
    };
    let mut tris = Vec::new();
    for j in 0..n {
        for i in 0..n {
            tris.push([p(i, j), p(i + 1, j), p(i + 1, j + 1)]);
            tris.push([p(i, j), p(i + 1, j + 1), p(i, j + 1)]);
        }
    }
    let counts = coverage_counts(&cam, &tris).unwrap();
    let (mut ones, mut checked) = (0, 0);
    for y in 0..h {
        for x in 0..w {
            let c = *counts.get(x, y);
            assert!(c <= 1, "({x},{y}) covered {c} times");
            // Where does the ray hit the ground plane?
            let a = cam.unproject(x as f32 + 0.5, y as f32 + 0.5, 0.0);
            let b = cam.unproject(x as f32 + 0.5, y as f32 + 0.5, 0.5);
            let d = b - a;
            if d.y < -1e-6 {
                let hit = a + d * (-a.y / d.y);
                if hit.x.abs() < 0.9 * ext && hit.z.abs() < 0.9 * ext {
                    checked += 1;
                    assert_eq!(c, 1, "({x},{y}) hit {hit} not covered");
                    ones += 1;
                }
            } else if d.y > 1e-6 {
                assert_eq!(c, 0, "({x},{y}) above the horizon");
            }
        }
    }
    assert!(checked > 1000 && ones == checked, "{checked}");
}

/// Scene with one instance per random triangle in front of a camera at z = 10 looking at -z.
fn random_triangle_scene(seed: u64, n: usize) -> Scene {
    let mut st = seed.wrapping_mul(0x2545F4914F6CDD1D) | 1;
    let mut r = move || {
        st ^= st << 13;
        st ^= st >> 7;
        st ^= st << 17;
        (st >> 11) as f32 / (1u64 << 53) as f32
    };
    let mut s = Scene { name: "random".into(), ..Default::default() };
    for _ in 0..n {
        let c = Vec3::new(r() * 6.0 - 3.0, r() * 4.0 - 2.0, r() * 8.0 - 6.0);
        let p: Vec<Vec3> = (0..3).map(|_| c + Vec3::new(r() * 4.0 - 2.0, r() * 4.0 - 2.0, r() * 4.0 - 2.0)).collect();
        let m = s.add_mesh(Mesh::new(p, vec![[0, 1, 2]]).unwrap());
        s.add_instance(m, Mat4::IDENTITY, Vec3::ONE, Animation::Static, false);
    }
    s
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(16))]

    /// Peeling against brute force: per pixel, the depths of all triangles (each rendered alone)
    /// sorted and deduplicated; layer k must hold the k-th one, with its item.
    #[test]
    fn prop_peeling_matches_brute_force(seed in 0u64..1_000_000) {
        let (w, h) = (40u32, 30u32);
        let cam = Camera::perspective(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, Vec3::Y, 0.9, 0.5, 40.0, w, h).unwrap();
        let s = random_triangle_scene(seed, 6);
        let singles: Vec<Frame> = (0..6u32)
            .map(|i| render_frame(&s, &cam, 0.0, &FrameOptions { color: false, objects: Some(&[i]) }).unwrap())
            .collect();
        let layers = render_layers(&s, &cam, 0.0, &PeelOptions { layers: 7, ..Default::default() }).unwrap();
        for p in 0..(w * h) as usize {
            let mut frags: Vec<(f32, u32)> = singles
                .iter()
                .filter(|f| f.depth.data()[p] < 1.0)
                .map(|f| (f.depth.data()[p], f.items.data()[p]))
                .collect();
            frags.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            frags.dedup_by(|b, a| a.0 == b.0);
            for (k, l) in layers.iter().enumerate() {
                match frags.get(k) {
                    Some(&(d, _)) => {
                        prop_assert_eq!(l.depth.data()[p], d, "layer {} pixel {}", k, p);
                        // The item must be one of the triangles at exactly that depth.
                        let it = l.items.data()[p];
                        prop_assert!(singles[it as usize].depth.data()[p] == d);
                    }
                    None => prop_assert_eq!(l.items.data()[p], NO_ITEM),
                }
            }
        }
    }

    /// The occlusion query against brute force: visible iff some pixel of the triangles' own
    /// rendering is strictly nearer than the stored depth.
    #[test]
    fn prop_occlusion_query_matches_brute_force(seed in 0u64..1_000_000, level in 0.0f32..1.0) {
        let (w, h) = (40u32, 30u32);
        let cam = Camera::perspective(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, Vec3::Y, 0.9, 0.5, 40.0, w, h).unwrap();
        let s = random_triangle_scene(seed, 3);
        let tris: Vec<[Vec3; 3]> = s.meshes.iter().map(|m| [m.positions[0], m.positions[1], m.positions[2]]).collect();
        let own = render_depth(&s, &cam, 0.0).unwrap();
        // Stored depth: a slanted ramp around `level` so the answer varies per pixel.
        let stored = Image::from_fn(w, h, |x, y| (level + 0.002 * (x as f32 - y as f32)).clamp(0.0, 1.0));
        let expect = own.data().iter().zip(stored.data()).any(|(&z, &d)| z < d);
        prop_assert_eq!(any_fragment_visible(&stored, &cam, &tris), expect);
        // Against its own depth buffer nothing is strictly nearer.
        prop_assert!(!any_fragment_visible(&own, &cam, &tris));
    }
}

/// A recycled depth target gives the fresh render bit for bit: one of another size is replaced,
/// one of the right size holding an earlier frame is overwritten everywhere.
#[test]
fn render_depth_into_a_recycled_target_equals_a_fresh_render() {
    let (w, h) = (64u32, 48u32);
    let cam = Camera::perspective(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, Vec3::Y, 0.9, 0.5, 40.0, w, h).unwrap();
    let (a, b) = (random_triangle_scene(3, 8), random_triangle_scene(4, 8));
    let fresh = render_depth(&b, &cam, 0.0).unwrap();
    let mut target = Image::new(7, 5, 0.25f32);
    render_depth_into(&b, &cam, 0.0, &mut target).unwrap();
    assert_eq!(target, fresh);
    render_depth_into(&a, &cam, 0.0, &mut target).unwrap();
    assert_ne!(target, fresh, "the scenes must differ for the test to mean anything");
    render_depth_into(&b, &cam, 0.0, &mut target).unwrap();
    assert_eq!(target, fresh);
}
