//! How cheap can a CPU depth warp be on this machine? The memory-traffic floor next to a
//! direct render of the same view, measured in the same run (issue 3's speed target: seed 000
//! Table 3's depth-warp vs depth-render ratios at N = 4, L = 3 — 2.9, 6.7, 24.7, 76.6 for YR,
//! MO, BL, CB — measured on a GPU).
//!
//! `cargo run --release -p zwarp-tools --bin traffic_floor -- [scenes=yr,mo,bl,cb] [w=1920]
//! [h=1080] [scale=1] [l=3] [reps=9]`
//!
//! Any backward warp of L source layers must at least read every layer's depth and motion
//! once (4 + 12 bytes per pixel: the motion bound needs all of them) and write the predicted
//! depth (4 bytes per pixel); `floor` is a kernel that does exactly that and nothing else
//! (a parallel streaming pass, all threads, buffers allocated once and warm), so no
//! implementation of the warp on this CPU can take less time. `render` is zwarp-raster's
//! depth-only render of the scene's view (all threads, warm). Both are medians of `reps` runs,
//! interleaved. `max_ratio = render / floor` bounds every CPU warp's speed-up over this
//! renderer at this size; where it is below the paper's ratio, that ratio cannot be reached
//! here by any implementation.

use std::time::Instant;

use glam::Vec2;
use rayon::prelude::*;
use zwarp_core::Motion;
use zwarp_raster::render_depth;
use zwarp_scene::SceneOptions;

/// Paper Table 3 (N = 4, L = 3): depth-warp speed-up over a depth-only render.
fn paper_ratio(scene: &str) -> Option<f64> {
    match scene {
        "yr" => Some(2.9),
        "mo" => Some(6.7),
        "bl" => Some(24.7),
        "cb" => Some(76.6),
        _ => None,
    }
}

fn median(mut v: Vec<f64>) -> (f64, f64, f64) {
    v.sort_by(f64::total_cmp);
    (v[v.len() / 2], v[0], v[v.len() - 1])
}

/// The minimal traffic of a warp: read each layer's depth and motion once, write one depth.
fn floor_pass(layers: &[(Vec<f32>, Vec<Motion>)], out: &mut [f32], w: usize) {
    out.par_chunks_mut(w * 8).enumerate().for_each(|(c, rows)| {
        let base = c * w * 8;
        for (i, o) in rows.iter_mut().enumerate() {
            let mut z = 1.0f32;
            for (d, m) in layers {
                let (d, m) = (d[base + i], &m[base + i]);
                // Uses every field read, so no load is elided.
                let cand = if d < 1.0 { m.depth + 0.0 * (m.v.x + m.v.y) } else { 1.0 };
                z = z.min(cand);
            }
            *o = z;
        }
    });
}

fn main() {
    let args = zwarp_tools::common::KeyArgs::from_env("scenes, w, h, scale, l, reps");
    let get = |k: &str, d: &str| args.get(k, d);
    let num = |k: &str, d: &str| -> f64 {
        get(k, d).parse().unwrap_or_else(|_| {
            eprintln!("error: {k} must be a number");
            std::process::exit(1)
        })
    };
    let scenes: Vec<String> = get("scenes", "yr,mo,bl,cb").split(',').map(String::from).collect();
    let (w, h) = (num("w", "1920") as u32, num("h", "1080") as u32);
    let (scale, l, reps) = (num("scale", "1") as f32, num("l", "3") as usize, num("reps", "9").max(1.0) as usize);
    if w == 0 || h == 0 || l == 0 {
        eprintln!("error: w, h and l must be positive");
        std::process::exit(1);
    }
    let n = w as usize * h as usize;
    // Source layers of the right size; the floor's time depends only on the bytes moved.
    let layers: Vec<(Vec<f32>, Vec<Motion>)> = (0..l)
        .map(|k| {
            let d: Vec<f32> = (0..n).map(|i| if (i + k) % 7 == 0 { 1.0 } else { 0.5 }).collect();
            let m = (0..n).map(|i| Motion { v: Vec2::new((i % 13) as f32, 1.0), depth: 0.4 }).collect();
            (d, m)
        })
        .collect();
    let mut out = vec![0.0f32; n];
    let bytes = (n * (16 * l + 4)) as f64;
    println!(
        "{w}x{h}, L = {l}, {} threads; floor = {:.0} MB per warp (read {l} x 16 B/px, write 4 B/px)",
        rayon::current_num_threads(),
        bytes / 1e6
    );
    println!("| scene | render ms (min-max) | floor ms (min-max) | GB/s | max_ratio | paper ratio | reachable |");
    println!("|---|---|---|---|---|---|---|");
    for name in &scenes {
        let opts = SceneOptions { seed: 1, scale, ..SceneOptions::default() };
        let loaded = match zwarp_scene::load_scene(name, &opts) {
            Ok(s) => s,
            Err(e) => {
                eprintln!("error: {name}: {e}");
                std::process::exit(1);
            }
        };
        let path = loaded.path_or_default();
        let t = path.time_of_frame(path.frame_count_at(1.0) / 3, 1.0);
        let cam = path.camera_at(t, w, h).expect("camera");
        let scene = loaded.scene;
        // Warm-up of both, then interleaved timed runs.
        render_depth(&scene, &cam, t).expect("render");
        floor_pass(&layers, &mut out, w as usize);
        let (mut rt, mut ft) = (Vec::new(), Vec::new());
        for _ in 0..reps {
            let t0 = Instant::now();
            std::hint::black_box(render_depth(&scene, &cam, t).expect("render"));
            rt.push(t0.elapsed().as_secs_f64() * 1e3);
            let t0 = Instant::now();
            floor_pass(&layers, &mut out, w as usize);
            std::hint::black_box(&out);
            ft.push(t0.elapsed().as_secs_f64() * 1e3);
        }
        let (r, rmin, rmax) = median(rt);
        let (f, fmin, fmax) = median(ft);
        let max_ratio = r / f;
        let (paper, ok) = match paper_ratio(name) {
            Some(p) => (format!("{p}"), if max_ratio >= p { "yes" } else { "no" }),
            None => ("-".into(), "-"),
        };
        println!(
            "| {name} | {r:.1} ({rmin:.1}-{rmax:.1}) | {f:.2} ({fmin:.2}-{fmax:.2}) | {:.1} | {max_ratio:.1} | {paper} | {ok} |",
            bytes / (f * 1e-3) / 1e9
        );
    }
}
