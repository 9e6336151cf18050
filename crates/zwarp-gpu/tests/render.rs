//! GPU renderer vs the CPU rasterizer (zwarp-raster) and an independent brute-force reference:
//! depth, item ids, colour, depth peeling (standard, ground layer, umbra culling); analytic
//! orientation checks; error paths.

use zwarp_testkit as common;

use common::*;
use glam::{Mat4, Vec3};
use std::sync::Arc;

use zwarp_core::{Animation, Camera, Image, Material, MeshPart, Scene, Texture, Wrap, EMPTY_DEPTH, NO_ITEM};
use zwarp_gpu::{test_context, FrameOptions, GpuScene, PeelOptions, Renderer, Shading, Umbra};

fn setup() -> Option<(Renderer, GpuScene, Scene)> {
    let ctx = test_context()?;
    let scene = test_scene();
    let gs = GpuScene::upload(&ctx, &scene).unwrap();
    Some((Renderer::new(&ctx).unwrap(), gs, scene))
}

/// The brief's bar: identical depth (|diff| < 1e-6) on >= 99.9% of pixels vs
/// `zwarp_raster::render_depth`, item ids equal where depths are equal.
#[test]
fn depth_and_items_match_zwarp_raster() {
    let Some((r, gs, scene)) = setup() else { return };
    for (cam, t) in [(camera_a(), 0.0), (camera_b(), 0.7)] {
        let cpu = zwarp_raster::render_frame(&scene, &cam, t, &Default::default()).unwrap();
        let depth_only = zwarp_raster::render_depth(&scene, &cam, t).unwrap();
        let gpu = r.render_frame(&gs, &cam, t, &FrameOptions::default()).unwrap();
        let agree = agreement(&gpu.depth, &depth_only, 1e-6);
        assert!(agree >= 0.999, "only {:.4}% of pixels agree", agree * 100.0);
        assert!(agreement(&gpu.depth, &cpu.depth, 1e-6) >= 0.999);
        let mut same_depth = 0;
        for i in 0..gpu.depth.len() {
            if (gpu.depth.data()[i] - cpu.depth.data()[i]).abs() < 1e-6 {
                same_depth += 1;
                assert_eq!(gpu.items.data()[i], cpu.items.data()[i], "pixel {i}");
            }
        }
        assert!(same_depth as f64 >= 0.999 * gpu.depth.len() as f64);
    }
}

/// A scene built by zwarp-raster's own generator (many objects, near clipping of large boxes).
#[test]
fn generated_box_city_matches_zwarp_raster() {
    let Some(ctx) = test_context() else { return };
    let (scene, cam) = zwarp_raster::scenes::box_city(6, W, H).unwrap();
    let gs = GpuScene::upload(&ctx, &scene).unwrap();
    let r = Renderer::new(&ctx).unwrap();
    let gpu = r.render_frame(&gs, &cam, 0.0, &FrameOptions::default()).unwrap();
    let cpu = zwarp_raster::render_frame(&scene, &cam, 0.0, &Default::default()).unwrap();
    let agree = agreement(&gpu.depth, &cpu.depth, 1e-6);
    assert!(agree >= 0.999, "only {:.4}% of pixels agree", agree * 100.0);
    let covered = cpu.depth.data().iter().filter(|d| **d < EMPTY_DEPTH).count();
    assert!(covered > 100, "generator scene barely visible ({covered} px)");
    for i in 0..gpu.depth.len() {
        if (gpu.depth.data()[i] - cpu.depth.data()[i]).abs() < 1e-6 {
            assert_eq!(gpu.items.data()[i], cpu.items.data()[i], "pixel {i}");
        }
    }
}

