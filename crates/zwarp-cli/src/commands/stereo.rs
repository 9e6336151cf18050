//! `zwarp stereo`: stereoscopic views by colour warping (seed 001 Sec. 3.3 Fig. 2, 6: stereo
//! post-conversion of a racing game). The eyes are the path's centre camera moved by `-E/2` and
//! `+E/2` along its right axis (ARCHITECTURE.md "Stereo/VR"). Two strategies: `cyclops` warps
//! the one rendered centre view to both eyes (spatial field, eq. 4), `alternate` warps the
//! previous frame's other eye (temporal + spatial field, Sec. 4's linear combination). Every
//! method is compared per eye with rendering that eye; anaglyph and side-by-side images.

use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::Args;
use serde::Serialize;
use zwarp_color::{Field, FieldParams, HeuristicParams, RobustParams, Seed, WarpBasis};
use zwarp_core::{Camera, Image};

use super::colorwarp::{self, Backends, Method, View};
use crate::args::{Backend, SceneArgs, SizeArgs};
use crate::harness::{self, Figures, Lone, PathFrames, Quality, Timing};
use crate::output::{self, Table};

/// Arguments of `zwarp stereo`.
#[derive(Args, Clone, Debug)]
pub struct StereoArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    #[command(flatten)]
    pub size: SizeArgs,
    /// Frames evaluated, spread evenly along the camera path.
    #[arg(long, default_value_t = 2)]
    pub frames: usize,
    /// Eye separation (interpupillary distance) in world units; default 64 mm.
    #[arg(long, default_value_t = 0.064, allow_negative_numbers = true)]
    pub eye_sep: f32,
    /// Strategies (comma list of cyclops, alternate).
    #[arg(long, default_value = "cyclops,alternate")]
    pub strategy: String,
    /// Methods (comma list of heuristic, robust, repeat, mesh, reproject, scatter, or `all`).
    #[arg(long, default_value = "all")]
    pub methods: String,
    /// `cpu` or `gpu` (renders and the two colour warps on the GPU; baselines on the CPU).
    #[arg(long, value_enum, default_value_t = Backend::Cpu)]
    pub backend: Backend,
    /// Timed repetitions per measurement (after one warm-up run).
    #[arg(long, default_value_t = 3)]
    pub reps: usize,
    /// Write anaglyph, side-by-side, predictions and FLIP maps here (first frame).
    #[arg(long)]
    pub images: Option<PathBuf>,
    /// Write the results as JSON (`rows`).
    #[arg(long)]
    pub json: PathBuf,
}

/// One (strategy, eye, method), aggregated over the frames (JSON `rows`).
#[derive(Clone, Debug, Serialize)]
pub struct StereoRow {
    /// `heuristic`, `robust`, `repeat`, `mesh`, `reproject`, `scatter`.
    pub method: String,
    /// `cyclops` (from the centre view) or `alternate` (from the previous frame's other eye).
    pub strategy: String,
    /// `left` or `right`.
    pub eye: String,
    /// Scene spec.
    pub scene: String,
    /// Eye separation (world units).
    pub eye_sep: f32,
    /// Frames the row averages.
    pub frames: usize,
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
    /// Quality (means over the frames).
    #[serde(flatten)]
    pub quality: Quality,
    /// Speed (the prediction of this eye; the render: this eye with colour).
    #[serde(flatten)]
    pub speed: colorwarp::WarpSpeed,
    /// The heuristic's fixed seed offset (pixels, x), the mean over the frames.
    pub seed_offset_px: f32,
}

/// The camera of one eye: `cam` moved by `side * sep / 2` along its right axis.
pub fn eye_camera(cam: &Camera, side: f32, sep: f32) -> Camera {
    colorwarp::offset_camera(cam, side * 0.5 * sep, 0.0, None)
}

/// Red-cyan anaglyph of two linear RGB views (red from the left eye, green and blue from the
/// right), as sRGB.
pub fn anaglyph(left: &Image<[f32; 3]>, right: &Image<[f32; 3]>) -> Image<[u8; 3]> {
    let (l, r) = (zwarp_viz::color_to_rgb8(left), zwarp_viz::color_to_rgb8(right));
    Image::from_fn(l.width(), l.height(), |x, y| [l.get(x, y)[0], r.get(x, y)[1], r.get(x, y)[2]])
}

#[derive(Default)]
struct Acc {
    q: Vec<Quality>,
    ms: Vec<f64>,
    floor: Vec<f64>,
    render: Vec<f64>,
    offset: Vec<f32>,
}

