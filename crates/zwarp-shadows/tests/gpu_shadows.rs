//! GPU soft shadows (seed 000, Sec. 6) against the CPU method of `zwarp_shadows`: the
//! accumulate kernel exactly, the parallax kernel to rounding, the reference and zwarp lit
//! counts per receiver on a few boxes over a plane, and the error paths.

use glam::{Mat4, Vec2, Vec3};
use zwarp_core::{Animation, Camera, Error, Image, Mesh, Scene};
use zwarp_gpu::{test_context, GpuScene};
use zwarp_raster::scenes::box_mesh;
use zwarp_raster::{render_frame, FrameOptions};
use zwarp_shadows::gpu::{gpu_peel_options, reference_shift, run_shadows_gpu, sample_warp_params, GpuShadows};
use zwarp_shadows::{
    default_light, peel_options, render_sample_map, run_shadows, LightRig, Method, Receiver, Receivers, ShadowParams,
    ZwarpMaps,
};
use zwarp_warp::gpu::{GpuWarpLayer, WarpKernel};
use zwarp_warp::{MotionScales, WarpLayer};

const W: u32 = 128;
const H: u32 = 96;
const SM: u32 = 128;

fn add(scene: &mut Scene, mesh: Mesh, albedo: Vec3, ground: bool) {
    let m = scene.add_mesh(mesh);
    scene.add_instance(m, Mat4::IDENTITY, albedo, Animation::Static, ground);
}

/// A 16 x 16 ground at z = 0 and three boxes of different heights (one floating) over it.
fn boxes_over_plane() -> Scene {
    let mut s = Scene { name: "boxes".into(), up: Vec3::Z, ..Scene::default() };
    let ground = Mesh::new(
        vec![
            Vec3::new(-8.0, -8.0, 0.0),
            Vec3::new(8.0, -8.0, 0.0),
            Vec3::new(8.0, 8.0, 0.0),
            Vec3::new(-8.0, 8.0, 0.0),
        ],
        vec![[0, 1, 2], [0, 2, 3]],
    )
    .unwrap();
    add(&mut s, ground, Vec3::splat(0.8), true);
    add(&mut s, box_mesh(Vec3::new(-3.0, -2.0, 0.0), Vec3::new(-1.0, 0.0, 3.0)), Vec3::new(0.8, 0.2, 0.2), false);
    add(&mut s, box_mesh(Vec3::new(1.0, 1.0, 1.5), Vec3::new(3.0, 2.0, 2.5)), Vec3::new(0.2, 0.8, 0.2), false);
    add(&mut s, box_mesh(Vec3::new(0.5, -4.0, 0.0), Vec3::new(1.5, -3.0, 1.0)), Vec3::new(0.2, 0.2, 0.8), false);
    s
}

fn camera() -> Camera {
    Camera::perspective(Vec3::new(0.0, -9.0, 8.0), Vec3::new(0.0, 0.0, 0.5), Vec3::Z, 0.9, 0.5, 60.0, W, H).unwrap()
}

fn params(samples: u32) -> ShadowParams {
    ShadowParams { samples, sm_size: SM, ..ShadowParams::default() }
}

/// Scene, rig and the CPU receivers (the one receiver construction both backends share).
fn setup(samples: u32) -> (Scene, LightRig, Receivers, ShadowParams) {
    let scene = boxes_over_plane();
    let p = params(samples);
    let light = default_light(&scene).unwrap();
    let rig = LightRig::new(&scene, 0.0, &light, samples, SM, p.seed, p.jitter).unwrap();
    let cam = camera();
    let frame = render_frame(&scene, &cam, 0.0, &FrameOptions::default()).unwrap();
    let recv = Receivers::build(&frame, &cam, &scene, &rig, &p.bias).unwrap();
    let n = recv.list.len();
    assert!(n > W as usize * H as usize / 2, "the camera should mostly see the scene ({n} receivers)");
    (scene, rig, recv, p)
}

/// Deterministic pseudo-random numbers in [0, 1) (SplitMix64).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// Per-receiver comparison of lit counts: (fraction identical, largest difference, mean
/// absolute difference in samples).
fn compare(gpu: &[u32], cpu: &[u32]) -> (f64, u32, f64) {
    assert_eq!(gpu.len(), cpu.len());
    let same = gpu.iter().zip(cpu).filter(|(a, b)| a == b).count() as f64 / gpu.len() as f64;
    let max = gpu.iter().zip(cpu).map(|(a, b)| a.abs_diff(*b)).max().unwrap_or(0);
    let mean = gpu.iter().zip(cpu).map(|(a, b)| a.abs_diff(*b) as f64).sum::<f64>() / gpu.len() as f64;
    (same, max, mean)
}

