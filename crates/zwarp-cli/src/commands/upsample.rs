//! `zwarp upsample`: frame-rate upsampling by colour warping (seed 001 Sec. 4-5: 30 -> 60 Hz
//! in a racing game, here also 120 Hz). Every in-between frame `k + j / factor` of the camera
//! path is predicted from the rendered frame `k` (extrapolation: its motion towards the previous
//! frame, linear `t M` or second-order `t M + t^2/2 A` from three frames; eq. 2, 3) or, with
//! `--interpolate`, from both rendered neighbours `k` and `k + 1` (Sec. 6), by the heuristic and
//! the robust warp and by the baselines, and compared with rendering it.

use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::Args;
use serde::Serialize;
use zwarp_color::{ColorWarpOutput, FieldParams, HeuristicParams, RobustParams, Seed, WarpBasis};
use zwarp_core::Image;

use super::colorwarp::{self, Backends, Method, View};
use crate::args::{Backend, SceneArgs, SizeArgs};
use crate::harness::{self, Figures, Lone, PathFrames, Quality, Timing};
use crate::output::{self, Table};

/// Arguments of `zwarp upsample`.
#[derive(Args, Clone, Debug)]
pub struct UpsampleArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    #[command(flatten)]
    pub size: SizeArgs,
    /// Rendered source frames, spread evenly along the camera path.
    #[arg(long, default_value_t = 2)]
    pub frames: usize,
    /// Output frames per rendered frame (2: 30 -> 60 Hz, 4: 30 -> 120 Hz); 2..=16.
    #[arg(long, default_value_t = 2)]
    pub factor: u32,
    /// Also predict every in-between frame from both rendered neighbours (rows with mode
    /// `interpolate`).
    #[arg(long)]
    pub interpolate: bool,
    /// Motion model of the extrapolation: `exact` (the motion field towards the in-between
    /// frame's camera and object transforms, which an engine that simulates at the output rate
    /// knows — the same knowledge the target's re-render of `reproject` needs), `linear` (`t M`
    /// from the motion towards the previous frame, eq. 2) or `quadratic` (`t M + t^2/2 A` from
    /// the two previous frames, eq. 3).
    #[arg(long, default_value = "exact")]
    pub motion: String,
    /// Methods (comma list of heuristic, robust, repeat, mesh, reproject, scatter, or `all`).
    #[arg(long, default_value = "all")]
    pub methods: String,
    /// `cpu` or `gpu` (renders and the two colour warps on the GPU; baselines on the CPU).
    #[arg(long, value_enum, default_value_t = Backend::Cpu)]
    pub backend: Backend,
    /// Timed repetitions per measurement (after one warm-up run).
    #[arg(long, default_value_t = 3)]
    pub reps: usize,
    /// Write source, reference, predictions and FLIP maps here (first in-between frame).
    #[arg(long)]
    pub images: Option<PathBuf>,
    /// Write the results as JSON (`rows`).
    #[arg(long)]
    pub json: PathBuf,
}

/// One method and mode, aggregated over every predicted frame (JSON `rows`).
#[derive(Clone, Debug, Serialize)]
pub struct UpsampleRow {
    /// `heuristic`, `robust`, `repeat`, `mesh`, `reproject`, `scatter`.
    pub method: String,
    /// `extrapolate` (from the previous rendered frame) or `interpolate` (from both).
    pub mode: String,
    /// `linear` or `quadratic` (extrapolation's motion model; `linear` for interpolation).
    pub motion: String,
    /// Scene spec.
    pub scene: String,
    /// Output frames per rendered frame.
    pub factor: u32,
    /// Predicted frames the row averages.
    pub frames: usize,
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
    /// Quality (means over the predicted frames).
    #[serde(flatten)]
    pub quality: Quality,
    /// Speed: the prediction is the warp from the motion buffers (reproject: the target's depth
    /// re-render, its motion towards the source and the look-up); the render is the predicted
    /// frame with colour.
    #[serde(flatten)]
    pub speed: colorwarp::WarpSpeed,
    /// Median time (ms) of the motion fields the field is built from, reported apart.
    pub motion_ms: f64,
}

/// Extrapolation motion model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Model {
    Exact,
    Linear,
    Quadratic,
}

impl Model {
    fn name(self) -> &'static str {
        match self {
            Model::Exact => "exact",
            Model::Linear => "linear",
            Model::Quadratic => "quadratic",
        }
    }
}

struct Plan {
    factor: u32,
    frames: usize,
    interpolate: bool,
    model: Model,
    methods: Vec<Method>,
    reps: usize,
}

