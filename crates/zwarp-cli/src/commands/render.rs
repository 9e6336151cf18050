//! `zwarp render`: the buffers of one frame as images a person can look at (PNG) and as float
//! EXR where the value matters.

use std::path::{Path, PathBuf};

use crate::device::Device;
use anyhow::{bail, Context, Result};
use clap::Args;
use serde::Serialize;

use crate::args::{Backend, SceneArgs, SizeArgs};
use crate::harness::Timing;
use crate::output;

/// Arguments of `zwarp render`.
#[derive(Args, Clone, Debug)]
pub struct RenderArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    #[command(flatten)]
    pub size: SizeArgs,
    /// Frame index along the camera path (motion goes to frame K+1).
    #[arg(long, default_value_t = 0)]
    pub frame: usize,
    /// Depth layers L to peel (0 = none); the ground gets its own extra last layer.
    #[arg(long, default_value_t = 4)]
    pub layers: usize,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
    /// Also write a JSON summary (sizes, counts, timings).
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// `cpu` (zwarp-raster) or `gpu` (wgpu, lavapipe without a GPU): same files and JSON fields.
    #[arg(long, value_enum, default_value_t = Backend::Cpu)]
    pub backend: Backend,
}

/// The buffers `zwarp render` writes, from either backend.
struct Rendered {
    depth: zwarp_core::Image<f32>,
    items: zwarp_core::Image<u32>,
    color: Option<zwarp_core::Image<[f32; 3]>>,
    motion: zwarp_core::Image<zwarp_core::Motion>,
    /// Depth of every peeled layer (the ground layer last when the scene has ground).
    layers: Vec<zwarp_core::Image<f32>>,
    /// Depth-only render times (ms), 3 samples.
    depth_samples: Vec<f64>,
    /// Adapter name on the GPU.
    adapter: Option<String>,
}

/// What one `zwarp render` draws: the frame at `t` seen by `cam`, its motion towards `cam_next`
/// at `t_next`, and `layers` peeled layers (the ground separate when the scene has one).
#[derive(Clone, Copy)]
struct RenderJob<'a> {
    scene: &'a zwarp_core::Scene,
    cam: &'a zwarp_core::Camera,
    t: f32,
    cam_next: &'a zwarp_core::Camera,
    t_next: f32,
    layers: usize,
    has_ground: bool,
}

/// The buffers of `job` on `device` (zwarp-raster and the CPU motion field, or the wgpu
/// renderer, the WGSL motion kernel and GPU depth peeling; the depth-only time on the GPU
/// fenced on the device).
fn render(device: &Device, job: &RenderJob<'_>) -> Result<Rendered> {
    let RenderJob { scene, cam, t, cam_next, t_next, layers, has_ground } = *job;
    let on_device = device.load(scene)?;
    let depth_samples = device.time_depth_only(&on_device, cam, t, 3)?;
    let (depth, items, color) = device.render_view(&on_device, cam, t)?;
    let motion = device.motion_field(&on_device, &depth, &items, (cam, t), (cam_next, t_next))?;
    let layers = if layers > 0 { device.peel_depths(&on_device, cam, t, layers, has_ground)? } else { Vec::new() };
    Ok(Rendered { depth, items, color, motion, layers, depth_samples, adapter: device.adapter() })
}

/// JSON summary of a render.
#[derive(Serialize)]
struct RenderRow {
    scene: String,
    frame: usize,
    t: f32,
    width: u32,
    height: u32,
    objects: usize,
    triangles: usize,
    depth_ms: f64,
    covered_fraction: f64,
    max_motion_px: f32,
    layer_coverage: Vec<usize>,
    files: Vec<String>,
}

