//! GPU backward depth warp vs `zwarp_warp::warp_depth` (the same function; seed 000 Sec. 3,
//! Fig. 3, 5, 6) on rendered frame pairs, plus exact cases and error paths.

use zwarp_testkit as common;

use common::*;
use glam::{Vec2, Vec3};
use zwarp_core::{motion_field, Camera, Error, Image, Motion};
use zwarp_gpu::{test_context, FrameOptions, GpuScene, PeelOptions, Renderer};
use zwarp_warp::gpu::WarpKernel;
use zwarp_warp::synth::SynthScene;
use zwarp_warp::{
    warp_depth, warp_prepared, BoundKind, CandidateChoice, HolePolicy, MotionScales, PixelState, PreparedLayer,
    Sampling, SeedStrategy, WarpLayer, WarpOutput, WarpParams,
};

/// The bar between backends: warped-depth SSIM >= 0.999 and converged masks equal on >= 99.5 %
/// of the pixels. Returns (ssim, mask agreement, exactly equal depth fraction).
fn assert_same(gpu: &WarpOutput, cpu: &WarpOutput, what: &str) -> (f64, f64, f64) {
    assert_eq!(gpu.depth.size(), cpu.depth.size());
    let ssim = zwarp_metrics::ssim(&gpu.depth, &cpu.depth, 1.0).unwrap();
    let n = gpu.depth.len() as f64;
    let mask = gpu.state.data().iter().zip(cpu.state.data()).filter(|(a, b)| a == b).count() as f64 / n;
    let exact = gpu.depth.data().iter().zip(cpu.depth.data()).filter(|(a, b)| a == b).count() as f64 / n;
    assert!(ssim >= 0.999, "{what}: SSIM {ssim}");
    assert!(mask >= 0.995, "{what}: state agreement {mask}");
    // Most pixels must be bit-identical: only floating-point contraction may differ.
    assert!(exact >= 0.98, "{what}: exactly equal depth on {exact}");
    (ssim, mask, exact)
}

fn city_pair(w: u32, h: u32, layers: u32) -> (Vec<Image<f32>>, Vec<Image<Motion>>) {
    let scene = SynthScene::moving_city();
    let a = Camera::perspective(Vec3::new(0.0, 8.0, 10.0), Vec3::new(0.0, 0.0, -4.0), Vec3::Y, 1.0, 0.5, 100.0, w, h)
        .unwrap();
    let b = Camera::perspective(Vec3::new(0.9, 8.3, 9.0), Vec3::new(0.6, 0.0, -4.5), Vec3::Y, 1.0, 0.5, 100.0, w, h)
        .unwrap();
    let (ta, tb) = (0.0, 0.25);
    let src = scene.render(&a, ta, layers, layers > 1);
    let deltas = scene.object_deltas(ta, tb);
    let motions =
        src.depth.iter().zip(&src.items).map(|(d, it)| motion_field(d, Some(it), &a, &b, &deltas).unwrap()).collect();
    (src.depth, motions)
}

fn layers_of<'a>(d: &'a [Image<f32>], m: &'a [Image<Motion>]) -> Vec<WarpLayer<'a>> {
    d.iter().zip(m).map(|(depth, motion)| WarpLayer { depth, motion }).collect()
}

fn base() -> WarpParams {
    WarpKernel::gpu_params(&WarpParams::default())
}

#[test]
fn gpu_params_is_the_supported_cpu_configuration() {
    let p = base();
    assert_eq!(p.bound, BoundKind::Oriented);
    assert_eq!((p.n_seeds, p.iterations, p.threshold, p.bound_iterations), (8, 3, 0.5, 6));
    assert!(p.accelerate && p.cross_layer && !p.record_source);
    assert_eq!(WarpKernel::gpu_params(&WarpParams { holes: HolePolicy::Awoc, ..p }).holes, HolePolicy::Awoc);
    assert!(!WarpKernel::gpu_params(&WarpParams { record_source: true, ..p }).record_source);
    assert!(WarpKernel::check_params(&p).is_ok());
}

