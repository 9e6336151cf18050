//! Measures reference / zwarp / PCSS soft shadows on one frame of a scene (seed 000, Table 8)
//! and prints per-stage times. Usage:
//! `cargo run --release -p zwarp-shadows --example shadow_table -- SCENE SCALE WIDTH HEIGHT S,S.. SM,SM.. [REPS] [OUTDIR]`
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
    let out = a.get(8).cloned();
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
        warmup: 1,
        full_max_samples: u32::MAX,
        base: ShadowParams {
            parallax_motion: std::env::var("ZW_PARALLAX").map_or(true, |v| v != "0"),
            ..ShadowParams::default()
        },
    };
    let rows = evaluate(&loaded.scene, &cam, t, &light, &cfg, |row, res, _| {
        if let Some(dir) = &out {
            std::fs::create_dir_all(dir).ok();
            let name = format!("{dir}/{spec}_{}_s{}_sm{}.png", row.method.name(), row.samples, row.sm);
            zwarp_viz::write_png(name, &zwarp_viz::color_to_rgb8(&res.image))?;
        }
        Ok(())
    })?;
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
