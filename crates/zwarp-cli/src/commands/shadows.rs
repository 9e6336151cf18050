//! `zwarp shadows`: soft shadows from warped shadow maps against the reference and PCSS
//! (paper 000, Sec. 6: Table 8, Fig. 15).
//!
//! One frame of the camera path is shaded with an area light (`--light` JSON, else a disc light
//! placed from the scene bounds). For every shadow-map size and number of light samples S the
//! reference (S maps rasterized), zwarp (the peeled centre map warped to the S sample views) and
//! PCSS (one map, filtered) are timed side by side (warm, repeated, median) and their shaded
//! images compared with the reference of the same S (PSNR, SSIM on linear RGB).

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use clap::Args;
use serde::Serialize;
use zwarp_core::Image;
use zwarp_shadows::{
    default_light, light_to_json, load_light_at, EvalConfig, EvalRow, Grouping, Method, ShadowParams, ShadowResult,
};

use crate::args::{parse_list, Backend, SceneArgs, SizeArgs};
use crate::device::Device;
use crate::harness::{Frame, PathFrames, Timing};
use crate::output::{self, fmt, ser_f64, Table};

/// Arguments of `zwarp shadows`.
#[derive(Args, Clone, Debug)]
pub struct ShadowsArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    #[command(flatten)]
    pub size: SizeArgs,
    /// Frame index along the camera path.
    #[arg(long, default_value_t = 0)]
    pub frame: usize,
    /// Area-light JSON (`{"center","target","up","shape":{"kind":"disc","radius"}|{"kind":"rect",
    /// "width","height"},"directional"}`); default: a disc light placed from the scene bounds.
    #[arg(long)]
    pub light: Option<PathBuf>,
    /// Numbers of light samples S (comma list).
    #[arg(long, default_value = "4,16,64,256")]
    pub samples: String,
    /// Shadow-map sizes (comma list).
    #[arg(long, default_value = "512,1024,2048")]
    pub sm: String,
    /// Methods besides the reference (comma list of zwarp, zwarp-full, pcss; zwarp-full warps
    /// every texel of every sample map: the path before the lazy synthesis).
    #[arg(long, default_value = "zwarp,pcss")]
    pub methods: String,
    /// Depth layers L of zwarp (the ground is the last one when the scene has one).
    #[arg(long, default_value_t = 3)]
    pub layers: usize,
    /// Search seeds N of zwarp.
    #[arg(long, default_value_t = 4)]
    pub n: u32,
    /// Timed repetitions per measurement (the median is reported).
    #[arg(long, default_value_t = 3)]
    pub reps: usize,
    /// Untimed warm-up runs before the repetitions (0 for expensive tables: the median of the
    /// repetitions absorbs a cold first run).
    #[arg(long, default_value_t = 1)]
    pub warmup: usize,
    /// Measure zwarp-full only for S up to this (it warps S full maps).
    #[arg(long, default_value_t = u32::MAX)]
    pub full_max_samples: u32,
    /// Write shaded images, visibility maps and visibility difference heat-maps here.
    #[arg(long)]
    pub images: Option<PathBuf>,
    /// Write the results as JSON (`rows`, one per method / S / map size).
    #[arg(long)]
    pub json: PathBuf,
    /// How zwarp tests the receivers against its lazily synthesized maps: `auto` (groups of
    /// receivers sharing a texel when there are many per texel), `never` (one test per receiver
    /// and sample), `always`. Same visibility bit for bit; only the time differs.
    #[arg(long, default_value = "auto")]
    pub grouping: String,
    /// Where the shadow maps are made: `gpu` renders, warps and accumulates them with wgpu
    /// (`zwarp_shadows::gpu::GpuShadows`; reference and zwarp only, PCSS is skipped), same JSON fields.
    #[arg(long, value_enum, default_value_t = Backend::Cpu)]
    pub backend: Backend,
}

