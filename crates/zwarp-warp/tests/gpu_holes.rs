//! GPU hole-fill post-pass (seed 000 Sec. 3.5 Fig. 8, Sec. 4 background fill) vs
//! `zwarp_warp::fill_holes` on random depth/state images of odd sizes, for both rules and
//! several radii; the post-pass over a far-hole GPU warp equals the warp's own dilation; errors.

use zwarp_testkit as common;

use glam::Vec2;
use proptest::prelude::*;
use zwarp_core::{Image, Motion, EMPTY_DEPTH};
use zwarp_gpu::readback::read_buffer;
use zwarp_gpu::test_context;
use zwarp_gpu::GpuContext;
use zwarp_warp::gpu::{GpuWarpLayer, HoleFillKernel, WarpKernel};
use zwarp_warp::holes::BackgroundLimits;
use zwarp_warp::{fill_holes, FillRule, HolePolicy, PixelState, WarpLayer, WarpParams};

/// Random states in blobs (so holes have converged neighbours at various distances).
fn random_buffers(w: u32, h: u32, seed: u64) -> (Image<f32>, Image<PixelState>) {
    let mut next = common::rng(seed);
    let cells: Vec<(f32, f32)> = (0..(w.div_ceil(3) * h.div_ceil(2))).map(|_| (next(), next())).collect();
    let mut depth = Image::new(w, h, EMPTY_DEPTH);
    let mut state = Image::new(w, h, PixelState::Hole);
    for y in 0..h {
        for x in 0..w {
            let (u, v) = cells[((y / 2) * w.div_ceil(3) + x / 3) as usize];
            let jitter = next();
            if u < 0.55 && jitter > 0.1 {
                *depth.get_mut(x, y) = 0.1 + 0.8 * v;
                *state.get_mut(x, y) = PixelState::Converged;
            } else if u < 0.62 {
                *depth.get_mut(x, y) = 0.5;
                *state.get_mut(x, y) = PixelState::Filled;
            }
        }
    }
    (depth, state)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(10))]

    #[test]
    fn fill_equals_the_cpu(w in 1u32..70, h in 1u32..50, seed in 0u64..10_000, radius in 1u32..6) {
        let Some(ctx) = test_context() else { return Ok(()) };
        let k = HoleFillKernel::new(&ctx).unwrap();
        let (d, s) = random_buffers(w, h, seed);
        for (policy, rule) in [(HolePolicy::Dilate { radius }, FillRule::Nearest), (HolePolicy::Background { radius }, FillRule::Background)] {
            let (gd, gs) = k.fill(&d, &s, policy).unwrap();
            let (mut cd, mut cs) = (d.clone(), s.clone());
            fill_holes(&mut cd, &mut cs, radius, rule);
            prop_assert_eq!(&gs, &cs, "{:?} {}x{}", policy, w, h);
            prop_assert_eq!(&gd, &cd, "{:?} {}x{}", policy, w, h);
        }
    }
}

/// Ties: a hole whose four distance-1 neighbours hold 0.3 (left), 0.7 (right) and 0.5
/// (above, below) takes the farthest of the tied nearest depths, 0.7, as on the CPU.
#[test]
fn analytic_ties_take_the_farther_depth() {
    let Some(ctx) = test_context() else { return };
    let k = HoleFillKernel::new(&ctx).unwrap();
    let d = Image::from_fn(3, 3, |x, y| if (x, y) == (1, 1) { EMPTY_DEPTH } else { [0.3, 0.5, 0.7][x as usize] });
    let s = Image::from_fn(3, 3, |x, y| if (x, y) == (1, 1) { PixelState::Hole } else { PixelState::Converged });
    let (gd, gs) = k.fill(&d, &s, HolePolicy::Dilate { radius: 1 }).unwrap();
    assert_eq!((*gd.get(1, 1), *gs.get(1, 1)), (0.7, PixelState::Filled));
    let (mut cd, mut cs) = (d.clone(), s.clone());
    fill_holes(&mut cd, &mut cs, 1, FillRule::Nearest);
    assert_eq!((gd, gs), (cd, cs));
}

