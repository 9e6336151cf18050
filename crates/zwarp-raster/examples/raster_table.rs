//! Timing table of the CPU rasterizer: 1920x1080 depth-only renders, warm, repeated.
//!
//! `cargo run --release -p zwarp-raster --example raster_table -- [SPONZA_DIR ...] [--reps N]`
//!
//! Each path argument is a folder with `VertexBuffer.bin` / `IndexBuffer.bin` (Crytek Sponza as
//! in `shared/scenes/sponza`), rendered with the README's view; procedural stand-ins are always
//! added. Prints a markdown table: median, spread (min-max and IQR), Mtris/s, CPU time.
//! `--dump DIR` also writes each scene's linearized depth (PGM) and flat-shaded colour (PPM).

use std::path::PathBuf;
use std::time::Instant;

use zwarp_core::{Camera, Scene};
use zwarp_raster::{render_depth, scenes};

fn stats(mut v: Vec<f64>) -> (f64, f64, f64, f64, f64) {
    v.sort_by(|a, b| a.total_cmp(b));
    let q = |p: f64| v[((v.len() - 1) as f64 * p).round() as usize];
    (q(0.5), v[0], v[v.len() - 1], q(0.25), q(0.75))
}

/// CPU time consumed so far by all threads of this process, in ms (Linux
/// `/proc/self/task/*/schedstat`, nanosecond precision); `None` elsewhere. Under load from other
/// processes wall time mostly measures waiting, CPU time still measures the work.
fn cpu_ms() -> Option<f64> {
    let mut total = 0u64;
    for t in std::fs::read_dir("/proc/self/task").ok()? {
        let p = t.ok()?.path().join("schedstat");
        let s = std::fs::read_to_string(p).ok()?;
        total += s.split_whitespace().next()?.parse::<u64>().ok()?;
    }
    Some(total as f64 / 1e6)
}

