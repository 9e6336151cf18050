//! Timing table of the CPU rasterizer on the evaluation scenes: depth-only renders (default
//! 1920x1080) from each scene's camera path, warm, repeated.
//!
//! ```text
//! cargo run --release -p zwarp-tools --bin raster_table -- yr mo bl cb /work/shared/scenes/sponza
//! ```
//!
//! Scene specs are anything [`zwarp_scene::load_scene`] accepts: `yr|mo|bl|cb` (the procedural
//! scenes of seed 000 Sec. 4, rendered from their recorded camera path) or a mesh file / folder.
//! Files have no recorded path: a folder named `sponza` uses the committed
//! `crates/zwarp-scene/paths/sponza_court.json` (compiled in), anything else
//! [`zwarp_scene::CameraPath::default_for`]. The frame rendered is the one at 1/3 of the path
//! (time `t0 + duration / 3`, also the animation time).
//!
//! Options:
//! - `--path FILE.json` camera path (`CameraPath` JSON) for the NEXT scene spec only;
//! - `--width W`, `--height H` (default 1920x1080), `--reps N` timed renders after two warm-up
//!   renders (default 15);
//! - `--seed N`, `--scale S` for the procedural generators, `--split none|components|K` for
//!   triangle soups (see `zwarp_scene::SceneOptions`);
//! - `--entry-points` adds a second table (depth only vs frame with items + colour vs peeling
//!   L = 4); `--dump DIR` writes each scene's linear depth (PGM) and flat colour (PPM).
//!
//! Prints a markdown table: objects, triangles, median wall ms, min-max, IQR, Mtris/s
//! (triangles / median), median CPU ms per render (all threads, from Linux schedstat: under
//! load from other processes wall time mostly measures waiting, CPU time still measures the
//! work) and the covered pixel fraction. Progress and load times go to stderr.

use std::path::{Path, PathBuf};
use std::time::Instant;

use zwarp_core::{Camera, Error, Result, Scene};
use zwarp_raster::{render_depth, render_frame, render_layers, FrameOptions, PeelOptions};
use zwarp_scene::{load_scene, CameraPath, SceneOptions, SplitMode};

/// The committed Sponza walk (see `crates/zwarp-scene/paths/README.md`), compiled in so the
/// binary does not depend on the working directory.
const SPONZA_COURT: &str = include_str!("../../../crates/zwarp-scene/paths/sponza_court.json");

/// One scene of the table: its spec and an optional camera path file.
struct Job {
    spec: String,
    path: Option<PathBuf>,
}

struct Config {
    jobs: Vec<Job>,
    width: u32,
    height: u32,
    reps: usize,
    opts: SceneOptions,
    entry_points: bool,
    dump: Option<PathBuf>,
}

fn main() {
    if let Err(e) = run() {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}

fn parse_args() -> Result<Config> {
    fn value<T: std::str::FromStr>(flag: &str, v: Option<String>) -> Result<T> {
        let v = v.ok_or_else(|| Error::invalid(format!("{flag} needs a value")))?;
        v.parse().map_err(|_| Error::invalid(format!("{flag}: cannot parse '{v}'")))
    }
    let mut cfg = Config {
        jobs: Vec::new(),
        width: 1920,
        height: 1080,
        reps: 15,
        opts: SceneOptions::default(),
        entry_points: false,
        dump: None,
    };
    let mut pending_path: Option<PathBuf> = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--width" => cfg.width = value(&a, args.next())?,
            "--height" => cfg.height = value(&a, args.next())?,
            "--reps" => cfg.reps = value(&a, args.next())?,
            "--seed" => cfg.opts.seed = value(&a, args.next())?,
            "--scale" => cfg.opts.scale = value(&a, args.next())?,
            "--split" => {
                cfg.opts.split = match args.next().as_deref() {
                    Some("none") => SplitMode::None,
                    Some("components") => SplitMode::Components,
                    Some(k) => SplitMode::Clusters(value("--split", Some(k.to_string()))?),
                    None => return Err(Error::invalid("--split needs none|components|<clusters>")),
                }
            }
            "--path" => pending_path = Some(value(&a, args.next())?),
            "--entry-points" => cfg.entry_points = true,
            "--dump" => cfg.dump = Some(value(&a, args.next())?),
            s if s.starts_with("--") => return Err(Error::invalid(format!("unknown option {s}"))),
            _ => cfg.jobs.push(Job { spec: a, path: pending_path.take() }),
        }
    }
    if pending_path.is_some() {
        return Err(Error::invalid("--path must be followed by the scene spec it applies to"));
    }
    if cfg.jobs.is_empty() {
        return Err(Error::invalid(
            "no scene given (usage: raster_table [options] SPEC... with SPEC = yr|mo|bl|cb|mesh file|folder)",
        ));
    }
    if cfg.width == 0 || cfg.height == 0 || cfg.reps == 0 {
        return Err(Error::invalid("--width, --height and --reps must be > 0"));
    }
    Ok(cfg)
}