impl UpsampleArgs {
    fn plan(&self) -> Result<Plan> {
        self.size.check()?;
        if !(2..=16).contains(&self.factor) {
            bail!("--factor must be 2..=16 (2: 30 -> 60 Hz, 4: 30 -> 120 Hz), got {}", self.factor);
        }
        if self.frames == 0 {
            bail!("--frames must be at least 1");
        }
        let model = match self.motion.as_str() {
            "exact" => Model::Exact,
            "linear" => Model::Linear,
            "quadratic" => Model::Quadratic,
            o => bail!("--motion: unknown motion model '{o}' (exact, linear, quadratic)"),
        };
        Ok(Plan {
            factor: self.factor,
            frames: self.frames,
            interpolate: self.interpolate,
            model,
            methods: colorwarp::parse_methods(&self.methods)?,
            reps: self.reps.max(1),
        })
    }
}

#[derive(Default)]
struct Acc {
    q: Vec<Quality>,
    ms: Vec<f64>,
    floor: Vec<f64>,
}

/// Runs the plan; one row per (mode, method).
fn evaluate(args: &UpsampleArgs, plan: &Plan, loaded: &crate::args::Loaded) -> Result<(Vec<UpsampleRow>, String)> {
    let scene = &loaded.scene;
    let path = &loaded.path;
    let (w, h) = (args.size.width, args.size.height);
    let be = Backends::new(scene, args.backend)?;
    let frames = PathFrames::new(path, 1.0, w, h);
    let total =
        frames.require(4, |total| format!("the camera path is too short for upsampling ({total} frames; need 4)"))?;
    // Source frames k in [2, total - 2]: two earlier frames for the quadratic motion, one later
    // for interpolation and as the end of the in-between interval.
    let sources = frames.pick(plan.frames, 2..=total - 2, Lone::Middle)?;
    let modes: Vec<bool> = if plan.interpolate { vec![false, true] } else { vec![false] };
    let motion_name = plan.model.name();
    let steps = (sources.len() * (plan.factor as usize - 1) * plan.methods.len() * modes.len()) as u64;
    let bar = harness::progress(steps, format!("upsample {}", args.scene.scene), true);
    let mut accs: Vec<((bool, Method), Acc)> = Vec::new();
    let mut strips = colorwarp::Strips::new();
    let mut slot = ColorWarpOutput::empty();
    let mut render_ms = Vec::new();
    let mut motion_ms = Vec::new();
    let hp = HeuristicParams { seed: Seed::Upstream(1.0), ..HeuristicParams::default() };
    let rp = RobustParams { fallback: hp, ..RobustParams::default() };
    for (ki, frame) in sources.iter().enumerate() {
        let src = be.view(&frame.cam, frame.t)?;
        colorwarp::check_has_surface(&src, &format!("frame {} of the camera path", frame.k))?;
        let after = frames.next(frame)?;
        let next = be.view(&after.cam, after.t)?;
        let t0 = std::time::Instant::now();
        let history = match plan.model {
            Model::Exact => None,
            Model::Linear => {
                // V(t) = t M with M towards frame k - 1: the target at +j/f is t = -j/f.
                let p = frames.previous(frame)?;
                let m_prev = be.motion(&src, &p.cam, p.t)?;
                Some(WarpBasis::temporal(&src.depth, &m_prev)?)
            }
            Model::Quadratic => {
                let (p, p2) = (frames.previous(frame)?, frames.frame(frame.k - 2)?);
                let m_prev = be.motion(&src, &p.cam, p.t)?;
                let m_prev2 = be.motion(&src, &p2.cam, p2.t)?;
                Some(WarpBasis::second_order(&src.depth, (-1.0, &m_prev), (-2.0, &m_prev2))?)
            }
        };
        motion_ms.push(t0.elapsed().as_secs_f64() * 1e3);
        let (fwd, bwd) = if plan.interpolate {
            let m_next = be.motion(&src, &next.cam, next.t)?;
            let m_back = be.motion(&next, &src.cam, src.t)?;
            (Some(WarpBasis::temporal(&src.depth, &m_next)?), Some(WarpBasis::temporal(&next.depth, &m_back)?))
        } else {
            (None, None)
        };
        for j in 1..plan.factor {
            let frac = j as f32 / plan.factor as f32;
            let tt = frame.t + frac / path.fps;
            let ct = frames.camera(tt)?;
            let (reference, samples) = harness::time_repeated(plan.reps, || be.view(&ct, tt))?;
            render_ms.extend(samples);
            // The target's geometry (RRC's re-render) and what the sources saw of it.
            let (tdepth, titems) = be.depth_items(&ct, tt)?;
            let target_view = View { cam: ct, t: tt, color: reference.color.clone(), depth: tdepth, items: titems };
            let to_src = be.motion(&target_view, &src.cam, src.t)?;
            let to_next = be.motion(&target_view, &next.cam, next.t)?;
            let unseen_src = colorwarp::unseen(&target_view.depth, &to_src, &src.depth, &src.cam)?;
            let unseen_next = colorwarp::unseen(&target_view.depth, &to_next, &next.depth, &next.cam)?;
            let unseen_both = Image::from_fn(w, h, |x, y| *unseen_src.get(x, y) && *unseen_next.get(x, y));
            let exact = match &history {
                Some(_) => None,
                None => {
                    let t0 = std::time::Instant::now();
                    let b = WarpBasis::temporal(&src.depth, &be.motion(&src, &ct, tt)?)?;
                    motion_ms.push(t0.elapsed().as_secs_f64() * 1e3);
                    Some(b)
                }
            };
            for &interp in &modes {
                let fe = match (&history, &exact) {
                    (Some(b), _) => {
                        b.field(FieldParams::temporal(if plan.model == Model::Quadratic { frac } else { -frac }))?
                    }
                    (None, Some(b)) => b.field(FieldParams::temporal(1.0))?,
                    _ => unreachable!("one extrapolation basis"),
                };
                let fa = fwd.as_ref().map(|b| b.field(FieldParams::temporal(frac))).transpose()?;
                let fb = bwd.as_ref().map(|b| b.field(FieldParams::temporal(1.0 - frac))).transpose()?;
                let combine = |a: ColorWarpOutput, b: ColorWarpOutput| -> Result<ColorWarpOutput> {
                    Ok(zwarp_color::combine_interpolated(&a, &b, frac, &src.cam)?)
                };
                let floor = if interp {
                    zwarp_color::floor::floor_ms(fa.as_ref().expect("fwd"), &src.color, plan.reps)?.0
                        + zwarp_color::floor::floor_ms(fb.as_ref().expect("bwd"), &next.color, plan.reps)?.0
                } else {
                    zwarp_color::floor::floor_ms(&fe, &src.color, plan.reps)?.0
                };
                for &m in &plan.methods {
                    let (out, samples) = match (m, interp) {
                        (Method::Heuristic, false) => {
                            harness::time_into(plan.reps, &mut slot, |o| be.heuristic_into(&fe, &src.color, &hp, o))?
                        }
                        (Method::Heuristic, true) => harness::time_repeated(plan.reps, || {
                            let a = be.heuristic(fa.as_ref().expect("fwd"), &src.color, &hp)?;
                            let b = be.heuristic(fb.as_ref().expect("bwd"), &next.color, &hp)?;
                            combine(a, b)
                        })?,
                        (Method::Robust, false) => {
                            harness::time_into(plan.reps, &mut slot, |o| be.robust_into(&fe, &src.color, &rp, o))?
                        }
                        (Method::Robust, true) => harness::time_repeated(plan.reps, || {
                            let a = be.robust(fa.as_ref().expect("fwd"), &src.color, &rp)?;
                            let b = be.robust(fb.as_ref().expect("bwd"), &next.color, &rp)?;
                            combine(a, b)
                        })?,
                        (Method::Repeat, _) => harness::time_repeated(plan.reps, || {
                            let v = if interp && frac > 0.5 { &next } else { &src };
                            Ok(zwarp_color::repeat(&v.color, &v.depth)?)
                        })?,
                        (Method::Mesh, false) => harness::time_repeated(plan.reps, || {
                            Ok(zwarp_color::mesh_warp(&fe, &src.color, &src.cam)?)
                        })?,
                        (Method::Mesh, true) => harness::time_repeated(plan.reps, || {
                            let a = zwarp_color::mesh_warp(fa.as_ref().expect("fwd"), &src.color, &src.cam)?;
                            let b = zwarp_color::mesh_warp(fb.as_ref().expect("bwd"), &next.color, &next.cam)?;
                            combine(a, b)
                        })?,
                        (Method::Scatter, false) => {
                            harness::time_repeated(plan.reps, || Ok(zwarp_color::scatter_warp(&fe, &src.color)?))?
                        }
                        (Method::Scatter, true) => harness::time_repeated(plan.reps, || {
                            let a = zwarp_color::scatter_warp(fa.as_ref().expect("fwd"), &src.color)?;
                            let b = zwarp_color::scatter_warp(fb.as_ref().expect("bwd"), &next.color)?;
                            combine(a, b)
                        })?,
                        (Method::Reproject, _) => harness::time_repeated(plan.reps, || {
                            // The re-render of the target's depth is part of the method's cost.
                            let (d, it) = be.depth_items(&ct, tt)?;
                            let tv = View { cam: ct, t: tt, color: Image::new(0, 0, [0.0; 3]), depth: d, items: it };
                            let ms = be.motion(&tv, &src.cam, src.t)?;
                            let a = zwarp_color::reproject(&tv.depth, &ms, &src.depth, &src.color, &src.cam)?;
                            if !interp {
                                return Ok(a);
                            }
                            let mn = be.motion(&tv, &next.cam, next.t)?;
                            let b = zwarp_color::reproject(&tv.depth, &mn, &next.depth, &next.color, &next.cam)?;
                            combine(a, b)
                        })?,
                    };
                    let unseen = if interp { &unseen_both } else { &unseen_src };
                    let q = harness::compare_color(
                        &reference.color,
                        &out.color,
                        out.converged_fraction(),
                        Some(unseen),
                        Figures::All,
                    )?;
                    if ki == 0 && j == 1 {
                        if let Some(dir) = &args.images {
                            let base = format!("{}_f{}", colorwarp::safe_name(&args.scene.scene), plan.factor);
                            let mode = if interp { "interp" } else { "extrap" };
                            colorwarp::write_color(dir, &format!("{base}_source"), &src.color)?;
                            colorwarp::write_color(dir, &format!("{base}_reference"), &reference.color)?;
                            zwarp_viz::write_png(
                                dir.join(format!("{base}_{mode}_unseen.png")),
                                &zwarp_viz::mask_to_rgb8(unseen),
                            )?;
                            colorwarp::write_color(dir, &format!("{base}_{mode}_{}", m.name()), &out.color)?;
                            colorwarp::write_flip(
                                dir,
                                &format!("{base}_{mode}_{}_flip", m.name()),
                                &reference.color,
                                &out.color,
                            )?;
                            colorwarp::add_panel(&mut strips, (interp, 0), &reference.color, &out.color, m.name())?;
                        }
                    }
                    let a = harness::entry(&mut accs, (interp, m));
                    a.q.push(q);
                    a.ms.extend(samples);
                    a.floor.push(floor);
                    bar.inc(1);
                }
            }
        }
    }
    bar.finish_and_clear();
    if let Some(dir) = &args.images {
        for ((interp, _), panels) in &strips {
            let mode = if *interp { "interp" } else { "extrap" };
            let base = format!("{}_f{}", colorwarp::safe_name(&args.scene.scene), plan.factor);
            colorwarp::write_strip(dir, &format!("{base}_{mode}_strip"), panels)?;
        }
    }
    let render = Timing::of(&render_ms).median;
    let rows = accs
        .into_iter()
        .map(|((interp, m), a)| {
            let speed = colorwarp::WarpSpeed::of(&a.ms, render, Timing::of(&a.floor).median);
            UpsampleRow {
                method: m.name().into(),
                mode: if interp { "interpolate" } else { "extrapolate" }.into(),
                motion: if interp { "linear" } else { motion_name }.into(),
                scene: args.scene.scene.clone(),
                factor: plan.factor,
                frames: a.q.len(),
                width: w,
                height: h,
                quality: harness::mean_quality(&a.q),
                speed,
                motion_ms: Timing::of(&motion_ms).median,
            }
        })
        .collect();
    Ok((rows, be.name()))
}