#[test]
fn accumulate_kernel_equals_cpu_accumulate_on_random_maps() {
    let Some(ctx) = test_context() else { return };
    let gpu = GpuShadows::new(&ctx).unwrap();
    let mut rng = Rng(7);
    let (mw, mh) = (61u32, 37u32);
    // Random receivers: positions partly off the map, thresholds over the depth range (and a
    // few -inf, the CPU's non-finite threshold), both signs of g.
    let list: Vec<Receiver> = (0..5000u32)
        .map(|k| {
            let mut r = Receiver {
                pixel: k,
                p_c: Vec2::new(rng.next() * (mw as f32 + 10.0) - 5.0, rng.next() * (mh as f32 + 10.0) - 5.0),
                g: rng.next() * 2.0 - 1.0,
                z: 1.0,
                threshold: rng.next(),
                bias: 0.0,
                tan_theta: 0.0,
                lambert: 1.0,
                albedo: Vec3::ONE,
            };
            if k % 97 == 0 {
                r.threshold = f32::NEG_INFINITY;
            }
            r
        })
        .collect();
    let recv = Receivers { width: 100, height: 50, list };
    let mut cpu = vec![0u32; recv.list.len()];
    let mut gl = vec![0u32; recv.list.len()];
    for i in 0..6 {
        // Empty texels (1.0) too.
        let data: Vec<f32> = (0..mw * mh).map(|_| if rng.next() < 0.2 { 1.0 } else { rng.next() }).collect();
        let map = Image::from_vec(mw, mh, data).unwrap();
        let shift = Vec2::new(rng.next() * 8.0 - 4.0, rng.next() * 8.0 - 4.0) * (i as f32);
        recv.accumulate(&map, shift, &mut cpu);
        gpu.accumulate(&recv, &map, shift, &mut gl).unwrap();
        assert_eq!(gl, cpu, "sample {i}");
    }
    // Some receivers are lit in every map (off the map), some never.
    assert!(cpu.contains(&6) && cpu.contains(&0), "{:?}", &cpu[..20]);
}

#[test]
fn parallax_kernel_matches_the_cpu_field() {
    let Some(ctx) = test_context() else { return };
    let gpu = GpuShadows::new(&ctx).unwrap();
    let (scene, rig, _, _) = setup(4);
    let depth = render_sample_map(&scene, &rig, 0.0, 0).unwrap();
    let k = reference_shift(&rig);
    let cpu = rig.parallax_field(&depth, k).unwrap();
    let (g, coverage) = gpu.parallax_field(&rig, &depth, k).unwrap();
    assert_eq!(coverage as usize, depth.data().iter().filter(|&&d| d < 1.0).count());
    let kmax = k.abs().max_element();
    for (a, b) in g.data().iter().zip(cpu.data()) {
        assert_eq!(a.depth, b.depth);
        // Division and contraction on the GPU: a few ulps of the pixel motion.
        assert!((a.v - b.v).abs().max_element() <= 1e-5 * kmax.max(1.0), "{a:?} vs {b:?}");
    }
    // Bad inputs: wrong size, NaN depth.
    assert!(gpu.parallax_field(&rig, &Image::new(3, 3, 0.5), k).is_err());
    let mut nan = depth.clone();
    nan.data_mut()[5] = f32::NAN;
    assert!(matches!(gpu.parallax_field(&rig, &nan, k), Err(Error::Invalid(_))));
}

