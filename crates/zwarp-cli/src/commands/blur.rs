//! `zwarp blur`: motion blur and defocus by accumulating many warped views (seed 001 Sec. 4,
//! Algorithm 1, Fig. 7, 10; the accumulation buffer of Haeberli & Akeley 1990). K parameter
//! samples `(t, u, v)` — shutter time and lens position — are drawn from a Poisson-disk
//! distribution; the reference averages K rendered views (the lens samples are thin-lens cameras
//! sheared to keep the focal plane), the warps average K reprojections of the one rendered
//! centre view with the field `t M + t^2/2 A + (u, v) S` (second-order motion through the two
//! neighbouring frames, eq. 3; spatial eq. 4 relative to the focal plane). The robust warp
//! subdivides once for all samples (eq. 9: `rho` maximised over the parameter ranges).

use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::Args;
use serde::Serialize;
use zwarp_color::{ColorWarpOutput, Field, FieldParams, HeuristicParams, RobustParams, Seed, Subdivision, WarpBasis};
use zwarp_core::Image;

use super::colorwarp::{self, Backends, Method, View};
use crate::args::{Backend, SceneArgs, SizeArgs};
use crate::harness::{self, Figures, Lone, PathFrames, Quality, Timing};
use crate::output::{self, Table};

/// Arguments of `zwarp blur`.
#[derive(Args, Clone, Debug)]
pub struct BlurArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    #[command(flatten)]
    pub size: SizeArgs,
    /// Frames evaluated, spread evenly along the camera path.
    #[arg(long, default_value_t = 1)]
    pub frames: usize,
    /// Motion blur over the shutter interval (`--shutter`).
    #[arg(long)]
    pub motion: bool,
    /// Defocus blur of a thin lens (`--aperture`, `--focus`).
    #[arg(long)]
    pub defocus: bool,
    /// K: views accumulated (Poisson samples over t, u, v).
    #[arg(long, default_value_t = 64)]
    pub samples: usize,
    /// Shutter interval in frames, centred on the frame (0.5 = a 180-degree shutter).
    #[arg(long, default_value_t = 0.5, allow_negative_numbers = true)]
    pub shutter: f32,
    /// Lens radius in world units.
    #[arg(long, default_value_t = 0.05, allow_negative_numbers = true)]
    pub aperture: f32,
    /// Focus distance in world units (default: the view depth at the image centre).
    #[arg(long)]
    pub focus: Option<f32>,
    /// Methods (comma list of heuristic, robust, repeat, mesh, reproject, scatter, or `all`).
    #[arg(long, default_value = "all")]
    pub methods: String,
    /// `cpu` or `gpu` (renders and the two colour warps on the GPU; baselines on the CPU).
    #[arg(long, value_enum, default_value_t = Backend::Cpu)]
    pub backend: Backend,
    /// Timed repetitions of every accumulation (after one warm-up run).
    #[arg(long, default_value_t = 1)]
    pub reps: usize,
    /// Write the reference, the accumulated predictions and FLIP maps here (first frame).
    #[arg(long)]
    pub images: Option<PathBuf>,
    /// Write the results as JSON (`rows`).
    #[arg(long)]
    pub json: PathBuf,
}

/// One method, aggregated over the frames (JSON `rows`).
#[derive(Clone, Debug, Serialize)]
pub struct BlurRow {
    /// `heuristic`, `robust`, `repeat` (the sharp frame), `mesh`, `reproject`, `scatter`.
    pub method: String,
    /// K: views accumulated.
    pub samples: usize,
    /// Motion blur on.
    pub motion: bool,
    /// Defocus on.
    pub defocus: bool,
    /// Scene spec.
    pub scene: String,
    /// Frames the row averages.
    pub frames: usize,
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
    /// Quality against the K rendered views' average (means over the frames).
    #[serde(flatten)]
    pub quality: Quality,
    /// Median time (ms) of the K accumulated predictions (robust: with its one subdivision).
    pub ms: f64,
    /// Fastest.
    pub ms_min: f64,
    /// Slowest.
    pub ms_max: f64,
    /// Median time (ms) of the reference: K rendered views accumulated, same run.
    pub render_ms: f64,
    /// `render_ms / ms`.
    pub speedup: f64,
    /// K times the streaming floor (ms) of one view (`zwarp_color::floor`), same run.
    pub floor_ms: f64,
    /// `ms / floor_ms`.
    pub floor_ratio: f64,
}