#[test]
fn city_single_and_multi_layer_match_cpu() {
    let Some(ctx) = test_context() else { return };
    let k = WarpKernel::new(&ctx).unwrap();
    let (d, m) = city_pair(128, 96, 3);
    let variants = [
        ("default (oriented)", base()),
        ("tight", WarpParams { bound: BoundKind::Tight, ..base() }),
        ("N=16 T=4", WarpParams { n_seeds: 16, iterations: 4, ..base() }),
        ("plain steps", WarpParams { accelerate: false, ..base() }),
        ("global bound", WarpParams { bound: BoundKind::Global, n_seeds: 4, ..base() }),
        ("nearest", WarpParams { sampling: Sampling::Nearest, ..base() }),
        ("no cross-layer", WarpParams { cross_layer: false, ..base() }),
        ("first converged", WarpParams { choice: CandidateChoice::FirstConverged, ..base() }),
        ("pixel seed", WarpParams { seeding: SeedStrategy::Pixel, iterations: 6, ..base() }),
        ("offset seed", WarpParams { seeding: SeedStrategy::Offset(Vec2::new(-3.0, 1.0)), ..base() }),
        ("dilate", WarpParams { holes: HolePolicy::Dilate { radius: 4 }, ..base() }),
        ("background fill", WarpParams { holes: HolePolicy::Background { radius: 4 }, ..base() }),
        ("no coverage test", WarpParams { cover_radius: 0.0, ..base() }),
        ("wide coverage", WarpParams { cover_radius: 8.0, ..base() }),
    ];
    for nl in [1usize, 3] {
        let layers = layers_of(&d[..nl], &m[..nl]);
        for (name, p) in &variants {
            let cpu = warp_depth(&layers, p).unwrap();
            let gpu = k.warp(&layers, p).unwrap();
            let (s, mask, exact) = assert_same(&gpu, &cpu, &format!("L={nl} {name}"));
            eprintln!(
                "L={nl} {name}: ssim {s:.6} mask {mask:.5} exact {exact:.5} cpu {:?} frames {:?}",
                cpu.counts(),
                WarpKernel::frames(&layers, p.bound, MotionScales::for_scale(p.motion_scale))
            );
            // The warp did real work: most pixels converged.
            assert!(cpu.counts().0 > cpu.depth.len() / 2, "{name}");
        }
    }
}

/// The multi-layer coverage test (`WarpParams::cover_radius`) where it decides most: a fast walk
/// along a near wall (80 cm per frame: wall texels leave the view by hundreds of pixels, so the
/// image clip of the bounds takes part), four peeled layers (seed 000 Sec. 3.4).
#[test]
fn near_wall_coverage_matches_cpu() {
    let Some(ctx) = test_context() else { return };
    let k = WarpKernel::new(&ctx).unwrap();
    let (w, h) = (160, 96);
    let scene = SynthScene::near_wall();
    let (a, b) = (SynthScene::near_wall_camera(0.0, w, h).unwrap(), SynthScene::near_wall_camera(0.8, w, h).unwrap());
    let src = scene.render(&a, 0.0, 4, true);
    let deltas = scene.object_deltas(0.0, 0.0);
    let m: Vec<Image<Motion>> =
        src.depth.iter().zip(&src.items).map(|(d, it)| motion_field(d, Some(it), &a, &b, &deltas).unwrap()).collect();
    let layers = layers_of(&src.depth, &m);
    // Exactly T iterations, where the front layer fails most and the coverage test decides most.
    let on = WarpParams { n_seeds: 4, extra_iterations: 0, ..base() };
    let off = WarpParams { cover_radius: 0.0, ..on };
    let (cpu_on, cpu_off) = (warp_depth(&layers, &on).unwrap(), warp_depth(&layers, &off).unwrap());
    // The test decides pixels here: the two CPU warps differ.
    let decided = cpu_on.state.data().iter().zip(cpu_off.state.data()).filter(|(x, y)| x != y).count();
    assert!(decided > 50, "{decided}");
    // The extra iterations of the walks still contracting after T decide pixels here too.
    let extra = WarpParams { extra_iterations: 3, ..on };
    let cpu_extra = warp_depth(&layers, &extra).unwrap();
    let walked = cpu_extra.state.data().iter().zip(cpu_on.state.data()).filter(|(x, y)| x != y).count();
    assert!(walked > 20, "{walked}");
    for (p, cpu, what) in [(&on, &cpu_on, "coverage"), (&off, &cpu_off, "no coverage"), (&extra, &cpu_extra, "extra")] {
        let gpu = k.warp(&layers, p).unwrap();
        assert_same(&gpu, cpu, what);
        let differ = gpu.state.data().iter().zip(cpu.state.data()).filter(|(x, y)| x != y).count();
        assert!(differ * 20 < decided, "{what}: {differ} states differ of {decided} decided");
    }
}

/// The CPU warp of the row-pattern layers `ls` (`zwarp_warp::synth`) prepared for `scales`, after
/// checking that the GPU gives the same states, depths and revealed pixels.
fn rows_match_cpu(
    ctx: &zwarp_gpu::GpuContext,
    k: &WarpKernel,
    ls: &[(Image<f32>, Image<Motion>)],
    p: &WarpParams,
    scales: MotionScales,
    what: &str,
) -> WarpOutput {
    let layers: Vec<WarpLayer<'_>> = ls.iter().map(|(depth, motion)| WarpLayer { depth, motion }).collect();
    let cpu =
        warp_prepared(&PreparedLayer::prepare_stack_for(&layers, p.bound, scales, Vec::new()).unwrap(), p).unwrap();
    let bufs = k.upload(&layers, p).unwrap();
    let views: Vec<zwarp_warp::gpu::GpuWarpLayer> = bufs
        .iter()
        .zip(WarpKernel::frames(&layers, p.bound, scales))
        .map(|((d, m), axis)| zwarp_warp::gpu::GpuWarpLayer { depth: d, motion: m, axis })
        .collect();
    let (w, h) = layers[0].depth.size();
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    let prepared = k.encode_prepare_for(&mut enc, &views, w, h, p, scales).unwrap();
    let out = k.encode_prepared(&mut enc, &prepared, p.motion_scale).unwrap();
    ctx.queue.submit([enc.finish()]);
    let gpu = out.read(ctx).unwrap();
    let what = format!("{what} {scales:?}");
    assert_eq!(gpu.state, cpu.state, "{what}");
    assert_eq!(gpu.depth, cpu.depth, "{what}");
    assert_eq!(gpu.revealed, cpu.revealed, "{what}");
    cpu
}

