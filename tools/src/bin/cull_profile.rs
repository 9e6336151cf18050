//! Per-stage cost of WOC (motion, warp, erosion, rapid draw, max-depth build, tests, hybrid)
//! next to VFC and two-phase in the same run, as `zwarp cull` measures them (cull + draw of the
//! kept objects; medians over the non-bootstrap frames).
//!
//! `cargo run --release -p zwarp-tools --bin cull_profile -- [scene[@path.json]] [scale] [width] [height] [frames] [speed] [downsample list]`

use zwarp_cull::{run_sequence, summarize, FrameReport, Method, WocParams};

fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let a = zwarp_tools::common::CullArgs::from_env("cb", "12")?;
    let arg = |i: usize, d: &str| a.arg(i, d);
    let (scene_name, scale, w, h, n_frames) = (a.scene.clone(), a.scale, a.width, a.height, a.frames);
    let speed: f32 = arg(5, "1").parse()?;
    let downs: Vec<u32> = arg(6, "1,4").split(',').map(|s| s.parse()).collect::<Result<_, _>>()?;
    // Optional 8th argument: comma list of WOC variants (`n4`, `n2`, `tight`, `global`, `bi<k>`
    // bound iterations, `t<k>` iterations, `norims`, `nobase` to skip VFC / two-phase).
    let mut base = WocParams::default();
    let mut baselines = true;
    for opt in arg(7, "-").split(',').filter(|o| *o != "-") {
        match opt {
            "n4" => base.warp.n_seeds = 4,
            "n2" => base.warp.n_seeds = 2,
            "tight" => base.warp.bound = zwarp_warp::BoundKind::Tight,
            "global" => base.warp.bound = zwarp_warp::BoundKind::Global,
            "norims" => base.open_rims = None,
            "nobase" => baselines = false,
            o if o.starts_with("bi") => base.warp.bound_iterations = o[2..].parse()?,
            o if o.starts_with("hyb") => {
                base.hybrid_objects = o[3..].parse()?;
                base.hybrid_min_triangles = 0;
            }
            o if o.starts_with('t') => base.warp.iterations = o[1..].parse()?,
            o => return Err(format!("unknown option '{o}'").into()),
        }
    }
    let t0 = std::time::Instant::now();
    let (loaded, path) = a.load()?;
    let scene = &loaded.scene;
    let mut frames = path.frames(w, h, speed)?;
    frames.truncate(n_frames);
    println!(
        "{scene_name} scale {scale}: {} objects, {} triangles, {w}x{h}, {} frames, speed {speed}x (load {:.1} s)",
        scene.instances.len(),
        scene.triangle_count(),
        frames.len(),
        t0.elapsed().as_secs_f64()
    );
    println!(
        "{:<12} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7} {:>8} {:>8} {:>8} {:>6} {:>4}",
        "method",
        "motion",
        "warp",
        "erode",
        "draw1",
        "build",
        "test",
        "hybrid",
        "cull",
        "draw",
        "frame",
        "full",
        "CR",
        "FN"
    );
    let row = |name: &str, reps: &[FrameReport]| {
        let rs: Vec<&FrameReport> = reps.iter().filter(|r| !r.bootstrap).collect();
        let m = |f: &dyn Fn(&FrameReport) -> f64| median(rs.iter().map(|r| f(r)).collect());
        let s = summarize(reps);
        println!(
            "{:<12} {:>7.2} {:>7.2} {:>7.2} {:>7.2} {:>7.2} {:>7.2} {:>7.2} {:>7.2} {:>8.2} {:>8.2} {:>8.2} {:>5.1}% {:>4}",
            name,
            m(&|r| r.cull.motion_ms),
            m(&|r| r.cull.warp_ms),
            m(&|r| r.cull.erosion_ms),
            m(&|r| r.cull.draw_ms),
            m(&|r| r.cull.build_ms),
            m(&|r| r.cull.test_ms),
            m(&|r| r.cull.hybrid_ms),
            m(&|r| r.cull.total_ms),
            m(&|r| r.draw_ms),
            m(&|r| r.cull.total_ms + r.draw_ms),
            m(&|r| r.full_draw_ms),
            100.0 * s.culling_ratio,
            s.false_negatives
        );
    };
    // `reps<k>` mode (9th argument): WOC on one frame pair (frame 1 from the full render of
    // frame 0), repeated k times; the minimum of each stage filters out machine load.
    if let Some(k) = a.get(8).and_then(|s| s.strip_prefix("reps")) {
        let k: usize = k.parse()?;
        let prev = zwarp_raster::render_frame(scene, &frames[0].1, frames[0].0, &Default::default())?;
        let pf = zwarp_cull::PrevFrame { depth: &prev.depth, items: &prev.items, cam: &frames[0].1, t: frames[0].0 };
        // Boxes kept across frames, as `run_sequence` (and an engine) keeps them.
        let bounds = zwarp_cull::ObjectBounds::new(scene);
        for &f in &downs {
            let p = WocParams { downsample: f, ..base };
            let mut best = [f64::INFINITY; 8];
            let mut totals = Vec::with_capacity(k);
            for _ in 0..k {
                let r = zwarp_cull::woc_with(scene, &bounds, &pf, &frames[1].1, frames[1].0, &p)?;
                let c = r.timings;
                let v =
                    [c.motion_ms, c.warp_ms, c.erosion_ms, c.draw_ms, c.build_ms, c.test_ms, c.hybrid_ms, c.total_ms];
                for (b, x) in best.iter_mut().zip(v) {
                    *b = b.min(x);
                }
                totals.push(c.total_ms);
            }
            // The same frame k times: any spread of the total is the machine's, not the path's.
            let windows: Vec<f64> =
                totals.chunks_exact(24).map(|w| w.iter().cloned().fold(0.0, f64::max) / median(w.to_vec())).collect();
            println!(
                "woc /{f} total over {k} runs of the same frame: median {:.2} ms, worst {:.2}; windows of 24 with worst/median > 1.5: {} of {}",
                median(totals.clone()),
                totals.iter().cloned().fold(0.0, f64::max),
                windows.iter().filter(|&&r| r > 1.5).count(),
                windows.len()
            );
            println!(
                "woc /{f} min of {k}: motion {:.2} warp {:.2} erode {:.2} draw1 {:.2} build {:.2} test {:.2} hybrid {:.2} total {:.2}",
                best[0], best[1], best[2], best[3], best[4], best[5], best[6], best[7]
            );
        }
        let mut best = f64::INFINITY;
        for _ in 0..k {
            best = best.min(zwarp_cull::vfc_cull_with(scene, &bounds, &frames[1].1, frames[1].0)?.timings.total_ms);
        }
        println!("vfc min of {k}: {best:.2}");
        return Ok(());
    }
    for method in [Method::Vfc, Method::TwoPhase].into_iter().filter(|_| baselines) {
        row(method.name(), &run_sequence(scene, &frames, method, &WocParams::default())?);
    }
    for &f in &downs {
        let p = WocParams { downsample: f, ..base };
        row(&format!("woc /{f}"), &run_sequence(scene, &frames, Method::Woc, &p)?);
    }
    Ok(())
}
