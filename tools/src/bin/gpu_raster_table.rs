//! Depth-only GPU render time of Crytek Sponza at 1920x1080 on the current adapter (lavapipe on
//! a machine without GPU): the bar the CPU rasterizer is compared with (seed 000 Sec. 4, REF).
//! The CPU rasterizer (`zwarp_raster::render_depth`) is timed in the same run on the same scene
//! and camera, and the two depth buffers are compared (ARCHITECTURE.md "Timings": a
//! ratio measured side by side is the figure).
//!
//! Usage: `cargo run --release -p zwarp-tools --bin gpu_raster_table -- /work/shared/scenes/sponza [runs]`
//!
//! The sponza folder holds the raw buffers of rawrunprotected/rasterizer: `VertexBuffer.bin`
//! (f32 x, y, z, w per vertex) and `IndexBuffer.bin` (u32, 3 per triangle).

use std::time::{Duration, Instant};

use zwarp_core::Result;
use zwarp_gpu::{DepthTarget, GpuContext, GpuScene, GpuTimer, LayerTargets, PeelOptions, Renderer, TimingStats};
use zwarp_tools::common;
use zwarp_warp::gpu::{MotionInput, MotionKernel, PyramidKernel};

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let dir = args.get(1).map(String::as_str).unwrap_or("/work/shared/scenes/sponza");
    let runs: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(15).max(10);
    let scene = common::load_sponza(dir)?;
    let ctx = GpuContext::new()?;
    let cam = common::atrium_camera(0.0)?;
    let gs = GpuScene::upload(&ctx, &scene)?;
    let r = Renderer::new(&ctx)?;
    let target = DepthTarget::new(&ctx, cam.width, cam.height)?;
    // Interleaved runs (GPU with each timer, then CPU) so that load from other
    // processes on a shared machine hits all three alike.
    // GpuTimer::new picks the fenced wall clock on software adapters (their timestamps miss
    // compute work); timestamps are shown beside it where the adapter has them.
    let timers: Vec<GpuTimer> =
        [Some(GpuTimer::new(&ctx)), GpuTimer::with_timestamps(&ctx)].into_iter().flatten().collect();
    let cpu_run = || -> Result<Duration> {
        let t0 = Instant::now();
        zwarp_raster::render_depth(&scene, &cam, 0.0).map(|_| t0.elapsed())
    };
    for _ in 0..3 {
        for timer in &timers {
            timer.measure(|enc| r.encode_depth(enc, &gs, &cam, 0.0, &target))?;
        }
        cpu_run()?;
    }
    let mut gpu_samples = vec![Vec::new(); timers.len()];
    let mut cpu_samples = Vec::new();
    for _ in 0..runs {
        for (k, timer) in timers.iter().enumerate() {
            gpu_samples[k].push(timer.measure(|enc| r.encode_depth(enc, &gs, &cam, 0.0, &target))?);
        }
        cpu_samples.push(cpu_run()?);
    }
    let rows: Vec<_> = timers
        .iter()
        .zip(&gpu_samples)
        .map(|(t, s)| Ok((t.method(), TimingStats::from_samples(s)?)))
        .collect::<Result<_>>()?;
    let cpu = TimingStats::from_samples(&cpu_samples)?;
    let depth = r.render_depth(&gs, &cam, 0.0)?;
    let cpu_depth = zwarp_raster::render_depth(&scene, &cam, 0.0)?;
    let same = depth.data().iter().zip(cpu_depth.data()).filter(|(a, b)| (**a - **b).abs() < 1e-6).count();
    let covered = depth.data().iter().filter(|d| **d < 1.0).count() as f64 / depth.len() as f64;
    println!("adapter: {}", ctx.adapter);
    println!(
        "scene: sponza, {} triangles; view eye (0,-11,2) -> (0,11,3), fov 60, near 0.1, far 100, 1920x1080",
        gs.triangle_count()
    );
    println!("covered pixels: {:.1}%", covered * 100.0);
    println!(
        "GPU vs CPU depth: {:.4}% of pixels within 1e-6 ({} threads for the CPU rasterizer)",
        same as f64 * 100.0 / depth.len() as f64,
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    println!("| pass | method | runs | median ms | min ms | max ms |");
    println!("|---|---|---|---|---|---|");
    let gpu_median = rows[0].1.median;
    for (method, s) in rows {
        println!(
            "| GPU depth-only ({}) | {method} | {} | {:.2} | {:.2} | {:.2} |",
            ctx.adapter.name,
            s.runs,
            ms(s.median),
            ms(s.min),
            ms(s.max)
        );
    }
    println!(
        "| CPU zwarp-raster depth-only | wall clock | {} | {:.2} | {:.2} | {:.2} |",
        cpu.runs,
        ms(cpu.median),
        ms(cpu.min),
        ms(cpu.max)
    );
    println!("CPU / GPU median ratio: {:.2}", cpu.median.as_secs_f64() / gpu_median.as_secs_f64());

    // Depth peeling (seed 000 Table 4): L layers with item ids, GPU vs CPU, same run.
    let peel_runs = (runs / 3).max(5);
    println!();
    println!("| depth peeling L | GPU median ms ({}) | CPU median ms | CPU / GPU |", GpuTimer::new(&ctx).method());
    println!("|---|---|---|---|");
    for l in [1u32, 2, 4] {
        let opts = PeelOptions { layers: l, ..Default::default() };
        let targets = LayerTargets::new(&r, cam.width, cam.height, l as usize, false)?;
        let timer = GpuTimer::new(&ctx);
        let cpu_opts = zwarp_raster::PeelOptions { layers: l as usize, ground_separate: false, umbra: None };
        timer.measure(|enc| r.encode_layers(enc, &gs, &cam, 0.0, &opts, &targets))?;
        zwarp_raster::render_layers(&scene, &cam, 0.0, &cpu_opts)?;
        let (mut g, mut c) = (Vec::new(), Vec::new());
        for _ in 0..peel_runs {
            g.push(timer.measure(|enc| r.encode_layers(enc, &gs, &cam, 0.0, &opts, &targets))?);
            let t0 = Instant::now();
            zwarp_raster::render_layers(&scene, &cam, 0.0, &cpu_opts)?;
            c.push(t0.elapsed());
        }
        let (g, c) = (TimingStats::from_samples(&g)?, TimingStats::from_samples(&c)?);
        println!(
            "| {l} | {:.2} | {:.2} | {:.2} |",
            ms(g.median),
            ms(c.median),
            c.median.as_secs_f64() / g.median.as_secs_f64()
        );
    }

    // Motion field (Sec. 3.1) and min-max motion mipmap (Sec. 3.3, "MMC" of Table 3) at
    // 1920x1080 towards a view 10 cm to the right, GPU kernels vs their CPU twins.
    let cam_b = common::atrium_camera(0.1)?;
    let mk = MotionKernel::new(&ctx)?;
    let pk = PyramidKernel::new(&ctx)?;
    let n = depth.len();
    let dev = &ctx.device;
    let dbuf = dev.create_buffer(&wgpu::BufferDescriptor {
        label: Some("depth"),
        size: n as u64 * 4,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    ctx.queue.write_buffer(&dbuf, 0, bytemuck::cast_slice(depth.data()));
    let mbuf = dev.create_buffer(&wgpu::BufferDescriptor {
        label: Some("motion"),
        size: n as u64 * 12,
        usage: wgpu::BufferUsages::STORAGE,
        mapped_at_creation: false,
    });
    let input = MotionInput { depth: &dbuf, items: None, row_stride: cam.width };
    let timer = GpuTimer::new(&ctx);
    let alt = GpuTimer::with_timestamps(&ctx).unwrap_or_else(|| GpuTimer::wall_clock(&ctx));
    let (mut gm, mut gp, mut cm, mut cp) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let (mut wm, mut wp) = (Vec::new(), Vec::new());
    for run in 0..runs + 2 {
        let a = timer.measure(|enc| mk.encode(enc, &input, &cam, &cam_b, &[], &mbuf))?;
        let b = timer.measure(|enc| pk.encode(enc, &mbuf, cam.width, cam.height, glam::Vec2::X).map(|_| ()))?;
        let xa = alt.measure(|enc| mk.encode(enc, &input, &cam, &cam_b, &[], &mbuf))?;
        let xb = alt.measure(|enc| pk.encode(enc, &mbuf, cam.width, cam.height, glam::Vec2::X).map(|_| ()))?;
        let t0 = Instant::now();
        let motion = zwarp_core::motion_field(&depth, None, &cam, &cam_b, &[])?;
        let c = t0.elapsed();
        let t0 = Instant::now();
        let pyr = zwarp_warp::MotionPyramid::build(&motion)?;
        let d = t0.elapsed();
        std::hint::black_box(pyr.top_level());
        if run >= 2 {
            wm.push(xa);
            wp.push(xb);
            gm.push(a);
            gp.push(b);
            cm.push(c);
            cp.push(d);
        }
    }
    println!();
    println!(
        "| kernel (1920x1080) | GPU median ms ({}) | GPU median ms ({}) | CPU median ms | CPU / GPU |",
        timer.method(),
        alt.method()
    );
    println!("|---|---|---|---|---|");
    for (name, g, w, c) in [("motion field", &gm, &wm, &cm), ("min-max motion mipmap", &gp, &wp, &cp)] {
        let (g, w, c) = (TimingStats::from_samples(g)?, TimingStats::from_samples(w)?, TimingStats::from_samples(c)?);
        println!(
            "| {name} | {:.2} | {:.2} | {:.2} | {:.2} |",
            ms(g.median),
            ms(w.median),
            ms(c.median),
            c.median.as_secs_f64() / g.median.as_secs_f64()
        );
    }
    Ok(())
}