fn evaluate(args: &StereoArgs, loaded: &crate::args::Loaded) -> Result<(Vec<StereoRow>, String)> {
    args.size.check()?;
    let sep = args.eye_sep;
    if !(sep.is_finite() && sep > 0.0) {
        bail!("--eye-sep must be a positive distance, got {sep}");
    }
    if args.frames == 0 {
        bail!("--frames must be at least 1");
    }
    let mut strategies = Vec::new();
    for s in crate::args::parse_list::<String>(&args.strategy, "--strategy")? {
        match s.as_str() {
            "cyclops" => strategies.push(false),
            "alternate" => strategies.push(true),
            o => bail!("--strategy: unknown strategy '{o}' (cyclops, alternate)"),
        }
    }
    let methods = colorwarp::parse_methods(&args.methods)?;
    let reps = args.reps.max(1);
    let (w, h) = (args.size.width, args.size.height);
    let path = &loaded.path;
    let be = Backends::new(&loaded.scene, args.backend)?;
    let frames = PathFrames::new(path, 1.0, w, h);
    let total =
        frames.require(2, |total| format!("the camera path is too short for stereo ({total} frame; need 2)"))?;
    // Frames with a previous one (the alternate strategy's source).
    let picked = frames.pick(args.frames, 1..=total - 1, Lone::Middle)?;
    let bar = harness::progress(
        (picked.len() * strategies.len() * 2 * methods.len()) as u64,
        format!("stereo {}", args.scene.scene),
        true,
    );
    let mut accs: Vec<((bool, bool, Method), Acc)> = Vec::new();
    let mut strips = colorwarp::Strips::new();
    // (name, left, right) views of the first frame for the anaglyph and side-by-side images.
    type Pair = (String, Image<[f32; 3]>, Image<[f32; 3]>);
    let mut pairs: Vec<Pair> = Vec::new();
    let mut slot = zwarp_color::ColorWarpOutput::empty();
    for (ki, frame) in picked.iter().enumerate() {
        let before = frames.previous(frame)?;
        let (t, tp, c, cp) = (frame.t, before.t, frame.cam, before.cam);
        let centre = be.view(&c, t)?;
        colorwarp::check_has_surface(&centre, &format!("frame {} of the camera path", frame.k))?;
        let centre_basis = WarpBasis::new(&centre.depth)?.with_spatial(&c, None)?;
        // Reference eyes, rendered and timed.
        let mut refs = Vec::new();
        for side in [-1.0f32, 1.0] {
            let ce = eye_camera(&c, side, sep);
            let (v, samples) = harness::time_repeated(reps, || be.view(&ce, t))?;
            refs.push((v, samples));
        }
        for &alternate in &strategies {
            let mut preds: Vec<Vec<(Method, Image<[f32; 3]>)>> = vec![Vec::new(), Vec::new()];
            for (ei, side) in [-1.0f32, 1.0].into_iter().enumerate() {
                let (reference, render_samples) = &refs[ei];
                // The source: the centre view now, or the other eye of the previous frame.
                let prev_other;
                let alt_basis;
                let (src, field): (&View, Field<'_>) = if alternate {
                    let cs = eye_camera(&cp, -side, sep);
                    prev_other = be.view(&cs, tp)?;
                    let cs_now = eye_camera(&c, -side, sep);
                    let m = be.motion(&prev_other, &cs_now, t)?;
                    alt_basis = WarpBasis::temporal(&prev_other.depth, &m)?.with_spatial(&cs, None)?;
                    (&prev_other, alt_basis.field(FieldParams { t: 1.0, u: side * sep, v: 0.0 })?)
                } else {
                    (&centre, centre_basis.field(FieldParams::spatial(side * 0.5 * sep, 0.0))?)
                };
                let offset = zwarp_color::fixed_offset(&field);
                let hp = HeuristicParams { seed: Seed::Offset(offset), ..HeuristicParams::default() };
                let rp = RobustParams { fallback: hp, ..RobustParams::default() };
                let to_src = be.motion(reference, &src.cam, src.t)?;
                let unseen = colorwarp::unseen(&reference.depth, &to_src, &src.depth, &src.cam)?;
                let floor = zwarp_color::floor::floor_ms(&field, &src.color, reps)?.0;
                for &m in &methods {
                    // The two warps write into the reused slot.
                    let (out, samples) = match m {
                        Method::Heuristic => {
                            harness::time_into(reps, &mut slot, |o| be.heuristic_into(&field, &src.color, &hp, o))?
                        }
                        Method::Robust => {
                            harness::time_into(reps, &mut slot, |o| be.robust_into(&field, &src.color, &rp, o))?
                        }
                        Method::Repeat => {
                            harness::time_repeated(reps, || Ok(zwarp_color::repeat(&src.color, &src.depth)?))?
                        }
                        Method::Mesh => {
                            harness::time_repeated(reps, || Ok(zwarp_color::mesh_warp(&field, &src.color, &src.cam)?))?
                        }
                        Method::Scatter => {
                            harness::time_repeated(reps, || Ok(zwarp_color::scatter_warp(&field, &src.color)?))?
                        }
                        Method::Reproject => harness::time_repeated(reps, || {
                            let (d, it) = be.depth_items(&reference.cam, t)?;
                            let tv =
                                View { cam: reference.cam, t, color: Image::new(0, 0, [0.0; 3]), depth: d, items: it };
                            let ms = be.motion(&tv, &src.cam, src.t)?;
                            Ok(zwarp_color::reproject(&tv.depth, &ms, &src.depth, &src.color, &src.cam)?)
                        })?,
                    };
                    let q = harness::compare_color(
                        &reference.color,
                        &out.color,
                        out.converged_fraction(),
                        Some(&unseen),
                        Figures::All,
                    )?;
                    if ki == 0 && args.images.is_some() {
                        colorwarp::add_panel(
                            &mut strips,
                            (alternate, ei as u32),
                            &reference.color,
                            &out.color,
                            m.name(),
                        )?;
                        preds[ei].push((m, out.color.clone()));
                    }
                    let a = harness::entry(&mut accs, (alternate, ei == 1, m));
                    a.q.push(q);
                    a.ms.extend(samples);
                    a.floor.push(floor);
                    a.render.extend(render_samples.iter().copied());
                    a.offset.push(offset.x);
                    bar.inc(1);
                }
            }
            if ki == 0 {
                let strategy = if alternate { "alternate" } else { "cyclops" };
                for (m, l) in &preds[0] {
                    if let Some((_, r)) = preds[1].iter().find(|(m2, _)| m2 == m) {
                        pairs.push((format!("{strategy}_{}", m.name()), l.clone(), r.clone()));
                    }
                }
            }
        }
        if ki == 0 {
            pairs.push(("reference".into(), refs[0].0.color.clone(), refs[1].0.color.clone()));
        }
    }
    bar.finish_and_clear();
    if let Some(dir) = &args.images {
        let base = colorwarp::safe_name(&args.scene.scene);
        colorwarp::write_color(dir, &format!("{base}_centre"), &be.view(&picked[0].cam, picked[0].t)?.color)?;
        for (name, l, r) in &pairs {
            zwarp_viz::write_png(dir.join(format!("{base}_{name}_anaglyph.png")), &anaglyph(l, r))?;
            let sbs = zwarp_viz::side_by_side(&[&zwarp_viz::color_to_rgb8(l), &zwarp_viz::color_to_rgb8(r)])?;
            zwarp_viz::write_png(dir.join(format!("{base}_{name}_sbs.png")), &sbs)?;
        }
        for ((alternate, eye), panels) in &strips {
            let strategy = if *alternate { "alternate" } else { "cyclops" };
            let eye = if *eye == 0 { "left" } else { "right" };
            colorwarp::write_strip(dir, &format!("{base}_{strategy}_{eye}_strip"), panels)?;
        }
    }
    let rows = accs
        .into_iter()
        .map(|((alternate, right, m), a)| {
            let speed = colorwarp::WarpSpeed::of(&a.ms, Timing::of(&a.render).median, Timing::of(&a.floor).median);
            StereoRow {
                method: m.name().into(),
                strategy: if alternate { "alternate" } else { "cyclops" }.into(),
                eye: if right { "right" } else { "left" }.into(),
                scene: args.scene.scene.clone(),
                eye_sep: sep,
                frames: a.q.len(),
                width: w,
                height: h,
                quality: harness::mean_quality(&a.q),
                speed,
                seed_offset_px: a.offset.iter().sum::<f32>() / a.offset.len().max(1) as f32,
            }
        })
        .collect();
    Ok((rows, be.name()))
}