/// The coverage test's fixed-point step (`synth::seam_layers`): the GPU hides the far layer
/// seen through the seam between three layers' views of a wall, as the CPU does (bounds of the
/// motion as it is).
#[test]
fn seam_coverage_matches_cpu() {
    let Some(ctx) = test_context() else { return };
    let k = WarpKernel::new(&ctx).unwrap();
    for sliver in [true, false] {
        let p = WarpParams { n_seeds: 4, cover_radius: 0.5, ..base() };
        let layers = zwarp_warp::synth::seam_layers(sliver);
        let what = format!("sliver {sliver}");
        let cpu = rows_match_cpu(&ctx, &k, &layers, &p, MotionScales::Any, &what);
        assert_eq!(*cpu.state.get(10, 1), if sliver { PixelState::Hole } else { PixelState::Converged });
        // Clipped to the image (the column's texels leave the 32 px image by up to 25 px) the
        // seam pixel's bound is narrower and the second search finds the wall's sliver.
        let clipped = rows_match_cpu(&ctx, &k, &layers, &p, MotionScales::AtLeastOne, &what);
        assert_eq!(*clipped.state.get(10, 1), PixelState::Converged);
    }
}

/// The continuation test (`synth::continuation_layers`): the GPU hides the far layer behind a
/// wall that may continue behind a near column or beside a surface at its depth, and keeps it
/// where the wall visibly ends, as the CPU does.
#[test]
fn continuation_coverage_matches_cpu() {
    let Some(ctx) = test_context() else { return };
    let k = WarpKernel::new(&ctx).unwrap();
    use zwarp_warp::synth::BesideWall;
    for beside in [BesideWall::Column, BesideWall::Ends, BesideWall::SameDepth] {
        let p = WarpParams { n_seeds: 4, ..base() };
        let far = if beside == BesideWall::Ends { PixelState::Converged } else { PixelState::Hole };
        for scales in [MotionScales::Any, MotionScales::AtLeastOne] {
            let layers = zwarp_warp::synth::continuation_layers(beside);
            let cpu = rows_match_cpu(&ctx, &k, &layers, &p, scales, &format!("{beside:?}"));
            assert_eq!(*cpu.state.get(6, 1), far, "{beside:?} {scales:?}");
        }
    }
}

/// `WarpParams::ground_layer` (`synth::ground_gap_layers`): the GPU hides the ground seen
/// through a disocclusion in front of a far surface, and keeps it where the far side is ground,
/// as the CPU does.
#[test]
fn ground_layer_matches_cpu() {
    let Some(ctx) = test_context() else { return };
    let k = WarpKernel::new(&ctx).unwrap();
    for (far, ground_layer) in [(0.8, true), (0.8, false), (0.95, true)] {
        let p = WarpParams { n_seeds: 4, ground_layer, ..base() };
        let what = format!("far {far} ground_layer {ground_layer}");
        let hidden = ground_layer && far < 0.95;
        for scales in [MotionScales::Any, MotionScales::AtLeastOne] {
            let cpu = rows_match_cpu(&ctx, &k, &zwarp_warp::synth::ground_gap_layers(far), &p, scales, &what);
            assert_eq!(*cpu.state.get(8, 1), if hidden { PixelState::Hole } else { PixelState::Converged });
            // Where kept, the ground's candidate is one the deeper layer revealed.
            assert_eq!(cpu.revealed.contains(&(cpu.depth.width() + 8)), !hidden, "{what} {scales:?}");
        }
    }
}