#[test]
fn colour_matches_zwarp_raster() {
    let Some((r, gs, scene)) = setup() else { return };
    let d = Shading::default();
    assert_eq!(d.light_dir_view, zwarp_raster::shading::LIGHT_DIR_VIEW);
    assert_eq!(d.ambient, zwarp_raster::shading::AMBIENT);
    assert_eq!(d.sky, zwarp_raster::shading::SKY_COLOR);
    let cam = camera_b();
    let cpu = zwarp_raster::render_frame(&scene, &cam, 0.4, &zwarp_raster::FrameOptions { color: true, objects: None })
        .unwrap();
    let gpu = r.render_frame(&gs, &cam, 0.4, &FrameOptions { color: true, shading: d }).unwrap();
    let (cc, gc) = (cpu.color.unwrap(), gpu.color.unwrap());
    let mut compared = 0;
    for i in 0..cc.len() {
        if gpu.items.data()[i] == cpu.items.data()[i] {
            compared += 1;
            for k in 0..3 {
                assert!(
                    (cc.data()[i][k] - gc.data()[i][k]).abs() < 1e-3,
                    "pixel {i}: {:?} vs {:?}",
                    gc.data()[i],
                    cc.data()[i]
                );
            }
        }
    }
    assert!(compared as f64 >= 0.999 * cc.len() as f64);
}

#[test]
fn depth_only_matches_reference_rasterizer() {
    let Some((r, gs, scene)) = setup() else { return };
    for (cam, t) in [(camera_a(), 0.0), (camera_b(), 0.7)] {
        let gpu = r.render_depth(&gs, &cam, t).unwrap();
        let (reference, _) = reference_depth(&scene, &cam, t);
        assert_eq!(gpu.size(), (W, H));
        let agree = agreement(&gpu, &reference, 1e-6);
        assert!(agree >= 0.999, "only {:.4}% of pixels agree", agree * 100.0);
        // The scene covers a good part of the image and leaves some sky.
        let covered = gpu.data().iter().filter(|d| **d < EMPTY_DEPTH).count();
        assert!(covered > (W * H / 3) as usize && covered < (W * H) as usize, "covered {covered}");
    }
}

#[test]
fn frame_pass_depth_equals_depth_only_and_items_match_reference() {
    let Some((r, gs, scene)) = setup() else { return };
    let cam = camera_a();
    let depth_only = r.render_depth(&gs, &cam, 0.3).unwrap();
    let frame = r.render_frame(&gs, &cam, 0.3, &FrameOptions::default()).unwrap();
    assert!(frame.color.is_none());
    // Same vertices, same rasterizer: bit-identical depth.
    assert_eq!(frame.depth, depth_only);
    let (ref_depth, ref_items) = reference_depth(&scene, &cam, 0.3);
    let mut compared = 0;
    for i in 0..frame.depth.len() {
        let d = frame.depth.data()[i];
        if (d - ref_depth.data()[i]).abs() < 1e-6 {
            assert_eq!(frame.items.data()[i], ref_items.data()[i], "pixel {i}");
            compared += 1;
        }
        // Empty depth <=> no item.
        assert_eq!(d >= EMPTY_DEPTH, frame.items.data()[i] == NO_ITEM, "pixel {i}");
    }
    assert!(compared as f64 >= 0.999 * frame.depth.len() as f64);
    // Every object is visible somewhere.
    for id in 0..scene.instances.len() as u32 {
        assert!(frame.items.data().contains(&id), "object {id} not visible");
    }
}

/// A quad covering exactly the left half of an orthographic view at a known distance: checks
/// row/column orientation (row 0 = top) and the depth value analytically.
#[test]
fn orientation_and_depth_are_analytic() {
    let Some(ctx) = test_context() else { return };
    let mut s = Scene::default();
    let q = s.add_mesh(quad_mesh());
    // Quad spans x in [-2, 0] (left half of a 4-unit wide view), y in [0, 2] (top half).
    s.add_instance(q, Mat4::from_translation(Vec3::new(-1.0, 1.0, 0.0)), Vec3::ONE, Animation::Static, false);
    let cam = Camera::orthographic(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 2.0, 1.0, 9.0, 16, 16).unwrap();
    let gs = GpuScene::upload(&ctx, &s).unwrap();
    let r = Renderer::new(&ctx).unwrap();
    let f = r.render_frame(&gs, &cam, 0.0, &FrameOptions::default()).unwrap();
    let expect = (5.0 - 1.0) / (9.0 - 1.0);
    for y in 0..16 {
        for x in 0..16 {
            let d = *f.depth.get(x, y);
            if x < 8 && y < 8 {
                assert!((d - expect).abs() < 1e-6, "({x},{y}) depth {d}");
                assert_eq!(*f.items.get(x, y), 0);
            } else {
                assert_eq!(d, EMPTY_DEPTH, "({x},{y})");
                assert_eq!(*f.items.get(x, y), NO_ITEM);
            }
        }
    }
}