/// The post-pass over the GPU warp's far-depth output equals the GPU warp run with the
/// dilation policy (and the CPU's): one function, two call sites.
#[test]
fn post_pass_equals_the_warp_dilation() {
    let Some(ctx) = test_context() else { return };
    let wk = WarpKernel::new(&ctx).unwrap();
    let hk = HoleFillKernel::new(&ctx).unwrap();
    // A near square moving right over a far background: a disocclusion strip opens behind it.
    let d = Image::from_fn(45, 33, |x, y| if (10..25).contains(&x) && (8..24).contains(&y) { 0.3 } else { 0.8 });
    let m = d.map(|&z| Motion { v: if z < 0.5 { Vec2::new(3.0, 0.0) } else { Vec2::ZERO }, depth: z });
    let layer = [WarpLayer { depth: &d, motion: &m }];
    let far = wk.warp(&layer, &WarpParams::default()).unwrap();
    assert!(far.counts().2 > 0, "the strip is a hole");
    let policy = HolePolicy::Dilate { radius: 4 };
    let dil = wk.warp(&layer, &WarpParams { holes: policy, ..WarpParams::default() }).unwrap();
    let (pd, ps) = hk.fill(&far.depth, &far.state, policy).unwrap();
    assert_eq!(pd, dil.depth);
    assert_eq!(ps, dil.state);
}

#[test]
fn bad_input_is_an_error() {
    let Some(ctx) = test_context() else { return };
    let k = HoleFillKernel::new(&ctx).unwrap();
    let (d, s) = random_buffers(8, 6, 1);
    let e = k.fill(&d, &s, HolePolicy::Awoc).unwrap_err().to_string();
    assert!(e.contains("AWOC"), "{e}");
    let e = k.fill(&d, &s, HolePolicy::Dilate { radius: 0 }).unwrap_err().to_string();
    assert!(e.contains("radius must be in 1..=64"), "{e}");
    let e = k.fill(&d, &Image::new(7, 6, PixelState::Hole), HolePolicy::Dilate { radius: 1 }).unwrap_err().to_string();
    assert!(e.contains("8x6") && e.contains("7x6"), "{e}");
    // FarDepth leaves the buffers as they are.
    assert_eq!(k.fill(&d, &s, HolePolicy::FarDepth).unwrap(), (d, s));
}

/// A camera-pan-like scene for the background fill: layer 0 = random blobs (some moving on
/// their own) in front of a ground on the lower rows and sky above; layer 1 = the ground alone
/// (a separately peeled last layer). Every pixel, sky included, pans by `pan` plus a slow
/// rotation-like shear; blobs add their own motion.
fn background_scene(w: u32, h: u32, seed: u64, pan: Vec2) -> (Vec<Image<f32>>, Vec<Image<Motion>>) {
    let (d, _) = random_buffers(w, h, seed);
    let horizon = h / 2;
    let ground = |y: u32| if y >= horizon { 0.7 + 0.2 * (y - horizon) as f32 / h as f32 } else { EMPTY_DEPTH };
    let shear = |x: u32, y: u32| pan + Vec2::new(0.02 * y as f32, -0.015 * x as f32);
    let d0 = Image::from_fn(w, h, |x, y| {
        let z = *d.get(x, y);
        if z < 0.6 && (x + 2 * y) % 5 != 0 {
            z
        } else {
            ground(y)
        }
    });
    let m0 = Image::from_fn(w, h, |x, y| {
        let z = *d0.get(x, y);
        let own = if z < 0.6 && z > 0.4 { Vec2::new(2.5, -1.0) } else { Vec2::ZERO };
        Motion { v: shear(x, y) + own, depth: z }
    });
    let d1 = Image::from_fn(w, h, |_, y| ground(y));
    let m1 = Image::from_fn(w, h, |x, y| Motion { v: shear(x, y), depth: *d1.get(x, y) });
    (vec![d0, d1], vec![m0, m1])
}

