//! The AVX2 builds of the preparation, the warp, the background fill and the forward baselines
//! (VFW, AFW) compute exactly what the portable code computes, and so do the AVX-512 builds
//! where the CPU has them (the warp's walks, VFW, the floor pass): every build on the same
//! inputs, compared bit for bit. (Its own test
//! binary: `simd::set_simd` is process-wide.) Where the CPU has no AVX2 both runs take the
//! portable code and the test checks nothing new; it says so.

use glam::{Vec2, Vec3};
use proptest::prelude::*;
use zwarp_core::{motion_field, Camera, Image, Motion, ParallaxMotion};
use zwarp_warp::synth::{SynthBox, SynthScene};
use zwarp_warp::*;

/// Held while a test runs both builds: the switch is process-wide and the tests of this binary
/// run on several threads.
static SWITCH: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Depth bits, states and source positions (bits) of a warp.
type Bits = (Vec<u32>, Vec<u8>, Option<Vec<(u32, u32, u32)>>);

fn bits(out: &WarpOutput) -> Bits {
    (
        out.depth.data().iter().map(|z| z.to_bits()).collect(),
        out.state.data().iter().map(|s| *s as u8).collect(),
        out.source.as_ref().map(|s| s.data().iter().map(|p| (p.q.x.to_bits(), p.q.y.to_bits(), p.layer)).collect()),
    )
}