#[test]
fn rendered_frame_pair_matches_cpu() {
    let Some(ctx) = test_context() else { return };
    let scene = test_scene();
    let gs = GpuScene::upload(&ctx, &scene).unwrap();
    let r = Renderer::new(&ctx).unwrap();
    let (a, b) = (camera_a(), camera_b());
    let (ta, tb) = (0.0, 0.5);
    let peel = PeelOptions { layers: 2, ground_separate: false, umbra: None, frame: FrameOptions::default() };
    let frames = r.render_layers(&gs, &a, ta, &peel).unwrap();
    let deltas = scene.object_deltas(ta, tb);
    let d: Vec<Image<f32>> = frames.iter().map(|f| f.depth.clone()).collect();
    let m: Vec<Image<Motion>> =
        frames.iter().map(|f| motion_field(&f.depth, Some(&f.items), &a, &b, &deltas).unwrap()).collect();
    let k = WarpKernel::new(&ctx).unwrap();
    for (nl, p) in [(1usize, base()), (2, base()), (2, WarpParams { bound: BoundKind::Tight, ..base() })] {
        let layers = layers_of(&d[..nl], &m[..nl]);
        // The host-side frame choice is the CPU's (PreparedLayer::prepare_stack_for), with
        // the bounds clipped to the image or not.
        for scales in [MotionScales::Any, MotionScales::AtLeastOne] {
            let prepared = zwarp_warp::PreparedLayer::prepare_stack_for(&layers, p.bound, scales, Vec::new()).unwrap();
            let axes: Vec<Vec2> = prepared.iter().map(|l| l.pyramid().frame().axis).collect();
            assert_eq!(WarpKernel::frames(&layers, p.bound, scales), axes, "{scales:?}");
        }
        let prepared = zwarp_warp::PreparedLayer::prepare_stack(&layers, p.bound).unwrap();
        let cpu_axes: Vec<Vec2> = prepared.iter().map(|l| l.pyramid().frame().axis).collect();
        if p.bound == BoundKind::Oriented {
            assert!(cpu_axes.iter().all(|a| *a != Vec2::X), "this pair exercises oriented bounds");
        }
        let cpu = warp_depth(&layers, &p).unwrap();
        let gpu = k.warp(&layers, &p).unwrap();
        let (s, mask, exact) = assert_same(&gpu, &cpu, &format!("rendered L={nl}"));
        eprintln!(
            "rendered L={nl} {:?}: ssim {s:.6} mask {mask:.5} exact {exact:.5} cpu {:?} frames {:?}",
            p.bound,
            cpu.counts(),
            cpu_axes
        );
    }
}

#[test]
fn zero_motion_gives_the_source_exactly() {
    let Some(ctx) = test_context() else { return };
    let k = WarpKernel::new(&ctx).unwrap();
    let d =
        Image::from_fn(
            37,
            23,
            |x, y| if (x * 3 + y * 5) % 11 == 0 { 1.0 } else { 0.3 + 0.01 * x as f32 + 0.005 * y as f32 },
        );
    let m = d.map(|&z| Motion { v: Vec2::ZERO, depth: z });
    for bound in [BoundKind::Oriented, BoundKind::Tight, BoundKind::Global] {
        for sampling in [Sampling::Nearest, Sampling::Adaptive] {
            let p = WarpParams { bound, sampling, ..base() };
            let out = k.warp(&[WarpLayer { depth: &d, motion: &m }], &p).unwrap();
            assert_eq!(out.depth, d, "{bound:?} {sampling:?}");
            for (z, s) in d.data().iter().zip(out.state.data()) {
                assert_eq!(*s, if *z < 1.0 { PixelState::Converged } else { PixelState::Hole });
            }
        }
    }
    // Dilation fills the isolated empty pixels from their converged neighbours, like the CPU.
    let p = WarpParams { holes: HolePolicy::Dilate { radius: 2 }, ..base() };
    let layer = [WarpLayer { depth: &d, motion: &m }];
    let (gpu, cpu) = (k.warp(&layer, &p).unwrap(), warp_depth(&layer, &p).unwrap());
    assert_eq!(gpu, cpu);
    assert!(gpu.counts().1 > 0);
}

#[test]
fn uniform_shift_moves_the_image() {
    let Some(ctx) = test_context() else { return };
    let k = WarpKernel::new(&ctx).unwrap();
    let d = Image::from_fn(40, 30, |x, y| 0.2 + 0.01 * x as f32 + 0.003 * y as f32);
    let m = d.map(|&z| Motion { v: Vec2::new(3.0, -2.0), depth: z });
    let out = k.warp(&[WarpLayer { depth: &d, motion: &m }], &base()).unwrap();
    for y in 0..30 {
        for x in 0..40 {
            let inside = x >= 3 && y + 2 < 30;
            assert_eq!(*out.state.get(x, y) == PixelState::Converged, inside, "({x}, {y})");
            if inside {
                assert_eq!(*out.depth.get(x, y), *d.get(x - 3, y + 2));
            } else {
                assert_eq!(*out.depth.get(x, y), 1.0);
            }
        }
    }
}

