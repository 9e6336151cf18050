//! Depth-only GPU render time of Crytek Sponza at 1920x1080 on the current adapter (lavapipe on
//! a machine without GPU): the bar the CPU rasterizer is compared with (seed 000 Sec. 4, REF).
//!
//! Usage: `cargo run --release -p zwarp-gpu --example gpu_raster_table -- /work/shared/scenes/sponza [runs]`
//!
//! The sponza folder holds the raw buffers of rawrunprotected/rasterizer: `VertexBuffer.bin`
//! (f32 x, y, z, w per vertex) and `IndexBuffer.bin` (u32, 3 per triangle).

use std::path::Path;
use std::time::Duration;

use glam::{Mat4, Vec3};
use zwarp_core::{Animation, Camera, Error, Mesh, Result, Scene};
use zwarp_gpu::{DepthTarget, GpuContext, GpuScene, GpuTimer, Renderer, TimingStats};

/// Tiny reader of the raw Sponza format (see `shared/scenes/README.md`).
fn load_sponza(dir: &Path) -> Result<Scene> {
    let read = |name: &str| {
        let p = dir.join(name);
        std::fs::read(&p).map_err(|e| Error::io(&p, e))
    };
    let vb = read("VertexBuffer.bin")?;
    let ib = read("IndexBuffer.bin")?;
    if vb.len() % 16 != 0 || ib.len() % 12 != 0 {
        return Err(Error::parse(dir, "vertex buffer must be f32x4 per vertex and index buffer u32x3 per triangle"));
    }
    let f: Vec<f32> = bytemuck::pod_collect_to_vec(&vb);
    let positions = f.chunks_exact(4).map(|v| Vec3::new(v[0], v[1], v[2])).collect();
    let i: Vec<u32> = bytemuck::pod_collect_to_vec(&ib);
    let indices = i.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
    let mesh = Mesh::new(positions, indices).map_err(|e| Error::parse(dir, e.to_string()))?;
    let mut scene = Scene { name: "sponza".into(), up: Vec3::Z, ..Default::default() };
    let m = scene.add_mesh(mesh);
    scene.add_instance(m, Mat4::IDENTITY, Vec3::splat(0.7), Animation::Static, false);
    Ok(scene)
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let dir = args.get(1).map(String::as_str).unwrap_or("/work/shared/scenes/sponza");
    let runs: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(15).max(10);
    let scene = load_sponza(Path::new(dir))?;
    let ctx = GpuContext::new()?;
    let cam = Camera::perspective(
        Vec3::new(0.0, -11.0, 2.0),
        Vec3::new(0.0, 11.0, 3.0),
        Vec3::Z,
        60f32.to_radians(),
        0.1,
        100.0,
        1920,
        1080,
    )?;
    let gs = GpuScene::upload(&ctx, &scene)?;
    let r = Renderer::new(&ctx)?;
    let target = DepthTarget::new(&ctx, cam.width, cam.height)?;
    let mut rows = Vec::new();
    for timer in [GpuTimer::new(&ctx), GpuTimer::wall_clock(&ctx)] {
        // Warm-up: pipeline compilation, first-touch of buffers.
        for _ in 0..3 {
            timer.measure(|enc| r.encode_depth(enc, &gs, &cam, 0.0, &target))?;
        }
        let samples: Vec<Duration> = (0..runs)
            .map(|_| timer.measure(|enc| r.encode_depth(enc, &gs, &cam, 0.0, &target)))
            .collect::<Result<_>>()?;
        rows.push((timer.method(), TimingStats::from_samples(&samples)?));
    }
    let depth = r.render_depth(&gs, &cam, 0.0)?;
    let covered = depth.data().iter().filter(|d| **d < 1.0).count() as f64 / depth.len() as f64;
    println!("adapter: {}", ctx.adapter);
    println!(
        "scene: sponza, {} triangles; view eye (0,-11,2) -> (0,11,3), fov 60, near 0.1, far 100, 1920x1080",
        gs.triangle_count()
    );
    println!("covered pixels: {:.1}%", covered * 100.0);
    println!("| pass | method | runs | median ms | min ms | max ms |");
    println!("|---|---|---|---|---|---|");
    for (method, s) in rows {
        println!(
            "| GPU depth-only | {method} | {} | {:.2} | {:.2} | {:.2} |",
            s.runs,
            ms(s.median),
            ms(s.min),
            ms(s.max)
        );
    }
    Ok(())
}