/// The rows as a table.
pub fn table(rows: &[StereoRow]) -> String {
    let mut t = Table::new(&colorwarp::columns(&["method", "strategy", "eye"], true, "warp ms"));
    for r in rows {
        let mut cells = vec![r.method.clone(), r.strategy.clone(), r.eye.clone()];
        cells.extend(colorwarp::quality_cells(&r.quality, true));
        cells.extend(r.speed.cells(2));
        t.row(cells);
    }
    t.render()
}

/// `zwarp stereo`.
pub fn run(args: StereoArgs) -> Result<()> {
    if !(args.eye_sep.is_finite() && args.eye_sep > 0.0) {
        bail!("--eye-sep must be a positive distance, got {}", args.eye_sep);
    }
    let loaded = args.scene.load()?;
    let (rows, backend) = evaluate(&args, &loaded)?;
    println!(
        "zwarp stereo: {} ({} objects, {} triangles), {}x{}, eye separation {}, {} frame(s), backend {backend}, {} CPU threads",
        args.scene.scene,
        loaded.scene.instances.len(),
        loaded.scene.triangle_count(),
        args.size.width,
        args.size.height,
        args.eye_sep,
        args.frames,
        rayon::current_num_threads()
    );
    println!("{}", table(&rows));
    output::write_json(
        &args.json,
        "stereo",
        &rows,
        serde_json::json!({ "backend": backend, "threads": rayon::current_num_threads() }),
    )?;
    println!("wrote {}", args.json.display());
    if let Some(d) = &args.images {
        println!("images in {}", d.display());
    }
    Ok(())
}