/// One measured configuration (JSON `rows`).
#[derive(Clone, Debug, Serialize)]
pub struct ShadowRow {
    /// `reference`, `zwarp` or `pcss`.
    pub method: String,
    /// Scene spec.
    pub scene: String,
    /// Light samples S.
    pub samples: u32,
    /// Shadow-map size.
    pub sm: u32,
    /// Median frame time over the warm repetitions (ms).
    pub ms: f64,
    /// Spread of the frame time.
    pub timing: Timing,
    /// PSNR (dB) of the shaded image vs the reference with the same S.
    #[serde(serialize_with = "ser_f64")]
    pub psnr: f64,
    /// SSIM of the shaded image vs the reference with the same S.
    pub ssim: f64,
    /// Reference ms / this method's ms (same S, same map size, same run).
    pub speedup: f64,
    /// Stage times of the median repetition (ms): camera frame + receivers.
    pub camera_ms: f64,
    /// Shadow-map rasterization (S maps, the peeled centre layers, or the PCSS map).
    pub render_ms: f64,
    /// Motion buffers (zwarp).
    pub motion_ms: f64,
    /// Motion mipmaps (zwarp: once with the shared mipmap, per sample for zwarp-full).
    pub mipmap_ms: f64,
    /// Warps (zwarp).
    pub warp_ms: f64,
    /// Visibility tests / PCSS filtering.
    pub visibility_ms: f64,
    /// Shading.
    pub shade_ms: f64,
    /// Texels warped over the S maps (zwarp: S sm^2 for zwarp-full, the looked-up texels and
    /// the hole neighbours of the dilation for zwarp).
    pub warped_texels: usize,
}

fn gray(v: &Image<f32>) -> Image<u8> {
    v.map(|x| (x.clamp(0.0, 1.0) * 255.0 + 0.5) as u8)
}