#[test]
fn depth_peeling_matches_reference_layers() {
    let Some((r, gs, scene)) = setup() else { return };
    let cam = camera_b();
    let l = 4;
    let opts = PeelOptions { layers: l, ..Default::default() };
    let layers = r.render_layers(&gs, &cam, 0.2, &opts).unwrap();
    assert_eq!(layers.len(), l as usize);
    let reference = reference_layers(&scene, &cam, 0.2, l as usize);
    for k in 0..l as usize {
        let agree = agreement(&layers[k].depth, &reference[k], 1e-6);
        assert!(agree >= 0.995, "layer {k}: only {:.3}% agree", agree * 100.0);
        if k > 0 {
            // Strictly behind the previous layer wherever the layer is not empty.
            for (a, b) in layers[k - 1].depth.data().iter().zip(layers[k].depth.data()) {
                assert!(*b == EMPTY_DEPTH || b > a, "{b} not behind {a}");
            }
        }
    }
    // Layer 1 is not empty (boxes and spheres have back faces) and layer 0 is the frame.
    assert!(layers[1].depth.data().iter().any(|d| *d < EMPTY_DEPTH));
    let frame = r.render_frame(&gs, &cam, 0.2, &FrameOptions::default()).unwrap();
    assert_eq!(layers[0].depth, frame.depth);
    assert_eq!(layers[0].items, frame.items);
}

/// `bar`: fraction of pixels that must agree (0.998 on Vulkan/lavapipe; the GLES fallback
/// evaluates the umbra threshold with slightly different rounding).
fn compare_layers(gpu: &[zwarp_gpu::GpuFrame], cpu: &[zwarp_raster::Layer], bar: f64) {
    assert_eq!(gpu.len(), cpu.len());
    for (k, (g, c)) in gpu.iter().zip(cpu).enumerate() {
        let agree = agreement(&g.depth, &c.depth, 1e-6);
        assert!(agree >= bar, "layer {k}: only {:.3}% agree", agree * 100.0);
        let ids = g.items.data().iter().zip(c.items.data()).filter(|(a, b)| a == b).count();
        assert!(ids as f64 >= bar * g.items.len() as f64, "layer {k}: item ids differ on {} px", g.items.len() - ids);
    }
}

#[test]
fn ground_separate_layers_match_zwarp_raster() {
    let Some((r, gs, scene)) = setup() else { return };
    let cam = camera_a();
    let opts = PeelOptions { layers: 3, ground_separate: true, ..Default::default() };
    let layers = r.render_layers(&gs, &cam, 0.0, &opts).unwrap();
    assert_eq!(layers.len(), 4, "L peeled layers + the ground layer");
    let cpu = zwarp_raster::render_layers(
        &scene,
        &cam,
        0.0,
        &zwarp_raster::PeelOptions { layers: 3, ground_separate: true, umbra: None },
    )
    .unwrap();
    compare_layers(&layers, &cpu, 0.998);
    // The ground layer holds only the ground (object 0); peeled layers never do.
    assert!(layers[3].items.data().iter().all(|&id| id == 0 || id == NO_ITEM));
    assert!(layers[3].items.data().contains(&0));
    assert!(layers[..3].iter().all(|l| !l.items.data().contains(&0)));
}