/// The rows as a table.
pub fn table(rows: &[UpsampleRow]) -> String {
    let mut t = Table::new(&colorwarp::columns(&["method", "mode", "motion", "factor"], true, "warp ms"));
    for r in rows {
        let mut cells = vec![r.method.clone(), r.mode.clone(), r.motion.clone(), r.factor.to_string()];
        cells.extend(colorwarp::quality_cells(&r.quality, true));
        cells.extend(r.speed.cells(2));
        t.row(cells);
    }
    t.render()
}

/// `zwarp upsample`.
pub fn run(args: UpsampleArgs) -> Result<()> {
    let plan = args.plan()?;
    let loaded = args.scene.load()?;
    let (rows, backend) = evaluate(&args, &plan, &loaded)?;
    println!(
        "zwarp upsample: {} ({} objects, {} triangles), {}x{}, factor {}, {} source frame(s), backend {backend}, {} CPU threads",
        args.scene.scene,
        loaded.scene.instances.len(),
        loaded.scene.triangle_count(),
        args.size.width,
        args.size.height,
        plan.factor,
        plan.frames,
        rayon::current_num_threads()
    );
    println!("{}", table(&rows));
    output::write_json(
        &args.json,
        "upsample",
        &rows,
        serde_json::json!({ "backend": backend, "threads": rayon::current_num_threads() }),
    )?;
    println!("wrote {}", args.json.display());
    if let Some(d) = &args.images {
        println!("images in {}", d.display());
    }
    Ok(())
}
