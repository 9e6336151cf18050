//! Times the per-frame metrics at 1920x1080 (release build): warm, repeated, median and spread
//! (ARCHITECTURE.md "Timings"). `cargo run --release -p zwarp-tools --bin time_metrics`.

use std::time::Instant;

use zwarp_core::{Camera, Image};
use zwarp_metrics::{depth_quality, normalized_linear_depth, psnr, signed_depth_errors, ssim, ssim_map, surface_range};

/// Process CPU time (user + system) in ms from /proc/self/stat (Linux; 10 ms ticks), so the
/// figures stay meaningful on a machine shared with other jobs; `None` elsewhere.
fn cpu_ms() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    let rest = &stat[stat.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let (u, s): (f64, f64) = (f.get(11)?.parse().ok()?, f.get(12)?.parse().ok()?);
    Some((u + s) * 10.0)
}

fn time<R>(name: &str, reps: usize, mut f: impl FnMut() -> R) {
    std::hint::black_box(f()); // warm-up
    let cpu0 = cpu_ms();
    let mut ms: Vec<f64> = (0..reps)
        .map(|_| {
            let t = Instant::now();
            std::hint::black_box(f());
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    let cpu = cpu0.zip(cpu_ms()).map_or(f64::NAN, |(a, b)| (b - a) / reps as f64);
    ms.sort_by(f64::total_cmp);
    println!(
        "{name:30} wall median {:8.2} ms  min {:8.2}  max {:8.2}  | cpu {:8.2} ms/call  ({reps} reps)",
        ms[reps / 2],
        ms[0],
        ms[reps - 1],
        cpu
    );
}

fn main() -> zwarp_core::Result<()> {
    let (w, h) = (1920u32, 1080u32);
    let cam =
        Camera::perspective(glam::Vec3::new(0.0, 0.0, 5.0), glam::Vec3::ZERO, glam::Vec3::Y, 1.0, 0.1, 100.0, w, h)?;
    let reference = Image::from_fn(w, h, |x, y| {
        if y < 100 {
            1.0
        } else {
            cam.stored_depth(2.0 + x as f32 / 800.0 + ((y / 37) % 3) as f32)
        }
    });
    let predicted = Image::from_fn(w, h, |x, y| {
        let d = *reference.get(x, y);
        if (x * 7 + y * 13) % 101 == 0 {
            1.0
        } else {
            d
        }
    });
    println!("threads: {}", rayon::current_num_threads());
    time("psnr 1920x1080", 15, || psnr(&predicted, &reference, 1.0));
    time("ssim 1920x1080", 15, || ssim(&predicted, &reference, 1.0));
    time("ssim_map 1920x1080", 15, || ssim_map(&predicted, &reference, 1.0));
    time("signed_depth_errors", 15, || signed_depth_errors(&predicted, &reference, 1e-4, 1.0));
    time("normalized_linear_depth", 9, || normalized_linear_depth(&predicted, &cam, (2.0, 6.0)));
    time("surface_range", 9, || surface_range(&reference, &cam));
    time("depth_quality (2 psnr+2 ssim)", 9, || depth_quality(&predicted, &reference, &cam));
    println!("{:?}", depth_quality(&predicted, &reference, &cam)?);
    Ok(())
}