#[test]
fn umbra_peeling_matches_zwarp_raster_and_peels_faster() {
    let Some((r, gs, scene)) = setup() else { return };
    let cam = camera_a();
    let bar = if r.context().adapter.backend == "Gl" { 0.99 } else { 0.998 };
    for (umbra, cpu_region) in [
        (Umbra::Disc { e: 0.3, c: 0.0 }, zwarp_raster::ViewRegion::Disc { e: 0.3, c: 0.0 }),
        (Umbra::Disc { e: 0.05, c: -1.0 }, zwarp_raster::ViewRegion::Disc { e: 0.05, c: -1.0 }),
        (Umbra::Directions { max_angle: 0.2 }, zwarp_raster::ViewRegion::Directions { max_angle: 0.2 }),
    ] {
        let gpu = r
            .render_layers(&gs, &cam, 0.0, &PeelOptions { layers: 3, umbra: Some(umbra), ..Default::default() })
            .unwrap();
        let cpu = zwarp_raster::render_layers(
            &scene,
            &cam,
            0.0,
            &zwarp_raster::PeelOptions {
                layers: 3,
                ground_separate: false,
                umbra: Some(zwarp_raster::UmbraPeeling { region: cpu_region }),
            },
        )
        .unwrap();
        compare_layers(&gpu, &cpu, bar);
    }
    // A positive umbra extent never peels more than standard peeling does.
    let std_l = r.render_layers(&gs, &cam, 0.0, &PeelOptions { layers: 3, ..Default::default() }).unwrap();
    let umb = r
        .render_layers(
            &gs,
            &cam,
            0.0,
            &PeelOptions { layers: 3, umbra: Some(Umbra::Disc { e: 0.3, c: 0.0 }), ..Default::default() },
        )
        .unwrap();
    let cov = |f: &zwarp_gpu::GpuFrame| f.depth.data().iter().filter(|d| **d < EMPTY_DEPTH).count();
    assert_eq!(cov(&std_l[0]), cov(&umb[0]));
    assert!(cov(&umb[2]) <= cov(&std_l[2]));
    let e = r.render_layers(
        &gs,
        &cam,
        0.0,
        &PeelOptions { layers: 2, umbra: Some(Umbra::Disc { e: -1.0, c: 0.0 }), ..Default::default() },
    );
    assert!(e.is_err());
}

#[test]
fn colour_is_lambert_with_sky() {
    let Some(ctx) = test_context() else { return };
    let mut s = Scene::default();
    let q = s.add_mesh(quad_mesh().with_material(Material::uniform(Vec3::ONE)));
    let albedo = Vec3::new(0.8, 0.4, 0.2);
    s.add_instance(q, Mat4::IDENTITY, albedo, Animation::Static, false);
    // Looking at the z = 0 quad from below: its +z normal faces away, two-sided shading must
    // flip it towards the camera (view-space normal +z).
    let cam = Camera::perspective(Vec3::new(0.0, 0.0, -3.0), Vec3::ZERO, Vec3::Y, 1.2, 0.1, 10.0, 32, 32).unwrap();
    let shading = Shading { light_dir_view: Vec3::new(0.0, 0.6, 0.8), ambient: 0.1, sky: [0.0, 0.5, 1.0] };
    let r = Renderer::new(&ctx).unwrap();
    let f = r
        .render_frame(&GpuScene::upload(&ctx, &s).unwrap(), &cam, 0.0, &FrameOptions { color: true, shading })
        .unwrap();
    let c = f.color.unwrap();
    let lit = albedo * (0.1 + 0.9 * 0.8);
    let px = *c.get(16, 16);
    // f32 colour targets are exact to rounding; the half-float fallback to ~1e-3.
    let tol = if r.color_format() == zwarp_gpu::render::COLOR_FORMAT { 1e-5 } else { 1e-3 };
    for k in 0..3 {
        assert!((px[k] - lit[k]).abs() < tol, "{px:?} vs {lit}");
    }
    assert_eq!(*c.get(0, 0), [0.0, 0.5, 1.0]);
}