#[test]
fn bad_input_is_an_error() {
    let Some(ctx) = test_context() else { return };
    let k = WarpKernel::new(&ctx).unwrap();
    let d = Image::new(8, 8, 0.5f32);
    let m = d.map(|&z| Motion { v: Vec2::ZERO, depth: z });
    let layer = [WarpLayer { depth: &d, motion: &m }];
    let inval = |r: zwarp_core::Result<WarpOutput>| matches!(r, Err(Error::Invalid(_)));
    assert!(inval(k.warp(&[], &base())));
    assert!(inval(k.warp(&layer, &WarpParams { record_source: true, ..base() })));
    assert!(inval(k.warp(&layer, &WarpParams { n_seeds: 0, ..base() })));
    let small = Image::new(4, 8, Motion::default());
    assert!(inval(k.warp(&[WarpLayer { depth: &d, motion: &small }], &base())));
    let d2 = Image::new(4, 8, 0.5f32);
    let m2 = Image::new(4, 8, Motion::default());
    assert!(inval(k.warp(&[layer[0], WarpLayer { depth: &d2, motion: &m2 }], &base())));
    let mut dn = d.clone();
    dn.data_mut()[3] = f32::NAN;
    assert!(inval(k.warp(&[WarpLayer { depth: &dn, motion: &m }], &base())));
    let mut mn = m.clone();
    mn.data_mut()[5].v.x = f32::NAN;
    assert!(inval(k.warp(&[WarpLayer { depth: &d, motion: &mn }], &base())));
    let many: Vec<WarpLayer> = (0..9).map(|_| layer[0]).collect();
    assert!(inval(k.warp(&many, &base())));
}

/// The engine path: render, copy depth, motion kernel and warp recorded into one encoder and
/// submitted once (no CPU round trip), against the CPU warp of the CPU motion field. The GPU
/// motion differs from the CPU one by < 1e-3 px, so only the backend bar is asserted.
#[test]
fn all_gpu_chain_matches_cpu() {
    let Some(ctx) = test_context() else { return };
    let scene = test_scene();
    let gs = GpuScene::upload(&ctx, &scene).unwrap();
    let r = Renderer::new(&ctx).unwrap();
    let mk = zwarp_warp::gpu::MotionKernel::new(&ctx).unwrap();
    let k = WarpKernel::new(&ctx).unwrap();
    let (a, b) = (camera_a(), camera_b());
    let (w, h) = (a.width, a.height);
    let target = zwarp_gpu::DepthTarget::new(&ctx, w, h).unwrap();
    let storage = |bytes: u64| {
        ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: None,
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        })
    };
    let (dbuf, mbuf) = (storage(w as u64 * h as u64 * 4), storage(w as u64 * h as u64 * 12));
    let p = base();
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    r.encode_depth(&mut enc, &gs, &a, 0.0, &target).unwrap();
    r.encode_depth_copy(&mut enc, &target, &dbuf, w).unwrap();
    let input = zwarp_warp::gpu::MotionInput { depth: &dbuf, items: None, row_stride: w };
    mk.encode(&mut enc, &input, &a, &b, &[], &mbuf).unwrap();
    // Axis-aligned bounds: the oriented frame would need the motion on the CPU.
    let p = WarpParams { bound: BoundKind::Tight, ..p };
    let layer = zwarp_warp::gpu::GpuWarpLayer { depth: &dbuf, motion: &mbuf, axis: Vec2::X };
    let out = k.encode(&mut enc, &[layer], w, h, &p).unwrap();
    ctx.queue.submit([enc.finish()]);
    let gpu = out.read(&ctx).unwrap();
    // The static part of the test scene (object motion is not passed here, as an engine with a
    // static scene would do).
    let depth = r.render_depth(&gs, &a, 0.0).unwrap();
    let motion = motion_field(&depth, None, &a, &b, &[]).unwrap();
    let cpu = warp_depth(&[WarpLayer { depth: &depth, motion: &motion }], &p).unwrap();
    let ssim = zwarp_metrics::ssim(&gpu.depth, &cpu.depth, 1.0).unwrap();
    let n = gpu.depth.len() as f64;
    let mask = gpu.state.data().iter().zip(cpu.state.data()).filter(|(x, y)| x == y).count() as f64 / n;
    eprintln!("all-GPU chain: ssim {ssim:.6} mask {mask:.5} cpu {:?}", cpu.counts());
    assert!(ssim >= 0.999 && mask >= 0.995, "ssim {ssim} mask {mask}");
    assert!(cpu.counts().0 > cpu.depth.len() / 3);
    // Bad GPU inputs: a motion buffer too small for the size, zero size, too many layers.
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    let l = zwarp_warp::gpu::GpuWarpLayer { depth: &dbuf, motion: &dbuf, axis: Vec2::X };
    assert!(matches!(k.encode(&mut enc, &[l], w, h, &p), Err(Error::Invalid(_))));
    let l = zwarp_warp::gpu::GpuWarpLayer { depth: &dbuf, motion: &mbuf, axis: Vec2::X };
    let bad_axis = zwarp_warp::gpu::GpuWarpLayer { axis: Vec2::new(2.0, 0.0), ..l };
    assert!(matches!(k.encode(&mut enc, &[bad_axis], w, h, &p), Err(Error::Invalid(_))));
    assert!(matches!(k.encode(&mut enc, &[l], 0, h, &p), Err(Error::Invalid(_))));
    assert!(matches!(k.encode(&mut enc, &[l; 9], w, h, &p), Err(Error::Invalid(_))));
}

