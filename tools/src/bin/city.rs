//! Prints warp quality on the synthetic city (seed 000 Sec. 4.2 style): non-converged fraction
//! and linear-depth error against the directly rendered target, for several N, L, hole policies
//! and the VFW/AFW baselines. `cargo run --release -p zwarp-tools --bin city -- [w h speed T plain|newton bound_iterations]`.

use glam::Vec3;
use std::time::Instant;
use zwarp_core::{motion_field, Camera, Image};
use zwarp_warp::synth::SynthScene;
use zwarp_warp::*;

fn stats(pred: &Image<f32>, reference: &Image<f32>, cam: &Camera) -> (f64, f64, f64) {
    // PSNR on linear depth normalised by the reference's nearest/farthest surface
    // (ARCHITECTURE.md "Evaluation protocol").
    let lin: Vec<f32> = reference.data().iter().filter(|d| **d < 1.0).map(|d| cam.linear_depth(*d)).collect();
    let (lo, hi) = lin.iter().fold((f32::MAX, f32::MIN), |(a, b), v| (a.min(*v), b.max(*v)));
    let norm = |d: f32| if d >= 1.0 { 1.0 } else { ((cam.linear_depth(d) - lo) / (hi - lo)).clamp(0.0, 1.0) };
    let mut mse = 0.0f64;
    let mut unsafe_px = 0usize;
    let mut bad = 0usize;
    for (p, r) in pred.data().iter().zip(reference.data()) {
        let e = (norm(*p) - norm(*r)) as f64;
        mse += e * e;
        // Unsafe for culling: nearer than the reference by more than 0.5 % in linear depth.
        if *r < 1.0 && cam.linear_depth(*p) < 0.995 * cam.linear_depth(*r) {
            unsafe_px += 1;
        }
        if e.abs() > 0.01 {
            bad += 1;
        }
    }
    mse /= pred.len() as f64;
    let n = pred.len() as f64;
    (10.0 * (1.0 / mse.max(1e-12)).log10(), unsafe_px as f64 / n, bad as f64 / n)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let w: u32 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(640);
    let h: u32 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(360);
    let speed: f32 = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(1.0);
    let t_iter: u32 = args.get(4).and_then(|s| s.parse().ok()).unwrap_or(3);
    let accelerate = args.get(5).map(|s| s != "plain").unwrap_or(true);
    let bound_iterations: u32 = args.get(6).and_then(|s| s.parse().ok()).unwrap_or(6);
    let scene = SynthScene::city(6);
    let a = Camera::perspective(Vec3::new(0.0, 9.0, 22.0), Vec3::new(0.0, 0.0, 0.0), Vec3::Y, 1.0, 0.5, 200.0, w, h)
        .unwrap();
    let b = Camera::perspective(
        Vec3::new(0.8 * speed, 9.0 + 0.2 * speed, 22.0 - 1.0 * speed),
        Vec3::new(0.3 * speed, 0.0, 0.0),
        Vec3::Y,
        1.0,
        0.5,
        200.0,
        w,
        h,
    )
    .unwrap();
    let src = scene.render(&a, 0.0, 3, true);
    let reference = scene.render(&b, 0.0, 1, false).depth.remove(0);
    let motions: Vec<_> =
        src.depth.iter().zip(&src.items).map(|(d, it)| motion_field(d, Some(it), &a, &b, &[]).unwrap()).collect();
    let layers: Vec<WarpLayer> =
        src.depth.iter().zip(&motions).map(|(d, m)| WarpLayer { depth: d, motion: m }).collect();
    let maxv = motions[0].data().iter().filter(|m| m.depth < 1.0).map(|m| m.v.length()).fold(0.0f32, f32::max);
    println!("{w}x{h}, max motion {maxv:.1} px");
    let (p, u, bad) = stats(&src.depth[0], &reference, &b);
    println!("no warp (last frame): psnr {p:.2} dB, unsafe {:.4}, bad {:.4}", u, bad);
    for l in [1usize, 2, 3] {
        for n in [1u32, 4, 8, 16] {
            for bound in [BoundKind::Global, BoundKind::Oriented] {
                let params = WarpParams {
                    n_seeds: n,
                    bound,
                    iterations: t_iter,
                    accelerate,
                    bound_iterations,
                    ..Default::default()
                };
                let t0 = Instant::now();
                let out = warp_depth(&layers[..l], &params).unwrap();
                let dt = t0.elapsed().as_secs_f64() * 1e3;
                let (p, u, bad) = stats(&out.depth, &reference, &b);
                println!(
                    "L={l} N={n:2} {bound:?}: psnr {p:.2} dB, non-conv {:.4}, unsafe {u:.4}, bad {bad:.4}, {dt:.1} ms",
                    out.non_converged_fraction()
                );
            }
        }
    }
    for holes in [HolePolicy::Dilate { radius: 2 }, HolePolicy::Awoc] {
        let out = warp_depth(&layers[..1], &WarpParams { holes, ..Default::default() }).unwrap();
        let (p, u, bad) = stats(&out.depth, &reference, &b);
        println!("L=1 N=8 {holes:?}: psnr {p:.2} dB, unsafe {u:.4}, bad {bad:.4}");
    }
    for l in [1usize, 3] {
        let t0 = Instant::now();
        let v = vfw_layers(&layers[..l]).unwrap();
        let tv = t0.elapsed().as_secs_f64() * 1e3;
        let t0 = Instant::now();
        let af = afw_layers(&layers[..l]).unwrap();
        let ta = t0.elapsed().as_secs_f64() * 1e3;
        let (p, u, bad) = stats(&v, &reference, &b);
        println!("VFW L={l}: psnr {p:.2} dB, unsafe {u:.4}, bad {bad:.4}, {tv:.1} ms");
        let (p, u, bad) = stats(&af, &reference, &b);
        println!("AFW L={l}: psnr {p:.2} dB, unsafe {u:.4}, bad {bad:.4}, {ta:.1} ms");
    }
}