/// `true` if `spec` is the Sponza soup folder of `shared/scenes/sponza` (a folder named
/// `sponza`, after resolving `.` and symlinks).
fn is_sponza_folder(spec: &str) -> bool {
    let p = Path::new(spec);
    p.is_dir()
        && p.canonicalize().ok().and_then(|c| c.file_name().map(|n| n.eq_ignore_ascii_case("sponza"))).unwrap_or(false)
}

/// The camera path of a job and a short label of where it came from.
fn camera_path(job: &Job, recorded: Option<&CameraPath>, scene: &Scene) -> Result<(CameraPath, String)> {
    if let Some(f) = &job.path {
        return Ok((CameraPath::from_json_file_at(f, scene.origin)?, f.display().to_string()));
    }
    if let Some(p) = recorded {
        return Ok((p.clone(), "recorded".into()));
    }
    if is_sponza_folder(&job.spec) {
        return Ok((CameraPath::from_json_str(SPONZA_COURT)?, "sponza_court.json".into()));
    }
    Ok((CameraPath::default_for(scene), "default".into()))
}

/// (median, min, max, q1, q3) of a non-empty sample.
fn stats(mut v: Vec<f64>) -> (f64, f64, f64, f64, f64) {
    v.sort_by(|a, b| a.total_cmp(b));
    let q = |p: f64| v[((v.len() - 1) as f64 * p).round() as usize];
    (q(0.5), v[0], v[v.len() - 1], q(0.25), q(0.75))
}

/// CPU time consumed so far by all threads of this process, in ms (Linux
/// `/proc/self/task/*/schedstat`, nanosecond precision); `None` elsewhere.
fn cpu_ms() -> Option<f64> {
    let mut total = 0u64;
    for t in std::fs::read_dir("/proc/self/task").ok()? {
        let p = t.ok()?.path().join("schedstat");
        let s = std::fs::read_to_string(p).ok()?;
        total += s.split_whitespace().next()?.parse::<u64>().ok()?;
    }
    Some(total as f64 / 1e6)
}

/// Median wall and CPU ms of `reps` calls of `f` after two warm-up calls (page faults, caches,
/// thread pool), plus the full wall-time sample.
fn time(reps: usize, f: &dyn Fn() -> Result<()>) -> Result<(Vec<f64>, f64)> {
    f()?;
    f()?;
    let (mut wall, mut cpu) = (Vec::with_capacity(reps), Vec::with_capacity(reps));
    for _ in 0..reps {
        let c0 = cpu_ms();
        let t0 = Instant::now();
        f()?;
        wall.push(t0.elapsed().as_secs_f64() * 1e3);
        if let (Some(a), Some(b)) = (c0, cpu_ms()) {
            cpu.push(b - a);
        }
    }
    let cpu_med = if cpu.is_empty() { f64::NAN } else { stats(cpu).0 };
    Ok((wall, cpu_med))
}