/// `WarpParams::motion_scale` (soft-shadow sample fields, frame interpolation): the GPU twin
/// scales fetches and mipmap bounds exactly like the CPU — per-axis and negative factors under
/// axis-aligned bounds, a uniform factor under oriented bounds — and rejects a non-uniform
/// factor under an oriented frame.
#[test]
fn motion_scale_matches_cpu() {
    let Some(ctx) = test_context() else { return };
    let k = WarpKernel::new(&ctx).unwrap();
    let (d, m) = city_pair(96, 64, 3);
    for nl in [1usize, 3] {
        let layers = layers_of(&d[..nl], &m[..nl]);
        for (name, p) in [
            ("tight (0.5, 1.7)", WarpParams { bound: BoundKind::Tight, motion_scale: Vec2::new(0.5, 1.7), ..base() }),
            ("tight (-1, 0.3)", WarpParams { bound: BoundKind::Tight, motion_scale: Vec2::new(-1.0, 0.3), ..base() }),
            ("oriented -0.6", WarpParams { motion_scale: Vec2::splat(-0.6), ..base() }),
        ] {
            let cpu = warp_depth(&layers, &p).unwrap();
            let gpu = k.warp(&layers, &p).unwrap();
            let (s, mask, exact) = assert_same(&gpu, &cpu, &format!("L={nl} {name}"));
            eprintln!("motion_scale L={nl} {name}: ssim {s:.6} mask {mask:.5} exact {exact:.5} cpu {:?}", cpu.counts());
            assert!(cpu.counts().0 > cpu.depth.len() / 3, "{name}");
        }
    }
    let layers = layers_of(&d[..1], &m[..1]);
    if WarpKernel::frames(&layers, BoundKind::Oriented, MotionScales::Any)[0] != Vec2::X {
        let p = WarpParams { motion_scale: Vec2::new(1.0, 0.5), ..base() };
        assert!(matches!(k.warp(&layers, &p), Err(Error::Invalid(_))));
        assert!(matches!(warp_depth(&layers, &p), Err(Error::Invalid(_))));
    }
}

/// AWOC (Sec. 5.3) in the GPU twin: non-converged pixels take the nearest sample at the corners
/// of the first searched layer's tight region, as on the CPU; single and multi layer, oriented
/// and axis-aligned bounds. The fill must actually happen (filled pixels exist) and agree.
#[test]
fn awoc_matches_cpu() {
    let Some(ctx) = test_context() else { return };
    let k = WarpKernel::new(&ctx).unwrap();
    let (d, m) = city_pair(128, 96, 3);
    for nl in [1usize, 3] {
        let layers = layers_of(&d[..nl], &m[..nl]);
        for bound in [BoundKind::Oriented, BoundKind::Tight] {
            let p = WarpParams { holes: HolePolicy::Awoc, bound, ..base() };
            let cpu = warp_depth(&layers, &p).unwrap();
            let gpu = k.warp(&layers, &p).unwrap();
            let (s, mask, exact) = assert_same(&gpu, &cpu, &format!("AWOC L={nl} {bound:?}"));
            eprintln!(
                "AWOC L={nl} {bound:?}: ssim {s:.6} mask {mask:.5} exact {exact:.5} cpu {:?} gpu {:?}",
                cpu.counts(),
                gpu.counts()
            );
            assert!(cpu.counts().1 > 0, "AWOC filled nothing (L={nl} {bound:?})");
            let filled_cpu = cpu.counts().1 as f64;
            let filled_gpu = gpu.counts().1 as f64;
            assert!((filled_cpu - filled_gpu).abs() <= 0.01 * filled_cpu + 2.0, "{filled_cpu} vs {filled_gpu}");
        }
    }
}

