//! Warp cost and quality on the procedural scenes of seed 000 (YR, MO, BL, CB), as `zwarp eval`
//! renders them (frame k -> k+1 along the recorded path, umbra peeling, ground as the last
//! layer, the paper's hole protocol), without the CLI: a fast loop for optimising the warp.
//!
//! `cargo run --release -p zwarp-tools --bin scenes -- [scenes=mo,bl,cb,yr] [w=960] [h=540]
//! [scale=0.5] [frames=2] [l=1,3,4] [n=4,16] [threads=1] [reps=3] [ms=1] [speed=1]`
//!
//! `ms=m` warps from sources rendered on an m x m sample grid per pixel
//! (`WarpParams::multisample`); the render and the quality are at `w x h`.
//!
//! Times are the minimum over `reps` runs of the on-CPU time of the process' threads
//! (`/proc/self/task/*/schedstat`, ns), so a loaded machine inflates them far less than wall
//! time. Per configuration: prepare (mipmaps)
//! and warp ms per frame, the render time of the same target (zwarp-raster `render_depth`,
//! same thread count) and the ratio (prepare + warp) / render, Mpx/s per core of prepare + warp,
//! bytes touched per pixel by the warp (counted: build with `--features stats`, see
//! `zwarp_warp::stats`; the preparation adds ~37 B per pixel and layer), PSNR / SSIM against the
//! render and the converged fraction.

use std::collections::HashMap;
use std::time::Instant;

use zwarp_core::{motion_field, Image, Motion};
use zwarp_raster::{render_depth, render_frame, render_source_layers, FrameOptions, UmbraPeeling, ViewRegion};
use zwarp_scene::SceneOptions;
use zwarp_warp::*;

/// Total on-CPU time of all threads of this process (ns).
fn cpu_ns() -> u64 {
    let mut total = 0;
    if let Ok(dir) = std::fs::read_dir("/proc/self/task") {
        for e in dir.flatten() {
            let s = std::fs::read_to_string(e.path().join("schedstat")).unwrap_or_default();
            total += s.split_whitespace().next().and_then(|v| v.parse::<u64>().ok()).unwrap_or(0);
        }
    }
    total
}

/// Runs `f` `reps` times after one warm-up run; returns the last result and the minimal CPU
/// and wall ms of one run (the minimum is the figure least disturbed by other processes).
fn time<T>(reps: usize, mut f: impl FnMut() -> T) -> (T, f64, f64) {
    let mut out = f();
    let (mut cpu, mut wall) = (f64::INFINITY, f64::INFINITY);
    for _ in 0..reps {
        let (c0, t0) = (cpu_ns(), Instant::now());
        out = f();
        wall = wall.min(t0.elapsed().as_secs_f64() * 1e3);
        cpu = cpu.min((cpu_ns() - c0) as f64 / 1e6);
    }
    (out, cpu, wall)
}

