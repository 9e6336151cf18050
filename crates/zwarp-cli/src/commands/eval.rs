//! `zwarp eval`: iterative depth warping against its baselines and a direct render
//! (paper 000, Sec. 4: Tables 1-3, Figs. 10-12).
//!
//! For each frame pair (frame k as source, k+1 as target) the source view is rendered and
//! peeled into L layers, each layer's motion buffer is computed, and the target depth is
//! predicted by our backward warp and by the forward baselines VFW and AFW; the target view
//! rendered directly is the reference for quality and for time.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use clap::Args;
use serde::Serialize;
use zwarp_core::{motion_field, Camera, Image, Motion, Scene};
use zwarp_raster::{render_frame, render_source_layers, FrameOptions, UmbraPeeling, ViewRegion};
use zwarp_scene::CameraPath;
use zwarp_warp::{BoundKind, HolePolicy, WarpLayer, WarpParams};

use crate::args::{parse_list, Backend, SceneArgs, SizeArgs};
use crate::device::Device;
use crate::harness::{self, DepthComparison, Lone, PathFrames, Timing};
use crate::output::{self, fmt, ser_f64, Table};

/// Arguments of `zwarp eval`.
#[derive(Args, Clone, Debug)]
pub struct EvalArgs {
    #[command(flatten)]
    pub scene: SceneArgs,
    #[command(flatten)]
    pub size: SizeArgs,
    /// Number of frame pairs (k, k+1), spread evenly along the camera path.
    #[arg(long, default_value_t = 4)]
    pub frames: usize,
    /// Motion-speed factors (comma list): frame k is taken at time k * speed / fps.
    #[arg(long, default_value = "1", allow_hyphen_values = true)]
    pub speed: String,
    /// Search seeds N (comma list).
    #[arg(long, default_value = "4,16")]
    pub n: String,
    /// Depth layers L (comma list); with a ground in the scene the last layer is the ground.
    #[arg(long, default_value = "1,3,4")]
    pub l: String,
    /// Fixed-point iterations T per seed (comma list).
    #[arg(long, default_value = "3")]
    pub t: String,
    /// Search-region bounds (comma list of global, tight, oriented).
    #[arg(long, default_value = "oriented")]
    pub bound: String,
    /// Methods (comma list of ours, vfw, afw).
    #[arg(long, default_value = "ours,vfw,afw")]
    pub methods: String,
    /// Hole policy of our warp: `paper` (Sec. 4's protocol for Tables 1-3: "the single-layer
    /// solution keeps holes (filled with the background depth), the multi-layer solutions use
    /// deep depth buffers, and employ our inpainting", Fig. 8's dilation disabled: `background`
    /// at every L), `far` (far depth everywhere: the conservative culling setting), `dilate`
    /// (Fig. 8), `awoc` (Sec. 5.3) or `background` (`zwarp_warp::holes::fill_background`: holes
    /// that see the source's empty background stay far, holes bracketed within the motion range
    /// (at most 64 px) take the farther neighbour's depth, strips open to the image border take the
    /// nearest depth inwards).
    #[arg(long, default_value = "paper")]
    pub holes: String,
    /// Multisampled source depth for our warp (comma list; seed 000 Sec. 7's remedy for
    /// sub-pixel silhouette error): `m` renders the source layers on an ordered m x m sample grid
    /// per pixel (m times the width and height) and warps them to the target's pixel centres
    /// (`WarpParams::multisample`); 1 = one sample per pixel. Rows with m > 1 are `ours` only
    /// (either backend: the WGSL twin warps multisampled sources too); their warp time includes
    /// the preparation of the m^2-times larger source.
    #[arg(long, default_value = "1")]
    pub multisample: String,
    /// Peeling: `umbra` (generalized umbra culling, eq. 1) or `standard`.
    #[arg(long, default_value = "umbra")]
    pub peel: String,
    /// Where our warp and the reference render run: `cpu` (zwarp-raster + zwarp-warp) or `gpu`
    /// (wgpu: GPU depth-only render and the WGSL twin of the warp; VFW/AFW stay on the CPU).
    #[arg(long, value_enum, default_value_t = Backend::Cpu)]
    pub backend: Backend,
    /// Timed repetitions per measurement (after one warm-up run).
    #[arg(long, default_value_t = 3)]
    pub reps: usize,
    /// Write one figure strip per configuration of ours here (first frame pair): source | ours
    /// | VFW | AFW | reference | error, with colour bars in metres.
    #[arg(long)]
    pub images: Option<PathBuf>,
    /// Write the results as JSON (`rows`, one per configuration).
    #[arg(long)]
    pub json: PathBuf,
}