/// A synthetic source of `sw x sh` samples for the multisample tests: layer 0 = random boxes
/// (some with their own motion) in front of a ground below the horizon and sky above; layer 1
/// = the ground alone (a separately peeled last layer). Every sample pans by `pan` plus a small
/// shear (motion in source samples).
fn synth_source(sw: u32, sh: u32, seed: u64, pan: Vec2) -> (Vec<Image<f32>>, Vec<Image<Motion>>) {
    let mut next = common::rng(seed);
    // (x0, y0, x1, y1, depth, own motion)
    let boxes: Vec<(f32, f32, f32, f32, f32, Vec2)> = (0..7)
        .map(|_| {
            let (x, y) = (next() * sw as f32, next() * sh as f32);
            let (bw, bh) = (3.0 + next() * sw as f32 / 4.0, 3.0 + next() * sh as f32 / 4.0);
            let own = if next() < 0.4 { Vec2::new(6.0 * next() - 3.0, 4.0 * next() - 2.0) } else { Vec2::ZERO };
            (x, y, x + bw, y + bh, 0.15 + 0.4 * next(), own)
        })
        .collect();
    let horizon = sh as f32 * 0.45;
    let ground = |y: u32| if y as f32 >= horizon { 0.65 + 0.3 * (y as f32 - horizon) / sh as f32 } else { 1.0 };
    let shear = |x: u32, y: u32| pan + Vec2::new(0.01 * y as f32, -0.008 * x as f32);
    let hit = |x: u32, y: u32| {
        let (fx, fy) = (x as f32 + 0.5, y as f32 + 0.5);
        boxes
            .iter()
            .filter(|b| fx >= b.0 && fx < b.2 && fy >= b.1 && fy < b.3)
            .min_by(|a, b| a.4.total_cmp(&b.4))
            .map(|b| (b.4 + 0.001 * (x % 5) as f32, b.5))
    };
    let d0 = Image::from_fn(sw, sh, |x, y| hit(x, y).map_or(ground(y), |b| b.0));
    let m0 = Image::from_fn(sw, sh, |x, y| {
        let own = hit(x, y).map_or(Vec2::ZERO, |b| b.1);
        Motion { v: shear(x, y) + own, depth: *d0.get(x, y) }
    });
    let d1 = Image::from_fn(sw, sh, |_, y| ground(y));
    let m1 = Image::from_fn(sw, sh, |x, y| Motion { v: shear(x, y), depth: *d1.get(x, y) });
    (vec![d0, d1], vec![m0, m1])
}

/// Bit-for-bit equality of two warps: depth bits and states of every pixel.
fn assert_bits(gpu: &WarpOutput, cpu: &WarpOutput, what: &str) {
    assert_eq!(gpu.depth.size(), cpu.depth.size(), "{what}: size");
    let bad = gpu
        .depth
        .data()
        .iter()
        .zip(cpu.depth.data())
        .zip(gpu.state.data().iter().zip(cpu.state.data()))
        .position(|((a, b), (s, t))| a.to_bits() != b.to_bits() || s != t);
    if let Some(i) = bad {
        let w = gpu.depth.width() as usize;
        panic!(
            "{what}: pixel ({}, {}) GPU {} {:?} vs CPU {} {:?}",
            i % w,
            i / w,
            gpu.depth.data()[i],
            gpu.state.data()[i],
            cpu.depth.data()[i],
            cpu.state.data()[i]
        );
    }
    assert_eq!(gpu.revealed, cpu.revealed, "{what}: revealed pixels");
}

/// `WarpParams::multisample` m = 2, 3 (seed 000 Sec. 7): the GPU warp of an m x m-sampled
/// source equals `zwarp_warp::warp_depth` bit for bit (depth bits and states) on synthetic
/// scenes (odd target sizes, so tiles are clipped), one layer and a separate ground layer,
/// every hole policy, axis-aligned and oriented bounds, both sampling modes; the output is the
/// target size; a source not divisible by m is rejected with the CPU's error.
#[test]
fn multisample_matches_cpu_bit_for_bit() {
    let Some(ctx) = test_context() else { return };
    let k = WarpKernel::new(&ctx).unwrap();
    let (tw, th) = (29u32, 19u32);
    let policies = [
        HolePolicy::FarDepth,
        HolePolicy::Dilate { radius: 3 },
        HolePolicy::Background { radius: 4 },
        HolePolicy::Awoc,
    ];
    for m in [2u32, 3] {
        for (seed, pan) in [(1u64, Vec2::new(2.5, -1.25)), (7, Vec2::new(-3.0, 0.75))] {
            let (d, mo) = synth_source(tw * m, th * m, seed, pan * m as f32);
            for nl in [1usize, 2] {
                let layers = layers_of(&d[..nl], &mo[..nl]);
                for holes in policies {
                    for (bound, sampling) in [
                        (BoundKind::Tight, Sampling::Adaptive),
                        (BoundKind::Oriented, Sampling::Adaptive),
                        (BoundKind::Tight, Sampling::Nearest),
                    ] {
                        let p = WarpParams { multisample: m, holes, bound, sampling, ..base() };
                        let what = format!("m={m} seed {seed} L={nl} {holes:?} {bound:?} {sampling:?}");
                        let cpu = warp_depth(&layers, &p).unwrap();
                        let gpu = k.warp(&layers, &p).unwrap();
                        assert_eq!(gpu.depth.size(), (tw, th), "{what}");
                        assert_bits(&gpu, &cpu, &what);
                        let (conv, filled, _) = cpu.counts();
                        // The ground and boxes converge (the sky above the horizon stays a hole).
                        assert!(conv > cpu.depth.len() / 3, "{what}: converged {conv}");
                        if holes != HolePolicy::FarDepth && nl == 1 {
                            assert!(filled > 0, "{what}: the hole policy filled nothing");
                        }
                    }
                }
            }
        }
    }
    // m = 1 on the same source warps to the source size.
    let (d, mo) = synth_source(tw * 3, th * 3, 3, Vec2::new(4.0, -2.0));
    let layers = layers_of(&d[..1], &mo[..1]);
    let one = k.warp(&layers, &base()).unwrap();
    assert_eq!(one.depth.size(), (tw * 3, th * 3));
    // The CPU's divisibility rule and error text.
    let p = WarpParams { multisample: 2, ..base() };
    let cpu = warp_depth(&layers, &p).unwrap_err().to_string();
    let gpu = k.warp(&layers, &p).unwrap_err().to_string();
    assert_eq!(gpu, cpu);
    assert!(gpu.contains("divisible by 2"), "{gpu}");
}