fn run() -> Result<()> {
    let cfg = parse_args()?;
    let (w, h) = (cfg.width, cfg.height);
    let mut rows = Vec::new();
    let mut rows2 = Vec::new();
    for (ji, job) in cfg.jobs.iter().enumerate() {
        let t0 = Instant::now();
        let loaded = load_scene(&job.spec, &cfg.opts)?;
        let scene = &loaded.scene;
        let (path, source) = camera_path(job, loaded.path.as_ref(), scene)?;
        path.validate()?;
        // The frame at 1/3 of the path: past the start-up of the recorded motions, and for the
        // procedural paths inside the densest part of the scene.
        let t = path.start() + path.duration() / 3.0;
        let cam = path.camera_at(t, w, h)?;
        eprintln!(
            "{}: {} objects, {} triangles, loaded in {:.0} ms; camera {source} at t = {t:.2} s",
            job.spec,
            scene.instances.len(),
            scene.triangle_count(),
            t0.elapsed().as_secs_f64() * 1e3
        );
        if let Some(dir) = &cfg.dump {
            write_images(dir, ji, scene, &cam, t)?;
        }
        let depth = render_depth(scene, &cam, t)?;
        let covered = depth.data().iter().filter(|&&z| z < 1.0).count();
        drop(depth);
        let (wall, cpu_med) = time(cfg.reps, &|| render_depth(scene, &cam, t).map(|d| drop(std::hint::black_box(d))))?;
        let (med, lo, hi, q1, q3) = stats(wall);
        let tris = scene.triangle_count();
        rows.push(format!(
            "| {} | {} | {tris} | {med:.2} | {lo:.2}-{hi:.2} | {:.2} | {:.1} | {cpu_med:.2} | {:.1}% | {source}, t = {t:.2} s |",
            scene.name,
            scene.instances.len(),
            q3 - q1,
            tris as f64 / med / 1e3,
            100.0 * covered as f64 / (w as f64 * h as f64),
        ));
        if cfg.entry_points {
            // Fewer repetitions: this table compares entry points, the first one has the spread.
            let reps2 = cfg.reps.div_ceil(2).max(5);
            let (d, dc) = time(reps2, &|| render_depth(scene, &cam, t).map(|_| ()))?;
            let (f, fc) = time(reps2, &|| {
                render_frame(scene, &cam, t, &FrameOptions { color: true, objects: None }).map(|_| ())
            })?;
            let (p, pc) = time(reps2, &|| {
                render_layers(scene, &cam, t, &PeelOptions { layers: 4, ..Default::default() }).map(|_| ())
            })?;
            rows2.push(format!(
                "| {} | {:.2} | {:.2} | {:.2} | {dc:.1} / {fc:.1} / {pc:.1} |",
                scene.name,
                stats(d).0,
                stats(f).0,
                stats(p).0
            ));
        }
    }
    println!("threads: {}, reps: {}, image {w}x{h}, depth only", rayon::current_num_threads(), cfg.reps);
    println!();
    println!(
        "| scene | objects | triangles | median ms | min-max ms | IQR ms | Mtris/s | CPU ms/render (median) | covered px | camera |"
    );
    println!("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |");
    for r in &rows {
        println!("{r}");
    }
    if cfg.entry_points {
        println!();
        println!("| scene | depth only ms | frame (items + colour) ms | peel L=4 ms | CPU ms depth / frame / peel |");
        println!("| --- | ---: | ---: | ---: | ---: |");
        for r in &rows2 {
            println!("{r}");
        }
    }
    Ok(())
}

/// Writes `scene<i>_depth.pgm` (linear depth, near = white, normalized by the nearest and
/// farthest surface) and `scene<i>_color.ppm`.
fn write_images(dir: &Path, i: usize, scene: &Scene, cam: &Camera, t: f32) -> Result<()> {
    let f = render_frame(scene, cam, t, &FrameOptions { color: true, objects: None })?;
    let lin: Vec<f32> = f.depth.data().iter().map(|&d| if d < 1.0 { cam.linear_depth(d) } else { f32::NAN }).collect();
    let lo = lin.iter().copied().filter(|v| v.is_finite()).fold(f32::INFINITY, f32::min);
    let hi = lin.iter().copied().filter(|v| v.is_finite()).fold(0.0f32, f32::max);
    let mut pgm = format!("P5 {} {} 255\n", cam.width, cam.height).into_bytes();
    pgm.extend(
        lin.iter().map(|&v| if v.is_finite() { (255.0 * (1.0 - (v - lo) / (hi - lo).max(1e-6))) as u8 } else { 0 }),
    );
    let p = dir.join(format!("scene{i}_depth.pgm"));
    std::fs::write(&p, pgm).map_err(|e| Error::io(p, e))?;
    let color = f.color.ok_or_else(|| Error::invalid("render_frame returned no colour although it was requested"))?;
    let mut ppm = format!("P6 {} {} 255\n", cam.width, cam.height).into_bytes();
    for c in color.data() {
        ppm.extend(c.iter().map(|&v| (v.clamp(0.0, 1.0).powf(1.0 / 2.2) * 255.0) as u8));
    }
    let p = dir.join(format!("scene{i}_color.ppm"));
    std::fs::write(&p, ppm).map_err(|e| Error::io(p, e))?;
    Ok(())
}
