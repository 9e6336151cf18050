//! GPU min-max motion mipmap vs `zwarp_warp::MotionPyramid` (seed 000 Sec. 3.3), including odd
//! and prime sizes, invalid samples and oriented frames; and the whole GPU chain render ->
//! motion -> pyramid vs the CPU chain.

use zwarp_testkit as common;

use common::*;
use glam::Vec2;
use proptest::prelude::*;
use zwarp_core::{motion_field, Image, Motion};
use zwarp_gpu::{test_context, FrameOptions, GpuContext, GpuScene, Renderer};
use zwarp_warp::gpu::{MotionKernel, PyramidKernel};
use zwarp_warp::{BoundFrame, MotionPyramid};

/// Every level and texel equal (bit-exact for the axis-aligned frame: min/max of the same
/// values; 1e-4 px for rotated frames, whose rotation may be FMA-contracted on the GPU).
fn compare(ctx: &GpuContext, motion: &Image<Motion>, axis: Vec2) {
    let k = PyramidKernel::new(ctx).unwrap();
    let gpu = k.build(motion, axis).unwrap().read(ctx).unwrap();
    let cpu = MotionPyramid::build_in_frame(motion, BoundFrame { axis }).unwrap();
    assert_eq!(gpu.len() as u32, cpu.top_level(), "level count for {:?}", motion.size());
    let tol = if axis == Vec2::X { 0.0 } else { 1e-4 };
    for (l, level) in gpu.iter().enumerate() {
        let lvl = l as u32 + 1;
        assert_eq!(level.size(), cpu.level_size(lvl), "level {lvl} size");
        for ty in 0..level.height() {
            for tx in 0..level.width() {
                let g = *level.get(tx, ty);
                let c = cpu.texel(lvl, tx, ty);
                let cv = [c.lo.x, c.lo.y, c.hi.x, c.hi.y];
                for k in 0..4 {
                    let same = g[k] == cv[k] || (g[k] - cv[k]).abs() <= tol * (1.0 + cv[k].abs());
                    assert!(same, "level {lvl} texel ({tx},{ty}): gpu {g:?} cpu {cv:?}");
                }
            }
        }
    }
}

fn synthetic(w: u32, h: u32, seed: u32) -> Image<Motion> {
    Image::from_fn(w, h, |x, y| {
        let hsh = (x.wrapping_mul(73856093) ^ y.wrapping_mul(19349663) ^ seed.wrapping_mul(83492791)) % 1000;
        let depth = match hsh % 10 {
            0 => 1.0,  // empty / left the target depth range
            1 => -0.1, // in front of the near plane: invalid
            _ => 0.5 + hsh as f32 / 2500.0,
        };
        Motion { v: Vec2::new(x as f32 * 0.37 - hsh as f32 * 0.01, y as f32 * -0.21 + (hsh % 17) as f32), depth }
    })
}

#[test]
fn odd_and_prime_sizes_match_cpu_pyramid() {
    let Some(ctx) = test_context() else { return };
    for (w, h) in [(1, 1), (2, 1), (1, 7), (13, 7), (31, 17), (128, 96), (97, 61)] {
        compare(&ctx, &synthetic(w, h, w * 31 + h), Vec2::X);
    }
}

#[test]
fn oriented_frame_and_all_invalid_match_cpu() {
    let Some(ctx) = test_context() else { return };
    compare(&ctx, &synthetic(45, 29, 3), Vec2::new(0.6, 0.8));
    // No valid sample: every texel is the empty bound (+inf, -inf).
    let empty = Image::new(9, 5, Motion { v: Vec2::ONE, depth: 1.0 });
    compare(&ctx, &empty, Vec2::X);
    let k = PyramidKernel::new(&ctx).unwrap();
    let top = k.build(&empty, Vec2::X).unwrap().read(&ctx).unwrap();
    assert_eq!(*top.last().unwrap().get(0, 0), [f32::INFINITY, f32::INFINITY, f32::NEG_INFINITY, f32::NEG_INFINITY]);
}

#[test]
fn pyramid_errors() {
    let Some(ctx) = test_context() else { return };
    let k = PyramidKernel::new(&ctx).unwrap();
    assert!(k.build(&Image::new(0, 3, Motion::default()), Vec2::X).is_err());
    assert!(k.build(&synthetic(4, 4, 0), Vec2::new(1.0, 1.0)).is_err());
    let mut nan = synthetic(4, 4, 0);
    nan.data_mut()[3].v.x = f32::NAN;
    assert!(k.build(&nan, Vec2::X).unwrap_err().to_string().contains("NaN"));
}

/// The GPU chain (render, motion field, mipmap) against the CPU chain on the test scene.
#[test]
fn render_motion_pyramid_chain_matches_cpu() {
    let Some(ctx) = test_context() else { return };
    let scene = test_scene();
    let gs = GpuScene::upload(&ctx, &scene).unwrap();
    let r = Renderer::new(&ctx).unwrap();
    let (a, b) = (camera_a(), camera_b());
    let f = r.render_frame(&gs, &a, 0.0, &FrameOptions::default()).unwrap();
    let deltas = scene.object_deltas(0.0, 0.25);
    let gm = MotionKernel::new(&ctx).unwrap().motion_field(&f.depth, Some(&f.items), &a, &b, &deltas).unwrap();
    let cm = motion_field(&f.depth, Some(&f.items), &a, &b, &deltas).unwrap();
    let gp = PyramidKernel::new(&ctx).unwrap().build(&gm, Vec2::X).unwrap().read(&ctx).unwrap();
    let cp = MotionPyramid::build(&cm).unwrap();
    let top = cp.global();
    let g = gp.last().unwrap().get(0, 0);
    for (gv, cv) in g.iter().zip([top.lo.x, top.lo.y, top.hi.x, top.hi.y]) {
        assert!((gv - cv).abs() < 1e-3, "global bound gpu {g:?} cpu {top:?}");
    }
    assert!(top.hi.x > top.lo.x, "the views differ, so motion varies");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 5, ..ProptestConfig::default() })]
    #[test]
    fn random_sizes_match_cpu(w in 1u32..70, h in 1u32..70, seed in 0u32..100) {
        let Some(ctx) = test_context() else { return Ok(()) };
        compare(&ctx, &synthetic(w, h, seed), Vec2::X);
    }
}
