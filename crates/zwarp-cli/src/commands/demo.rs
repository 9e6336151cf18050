//! `zwarp demo`: the main job on an embedded procedural scene, in a minute or two.
//! Renders a frame pair, warps the source to the target with zwarp and with the forward-warping
//! baselines, compares each with a direct render and writes the images.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use super::eval::{evaluate, table, EvalPlan};
use crate::args::Backend;
use zwarp_warp::BoundKind;

/// Arguments of `zwarp demo`.
#[derive(Args, Clone, Debug)]
pub struct DemoArgs {
    /// Output folder for the images and the JSON.
    #[arg(long, default_value = "out/demo")]
    pub out: PathBuf,
    /// Image width.
    #[arg(long, default_value_t = 1280)]
    pub width: u32,
    /// Image height.
    #[arg(long, default_value_t = 720)]
    pub height: u32,
    /// Where the reference render and our warp run: `cpu` (default) or `gpu` (wgpu; VFW/AFW stay
    /// on the CPU).
    #[arg(long, value_enum, default_value_t = Backend::Cpu)]
    pub backend: Backend,
}

/// `zwarp demo`.
pub fn run(args: DemoArgs) -> Result<()> {
    crate::args::SizeArgs { width: args.width, height: args.height }.check()?;
    let spec = "mo";
    let t0 = std::time::Instant::now();
    let loaded =
        zwarp_scene::load_scene(spec, &zwarp_scene::SceneOptions { seed: 7, scale: 0.5, ..Default::default() })?;
    let scene = &loaded.scene;
    let path = loaded.path_or_default();
    println!(
        "zwarp demo: procedural scene '{spec}' (seed 7, scale 0.5): {} objects, {} triangles, camera path {:.1} s at {} Hz",
        scene.instances.len(),
        scene.triangle_count(),
        path.duration(),
        path.fps
    );
    let device = match args.backend {
        Backend::Cpu => format!("CPU ({} threads)", rayon::current_num_threads()),
        Backend::Gpu => "GPU (wgpu; VFW/AFW on the CPU)".to_string(),
    };
    println!(
        "Warping the depth buffer of frame k to frame k+1 (3 pairs), at 1x and 4x camera speed, {}x{}, {device}.",
        args.width, args.height
    );
    let images = args.out.join("images");
    let plan = EvalPlan {
        frames: 3,
        speeds: vec![1.0, 4.0],
        ns: vec![8],
        ls: vec![1, 3],
        ts: vec![3],
        multisamples: vec![1],
        bounds: vec![BoundKind::Oriented],
        methods: vec!["ours".into(), "vfw".into(), "afw".into()],
        holes: None, // the paper's protocol: background fill at every L
        umbra: true,
        reps: 3,
        backend: args.backend,
        width: args.width,
        height: args.height,
        images: Some(images.clone()),
    };
    let rows = evaluate(spec, scene, &path, &plan, true)?;
    println!("\nDepth warping vs a direct depth render of the target view (PSNR/SSIM on normalised linear depth, time = median):");
    println!("{}", table(&rows));
    // One line per layer count at 1x: quality and cost side by side (the best SSIM alone would
    // hide a cheaper row of the same quality).
    let ours: Vec<_> = rows.iter().filter(|r| r.method == "ours" && r.speed == 1.0).collect();
    for (i, b) in ours.iter().enumerate() {
        // Two decimals: near parity one decimal reads "1.0x faster" for a 4 % gain.
        let cost = if b.speedup >= 1.0 {
            format!("{:.2}x as fast as rendering it on the same backend", b.speedup)
        } else {
            format!("at {:.2}x the cost of rendering it on the same backend", 1.0 / b.speedup)
        };
        println!(
            "{}zwarp (N={}, L={}) predicts the next depth buffer with SSIM {:.4} / PSNR {:.1} dB, {cost}.",
            if i == 0 { "\n" } else { "" },
            b.n,
            b.l,
            b.ssim,
            b.psnr
        );
    }
    let json = args.out.join("demo.json");
    crate::output::write_json(&json, "demo", &rows, serde_json::json!({ "scene": spec }))?;
    let mut strips: Vec<String> = std::fs::read_dir(&images)
        .map(|rd| {
            rd.filter_map(|e| e.ok()).map(|e| e.path().display().to_string()).filter(|p| p.ends_with(".png")).collect()
        })
        .unwrap_or_default();
    strips.sort();
    println!(
        "Figure strips (source | ours | VFW | AFW | reference | error, depth in metres on the colour bars) in {}, e.g. {}; results in {}.",
        images.display(),
        strips.first().map_or("-", String::as_str),
        json.display()
    );
    println!("Done in {:.1} s.", t0.elapsed().as_secs_f64());
    println!(
        "Next: `zwarp report --quick --out report` reproduces every table and figure of the papers (add --full for their protocol) and writes report/index.html."
    );
    Ok(())
}