#[test]
fn bad_inputs_are_errors() {
    let Some((r, gs, _)) = setup() else { return };
    let cam = camera_a();
    let e = r.render_layers(&gs, &cam, 0.0, &PeelOptions { layers: 0, ..Default::default() }).unwrap_err();
    assert!(e.to_string().contains("at least one layer"), "{e}");
    assert!(r.render_depth(&gs, &cam, f32::NAN).is_err());
    let empty = Scene::default();
    assert!(GpuScene::upload(r.context(), &empty).is_err());
    let mut bad_mesh = test_scene();
    bad_mesh.instances[2].mesh = 99;
    assert!(GpuScene::upload(r.context(), &bad_mesh).unwrap_err().to_string().contains("mesh 99"));
    let mut short_uv = test_scene();
    short_uv.meshes[0].uvs = Some(vec![glam::Vec2::ZERO; 3]);
    let e = GpuScene::upload(r.context(), &short_uv).unwrap_err().to_string();
    assert_eq!(e, "invalid input: mesh 0: mesh has 3 uvs for 4 vertices (need one per vertex)");
    let mut nan = test_scene();
    nan.instances[1].animation = Animation::Linear { velocity: Vec3::new(f32::NAN, 0.0, 0.0) };
    let gnan = GpuScene::upload(r.context(), &nan).unwrap();
    assert!(r.render_depth(&gnan, &cam, 1.0).unwrap_err().to_string().contains("non-finite"));
    let big = cam.with_size(100_000, 4);
    if let Ok(big) = big {
        assert!(r.render_depth(&gs, &big, 0.0).is_err());
    }
    let target = zwarp_gpu::DepthTarget::new(r.context(), 8, 8).unwrap();
    let mut enc = r.context().device.create_command_encoder(&Default::default());
    assert!(r.encode_depth(&mut enc, &gs, &cam, 0.0, &target).is_err());
    assert!(zwarp_gpu::DepthTarget::new(r.context(), 0, 8).is_err());
    // Layer targets must match the peel (L + ground layer) and the requested outputs.
    let targets = zwarp_gpu::LayerTargets::new(&r, W, H, 2, false).unwrap();
    let peel3 = PeelOptions { layers: 3, ..Default::default() };
    let e = r.encode_layers(&mut enc, &gs, &cam, 0.0, &peel3, &targets).unwrap_err();
    assert!(e.to_string().contains("layer targets hold 2"), "{e}");
    let ground = PeelOptions { layers: 1, ground_separate: true, ..Default::default() };
    assert!(r.encode_layers(&mut enc, &gs, &cam, 0.0, &ground, &targets).is_ok());
    let colour =
        PeelOptions { layers: 2, frame: FrameOptions { color: true, ..Default::default() }, ..Default::default() };
    assert!(r.encode_layers(&mut enc, &gs, &cam, 0.0, &colour, &targets).unwrap_err().to_string().contains("colour"));
    assert!(r.render_layers(&gs, &cam, 0.0, &PeelOptions { layers: 65, ..Default::default() }).is_err());
    assert!(zwarp_gpu::LayerTargets::new(&r, W, H, 0, false).is_err());
    let dark = FrameOptions { color: true, shading: Shading { light_dir_view: Vec3::ZERO, ..Default::default() } };
    assert!(r.render_frame(&gs, &cam, 0.0, &dark).is_err());
    let _ = Image::new(1, 1, 0.0f32);
}

/// Orthographic views (directional-light shadow maps, seed 000 Sec. 6): depth, items, colour
/// and umbra peeling for a range of directions vs zwarp-raster.
#[test]
fn orthographic_view_matches_zwarp_raster() {
    let Some((r, gs, scene)) = setup() else { return };
    let cam = Camera::orthographic(Vec3::new(3.0, -2.0, 6.0), Vec3::new(0.0, 1.0, 0.5), Vec3::Z, 3.2, 0.5, 20.0, W, H)
        .unwrap();
    let cpu = zwarp_raster::render_frame(&scene, &cam, 0.2, &zwarp_raster::FrameOptions { color: true, objects: None })
        .unwrap();
    let gpu = r.render_frame(&gs, &cam, 0.2, &FrameOptions { color: true, ..Default::default() }).unwrap();
    assert!(agreement(&gpu.depth, &cpu.depth, 1e-6) >= 0.999);
    let (cc, gc) = (cpu.color.unwrap(), gpu.color.unwrap());
    let mut same = 0;
    for i in 0..cc.len() {
        if gpu.items.data()[i] == cpu.items.data()[i] {
            same += 1;
            let d = (0..3).map(|k| (cc.data()[i][k] - gc.data()[i][k]).abs()).fold(0.0, f32::max);
            assert!(d < 1e-3, "pixel {i}: {:?} vs {:?}", gc.data()[i], cc.data()[i]);
        }
    }
    assert!(same as f64 >= 0.999 * cc.len() as f64);
    let gl = r
        .render_layers(
            &gs,
            &cam,
            0.2,
            &PeelOptions { layers: 3, umbra: Some(Umbra::Directions { max_angle: 0.1 }), ..Default::default() },
        )
        .unwrap();
    let region = zwarp_raster::ViewRegion::Directions { max_angle: 0.1 };
    let cl = zwarp_raster::render_layers(
        &scene,
        &cam,
        0.2,
        &zwarp_raster::PeelOptions {
            layers: 3,
            ground_separate: false,
            umbra: Some(zwarp_raster::UmbraPeeling { region }),
        },
    )
    .unwrap();
    let bar = if r.context().adapter.backend == "Gl" { 0.99 } else { 0.998 };
    compare_layers(&gl, &cl, bar);
}

