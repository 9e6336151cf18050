//! Analytic and cross-checking tests of the soft-shadow pipeline.

use glam::{Mat4, Vec2, Vec3};
use proptest::prelude::*;
use zwarp_core::{Animation, AreaLight, Camera, Image, LightShape, Mesh, Scene};
use zwarp_raster::scenes::box_mesh;

use super::*;

/// A horizontal quad `[x0, x1] x [y0, y1]` at height `z`.
fn quad(x0: f32, x1: f32, y0: f32, y1: f32, z: f32) -> Mesh {
    Mesh::new(
        vec![Vec3::new(x0, y0, z), Vec3::new(x1, y0, z), Vec3::new(x1, y1, z), Vec3::new(x0, y1, z)],
        vec![[0, 1, 2], [0, 2, 3]],
    )
    .unwrap()
}

fn add(scene: &mut Scene, mesh: Mesh, albedo: Vec3, ground: bool) {
    let m = scene.add_mesh(mesh);
    scene.add_instance(m, Mat4::IDENTITY, albedo, Animation::Static, ground);
}

/// Ground 16 x 16 at z = 0 and (optionally) a 4 x 4 square occluder at z = 5 centred on the origin.
fn square_over_plane(occluder: bool) -> Scene {
    let mut s = Scene { name: "square".into(), ..Scene::default() };
    add(&mut s, quad(-8.0, 8.0, -8.0, 8.0, 0.0), Vec3::splat(0.8), true);
    if occluder {
        add(&mut s, quad(-2.0, 2.0, -2.0, 2.0, 5.0), Vec3::new(0.8, 0.2, 0.2), false);
    }
    s
}

/// Orthographic camera looking straight down on a strip `|x| <= 6`, 0.05 units per pixel,
/// 16 rows around y = 0.
fn strip_camera() -> Camera {
    Camera::orthographic(Vec3::new(0.0, 0.0, 20.0), Vec3::ZERO, Vec3::Y, 0.4, 1.0, 40.0, 240, 16).unwrap()
}

fn disc_light(center: Vec3, radius: f32, directional: bool) -> AreaLight {
    AreaLight { center, target: Vec3::ZERO, up: Vec3::Y, shape: LightShape::Disc { radius }, directional }
}

/// Penumbra on row `y` for `x > x_min` (world): (last x with V = 0, first x after which V = 1).
fn penumbra_extent(v: &Image<f32>, cam: &Camera, y: u32, x_min: f32) -> (f32, f32) {
    let px = 2.0 * 6.0 / cam.width as f32;
    let xw = |i: u32| -6.0 + (i as f32 + 0.5) * px;
    let row = v.row(y);
    let mut umbra_end = f32::NAN;
    let mut lit_start = f32::NAN;
    for (i, &vis) in row.iter().enumerate() {
        let x = xw(i as u32);
        if x <= x_min {
            continue;
        }
        if vis <= 0.0 {
            umbra_end = x;
        }
    }
    for (i, &vis) in row.iter().enumerate().rev() {
        let x = xw(i as u32);
        if x <= x_min {
            break;
        }
        if vis < 1.0 {
            break;
        }
        lit_start = x;
    }
    (umbra_end, lit_start)
}

fn params(samples: u32, sm: u32) -> ShadowParams {
    ShadowParams { samples, sm_size: sm, jitter: false, ..ShadowParams::default() }
}

