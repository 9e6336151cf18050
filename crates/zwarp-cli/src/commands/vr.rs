//! `zwarp vr`: both eyes of a stereo / VR frame by hybrid image warping (seed 003,
//! `zwarp-vr`) compared with rendering each eye. The eyes are the path's centre camera moved by
//! `-IPD/2` and `+IPD/2` along its right axis. Strategies (seed 003 Fig. 10): `cyclops` renders
//! the centre view and warps it to both eyes; `alternate` renders one eye per frame, so the
//! other eye is warped from its render of the previous frame.
//!
//! Per (strategy, eye, method, holes, abuffer) one row, means over the frames: quality against
//! the rendered eye (PSNR, PSNR over the pixels the source did not see, SSIM, FLIP), primitives
//! drawn, per-stage medians of warm repetitions and the render of the eye timed in the same run.
//! `fpi` fills its own disocclusions (seed 001's orbit in-painting): its rows say
//! `holes: "builtin"`.

use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::Args;
use serde::Serialize;
use zwarp_core::{Camera, Image, Scene};
use zwarp_vr::grid::{draw_cells, Source, WarpOutput, WarpParams};
use zwarp_vr::{fill_holes, ray_cast, ABuffer, ColorFilter, HoleMethod, Method, MinMaxTree, RayCastParams};

use super::colorwarp;
use crate::args::{Backend, SceneArgs, SizeArgs};
use crate::device::Device;
use crate::harness::{self, Figures, Lone, PathFrames, Quality, Timing};
use crate::output::{self, fmt, ser_f64, Table};

/// Arguments of `zwarp vr`.
#[derive(Args, Clone, Debug)]
pub struct VrArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    #[command(flatten)]
    pub size: SizeArgs,
    /// Frames evaluated, spread evenly along the camera path.
    #[arg(long, default_value_t = 2)]
    pub frames: usize,
    /// Warp methods (comma list of grid, quads, points, didyk, fpi; also grid-partial,
    /// grid-cross for the other two quadtree reductions).
    #[arg(long, default_value = "grid,quads,points,didyk,fpi")]
    pub method: String,
    /// Strategies (comma list of cyclops, alternate).
    #[arg(long, default_value = "cyclops,alternate")]
    pub strategy: String,
    /// Colour fetch of the grid methods (comma list of bilinear, adaptive): `adaptive` is seed
    /// 003 Sec. 5.1's (nearest across discontinuities), `bilinear` the default
    /// (`zwarp_vr::ColorFilter`). Quads and Didyk fetch bilinear, points nearest.
    #[arg(long, default_value = "bilinear")]
    pub filter: String,
    /// Hole filling (comma list of lowpass, rubber, stretch, pushpull).
    #[arg(long, default_value = "lowpass,rubber,stretch,pushpull")]
    pub holes: String,
    /// Fraction of the scene's other objects made glass-like (alpha 0.3-0.6, chosen by --seed);
    /// translucent materials of the file (glTF `alphaMode: BLEND`) are transparent anyway.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub transparent: f32,
    /// Interpupillary distance in world units (metres); default 64 mm.
    #[arg(long, default_value_t = 0.064, allow_negative_numbers = true)]
    pub ipd: f32,
    /// With transparency: ray cast the A-buffer (`on`) and/or warp the composited image as if
    /// it were opaque (`off`); comma list.
    #[arg(long, default_value = "on,off")]
    pub abuffer: String,
    /// `cpu` or `gpu`: on the GPU the warp stage (the mesh drawn by the GPU's rasteriser with the
    /// colour fetch; fpi's heuristic colour warp) and the timed render of each eye; the quadtree,
    /// the grid, hole filling and the A-buffer stay on the CPU. Quality is measured against the
    /// CPU render of each eye on both backends.
    #[arg(long, value_enum, default_value_t = Backend::Cpu)]
    pub backend: Backend,
    /// Timed repetitions per measurement (after one warm-up run).
    #[arg(long, default_value_t = 3)]
    pub reps: usize,
    /// Write eyes, anaglyphs, error maps and the grids here (first frame).
    #[arg(long)]
    pub images: Option<PathBuf>,
    /// Write the results as JSON (`rows`).
    #[arg(long)]
    pub json: PathBuf,
}