/// CPU vs GPU colour on the pixels whose item ids agree (an edge pixel may show another
/// triangle): `(compared pixels, mean |diff| over channels, max |diff|, fraction of pixels
/// with a channel off by more than 1e-3)`.
fn colour_diff(cpu: &zwarp_raster::Frame, gpu: &zwarp_gpu::GpuFrame) -> (usize, f64, f32, f64) {
    let (cc, gc) = (cpu.color.as_ref().unwrap(), gpu.color.as_ref().unwrap());
    let (mut n, mut sum, mut max, mut over) = (0usize, 0.0f64, 0.0f32, 0usize);
    for i in 0..cc.len() {
        if gpu.items.data()[i] != cpu.items.data()[i] {
            continue;
        }
        n += 1;
        let mut worst = 0.0f32;
        for k in 0..3 {
            let d = (cc.data()[i][k] - gc.data()[i][k]).abs();
            sum += d as f64;
            worst = worst.max(d);
        }
        max = max.max(worst);
        over += (worst > 1e-3) as usize;
    }
    (n, sum / (3 * n.max(1)) as f64, max, over as f64 / n.max(1) as f64)
}

/// Textures with every wrap mode and UVs beyond [0, 1], vertex normals, a mesh whose parts
/// (uniform, textured, pattern) share vertices, an animated patterned object.
fn textured_scene() -> Scene {
    let mut next = rng(11);
    let noise = Image::from_fn(16, 16, |_, _| [next(), next(), next(), 1.0]);
    let a = Arc::new(Texture::new(noise.clone(), Wrap::Repeat, Wrap::Repeat).unwrap());
    let b = Arc::new(
        Texture::new(
            Image::from_fn(8, 6, |i, j| [i as f32 / 8.0, j as f32 / 6.0, 0.5, 1.0]),
            Wrap::Clamp,
            Wrap::Mirror,
        )
        .unwrap(),
    );
    let mut s = Scene { name: "textured".into(), ..Default::default() };
    let uv4 = |k: f32, o: f32| {
        vec![glam::Vec2::new(o, o), glam::Vec2::new(o + k, o), glam::Vec2::new(o + k, o + k), glam::Vec2::new(o, o + k)]
    };
    let ground = s
        .add_mesh(quad_mesh().with_uvs(uv4(3.0, 0.0)).unwrap().with_material(Material::textured(Vec3::ONE, a.clone())));
    let card = s.add_mesh(
        quad_mesh().with_uvs(uv4(3.0, -1.0)).unwrap().with_material(Material::textured(Vec3::new(1.0, 0.8, 0.9), b)),
    );
    let sphere = sphere_mesh(12, 20);
    let normals = sphere.positions.clone();
    let sphere =
        s.add_mesh(sphere.with_normals(normals).unwrap().with_material(Material::pattern(Vec3::new(0.9, 0.8, 0.7))));
    let bx = box_mesh();
    let buv = bx.positions.iter().map(|p| glam::Vec2::new(p.x + 0.5, p.y + p.z)).collect();
    let parts = vec![
        MeshPart { first_triangle: 0, material: Material::uniform(Vec3::new(0.9, 0.3, 0.2)) },
        MeshPart { first_triangle: 4, material: Material::textured(Vec3::ONE, a) },
        MeshPart { first_triangle: 8, material: Material::pattern(Vec3::ONE) },
    ];
    let bx = s.add_mesh(bx.with_uvs(buv).unwrap().with_parts(parts).unwrap());
    let g = Mat4::from_translation(Vec3::new(0.13, 1.57, 0.0)) * Mat4::from_scale(Vec3::new(4.1, 4.3, 1.0));
    s.add_instance(ground, g, Vec3::ONE, Animation::Static, true);
    let c = Mat4::from_translation(Vec3::new(-1.3, 2.0, 1.1))
        * Mat4::from_rotation_x(1.2)
        * Mat4::from_scale(Vec3::splat(0.9));
    s.add_instance(card, c, Vec3::ONE, Animation::Static, false);
    let sp = Mat4::from_scale_rotation_translation(
        Vec3::splat(0.7),
        glam::Quat::from_rotation_y(0.5),
        Vec3::new(0.9, 1.2, 0.8),
    );
    s.add_instance(
        sphere,
        sp,
        Vec3::ONE,
        Animation::Spin { center: Vec3::new(0.9, 1.2, 0.8), axis: Vec3::Z, angular_speed: 0.6 },
        false,
    );
    let bm = Mat4::from_scale_rotation_translation(
        Vec3::new(0.9, 0.7, 1.1),
        glam::Quat::from_rotation_z(0.6),
        Vec3::new(-0.4, -0.3, 0.6),
    );
    s.add_instance(bx, bm, Vec3::new(1.0, 0.9, 0.8), Animation::Linear { velocity: Vec3::new(0.2, 0.1, 0.0) }, false);
    s
}