#[test]
fn penumbra_width_matches_similar_triangles_for_a_local_disc_light() {
    // Disc of diameter D = 2 at height 10, occluder edge at height 5 (x = 2), receiver at 0:
    // w = D (d_r - d_o) / d_o = 2 (10 - 5) / 5 = 2, centred on the edge's projection x = 4.
    let scene = square_over_plane(true);
    let cam = strip_camera();
    let light = disc_light(Vec3::new(0.0, 0.0, 10.0), 1.0, false);
    let r = run_shadows(&scene, &cam, 0.0, &light, Method::Reference, &params(1024, 512)).unwrap();
    let (a, b) = penumbra_extent(&r.visibility, &cam, 8, 2.2);
    let px = 0.05;
    // The penumbra pixels lie strictly between a and b: width = b - a - px.
    let w = b - a - px;
    assert!((w - 2.0).abs() <= 2.0 * px, "penumbra [{a}, {b}] width {w}, expected 2");
    assert!(((a + b) * 0.5 - 4.0).abs() <= 1.5 * px, "penumbra centre {} expected 4", (a + b) * 0.5);
    // Zwarp at the same S reproduces the reference profile.
    let z = run_shadows(&scene, &cam, 0.0, &light, Method::Zwarp, &params(64, 512)).unwrap();
    let rr = run_shadows(&scene, &cam, 0.0, &light, Method::Reference, &params(64, 512)).unwrap();
    let diffs: Vec<f32> = z.visibility.data().iter().zip(rr.visibility.data()).map(|(a, b)| (a - b).abs()).collect();
    let max_diff = diffs.iter().copied().fold(0.0, f32::max);
    let mean = diffs.iter().sum::<f32>() / diffs.len() as f32;
    let (za, zb) = penumbra_extent(&z.visibility, &cam, 8, 2.2);
    let (ra, rb) = penumbra_extent(&rr.visibility, &cam, 8, 2.2);
    eprintln!("zwarp vs reference: max {max_diff} mean {mean}, penumbra [{za}, {zb}] vs [{ra}, {rb}]");
    // The warp moves texel-sized source squares, so a silhouette may shift by up to a texel
    // (seed 000, Sec. 7: "limited in sub-pixel accuracy"): a few samples per pixel, on average
    // well under one.
    assert!(
        max_diff <= 7.0 / 64.0 + 1e-6 && mean < 3.0 / 256.0,
        "zwarp vs reference visibility: max {max_diff} mean {mean}"
    );
    assert!((za - ra).abs() <= px + 1e-4 && (zb - rb).abs() <= px + 1e-4);
}

#[test]
fn penumbra_width_of_a_directional_disc_light() {
    // Sun-like disc of angular radius 0.1 (R = 10 at D = |(30, 0, 100)|), tilted in x. The edge
    // (x = 2, z = 5) casts rays along the extreme directions d = (target - center) -+ R right.
    let scene = square_over_plane(true);
    let cam = strip_camera();
    let center = Vec3::new(-30.0, 0.0, 100.0);
    let light = disc_light(center, 10.0, true);
    let axis = (-center).normalize();
    let right = axis.cross(Vec3::Y).normalize();
    let hit = |o: f32| {
        let d = -center - right * o;
        2.0 + d.x / d.z * (0.0 - 5.0)
    };
    let (x1, x2) = (hit(10.0).min(hit(-10.0)), hit(10.0).max(hit(-10.0)));
    let r = run_shadows(&scene, &cam, 0.0, &light, Method::Reference, &params(1024, 512)).unwrap();
    let (a, b) = penumbra_extent(&r.visibility, &cam, 8, 2.2);
    let px = 0.05;
    let w = b - a - px;
    assert!(((x2 - x1) - w).abs() <= 2.0 * px, "penumbra [{a}, {b}] width {w}, expected [{x1}, {x2}]");
    assert!(((a + b) - (x1 + x2)).abs() * 0.5 <= 1.5 * px);
}

#[test]
fn one_centre_sample_is_the_hard_shadow() {
    let scene = square_over_plane(true);
    let cam = strip_camera();
    // Rect light: S = 1 must be its centre whatever the jitter.
    let light = AreaLight {
        center: Vec3::new(0.5, 0.3, 10.0),
        target: Vec3::new(0.5, 0.3, 0.0),
        up: Vec3::Y,
        shape: LightShape::Rect { width: 3.0, height: 1.0 },
        directional: false,
    };
    let p = ShadowParams { samples: 1, sm_size: 1024, jitter: true, ..ShadowParams::default() };
    let r = run_shadows(&scene, &cam, 0.0, &light, Method::Reference, &p).unwrap();
    let z = run_shadows(&scene, &cam, 0.0, &light, Method::Zwarp, &p).unwrap();
    // Zero parallax: the warp is the identity, the maps and so the images are identical.
    assert_eq!(r.visibility, z.visibility);
    assert_eq!(r.image, z.image);
    // Analytic hard shadow from the point (0.5, 0.3, 10): ground point (x, y) is shadowed iff the
    // segment to the light crosses z = 5 inside the square, i.e. (x + 0.5) / 2 in [-2, 2] (same in y).
    let texel = 0.05; // ground-texel footprint of a 1024 map covering ~18 units is ~0.02; be generous
    let mut checked = 0;
    for y in 0..cam.height {
        for x in 0..cam.width {
            let w = cam.unproject(x as f32 + 0.5, y as f32 + 0.5, 0.5);
            let mx = (w.x + 0.5) * 0.5;
            let my = (w.y + 0.3) * 0.5;
            // Pixels seeing the occluder itself are lit (nothing above it).
            if w.x.abs() <= 2.0 && w.y.abs() <= 2.0 {
                continue;
            }
            let dist = (mx.abs() - 2.0).abs().min((my.abs() - 2.0).abs());
            if dist < texel {
                continue;
            }
            let shadowed = mx.abs() <= 2.0 && my.abs() <= 2.0;
            let v = *r.visibility.get(x, y);
            assert_eq!(v, if shadowed { 0.0 } else { 1.0 }, "pixel ({x}, {y}) world {w:?}");
            checked += 1;
        }
    }
    assert!(checked > 2000, "{checked}");
}

