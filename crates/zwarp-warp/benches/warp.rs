//! Depth-warp benchmark (seed 000 Table 1/3 style) on a synthetic 1920x1080 city: ground plus
//! 6x6 boxes ray cast analytically, peeled into 3 layers (the last = ground only), camera
//! motion through `zwarp_core::motion_field`. Measures the backward warp for N in {1, 4, 16}
//! and L in {1, 3} on one preparation (as many warps of one source share it: the first
//! layer's gradient texels, computed where the first warp looks them up, are then warm), the
//! warp of a fresh preparation every frame (`frame_L*`: preparation and warp, the per-frame
//! cost of a prediction without its hole protocol), the motion mipmap construction (MMC, part of the preparation, timed as an
//! engine runs it: `PreparedLayer::prepare_stack_recycling` into last frame's buffers), the
//! motion field itself (AVX2 and portable builds), the
//! VFW / AFW forward baselines side by side, a sparse warp of listed pixels with a motion scale
//! (AVX2 lanes and the portable kernel), a layer prepared from a parallax field (directly and
//! through a motion buffer), the AVX2 builds of the walks and of VFW beside
//! their AVX-512-enabled builds, and the streaming floor of the same inputs
//! (`floor::floor_pass`: one read of every layer, one write of the output).
//!
//! After the criterion groups a summary prints, per configuration: median wall time over a few
//! warm runs, the ratio to the floor, megapixels per second per core (rayon threads), and an estimate of bytes touched
//! per target pixel (counted texel reads x texel size, plus output writes), from an
//! instrumented replay of the single-layer search.
//!
//! `cargo bench -p zwarp-warp --bench warp` (set RAYON_NUM_THREADS to pin the core count).

use std::cell::Cell;
use std::time::Instant;

use criterion::{BenchmarkId, Criterion};
use glam::{Vec2, Vec3};
use zwarp_core::{motion_field, motion_field_into, Camera, Image, Motion, ParallaxMotion};
use zwarp_warp::search::{effective_seeds, seed_key, stratified_seeds};
use zwarp_warp::synth::SynthScene;
use zwarp_warp::*;

struct Case {
    depth: Vec<Image<f32>>,
    items: Vec<Image<u32>>,
    motion: Vec<Image<Motion>>,
    cams: (Camera, Camera),
}

fn build_case() -> Case {
    let (w, h) = (1920, 1080);
    let scene = SynthScene::city(6);
    let a = Camera::perspective(Vec3::new(0.0, 9.0, 22.0), Vec3::ZERO, Vec3::Y, 1.0, 0.5, 200.0, w, h).unwrap();
    let b = Camera::perspective(Vec3::new(0.8, 9.2, 21.0), Vec3::new(0.3, 0.0, 0.0), Vec3::Y, 1.0, 0.5, 200.0, w, h)
        .unwrap();
    let src = scene.render(&a, 0.0, 3, true);
    let motion =
        src.depth.iter().zip(&src.items).map(|(d, it)| motion_field(d, Some(it), &a, &b, &[]).unwrap()).collect();
    Case { depth: src.depth, items: src.items, motion, cams: (a, b) }
}

fn layers(case: &Case, l: usize) -> Vec<WarpLayer<'_>> {
    case.depth.iter().zip(&case.motion).take(l).map(|(d, m)| WarpLayer { depth: d, motion: m }).collect()
}