/// `x` in `[0, 1)` from a 64-bit counter (splitmix64).
fn unit(state: &mut u64) -> f32 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
}

/// K Poisson samples (dart throwing, deterministic) of `(t, u, v)`: `t` in `[-shutter/2,
/// shutter/2]` when `motion`, `(u, v)` in the disc of radius `aperture` when `defocus` (zero
/// otherwise). Seed 001 Sec. 4: "a Poisson-ball distribution".
pub fn poisson_samples(k: usize, motion: bool, defocus: bool, shutter: f32, aperture: f32) -> Vec<FieldParams> {
    let dims = motion as u32 + 2 * defocus as u32;
    let mut state = 0x5EED_u64;
    let mut pts: Vec<[f32; 3]> = Vec::with_capacity(k);
    // Unit domain: t in [-1/2, 1/2], (u, v) in the disc of radius 1/2.
    let volume = if defocus { std::f32::consts::PI * 0.25 } else { 1.0 };
    let mut r = 0.8 * (volume / k.max(1) as f32).powf(1.0 / dims.max(1) as f32);
    let mut fails = 0;
    while pts.len() < k {
        let t = if motion { unit(&mut state) - 0.5 } else { 0.0 };
        let (u, v) = if defocus {
            loop {
                let (a, b) = (unit(&mut state) - 0.5, unit(&mut state) - 0.5);
                if a * a + b * b <= 0.25 {
                    break (a, b);
                }
            }
        } else {
            (0.0, 0.0)
        };
        let p = [t, u, v];
        let ok = pts.iter().all(|q| (0..3).map(|i| (p[i] - q[i]).powi(2)).sum::<f32>() >= r * r);
        if ok || dims == 0 {
            pts.push(p);
            fails = 0;
        } else {
            fails += 1;
            if fails > 200 {
                r *= 0.9;
                fails = 0;
            }
        }
    }
    pts.iter().map(|p| FieldParams { t: p[0] * shutter, u: p[1] * 2.0 * aperture, v: p[2] * 2.0 * aperture }).collect()
}

fn accumulate(acc: &mut [[f32; 3]], img: &Image<[f32; 3]>) {
    for (a, c) in acc.iter_mut().zip(img.data()) {
        a[0] += c[0];
        a[1] += c[1];
        a[2] += c[2];
    }
}

fn average(w: u32, h: u32, acc: Vec<[f32; 3]>, k: usize) -> ColorWarpOutput {
    let s = 1.0 / k.max(1) as f32;
    let color = Image::from_vec(w, h, acc.into_iter().map(|c| c.map(|v| v * s)).collect()).expect("size");
    ColorWarpOutput { color, depth: Image::new(w, h, 1.0), residual: Image::new(w, h, 0.0), threshold: 0.5 }
}

#[derive(Default)]
struct Acc {
    q: Vec<Quality>,
    ms: Vec<f64>,
    floor: Vec<f64>,
}