#[test]
fn scene_without_occluder_is_fully_lit_by_every_method() {
    // A bent sheet (flat ground for x <= 2, rising with slope 0.6 beyond) lit from the flat side:
    // a concave height field, nothing can shadow it; no acne with the default bias.
    let mut scene = Scene { name: "sheet".into(), ..Scene::default() };
    add(&mut scene, quad(-8.0, 2.0, -8.0, 8.0, 0.0), Vec3::splat(0.8), true);
    let tilted = Mesh::new(
        vec![Vec3::new(2.0, -8.0, 0.0), Vec3::new(6.0, -8.0, 2.4), Vec3::new(6.0, 8.0, 2.4), Vec3::new(2.0, 8.0, 0.0)],
        vec![[0, 1, 2], [0, 2, 3]],
    )
    .unwrap();
    add(&mut scene, tilted, Vec3::splat(0.5), false);
    let cam =
        Camera::perspective(Vec3::new(-6.0, -9.0, 9.0), Vec3::new(1.0, 0.0, 0.0), Vec3::Z, 0.9, 0.5, 60.0, 96, 64)
            .unwrap();
    let light = disc_light(Vec3::new(-3.0, 2.0, 12.0), 1.0, false);
    for method in [Method::Reference, Method::Zwarp, Method::Pcss] {
        for sm in [256, 1024] {
            let r = run_shadows(&scene, &cam, 0.0, &light, method, &params(16, sm)).unwrap();
            let dark = r.visibility.data().iter().filter(|&&v| v < 1.0).count();
            assert_eq!(dark, 0, "{method:?} sm {sm}: {dark} pixels not fully lit");
        }
    }
}

/// Three boxes on a ground, seen obliquely.
fn boxes_scene() -> (Scene, Camera, AreaLight) {
    let mut s = Scene { name: "boxes".into(), ..Scene::default() };
    add(&mut s, quad(-10.0, 10.0, -10.0, 10.0, 0.0), Vec3::new(0.7, 0.7, 0.6), true);
    add(&mut s, box_mesh(Vec3::new(-3.0, -1.0, 0.0), Vec3::new(-1.0, 1.0, 3.0)), Vec3::new(0.8, 0.3, 0.2), false);
    add(&mut s, box_mesh(Vec3::new(1.0, -2.0, 0.0), Vec3::new(2.0, 2.0, 1.5)), Vec3::new(0.2, 0.6, 0.8), false);
    add(&mut s, box_mesh(Vec3::new(0.5, 2.5, 2.0), Vec3::new(2.5, 4.0, 2.5)), Vec3::new(0.3, 0.8, 0.3), false);
    let cam =
        Camera::perspective(Vec3::new(2.0, -14.0, 9.0), Vec3::new(0.0, 0.5, 0.5), Vec3::Z, 0.8, 0.5, 60.0, 128, 96)
            .unwrap();
    let light = disc_light(Vec3::new(-6.0, 3.0, 14.0), 1.5, false);
    (s, cam, light)
}