#[test]
fn gpu_reference_lit_counts_match_the_cpu_reference() {
    let Some(ctx) = test_context() else { return };
    let gpu = GpuShadows::new(&ctx).unwrap();
    let (scene, rig, recv, _) = setup(9);
    let mut cpu = vec![0u32; recv.list.len()];
    for i in 0..rig.samples() {
        let map = render_sample_map(&scene, &rig, 0.0, i).unwrap();
        recv.accumulate(&map, rig.shifts[i], &mut cpu);
    }
    let gs = GpuScene::upload(&ctx, &scene).unwrap();
    let gr = gpu.upload_receivers(&recv).unwrap();
    let lit = gpu.reference_lit(&gs, &rig, 0.0, &gr).unwrap();
    // The maps differ only on shared-edge texels (GPU vs CPU rasterizer, >= 99.9 % identical),
    // and a receiver reads one texel per map: >= 99.5 % identical counts, never more than a
    // couple of samples apart.
    let (same, max, mean) = compare(&lit, &cpu);
    eprintln!("reference: identical {same}, max {max}, mean {mean}");
    assert!(same >= 0.995, "identical on {same}");
    assert!(max <= 2, "max difference {max}");
    assert!(mean < 0.005, "mean difference {mean}");
    // The scene casts shadows: some receivers are in umbra, some in penumbra.
    assert!(cpu.contains(&0) && cpu.iter().any(|&l| l > 0 && l < 9));
}

#[test]
fn gpu_zwarp_lit_counts_match_the_cpu_full_map_warps() {
    let Some(ctx) = test_context() else { return };
    let gpu = GpuShadows::new(&ctx).unwrap();
    let (scene, rig, recv, p) = setup(16);
    // CPU: the shared-mipmap maps (what Method::Zwarp looks up), warped in full.
    let mut maps = ZwarpMaps::new(&scene, &rig, 0.0, &p).unwrap();
    assert!(maps.shares_mipmap());
    let mut cpu = vec![0u32; recv.list.len()];
    for i in 0..rig.samples() {
        let out = maps.map(i).unwrap();
        recv.accumulate(&out.depth, rig.shifts[i], &mut cpu);
    }
    let gs = GpuScene::upload(&ctx, &scene).unwrap();
    let gr = gpu.upload_receivers(&recv).unwrap();
    let peel = gpu_peel_options(&peel_options(&scene, &rig, &p)).unwrap();
    let layers = gpu.peel(&gs, &rig, 0.0, &peel).unwrap();
    // Same non-empty layers as the CPU peel (the GPU keeps the same ones).
    assert_eq!(layers.layers.len(), maps.layers().len());
    for (g, c) in layers.coverage.iter().filter(|&&c| c > 0).zip(maps.layers()) {
        let c = c.coverage() as f64;
        assert!((*g as f64 - c).abs() <= 0.01 * c + 4.0, "coverage {g} vs {c}");
    }
    let lit = gpu.zwarp_lit(&layers, &rig, &p, &gr).unwrap();
    let (same, max, mean) = compare(&lit, &cpu);
    eprintln!("zwarp: identical {same}, max {max}, mean {mean}");
    assert!(same >= 0.995, "identical on {same} (max {max}, mean {mean})");
    assert!(mean < 0.01, "mean difference {mean}");
    // And zwarp is close to the reference on this scene (the method works on the GPU too).
    let gr_lit = gpu.reference_lit(&gs, &rig, 0.0, &gr).unwrap();
    let (_, _, mean_ref) = compare(&lit, &gr_lit);
    assert!(mean_ref < 0.25, "zwarp vs reference: {mean_ref} samples per receiver");
}

#[test]
fn run_shadows_gpu_matches_the_cpu_run() {
    let Some(ctx) = test_context() else { return };
    let gpu = GpuShadows::new(&ctx).unwrap();
    let scene = boxes_over_plane();
    let gs = GpuScene::upload(&ctx, &scene).unwrap();
    let light = default_light(&scene).unwrap();
    let cam = camera();
    let p = params(8);
    for method in [Method::Reference, Method::Zwarp] {
        let c = run_shadows(&scene, &cam, 0.0, &light, method, &p).unwrap();
        let g = run_shadows_gpu(&gpu, &scene, &gs, &cam, 0.0, &light, method, &p).unwrap();
        assert_eq!(g.image.size(), (W, H));
        let same =
            g.visibility.data().iter().zip(c.visibility.data()).filter(|(a, b)| a == b).count() as f64 / (W * H) as f64;
        // The camera frame is rendered on the GPU here: edge pixels may become other receivers.
        assert!(same >= 0.98, "{}: equal visibility on {same}", method.name());
        if method == Method::Zwarp {
            assert_eq!(g.warped_texels, 8 * (SM * SM) as usize);
        }
    }
    // No occluder in front of the ground: fully lit.
    let mut open = Scene { name: "open".into(), up: Vec3::Z, ..Scene::default() };
    add(&mut open, scene.meshes[0].clone(), Vec3::splat(0.8), true);
    let go = GpuScene::upload(&ctx, &open).unwrap();
    let lo = default_light(&open).unwrap();
    for method in [Method::Reference, Method::Zwarp] {
        let g = run_shadows_gpu(&gpu, &open, &go, &cam, 0.0, &lo, method, &p).unwrap();
        assert!(g.visibility.data().iter().all(|&v| v == 1.0), "{}", method.name());
    }
    // PCSS and bad parameters are one-line errors.
    let e = run_shadows_gpu(&gpu, &scene, &gs, &cam, 0.0, &light, Method::Pcss, &p).unwrap_err();
    assert!(e.to_string().contains("PCSS"), "{e}");
    let bad = ShadowParams { samples: 0, ..p };
    assert!(run_shadows_gpu(&gpu, &scene, &gs, &cam, 0.0, &light, Method::Zwarp, &bad).is_err());
    assert!(run_shadows_gpu(&gpu, &scene, &gs, &cam, f32::NAN, &light, Method::Reference, &p).is_err());
}