/// One configuration's results, aggregated over the frame pairs (JSON `rows`).
#[derive(Clone, Debug, Serialize)]
pub struct EvalRow {
    /// `ours`, `vfw` or `afw`.
    pub method: String,
    /// Scene spec.
    pub scene: String,
    /// Seeds N (0 for the forward warps).
    pub n: u32,
    /// Layers L.
    pub l: usize,
    /// Iterations T (0 for the forward warps).
    pub t: u32,
    /// `global`, `tight`, `oriented` (`-` for the forward warps).
    pub bound: String,
    /// Hole policy of our warp: `far`, `dilate`, `awoc` (`-` for the forward warps).
    pub holes: String,
    /// Source depth samples per pixel and axis (`WarpParams::multisample`; 1 = none).
    pub multisample: u32,
    /// Motion-speed factor.
    pub speed: f32,
    /// Frame pairs evaluated.
    pub frames: usize,
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
    /// Mean PSNR (dB) on linear depth normalised by the reference's surface range.
    #[serde(serialize_with = "ser_f64")]
    pub psnr: f64,
    /// Mean SSIM on the same normalised linear depth.
    pub ssim: f64,
    /// Worst frame PSNR.
    #[serde(serialize_with = "ser_f64")]
    pub psnr_min: f64,
    /// Mean PSNR on the stored `[0,1]` buffer.
    #[serde(serialize_with = "ser_f64")]
    pub psnr_buffer: f64,
    /// Mean SSIM on the stored `[0,1]` buffer.
    pub ssim_buffer: f64,
    /// Mean fraction of the reference's surface pixels where the method produced a depth
    /// (ours: a converged search; forward warps: a splat landed).
    pub converged: f64,
    /// [`EvalRow::converged`] over the reference's surface pixels that the source view saw
    /// (their point reprojected into the source lands on its nearest surface): disocclusions
    /// and the strip entering at the border, which no single-layer search can solve, left out.
    pub converged_seen: f64,
    /// Median warp time (ms) including the motion min-max mipmap; excluding the motion field.
    pub warp_ms: f64,
    /// Spread of the warp time (min, max ms).
    pub warp_ms_min: f64,
    /// Spread of the warp time.
    pub warp_ms_max: f64,
    /// Median depth-only render time of the target (ms), same run, peeling excluded.
    pub ref_ms: f64,
    /// `ref_ms / warp_ms`.
    pub speedup: f64,
    /// Median motion-field time for the L layers (ms), reported apart.
    pub motion_ms: f64,
    /// Median time (ms) of the streaming floor of this configuration, same run: one parallel
    /// read of every layer's depth and motion, one write of the output (`zwarp_warp::floor`).
    pub floor_ms: f64,
    /// `warp_ms / floor_ms`: how far the prediction is from the speed of memory.
    pub floor_ratio: f64,
    /// Bandwidth of the floor pass in this run (GB/s: `zwarp_warp::floor::floor_bytes` over
    /// `floor_ms`). A shared machine's streaming speed changes between runs, and `floor_ratio`
    /// with it; rows of different runs compare only at equal `floor_gbps`.
    pub floor_gbps: f64,
    /// Per frame pair, in path order: PSNR, SSIM and converged fraction.
    pub frames_detail: Vec<FrameDetail>,
    /// Warp throughput: output pixels per second per core (millions).
    pub mpix_per_s_per_core: f64,
}

/// The quality of one frame pair of an [`EvalRow`].
#[derive(Clone, Debug, Serialize)]
pub struct FrameDetail {
    /// Index of the frame pair along the path.
    pub pair: usize,
    /// PSNR (dB) on normalised linear depth.
    #[serde(serialize_with = "ser_f64")]
    pub psnr: f64,
    /// SSIM on normalised linear depth.
    pub ssim: f64,
    /// Converged (ours) or covered (forward warps) fraction of the reference's surfaces.
    pub converged: f64,
    /// The same over the surfaces the source view saw ([`EvalRow::converged_seen`]).
    pub converged_seen: f64,
}