/// `zwarp_warp::holes::fill_background` of `warped` (radius 64) on the GPU equals the CPU's:
/// depth, state and the revealed pixels left over. Returns the CPU's result.
fn fill_background_agrees(
    k: &HoleFillKernel,
    src: &[WarpLayer<'_>],
    warped: &zwarp_warp::WarpOutput,
    search: &zwarp_warp::SearchParams,
    what: &str,
) -> zwarp_warp::WarpOutput {
    let gpu = k.fill_background(src, warped, 64, search).unwrap();
    let mut cpu = warped.clone();
    zwarp_warp::holes::fill_background(src, &mut cpu, 64, search).unwrap();
    assert_eq!(gpu.state, cpu.state, "{what}");
    assert_eq!(gpu.depth, cpu.depth, "{what}");
    assert_eq!(gpu.revealed, cpu.revealed, "{what}");
    cpu
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(8))]

    /// zwarp_warp::holes::fill_background and its WGSL twin give the same depth and state on a
    /// far-hole warp (sky seen through holes, bracketed holes, border strips), for one layer and
    /// for a separately peeled ground, both search variants.
    #[test]
    fn background_fill_equals_the_cpu(
        w in 8u32..70, h in 6u32..50, seed in 0u64..10_000,
        px in -4.0f32..4.0, py in -3.0f32..3.0, layers in 1usize..=2, accelerate in proptest::bool::ANY,
    ) {
        let Some(ctx) = test_context() else { return Ok(()) };
        let k = HoleFillKernel::new(&ctx).unwrap();
        let (ds, ms) = background_scene(w, h, seed, Vec2::new(px, py));
        let src: Vec<WarpLayer> = ds.iter().zip(&ms).take(layers).map(|(d, m)| WarpLayer { depth: d, motion: m }).collect();
        let warped = zwarp_warp::warp_depth(&src, &WarpParams::default()).unwrap();
        let search = zwarp_warp::SearchParams { accelerate, ..zwarp_warp::WarpParams::default().search() };
        fill_background_agrees(&k, &src, &warped, &search, &format!("{w}x{h} seed {seed}"));
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(6))]

    /// Step 0 of fill_background (lone revealed pixels become holes) on the GPU equals the CPU:
    /// random converged / hole blobs, every other converged pixel listed as revealed (the warp's
    /// state code 3 on the GPU), one source layer with a surface everywhere; depth, state and
    /// the revealed list left over agree, and the step acted.
    #[test]
    fn lone_revealed_pixels_equal_the_cpu(w in 12u32..60, h in 8u32..40, seed in 0u64..10_000) {
        let Some(ctx) = test_context() else { return Ok(()) };
        let k = HoleFillKernel::new(&ctx).unwrap();
        let (depth, raw) = random_buffers(w, h, seed);
        // Converged and holes only, as a far-hole warp leaves them.
        let state = raw.map(|s| if *s == PixelState::Converged { PixelState::Converged } else { PixelState::Hole });
        let depth = Image::from_fn(w, h, |x, y| {
            if *state.get(x, y) == PixelState::Converged { *depth.get(x, y) } else { EMPTY_DEPTH }
        });
        let revealed: Vec<u32> =
            (0..w * h).filter(|&i| state.data()[i as usize] == PixelState::Converged && i % 2 == 0).collect();
        let warped = zwarp_warp::WarpOutput { depth, state, source: None, revealed };
        let lone = zwarp_warp::holes::lone_revealed(&warped.depth, &warped.state, &warped.revealed);
        prop_assume!(!lone.is_empty());
        let d = Image::new(w, h, 0.5f32);
        let m = Image::from_fn(w, h, |x, _| Motion { v: Vec2::new(0.25 * (x % 5) as f32, 0.0), depth: 0.5 });
        let src = [WarpLayer { depth: &d, motion: &m }];
        let search = zwarp_warp::WarpParams::default().search();
        let cpu = fill_background_agrees(&k, &src, &warped, &search, &format!("{w}x{h} seed {seed}"));
        prop_assert_eq!(cpu.revealed.len() + lone.len(), warped.revealed.len());
    }
}

/// The three steps show on the GPU as on the CPU: a 3-px pan leaves a border strip that takes
/// the ground's depth on ground rows and stays sky above the horizon.
#[test]
fn background_fill_analytic_pan() {
    let Some(ctx) = test_context() else { return };
    let k = HoleFillKernel::new(&ctx).unwrap();
    let ground = |y: u32| 0.6 + 0.01 * y as f32;
    let d = Image::from_fn(24, 12, |_, y| if y >= 6 { ground(y) } else { EMPTY_DEPTH });
    let m = d.map(|&z| Motion { v: Vec2::new(3.0, 0.0), depth: z });
    let src = [WarpLayer { depth: &d, motion: &m }];
    let warped = zwarp_warp::warp_depth(&src, &WarpParams::default()).unwrap();
    let search = zwarp_warp::WarpParams::default().search();
    let gpu = k.fill_background(&src, &warped, 4, &search).unwrap();
    let (gd, gs) = (&gpu.depth, &gpu.state);
    for y in 0..12 {
        for x in 0..3 {
            assert_eq!(*gs.get(x, y), PixelState::Filled, "({x},{y})");
            assert_eq!(*gd.get(x, y), if y >= 6 { ground(y) } else { EMPTY_DEPTH }, "({x},{y})");
        }
        assert_eq!(*gs.get(10, y), PixelState::Converged);
    }
    let e = k.fill_background(&src, &warped, 0, &search).unwrap_err().to_string();
    assert!(e.contains("radius"), "{e}");
    let e = k.fill_background(&[], &warped, 4, &search).unwrap_err().to_string();
    assert!(e.contains("at least one source layer"), "{e}");
}