/// One (strategy, eye, method, holes, abuffer), means over the frames (JSON `rows`).
#[derive(Clone, Debug, Serialize)]
pub struct VrRow {
    /// `grid`, `quads`, `points`, `didyk`, `fpi` (`grid-partial`, `grid-cross`).
    pub method: String,
    /// `cyclops` or `alternate`.
    pub strategy: String,
    /// `lowpass`, `rubber`, `stretch`, `pushpull` (`builtin` for fpi).
    pub holes: String,
    /// Colour fetch: `bilinear` or `adaptive` (grid methods), `bilinear` (quads, Didyk),
    /// `nearest` (points), `builtin` (fpi).
    pub filter: String,
    /// Transparent fragments ray cast from the A-buffer (`false`: the composited image warped
    /// as if opaque, or no transparency at all).
    pub abuffer: bool,
    /// `left` or `right`.
    pub eye: String,
    /// Scene spec.
    pub scene: String,
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
    /// Frames the row averages.
    pub frames: usize,
    /// Interpupillary distance (world units).
    pub ipd: f32,
    /// Fraction of glass-like objects.
    pub transparent: f32,
    /// PSNR (dB), linear RGB, against the rendered eye.
    #[serde(serialize_with = "ser_f64")]
    pub psnr: f64,
    /// PSNR (dB) over the pixels the source view did not see.
    #[serde(serialize_with = "ser_f64")]
    pub psnr_holes: f64,
    /// Fraction of those pixels.
    pub holes_fraction: f64,
    /// Mean per-channel SSIM.
    pub ssim: f64,
    /// Mean FLIP (LDR).
    pub flip: f64,
    /// Grid cells, quads or splats drawn (mean over the frames).
    pub primitives: f64,
    /// Median ms: the surface-estimation quadtree.
    pub ms_quadtree: f64,
    /// Median ms: the grid (or mesh) of this view.
    pub ms_grid: f64,
    /// Median ms: warp and rasterisation with the colour fetch.
    pub ms_warp: f64,
    /// Median ms: hole filling.
    pub ms_holes: f64,
    /// Median ms: A-buffer min-max quadtree and ray casting.
    pub ms_abuffer: f64,
    /// Sum of the stage medians.
    pub warp_ms: f64,
    /// Median ms of rendering this eye (colour, and the A-buffer with transparency), same run.
    pub render_ms: f64,
    /// `render_ms / warp_ms`.
    pub speedup: f64,
}

/// One rendered view: the opaque G-buffer, the A-buffer and the colour an eye sees.
pub struct EyeView {
    /// Camera.
    pub cam: Camera,
    /// Scene time.
    pub t: f32,
    /// Opaque depth.
    pub depth: Image<f32>,
    /// Opaque item ids.
    pub items: Image<u32>,
    /// Opaque colour.
    pub opaque: Image<[f32; 3]>,
    /// The transparent fragments (with translucent objects).
    pub abuf: Option<ABuffer>,
    /// What the eye sees: the opaque colour with the transparent fragments composited.
    pub seen: Image<[f32; 3]>,
}