/// The parsed evaluation plan.
#[derive(Clone, Debug)]
pub struct EvalPlan {
    pub frames: usize,
    pub speeds: Vec<f32>,
    pub ns: Vec<u32>,
    pub ls: Vec<usize>,
    pub ts: Vec<u32>,
    /// Source multisampling factors m (`--multisample`).
    pub multisamples: Vec<u32>,
    pub bounds: Vec<BoundKind>,
    pub methods: Vec<String>,
    /// `None` = the paper's protocol (see [`EvalPlan::holes`]).
    pub holes: Option<HolePolicy>,
    pub umbra: bool,
    pub reps: usize,
    pub backend: Backend,
    pub width: u32,
    pub height: u32,
    pub images: Option<PathBuf>,
}

impl EvalPlan {
    /// The hole policy of every warp: the explicit `--holes`, or the paper's Sec. 4 protocol
    /// (holes filled with the background depth, at every L; see `EvalArgs::holes`).
    pub fn holes(&self) -> HolePolicy {
        self.holes.unwrap_or(HolePolicy::PAPER)
    }
}

/// A forward-warping baseline (`warp`: VFW or AFW into a recycled buffer) with the same hole
/// protocol as ours, so the comparison is fair: under [`HolePolicy::Background`] its uncovered
/// pixels (far depth) go through `fill_background` too (sky seen through them stays far); other
/// policies leave them far. The depth buffer in `slot` and the states in `states` carry over from
/// call to call, as ours do.
fn baseline(
    layers: &[WarpLayer<'_>],
    holes: HolePolicy,
    warp: fn(&[WarpLayer<'_>], &mut Image<f32>) -> zwarp_core::Result<()>,
    slot: &mut Option<Predicted>,
    states: &mut Image<zwarp_warp::PixelState>,
) -> Result<()> {
    use zwarp_warp::PixelState;
    let mut depth = slot.take().map_or_else(|| Image::new(0, 0, zwarp_core::EMPTY_DEPTH), |p| p.0);
    warp(layers, &mut depth)?;
    if let HolePolicy::Background { radius } = holes {
        let (w, h) = depth.size();
        let mut st = std::mem::replace(states, Image::new(0, 0, PixelState::Hole)).into_vec();
        st.clear();
        st.extend(depth.data().iter().map(|&z| {
            if z >= zwarp_core::EMPTY_DEPTH {
                PixelState::Hole
            } else {
                PixelState::Converged
            }
        }));
        let mut out =
            zwarp_warp::WarpOutput { depth, state: Image::from_vec(w, h, st)?, source: None, revealed: Vec::new() };
        zwarp_warp::holes::fill_background(layers, &mut out, radius, &WarpParams::default().search())?;
        depth = out.depth;
        *states = out.state;
    }
    *slot = Some((depth, None));
    Ok(())
}

/// A predicted depth buffer and, for our warp, its per-pixel states.
type Predicted = (Image<f32>, Option<Image<zwarp_warp::PixelState>>);

/// One configuration: method, L, N, T, bound (ours only), source multisampling m.
type Key = (String, usize, u32, u32, Option<BoundKind>, u32);

fn bound_name(b: BoundKind) -> &'static str {
    match b {
        BoundKind::Global => "global",
        BoundKind::Tight => "tight",
        BoundKind::Oriented => "oriented",
    }
}

fn hole_name(h: HolePolicy) -> &'static str {
    match h {
        HolePolicy::FarDepth => "far",
        HolePolicy::Dilate { .. } => "dilate",
        HolePolicy::Awoc => "awoc",
        HolePolicy::Background { .. } => "background",
    }
}

impl EvalArgs {
    /// Validates and parses the lists.
    pub fn plan(&self) -> Result<EvalPlan> {
        self.size.check()?;
        if self.frames == 0 {
            bail!("--frames must be at least 1");
        }
        let speeds: Vec<f32> = parse_list(&self.speed, "--speed")?;
        if speeds.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
            bail!("--speed values must be positive");
        }
        let ns: Vec<u32> = parse_list(&self.n, "--n")?;
        let ls: Vec<usize> = parse_list(&self.l, "--l")?;
        if ls.contains(&0) {
            bail!("--l values must be at least 1");
        }
        let ts: Vec<u32> = parse_list(&self.t, "--t")?;
        let multisamples: Vec<u32> = parse_list(&self.multisample, "--multisample")?;
        for &m in &multisamples {
            WarpParams { multisample: m, ..WarpParams::default() }
                .validate()
                .with_context(|| format!("--multisample {m}"))?;
        }
        let bounds = parse_list::<String>(&self.bound, "--bound")?
            .iter()
            .map(|b| match b.as_str() {
                "global" => Ok(BoundKind::Global),
                "tight" => Ok(BoundKind::Tight),
                "oriented" => Ok(BoundKind::Oriented),
                o => bail!("--bound: unknown bound '{o}' (global, tight, oriented)"),
            })
            .collect::<Result<Vec<_>>>()?;
        let methods: Vec<String> = parse_list(&self.methods, "--methods")?;
        for m in &methods {
            if !["ours", "vfw", "afw"].contains(&m.as_str()) {
                bail!("--methods: unknown method '{m}' (ours, vfw, afw)");
            }
        }
        let holes = match self.holes.as_str() {
            "paper" => None,
            "far" => Some(HolePolicy::FarDepth),
            "dilate" => Some(HolePolicy::Dilate { radius: 4 }),
            "awoc" => Some(HolePolicy::Awoc),
            "background" => Some(HolePolicy::PAPER),
            o => bail!("--holes: unknown hole policy '{o}' (paper, far, dilate, awoc, background)"),
        };
        let umbra = match self.peel.as_str() {
            "umbra" => true,
            "standard" => false,
            o => bail!("--peel: unknown peeling '{o}' (umbra, standard)"),
        };
        // Validate every warp configuration before any rendering starts.
        for &n in &ns {
            for &t in &ts {
                WarpParams { n_seeds: n, iterations: t, ..WarpParams::default() }.validate()?;
            }
        }
        Ok(EvalPlan {
            frames: self.frames,
            speeds,
            ns,
            ls,
            ts,
            multisamples,
            bounds,
            methods,
            holes,
            umbra,
            reps: self.reps.max(1),
            backend: self.backend,
            width: self.size.width,
            height: self.size.height,
            images: self.images.clone(),
        })
    }
}

