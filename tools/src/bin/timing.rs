//! Quick timing breakdown on the synthetic city at 1920x1080 (release):
//! `cargo run --release -p zwarp-tools --bin timing -- [threads]`.
use glam::Vec3;
use std::time::Instant;
use zwarp_core::{motion_field, Camera};
use zwarp_warp::synth::SynthScene;
use zwarp_warp::*;

/// CPU time of the whole process in ms (utime + stime from /proc/self/stat, 10 ms ticks):
/// far less sensitive to other processes on a loaded machine than wall time.
fn cpu_ms() -> f64 {
    let s = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let rest = s.rsplit(')').next().unwrap_or("");
    let f: Vec<&str> = rest.split_whitespace().collect();
    let tick = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    // Fields after the command: state is index 0, utime 11, stime 12 (man 5 proc).
    (tick(11) + tick(12)) * 10.0
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

fn main() {
    let threads: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(1);
    rayon::ThreadPoolBuilder::new().num_threads(threads).build_global().unwrap();
    let (w, h) = (1920, 1080);
    let scene = SynthScene::city(6);
    let a = Camera::perspective(Vec3::new(0.0, 9.0, 22.0), Vec3::ZERO, Vec3::Y, 1.0, 0.5, 200.0, w, h).unwrap();
    let b = Camera::perspective(Vec3::new(0.8, 9.2, 21.0), Vec3::new(0.3, 0.0, 0.0), Vec3::Y, 1.0, 0.5, 200.0, w, h)
        .unwrap();
    let t0 = Instant::now();
    let src = scene.render(&a, 0.0, 3, true);
    println!("ray cast 3 layers: {:.1} ms", t0.elapsed().as_secs_f64() * 1e3);
    let motions: Vec<_> =
        src.depth.iter().zip(&src.items).map(|(d, it)| motion_field(d, Some(it), &a, &b, &[]).unwrap()).collect();
    let layers: Vec<WarpLayer> =
        src.depth.iter().zip(&motions).map(|(d, m)| WarpLayer { depth: d, motion: m }).collect();
    for bound in [BoundKind::Tight, BoundKind::Oriented] {
        let c0 = cpu_ms();
        let t = median(
            (0..3)
                .map(|_| {
                    let t0 = Instant::now();
                    let _ = PreparedLayer::new(&layers[0], bound).unwrap();
                    t0.elapsed().as_secs_f64() * 1e3
                })
                .collect(),
        );
        println!("prepare 1 layer {bound:?}: {t:.1} ms, CPU {:.0} ms", (cpu_ms() - c0) / 3.0);
    }
    // Seed statistics are slow (serial): only with ZWARP_SEED_STATS set.
    for bi in [3u32, 6].into_iter().filter(|_| std::env::var_os("ZWARP_SEED_STATS").is_some()) {
        // Seed statistics of layer 0: how many pixels need more than one seed.
        let p0 = PreparedLayer::new(&layers[0], BoundKind::Oriented).unwrap();
        let mut hist = [0usize; 5];
        let mut sum = 0u64;
        for y in 0..h {
            for x in 0..w {
                let p = glam::Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                let n = match p0.pyramid().tight_bound(p, bi, 0.5) {
                    None => 0,
                    Some(tb) => zwarp_warp::search::effective_seeds(16, tb.region.extent()),
                };
                sum += n as u64;
                hist[match n {
                    0 => 0,
                    1 => 1,
                    2..=4 => 2,
                    5..=8 => 3,
                    _ => 4,
                }] += 1;
            }
        }
        println!(
            "bound iterations {bi}: N=16 seeds/pixel {:.2}; pixels with 0 / 1 / 2-4 / 5-8 / 9-16 seeds: {hist:?}",
            sum as f64 / (w * h) as f64
        );
    }
    {
        // Fast-path fraction of layer 0: pixels whose 4x4 tile bound (after tightening) is
        // within 1 px in both axes take one seed with no per-pixel tightening.
        let p0 = PreparedLayer::new(&layers[0], BoundKind::Oriented).unwrap();
        let pyr = p0.pyramid();
        let (mut fast, mut searched) = (0u64, 0u64);
        for ty in (0..h).step_by(4) {
            for tx in (0..w).step_by(4) {
                let lo = glam::Vec2::new(tx as f32 + 0.5, ty as f32 + 0.5);
                let hi = glam::Vec2::new((tx + 3).min(w - 1) as f32 + 0.5, (ty + 3).min(h - 1) as f32 + 0.5);
                let px = (((tx + 4).min(w) - tx) * ((ty + 4).min(h) - ty)) as u64;
                if let Some(tb) = pyr.tight_bound_box(lo, hi, pyr.global(), 6, 0.5) {
                    searched += px;
                    let e = tb.motion.extent();
                    if e.x <= 1.0 && e.y <= 1.0 {
                        fast += px;
                    }
                }
            }
        }
        println!(
            "layer 0 tile fast path (bound <= 1 px): {:.1} % of searched pixels, {:.1} % of all ({} searched)",
            100.0 * fast as f64 / searched.max(1) as f64,
            100.0 * fast as f64 / (w * h) as f64,
            searched
        );
    }
    for l in [1usize, 3] {
        let prepared = PreparedLayer::prepare_stack(&layers[..l], BoundKind::Oriented).unwrap();
        for n in [1u32, 4, 16] {
            let params = WarpParams { n_seeds: n, ..Default::default() };
            let c0 = cpu_ms();
            let t = median(
                (0..3)
                    .map(|_| {
                        let t0 = Instant::now();
                        let _ = warp_prepared(&prepared, &params).unwrap();
                        t0.elapsed().as_secs_f64() * 1e3
                    })
                    .collect(),
            );
            let cpu = (cpu_ms() - c0) / 3.0;
            println!(
                "warp L={l} N={n:2}: {t:.1} ms = {:.1} Mpx/s on {threads} thread(s), CPU {cpu:.0} ms per warp",
                (w * h) as f64 / t / 1e3
            );
        }
        let t0 = Instant::now();
        let _ = afw_layers(&layers[..l]).unwrap();
        println!("AFW L={l}: {:.1} ms", t0.elapsed().as_secs_f64() * 1e3);
        let t0 = Instant::now();
        let _ = vfw_layers(&layers[..l]).unwrap();
        println!("VFW L={l}: {:.1} ms", t0.elapsed().as_secs_f64() * 1e3);
    }
}
