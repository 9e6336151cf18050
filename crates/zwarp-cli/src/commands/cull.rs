//! `zwarp cull`: warping-based occlusion culling (paper 000 Sec. 5, thesis 002) against its
//! baselines along a camera path, every method measured in the same run.

use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::Args;
use serde::Serialize;
use zwarp_cull::{Method, WocParams};
use zwarp_raster::{render_frame, FrameOptions};

use crate::args::{parse_list, Backend, SceneArgs, SizeArgs};
use crate::device::Device;
use crate::harness::{self, timing_of, Lone, PathFrames};
use crate::output::{self, fmt, ser_f64, Table};

/// `--downsample` when not given, on the CPU backend (see [`CullArgs::downsample`]).
pub const CPU_DOWNSAMPLE: u32 = 4;

/// Arguments of `zwarp cull`.
#[derive(Args, Clone, Debug)]
pub struct CullArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    #[command(flatten)]
    pub size: SizeArgs,
    /// Consecutive frames to run from the start of the path (at least 2; more than the path
    /// has runs the whole path).
    #[arg(long, default_value_t = 30)]
    pub frames: usize,
    /// Motion-speed factors (comma list): frame k is taken at time k * speed / fps.
    #[arg(long, default_value = "1", allow_hyphen_values = true)]
    pub speed: String,
    /// Methods (comma list of nocull, vfc, lastframe, twophase, woc, awoc, ideal, ref).
    #[arg(long, default_value = "nocull,vfc,lastframe,twophase,woc,awoc,ideal,ref")]
    pub method: String,
    /// Search seeds N of WOC's single-layer warp.
    #[arg(long, default_value_t = 8)]
    pub n: u32,
    /// Culling resolution divisor for WOC/AWOC (1 = full resolution; k = warp and test at
    /// 1/k of the size with conservative max reduction). Default: 4 on the CPU, 1 on the GPU
    /// (whose WOC kernels run at full resolution). Measured on CB and BL (scale 1, 960x540,
    /// crates/zwarp-cull/README.md): no divisor wins everywhere (CB prefers /4-/6,
    /// BL /2-/3, whose draw time follows every point of culling ratio), /4 stays close to the
    /// best in each case, and full resolution is the slowest frame in every case (its warp
    /// costs more than drawing what it saves on this CPU).
    #[arg(long)]
    pub downsample: Option<u32>,
    /// WOC/AWOC's opening-rim threshold in pixels per frame (`WocParams::open_rims`): near-side
    /// rim texels of two objects separating faster than this become far, so what the opening
    /// shows is not culled. Default 0.1: slower openings are trusted (CB at 960x540, full
    /// resolution, culls one visible object in 24 frames through a 0.077 px opening); 0.01
    /// trusts only what the motion field's own precision cannot tell, at 2-4 points of culling
    /// ratio (crates/zwarp-cull/README.md).
    #[arg(long, allow_hyphen_values = true)]
    pub rim_separation: Option<f32>,
    /// Cull every frame this many times from the same inputs and keep the repetition of median
    /// cost (the decision is the same each time): `cull_ms` and `cull_ms_p99` then describe
    /// the cost along the path rather than the machine's one-off hiccups. CPU backend only.
    #[arg(long, default_value_t = 1)]
    pub repeat: usize,
    /// Skip the colour renders used for `psnr_mean` / `psnr_worst` (faster).
    #[arg(long)]
    pub no_psnr: bool,
    /// Write the results as JSON (`rows`, one per method and speed).
    #[arg(long)]
    pub json: PathBuf,
    /// `cpu` (default) or `gpu`: culling, full and culled renders on one wgpu device
    /// (lavapipe without a GPU), same JSON fields. On the GPU `twophase` is CPU-only and
    /// skipped, and `--downsample` must be 1.
    #[arg(long, value_enum, default_value_t = Backend::Cpu)]
    pub backend: Backend,
}