/// Source-view buffers of one frame pair: depth + motion of the plain depth buffer (L = 1), of
/// the peeled layers and of the separate ground layer (seed 000, Sec. 3.4).
struct PairBuffers {
    single: (Image<f32>, Image<Motion>),
    peeled: Vec<(Image<f32>, Image<Motion>)>,
    ground: Option<(Image<f32>, Image<Motion>)>,
}

impl PairBuffers {
    /// `true` if the last of [`Self::prefix`]`(l)` is the separately peeled ground
    /// (`WarpParams::ground_layer`).
    fn ground_last(&self, l: usize) -> bool {
        l > 1 && self.ground.is_some()
    }

    /// The `l` layers to warp: L = 1 is the plain depth buffer; otherwise `l - 1` peeled layers
    /// plus the ground layer when the scene has ground, else `l` peeled layers.
    fn prefix(&self, l: usize) -> Vec<WarpLayer<'_>> {
        fn as_layer((d, m): &(Image<f32>, Image<Motion>)) -> WarpLayer<'_> {
            WarpLayer { depth: d, motion: m }
        }
        if l == 1 {
            return vec![as_layer(&self.single)];
        }
        match &self.ground {
            Some(g) => self.peeled.iter().take(l - 1).chain(std::iter::once(g)).map(as_layer).collect(),
            None => self.peeled.iter().take(l).map(as_layer).collect(),
        }
    }
}

/// Renders the source view's layers and their motion buffers towards the target view.
fn source_buffers(
    scene: &Scene,
    ca: &Camera,
    ta: f32,
    cb: &Camera,
    tb: f32,
    max_l: usize,
    umbra: bool,
) -> Result<(PairBuffers, f64)> {
    let deltas = scene.object_deltas(ta, tb);
    let has_ground = scene.instances.iter().any(|i| i.is_ground);
    let frame = render_frame(scene, ca, ta, &FrameOptions::default())?;
    // Umbra culling serves every viewpoint within the eye displacement to the target (with a
    // margin for the path's curvature); object motion is covered by the motion field, not here.
    let e = (cb.eye() - ca.eye()).length() * 1.5;
    let umbra = umbra.then_some(UmbraPeeling { region: ViewRegion::Disc { e, c: 0.0 } });
    let layers = if max_l > 1 { render_source_layers(scene, ca, ta, max_l, umbra)? } else { Vec::new() };
    let t0 = std::time::Instant::now();
    let single_motion = motion_field(&frame.depth, Some(&frame.items), ca, cb, &deltas)?;
    let mut with_motion = Vec::with_capacity(layers.len());
    for layer in layers {
        let m = motion_field(&layer.depth, Some(&layer.items), ca, cb, &deltas)?;
        with_motion.push((layer.depth, m));
    }
    let motion_ms = t0.elapsed().as_secs_f64() * 1e3;
    let ground = if has_ground && max_l > 1 { with_motion.pop() } else { None };
    Ok((PairBuffers { single: (frame.depth, single_motion), peeled: with_motion, ground }, motion_ms))
}