/// `zwarp_warp::holes::fill_background` of a multisampled warp (`WarpParams::multisample` = 2:
/// source layers twice the warped buffer's size, m inferred from the ratio) and its WGSL twin
/// give the same depth and state, bit for bit, on the pan scenes (one layer and a separate
/// ground, both search variants), for the CPU warp and for the GPU warp of the same source;
/// the sky pass, the bracketed fill and the border strips all act. A source that is a multiple
/// of the width only is rejected with the CPU's error.
#[test]
fn background_fill_of_a_multisampled_source_equals_the_cpu() {
    let Some(ctx) = test_context() else { return };
    let k = HoleFillKernel::new(&ctx).unwrap();
    let wk = WarpKernel::new(&ctx).unwrap();
    let m = 2u32;
    for (w, h, seed, pan) in [(31u32, 22u32, 5u64, Vec2::new(3.0, -1.5)), (24, 17, 42, Vec2::new(-2.5, 2.0))] {
        // The scene at the source resolution, motion in source samples.
        let (ds, ms) = background_scene(w * m, h * m, seed, pan * m as f32);
        for layers in [1usize, 2] {
            let src: Vec<WarpLayer> =
                ds.iter().zip(&ms).take(layers).map(|(d, m)| WarpLayer { depth: d, motion: m }).collect();
            let params = WarpParams { multisample: m, ..WarpParams::default() };
            let warped = zwarp_warp::warp_depth(&src, &params).unwrap();
            assert_eq!(warped.depth.size(), (w, h));
            assert_eq!(wk.warp(&src, &params).unwrap(), warped, "GPU warp {w}x{h} L={layers}");
            for accelerate in [false, true] {
                let search = zwarp_warp::SearchParams { accelerate, ..zwarp_warp::WarpParams::default().search() };
                let gpu = k.fill_background(&src, &warped, 64, &search).unwrap();
                let (gd, gs) = (gpu.depth, gpu.state);
                let mut cpu = warped.clone();
                zwarp_warp::holes::fill_background(&src, &mut cpu, 64, &search).unwrap();
                let what = format!("{w}x{h} seed {seed} L={layers} accelerate {accelerate}");
                assert_eq!(gs, cpu.state, "{what}");
                let bits = |d: &Image<f32>| d.data().iter().map(|z| z.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&gd), bits(&cpu.depth), "{what}");
                // Every step acted: holes were left far (sky), filled (bracket / border).
                let holes = warped.state.data().iter().filter(|s| **s == PixelState::Hole).count();
                let filled = gs.data().iter().filter(|s| **s == PixelState::Filled).count();
                let sky = gs
                    .data()
                    .iter()
                    .zip(warped.state.data())
                    .filter(|(a, b)| **a == PixelState::Converged && **b == PixelState::Hole)
                    .count();
                assert!(holes > 0 && filled > 0 && sky > 0, "{what}: holes {holes} filled {filled} sky {sky}");
            }
        }
    }
    // Twice the width but not the height: no multisampled source, the CPU's error.
    let (ds, ms) = background_scene(16, 6, 1, Vec2::ZERO);
    let src = [WarpLayer { depth: &ds[0], motion: &ms[0] }];
    let out = zwarp_warp::WarpOutput {
        depth: Image::new(8, 6, EMPTY_DEPTH),
        state: Image::new(8, 6, PixelState::Hole),
        source: None,
        revealed: Vec::new(),
    };
    let search = zwarp_warp::WarpParams::default().search();
    let gpu = k.fill_background(&src, &out, 4, &search).unwrap_err().to_string();
    let mut cpu_out = out.clone();
    let cpu = zwarp_warp::holes::fill_background(&src, &mut cpu_out, 4, &search).unwrap_err().to_string();
    assert_eq!(gpu, cpu);
}

