//! Control for the stable-cost target (issue 4: WOC's cull time p99 within 1.5x of its median):
//! how much a fixed, pure-compute fork-join workload shaped like one WOC frame varies on this
//! machine. Every "frame" does exactly the same work (`regions` parallel regions over the same
//! data, ~`ms` milliseconds in all), so any spread is the machine's (descheduled workers, a
//! shared host), not the algorithm's. Prints, per window of `frames` frames (the `zwarp cull`
//! protocol's 24), the median, the worst frame and their ratio, then how many windows exceed
//! 1.5x.
//!
//! `cargo run --release -p zwarp-tools --bin jitter_control -- [frames] [windows] [ms] [regions]`
//! (defaults `24 10 8 30`). Compare with `RAYON_NUM_THREADS=1` and with
//! `woc_eval ... verbose` (per-frame WOC cull times) run alongside.

use rayon::prelude::*;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |i: usize, d: &str| args.get(i).cloned().unwrap_or_else(|| d.to_string());
    let frames: usize = arg(0, "24").parse()?;
    let windows: usize = arg(1, "10").parse()?;
    let target_ms: f64 = arg(2, "8").parse()?;
    let regions: usize = arg(3, "30").parse()?;
    if frames == 0 || windows == 0 || regions == 0 || target_ms.is_nan() || target_ms <= 0.0 {
        return Err("frames, windows, ms and regions must be positive".into());
    }
    let data: Vec<f32> = (0..1 << 16).map(|i| i as f32 * 1e-5).collect();
    let region = |reps: usize| -> f32 {
        data.par_chunks(1024)
            .map(|c| {
                let mut acc = 0.0f32;
                for _ in 0..reps {
                    acc += c.iter().map(|x| (x * 1.0001).sin()).sum::<f32>();
                }
                acc
            })
            .sum()
    };
    let frame = |reps: usize| -> f64 {
        let t = Instant::now();
        let mut acc = 0.0;
        for _ in 0..regions {
            acc += region(reps);
        }
        std::hint::black_box(acc);
        t.elapsed().as_secs_f64() * 1e3
    };
    // Calibrate the per-region work so that one frame takes about `target_ms` (warm).
    let mut reps = 1usize;
    while frame(reps) < target_ms / 2.0 && reps < 1 << 20 {
        reps *= 2;
    }
    let probe: Vec<f64> = (0..5).map(|_| frame(reps)).collect();
    reps = ((reps as f64 * target_ms / median(&probe)).round() as usize).max(1);
    println!(
        "{} threads, {regions} regions per frame, {frames} frames per window, calibrated to {:.2} ms",
        rayon::current_num_threads(),
        median(&(0..5).map(|_| frame(reps)).collect::<Vec<_>>())
    );
    let mut over = 0;
    for w in 0..windows {
        let times: Vec<f64> = (0..frames).map(|_| frame(reps)).collect();
        let (med, max) = (median(&times), times.iter().cloned().fold(0.0, f64::max));
        over += usize::from(max > 1.5 * med);
        println!("window {w}: median {med:.2} ms, worst {max:.2} ms, worst/median {:.2}", max / med);
    }
    println!("windows with worst/median > 1.5: {over} of {windows}");
    Ok(())
}

fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    s[s.len() / 2]
}