/// One method at one speed (JSON `rows`).
#[derive(Clone, Debug, Serialize)]
pub struct CullRow {
    /// `nocull`, `vfc`, `lastframe`, `twophase`, `woc`, `awoc`, `ideal` or `ref`.
    pub method: String,
    /// Scene spec.
    pub scene: String,
    /// Motion-speed factor.
    pub speed: f32,
    /// Frames measured (frame 0 of history-based methods bootstraps with VFC and is left out
    /// of the statistics; the other methods count every frame).
    pub frames: usize,
    /// Objects in the scene.
    pub objects: usize,
    /// Mean fraction of the scene's objects culled.
    pub culling_ratio: f64,
    /// Mean culling ratio relative to what REF culls (thesis CR: NOCULL 0, REF 1).
    pub culling_ratio_vs_ref: f64,
    /// Mean over frames of (objects REF shows but the method culled) / (objects REF shows).
    pub object_error: f64,
    /// Worst frame of `object_error`.
    pub object_error_max: f64,
    /// Visible objects culled, summed over the frames.
    pub culled_visible: usize,
    /// Every visible object the method culled: `{frame, id, pixels}` (its size in the full
    /// render), so a user can see whether errors are slivers or real objects.
    pub culled_visible_objects: Vec<serde_json::Value>,
    /// Mean count of pixels whose depth differs from the full render.
    pub pixel_error: f64,
    /// PSNR (dB) of the colour images against the full render over all frames, from the mean
    /// squared error (`inf` when identical).
    #[serde(serialize_with = "ser_f64")]
    pub psnr_mean: f64,
    /// Worst-frame PSNR.
    #[serde(serialize_with = "ser_f64")]
    pub psnr_worst: f64,
    /// Median culling cost (ms).
    pub cull_ms: f64,
    /// 99th percentile of the culling cost (ms).
    pub cull_ms_p99: f64,
    /// Median culling + rendering (depth and item ids of the kept objects) (ms).
    pub frame_ms: f64,
    /// Median time to render everything in the same run (ms).
    pub full_ms: f64,
    /// Mean fraction of the scene's triangles drawn.
    pub triangle_fraction: f64,
    /// `frame_ms` of VFC divided by this method's `frame_ms` (same run).
    pub speedup_vs_vfc: f64,
    /// Occlusion-map accuracy (thesis Sec. V.1, Fig. 8; methods with a map: woc, awoc,
    /// lastframe, ideal; `nan` otherwise): mean fraction of map texels nearer than the true
    /// depth reduced to the map's resolution (unsafe errors).
    #[serde(serialize_with = "ser_f64")]
    pub map_error_fraction: f64,
    /// Worst frame of `map_error_fraction`.
    #[serde(serialize_with = "ser_f64")]
    pub map_error_fraction_max: f64,
    /// Mean fraction of map texels farther than the truth (safe over-estimation: far holes,
    /// erosion).
    #[serde(serialize_with = "ser_f64")]
    pub map_overestimation_fraction: f64,
    /// Worst-frame PSNR (dB) of the nearer-than-truth part of the map (`inf`: no error).
    #[serde(serialize_with = "ser_f64")]
    pub map_error_psnr_worst: f64,
    /// Per frame: culling ratio and frame cost (the culling-ratio-over-frames plot).
    pub frames_detail: Vec<CullFrame>,
}

/// One frame of a [`CullRow`].
#[derive(Clone, Debug, Serialize)]
pub struct CullFrame {
    /// Frame index along the path.
    pub frame: usize,
    /// Fraction of the scene's objects culled.
    pub culling_ratio: f64,
    /// Culling + rendering of the kept objects (ms).
    pub frame_ms: f64,
}