/// Source layers uploaded as they are (no checks: NaN motion included).
fn upload(ctx: &GpuContext, ds: &[Image<f32>], ms: &[Image<Motion>]) -> Vec<(wgpu::Buffer, wgpu::Buffer)> {
    let usage = wgpu::BufferUsages::STORAGE;
    ds.iter()
        .zip(ms)
        .map(|(d, m)| {
            (
                ctx.buffer_with("test depth", bytemuck::cast_slice(d.data()), usage).unwrap(),
                ctx.buffer_with("test motion", bytemuck::cast_slice(m.data()), usage).unwrap(),
            )
        })
        .collect()
}

/// `HoleFillKernel::encode_limits` of `ds` / `ms` (for a `w x h` warp at `m x m` samples),
/// read back: the limits and the empty-background mask.
fn gpu_limits(
    ctx: &GpuContext,
    k: &HoleFillKernel,
    (ds, ms): (&[Image<f32>], &[Image<Motion>]),
    (w, h, m): (u32, u32, u32),
    radius: u32,
) -> (BackgroundLimits, Vec<u32>) {
    let bufs = upload(ctx, ds, ms);
    let views: Vec<GpuWarpLayer> =
        bufs.iter().map(|(d, m)| GpuWarpLayer { depth: d, motion: m, axis: Vec2::X }).collect();
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    let lim = k.encode_limits(&mut enc, &views, w, h, m, radius).unwrap();
    ctx.queue.submit([enc.finish()]);
    assert_eq!(lim.source_size, (w * m, h * m));
    (lim.read(ctx).unwrap(), read_buffer::<u32>(ctx, &lim.empty, ds[0].len()).unwrap())
}

/// The CPU's measurements: `BackgroundLimits::of_multisampled` and the empty-background rule
/// (every layer's depth >= 1).
fn cpu_limits(
    ds: &[Image<f32>],
    ms: &[Image<Motion>],
    w: u32,
    h: u32,
    m: u32,
    radius: u32,
) -> (BackgroundLimits, Vec<u32>) {
    let layers: Vec<WarpLayer> = ds.iter().zip(ms).map(|(d, m)| WarpLayer { depth: d, motion: m }).collect();
    let limits = BackgroundLimits::of_multisampled(&layers, w, h, m, radius).unwrap();
    let empty = (0..ds[0].len()).map(|i| ds.iter().all(|d| d.data()[i] >= EMPTY_DEPTH) as u32).collect();
    (limits, empty)
}

/// The background protocol's measurements on the GPU (`HoleFillKernel::encode_limits`: the
/// surfaces' motion range reduced with atomics on order keys, then `BackgroundLimits`'
/// arithmetic in WGSL) equal `BackgroundLimits::of_multisampled` and the CPU's empty-background
/// mask: on the pan scenes (one layer and a separate ground, one and 2x2 samples per pixel,
/// radii 1, 5 and 64), on an all-empty source (no surface: bracket and reach 1), on motion
/// wider than both caps, on negative-only and sub-pixel motion.
#[test]
fn limits_equal_the_cpu() {
    let Some(ctx) = test_context() else { return };
    let k = HoleFillKernel::new(&ctx).unwrap();
    // (depth layers, motion layers, warped width, height, multisample)
    type Case = (Vec<Image<f32>>, Vec<Image<Motion>>, u32, u32, u32);
    let mut cases: Vec<Case> = Vec::new();
    for (w, h, seed, pan) in [(37u32, 23u32, 3u64, Vec2::new(3.5, -1.25)), (20, 31, 77, Vec2::new(-6.0, 9.5))] {
        for m in [1u32, 2] {
            let (ds, ms) = background_scene(w * m, h * m, seed, pan * m as f32);
            for layers in [1usize, 2] {
                cases.push((ds[..layers].to_vec(), ms[..layers].to_vec(), w, h, m));
            }
        }
    }
    let constant = |w: u32, h: u32, z: f32, v: Vec2| {
        let d = Image::new(w, h, z);
        let m = Image::new(w, h, Motion { v, depth: z });
        (vec![d], vec![m])
    };
    // All empty (sky only): moving, but no surface.
    let (d, m) = constant(19, 11, EMPTY_DEPTH, Vec2::new(40.0, -3.0));
    cases.push((d, m, 19, 11, 1));
    // Wider than the bracket cap (64) and the image; behind-eye samples (1e9) among them.
    let (mut d, mut m) = constant(40, 30, 0.5, Vec2::new(-300.0, 120.0));
    m[0].data_mut()[17] = Motion { v: Vec2::splat(1e9), depth: 1.0 };
    d[0].data_mut()[5] = EMPTY_DEPTH;
    cases.push((d, m, 40, 30, 1));
    // Negative only, sub-pixel range.
    let (d, _) = constant(16, 12, 0.3, Vec2::ZERO);
    let v = |x: u32, y: u32| Vec2::new(-2.25 - 0.05 * x as f32, -0.5 - 0.01 * y as f32);
    let m = vec![Image::from_fn(16, 12, |x, y| Motion { v: v(x, y), depth: 0.3 })];
    cases.push((d, m, 16, 12, 1));
    for (ds, ms, w, h, m) in &cases {
        for radius in [1, 5, 64] {
            let gpu = gpu_limits(&ctx, &k, (ds, ms), (*w, *h, *m), radius);
            let cpu = cpu_limits(ds, ms, *w, *h, *m, radius);
            assert_eq!(gpu.0, cpu.0, "{w}x{h} m {m} L={} radius {radius}", ds.len());
            assert_eq!(gpu.1, cpu.1, "empty mask {w}x{h} m {m} L={}", ds.len());
        }
    }
    // The all-empty source measures no surface; the wide one hits both caps.
    assert_eq!(cpu_limits(&cases[8].0, &cases[8].1, 19, 11, 1, 64).0, BackgroundLimits { bracket: 1, reach: 1 });
    assert_eq!(cpu_limits(&cases[9].0, &cases[9].1, 40, 30, 1, 64).0, BackgroundLimits { bracket: 64, reach: 40 });
}