/// `zwarp render`.
pub fn run(args: RenderArgs) -> Result<()> {
    args.size.check()?;
    let loaded = args.scene.load()?;
    let (scene, path) = (&loaded.scene, &loaded.path);
    let total = path.frame_count();
    if args.frame >= total {
        bail!("--frame {} is past the camera path's last frame ({})", args.frame, total.saturating_sub(1));
    }
    let (w, h) = (args.size.width, args.size.height);
    let t = path.time_of_frame(args.frame, 1.0);
    let cam = path.camera_at(t, w, h)?;
    let next = (args.frame + 1).min(total - 1);
    let t_next = path.time_of_frame(next, 1.0);
    let cam_next = path.camera_at(t_next, w, h)?;
    std::fs::create_dir_all(&args.out).with_context(|| format!("{}: cannot create folder", args.out.display()))?;
    let out = |name: &str| -> PathBuf { args.out.join(name) };
    let mut files = Vec::new();
    let mut note = |p: &Path| files.push(p.display().to_string());

    let has_ground = scene.instances.iter().any(|i| i.is_ground);
    let job = RenderJob { scene, cam: &cam, t, cam_next: &cam_next, t_next, layers: args.layers, has_ground };
    let rendered = render(&Device::open(args.backend)?, &job)?;
    let (frame, motion) = (&rendered, &rendered.motion);

    let p = out("depth.png");
    zwarp_viz::write_png(&p, &zwarp_viz::depth_to_rgb8(&frame.depth, Some(&cam)))?;
    note(&p);
    let p = out("depth.exr");
    zwarp_viz::write_exr_f32(&p, &frame.depth, "Z")?;
    note(&p);
    let p = out("items.png");
    zwarp_viz::write_png(&p, &zwarp_viz::items_to_rgb8(&frame.items))?;
    note(&p);
    if let Some(color) = &frame.color {
        let p = out("color.png");
        zwarp_viz::write_png(&p, &zwarp_viz::color_to_rgb8(color))?;
        note(&p);
        let p = out("color.exr");
        zwarp_viz::write_exr_rgb(&p, color)?;
        note(&p);
    }
    let p = out("motion.png");
    zwarp_viz::write_png(&p, &zwarp_viz::motion_to_rgb8(motion, None))?;
    note(&p);
    let p = out("motion.exr");
    zwarp_viz::write_exr_motion(&p, motion)?;
    note(&p);

    let mut layer_coverage = Vec::new();
    for (k, layer) in rendered.layers.iter().enumerate() {
        let name =
            if has_ground && k + 1 == rendered.layers.len() { "layer_ground".to_string() } else { format!("layer{k}") };
        let p = out(&format!("{name}.png"));
        zwarp_viz::write_png(&p, &zwarp_viz::depth_to_rgb8(layer, Some(&cam)))?;
        note(&p);
        let p = out(&format!("{name}.exr"));
        zwarp_viz::write_exr_f32(&p, layer, "Z")?;
        note(&p);
        layer_coverage.push(layer.data().iter().filter(|&&d| d < 1.0).count());
    }
    let covered = frame.depth.data().iter().filter(|&&d| d < 1.0).count() as f64 / frame.depth.len() as f64;
    let max_motion = motion
        .data()
        .iter()
        .zip(frame.depth.data())
        .filter(|(_, &d)| d < 1.0)
        .map(|(m, _)| m.v.length())
        .fold(0.0f32, f32::max);
    let row = RenderRow {
        scene: args.scene.scene.clone(),
        frame: args.frame,
        t,
        width: w,
        height: h,
        objects: scene.instances.len(),
        triangles: scene.triangle_count(),
        depth_ms: Timing::of(&rendered.depth_samples).median,
        covered_fraction: covered,
        max_motion_px: max_motion,
        layer_coverage,
        files,
    };
    let backend = match &rendered.adapter {
        Some(a) => format!("GPU {a}"),
        None => format!("CPU, {} threads", rayon::current_num_threads()),
    };
    println!(
        "rendered {} frame {} (t = {:.3} s) at {}x{} on {backend}: {} objects, {} triangles, depth-only {:.1} ms (median of 3), {:.1}% covered, max motion {:.1} px",
        row.scene,
        row.frame,
        t,
        w,
        h,
        row.objects,
        row.triangles,
        row.depth_ms,
        covered * 100.0,
        max_motion
    );
    println!("wrote {} files to {}", row.files.len(), args.out.display());
    if let Some(j) = &args.json {
        let meta = serde_json::json!({
            "backend": if rendered.adapter.is_some() { "gpu" } else { "cpu" },
            "adapter": rendered.adapter,
            "threads": rayon::current_num_threads(),
        });
        output::write_json(j, "render", std::slice::from_ref(&row), meta)?;
    }
    Ok(())
}