fn evaluate(args: &BlurArgs, loaded: &crate::args::Loaded) -> Result<(Vec<BlurRow>, String, f64)> {
    let methods = colorwarp::parse_methods(&args.methods)?;
    let (w, h) = (args.size.width, args.size.height);
    let (k, reps) = (args.samples, args.reps.max(1));
    let path = &loaded.path;
    let be = Backends::new(&loaded.scene, args.backend)?;
    let frames = PathFrames::new(path, 1.0, w, h);
    let total =
        frames.require(3, |total| format!("the camera path is too short for motion blur ({total} frames; need 3)"))?;
    // Frames with a frame before and after (the second-order motion of the shutter interval).
    let picked = frames.pick(args.frames, 1..=total - 2, Lone::Middle)?;
    let samples = poisson_samples(k, args.motion, args.defocus, args.shutter, args.aperture);
    let bar =
        harness::progress((picked.len() * (methods.len() + 1)) as u64, format!("blur {}", args.scene.scene), true);
    let mut accs: Vec<(Method, Acc)> = Vec::new();
    let mut render_ms = Vec::new();
    let mut strips = colorwarp::Strips::new();
    let mut focus_used = 0.0;
    let mut slot = ColorWarpOutput::empty();
    for (ki, frame) in picked.iter().enumerate() {
        let (t, c) = (frame.t, frame.cam);
        let centre = be.view(&c, t)?;
        colorwarp::check_has_surface(&centre, &format!("frame {} of the camera path", frame.k))?;
        let focus = match args.focus {
            Some(f) => f,
            None => {
                let d = *centre.depth.get(w / 2, h / 2);
                let d = if d < 1.0 {
                    d
                } else {
                    let mut s: Vec<f32> = centre.depth.data().iter().copied().filter(|&d| d < 1.0).collect();
                    let mid = s.len() / 2;
                    *s.select_nth_unstable_by(mid, f32::total_cmp).1
                };
                c.linear_depth(d)
            }
        };
        focus_used = focus;
        let dt = 1.0 / path.fps;
        let sample_cam = |p: &FieldParams| -> Result<zwarp_core::Camera> {
            let cam = frames.camera(t + p.t * dt)?;
            Ok(if args.defocus { colorwarp::offset_camera(&cam, p.u, p.v, Some(focus)) } else { cam })
        };
        // The reference: K rendered views.
        let (reference, samples_ms) = harness::time_repeated(reps, || {
            let mut acc = vec![[0.0f32; 3]; (w * h) as usize];
            for p in &samples {
                accumulate(&mut acc, &be.view(&sample_cam(p)?, t + p.t * dt)?.color);
            }
            Ok(average(w, h, acc, k))
        })?;
        render_ms.extend(samples_ms);
        bar.inc(1);
        // The warp basis of the centre view.
        let mut basis = if args.motion {
            let m_next = be.motion(&centre, &frames.camera(t + dt)?, t + dt)?;
            let m_prev = be.motion(&centre, &frames.camera(t - dt)?, t - dt)?;
            WarpBasis::second_order(&centre.depth, (1.0, &m_next), (-1.0, &m_prev))?
        } else {
            WarpBasis::new(&centre.depth)?
        };
        if args.defocus {
            basis = basis.with_spatial(&c, Some(focus))?;
        }
        let fields: Vec<Field<'_>> = basis.fields(&samples)?;
        // eq. 9: rho over the corners of the parameter ranges.
        let mut corners = Vec::new();
        for ts in if args.motion { vec![-0.5, 0.5] } else { vec![0.0] } {
            for (us, vs) in
                if args.defocus { vec![(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] } else { vec![(0.0, 0.0)] }
            {
                corners.push(FieldParams { t: ts * args.shutter, u: us * args.aperture, v: vs * args.aperture });
            }
        }
        let corner_fields = basis.fields(&corners)?;
        let hp = HeuristicParams { seed: Seed::Upstream(1.0), ..HeuristicParams::default() };
        let rp = RobustParams { fallback: hp, ..RobustParams::default() };
        let floor = k as f64 * zwarp_color::floor::floor_ms(&fields[fields.len() / 2], &centre.color, 3)?.0;
        for &m in &methods {
            let (out, ms) = harness::time_repeated(reps, || -> Result<ColorWarpOutput> {
                if m == Method::Repeat {
                    return Ok(zwarp_color::repeat(&centre.color, &centre.depth)?);
                }
                let sub =
                    if m == Method::Robust { Some(Subdivision::of_fields(&corner_fields, rp.tile)?) } else { None };
                let mut acc = vec![[0.0f32; 3]; (w * h) as usize];
                for (f, p) in fields.iter().zip(&samples) {
                    let owned;
                    let o = match m {
                        Method::Heuristic => {
                            be.heuristic_into(f, &centre.color, &hp, &mut slot)?;
                            &slot
                        }
                        Method::Robust => {
                            be.robust_with_into(sub.as_ref().expect("subdivided"), f, &centre.color, &rp, &mut slot)?;
                            &slot
                        }
                        Method::Mesh => {
                            owned = zwarp_color::mesh_warp(f, &centre.color, &centre.cam)?;
                            &owned
                        }
                        Method::Scatter => {
                            owned = zwarp_color::scatter_warp(f, &centre.color)?;
                            &owned
                        }
                        Method::Reproject => {
                            let (cam, ts) = (sample_cam(p)?, t + p.t * dt);
                            let (d, it) = be.depth_items(&cam, ts)?;
                            let tv = View { cam, t: ts, color: Image::new(0, 0, [0.0; 3]), depth: d, items: it };
                            let mo = be.motion(&tv, &centre.cam, centre.t)?;
                            owned = zwarp_color::reproject(&tv.depth, &mo, &centre.depth, &centre.color, &centre.cam)?;
                            &owned
                        }
                        Method::Repeat => unreachable!("handled above"),
                    };
                    accumulate(&mut acc, &o.color);
                }
                Ok(average(w, h, acc, k))
            })?;
            let q = harness::compare_color(&reference.color, &out.color, out.converged_fraction(), None, Figures::All)?;
            if ki == 0 {
                if let Some(dir) = &args.images {
                    let base = colorwarp::safe_name(&args.scene.scene);
                    colorwarp::write_color(dir, &format!("{base}_blur_reference"), &reference.color)?;
                    colorwarp::write_color(dir, &format!("{base}_blur_{}", m.name()), &out.color)?;
                    colorwarp::add_panel(&mut strips, (false, 0), &reference.color, &out.color, m.name())?;
                }
            }
            let a = harness::entry(&mut accs, m);
            a.q.push(q);
            a.ms.extend(ms);
            a.floor.push(floor);
            bar.inc(1);
        }
    }
    bar.finish_and_clear();
    if let Some(dir) = &args.images {
        for (_, panels) in &strips {
            colorwarp::write_strip(dir, &format!("{}_blur_strip", colorwarp::safe_name(&args.scene.scene)), panels)?;
        }
    }
    let render = Timing::of(&render_ms).median;
    let rows = accs
        .into_iter()
        .map(|(m, a)| {
            let t = Timing::of(&a.ms);
            let floor = Timing::of(&a.floor).median;
            BlurRow {
                method: m.name().into(),
                samples: if m == Method::Repeat { 1 } else { k },
                motion: args.motion,
                defocus: args.defocus,
                scene: args.scene.scene.clone(),
                frames: a.q.len(),
                width: w,
                height: h,
                quality: harness::mean_quality(&a.q),
                ms: t.median,
                ms_min: t.min,
                ms_max: t.max,
                render_ms: render,
                speedup: render / t.median.max(1e-9),
                floor_ms: floor,
                floor_ratio: t.median / floor.max(1e-9),
            }
        })
        .collect();
    Ok((rows, be.name(), focus_used as f64))
}

/// The rows as a table.
pub fn table(rows: &[BlurRow]) -> String {
    let mut t = Table::new(&colorwarp::columns(&["method", "samples"], false, "ms"));
    for r in rows {
        let mut cells = vec![r.method.clone(), r.samples.to_string()];
        cells.extend(colorwarp::quality_cells(&r.quality, false));
        cells.extend(colorwarp::speed_cells(r.ms, r.floor_ms, r.floor_ratio, r.render_ms, r.speedup, 1));
        t.row(cells);
    }
    t.render()
}

/// `zwarp blur`.
pub fn run(args: BlurArgs) -> Result<()> {
    args.size.check()?;
    if args.samples == 0 {
        bail!("--samples must be at least 1");
    }
    if !args.motion && !args.defocus {
        bail!("nothing to blur: give --motion and/or --defocus");
    }
    if args.frames == 0 {
        bail!("--frames must be at least 1");
    }
    if !(args.shutter.is_finite() && args.shutter > 0.0 && args.shutter <= 2.0) {
        bail!("--shutter must be in (0, 2] frames, got {}", args.shutter);
    }
    if !(args.aperture.is_finite() && args.aperture > 0.0) {
        bail!("--aperture must be a positive lens radius, got {}", args.aperture);
    }
    if let Some(f) = args.focus {
        if !(f.is_finite() && f > 0.0) {
            bail!("--focus must be a positive distance, got {f}");
        }
    }
    let loaded = args.scene.load()?;
    let (rows, backend, focus) = evaluate(&args, &loaded)?;
    println!(
        "zwarp blur: {} ({} objects, {} triangles), {}x{}, K = {}, motion {}, defocus {} (focus {focus:.2}), backend {backend}, {} CPU threads",
        args.scene.scene,
        loaded.scene.instances.len(),
        loaded.scene.triangle_count(),
        args.size.width,
        args.size.height,
        args.samples,
        args.motion,
        args.defocus,
        rayon::current_num_threads()
    );
    println!("{}", table(&rows));
    output::write_json(
        &args.json,
        "blur",
        &rows,
        serde_json::json!({ "backend": backend, "threads": rayon::current_num_threads(), "focus": focus }),
    )?;
    println!("wrote {}", args.json.display());
    if let Some(d) = &args.images {
        println!("images in {}", d.display());
    }
    Ok(())
}
