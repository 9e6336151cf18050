//! Measures reference / zwarp / PCSS soft shadows on one frame of a scene (seed 000, Table 8)
//! and prints per-stage times. Usage:
//! `cargo run --release -p zwarp-tools --bin shadow_table -- SCENE SCALE WIDTH HEIGHT S,S.. SM,SM.. [REPS] [OUTDIR] [JSON]`
//! (OUTDIR: shaded images, visibility and difference heat-maps as `zwarp shadows --images`;
//! JSON: the rows in the format of `zwarp shadows --json`; env `ZW_WARMUP` = untimed runs,
//! default 1; `ZW_GROUPING` = auto | never | always; `ZW_UMBRA=0`: peel without umbra culling).
use zwarp_shadows::*;

fn list(s: &str) -> Vec<u32> {
    s.split(',').map(|x| x.trim().parse().expect("number")).collect()
}

fn main() -> zwarp_core::Result<()> {
    let a: Vec<String> = std::env::args().collect();
    let spec = a.get(1).map(String::as_str).unwrap_or("yr");
    let scale: f32 = a.get(2).map(|s| s.parse().expect("scale")).unwrap_or(0.25);
    let w: u32 = a.get(3).map(|s| s.parse().expect("width")).unwrap_or(640);
    let h: u32 = a.get(4).map(|s| s.parse().expect("height")).unwrap_or(360);
    let samples = a.get(5).map(|s| list(s)).unwrap_or(vec![4, 16]);
    let sms = a.get(6).map(|s| list(s)).unwrap_or(vec![512]);
    let reps: usize = a.get(7).map(|s| s.parse().expect("reps")).unwrap_or(1);
    let out = a.get(8).cloned().filter(|d| !d.is_empty() && d != "-");
    let json = a.get(9).cloned();
    let warmup: usize = std::env::var("ZW_WARMUP").ok().and_then(|v| v.parse().ok()).unwrap_or(1);
    let grouping = match std::env::var("ZW_GROUPING").as_deref() {
        Ok("never") => Grouping::Never,
        Ok("always") => Grouping::Always,
        _ => Grouping::Auto,
    };
    let t0 = std::time::Instant::now();
    let loaded = zwarp_scene::load_scene(spec, &zwarp_scene::SceneOptions { scale, ..Default::default() })?;
    let path = loaded.path_or_default();
    let t = path.time_of_frame(0, 1.0);
    let cam = path.camera_at(t, w, h)?;
    let light = default_light(&loaded.scene)?;
    eprintln!(
        "{spec} x{scale}: {} objects, {} triangles, loaded in {:.0} ms; light {}",
        loaded.scene.instances.len(),
        loaded.scene.triangle_count(),
        t0.elapsed().as_secs_f64() * 1e3,
        light_to_json(&light).replace('\n', "")
    );
    let cfg = EvalConfig {
        samples,
        sm_sizes: sms,
        methods: vec![Method::Zwarp, Method::Pcss],
        reps,
        warmup,
        full_max_samples: u32::MAX,
        base: ShadowParams {
            parallax_motion: std::env::var("ZW_PARALLAX").map_or(true, |v| v != "0"),
            grouping,
            umbra: std::env::var("ZW_UMBRA").map_or(true, |v| v != "0"),
            ..ShadowParams::default()
        },
    };
    let rows = evaluate(&loaded.scene, &cam, t, &light, &cfg, |row, res, reference| {
        eprintln!("{}", row.progress_line());
        if let Some(dir) = &out {
            std::fs::create_dir_all(dir).ok();
            let stem = format!("{dir}/{spec}_{}_s{}_sm{}", row.method.name(), row.samples, row.sm);
            zwarp_viz::write_png(format!("{stem}.png"), &zwarp_viz::color_to_rgb8(&res.image))?;
            let vis = res.visibility.map(|x| (x.clamp(0.0, 1.0) * 255.0 + 0.5) as u8);
            zwarp_viz::write_png_gray(format!("{stem}_vis.png"), &vis)?;
            if row.method != Method::Reference {
                let heat = zwarp_viz::diff_heatmap(&res.visibility, &reference.visibility, 0.5)?;
                zwarp_viz::write_png(format!("{stem}_diff.png"), &heat)?;
            }
        }
        Ok(())
    })?;
    if let Some(path) = &json {
        let stats = |v: &[f64]| {
            let mut s = v.to_vec();
            s.sort_by(|a, b| a.total_cmp(b));
            let n = s.len().max(1);
            let median = if s.is_empty() {
                0.0
            } else if n % 2 == 1 {
                s[n / 2]
            } else {
                0.5 * (s[n / 2 - 1] + s[n / 2])
            };
            let p99 = s.get(((0.99 * n as f64).ceil() as usize).clamp(1, n) - 1).copied().unwrap_or(0.0);
            serde_json::json!({ "median": median, "min": s.first().copied().unwrap_or(0.0),
                "max": s.last().copied().unwrap_or(0.0), "p99": p99 })
        };
        let num = |x: f64| if x.is_finite() { serde_json::json!(x) } else { serde_json::json!(null) };
        let out_rows: Vec<serde_json::Value> = rows
            .iter()
            .map(|r| {
                serde_json::json!({
                    "method": r.method.name(), "scene": spec, "samples": r.samples, "sm": r.sm, "ms": r.ms,
                    "timing": stats(&r.times), "psnr": num(r.psnr), "ssim": r.ssim, "speedup": r.speedup,
                    "camera_ms": r.timings.camera, "render_ms": r.timings.render, "motion_ms": r.timings.motion,
                    "mipmap_ms": r.timings.mipmap, "warp_ms": r.timings.warp, "visibility_ms": r.timings.visibility,
                    "shade_ms": r.timings.shade, "warped_texels": r.warped_texels,
                })
            })
            .collect();
        let light_json: serde_json::Value =
            serde_json::from_str(&light_to_json(&light)).map_err(|e| zwarp_core::Error::invalid(e.to_string()))?;
        let doc = serde_json::json!({
            "command": "shadows", "rows": out_rows, "scene": spec, "seed": 1, "scale": scale, "frame": 0, "t": t,
            "width": w, "height": h, "light": light_json, "layers": cfg.base.layers, "n": cfg.base.n_seeds,
            "reps": reps, "warmup": warmup, "threads": rayon::current_num_threads(), "backend": "cpu",
            "grouping": format!("{grouping:?}").to_ascii_lowercase(),
            "objects": loaded.scene.instances.len(), "triangles": loaded.scene.triangle_count(),
            "tool": "cargo run --release -p zwarp-tools --bin shadow_table",
        });
        let text = serde_json::to_string_pretty(&doc).map_err(|e| zwarp_core::Error::invalid(e.to_string()))?;
        std::fs::write(path, text).map_err(|e| zwarp_core::Error::io(path, e))?;
    }
    println!("| scene | method | S | sm | ms | psnr | ssim | speedup | cam | render | motion | warp | vis | holes |");
    for r in rows {
        let tm = r.timings;
        println!(
            "| {spec} | {} | {} | {} | {:.1} | {:.2} | {:.4} | {:.2} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {} |",
            r.method.name(),
            r.samples,
            r.sm,
            r.ms,
            r.psnr,
            r.ssim,
            r.speedup,
            tm.camera,
            tm.render,
            tm.motion,
            tm.warp,
            tm.visibility,
            r.warp_holes
        );
    }
    Ok(())
}