/// The warp (and, for the background policy, the complete fill) of `layers` with both builds.
fn both(layers: &[WarpLayer<'_>], params: &WarpParams) -> (WarpOutput, WarpOutput) {
    let _switch = SWITCH.lock().unwrap_or_else(|e| e.into_inner());
    let run = |simd: bool| {
        simd::set_simd(simd);
        let prepared = PreparedLayer::prepare_stack(layers, params.bound).unwrap();
        let wp = WarpParams { holes: HolePolicy::FarDepth, ..*params };
        let mut out =
            warp_prepared(&prepared, if matches!(params.holes, HolePolicy::Background { .. }) { &wp } else { params })
                .unwrap();
        if let HolePolicy::Background { radius } = params.holes {
            holes::fill_background(layers, &mut out, radius, &params.search()).unwrap();
        }
        out
    };
    let fast = run(true);
    // The AVX2 build of the walks (the AVX-512 one runs where the CPU has it): the same bits.
    simd::set_avx512(false);
    let narrow = run(true);
    simd::set_avx512(true);
    assert!(bits(&fast) == bits(&narrow), "the AVX-512 and AVX2 builds differ");
    let portable = run(false);
    simd::set_simd(true);
    (fast, portable)
}

fn city(w: u32, h: u32, layers: u32, m: u32) -> (Vec<Image<f32>>, Vec<Image<Motion>>) {
    let mut scene = SynthScene::city(3);
    scene.boxes.push(SynthBox {
        aabb: zwarp_core::Aabb::new(Vec3::new(-1.0, 2.0, 3.0), Vec3::new(1.0, 4.0, 5.0)),
        velocity: Vec3::new(4.0, 0.0, 0.0),
    });
    let cam =
        |eye: Vec3, target: Vec3| Camera::perspective(eye, target, Vec3::Y, 1.0, 0.5, 200.0, w * m, h * m).unwrap();
    let a = cam(Vec3::new(0.0, 9.0, 22.0), Vec3::ZERO);
    let b = cam(Vec3::new(1.2, 9.4, 20.5), Vec3::new(0.4, 0.2, 0.0));
    let src = scene.render(&a, 0.0, layers, layers > 1);
    let deltas = scene.object_deltas(0.0, 0.25);
    let motions =
        src.depth.iter().zip(&src.items).map(|(d, it)| motion_field(d, Some(it), &a, &b, &deltas).unwrap()).collect();
    (src.depth, motions)
}

#[test]
fn avx2_warp_equals_the_portable_warp_on_a_moving_city() {
    if !simd::has_avx2() {
        eprintln!("note: no AVX2 on this CPU; both runs take the portable code");
    }
    let (w, h) = (97, 61);
    let (depth, motion) = city(w, h, 3, 1);
    for l in [1usize, 2, 3] {
        let layers: Vec<WarpLayer> =
            depth.iter().zip(&motion).take(l).map(|(d, m)| WarpLayer { depth: d, motion: m }).collect();
        for bound in [BoundKind::Global, BoundKind::Tight, BoundKind::Oriented] {
            for (n, t) in [(1, 3), (4, 1), (4, 3), (16, 3)] {
                for (cross_layer, choice) in
                    [(true, CandidateChoice::MinDepth), (false, CandidateChoice::FirstConverged)]
                {
                    for holes in [HolePolicy::FarDepth, HolePolicy::Background { radius: 8 }, HolePolicy::Awoc] {
                        let params = WarpParams {
                            n_seeds: n,
                            iterations: t,
                            bound,
                            cross_layer,
                            choice,
                            holes,
                            record_source: true,
                            // The third rendered layer is the ground alone.
                            ground_layer: l == 3,
                            ..WarpParams::default()
                        };
                        let (a, b) = both(&layers, &params);
                        assert!(bits(&a) == bits(&b), "L={l} {bound:?} N={n} T={t} {cross_layer} {choice:?} {holes:?}");
                    }
                }
            }
        }
    }
}

/// Tiles whose region holds one solution (`PreparedLayer::unique_solution`: a walk toward a wall
/// past a box, `synth::approach_field`, contracting or magnified) take one seed per lane; the
/// AVX2 gradient texels and the lanes' one-seed pass equal the portable ones, with the box's
/// tiles on the complete path.
#[test]
fn avx2_warp_equals_the_portable_warp_approaching_a_wall() {
    for (w, h, s) in [(64u32, 48u32, 0.4f32), (77, 45, 0.3), (64, 48, 0.8), (77, 45, 1.5)] {
        let (d, m) = synth::approach_field(w, h, s);
        let layers = [WarpLayer { depth: &d, motion: &m }];
        for bound in [BoundKind::Tight, BoundKind::Oriented] {
            for n in [1, 4, 16] {
                let params = WarpParams { n_seeds: n, bound, record_source: true, ..WarpParams::default() };
                let (a, b) = both(&layers, &params);
                assert!(bits(&a) == bits(&b), "{w}x{h} s={s} {bound:?} N={n}");
            }
        }
    }
}

/// Nearest sampling (WOC's warp, seed 000 Sec. 5: the exact texel depths) through the lanes.
#[test]
fn avx2_warp_equals_the_portable_warp_with_nearest_sampling() {
    let (w, h) = (97, 61);
    let (depth, motion) = city(w, h, 3, 1);
    for l in [1usize, 3] {
        let layers: Vec<WarpLayer> =
            depth.iter().zip(&motion).take(l).map(|(d, m)| WarpLayer { depth: d, motion: m }).collect();
        for bound in [BoundKind::Tight, BoundKind::Oriented] {
            for (n, t) in [(1, 3), (8, 3), (16, 1)] {
                for holes in [HolePolicy::FarDepth, HolePolicy::Background { radius: 8 }] {
                    let params = WarpParams {
                        n_seeds: n,
                        iterations: t,
                        bound,
                        holes,
                        sampling: Sampling::Nearest,
                        record_source: true,
                        ..WarpParams::default()
                    };
                    let (a, b) = both(&layers, &params);
                    assert!(bits(&a) == bits(&b), "L={l} {bound:?} N={n} T={t} {holes:?}");
                }
            }
        }
    }
}

/// The sparse warp (`warp_pixels`, the soft shadows' look-ups listed tile by tile) takes its
/// tile stages eight at a time with AVX2, also under a `WarpParams::motion_scale` (the mipmap's
/// bounds scaled as `Bound::scaled` scales them: negative, zero and mixed factors): the same
/// depths and states as the portable stages, one tile at a time.
#[test]
fn avx2_sparse_warp_equals_the_portable_one_with_a_motion_scale() {
    let (w, h) = (97, 61);
    let (depth, motion) = city(w, h, 3, 1);
    let mut tiled: Vec<u32> = (0..w * h).filter(|i| i % 3 != 1).collect();
    tiled.sort_by_key(|&i| ((i / w / 4, i % w / 4), i / w, i % w));
    for l in [1usize, 3] {
        let layers: Vec<WarpLayer> =
            depth.iter().zip(&motion).take(l).map(|(d, m)| WarpLayer { depth: d, motion: m }).collect();
        for s in [Vec2::ONE, Vec2::new(0.5, 1.7), Vec2::new(-1.0, 0.3), Vec2::new(0.0, -0.8)] {
            for bound in [BoundKind::Tight, BoundKind::Global] {
                let params = WarpParams { n_seeds: 4, bound, motion_scale: s, ..WarpParams::default() };
                let _switch = SWITCH.lock().unwrap_or_else(|e| e.into_inner());
                let sparse = |simd: bool| {
                    simd::set_simd(simd);
                    let scales = MotionScales::for_scale(s);
                    let prepared = PreparedLayer::prepare_stack_for(&layers, params.bound, scales, Vec::new()).unwrap();
                    let r = warp_pixels(&prepared, &params, &tiled).unwrap();
                    r.iter().map(|(z, st)| (z.to_bits(), *st as u8)).collect::<Vec<_>>()
                };
                let (fast, portable) = (sparse(true), sparse(false));
                simd::set_simd(true);
                assert!(fast == portable, "L={l} s={s} {bound:?}");
                let converged = fast.iter().filter(|p| p.1 == PixelState::Converged as u8).count();
                assert!(converged > tiled.len() / 4, "L={l} s={s} {bound:?}: too few converged to test anything");
            }
        }
    }
}

#[test]
fn avx2_warp_equals_the_portable_warp_on_multisampled_sources() {
    let (w, h) = (45, 29);
    for m in [2u32, 3] {
        let (depth, motion) = city(w, h, 2, m);
        let layers: Vec<WarpLayer> =
            depth.iter().zip(&motion).map(|(d, m)| WarpLayer { depth: d, motion: m }).collect();
        for n in [1, 8] {
            let params = WarpParams { n_seeds: n, multisample: m, record_source: true, ..WarpParams::default() };
            let (a, b) = both(&layers, &params);
            assert!(bits(&a) == bits(&b), "m={m} N={n}");
            let params = WarpParams { holes: HolePolicy::Background { radius: 16 }, ..params };
            let (a, b) = both(&layers, &params);
            assert!(bits(&a) == bits(&b), "m={m} N={n} background fill");
        }
    }
}

/// VFW and AFW of `layers` with both builds, as depth bits: (AVX2, portable) per method.
fn forward_both(layers: &[WarpLayer<'_>]) -> [(Vec<u32>, Vec<u32>); 2] {
    let _switch = SWITCH.lock().unwrap_or_else(|e| e.into_inner());
    let run = |simd: bool, f: fn(&[WarpLayer<'_>]) -> zwarp_core::Result<Image<f32>>| {
        simd::set_simd(simd);
        let out = f(layers).unwrap().data().iter().map(|z| z.to_bits()).collect::<Vec<_>>();
        simd::set_simd(true);
        out
    };
    simd::set_avx512(false);
    let narrow = run(true, vfw_layers);
    simd::set_avx512(true);
    let wide = run(true, vfw_layers);
    assert!(wide == narrow, "VFW: the AVX-512 and AVX2 builds differ");
    [(wide, run(false, vfw_layers)), (run(true, afw_layers), run(false, afw_layers))]
}

/// The streaming floor pass: its AVX-512, AVX2 and portable builds write the same values.
#[test]
fn the_floor_pass_builds_agree() {
    let (depth, motion) = city(131, 77, 3, 1);
    let layers: Vec<WarpLayer> = depth.iter().zip(&motion).map(|(d, m)| WarpLayer { depth: d, motion: m }).collect();
    let _switch = SWITCH.lock().unwrap_or_else(|e| e.into_inner());
    let run = |simd: bool, wide: bool| {
        simd::set_simd(simd);
        simd::set_avx512(wide);
        let mut out = vec![0f32; 131 * 77];
        floor::floor_pass(&layers, 1, 131, &mut out).unwrap();
        simd::set_simd(true);
        simd::set_avx512(true);
        out.iter().map(|z| z.to_bits()).collect::<Vec<_>>()
    };
    let wide = run(true, true);
    assert_eq!(wide, run(true, false));
    assert_eq!(wide, run(false, false));
    assert!(wide.iter().any(|&z| f32::from_bits(z) < 1.0), "no surface to compare");
}

#[test]
fn avx2_forward_warps_equal_the_portable_ones_on_a_moving_city() {
    let (depth, motion) = city(131, 77, 3, 1);
    for l in [1usize, 3] {
        let layers: Vec<WarpLayer> =
            depth.iter().zip(&motion).take(l).map(|(d, m)| WarpLayer { depth: d, motion: m }).collect();
        for (k, (fast, portable)) in forward_both(&layers).into_iter().enumerate() {
            assert!(fast == portable, "{} at L = {l}", ["VFW", "AFW"][k]);
        }
    }
}

/// A smooth field with a hole and strong rotation-like parts: the PCA frame is used.
/// The bits of a preparation: its samples, frame, surfaces' motion range and every texel.
fn prep_bits(p: &[PreparedLayer]) -> Vec<(Vec<u32>, BoundFrame, String, Vec<String>)> {
    p.iter()
        .map(|l| {
            let pl = l.planes();
            let samples = pl.vx.iter().chain(&pl.vy).chain(&pl.z).map(|v| v.to_bits()).collect();
            let py = l.pyramid();
            let texels = (1..=py.top_level())
                .flat_map(|level| {
                    let (lw, lh) = py.level_size(level);
                    (0..lh).flat_map(move |ty| (0..lw).map(move |tx| format!("{:?}", py.texel(level, tx, ty))))
                })
                .collect();
            (samples, py.frame(), format!("{:?}", l.surfaces()), texels)
        })
        .collect()
}

/// A recycled stack remembers the frame it chose, and the next preparation's pass writes that
/// frame's texels only (or both, where the choice changes): in both builds the same
/// preparation as a fresh one, on fields where the oriented frame wins and where the
/// axis-aligned one does.
#[test]
fn recycled_preparations_equal_fresh_ones_in_both_builds() {
    let _switch = SWITCH.lock().unwrap_or_else(|e| e.into_inner());
    let fields = [field(83, 47, [0.3, 1.0, 0.2, 0.5]), field(83, 47, [1.1, 0.0, 2.0, 1.5])];
    let mut frames = Vec::new();
    let mut builds = Vec::new();
    for simd in [true, false] {
        simd::set_simd(simd);
        let mut recycled = Vec::new();
        let mut seen = Vec::new();
        for k in [0usize, 0, 1, 1, 0, 1] {
            let layers = [WarpLayer { depth: &fields[k].0, motion: &fields[k].1 }];
            let fresh = PreparedLayer::prepare_stack(&layers, BoundKind::Oriented).unwrap();
            let got = PreparedLayer::prepare_stack_recycling(&layers, BoundKind::Oriented, recycled).unwrap();
            assert!(prep_bits(&got) == prep_bits(&fresh), "field {k}, simd {simd}");
            seen.push(prep_bits(&got));
            frames.push(fresh[0].pyramid().frame().is_identity());
            // The oriented frame is a candidate on both fields (else its texels are never written).
            let samples: Vec<Motion> = fields[k]
                .1
                .data()
                .iter()
                .zip(fields[k].0.data())
                .map(|(m, &d)| if d < 1.0 { *m } else { Motion { v: Vec2::ZERO, depth: f32::INFINITY } })
                .collect();
            assert!(!bounds::pca_frame(&samples, 83, 47, 64).is_identity(), "field {k}");
            recycled = got;
        }
        builds.push(seen);
    }
    simd::set_simd(true);
    assert!(builds[0] == builds[1], "the AVX2 and portable preparations differ");
    assert!(frames.contains(&true) && frames.contains(&false), "the fields must choose both frames: {frames:?}");
}

/// A preparation from a parallax field (`PreparedLayer::new_parallax`: the field evaluated in
/// the pass) equals the preparation of the buffer of that field (`ParallaxMotion::motion` per
/// pixel) bit for bit, in both builds: perspective and orthographic views, `1/z` and pivoted
/// parallax, empty pixels, widths with and without an AVX2 tail, every bound kind; and both
/// builds agree.
#[test]
fn parallax_preparations_equal_the_preparation_of_their_field_in_both_builds() {
    let _switch = SWITCH.lock().unwrap_or_else(|e| e.into_inner());
    let mut builds = Vec::new();
    for simd in [true, false] {
        simd::set_simd(simd);
        let mut seen = Vec::new();
        for (w, h) in [(64u32, 40u32), (83, 47), (5, 3)] {
            let depth = Image::from_fn(w, h, |x, y| {
                if (x * 7 + y * 3) % 11 == 0 {
                    1.0
                } else {
                    0.05 + 0.9 * ((x * 13 + y * 29) % 97) as f32 / 97.0
                }
            });
            for (perspective, pivot) in [(true, None), (false, Some(3.5)), (true, Some(0.7)), (false, None)] {
                let p = ParallaxMotion { shift: Vec2::new(2.5, -1.75), near: 0.3, far: 40.0, perspective, pivot };
                let motion = Image::from_fn(w, h, |x, y| p.motion(*depth.get(x, y)));
                for bound in [BoundKind::Tight, BoundKind::Oriented, BoundKind::Global] {
                    for scales in [MotionScales::AtLeastOne, MotionScales::Any] {
                        let direct = PreparedLayer::new_parallax(&depth, &p, bound, scales).unwrap();
                        let layer = [WarpLayer { depth: &depth, motion: &motion }];
                        let buffered = PreparedLayer::prepare_stack_for(&layer, bound, scales, Vec::new()).unwrap();
                        let a = prep_bits(std::slice::from_ref(&direct));
                        assert!(a == prep_bits(&buffered), "{w}x{h} {p:?} {bound:?} {scales:?} simd {simd}");
                        seen.push(a);
                    }
                }
            }
        }
        builds.push(seen);
    }
    simd::set_simd(true);
    assert!(builds[0] == builds[1], "the AVX2 and portable parallax preparations differ");
    let depth = Image::new(8, 8, 0.5f32);
    let bad = ParallaxMotion { shift: Vec2::new(f32::NAN, 0.0), near: 0.3, far: 40.0, perspective: true, pivot: None };
    let e = PreparedLayer::new_parallax(&depth, &bad, BoundKind::Tight, MotionScales::Any)
        .err()
        .expect("a NaN shift is an error");
    assert!(e.to_string().contains("parallax motion must be finite"), "{e}");
    let nan_depth = Image::from_fn(8, 8, |x, _| if x == 3 { f32::NAN } else { 0.5 });
    let ok = ParallaxMotion { shift: Vec2::ONE, ..bad };
    assert!(PreparedLayer::new_parallax(&nan_depth, &ok, BoundKind::Tight, MotionScales::Any).is_err());
}

/// The row patterns of `synth` behind the multi-layer coverage tests (a seam between three
/// layers' views of a wall, a ground layer seen through a gap, a wall that may continue behind
/// a column): every build gives the same warp.
#[test]
fn avx2_warp_equals_the_portable_warp_on_the_layer_patterns() {
    use zwarp_warp::synth::{continuation_layers, ground_gap_layers, seam_layers, BesideWall};
    let far = WarpParams { n_seeds: 4, holes: HolePolicy::FarDepth, ..WarpParams::default() };
    let mut cases = Vec::new();
    for sliver in [true, false] {
        cases.push((seam_layers(sliver), 4, WarpParams { cover_radius: 0.5, ..far }));
    }
    for (g, ground_layer) in [(0.8, true), (0.8, false), (0.95, true)] {
        cases.push((ground_gap_layers(g), 2, WarpParams { ground_layer, ..far }));
    }
    for beside in [BesideWall::Column, BesideWall::Ends, BesideWall::SameDepth] {
        cases.push((continuation_layers(beside), 3, far));
    }
    for (ls, n, params) in &cases {
        for l in 1..=*n {
            let layers: Vec<WarpLayer> = ls[..l].iter().map(|(d, m)| WarpLayer { depth: d, motion: m }).collect();
            let (fast, portable) = both(&layers, params);
            assert!(bits(&fast) == bits(&portable), "L = {l} of {n}, {params:?}");
        }
    }
}

fn field(w: u32, h: u32, c: [f32; 4]) -> (Image<f32>, Image<Motion>) {
    let depth = Image::from_fn(w, h, |x, y| {
        let (dx, dy) = (x as f32 - 0.3 * w as f32, y as f32 - 0.6 * h as f32);
        if dx * dx + dy * dy < 20.0 || (x + 3 * y) % 23 == 0 {
            1.0
        } else {
            0.3 + 0.4 * ((x as f32 * 0.13 + c[0]).sin() * 0.5 + 0.5)
        }
    });
    let motion = Image::from_fn(w, h, |x, y| {
        let (fx, fy) = (x as f32 / w as f32, y as f32 / h as f32);
        let t = c[1] * 6.0 * fx + 2.0 * (fy * 3.0 + c[2]).sin();
        let v = Vec2::new(t + c[3] * 3.0 * (fx * 5.0).cos(), 0.8 * t - 1.0 + 1.5 * (fx * 2.0 + fy).sin());
        Motion { v, depth: *depth.get(x, y) * 0.98 }
    });
    (depth, motion)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    /// Random sizes (odd, not multiples of the tile or of eight), fields, N and T, both bound
    /// kinds that tighten: bit-identical warps.
    #[test]
    fn avx2_warp_equals_the_portable_warp_on_random_fields(
        w in 9u32..70, h in 5u32..40, a in -1.0f32..1.0, b in -1.5f32..1.5, c in 0.0f32..6.0, d in -1.0f32..1.0,
        n in 1u32..20, t in 1u32..5, oriented in any::<bool>(), accelerate in any::<bool>(),
        nearest in any::<bool>(),
    ) {
        let (depth, motion) = field(w, h, [a, b, c, d]);
        let layers = [WarpLayer { depth: &depth, motion: &motion }];
        let bound = if oriented { BoundKind::Oriented } else { BoundKind::Tight };
        let sampling = if nearest { Sampling::Nearest } else { Sampling::Adaptive };
        let params = WarpParams {
            n_seeds: n, iterations: t, bound, accelerate, sampling, record_source: true, ..WarpParams::default()
        };
        let (x, y) = both(&layers, &params);
        prop_assert!(bits(&x) == bits(&y));
    }

    /// Random fields through the forward baselines: bit-identical builds.
    #[test]
    fn avx2_forward_warps_equal_the_portable_ones_on_random_fields(
        w in 9u32..90, h in 3u32..50, a in -1.0f32..1.0, b in -1.5f32..1.5, c in 0.0f32..6.0, d in -1.0f32..1.0,
    ) {
        let (depth, motion) = field(w, h, [a, b, c, d]);
        for (fast, portable) in forward_both(&[WarpLayer { depth: &depth, motion: &motion }]) {
            prop_assert!(fast == portable);
        }
    }
}