fn main() {
    let args = zwarp_tools::common::KeyArgs::from_env("scenes, w, h, scale, frames, l, n, threads, reps, ms, speed");
    let get = |k: &str, d: &str| args.get(k, d);
    let list = |k: &str, d: &str| -> Vec<u32> { get(k, d).split(',').map(|s| s.parse().unwrap()).collect() };
    let scenes: Vec<String> = get("scenes", "mo,bl,cb,yr").split(',').map(String::from).collect();
    let (w, h): (u32, u32) = (get("w", "960").parse().unwrap(), get("h", "540").parse().unwrap());
    let scale: f32 = get("scale", "0.5").parse().unwrap();
    let frames: usize = get("frames", "2").parse().unwrap();
    let ls = list("l", "1,3,4");
    let ns = list("n", "4,16");
    let threads: usize = get("threads", "1").parse().unwrap();
    let reps: usize = get("reps", "3").parse().unwrap();
    let ms: u32 = get("ms", "1").parse().unwrap();
    let speed: f32 = get("speed", "1").parse().unwrap();
    rayon::ThreadPoolBuilder::new().num_threads(threads).build_global().unwrap();
    let max_l = *ls.iter().max().unwrap() as usize;
    println!(
        "scene  L  N  prepare_ms  warp_ms  render_ms  w/r_ratio  Mpx/s/core  B/px    psnr     ssim      converged  output_hash"
    );
    for name in &scenes {
        let opts = SceneOptions { seed: 1, scale, ..SceneOptions::default() };
        let loaded = zwarp_scene::load_scene(name, &opts).unwrap();
        let path = loaded.path_or_default();
        let scene = loaded.scene;
        // Frame pairs as `zwarp eval` (evenly spread along the path).
        let total = path.frame_count_at(speed);
        let last = total - 2;
        let count = frames.min(last + 1);
        // (L, N) -> (prepare ms, warp ms, render ms, psnr, ssim, converged, bytes per pixel)
        // summed over pairs.
        let mut acc: HashMap<(u32, u32), [f64; 7]> = HashMap::new();
        let mut hashes: HashMap<(u32, u32), u64> = HashMap::new();
        for i in 0..count {
            let k = if count == 1 { 0 } else { i * last / (count - 1) };
            let (ta, tb) = (path.time_of_frame(k, speed), path.time_of_frame(k + 1, speed));
            let cb = path.camera_at(tb, w, h).unwrap();
            // The source views (and the motion's target space) on the ms x ms sample grid.
            let (ca, cb_src) =
                (path.camera_at(ta, w * ms, h * ms).unwrap(), path.camera_at(tb, w * ms, h * ms).unwrap());
            let (reference, render_ms, _) = time(reps, || render_depth(&scene, &cb, tb).unwrap());
            let deltas = scene.object_deltas(ta, tb);
            let has_ground = scene.instances.iter().any(|i| i.is_ground);
            let frame = render_frame(&scene, &ca, ta, &FrameOptions::default()).unwrap();
            let e = (cb.eye() - ca.eye()).length() * 1.5;
            // zwarp eval's protocol: the ground alone as the last layer.
            let umbra = Some(UmbraPeeling { region: ViewRegion::Disc { e, c: 0.0 } });
            let peeled =
                if max_l > 1 { render_source_layers(&scene, &ca, ta, max_l, umbra).unwrap() } else { Vec::new() };
            let single =
                (frame.depth.clone(), motion_field(&frame.depth, Some(&frame.items), &ca, &cb_src, &deltas).unwrap());
            let mut bufs: Vec<(Image<f32>, Image<Motion>)> = peeled
                .iter()
                .map(|l| (l.depth.clone(), motion_field(&l.depth, Some(&l.items), &ca, &cb_src, &deltas).unwrap()))
                .collect();
            let ground = if has_ground && max_l > 1 { bufs.pop() } else { None };
            for &l in &ls {
                let layers: Vec<WarpLayer> = if l == 1 {
                    vec![WarpLayer { depth: &single.0, motion: &single.1 }]
                } else {
                    let take = if ground.is_some() { l as usize - 1 } else { l as usize };
                    bufs.iter()
                        .take(take)
                        .chain(ground.iter())
                        .map(|(d, m)| WarpLayer { depth: d, motion: m })
                        .collect()
                };
                let (prepared, prep_ms, _) =
                    time(reps, || PreparedLayer::prepare_stack(&layers, BoundKind::Oriented).unwrap());
                for &n in &ns {
                    let holes = if l == 1 { HolePolicy::Background { radius: 4 } } else { HolePolicy::FarDepth };
                    let params = WarpParams { n_seeds: n, holes, multisample: ms, ..Default::default() };
                    let (out, warp_ms, _) = time(reps, || warp_prepared(&prepared, &params).unwrap());
                    if l == 1 {
                        // `zwarp eval`'s single-layer protocol (`predict_into`: preparation into
                        // recycled buffers, the warp, `holes::fill_background`), whole and by step.
                        let params = WarpParams { n_seeds: n, multisample: ms, ..Default::default() };
                        let mut o = WarpOutput::empty();
                        let mut rec = Vec::new();
                        let (_, all, _) = time(reps, || {
                            rec = predict_into(&layers, &params, std::mem::take(&mut rec), &mut o).unwrap();
                        });
                        let far = WarpParams { holes: HolePolicy::FarDepth, ..params };
                        let (_, prep, _) = time(reps, || {
                            rec = PreparedLayer::prepare_stack_recycling(&layers, far.bound, std::mem::take(&mut rec))
                                .unwrap();
                        });
                        let (_, warp, _) = time(reps, || warp_prepared_into(&rec, &far, &mut o).unwrap());
                        let warped = o.clone();
                        let (tw, th) = o.depth.size();
                        let (_, fill, _) = time(reps, || {
                            let mut f = warped.clone();
                            let limits = holes::BackgroundLimits::of_prepared(&rec, tw, th, ms, 4).unwrap();
                            holes::fill_background_with(&layers, &mut f, limits, &far.search()).unwrap();
                        });
                        let (_, copy, _) = time(reps, || warped.clone());
                        eprintln!(
                            "  {name} L=1 N={n} predict_into: {all:.1} CPU ms (prepare {prep:.1}, warp {warp:.1}, fill {:.1})",
                            fill - copy
                        );
                    }
                    // One more run for the counters (`--features stats`): bytes touched / pixel.
                    stats::take();
                    let _ = warp_prepared(&prepared, &params).unwrap();
                    let counts = stats::take();
                    let bpp = counts.bytes_per_pixel();
                    if stats::ENABLED {
                        let px = counts.pixels.max(1) as f64;
                        eprintln!(
                            "  {name} L={l} N={n}: per pixel {:.2} tightenings (incl. tiles), {:.2} mip texels, {:.2} seeds, {:.2} fetches",
                            counts.tightenings as f64 / px,
                            counts.mip_texels as f64 / px,
                            counts.seeds as f64 / px,
                            counts.fetches as f64 / px
                        );
                    }
                    let q = zwarp_metrics::depth_quality(&out.depth, &reference, &cb).unwrap();
                    let conv = 1.0 - out.non_converged_fraction();
                    // Output fingerprint (FNV-1a over depth bits and states): tells a
                    // bit-identical optimisation from one that changes the function.
                    let mut fp = 0xcbf29ce484222325u64;
                    for (z, s) in out.depth.data().iter().zip(out.state.data()) {
                        for b in z.to_bits().to_le_bytes().into_iter().chain([*s as u8]) {
                            fp = (fp ^ b as u64).wrapping_mul(0x100000001b3);
                        }
                    }
                    *hashes.entry((l, n)).or_insert(0) ^= fp.rotate_left(i as u32);
                    let a = acc.entry((l, n)).or_default();
                    for (s, v) in a.iter_mut().zip([prep_ms, warp_ms, render_ms, q.psnr, q.ssim, conv, bpp]) {
                        *s += v;
                    }
                }
            }
        }
        for &l in &ls {
            for &n in &ns {
                let a = acc[&(l, n)].map(|v| v / count as f64);
                let mpx = (w * h) as f64 / 1e6 / ((a[0] + a[1]) / 1e3) / threads as f64;
                let bpp = if stats::ENABLED { format!("{:6.0}", a[6]) } else { "     -".into() };
                println!(
                    "{name:5} {l:2} {n:2}  {:9.1}  {:7.1}  {:9.1}  {:7.2}  {mpx:10.2}  {bpp}  {:7.3}  {:.5}  {:.4}  {:016x}",
                    a[0],
                    a[1],
                    a[2],
                    (a[0] + a[1]) / a[2],
                    a[3],
                    a[4],
                    a[5],
                    hashes[&(l, n)]
                );
            }
        }
    }
}