/// `zwarp cull`.
pub fn run(args: CullArgs) -> Result<()> {
    args.size.check()?;
    if args.frames < 2 {
        bail!("--frames must be at least 2 (culling frame k uses frame k - 1), got {}", args.frames);
    }
    let speeds: Vec<f32> = parse_list(&args.speed, "--speed")?;
    if speeds.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
        bail!("--speed values must be positive");
    }
    let mut methods = parse_list::<String>(&args.method, "--method")?
        .iter()
        .map(|m| Method::parse(m).map_err(anyhow::Error::from))
        .collect::<Result<Vec<_>>>()?;
    let device = Device::open(args.backend)?;
    let skipped: Vec<&str> = methods.iter().filter(|m| !device.supports_cull(**m)).map(|m| m.name()).collect();
    if !skipped.is_empty() {
        eprintln!("zwarp cull: {} CPU-only, skipped on the GPU backend", skipped.join(", "));
        methods.retain(|m| device.supports_cull(*m));
        if methods.is_empty() {
            bail!("none of the requested culling methods runs on the GPU backend");
        }
    }
    if args.repeat == 0 {
        bail!("--repeat must be at least 1");
    }
    if device.is_gpu() && args.repeat != 1 {
        bail!("--repeat is CPU-only (the GPU backend culls each frame once)");
    }
    let downsample = args.downsample.unwrap_or(if device.is_gpu() { 1 } else { CPU_DOWNSAMPLE });
    if downsample == 0 {
        bail!("--downsample must be at least 1");
    }
    let mut params = WocParams { downsample, ..WocParams::default() };
    if let Some(px) = args.rim_separation {
        params.open_rims = Some(px);
    }
    params.warp.n_seeds = args.n;
    params.validate()?;
    let loaded = args.scene.load()?;
    let (scene, path) = (&loaded.scene, &loaded.path);
    let device_line = if !device.is_gpu() && args.repeat > 1 {
        format!("{}, each frame culled {} times (median kept)", device.describe(), args.repeat)
    } else {
        device.describe()
    };
    println!(
        "zwarp cull: {} ({} objects, {} triangles), {}x{}, {device_line}",
        args.scene.scene,
        scene.instances.len(),
        scene.triangle_count(),
        args.size.width,
        args.size.height,
    );
    let mut rows: Vec<CullRow> = Vec::new();
    for &speed in &speeds {
        // The first `--frames` consecutive frames (all of them on a shorter path).
        let path_frames = PathFrames::new(path, speed, args.size.width, args.size.height).held_at_end();
        let total = path_frames.require(2, |total| {
            format!("the camera path gives {total} frame(s) at speed {speed}x; culling needs at least 2")
        })?;
        let frames: Vec<(f32, zwarp_core::Camera)> = path_frames
            .pick(args.frames, 0..=args.frames.min(total) - 1, Lone::First)?
            .into_iter()
            .map(|f| (f.t, f.cam))
            .collect();
        // Full colour renders, the reference of the image-quality metrics (untimed).
        let full_color: Vec<Option<zwarp_core::Image<[f32; 3]>>> = if args.no_psnr {
            vec![None; frames.len()]
        } else {
            frames
                .iter()
                .map(|(t, cam)| Ok(render_frame(scene, cam, *t, &FrameOptions { color: true, objects: None })?.color))
                .collect::<Result<_>>()?
        };
        let bar = harness::progress(methods.len() as u64, format!("cull {} {speed}x", args.scene.scene), true);
        let mut speed_rows = Vec::new();
        for &method in &methods {
            let reports = device.cull_sequence(scene, &frames, method, &params, args.repeat)?;
            let steady: Vec<_> = reports.iter().filter(|r| !r.bootstrap).collect();
            let rs = if steady.is_empty() { reports.iter().collect() } else { steady };
            let nf = rs.len().max(1) as f64;
            let obj_err: Vec<f64> =
                rs.iter().map(|r| r.accuracy.false_negatives as f64 / r.accuracy.reference.max(1) as f64).collect();
            let mut psnrs = Vec::new();
            let mut mses = Vec::new();
            for r in &rs {
                if let Some(full) = &full_color[r.frame] {
                    let (t, cam) = &frames[r.frame];
                    let img =
                        render_frame(scene, cam, *t, &FrameOptions { color: true, objects: Some(&r.visible_ids) })?;
                    let mse = zwarp_metrics::mse_rgb(img.color.as_ref().expect("colour requested"), full)?;
                    mses.push(mse);
                    psnrs.push(zwarp_metrics::psnr_from_mse(mse, 1.0)?);
                }
            }
            // Occlusion-map accuracy over the frames that have a map (none: nan).
            let maps: Vec<zwarp_cull::MapAccuracy> = rs.iter().filter_map(|r| r.map_accuracy).collect();
            let map_mean = |f: fn(&zwarp_cull::MapAccuracy) -> f64| -> f64 {
                if maps.is_empty() {
                    f64::NAN
                } else {
                    maps.iter().map(f).sum::<f64>() / maps.len() as f64
                }
            };
            let map_fold = |f: fn(&zwarp_cull::MapAccuracy) -> f64, g: fn(f64, f64) -> f64| -> f64 {
                maps.iter().map(f).reduce(g).unwrap_or(f64::NAN)
            };
            let cull_t = timing_of(&rs, |r| r.cull.total_ms);
            let frame_t = timing_of(&rs, |r| r.cull.total_ms + r.draw_ms);
            speed_rows.push(CullRow {
                method: method.name().to_string(),
                scene: args.scene.scene.clone(),
                speed,
                frames: rs.len(),
                objects: scene.instances.len(),
                culling_ratio: rs
                    .iter()
                    .map(|r| 1.0 - r.visible as f64 / scene.instances.len().max(1) as f64)
                    .sum::<f64>()
                    / nf,
                culling_ratio_vs_ref: rs.iter().map(|r| r.accuracy.culling_ratio).sum::<f64>() / nf,
                object_error: obj_err.iter().sum::<f64>() / nf,
                object_error_max: obj_err.iter().copied().fold(0.0, f64::max),
                culled_visible: rs.iter().map(|r| r.accuracy.false_negatives).sum(),
                culled_visible_objects: rs
                    .iter()
                    .flat_map(|r| {
                        r.culled_visible
                            .iter()
                            .map(move |c| serde_json::json!({ "frame": r.frame, "id": c.id, "pixels": c.pixels }))
                    })
                    .collect(),
                pixel_error: rs.iter().map(|r| r.pixel_error as f64).sum::<f64>() / nf,
                // PSNR of the mean squared error over the frames (`inf` when every frame is
                // identical to the full render; a mean of per-frame PSNRs would be infinite as
                // soon as one frame is).
                psnr_mean: if mses.is_empty() {
                    f64::NAN
                } else {
                    zwarp_metrics::psnr_from_mse(mses.iter().sum::<f64>() / mses.len() as f64, 1.0)?
                },
                psnr_worst: psnrs.iter().copied().fold(f64::INFINITY, f64::min),
                cull_ms: cull_t.median,
                cull_ms_p99: cull_t.p99,
                frame_ms: frame_t.median,
                full_ms: timing_of(&rs, |r| r.full_draw_ms).median,
                triangle_fraction: rs.iter().map(|r| r.triangles as f64 / r.full_triangles.max(1) as f64).sum::<f64>()
                    / nf,
                speedup_vs_vfc: f64::NAN,
                map_error_fraction: map_mean(|m| m.error_fraction),
                map_error_fraction_max: map_fold(|m| m.error_fraction, f64::max),
                map_overestimation_fraction: map_mean(|m| m.overestimation_fraction),
                map_error_psnr_worst: map_fold(|m| m.error_psnr, f64::min),
                frames_detail: rs
                    .iter()
                    .map(|r| CullFrame {
                        frame: r.frame,
                        culling_ratio: 1.0 - r.visible as f64 / scene.instances.len().max(1) as f64,
                        frame_ms: r.cull.total_ms + r.draw_ms,
                    })
                    .collect(),
            });
            bar.inc(1);
        }
        bar.finish_and_clear();
        if let Some(vfc) = speed_rows.iter().find(|r| r.method == "vfc").map(|r| r.frame_ms) {
            for r in &mut speed_rows {
                r.speedup_vs_vfc = vfc / r.frame_ms.max(1e-9);
            }
        }
        rows.extend(speed_rows);
    }
    let mut t = Table::new(&[
        "method",
        "speed",
        "culled",
        "CR vs ref",
        "obj err %",
        "max %",
        "culled vis",
        "px err",
        "PSNR mean",
        "PSNR worst",
        "cull ms",
        "p99",
        "frame ms",
        "x VFC",
        "map err %",
    ]);
    for r in &rows {
        t.row(vec![
            r.method.clone(),
            format!("{}x", r.speed),
            fmt(r.culling_ratio * 100.0, 2),
            fmt(r.culling_ratio_vs_ref, 3),
            fmt(r.object_error * 100.0, 4),
            fmt(r.object_error_max * 100.0, 3),
            r.culled_visible.to_string(),
            fmt(r.pixel_error, 1),
            fmt(r.psnr_mean, 1),
            fmt(r.psnr_worst, 1),
            fmt(r.cull_ms, 2),
            fmt(r.cull_ms_p99, 2),
            fmt(r.frame_ms, 2),
            fmt(r.speedup_vs_vfc, 2),
            fmt(r.map_error_fraction * 100.0, 4),
        ]);
    }
    println!("{}", t.render());
    output::write_json(
        &args.json,
        "cull",
        &rows,
        serde_json::json!({
            "backend": if device.is_gpu() { "gpu" } else { "cpu" },
            "adapter": device.adapter(),
            "threads": rayon::current_num_threads(),
            "width": args.size.width,
            "height": args.size.height,
            "downsample": downsample,
            "repeat": args.repeat,
            "rim_separation": params.open_rims,
        }),
    )?;
    println!("wrote {}", args.json.display());
    Ok(())
}