/// The target pixels (view `cb` at `tb`) whose surface the source view (`ca` at `ta`, depth
/// `source`) saw: the target's depth moved into the source (camera and object motion back from
/// `tb` to `ta`) lands on the source's nearest surface (`zwarp_color::source_visibility`).
fn seen_by_source(
    scene: &Scene,
    source: &Image<f32>,
    ca: &Camera,
    ta: f32,
    cb: &Camera,
    tb: f32,
) -> Result<Image<bool>> {
    let target = render_frame(scene, cb, tb, &FrameOptions::default())?;
    let back = motion_field(&target.depth, Some(&target.items), cb, ca, &scene.object_deltas(tb, ta))?;
    Ok(zwarp_color::source_visibility(&target.depth, &back, source, ca)?)
}

/// Per-configuration accumulator over frame pairs.
#[derive(Default)]
struct Acc {
    quality: Vec<DepthComparison>,
    warp_ms: Vec<f64>,
    floor_ms: Vec<f64>,
    /// `zwarp_warp::floor::floor_bytes` of the configuration (the same every frame pair).
    floor_bytes: u64,
    detail: Vec<FrameDetail>,
}

/// Runs the evaluation plan on a loaded scene; returns one row per configuration.
pub fn evaluate(
    scene_name: &str,
    scene: &Scene,
    path: &CameraPath,
    plan: &EvalPlan,
    progress: bool,
) -> Result<Vec<EvalRow>> {
    let max_l = *plan.ls.iter().max().unwrap_or(&1);
    // The reference render and our warp run on one device, so their ratio is the figure.
    let device = Device::open(plan.backend)?;
    let on_device = device.load(scene)?;
    let cores = rayon::current_num_threads() as f64;
    let mut rows = Vec::new();
    let configs_per_pair = plan
        .methods
        .iter()
        .map(|m| {
            if m == "ours" {
                plan.ns.len() * plan.ts.len() * plan.bounds.len() * plan.ls.len() * plan.multisamples.len()
            } else {
                plan.ls.len() * plan.multisamples.contains(&1) as usize
            }
        })
        .sum::<usize>();
    for &speed in &plan.speeds {
        // Frame pairs (k, k + 1) spread evenly along the path (a single one starts it).
        let frames = PathFrames::new(path, speed, plan.width, plan.height);
        let total = frames.require(2, |total| {
            format!("the camera path is too short for a frame pair at speed {speed}x ({total} frame)")
        })?;
        let pairs = frames
            .pick(plan.frames, 0..=total - 2, Lone::First)?
            .into_iter()
            .map(|a| Ok((a, frames.next(&a)?)))
            .collect::<Result<Vec<_>>>()?;
        let bar = harness::progress(
            (pairs.len() * (configs_per_pair + plan.multisamples.len())) as u64,
            format!("eval {scene_name} {speed}x"),
            progress,
        );
        let mut accs: Vec<(Key, Acc)> = Vec::new();
        let mut firsts = FirstPair::default();
        let mut ref_samples = Vec::new();
        // Motion-field time per multisampling factor m.
        let mut motion_samples: Vec<(u32, f64)> = Vec::new();
        let mut ref_target = Image::new(0, 0, 1.0f32);
        for (pi, (fa, fb)) in pairs.iter().enumerate() {
            let (ta, tb, cb) = (fa.t, fb.t, &fb.cam);
            // The render target is recycled like the warp's buffers (an engine keeps both).
            let (reference, samples) =
                harness::time_into(plan.reps, &mut ref_target, |d| device.render_depth_into(&on_device, cb, tb, d))?;
            ref_samples.extend(samples);
            let (plain_a, plain_b) = (fa.cam, fb.cam);
            // Computed once per pair, from the single-sample source when the plan renders it.
            let mut seen: Option<Image<bool>> = None;
            for &ms in &plan.multisamples {
                // The source (and the motion's target space) on the m x m sample grid: the same
                // views at m times the resolution, so target pixel centres sit at m (x + 0.5).
                let (ca, cb_grid) = if ms == 1 {
                    (plain_a, plain_b)
                } else {
                    let (mw, mh) = (plan.width * ms, plan.height * ms);
                    (path.camera_at(ta, mw, mh)?, path.camera_at(tb, mw, mh)?)
                };
                let (bufs, motion_ms) = source_buffers(scene, &ca, ta, &cb_grid, tb, max_l, plan.umbra)?;
                motion_samples.push((ms, motion_ms));
                if seen.is_none() {
                    let plain;
                    let source = if ms == 1 {
                        &bufs.single.0
                    } else {
                        plain = render_frame(scene, &plain_a, ta, &FrameOptions::default())?.depth;
                        &plain
                    };
                    seen = Some(seen_by_source(scene, source, &plain_a, ta, &plain_b, tb)?);
                }
                let seen = seen.as_ref().expect("set above");
                if pi == 0 && plan.images.is_some() {
                    firsts.sources.push((ms, bufs.single.0.clone(), ca));
                    firsts.reference = Some((reference.clone(), *cb));
                }
                bar.inc(1);
                // `f` computes a configuration's prediction into the slot, which holds the previous
                // repetition's output for reuse (one untimed warm-up, then `reps` timed runs).
                let mut run = |key: Key,
                               layers: &[WarpLayer<'_>],
                               f: &mut dyn FnMut(&mut Option<Predicted>) -> Result<()>|
                 -> Result<()> {
                    let (out, samples) = harness::time_into(plan.reps, &mut None, |s| f(s))?;
                    let out = out.expect("the prediction ran");
                    // The streaming floor of the same inputs, right after (same run, warm).
                    let (floor, _, _) = zwarp_warp::floor::floor_ms(layers, key.5, plan.reps.max(1))?;
                    let q = harness::compare_depth(&out.0, out.1.as_ref(), &reference, cb, seen)?;
                    let a = harness::entry(&mut accs, key.clone());
                    a.quality.push(q);
                    a.warp_ms.extend(samples);
                    a.floor_ms.push(floor);
                    a.floor_bytes = zwarp_warp::floor::floor_bytes(layers, key.5);
                    a.detail.push(FrameDetail {
                        pair: pi,
                        psnr: q.psnr,
                        ssim: q.ssim,
                        converged: q.converged,
                        converged_seen: q.converged_seen,
                    });
                    if pi == 0 && plan.images.is_some() {
                        firsts.predictions.push((key.clone(), out.0.clone()));
                    }
                    bar.inc(1);
                    Ok(())
                };
                for method in &plan.methods {
                    if ms > 1 && method != "ours" {
                        continue; // the forward baselines splat one sample per pixel
                    }
                    for &l in &plan.ls {
                        let layers = bufs.prefix(l);
                        match method.as_str() {
                            "ours" => {
                                for &n in &plan.ns {
                                    for &t in &plan.ts {
                                        for &bound in &plan.bounds {
                                            let params = WarpParams {
                                                n_seeds: n,
                                                iterations: t,
                                                bound,
                                                holes: plan.holes(),
                                                multisample: ms,
                                                ground_layer: bufs.ground_last(l),
                                                ..WarpParams::default()
                                            };
                                            // The preparation's buffers carry over from one timed
                                            // run to the next, as an engine keeps them across
                                            // frames (the first, untimed run allocates them).
                                            let mut recycled = Vec::new();
                                            run(("ours".into(), l, n, t, Some(bound), ms), &layers, &mut |slot| {
                                                // The output buffers carry over too (an
                                                // engine's steady state).
                                                let mut o = match slot.take() {
                                                    Some((depth, Some(state))) => zwarp_warp::WarpOutput {
                                                        depth,
                                                        state,
                                                        source: None,
                                                        revealed: Vec::new(),
                                                    },
                                                    _ => zwarp_warp::WarpOutput::empty(),
                                                };
                                                device.predict(&layers, &params, &mut recycled, &mut o)?;
                                                *slot = Some((o.depth, Some(o.state)));
                                                Ok(())
                                            })?;
                                        }
                                    }
                                }
                            }
                            "vfw" => {
                                let mut states = Image::new(0, 0, zwarp_warp::PixelState::Hole);
                                run(("vfw".into(), l, 0, 0, None, 1), &layers, &mut |slot| {
                                    baseline(&layers, plan.holes(), zwarp_warp::vfw_layers_into, slot, &mut states)
                                })?
                            }
                            _ => {
                                let mut states = Image::new(0, 0, zwarp_warp::PixelState::Hole);
                                run(("afw".into(), l, 0, 0, None, 1), &layers, &mut |slot| {
                                    baseline(&layers, plan.holes(), zwarp_warp::afw_layers_into, slot, &mut states)
                                })?
                            }
                        }
                    }
                }
            }
        }
        bar.finish_and_clear();
        if let Some(dir) = &plan.images {
            write_strips(dir, scene_name, speed, &firsts)?;
        }
        let ref_t = Timing::of(&ref_samples);
        for (key, a) in accs {
            let wt = Timing::of(&a.warp_ms);
            let q = harness::mean_depth(&a.quality);
            let motion: Vec<f64> = motion_samples.iter().filter(|(m, _)| *m == key.5).map(|s| s.1).collect();
            let motion_t = Timing::of(&motion);
            rows.push(EvalRow {
                method: key.0,
                scene: scene_name.to_string(),
                n: key.2,
                l: key.1,
                t: key.3,
                bound: key.4.map_or("-", bound_name).to_string(),
                holes: match (key.4, plan.holes()) {
                    (Some(_), h) => hole_name(h),
                    (None, h @ HolePolicy::Background { .. }) => hole_name(h),
                    (None, _) => "far",
                }
                .to_string(),
                multisample: key.5,
                speed,
                frames: pairs.len(),
                width: plan.width,
                height: plan.height,
                psnr: q.psnr,
                ssim: q.ssim,
                psnr_min: a.quality.iter().map(|q| q.psnr).fold(f64::INFINITY, f64::min),
                psnr_buffer: q.psnr_buffer,
                ssim_buffer: q.ssim_buffer,
                converged: q.converged,
                converged_seen: q.converged_seen,
                warp_ms: wt.median,
                warp_ms_min: wt.min,
                warp_ms_max: wt.max,
                ref_ms: ref_t.median,
                speedup: ref_t.median / wt.median.max(1e-9),
                motion_ms: motion_t.median,
                floor_ms: Timing::of(&a.floor_ms).median,
                floor_ratio: wt.median / Timing::of(&a.floor_ms).median.max(1e-9),
                floor_gbps: a.floor_bytes as f64 / (Timing::of(&a.floor_ms).median.max(1e-9) * 1e6),
                frames_detail: a.detail,
                mpix_per_s_per_core: (plan.width as f64 * plan.height as f64)
                    / (wt.median.max(1e-9) * 1e-3)
                    / cores
                    / 1e6,
            });
        }
    }
    Ok(rows)
}

/// The first frame pair's buffers, kept for the figure strips when `--images` is given.
#[derive(Default)]
struct FirstPair {
    /// `(m, source depth, source camera)` per multisampling factor.
    sources: Vec<(u32, Image<f32>, Camera)>,
    /// The directly rendered target and its camera.
    reference: Option<(Image<f32>, Camera)>,
    /// Every configuration's prediction.
    predictions: Vec<(Key, Image<f32>)>,
}

/// Width in pixels of one panel of a figure strip.
const PANEL_WIDTH: u32 = 480;

/// One labelled PNG per configuration of ours: source | ours | VFW | AFW (same L, when run) |
/// reference | error of ours, each depth panel with its colour bar in metres (predictions in
/// the reference's range) and the error panel with its scale.
fn write_strips(dir: &std::path::Path, scene: &str, speed: f32, firsts: &FirstPair) -> Result<()> {
    let Some((reference, cb)) = &firsts.reference else { return Ok(()) };
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create folder", dir.display()))?;
    // Named by the scene's file stem (`sponza` for `../scenes/sponza`, `cb` for cb).
    let stem =
        std::path::Path::new(scene.trim_end_matches('/')).file_stem().map_or(scene.into(), |s| s.to_string_lossy());
    let safe: String = stem.chars().map(|c| if c.is_ascii_alphanumeric() { c } else { '_' }).collect();
    let shown = zwarp_viz::depth_range(reference, Some(cb)).unwrap_or((cb.near, cb.far));
    // The error on linear depth normalised like the headline metric, full scale at 1 % of the
    // reference's surface range.
    let range = zwarp_metrics::surface_range(reference, cb).unwrap_or((cb.near, cb.far));
    let norm = |d: &Image<f32>| zwarp_metrics::normalized_linear_depth(d, cb, range);
    let rn = norm(reference);
    let reference_panel = zwarp_viz::depth_panel("reference (render)", reference, cb, shown, PANEL_WIDTH)?;
    let baseline = |name: &str, l: usize| {
        firsts.predictions.iter().find(|(k, _)| k.0 == name && k.1 == l && k.5 == 1).map(|(_, d)| d)
    };
    for (key, ours) in firsts.predictions.iter().filter(|(k, _)| k.0 == "ours") {
        let Some((_, source, ca)) = firsts.sources.iter().find(|(m, _, _)| *m == key.5) else { continue };
        let src_range = zwarp_viz::depth_range(source, Some(ca)).unwrap_or((ca.near, ca.far));
        let bound = key.4.map_or("-", bound_name);
        let mut panels = vec![
            zwarp_viz::depth_panel(&format!("source L={} m={}", key.1, key.5), source, ca, src_range, PANEL_WIDTH)?,
            zwarp_viz::depth_panel(&format!("ours N={} T={} {bound}", key.2, key.3), ours, cb, shown, PANEL_WIDTH)?,
        ];
        for name in ["vfw", "afw"] {
            if let Some(d) = baseline(name, key.1) {
                panels.push(zwarp_viz::depth_panel(&name.to_uppercase(), d, cb, shown, PANEL_WIDTH)?);
            }
        }
        panels.push(reference_panel.clone());
        panels.push(zwarp_viz::diff_panel(
            "error (red: nearer)",
            &norm(ours),
            &rn,
            0.01,
            0.01 * (range.1 - range.0),
            PANEL_WIDTH,
        )?);
        let name = format!("{safe}_{speed}x_l{}_n{}_t{}_{bound}_m{}.png", key.1, key.2, key.3, key.5);
        zwarp_viz::write_png(dir.join(name), &zwarp_viz::strip(&panels)?)?;
    }
    Ok(())
}

/// Prints the rows as a table.
pub fn table(rows: &[EvalRow]) -> String {
    let mut t = Table::new(&[
        "method", "L", "N", "T", "bound", "m", "speed", "PSNR", "SSIM", "conv", "seen", "warp ms", "floor ms",
        "x floor", "ref ms", "speedup",
    ]);
    for r in rows {
        t.row(vec![
            r.method.clone(),
            r.l.to_string(),
            if r.n > 0 { r.n.to_string() } else { "-".into() },
            if r.t > 0 { r.t.to_string() } else { "-".into() },
            r.bound.clone(),
            r.multisample.to_string(),
            format!("{}x", r.speed),
            fmt(r.psnr, 2),
            fmt(r.ssim, 4),
            fmt(r.converged, 4),
            fmt(r.converged_seen, 4),
            fmt(r.warp_ms, 2),
            fmt(r.floor_ms, 2),
            fmt(r.floor_ratio, 1),
            fmt(r.ref_ms, 2),
            fmt(r.speedup, 2),
        ]);
    }
    t.render()
}

/// `zwarp eval`.
pub fn run(args: EvalArgs) -> Result<()> {
    let plan = args.plan()?;
    let loaded = args.scene.load()?;
    let rows = evaluate(&args.scene.scene, &loaded.scene, &loaded.path, &plan, true)?;
    println!(
        "zwarp eval: {} ({} objects, {} triangles), {}x{}, {} frame pair(s), backend {:?}, {} CPU threads",
        args.scene.scene,
        loaded.scene.instances.len(),
        loaded.scene.triangle_count(),
        plan.width,
        plan.height,
        plan.frames,
        plan.backend,
        rayon::current_num_threads()
    );
    println!("{}", table(&rows));
    output::write_json(
        &args.json,
        "eval",
        &rows,
        serde_json::json!({
            "backend": if plan.backend == Backend::Gpu { "gpu" } else { "cpu" },
            "threads": rayon::current_num_threads(),
        }),
    )?;
    println!("wrote {}", args.json.display());
    if let Some(d) = &plan.images {
        println!("images in {}", d.display());
    }
    Ok(())
}