/// Runs `zwarp shadows`.
pub fn run(a: ShadowsArgs) -> Result<()> {
    a.size.check()?;
    let samples: Vec<u32> = parse_list(&a.samples, "--samples")?;
    let sms: Vec<u32> = parse_list(&a.sm, "--sm")?;
    let names: Vec<String> = parse_list(&a.methods, "--methods")?;
    let mut methods = Vec::new();
    for n in &names {
        let m: Method = n.parse().map_err(|e| anyhow::anyhow!("--methods: {e}"))?;
        if !methods.contains(&m) {
            methods.push(m);
        }
    }
    if a.reps == 0 {
        bail!("--reps must be at least 1");
    }
    let device = Device::open(a.backend)?;
    let loaded = a.scene.load()?;
    let scene = &loaded.scene;
    let frames = PathFrames::new(&loaded.path, 1.0, a.size.width, a.size.height).held_at_end();
    frames.require(a.frame.saturating_add(1), |total| {
        format!("--frame {} is beyond the camera path ({total} frames)", a.frame)
    })?;
    let Frame { t, cam, .. } = frames.frame(a.frame)?;
    let light = match &a.light {
        // Written in the coordinates of the scene's file, as camera paths are.
        Some(p) => load_light_at(p, scene.origin)?,
        None => default_light(scene)?,
    };
    let grouping = match a.grouping.to_ascii_lowercase().as_str() {
        "auto" => Grouping::Auto,
        "never" => Grouping::Never,
        "always" => Grouping::Always,
        other => bail!("--grouping: '{other}' is not one of auto, never, always"),
    };
    let base = ShadowParams { layers: a.layers, n_seeds: a.n, seed: a.scene.seed, grouping, ..ShadowParams::default() };
    base.validate()?;
    let cfg = EvalConfig {
        samples,
        sm_sizes: sms,
        methods,
        reps: a.reps,
        warmup: a.warmup,
        full_max_samples: a.full_max_samples,
        base,
    };
    if let Some(dir) = &a.images {
        std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create folder", dir.display()))?;
    }
    let tag = std::path::Path::new(&a.scene.scene)
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| a.scene.scene.clone());
    eprintln!(
        "shadows: {} ({} objects, {} triangles), frame {} (t = {t:.3} s), {}x{}",
        a.scene.scene,
        scene.instances.len(),
        scene.triangle_count(),
        a.frame,
        a.size.width,
        a.size.height
    );
    let mut on_result = |row: &EvalRow, res: &ShadowResult, reference: &ShadowResult| -> zwarp_core::Result<()> {
        eprintln!("{}", row.progress_line());
        if let Some(dir) = &a.images {
            let stem = dir.join(format!("{tag}_{}_s{}_sm{}", row.method.name(), row.samples, row.sm));
            let path = |suffix: &str| PathBuf::from(format!("{}{suffix}.png", stem.display()));
            zwarp_viz::write_png(path(""), &zwarp_viz::color_to_rgb8(&res.image))?;
            zwarp_viz::write_png_gray(path("_vis"), &gray(&res.visibility))?;
            if row.method != Method::Reference {
                // Red = less visible than the reference (too dark), blue = more (light leak);
                // saturates at a visibility difference of 0.5.
                let heat = zwarp_viz::diff_heatmap(&res.visibility, &reference.visibility, 0.5)?;
                zwarp_viz::write_png(path("_diff"), &heat)?;
            }
        }
        Ok(())
    };
    if device.is_gpu() && cfg.methods.contains(&Method::Pcss) {
        eprintln!("zwarp shadows: pcss is CPU-only, skipped on the GPU backend");
    }
    let rows = device.shadows(&device.load(scene)?, &cam, t, &light, &cfg, &mut on_result)?;

    let out: Vec<ShadowRow> = rows
        .iter()
        .map(|r| ShadowRow {
            method: r.method.name().to_string(),
            scene: a.scene.scene.clone(),
            samples: r.samples,
            sm: r.sm,
            ms: r.ms,
            timing: Timing::of(&r.times),
            psnr: r.psnr,
            ssim: r.ssim,
            speedup: r.speedup,
            camera_ms: r.timings.camera,
            render_ms: r.timings.render,
            motion_ms: r.timings.motion,
            mipmap_ms: r.timings.mipmap,
            warp_ms: r.timings.warp,
            visibility_ms: r.timings.visibility,
            shade_ms: r.timings.shade,
            warped_texels: r.warped_texels,
        })
        .collect();
    let mut table = Table::new(&[
        "method", "S", "sm", "ms", "min", "max", "psnr", "ssim", "speedup", "render", "motion", "mipmap", "warp",
        "vis", "warped",
    ]);
    for r in &out {
        table.row(vec![
            r.method.clone(),
            r.samples.to_string(),
            r.sm.to_string(),
            fmt(r.ms, 1),
            fmt(r.timing.min, 1),
            fmt(r.timing.max, 1),
            fmt(r.psnr, 2),
            fmt(r.ssim, 4),
            fmt(r.speedup, 2),
            fmt(r.render_ms, 1),
            fmt(r.motion_ms, 1),
            fmt(r.mipmap_ms, 1),
            fmt(r.warp_ms, 1),
            fmt(r.visibility_ms, 1),
            r.warped_texels.to_string(),
        ]);
    }
    println!("{}", table.render());
    let light_json: serde_json::Value = serde_json::from_str(&light_to_json(&light))?;
    output::write_json(
        &a.json,
        "shadows",
        &out,
        serde_json::json!({
            "scene": a.scene.scene,
            "seed": a.scene.seed,
            "scale": a.scene.scale,
            "frame": a.frame,
            "t": t,
            "width": a.size.width,
            "height": a.size.height,
            "light": light_json,
            "layers": a.layers,
            "grouping": a.grouping.to_ascii_lowercase(),
            "n": a.n,
            "reps": a.reps,
            "warmup": a.warmup,
            "threads": rayon::current_num_threads(),
            "backend": if device.is_gpu() { "gpu" } else { "cpu" },
            "adapter": device.adapter(),
        }),
    )?;
    Ok(())
}