#[test]
fn zwarp_matches_the_reference_on_a_simple_scene_and_beats_pcss() {
    let (scene, cam, light) = boxes_scene();
    let p = ShadowParams { samples: 16, sm_size: 512, ..ShadowParams::default() };
    let r = run_shadows(&scene, &cam, 0.0, &light, Method::Reference, &p).unwrap();
    let z = run_shadows(&scene, &cam, 0.0, &light, Method::Zwarp, &p).unwrap();
    let c = run_shadows(&scene, &cam, 0.0, &light, Method::Pcss, &p).unwrap();
    let sz = zwarp_metrics::ssim_rgb(&z.image, &r.image, 1.0).unwrap();
    let sc = zwarp_metrics::ssim_rgb(&c.image, &r.image, 1.0).unwrap();
    let pz = zwarp_metrics::psnr_rgb(&z.image, &r.image, 1.0).unwrap();
    let pc = zwarp_metrics::psnr_rgb(&c.image, &r.image, 1.0).unwrap();
    assert!(sz > 0.99, "zwarp SSIM {sz}");
    assert!(sz > sc && pz > pc, "zwarp {sz}/{pz} dB vs pcss {sc}/{pc} dB");
    // Shadows exist at all (the test is not vacuous).
    let shadowed = r.visibility.data().iter().filter(|&&v| v < 0.5).count();
    assert!(shadowed > 500, "{shadowed}");
}

#[test]
fn directional_rect_light_zwarp_matches_reference() {
    let (scene, cam, _) = boxes_scene();
    let light = AreaLight {
        center: Vec3::new(-40.0, 20.0, 80.0),
        target: Vec3::ZERO,
        up: Vec3::Z,
        shape: LightShape::Rect { width: 6.0, height: 3.0 },
        directional: true,
    };
    let p = ShadowParams { samples: 16, sm_size: 512, ..ShadowParams::default() };
    let r = run_shadows(&scene, &cam, 0.0, &light, Method::Reference, &p).unwrap();
    let z = run_shadows(&scene, &cam, 0.0, &light, Method::Zwarp, &p).unwrap();
    let sz = zwarp_metrics::ssim_rgb(&z.image, &r.image, 1.0).unwrap();
    assert!(sz > 0.99, "zwarp SSIM {sz}");
}

#[test]
fn default_light_is_above_and_aside() {
    let (scene, _, _) = boxes_scene();
    let l = default_light(&scene).unwrap();
    validate_light(&l).unwrap();
    let b = scene.bounds();
    assert!(l.center.z > b.max.z + b.extent().length() * 0.9, "{l:?}");
    assert!(Vec2::new(l.center.x - b.center().x, l.center.y - b.center().y).length() > 1.0);
    assert!(matches!(l.shape, LightShape::Disc { radius } if radius > 0.0));
    assert!(!l.directional);
    assert!(default_light(&Scene::default()).is_err());
    // It lights the scene without errors, with visible shadows.
    let cam = boxes_scene().1;
    let r = run_shadows(&scene, &cam, 0.0, &l, Method::Reference, &params(4, 256)).unwrap();
    assert!(r.visibility.data().iter().any(|&v| v < 1.0));
}