#[test]
fn accumulate_rejects_bad_inputs() {
    let Some(ctx) = test_context() else { return };
    let gpu = GpuShadows::new(&ctx).unwrap();
    let (_, _, recv, _) = setup(1);
    let map = Image::new(8, 8, 1.0f32);
    let mut short = vec![0u32; 3];
    assert!(matches!(gpu.accumulate(&recv, &map, Vec2::ZERO, &mut short), Err(Error::Invalid(_))));
    let mut lit = vec![0u32; recv.list.len()];
    assert!(gpu.accumulate(&recv, &map, Vec2::NAN, &mut lit).is_err());
    // An empty map of far depth lights everything.
    gpu.accumulate(&recv, &map, Vec2::ZERO, &mut lit).unwrap();
    assert!(lit.iter().all(|&l| l == 1));
    // Empty receiver lists are fine.
    let none = Receivers { width: 4, height: 4, list: Vec::new() };
    gpu.accumulate(&none, &map, Vec2::ONE, &mut []).unwrap();
}

#[test]
fn prepared_warps_equal_one_shot_warps() {
    // WarpKernel::encode_prepare_for (MotionScales::Any) once + encode_prepared per sample
    // (what GpuShadows::zwarp_lit runs) gives a preparation per sample's output bit for bit at
    // every sample's motion_scale.
    let Some(ctx) = test_context() else { return };
    let (scene, rig, _, p) = setup(4);
    let maps = ZwarpMaps::new(&scene, &rig, 0.0, &p).unwrap();
    let k = reference_shift(&rig);
    let motions: Vec<_> = maps.layers().iter().map(|l| rig.parallax_field(&l.depth, k).unwrap()).collect();
    let layers: Vec<WarpLayer<'_>> =
        maps.layers().iter().zip(&motions).map(|(l, m)| WarpLayer { depth: &l.depth, motion: m }).collect();
    let kernel = WarpKernel::new(&ctx).unwrap();
    let base = sample_warp_params(&p, k, k);
    let bufs = kernel.upload(&layers, &base).unwrap();
    let views: Vec<GpuWarpLayer<'_>> =
        bufs.iter().map(|(d, m)| GpuWarpLayer { depth: d, motion: m, axis: Vec2::X }).collect();
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    let prepared = kernel.encode_prepare_for(&mut enc, &views, SM, SM, &base, MotionScales::Any).unwrap();
    ctx.queue.submit([enc.finish()]);
    assert_eq!(prepared.size(), (SM, SM));
    for &shift in &rig.shifts {
        let wp = sample_warp_params(&p, shift, k);
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        let own = kernel.encode_prepare_for(&mut enc, &views, SM, SM, &wp, MotionScales::Any).unwrap();
        let one = kernel.encode_prepared(&mut enc, &own, wp.motion_scale).unwrap();
        let two = kernel.encode_prepared(&mut enc, &prepared, wp.motion_scale).unwrap();
        ctx.queue.submit([enc.finish()]);
        let (a, b) = (one.read(&ctx).unwrap(), two.read(&ctx).unwrap());
        assert_eq!(a.depth.data(), b.depth.data());
        assert_eq!(a.state.data(), b.state.data());
    }
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    assert!(kernel.encode_prepared(&mut enc, &prepared, Vec2::new(f32::NAN, 1.0)).is_err());
}
