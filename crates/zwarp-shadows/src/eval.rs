//! The measurement protocol of seed 000, Table 8 / Fig. 15: for every shadow-map size and number
//! of light samples S, the frame time of the reference, zwarp and PCSS (warm, repeated, median;
//! ARCHITECTURE.md "Timings") and the quality of each shaded image against the reference with
//! the same S (PSNR and SSIM on linear RGB in `[0, 1]`), with the speed-up measured side by side.

use zwarp_core::{AreaLight, Camera, Error, Result, Scene};

use crate::{run_shadows, Method, ShadowParams, ShadowResult, StageTimings};

/// What [`evaluate`] measures.
#[derive(Clone, Debug, PartialEq)]
pub struct EvalConfig {
    /// The S values (each gets its own reference).
    pub samples: Vec<u32>,
    /// The shadow-map sizes.
    pub sm_sizes: Vec<u32>,
    /// Methods besides the reference (which always runs: it is the quality baseline).
    pub methods: Vec<Method>,
    /// Timed repetitions (>= 1; the median is reported).
    pub reps: usize,
    /// Untimed warm-up runs before the timed ones (ARCHITECTURE.md "Timings"; 0 leaves the
    /// median of the repetitions to absorb a cold first run, for expensive configurations).
    pub warmup: usize,
    /// [`Method::ZwarpFull`] (every texel of every map) is measured only for S up to this
    /// (it costs up to S full warps; the before/after comparison needs a few S only).
    pub full_max_samples: u32,
    /// Everything else (L, N, T, holes, bias, seed...); `samples` and `sm_size` are overridden.
    pub base: ShadowParams,
}

/// One measured configuration.
#[derive(Clone, Debug, PartialEq)]
pub struct EvalRow {
    /// The method.
    pub method: Method,
    /// S.
    pub samples: u32,
    /// Shadow-map size.
    pub sm: u32,
    /// Median frame time of the timed repetitions (ms).
    pub ms: f64,
    /// Fastest repetition (ms).
    pub ms_min: f64,
    /// Slowest repetition (ms).
    pub ms_max: f64,
    /// Every timed repetition (ms).
    pub times: Vec<f64>,
    /// PSNR (dB) of the shaded image vs the reference with the same S (`inf` if identical).
    pub psnr: f64,
    /// SSIM of the shaded image vs the reference with the same S.
    pub ssim: f64,
    /// Reference median ms / this method's median ms (same S and map size, same run).
    pub speedup: f64,
    /// Stage times of the median repetition.
    pub timings: StageTimings,
    /// Hole pixels left in the warped maps (zwarp).
    pub warp_holes: usize,
    /// Texels warped over the S maps (zwarp; see [`ShadowResult::warped_texels`]).
    pub warped_texels: usize,
}

impl EvalRow {
    /// One progress line for a person watching a run: method, S, map size, median ms, SSIM.
    pub fn progress_line(&self) -> String {
        format!(
            "  {:<9} S={:<4} sm={:<5} {:>9.1} ms  ssim {:.4}",
            self.method.name(),
            self.samples,
            self.sm,
            self.ms,
            self.ssim
        )
    }
}

/// Timings of the repetitions of one configuration.
#[derive(Clone)]
struct Timed {
    ms: f64,
    lo: f64,
    hi: f64,
    times: Vec<f64>,
    stages: StageTimings,
}

fn summarize(mut v: Vec<(f64, StageTimings)>) -> Timed {
    let times = v.iter().map(|x| x.0).collect();
    v.sort_by(|a, b| a.0.total_cmp(&b.0));
    let m = v[v.len() / 2];
    Timed { ms: m.0, lo: v[0].0, hi: v[v.len() - 1].0, times, stages: m.1 }
}

/// Runs `method` through `run` `warmup` untimed then `reps` (>= 1) timed times, returns the
/// last result and the timings.
fn timed(
    run: &mut impl FnMut(Method, &ShadowParams) -> Result<ShadowResult>,
    method: Method,
    p: &ShadowParams,
    warmup: usize,
    reps: usize,
) -> Result<(ShadowResult, Timed)> {
    for _ in 0..warmup {
        run(method, p)?;
    }
    let mut times = Vec::with_capacity(reps);
    let mut out = None;
    for _ in 0..reps.max(1) {
        let r = run(method, p)?;
        times.push((r.ms, r.timings));
        out = Some(r);
    }
    let out = out.ok_or_else(|| Error::invalid("no timed repetition"))?;
    Ok((out, summarize(times)))
}