#[test]
fn bad_inputs_are_errors_not_panics() {
    let (scene, cam, light) = boxes_scene();
    let bad = |p: ShadowParams| run_shadows(&scene, &cam, 0.0, &light, Method::Zwarp, &p).is_err();
    assert!(bad(ShadowParams { samples: 0, ..ShadowParams::default() }));
    assert!(bad(ShadowParams { sm_size: 0, ..ShadowParams::default() }));
    assert!(bad(ShadowParams { layers: 0, ..ShadowParams::default() }));
    assert!(bad(ShadowParams { n_seeds: 0, ..ShadowParams::default() }));
    assert!(bad(ShadowParams { ambient: 2.0, ..ShadowParams::default() }));
    assert!(bad(ShadowParams { bias: DepthBias { constant: -1.0, slope: 0.0 }, ..ShadowParams::default() }));
    assert!(run_shadows(&scene, &cam, f32::NAN, &light, Method::Reference, &params(4, 64)).is_err());
    assert!(run_shadows(&Scene::default(), &cam, 0.0, &light, Method::Reference, &params(4, 64)).is_err());
    // A local light inside the scene bounds cannot be covered by one perspective map.
    let inside = disc_light(Vec3::new(0.0, 0.0, 1.0), 0.5, false);
    let e = run_shadows(&scene, &cam, 0.0, &inside, Method::Reference, &params(4, 64)).unwrap_err();
    assert!(e.to_string().contains("not in front"), "{e}");
    assert!("nope".parse::<Method>().is_err());
    assert_eq!("ZWARP".parse::<Method>().unwrap(), Method::Zwarp);
    // Receivers need a frame of the camera's size.
    let rig = LightRig::new(&scene, 0.0, &light, 4, 64, 1, true).unwrap();
    let frame = zwarp_raster::render_frame(&scene, &cam, 0.0, &Default::default()).unwrap();
    let small = cam.with_size(8, 8).unwrap();
    assert!(Receivers::build(&frame, &small, &scene, &rig, &DepthBias::default()).is_err());
    let recv = Receivers::build(&frame, &cam, &scene, &rig, &DepthBias::default()).unwrap();
    assert!(recv.shade(&Image::new(3, 3, 1.0), 0.25).is_err());
    assert!(pcss_visibility(&recv, &rig, &Image::new(3, 3, 1.0), &PcssParams::default()).is_err());
    assert!(rig.parallax_field(&Image::new(3, 3, 0.5), Vec2::ONE).is_err());
    assert!(rig.parallax_field(&Image::new(64, 64, f32::NAN), Vec2::ONE).is_err());
    assert!(rig.parallax_field(&Image::new(64, 64, 0.5), Vec2::splat(f32::NAN)).is_err());
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    /// The visibility pass's two multiply-adds `p_c + K_i g` equal a full projection with the
    /// sample cameras the maps are rendered with (local and directional lights).
    #[test]
    fn sample_shift_equals_projection(
        px in -4.0f32..4.0, py in -4.0f32..4.0, pz in 0.0f32..3.0, directional in any::<bool>(), i in 0usize..16,
    ) {
        let (scene, _, _) = boxes_scene();
        let light = AreaLight {
            center: Vec3::new(-6.0, 3.0, 14.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            shape: LightShape::Rect { width: 3.0, height: 2.0 },
            directional,
        };
        let rig = LightRig::new(&scene, 0.0, &light, 16, 512, 3, true).unwrap();
        let p = Vec3::new(px, py, pz);
        let c = rig.center.project(p).unwrap();
        let z = -(rig.center.view * p.extend(1.0)).z;
        let s = rig.cameras[i].project(p).unwrap();
        let pred = Vec2::new(c.x, c.y) + rig.shifts[i] * rig.depth_param(z);
        prop_assert!((pred - Vec2::new(s.x, s.y)).length() < 2e-2, "{:?} vs {:?}", pred, s);
        // Same view depth in every sample map.
        prop_assert!((s.z - c.z).abs() < 1e-5);
        // And the point is inside every map (the rig covers the bounds from every sample).
        prop_assert!(s.x >= 0.0 && s.y >= 0.0 && s.x <= 512.0 && s.y <= 512.0);
    }
}

#[test]
fn parallax_motion_equals_motion_field() {
    for directional in [false, true] {
        let (scene, _, mut light) = boxes_scene();
        light.directional = directional;
        let rig = LightRig::new(&scene, 0.0, &light, 16, 128, 2, true).unwrap();
        let fast = ZwarpMaps::new(&scene, &rig, 0.0, &ShadowParams::default()).unwrap();
        let slow =
            ZwarpMaps::new(&scene, &rig, 0.0, &ShadowParams { parallax_motion: false, ..ShadowParams::default() })
                .unwrap();
        for i in [0, 7, 15] {
            let (a, b) = (fast.motions(i).unwrap(), slow.motions(i).unwrap());
            assert_eq!(a.len(), b.len());
            for (layer, (ma, mb)) in a.iter().zip(&b).enumerate() {
                for (k, (x, y)) in ma.data().iter().zip(mb.data()).enumerate() {
                    if layer_valid(fast.layers(), layer, k) {
                        assert!((x.v - y.v).length() < 1e-3, "layer {layer} texel {k}: {:?} vs {:?}", x, y);
                        assert!((x.depth - y.depth).abs() < 1e-5);
                    }
                }
            }
        }
    }
}

fn layer_valid(layers: &[zwarp_raster::Layer], layer: usize, k: usize) -> bool {
    layers[layer].depth.data()[k] < 1.0
}

/// Task of the lazy synthesis (`lookups`): per sample, the sparse map equals the full warped
/// map at every texel a receiver reads, bit for bit (states too, dilated holes included), so
/// the visibility — the lit counts — is exactly that of the full maps. Local and directional
/// lights; with a starved search (N = 1, T = 1) the sample maps have cracks the dilation fills.
#[test]
fn lazy_visibility_equals_full_map_visibility_exactly() {
    let mut filled_seen = 0usize;
    let cases = [(false, false, true), (true, false, true), (false, true, true), (false, true, false)];
    for (directional, starved, shared_mipmap) in cases {
        let (scene, cam, mut light) = boxes_scene();
        light.directional = directional;
        let p = ShadowParams { samples: 16, sm_size: 192, shared_mipmap, ..ShadowParams::default() };
        let p = if starved { ShadowParams { n_seeds: 1, iterations: 1, ..p } } else { p };
        let rig = LightRig::new(&scene, 0.0, &light, p.samples, p.sm_size, p.seed, p.jitter).unwrap();
        let frame = zwarp_raster::render_frame(&scene, &cam, 0.0, &Default::default()).unwrap();
        let recv = Receivers::build(&frame, &cam, &scene, &rig, &p.bias).unwrap();
        let mut maps = ZwarpMaps::new(&scene, &rig, 0.0, &p).unwrap();
        let mut sparse = SparseMap::new(p.sm_size, p.sm_size);
        let (mut lit_full, mut lit_lazy) = (vec![0u32; recv.list.len()], vec![0u32; recv.list.len()]);
        let mut lit_kept = vec![0u32; recv.list.len()];
        let hot = HotReceivers::new(&recv);
        let mut looked_up = 0usize;
        for i in 0..rig.samples() {
            let full = maps.map(i).unwrap();
            let n = sparse.collect(&hot, rig.shifts[i]);
            assert!(n > 0 && n < (p.sm_size * p.sm_size) as usize);
            looked_up += n;
            maps.warp_sparse(i, &mut sparse).unwrap();
            for &t in sparse.texels() {
                assert_eq!(sparse.depth_at(t).to_bits(), full.depth.data()[t as usize].to_bits());
                assert_eq!(sparse.state(t), full.state.data()[t as usize], "sample {i} texel {t}");
                filled_seen += (sparse.state(t) == zwarp_warp::PixelState::Filled) as usize;
            }
            recv.accumulate(&full.depth, rig.shifts[i], &mut lit_full);
            // The sparse map as a full image (stale texels never read) through the plain pass.
            let mut img = Image::new(p.sm_size, p.sm_size, 0.5f32);
            for &t in sparse.texels() {
                img.data_mut()[t as usize] = sparse.depth_at(t);
            }
            recv.accumulate(&img, rig.shifts[i], &mut lit_lazy);
            sparse.accumulate(&hot, &mut lit_kept);
        }
        assert_eq!(lit_full, lit_lazy);
        assert_eq!(lit_full, lit_kept);
        assert!(lit_full.iter().any(|&l| l > 0 && l < 16), "no penumbra: the test would be vacuous");
        eprintln!("directional {directional}: {looked_up} texels looked up over 16 samples");
        // run_shadows (samples warped in parallel groups with the shared mipmap) gives the
        // visibility of these full maps.
        let a = run_shadows(&scene, &cam, 0.0, &light, Method::Zwarp, &p).unwrap();
        assert_eq!(a.visibility, recv.visibility_image(&lit_full, 16));
        // Receivers tested in groups (ReceiverGroups) or one by one: the same visibility.
        for grouping in [Grouping::Always, Grouping::Never] {
            let a = run_shadows(&scene, &cam, 0.0, &light, Method::Zwarp, &ShadowParams { grouping, ..p }).unwrap();
            assert_eq!(a.visibility, recv.visibility_image(&lit_full, 16), "{grouping:?}");
        }
        if !shared_mipmap {
            // run_shadows gives the same visibility through both methods (ZwarpFull always
            // uses per-sample mipmaps).
            let a = run_shadows(&scene, &cam, 0.0, &light, Method::Zwarp, &p).unwrap();
            let b = run_shadows(&scene, &cam, 0.0, &light, Method::ZwarpFull, &p).unwrap();
            assert_eq!(a.visibility, b.visibility);
            assert_eq!(a.image, b.image);
        }
    }
    assert!(filled_seen > 0, "no dilated hole among the looked-up texels: the dilation path is untested");
}

/// One motion mipmap for all samples: warping the reference field's prepared layers with
/// `motion_scale = K_i / K_ref` equals warping each sample's explicitly scaled motion buffers
/// with their own axis-aligned mipmaps, bit for bit at every looked-up texel (local and
/// directional lights, samples with negative and mixed-sign scales).
#[test]
fn shared_mipmap_equals_per_sample_scaled_mipmaps() {
    for directional in [false, true] {
        let (scene, cam, mut light) = boxes_scene();
        light.directional = directional;
        let p = ShadowParams { samples: 16, sm_size: 160, ..ShadowParams::default() };
        let rig = LightRig::new(&scene, 0.0, &light, p.samples, p.sm_size, p.seed, p.jitter).unwrap();
        let frame = zwarp_raster::render_frame(&scene, &cam, 0.0, &Default::default()).unwrap();
        let recv = Receivers::build(&frame, &cam, &scene, &rig, &p.bias).unwrap();
        let mut maps = ZwarpMaps::new(&scene, &rig, 0.0, &p).unwrap();
        assert!(maps.shares_mipmap());
        let mut sparse = SparseMap::new(p.sm_size, p.sm_size);
        let mut signs = std::collections::HashSet::new();
        for i in 0..rig.samples() {
            let sp = maps.sample_params(i).unwrap();
            signs.insert((sp.motion_scale.x < 0.0, sp.motion_scale.y < 0.0));
            sparse.collect(&HotReceivers::new(&recv), rig.shifts[i]);
            maps.warp_sparse(i, &mut sparse).unwrap();
            // The per-sample path: scaled buffers, own AAB mipmaps, unit scale.
            let motions = maps.motions(i).unwrap();
            let own: Vec<PreparedLayer> = maps
                .layers()
                .iter()
                .zip(&motions)
                .map(|(l, m)| {
                    let layer = WarpLayer { depth: &l.depth, motion: m };
                    PreparedLayer::new_for(&layer, BoundKind::Tight, MotionScales::Any).unwrap()
                })
                .collect();
            let wp = WarpParams { bound: BoundKind::Tight, ..p.warp_params() };
            let full = warp_prepared(&own, &wp).unwrap();
            for &t in sparse.texels() {
                assert_eq!(
                    sparse.depth_at(t).to_bits(),
                    full.depth.data()[t as usize].to_bits(),
                    "directional {directional} sample {i} texel {t}"
                );
                assert_eq!(sparse.state(t), full.state.data()[t as usize]);
            }
        }
        assert!(signs.len() >= 3, "the samples do not exercise mixed-sign scales: {signs:?}");
    }
}

#[test]
fn the_ground_layer_rule_follows_the_kept_ground_layer() {
    // Boxes on a ground, L = 3: two object layers and the ground peeled alone, last.
    let (scene, _, light) = boxes_scene();
    let p = ShadowParams { samples: 4, sm_size: 128, ..ShadowParams::default() };
    let rig = LightRig::new(&scene, 0.0, &light, p.samples, p.sm_size, p.seed, p.jitter).unwrap();
    let maps = ZwarpMaps::new(&scene, &rig, 0.0, &p).unwrap();
    let ground = maps.layers().last().unwrap();
    assert!(ground.items.data().iter().all(|&i| i == 0 || i == zwarp_core::NO_ITEM), "the ground alone is last");
    assert!(maps.layers().len() > 1 && maps.sample_params(0).unwrap().ground_layer);
    // One layer (no separate ground), or the ground alone (nothing in front of it): no rule.
    let one = ZwarpMaps::new(&scene, &rig, 0.0, &ShadowParams { layers: 1, ..p }).unwrap();
    assert!(!one.sample_params(0).unwrap().ground_layer);
    let bare = square_over_plane(false);
    let rig = LightRig::new(&bare, 0.0, &light, p.samples, p.sm_size, p.seed, p.jitter).unwrap();
    let alone = ZwarpMaps::new(&bare, &rig, 0.0, &p).unwrap();
    assert_eq!(alone.layers().len(), 1);
    assert!(!alone.sample_params(0).unwrap().ground_layer);
}

#[test]
fn a_light_in_file_coordinates_moves_with_its_scene() {
    let origin = glam::DVec3::new(690_000.0, 0.0, 5_334_000.0);
    let json = r#"{"center": [690003.37, 12.5, 5334001.25], "target": [690000.0, 0, 5334000.0], "up": [0, 0, 1],
                   "shape": {"kind": "disc", "radius": 0.5}}"#;
    let l = light_from_json_str_at(json, origin).unwrap();
    // f64 before f32: 690003.37 in f32 would be 690003.375.
    assert_eq!((l.center, l.target), (Vec3::new(3.37, 12.5, 1.25), Vec3::ZERO));
    assert_eq!(light_from_json_str(json).unwrap().center.x, 690_003.37f64 as f32, "read as f32 first: .375");
    let e = light_from_json_str_at(r#"{"center": "x"}"#, origin).unwrap_err().to_string();
    assert!(e.contains("bad light JSON") && !e.contains('\n'), "{e}");
}