/// Tiles whose region holds one solution (`PreparedLayer::unique_solution`: a walk toward a wall
/// past a box, `synth::approach_field`) take one seed at the centre of the region under the
/// tile's bound on the GPU as on the CPU: bit for bit, for N = 4 and 16, axis-aligned and
/// oriented bounds, contracting and magnified walls (monotone), and motion scales (the gradient
/// test scales with them; a uniform positive one also takes the monotone test).
#[test]
fn unique_solution_tiles_match_cpu_bit_for_bit() {
    let Some(ctx) = test_context() else { return };
    let k = WarpKernel::new(&ctx).unwrap();
    for (w, h, s) in [(64u32, 48u32, 0.4f32), (61, 37, 0.3), (64, 48, 0.8), (61, 37, 1.5)] {
        let (d, m) = zwarp_warp::synth::approach_field(w, h, s);
        let layers = [WarpLayer { depth: &d, motion: &m }];
        for (bound, scale) in [
            (BoundKind::Tight, Vec2::ONE),
            (BoundKind::Oriented, Vec2::ONE),
            (BoundKind::Tight, Vec2::new(0.5, 1.5)),
            (BoundKind::Tight, Vec2::splat(-1.2)),
            (BoundKind::Tight, Vec2::splat(2.0)),
        ] {
            for n in [4, 16] {
                let p = WarpParams { n_seeds: n, bound, motion_scale: scale, ..base() };
                let what = format!("{w}x{h} s={s} {bound:?} scale {scale} N={n}");
                let cpu = warp_depth(&layers, &p).unwrap();
                assert_bits(&k.warp(&layers, &p).unwrap(), &cpu, &what);
                if scale == Vec2::ONE {
                    assert!(cpu.counts().0 > cpu.depth.len() / 2, "{what}");
                }
            }
        }
    }
}

/// The engine path with multisample: `encode_prepare` on the source size, `encode_prepared`
/// with two motion scales, each equal to the CPU warp with that scale, target-sized outputs.
#[test]
fn multisample_prepared_warps_match_cpu() {
    let Some(ctx) = test_context() else { return };
    let k = WarpKernel::new(&ctx).unwrap();
    let m = 2u32;
    let (tw, th) = (33u32, 18u32);
    let (d, mo) = synth_source(tw * m, th * m, 11, Vec2::new(3.0, 1.0));
    let layers = layers_of(&d, &mo);
    let p = WarpParams { multisample: m, bound: BoundKind::Tight, holes: HolePolicy::Dilate { radius: 2 }, ..base() };
    let gpu_layers = k.upload(&layers, &p).unwrap();
    let views: Vec<zwarp_warp::gpu::GpuWarpLayer> =
        gpu_layers.iter().map(|(d, m)| zwarp_warp::gpu::GpuWarpLayer { depth: d, motion: m, axis: Vec2::X }).collect();
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    let prepared = k.encode_prepare_for(&mut enc, &views, tw * m, th * m, &p, MotionScales::Any).unwrap();
    assert_eq!((prepared.size(), prepared.target_size()), ((tw * m, th * m), (tw, th)));
    let scales = [Vec2::ONE, Vec2::new(0.5, -0.75)];
    let outs: Vec<zwarp_warp::gpu::GpuWarpOutput> =
        scales.iter().map(|&s| k.encode_prepared(&mut enc, &prepared, s).unwrap()).collect();
    ctx.queue.submit([enc.finish()]);
    for (out, &s) in outs.iter().zip(&scales) {
        assert_eq!((out.width, out.height), (tw, th));
        let cpu_prepared = PreparedLayer::prepare_stack_for(&layers, p.bound, MotionScales::Any, Vec::new()).unwrap();
        let cpu = warp_prepared(&cpu_prepared, &WarpParams { motion_scale: s, ..p }).unwrap();
        assert_bits(&out.read(&ctx).unwrap(), &cpu, &format!("prepared m={m} scale {s}"));
    }
    // A source size not divisible by m.
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    let e = k.encode(&mut enc, &views, tw * m - 1, th * m, &p).unwrap_err().to_string();
    assert!(e.contains("divisible by 2"), "{e}");
}