/// Measures every (map size, S, method) of `cfg` on one frame on the CPU ([`run_shadows`]).
/// `on_result` sees each row with its result and the reference result of the same S and map
/// size (to write images).
pub fn evaluate(
    scene: &Scene,
    cam: &Camera,
    t: f32,
    light: &AreaLight,
    cfg: &EvalConfig,
    on_result: impl FnMut(&EvalRow, &ShadowResult, &ShadowResult) -> Result<()>,
) -> Result<Vec<EvalRow>> {
    evaluate_with(cfg, |m, p| run_shadows(scene, cam, t, light, m, p), |_| true, on_result)
}

/// The evaluation of seed 000's Table 8 / Fig. 15 protocol on any backend: `run(method,
/// params)` is one run of a method (its time and stage timings inside the result), `supports`
/// says which methods the backend has (the others are skipped). For every map size and S: the
/// reference, then each method of `cfg` (warm, repeated, median), quality against the
/// reference of the same S and map size, speed-up over it in the same run. PCSS does not
/// depend on S: it is measured once per map size.
pub fn evaluate_with(
    cfg: &EvalConfig,
    mut run: impl FnMut(Method, &ShadowParams) -> Result<ShadowResult>,
    supports: impl Fn(Method) -> bool,
    mut on_result: impl FnMut(&EvalRow, &ShadowResult, &ShadowResult) -> Result<()>,
) -> Result<Vec<EvalRow>> {
    if cfg.samples.is_empty() || cfg.sm_sizes.is_empty() {
        return Err(Error::invalid("evaluation needs at least one S and one shadow-map size"));
    }
    if cfg.reps == 0 {
        return Err(Error::invalid("evaluation needs at least one timed repetition"));
    }
    let mut rows = Vec::new();
    for &sm in &cfg.sm_sizes {
        let mut pcss: Option<(ShadowResult, Timed)> = None;
        for &s in &cfg.samples {
            let p = ShadowParams { samples: s, sm_size: sm, ..cfg.base };
            let (reference, rt) = timed(&mut run, Method::Reference, &p, cfg.warmup, cfg.reps)?;
            let rms = rt.ms;
            let ref_row = EvalRow {
                method: Method::Reference,
                samples: s,
                sm,
                ms: rt.ms,
                ms_min: rt.lo,
                ms_max: rt.hi,
                times: rt.times,
                psnr: f64::INFINITY,
                ssim: 1.0,
                speedup: 1.0,
                timings: rt.stages,
                warp_holes: 0,
                warped_texels: 0,
            };
            on_result(&ref_row, &reference, &reference)?;
            rows.push(ref_row);
            for &m in &cfg.methods {
                if !supports(m) {
                    continue;
                }
                let (res, tm) = match m {
                    Method::Reference => continue,
                    Method::Pcss => {
                        if pcss.is_none() {
                            pcss = Some(timed(&mut run, m, &p, cfg.warmup, cfg.reps)?);
                        }
                        pcss.clone().ok_or_else(|| Error::invalid("PCSS result missing"))?
                    }
                    Method::ZwarpFull if s > cfg.full_max_samples => continue,
                    Method::Zwarp | Method::ZwarpFull => timed(&mut run, m, &p, cfg.warmup, cfg.reps)?,
                };
                let ms = tm.ms;
                let row = EvalRow {
                    method: m,
                    samples: s,
                    sm,
                    ms,
                    ms_min: tm.lo,
                    ms_max: tm.hi,
                    times: tm.times,
                    psnr: zwarp_metrics::psnr_rgb(&res.image, &reference.image, 1.0)?,
                    ssim: zwarp_metrics::ssim_rgb(&res.image, &reference.image, 1.0)?,
                    speedup: rms / ms.max(1e-9),
                    timings: tm.stages,
                    warp_holes: res.warp_holes,
                    warped_texels: res.warped_texels,
                };
                on_result(&row, &res, &reference)?;
                rows.push(row);
            }
        }
    }
    Ok(rows)
}
