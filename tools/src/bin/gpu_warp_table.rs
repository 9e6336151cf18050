//! GPU backward depth warp (seed 000 Sec. 3) vs GPU depth-only render of the same frame at
//! 1920x1080 on the current adapter (lavapipe on a machine without GPU), with the CPU warp
//! (`zwarp_warp::warp_depth`, same parameters) and the CPU rasterizer (`zwarp_raster::render_depth`)
//! timed in the same run, interleaved (ARCHITECTURE.md "Timings": a ratio measured side by side
//! is the figure).
//!
//! Frame pair: Crytek Sponza, source view eye (0,-11,2) -> (0,11,3), target view 10 cm to the
//! right, eye (0.1,-11,2) -> (0.1,11,3) (up +z, fov 60, near 0.1, far 100; the pair of the
//! motion/mipmap rows of `gpu_raster_table`). Source layers are peeled on
//! the GPU, motion comes from `zwarp_core::motion_field`. GPU warp time = `WarpKernel::encode`
//! on GPU-resident layers (sample validation, min-max + min-depth mipmaps, warp), fenced wall
//! clock (`GpuTimer::new`; lavapipe's timestamps miss compute work); CPU warp time =
//! `warp_depth` (validation, mipmaps, warp) on all cores.
//!
//! Usage: `cargo run --release -p zwarp-tools --bin gpu_warp_table -- /work/shared/scenes/sponza [runs]`
//!
//! Measured on the shared 2-core box (lavapipe, default `WarpParams`: N=8, T=3, oriented bounds;
//! the GPU result is bit-identical to the CPU one), median of 7: L=1 GPU warp 1242 ms vs GPU
//! render 134 ms (9.3x), CPU warp 345 ms vs CPU render 54 ms (6.4x); L=2 GPU 1468 / 104 ms
//! (14x), CPU 603 / 47 ms (13x). lavapipe runs the warp's divergent per-pixel loops 2.5-3.5x
//! slower than the CPU code. The GPU time excludes `WarpKernel::frames` (the CPU's PCA frame
//! choice, done once per frame pair on the CPU), which the CPU warp time includes.

use std::time::{Duration, Instant};

use zwarp_core::{motion_field, Image, Motion, Result};
use zwarp_gpu::{DepthTarget, GpuContext, GpuScene, GpuTimer, PeelOptions, Renderer, TimingStats};
use zwarp_tools::common;
use zwarp_warp::gpu::{GpuWarpLayer, WarpKernel};
use zwarp_warp::{warp_depth, MotionScales, PixelState, WarpLayer, WarpParams};

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let dir = args.get(1).map(String::as_str).unwrap_or("/work/shared/scenes/sponza");
    let runs: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(5).max(5);
    let scene = common::load_sponza(dir)?;
    let ctx = GpuContext::new()?;
    let cam_a = common::atrium_camera(0.0)?;
    let cam_b = common::atrium_camera(0.1)?;
    let (w, h) = (cam_b.width, cam_b.height);
    let gs = GpuScene::upload(&ctx, &scene)?;
    let r = Renderer::new(&ctx)?;
    let k = WarpKernel::new(&ctx)?;
    let target = DepthTarget::new(&ctx, w, h)?;
    let timer = GpuTimer::new(&ctx);
    let params = WarpKernel::gpu_params(&WarpParams::default());
    let reference = r.render_depth(&gs, &cam_b, 0.0)?;
    println!("adapter: {}; timing: {}", ctx.adapter, timer.method());
    println!(
        "sponza, {} triangles, 1920x1080; warp params: N={} T={} threshold {} {:?} bound, {} bound steps, \
         accelerate {}, cross-layer {}, {:?} holes",
        gs.triangle_count(),
        params.n_seeds,
        params.iterations,
        params.threshold,
        params.bound,
        params.bound_iterations,
        params.accelerate,
        params.cross_layer,
        params.holes
    );
    println!("| L | GPU warp ms | GPU depth-only render ms | GPU warp / render | CPU warp ms | CPU render ms | CPU warp / render | converged | GPU = CPU depth |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for l in [1u32, 2] {
        let peel = PeelOptions { layers: l, ..Default::default() };
        let frames = r.render_layers(&gs, &cam_a, 0.0, &peel)?;
        let depths: Vec<Image<f32>> = frames.iter().map(|f| f.depth.clone()).collect();
        let motions: Vec<Image<Motion>> =
            depths.iter().map(|d| motion_field(d, None, &cam_a, &cam_b, &[])).collect::<Result<_>>()?;
        let layers: Vec<WarpLayer> =
            depths.iter().zip(&motions).map(|(depth, motion)| WarpLayer { depth, motion }).collect();
        let bufs = k.upload(&layers, &params)?;
        // The oriented bound frame per layer (a CPU pass over the motion, done once here).
        let frames = WarpKernel::frames(&layers, params.bound, MotionScales::for_scale(params.motion_scale));
        let views: Vec<GpuWarpLayer> =
            bufs.iter().zip(&frames).map(|((d, m), &axis)| GpuWarpLayer { depth: d, motion: m, axis }).collect();
        let (mut gw, mut gr, mut cw, mut cr) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for run in 0..runs + 1 {
            let a = timer.measure(|enc| k.encode(enc, &views, w, h, &params).map(|_| ()))?;
            let b = timer.measure(|enc| r.encode_depth(enc, &gs, &cam_b, 0.0, &target))?;
            let t0 = Instant::now();
            let cpu_out = warp_depth(&layers, &params)?;
            let c = t0.elapsed();
            let t0 = Instant::now();
            zwarp_raster::render_depth(&scene, &cam_b, 0.0)?;
            let d = t0.elapsed();
            drop(cpu_out);
            if run > 0 {
                gw.push(a);
                gr.push(b);
                cw.push(c);
                cr.push(d);
            }
        }
        let [gw, gr, cw, cr] = [gw, gr, cw, cr].map(|s| TimingStats::from_samples(&s).map(|t| t.median));
        let (gw, gr, cw, cr) = (gw?, gr?, cw?, cr?);
        let gpu = k.warp(&layers, &params)?;
        let cpu = warp_depth(&layers, &params)?;
        let n = gpu.depth.len() as f64;
        let same = gpu.depth.data().iter().zip(cpu.depth.data()).filter(|(a, b)| a == b).count() as f64 / n;
        let conv = gpu.state.data().iter().filter(|s| **s == PixelState::Converged).count() as f64 / n;
        println!(
            "| {l} | {:.1} | {:.1} | {:.2} | {:.1} | {:.1} | {:.2} | {:.1}% | {:.3}% |",
            ms(gw),
            ms(gr),
            gw.as_secs_f64() / gr.as_secs_f64(),
            ms(cw),
            ms(cr),
            cw.as_secs_f64() / cr.as_secs_f64(),
            conv * 100.0,
            same * 100.0
        );
        // Sanity: the warp predicts the target render (linear depth within 1 % on most
        // converged pixels).
        let good = gpu
            .depth
            .data()
            .iter()
            .zip(reference.data())
            .zip(gpu.state.data())
            .filter(|((g, r), s)| {
                **s == PixelState::Converged
                    && **r < 1.0
                    && (cam_b.linear_depth(**g) - cam_b.linear_depth(**r)).abs() < 0.01 * cam_b.linear_depth(**r)
            })
            .count() as f64;
        eprintln!("L={l}: converged pixels within 1% of the target render: {:.1}%", good * 100.0 / (conv * n).max(1.0));
    }
    println!(
        "median of {runs} warm runs each; {} CPU threads; GPU = fenced wall clock of one submit",
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    Ok(())
}