/// Motion the CPU rejects (NaN, infinite) is not checked on the GPU-resident path, but the
/// measured limits stay bounded (the widest ones: bracket = radius, reach = max(w, h)), and the
/// background protocol over them finishes.
#[test]
fn limits_of_non_finite_motion_stay_bounded() {
    let Some(ctx) = test_context() else { return };
    let k = HoleFillKernel::new(&ctx).unwrap();
    let (w, h) = (24u32, 18u32);
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -f32::NAN] {
        let d = Image::from_fn(w, h, |x, _| if x < 12 { 0.4 } else { EMPTY_DEPTH });
        let mut m = d.map(|&z| Motion { v: Vec2::new(1.5, 0.0), depth: z });
        m.data_mut()[30].v.y = bad;
        let (limits, _) = gpu_limits(&ctx, &k, (std::slice::from_ref(&d), std::slice::from_ref(&m)), (w, h, 1), 7);
        assert_eq!(limits, BackgroundLimits { bracket: 7, reach: w.max(h) }, "motion {bad}");
        let bufs = upload(&ctx, std::slice::from_ref(&d), std::slice::from_ref(&m));
        let views = [GpuWarpLayer { depth: &bufs[0].0, motion: &bufs[0].1, axis: Vec2::X }];
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        let warped = WarpKernel::new(&ctx).unwrap().encode(&mut enc, &views, w, h, &WarpParams::default()).unwrap();
        let search = zwarp_warp::WarpParams::default().search();
        let out = k.encode_background(&mut enc, &warped, &views, 7, &search).unwrap();
        ctx.queue.submit([enc.finish()]);
        assert_eq!(out.read(&ctx).unwrap().depth.size(), (w, h));
    }
}

/// `encode_limits`' errors: the CPU's for no layer and a bad radius, and buffers too small for
/// the multisampled source.
#[test]
fn limits_bad_input_is_an_error() {
    let Some(ctx) = test_context() else { return };
    let k = HoleFillKernel::new(&ctx).unwrap();
    let (ds, ms) = background_scene(10, 8, 1, Vec2::ONE);
    let bufs = upload(&ctx, &ds[..1], &ms[..1]);
    let views = [GpuWarpLayer { depth: &bufs[0].0, motion: &bufs[0].1, axis: Vec2::X }];
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    let err = |r: zwarp_core::Result<_>| r.map(|_: zwarp_warp::gpu::GpuBackgroundLimits| ()).unwrap_err().to_string();
    assert!(err(k.encode_limits(&mut enc, &[], 10, 8, 1, 4)).contains("at least one source layer"));
    assert!(err(k.encode_limits(&mut enc, &views, 10, 8, 1, 0)).contains("radius must be in 1..=64"));
    assert!(err(k.encode_limits(&mut enc, &views, 10, 8, 2, 4)).contains("too small for 20x16"));
    assert!(err(k.encode_limits(&mut enc, &views, 10, 8, 0, 4)).contains("10x8"));
}