/// Object `i`'s glass colour under `seed`, or `None` if it stays opaque: a fraction `f` of the
/// objects, chosen by a hash of (seed, object), get alpha 0.3-0.6 and a light tint
/// (premultiplied RGBA).
pub fn glass_of(seed: u64, i: u32, f: f32) -> Option<[f32; 4]> {
    let mut z = seed ^ (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0xD1B5_4A32_D192_ED03;
    let mut next = || {
        z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut x = z;
        x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((x ^ (x >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    };
    if next() >= f {
        return None;
    }
    let a = 0.3 + 0.3 * next();
    let tint = [0.5 + 0.5 * next(), 0.5 + 0.5 * next(), 0.5 + 0.5 * next()];
    Some([tint[0] * a, tint[1] * a, tint[2] * a, a])
}

/// Depth-peeling passes for the A-buffer at most (a pixel behind more transparent surfaces
/// than this is an error, not a silent loss).
const PEEL_LAYERS: usize = 64;

/// Object `i`'s colour from the scene file, or `None` if it is opaque: a mostly translucent
/// mesh ([`zwarp_core::Mesh::translucent_color`], e.g. glTF `alphaMode: BLEND`) tinted by the
/// instance's albedo (premultiplied RGBA).
pub fn file_glass_of(scene: &Scene, i: u32) -> Option<[f32; 4]> {
    let inst = &scene.instances[i as usize];
    let [r, g, b, a] = scene.meshes[inst.mesh as usize].translucent_color()?;
    Some([r * inst.albedo.x, g * inst.albedo.y, b * inst.albedo.z, a])
}

/// Renders the views of a scene: opaque objects into the G-buffer, translucent ones (the
/// file's, [`file_glass_of`], and glass-like ones by [`glass_of`]) depth-peeled into the
/// A-buffer.
pub struct Renderer<'a> {
    scene: &'a Scene,
    /// Opaque objects (`None`: all, no transparency).
    opaque: Option<Vec<u32>>,
    /// The transparent objects alone, and their colour by original id.
    glass: Option<(Scene, Vec<u32>, Vec<[f32; 4]>)>,
}

impl<'a> Renderer<'a> {
    /// A renderer of `scene` with its translucent objects and a fraction `transparent` of the
    /// others made glass by `seed`.
    pub fn new(scene: &'a Scene, transparent: f32, seed: u64) -> Self {
        let n = scene.instances.len() as u32;
        let colours: Vec<Option<[f32; 4]>> =
            (0..n).map(|i| file_glass_of(scene, i).or_else(|| glass_of(seed, i, transparent))).collect();
        if colours.iter().all(Option::is_none) {
            return Renderer { scene, opaque: None, glass: None };
        }
        let opaque: Vec<u32> = (0..n).filter(|&i| colours[i as usize].is_none()).collect();
        let ids: Vec<u32> = (0..n).filter(|&i| colours[i as usize].is_some()).collect();
        let mut sub = Scene { name: format!("{} (glass)", scene.name), up: scene.up, ..Scene::default() };
        let mut remap = vec![u32::MAX; scene.meshes.len()];
        for &i in &ids {
            let inst = &scene.instances[i as usize];
            if remap[inst.mesh as usize] == u32::MAX {
                remap[inst.mesh as usize] = sub.add_mesh(scene.meshes[inst.mesh as usize].clone());
            }
            let mut c = inst.clone();
            c.mesh = remap[inst.mesh as usize];
            sub.instances.push(c);
        }
        let rgba = colours.iter().map(|c| c.unwrap_or([0.0; 4])).collect();
        Renderer { scene, opaque: Some(opaque), glass: Some((sub, ids, rgba)) }
    }

    /// Translucent objects (the file's and the glass ones).
    pub fn transparent_count(&self) -> usize {
        self.glass.as_ref().map_or(0, |g| g.1.len())
    }

    /// Renders `cam` at `t`.
    pub fn view(&self, cam: &Camera, t: f32) -> Result<EyeView> {
        let opts = zwarp_raster::FrameOptions { color: true, objects: self.opaque.as_deref() };
        let f = zwarp_raster::render_frame(self.scene, cam, t, &opts)?;
        let opaque = zwarp_color::require_color(f.color.as_ref(), "the rendered frame")?.clone();
        let abuf = match &self.glass {
            Some((sub, ids, rgba)) if !sub.instances.is_empty() => {
                let peel = zwarp_raster::PeelOptions { layers: PEEL_LAYERS, ground_separate: false, umbra: None };
                let layers = zwarp_raster::render_layers(sub, cam, t, &peel)?;
                if layers.last().is_some_and(|l| l.coverage() > 0) {
                    bail!("A-buffer: some pixel lies behind {PEEL_LAYERS} or more transparent surfaces (the peeling bound)");
                }
                let layers: Vec<(Image<f32>, Image<u32>)> = layers
                    .into_iter()
                    .map(|l| (l.depth, l.items.map(|&i| if i == zwarp_core::NO_ITEM { i } else { ids[i as usize] })))
                    .collect();
                Some(ABuffer::from_layers(&layers, &f.depth, |i| rgba[i as usize])?)
            }
            Some(_) => Some(ABuffer::empty(cam.width, cam.height)),
            None => None,
        };
        let seen = match &abuf {
            Some(a) => a.composite(&opaque)?,
            None => opaque.clone(),
        };
        Ok(EyeView { cam: *cam, t, depth: f.depth, items: f.items, opaque, abuf, seen })
    }
}

fn parse<T>(s: &str, what: &str, f: impl Fn(&str) -> zwarp_core::Result<T>) -> Result<Vec<T>> {
    let mut out = Vec::new();
    for name in crate::args::parse_list::<String>(s, what)? {
        match f(&name) {
            Ok(v) => out.push(v),
            Err(e) => bail!("{what}: {e}"),
        }
    }
    Ok(out)
}

/// The validated options.
struct Plan {
    /// Each method with its colour filter (one per `--filter` for the grid methods).
    variants: Vec<(Method, Option<ColorFilter>)>,
    filters: Vec<ColorFilter>,
    strategies: Vec<bool>,
    holes: Vec<HoleMethod>,
    abuffer: Vec<bool>,
}

fn plan(args: &VrArgs) -> Result<Plan> {
    args.size.check()?;
    if !args.ipd.is_finite() || args.ipd < 0.0 {
        bail!("--ipd must be a finite distance >= 0, got {}", args.ipd);
    }
    if !(args.transparent.is_finite() && (0.0..=1.0).contains(&args.transparent)) {
        bail!("--transparent must be a fraction in [0, 1], got {}", args.transparent);
    }
    if args.frames == 0 {
        bail!("--frames must be at least 1");
    }
    let methods = parse(&args.method, "--method", Method::parse)?;
    let holes = parse(&args.holes, "--holes", HoleMethod::parse)?;
    let filters = parse(&args.filter, "--filter", ColorFilter::parse)?;
    let strategies = parse(&args.strategy, "--strategy", |s| match s {
        "cyclops" => Ok(false),
        "alternate" => Ok(true),
        o => Err(zwarp_core::Error::invalid(format!("unknown strategy '{o}' (cyclops, alternate)"))),
    })?;
    let abuffer = parse(&args.abuffer, "--abuffer", |s| match s {
        "on" => Ok(true),
        "off" => Ok(false),
        o => Err(zwarp_core::Error::invalid(format!("'{o}' is neither on nor off"))),
    })?;
    let variants = methods
        .iter()
        .flat_map(|&m| match m {
            Method::Grid(_) => filters.iter().map(|&f| (m, Some(f))).collect::<Vec<_>>(),
            _ => vec![(m, None)],
        })
        .collect();
    Ok(Plan { variants, filters, strategies, holes, abuffer })
}

#[derive(Default)]
struct Acc {
    quality: Vec<Quality>,
    primitives: Vec<f64>,
    quadtree: Vec<f64>,
    grid: Vec<f64>,
    warp: Vec<f64>,
    holes: Vec<f64>,
    abuffer: Vec<f64>,
    render: Vec<f64>,
}

/// Row key: (alternate, right eye, method, filter name, holes name, abuffer).
type Key = (bool, bool, String, String, String, bool);

/// JSON `filter` of a row: the grid methods' [`ColorFilter`], else the method's own fetch.
fn filter_name(m: Method, filter: Option<ColorFilter>) -> &'static str {
    match (m, filter) {
        (_, Some(f)) => f.name(),
        (Method::Points, None) => "nearest",
        (Method::Fpi, None) => "builtin",
        _ => "bilinear",
    }
}

/// The pixels of the eye `reference` that `source` did not see.
fn unseen(scene: &Scene, reference: &EyeView, source: &EyeView) -> Result<Image<bool>> {
    let to_src = zwarp_core::motion_field(
        &reference.depth,
        Some(&reference.items),
        &reference.cam,
        &source.cam,
        &scene.object_deltas(reference.t, source.t),
    )?;
    super::colorwarp::unseen(&reference.depth, &to_src, &source.depth, &source.cam)
}

/// A prediction of the first frame kept for the images.
struct Shot {
    name: String,
    right: bool,
    image: Image<[f32; 3]>,
    reference: Image<[f32; 3]>,
}

fn evaluate(args: &VrArgs, loaded: &crate::args::Loaded, p: &Plan, device: &Device) -> Result<Vec<VrRow>> {
    let (w, h) = (args.size.width, args.size.height);
    let reps = args.reps.max(1);
    let ipd = args.ipd;
    let path = &loaded.path;
    let r = Renderer::new(&loaded.scene, args.transparent, args.scene.seed);
    let on_device = device.load(&loaded.scene)?;
    let frames = PathFrames::new(path, 1.0, w, h);
    let total =
        frames.require(2, |total| format!("the camera path is too short for zwarp vr ({total} frame; need 2)"))?;
    // Frames with a previous one (the alternate strategy's source).
    let picked = frames.pick(args.frames, 1..=total - 1, Lone::Middle)?;
    let bar = harness::progress(
        (picked.len() * p.strategies.len() * 2 * p.variants.len()) as u64,
        format!("vr {}", args.scene.scene),
        true,
    );
    let wp = WarpParams::default();
    let mut accs: Vec<(Key, Acc)> = Vec::new();
    let mut shots: Vec<Shot> = Vec::new();
    let mut grids: Vec<(String, Image<[f32; 3]>)> = Vec::new();
    let abuffers: Vec<bool> = if r.transparent_count() > 0 { p.abuffer.clone() } else { vec![false] };
    for (ki, frame) in picked.iter().enumerate() {
        let before = frames.previous(frame)?;
        let (t, tp, c, cp) = (frame.t, before.t, frame.cam, before.cam);
        let centre = r.view(&c, t)?;
        if centre.depth.data().iter().all(|&d| d >= 1.0) {
            // Glass over sky has no opaque surface to carry the warp either.
            if centre.abuf.as_ref().is_some_and(|a| !a.is_empty()) {
                bail!(
                    "frame {} of the camera path shows only transparent surfaces ({} of {} objects are glass): no opaque surface to warp; lower --transparent",
                    frame.k,
                    r.transparent_count(),
                    loaded.scene.instances.len()
                );
            }
            bail!(
                "frame {} of the camera path shows no surface of the scene (only sky): nothing to warp; check --path",
                frame.k
            );
        }
        // The eyes, rendered and timed.
        let mut refs = Vec::new();
        for side in [-1.0f32, 1.0] {
            let ce = super::stereo::eye_camera(&c, side, ipd);
            let (view, cpu_samples) = harness::time_repeated(reps, || r.view(&ce, t))?;
            // The render a warp replaces, timed on the warp's device (the GPU renders the
            // opaque scene).
            let samples = if device.is_gpu() {
                harness::time_repeated(reps, || device.render_view(&on_device, &ce, t))?.1
            } else {
                cpu_samples
            };
            refs.push((view, samples));
        }
        for &alternate in &p.strategies {
            let strategy = if alternate { "alternate" } else { "cyclops" };
            for (ei, side) in [-1.0f32, 1.0].into_iter().enumerate() {
                let right = ei == 1;
                let (reference, render_samples) = &refs[ei];
                let prev;
                let src: &EyeView = if alternate {
                    prev = r.view(&super::stereo::eye_camera(&cp, side, ipd), tp)?;
                    &prev
                } else {
                    &centre
                };
                let mask = unseen(&loaded.scene, reference, src)?;
                let render_ms = Timing::of(render_samples).median;
                for &(m, filter) in &p.variants {
                    let wp = zwarp_vr::grid::WarpParams { filter: filter.unwrap_or(wp.filter), ..wp };
                    let fname = filter_name(m, filter);
                    // Image names carry the filter only when several are compared.
                    let tag = match filter {
                        Some(f) if p.filters.len() > 1 => format!("{}-{}", m.name(), f.name()),
                        _ => m.name(),
                    };
                    for &ab in &abuffers {
                        // Without the A-buffer the composited image is warped as if opaque.
                        let colour = if ab { &src.opaque } else { &src.seen };
                        let source = Source { cam: &src.cam, depth: &src.depth, color: colour };
                        let (out, stage) =
                            harness::time_stages(reps, || device.vr_warp(&source, &reference.cam, m, &wp), |o| o.ms)?;
                        let med = |f: fn(&zwarp_vr::grid::StageMs) -> f64| harness::timing_of(&stage, f).median;
                        let (mq, mg, mw) = (med(|s| s.quadtree), med(|s| s.grid), med(|s| s.warp));
                        if ki == 0 && args.images.is_some() && !out.cells.is_empty() && !right {
                            grids.push((format!("{strategy}_{tag}"), draw_cells(colour, &out.cells, [1.0, 0.1, 0.1])));
                        }
                        // Transparent fragments: min-max quadtree and ray casting over the warped
                        // opaque image (seed 003 Sec. 5.3), once for every hole method.
                        let (composited, ms_abuffer) = match (&src.abuf, ab) {
                            (Some(abuf), true) => {
                                let (rc, s) = harness::time_repeated(reps, || {
                                    let tree = MinMaxTree::build(abuf);
                                    Ok(ray_cast(
                                        abuf,
                                        &tree,
                                        &src.cam,
                                        &reference.cam,
                                        &out.color,
                                        &out.depth,
                                        &RayCastParams::default(),
                                    )?)
                                })?;
                                (Some(WarpOutput { color: rc.color, ..out.clone() }), Timing::of(&s).median)
                            }
                            _ => (None, 0.0),
                        };
                        // Holes last, from the composited colours around them: the glass in front
                        // of a disocclusion's background is in its border, which the source's
                        // A-buffer cannot show inside it (the foreground hid it there).
                        let base = composited.as_ref().unwrap_or(&out);
                        let fill_source = Source { cam: &src.cam, depth: &src.depth, color: &src.seen };
                        let hole_list: Vec<Option<HoleMethod>> =
                            if m == Method::Fpi { vec![None] } else { p.holes.iter().copied().map(Some).collect() };
                        for hm in hole_list {
                            let (pred, hs) = match hm {
                                Some(hm) => harness::time_repeated(reps, || {
                                    Ok(fill_holes(base, &fill_source, &reference.cam, hm)?)
                                })?,
                                None => (base.color.clone(), vec![0.0]),
                            };
                            let ms_holes = Timing::of(&hs).median;
                            let hname = hm.map_or("builtin", |h| h.name()).to_string();
                            // The rows report the headline figures only, and no convergence.
                            let q = harness::compare_color(
                                &reference.seen,
                                &pred,
                                f64::NAN,
                                Some(&mask),
                                Figures::Headline,
                            )?;
                            let a = harness::entry(
                                &mut accs,
                                (alternate, right, m.name(), fname.to_string(), hname.clone(), ab),
                            );
                            a.quality.push(q);
                            a.primitives.push(out.primitives as f64);
                            a.quadtree.push(mq);
                            a.grid.push(mg);
                            a.warp.push(mw);
                            a.holes.push(ms_holes);
                            a.abuffer.push(ms_abuffer);
                            a.render.push(render_ms);
                            if ki == 0 && args.images.is_some() {
                                let ab_name = if abuffers.len() > 1 {
                                    if ab {
                                        "_abuf"
                                    } else {
                                        "_opaque"
                                    }
                                } else {
                                    ""
                                };
                                shots.push(Shot {
                                    name: format!("{strategy}_{tag}_{hname}{ab_name}"),
                                    right,
                                    image: pred,
                                    reference: reference.seen.clone(),
                                });
                            }
                        }
                    }
                    bar.inc(1);
                }
            }
        }
        if ki == 0 {
            if let Some(dir) = &args.images {
                let base = colorwarp::safe_name(&args.scene.scene);
                colorwarp::write_color(dir, &format!("{base}_centre"), &centre.seen)?;
                colorwarp::write_color(dir, &format!("{base}_reference_left"), &refs[0].0.seen)?;
                colorwarp::write_color(dir, &format!("{base}_reference_right"), &refs[1].0.seen)?;
                let ana = super::stereo::anaglyph(&refs[0].0.seen, &refs[1].0.seen);
                zwarp_viz::write_png(dir.join(format!("{base}_reference_anaglyph.png")), &ana)?;
            }
        }
    }
    bar.finish_and_clear();
    if let Some(dir) = &args.images {
        let base = colorwarp::safe_name(&args.scene.scene);
        for s in &shots {
            let eye = if s.right { "right" } else { "left" };
            colorwarp::write_color(dir, &format!("{base}_{}_{eye}", s.name), &s.image)?;
            colorwarp::write_flip(dir, &format!("{base}_{}_{eye}_flip", s.name), &s.reference, &s.image)?;
            if s.right {
                if let Some(l) = shots.iter().find(|o| o.name == s.name && !o.right) {
                    let ana = super::stereo::anaglyph(&l.image, &s.image);
                    zwarp_viz::write_png(dir.join(format!("{base}_{}_anaglyph.png", s.name)), &ana)?;
                }
            }
        }
        for (name, img) in &grids {
            colorwarp::write_color(dir, &format!("{base}_{name}_grid"), img)?;
        }
    }
    let med = |v: &[f64]| Timing::of(v).median;
    Ok(accs
        .into_iter()
        .map(|((alternate, right, method, filter, holes, ab), a)| {
            let (q, g, wv, hl, abm) = (med(&a.quadtree), med(&a.grid), med(&a.warp), med(&a.holes), med(&a.abuffer));
            let warp_ms = q + g + wv + hl + abm;
            let render_ms = med(&a.render);
            let quality = harness::mean_quality(&a.quality);
            VrRow {
                method,
                strategy: if alternate { "alternate" } else { "cyclops" }.into(),
                holes,
                filter,
                abuffer: ab,
                eye: if right { "right" } else { "left" }.into(),
                scene: args.scene.scene.clone(),
                width: w,
                height: h,
                frames: a.quality.len(),
                ipd,
                transparent: args.transparent,
                psnr: quality.psnr,
                psnr_holes: quality.disocc_psnr,
                holes_fraction: quality.disocc_fraction,
                ssim: quality.ssim,
                flip: quality.flip,
                primitives: harness::mean_finite(&a.primitives),
                ms_quadtree: q,
                ms_grid: g,
                ms_warp: wv,
                ms_holes: hl,
                ms_abuffer: abm,
                warp_ms,
                render_ms,
                speedup: render_ms / warp_ms.max(1e-9),
            }
        })
        .collect())
}

/// The rows as a table.
pub fn table(rows: &[VrRow]) -> String {
    let mut t = Table::new(&[
        "method",
        "strategy",
        "holes",
        "filter",
        "abuffer",
        "eye",
        "PSNR",
        "PSNR holes",
        "SSIM",
        "FLIP",
        "prims",
        "quadtree ms",
        "grid ms",
        "warp ms",
        "holes ms",
        "abuffer ms",
        "total ms",
        "render ms",
        "speedup",
    ]);
    for r in rows {
        t.row(vec![
            r.method.clone(),
            r.strategy.clone(),
            r.holes.clone(),
            r.filter.clone(),
            if r.abuffer { "on" } else { "off" }.into(),
            r.eye.clone(),
            fmt(r.psnr, 2),
            fmt(r.psnr_holes, 2),
            fmt(r.ssim, 4),
            fmt(r.flip, 4),
            fmt(r.primitives, 0),
            fmt(r.ms_quadtree, 2),
            fmt(r.ms_grid, 2),
            fmt(r.ms_warp, 2),
            fmt(r.ms_holes, 2),
            fmt(r.ms_abuffer, 2),
            fmt(r.warp_ms, 2),
            fmt(r.render_ms, 2),
            fmt(r.speedup, 2),
        ]);
    }
    t.render()
}

/// `zwarp vr`.
pub fn run(args: VrArgs) -> Result<()> {
    let p = plan(&args)?;
    let loaded = args.scene.load()?;
    let device = Device::open(args.backend)?;
    let rows = evaluate(&args, &loaded, &p, &device)?;
    println!(
        "zwarp vr: {} ({} objects, {} triangles), {}x{}, IPD {}, {} transparent ({} objects), {} frame(s), {}",
        args.scene.scene,
        loaded.scene.instances.len(),
        loaded.scene.triangle_count(),
        args.size.width,
        args.size.height,
        args.ipd,
        args.transparent,
        Renderer::new(&loaded.scene, args.transparent, args.scene.seed).transparent_count(),
        args.frames,
        device.describe()
    );
    println!("{}", table(&rows));
    output::write_json(
        &args.json,
        "vr",
        &rows,
        serde_json::json!({
            "backend": if device.is_gpu() { "gpu" } else { "cpu" },
            "adapter": device.adapter(),
            "threads": rayon::current_num_threads(),
            "reps": args.reps
        }),
    )?;
    println!("wrote {}", args.json.display());
    if let Some(d) = &args.images {
        println!("images in {}", d.display());
    }
    Ok(())
}