/// The brief's comparison: GPU colour vs zwarp-raster's on the pixels whose ids agree. The
/// two interpolate the same object-space attributes from different barycentrics (hardware
/// from snapped vertices in f32, CPU from unsnapped clip-space vertices in f64) and the WGSL
/// compiler may fuse multiply-adds, so values agree to rounding; the pattern and texture are
/// smooth (continuous, Lipschitz), so rounding stays rounding. Bars: mean |diff| < 2e-5 and
/// 99.9% of compared pixels within 1e-3 on every channel.
#[test]
fn textured_colour_matches_zwarp_raster() {
    let Some(ctx) = test_context() else { return };
    let r = Renderer::new(&ctx).unwrap();
    let scene = textured_scene();
    let gs = GpuScene::upload(&ctx, &scene).unwrap();
    for (cam, t) in [(camera_a(), 0.0), (camera_b(), 0.8)] {
        let cpu =
            zwarp_raster::render_frame(&scene, &cam, t, &zwarp_raster::FrameOptions { color: true, objects: None })
                .unwrap();
        let gpu = r.render_frame(&gs, &cam, t, &FrameOptions { color: true, ..Default::default() }).unwrap();
        let ids: std::collections::HashSet<u32> = cpu.items.data().iter().copied().collect();
        assert!(ids.len() >= 5, "all objects in view: {ids:?}");
        let (n, mean, max, over) = colour_diff(&cpu, &gpu);
        eprintln!(
            "textured scene t={t}: {n} px compared, mean |diff| {mean:.2e}, max {max:.2e}, >1e-3 on {:.4}%",
            over * 100.0
        );
        assert!(n as f64 >= 0.995 * cpu.items.len() as f64, "ids agree on only {n} px");
        let half = r.color_format() != zwarp_gpu::render::COLOR_FORMAT;
        assert!(mean < if half { 5e-4 } else { 2e-5 }, "mean {mean}");
        assert!(half || over <= 1e-3, "{over}");
    }
}

