//! `zwarp render`: the buffers of one frame as images a person can look at (PNG) and as float
//! EXR where the value matters.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::Args;
use serde::Serialize;
use zwarp_raster::{render_frame, render_layers, FrameOptions, PeelOptions};

use crate::args::{SceneArgs, SizeArgs};
use crate::report::{self, Timing};

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

    let (_, samples) = report::time_repeated(3, || Ok(zwarp_raster::render_depth(scene, &cam, t)?))?;
    let frame = render_frame(scene, &cam, t, &FrameOptions { color: true, objects: None })?;
    let motion =
        zwarp_core::motion_field(&frame.depth, Some(&frame.items), &cam, &cam_next, &scene.object_deltas(t, t_next))?;

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
    zwarp_viz::write_png(&p, &zwarp_viz::motion_to_rgb8(&motion, None))?;
    note(&p);
    let p = out("motion.exr");
    zwarp_viz::write_exr_motion(&p, &motion)?;
    note(&p);

    let mut layer_coverage = Vec::new();
    if args.layers > 0 {
        let has_ground = scene.instances.iter().any(|i| i.is_ground);
        let layers = render_layers(
            scene,
            &cam,
            t,
            &PeelOptions { layers: args.layers, ground_separate: has_ground, umbra: None },
        )?;
        for (k, layer) in layers.iter().enumerate() {
            let name =
                if has_ground && k + 1 == layers.len() { "layer_ground".to_string() } else { format!("layer{k}") };
            let p = out(&format!("{name}.png"));
            zwarp_viz::write_png(&p, &zwarp_viz::depth_to_rgb8(&layer.depth, Some(&cam)))?;
            note(&p);
            let p = out(&format!("{name}.exr"));
            zwarp_viz::write_exr_f32(&p, &layer.depth, "Z")?;
            note(&p);
            layer_coverage.push(layer.coverage());
        }
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
        depth_ms: Timing::of(&samples).median,
        covered_fraction: covered,
        max_motion_px: max_motion,
        layer_coverage,
        files,
    };
    println!(
        "rendered {} frame {} (t = {:.3} s) at {}x{}: {} objects, {} triangles, depth-only {:.1} ms (median of 3), {:.1}% covered, max motion {:.1} px",
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
        report::write_json(j, "render", std::slice::from_ref(&row), serde_json::json!({}))?;
    }
    Ok(())
}
