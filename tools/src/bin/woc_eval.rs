//! Culling evaluation on a procedural scene (seed 000 Table 5/7, thesis Table 1/3): every method
//! along the scene's recorded camera path, with the full render of each frame measured in the
//! same run.
//!
//! `cargo run --release -p zwarp-tools --bin woc_eval -- [scene] [width] [height] [frames]
//! [scale] [speed] [methods] [options]` (defaults: `cb 640 360 20 0.1 1 all -`; `methods` is a
//! comma list of nocull,vfc,woc,awoc,lastframe,twophase,ideal; `options` a comma list of WOC
//! variants: `bilinear` (adaptive bilinear motion sampling instead of nearest), `n4` (N = 4 seeds), `noerode`, `norapid`, `verbose` (per-frame lines), `down2` / `down4` (coarse culling resolution),
//! `mipmap` / `nbuffer` (max-depth structure)).

use zwarp_cull::{run_sequence, summarize, Method, WocParams};
use zwarp_scene::{load_scene, SceneOptions};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |i: usize, d: &str| args.get(i).cloned().unwrap_or_else(|| d.to_string());
    let scene_name = arg(0, "cb");
    let (w, h): (u32, u32) = (arg(1, "640").parse()?, arg(2, "360").parse()?);
    let n_frames: usize = arg(3, "20").parse()?;
    let scale: f32 = arg(4, "0.1").parse()?;
    let speed: f32 = arg(5, "1").parse()?;
    let methods: Vec<Method> = match arg(6, "all").as_str() {
        "all" => Method::ALL.to_vec(),
        list => list.split(',').map(Method::parse).collect::<Result<_, _>>()?,
    };
    let loaded = load_scene(&scene_name, &SceneOptions { scale, ..SceneOptions::default() })?;
    let scene = &loaded.scene;
    let frames = loaded.path_or_default().frames(w, h, speed)?;
    // Frames from the middle of the path (the start of some paths is a slow take-off).
    let start = frames.len().saturating_sub(n_frames) / 2;
    let frames = &frames[start..(start + n_frames).min(frames.len())];
    println!(
        "scene {scene_name} (scale {scale}): {} objects, {} triangles, {w}x{h}, {} frames from {start}, speed {speed}x",
        scene.instances.len(),
        scene.triangle_count(),
        frames.len()
    );
    println!(
        "{:<10} {:>8} {:>9} {:>9} {:>8} {:>7} {:>7} {:>6} {:>8}",
        "method", "cull_ms", "draw_ms", "full_ms", "ratio", "CR", "tris%", "FN", "pix_err"
    );
    let mut params = WocParams::default();
    let mut verbose = false;
    for opt in arg(7, "-").split(',').filter(|o| *o != "-") {
        match opt {
            "bilinear" => params.warp.sampling = zwarp_warp::Sampling::Adaptive,
            "n4" => params.warp.n_seeds = 4,
            "noerode" => params.erosion = false,
            "norapid" => params.rapid_motion = None,
            "verbose" => verbose = true,
            "down2" => params.downsample = 2,
            "down4" => params.downsample = 4,
            "mipmap" => params.max_depth = zwarp_cull::MaxDepthKind::Mipmap,
            "nbuffer" => params.max_depth = zwarp_cull::MaxDepthKind::NBuffer,
            other => return Err(format!("unknown option '{other}'").into()),
        }
    }
    println!("params: {params:?}");
    for m in methods {
        let reps = run_sequence(scene, frames, m, &params)?;
        let s = summarize(&reps);
        if verbose {
            for r in &reps {
                println!(
                    "    frame {:>3} t {:.3}: cull {:6.2} ms (motion {:.2} warp {:.2} erosion {:.2} draw {:.2} build {:.2} test {:.2}) visible {:>6} CR {:5.1}% FN {:>3} stats {:?}",
                    r.frame,
                    r.t,
                    r.cull.total_ms,
                    r.cull.motion_ms,
                    r.cull.warp_ms,
                    r.cull.erosion_ms,
                    r.cull.draw_ms,
                    r.cull.build_ms,
                    r.cull.test_ms,
                    r.visible,
                    100.0 * r.accuracy.culling_ratio,
                    r.accuracy.false_negatives,
                    r.stats
                );
            }
        }
        println!(
            "{:<10} {:>8.2} {:>9.2} {:>9.2} {:>8.3} {:>6.1}% {:>6.1}% {:>6} {:>8.1}",
            m.name(),
            s.cull_ms,
            s.draw_ms,
            s.full_draw_ms,
            (s.cull_ms + s.draw_ms) / s.full_draw_ms,
            100.0 * s.culling_ratio,
            100.0 * s.triangle_fraction,
            s.false_negatives,
            s.pixel_error
        );
        if matches!(m, Method::Woc | Method::Awoc) {
            let steady: Vec<_> = reps.iter().filter(|r| !r.bootstrap).collect();
            let k = steady.len().max(1) as f64;
            let avg = |f: &dyn Fn(&zwarp_cull::FrameReport) -> f64| steady.iter().map(|r| f(r)).sum::<f64>() / k;
            println!(
                "    stages (mean ms): motion {:.2} warp {:.2} erosion {:.2} rapid-draw {:.2} build {:.2} test {:.2} hybrid {:.2}; rapid objects {:.1}, hybrid tested {:.1} culled {:.1}",
                avg(&|r| r.cull.motion_ms),
                avg(&|r| r.cull.warp_ms),
                avg(&|r| r.cull.erosion_ms),
                avg(&|r| r.cull.draw_ms),
                avg(&|r| r.cull.build_ms),
                avg(&|r| r.cull.test_ms),
                avg(&|r| r.cull.hybrid_ms),
                avg(&|r| r.stats.rapid as f64),
                avg(&|r| r.stats.hybrid_tested as f64),
                avg(&|r| r.stats.hybrid_culled as f64),
            );
        }
    }
    Ok(())
}