/// The procedural scenes (pattern only, many objects, instance tints, animation) on their
/// paths: the same bars as the textured scene.
#[test]
fn procedural_scene_colour_matches_zwarp_raster() {
    let Some(ctx) = test_context() else { return };
    let r = Renderer::new(&ctx).unwrap();
    for name in ["yr", "mo", "bl", "cb"] {
        let opts =
            zwarp_scene::SceneOptions { seed: 3, scale: if name == "yr" { 0.05 } else { 0.02 }, ..Default::default() };
        let loaded = zwarp_scene::load_scene(name, &opts).unwrap();
        let (scene, path) = (&loaded.scene, loaded.path_or_default());
        let t = path.start() + 0.4 * path.duration();
        let cam = path.camera_at(t, W, H).unwrap();
        let gs = GpuScene::upload(&ctx, scene).unwrap();
        let cpu =
            zwarp_raster::render_frame(scene, &cam, t, &zwarp_raster::FrameOptions { color: true, objects: None })
                .unwrap();
        let gpu = r.render_frame(&gs, &cam, t, &FrameOptions { color: true, ..Default::default() }).unwrap();
        let (n, mean, max, over) = colour_diff(&cpu, &gpu);
        eprintln!("{name}: {n} px compared, mean |diff| {mean:.2e}, max {max:.2e}, >1e-3 on {:.4}%", over * 100.0);
        assert!(n as f64 >= 0.99 * cpu.items.len() as f64, "{name}: ids agree on only {n} px");
        let half = r.color_format() != zwarp_gpu::render::COLOR_FORMAT;
        assert!(mean < if half { 5e-4 } else { 2e-5 }, "{name}: mean {mean}");
        assert!(half || over <= 1e-3, "{name}: {over}");
    }
}

/// A camera-facing textured quad on the GPU: every pixel shows its texel (the GPU twin of
/// zwarp-raster's analytic texture test; also checks the texture is not flipped).
#[test]
fn gpu_texels_land_on_their_pixels() {
    let Some(ctx) = test_context() else { return };
    let (w, h) = (12u32, 8u32);
    let img = Image::from_fn(w, h, |i, j| [i as f32 / 16.0, j as f32 / 8.0, 0.25 + ((i + j) % 3) as f32 * 0.25, 1.0]);
    let tex = Arc::new(Texture::new(img.clone(), Wrap::Repeat, Wrap::Repeat).unwrap());
    let quad = zwarp_core::Mesh::new(
        vec![
            Vec3::new(-6.0, -4.0, 0.0),
            Vec3::new(6.0, -4.0, 0.0),
            Vec3::new(6.0, 4.0, 0.0),
            Vec3::new(-6.0, 4.0, 0.0),
        ],
        vec![[0, 1, 2], [0, 2, 3]],
    )
    .unwrap()
    .with_uvs(vec![glam::Vec2::new(0.0, 1.0), glam::Vec2::new(1.0, 1.0), glam::Vec2::new(1.0, 0.0), glam::Vec2::ZERO])
    .unwrap()
    .with_material(Material::textured(Vec3::ONE, tex));
    let mut s = Scene::default();
    let q = s.add_mesh(quad);
    s.add_instance(q, Mat4::IDENTITY, Vec3::ONE, Animation::Static, false);
    let cam = Camera::orthographic(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, Vec3::Y, 4.0, 1.0, 100.0, w, h).unwrap();
    let r = Renderer::new(&ctx).unwrap();
    let f = r
        .render_frame(
            &GpuScene::upload(&ctx, &s).unwrap(),
            &cam,
            0.0,
            &FrameOptions { color: true, ..Default::default() },
        )
        .unwrap();
    let c = f.color.unwrap();
    let l = zwarp_raster::shading::LIGHT_DIR_VIEW.normalize();
    let k = zwarp_raster::shading::AMBIENT + (1.0 - zwarp_raster::shading::AMBIENT) * l.z;
    let tol = if r.color_format() == zwarp_gpu::render::COLOR_FORMAT { 1e-5 } else { 1e-3 };
    for y in 0..h {
        for x in 0..w {
            let t = img.get(x, y);
            let got = c.get(x, y);
            for ch in 0..3 {
                assert!((got[ch] - t[ch] * k).abs() < tol, "({x},{y}): {got:?} vs {t:?} * {k}");
            }
        }
    }
}