fn median_ms(runs: usize, mut f: impl FnMut()) -> (f64, f64, f64) {
    f(); // warm-up
    let mut t: Vec<f64> = (0..runs)
        .map(|_| {
            let t0 = Instant::now();
            f();
            t0.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    t.sort_by(|a, b| a.total_cmp(b));
    (t[runs / 2], t[0], t[runs - 1])
}

/// Counts texel reads of the single-layer search (the kernel's logic replayed through the
/// public API with a counting sampler) to estimate memory traffic per pixel. The replay
/// tightens per pixel from the global bound (no tile stage) and charges every tightening step,
/// so its look-up bytes are an upper bound of the kernel's.
fn traffic_per_pixel(prep: &PreparedLayer, params: &WarpParams) -> (f64, f64) {
    struct Counting<'a>(LayerSampler<'a>, &'a Cell<u64>);
    impl MotionSource for Counting<'_> {
        type Walk = ();
        fn sample(&self, q: Vec2, w: &mut ()) -> Option<Sample> {
            self.1.set(self.1.get() + 1);
            self.0.sample(q, w)
        }
    }
    let (w, h) = prep.size();
    let fetches = Cell::new(0u64);
    let src = Counting(prep.sampler(params, 0), &fetches);
    let sp = params.search();
    let mut lookups = 0u64;
    let mut seeds_total = 0u64;
    let mut seeds = [Vec2::ZERO; MAX_SEEDS as usize];
    // Every 4th pixel in both axes is representative and keeps this quick.
    let mut n_px = 0u64;
    for y in (0..h).step_by(4) {
        for x in (0..w).step_by(4) {
            n_px += 1;
            let p = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            lookups += 4 * (params.bound_iterations as u64 + 1);
            let Some(tb) = prep.pyramid().tight_bound(p, params.bound_iterations, params.sampling.footprint()) else {
                continue;
            };
            let n = effective_seeds(params.n_seeds, tb.region.extent());
            let n = stratified_seeds(&prep.pyramid().frame(), &tb.region, n, seed_key(x, y, 0), &mut seeds);
            seeds_total += n as u64;
            let _ = fixed_point_search(&src, p, &seeds[..n], &sp);
        }
    }
    // Adaptive sampling reads a 2x2 block of 12-byte motion texels; a mipmap look-up reads one
    // 16-byte min-max texel; the output writes 4 bytes of depth and 1 byte of state.
    let bytes = fetches.get() as f64 * 4.0 * 12.0 + lookups as f64 * 16.0 + n_px as f64 * 5.0;
    (bytes / n_px as f64, seeds_total as f64 / n_px as f64)
}

fn main() {
    let case = build_case();
    let mut c = Criterion::default().configure_from_args().sample_size(10);
    {
        let mut g = c.benchmark_group("depth_warp_1080p");
        g.sample_size(10);
        for l in [1usize, 3] {
            let ls = layers(&case, l);
            let mut floor_out = vec![0.0f32; 1920 * 1080];
            g.bench_with_input(BenchmarkId::new("floor", l), &l, |b, _| {
                b.iter(|| zwarp_warp::floor::floor_pass(&ls, 1, 1920, &mut floor_out).unwrap())
            });
            // The steady state of an engine: last frame's preparation recycled.
            let mut rec = Vec::new();
            g.bench_with_input(BenchmarkId::new("mmc_prepare", l), &l, |b, _| {
                b.iter(|| {
                    rec = PreparedLayer::prepare_stack_recycling(&ls, BoundKind::Oriented, std::mem::take(&mut rec))
                        .unwrap()
                })
            });
            let prepared = PreparedLayer::prepare_stack(&ls, BoundKind::Oriented).unwrap();
            // Outputs recycled too, as `zwarp eval` and an engine keep them.
            let (mut out, mut fwd) = (WarpOutput::empty(), Image::new(0, 0, 0.0f32));
            for n in [1u32, 4, 16] {
                let params = WarpParams { n_seeds: n, ..Default::default() };
                g.bench_with_input(BenchmarkId::new(format!("ours_L{l}"), n), &n, |b, _| {
                    b.iter(|| warp_prepared_into(&prepared, &params, &mut out).unwrap())
                });
            }
            // A frame of an engine: last frame's preparation recycled for this frame's layers, and
            // the warp on it (the gradient texels it asks for computed anew).
            let params = WarpParams { n_seeds: 4, ..Default::default() };
            let mut rec = Vec::new();
            g.bench_with_input(BenchmarkId::new(format!("frame_L{l}"), 4), &4, |b, _| {
                b.iter(|| {
                    rec = PreparedLayer::prepare_stack_recycling(&ls, BoundKind::Oriented, std::mem::take(&mut rec))
                        .unwrap();
                    warp_prepared_into(&rec, &params, &mut out).unwrap()
                })
            });
            // The AVX2 builds of the walks and of VFW beside the AVX-512-enabled ones (where the
            // CPU has AVX-512; elsewhere both rows time the AVX2 build).
            let params = WarpParams { n_seeds: 16, ..Default::default() };
            g.bench_with_input(BenchmarkId::new(format!("ours_L{l}_avx2_only"), 16), &16, |b, _| {
                zwarp_warp::simd::set_avx512(false);
                b.iter(|| warp_prepared_into(&prepared, &params, &mut out).unwrap());
                zwarp_warp::simd::set_avx512(true);
            });
            g.bench_with_input(BenchmarkId::new("vfw", l), &l, |b, _| {
                b.iter(|| vfw_layers_into(&ls, &mut fwd).unwrap())
            });
            g.bench_with_input(BenchmarkId::new("vfw_avx2_only", l), &l, |b, _| {
                zwarp_warp::simd::set_avx512(false);
                b.iter(|| vfw_layers_into(&ls, &mut fwd).unwrap());
                zwarp_warp::simd::set_avx512(true);
            });
            g.bench_with_input(BenchmarkId::new("afw", l), &l, |b, _| {
                b.iter(|| afw_layers_into(&ls, &mut fwd).unwrap())
            });
        }
        // A sparse warp (`warp_pixels`) as the soft shadows run it per light sample: scattered
        // listed texels, a motion scale on an axis-aligned preparation; the AVX2 lanes beside
        // the portable kernel.
        {
            let ls = layers(&case, 1);
            let prepared = PreparedLayer::prepare_stack(&ls, BoundKind::Tight).unwrap();
            let list: Vec<u32> = (0..1920 * 1080).step_by(7).collect();
            let params = WarpParams {
                n_seeds: 4,
                bound: BoundKind::Tight,
                motion_scale: Vec2::new(0.8, 1.3),
                holes: HolePolicy::FarDepth,
                ..Default::default()
            };
            for (name, simd) in [("sparse_L1", true), ("sparse_L1_portable", false)] {
                g.bench_function(name, |b| {
                    zwarp_warp::simd::set_simd(simd);
                    b.iter(|| warp_pixels(&prepared, &params, &list).unwrap());
                    zwarp_warp::simd::set_simd(true);
                });
            }
        }
        // A layer whose motion is a parallax of its depth (a light rig's sample eye): prepared
        // from the field directly, beside writing the field's buffer and preparing that.
        {
            let field = ParallaxMotion::of_camera(&case.cams.0, Vec2::new(3.0, -2.0), None);
            let depth = &case.depth[0];
            g.bench_function("prepare_parallax", |b| {
                b.iter(|| PreparedLayer::new_parallax(depth, &field, BoundKind::Tight, MotionScales::Any).unwrap())
            });
            g.bench_function("prepare_parallax_buffer", |b| {
                b.iter(|| {
                    let m = Image::from_vec(
                        depth.width(),
                        depth.height(),
                        depth.data().iter().map(|&d| field.motion(d)).collect(),
                    )
                    .unwrap();
                    PreparedLayer::new(&WarpLayer { depth, motion: &m }, BoundKind::Tight).unwrap()
                })
            });
        }
        // The motion of layer 0 (Sec. 3.1) into a reused buffer: the AVX2 build and the portable one.
        let mut out = Image::new(0, 0, Motion::default());
        let (a, b) = &case.cams;
        for (name, simd) in [("motion_field", true), ("motion_field_portable", false)] {
            g.bench_function(name, |bch| {
                zwarp_core::motion::set_simd(simd);
                bch.iter(|| motion_field_into(&case.depth[0], Some(&case.items[0]), a, b, &[], &mut out).unwrap());
                zwarp_core::motion::set_simd(true);
            });
        }
        g.finish();
    }
    c.final_summary();

    // Side-by-side summary (one run, warm, median of 5).
    let threads = rayon::current_num_threads();
    let px = 1920.0 * 1080.0;
    println!("\nsummary: 1920x1080, {threads} rayon thread(s); median [min, max] of 5 warm runs");
    {
        let mut out = Image::new(0, 0, Motion::default());
        let (a, b) = &case.cams;
        let mut motion = |simd: bool| {
            zwarp_core::motion::set_simd(simd);
            let r =
                median_ms(5, || motion_field_into(&case.depth[0], Some(&case.items[0]), a, b, &[], &mut out).unwrap());
            zwarp_core::motion::set_simd(true);
            r
        };
        let ((t, lo, hi), (tp, plo, phi)) = (motion(true), motion(false));
        println!(
            "motion field (layer 0): {t:.2} ms [{lo:.2}, {hi:.2}]; portable build {tp:.2} ms [{plo:.2}, {phi:.2}] ({:.1}x)",
            tp / t
        );
    }
    for l in [1usize, 3] {
        let ls = layers(&case, l);
        // The streaming floor of the same inputs (one read of every layer, one write; settled
        // over `floor::FLOOR_MIN_REPS` passes, as `zwarp eval` measures it): the ratios below
        // are kernel time over it.
        let (floor, flo, fhi) = zwarp_warp::floor::floor_ms(&ls, 1, 5).unwrap();
        println!("L={l} floor: {floor:.2} ms [{flo:.2}, {fhi:.2}]");
        let mut rec = Vec::new();
        let (t, lo, hi) = median_ms(5, || {
            rec = PreparedLayer::prepare_stack_recycling(&ls, BoundKind::Oriented, std::mem::take(&mut rec)).unwrap();
        });
        println!("L={l} MMC+prepare (recycled): {t:.1} ms [{lo:.1}, {hi:.1}], {:.1}x floor", t / floor);
        let prepared = PreparedLayer::prepare_stack(&ls, BoundKind::Oriented).unwrap();
        let (mut out, mut fwd) = (WarpOutput::empty(), Image::new(0, 0, 0.0f32));
        for n in [1u32, 4, 16] {
            let params = WarpParams { n_seeds: n, ..Default::default() };
            let (t, lo, hi) = median_ms(5, || warp_prepared_into(&prepared, &params, &mut out).unwrap());
            let mpx = px / (t * 1e-3) / 1e6 / threads as f64;
            let traffic = if l == 1 {
                let (b, s) = traffic_per_pixel(&prepared[0], &params);
                format!(", ~{b:.0} B/px touched, {s:.2} seeds/px")
            } else {
                String::new()
            };
            println!(
                "L={l} ours N={n:2}: {t:.1} ms [{lo:.1}, {hi:.1}], {:.1}x floor, {mpx:.2} Mpx/s/core{traffic}",
                t / floor
            );
        }
        {
            // The walks' AVX2 build at N = 16 (the AVX-512-enabled one is the row above).
            let params = WarpParams { n_seeds: 16, ..Default::default() };
            zwarp_warp::simd::set_avx512(false);
            let (t, lo, hi) = median_ms(5, || warp_prepared_into(&prepared, &params, &mut out).unwrap());
            zwarp_warp::simd::set_avx512(true);
            println!("L={l} ours N=16, AVX2 build only: {t:.1} ms [{lo:.1}, {hi:.1}], {:.1}x floor", t / floor);
        }
        for (name, f) in
            [("VFW", vfw_layers_into as fn(&[WarpLayer<'_>], &mut Image<f32>) -> _), ("AFW", afw_layers_into)]
        {
            let (t, lo, hi) = median_ms(5, || f(&ls, &mut fwd).unwrap());
            let mpx = px / (t * 1e-3) / 1e6 / threads as f64;
            println!("L={l} {name}: {t:.1} ms [{lo:.1}, {hi:.1}], {:.1}x floor, {mpx:.2} Mpx/s/core", t / floor);
        }
    }
}