fn main() -> zwarp_core::Result<()> {
    let mut reps = 15usize;
    let mut dump: Option<PathBuf> = None;
    let mut paths = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        if a == "--dump" {
            dump = args.next().map(PathBuf::from);
        } else if a == "--reps" {
            reps = args.next().and_then(|s| s.parse().ok()).unwrap_or(reps).max(1);
        } else {
            paths.push(PathBuf::from(a));
        }
    }
    let (w, h) = (1920, 1080);
    let mut cases: Vec<(String, Scene, Camera)> = Vec::new();
    for p in &paths {
        let s = scenes::load_raw_sponza(p)?;
        cases.push((format!("sponza ({})", p.display()), s, scenes::sponza_camera(w, h)?));
    }
    let (s, c) = scenes::sphere_field(16, 48, w, h)?;
    cases.push(("spheres 16x16 (YR-like)".into(), s, c));
    let (s, c) = scenes::box_city(100, w, h)?;
    cases.push(("box city 100x100 (CB-like)".into(), s, c));

    println!("threads: {}, reps: {reps}, image {w}x{h}, depth only", rayon::current_num_threads());
    println!();
    println!("| scene | triangles | objects | median ms | min-max ms | IQR ms | Mtris/s | CPU ms/render (median) | covered px |");
    println!("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |");
    for (ci, (name, scene, cam)) in cases.iter().enumerate() {
        if let Some(dir) = &dump {
            write_images(dir, ci, scene, cam)?;
        }
        // Warm-up (page faults, caches, thread pool).
        let d = render_depth(scene, cam, 0.0)?;
        let _ = render_depth(scene, cam, 0.0)?;
        let covered = d.data().iter().filter(|&&z| z < 1.0).count();
        let mut times = Vec::with_capacity(reps);
        let mut cpu = Vec::with_capacity(reps);
        for _ in 0..reps {
            let c0 = cpu_ms();
            let t0 = Instant::now();
            let d = render_depth(scene, cam, 0.0)?;
            times.push(t0.elapsed().as_secs_f64() * 1e3);
            if let (Some(a), Some(b)) = (c0, cpu_ms()) {
                cpu.push(b - a);
            }
            std::hint::black_box(d);
        }
        let cpu_med = if cpu.is_empty() { f64::NAN } else { stats(cpu).0 };
        let (med, lo, hi, q1, q3) = stats(times);
        let tris = scene.triangle_count();
        println!(
            "| {name} | {tris} | {} | {med:.2} | {lo:.2}-{hi:.2} | {:.2} | {:.1} | {cpu_med:.2} | {:.1}% |",
            scene.instances.len(),
            q3 - q1,
            tris as f64 / med / 1e3,
            100.0 * covered as f64 / (w * h) as f64
        );
    }
    // Second table: the other entry points on the same scenes (median wall ms and CPU ms).
    println!();
    println!("| scene | depth only ms | frame (items + colour) ms | peel L=4 ms | CPU ms depth / frame / peel |");
    println!("| --- | ---: | ---: | ---: | ---: |");
    let reps2 = reps.div_ceil(2).max(5);
    for (name, scene, cam) in &cases {
        let run = |f: &dyn Fn() -> zwarp_core::Result<()>| -> zwarp_core::Result<(f64, f64)> {
            f()?;
            let (mut wall, mut cpu) = (Vec::new(), Vec::new());
            for _ in 0..reps2 {
                let c0 = cpu_ms();
                let t0 = Instant::now();
                f()?;
                wall.push(t0.elapsed().as_secs_f64() * 1e3);
                if let (Some(a), Some(b)) = (c0, cpu_ms()) {
                    cpu.push(b - a);
                }
            }
            Ok((stats(wall).0, if cpu.is_empty() { f64::NAN } else { stats(cpu).0 }))
        };
        let d = run(&|| render_depth(scene, cam, 0.0).map(|_| ()))?;
        let fr = run(&|| {
            zwarp_raster::render_frame(scene, cam, 0.0, &zwarp_raster::FrameOptions { color: true, objects: None })
                .map(|_| ())
        })?;
        let pl = run(&|| {
            zwarp_raster::render_layers(scene, cam, 0.0, &zwarp_raster::PeelOptions { layers: 4, ..Default::default() })
                .map(|_| ())
        })?;
        println!("| {name} | {:.2} | {:.2} | {:.2} | {:.1} / {:.1} / {:.1} |", d.0, fr.0, pl.0, d.1, fr.1, pl.1);
    }
    Ok(())
}

/// Writes `scene<i>_depth.pgm` (linear depth, near = white, normalized by the nearest and
/// farthest surface) and `scene<i>_color.ppm`.
fn write_images(dir: &std::path::Path, i: usize, scene: &Scene, cam: &Camera) -> zwarp_core::Result<()> {
    use zwarp_raster::{render_frame, FrameOptions};
    let f = render_frame(scene, cam, 0.0, &FrameOptions { color: true, objects: None })?;
    let lin: Vec<f32> = f.depth.data().iter().map(|&d| if d < 1.0 { cam.linear_depth(d) } else { f32::NAN }).collect();
    let lo = lin.iter().copied().filter(|v| v.is_finite()).fold(f32::INFINITY, f32::min);
    let hi = lin.iter().copied().filter(|v| v.is_finite()).fold(0.0f32, f32::max);
    let mut pgm = format!("P5 {} {} 255\n", cam.width, cam.height).into_bytes();
    pgm.extend(
        lin.iter().map(|&v| if v.is_finite() { (255.0 * (1.0 - (v - lo) / (hi - lo).max(1e-6))) as u8 } else { 0 }),
    );
    let p = dir.join(format!("scene{i}_depth.pgm"));
    std::fs::write(&p, pgm).map_err(|e| zwarp_core::Error::io(p, e))?;
    let mut ppm = format!("P6 {} {} 255\n", cam.width, cam.height).into_bytes();
    for c in f.color.as_ref().expect("colour requested").data() {
        ppm.extend(c.iter().map(|&v| (v.clamp(0.0, 1.0).powf(1.0 / 2.2) * 255.0) as u8));
    }
    let p = dir.join(format!("scene{i}_color.ppm"));
    std::fs::write(&p, ppm).map_err(|e| zwarp_core::Error::io(p, e))?;
    Ok(())
}
