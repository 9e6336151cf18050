//! Runs a culling method along a camera path the way an engine would (seed 000 Sec. 5.3, thesis
//! Sec. V): each frame is culled, the visible set is drawn (depth + item ids), and that drawing
//! is the previous frame of the next one. Every frame is also rendered in full (REF / NOCULL) in
//! the same run, so accuracy (object error, pixel error, culling ratio) and the draw-time ratio
//! are measured side by side (ARCHITECTURE.md "Evaluation protocol"). The engine's loop runs
//! first, alone and timed; the full renders and comparisons follow in a second pass, so they
//! never sit between a frame's draw and the next cull.

use std::time::Instant;

use serde::Serialize;
use zwarp_core::{Camera, Error, Image, Result, Scene, NO_ITEM};
use zwarp_raster::{render_frame, Frame, FrameOptions};

use crate::bounds::ObjectBounds;
use crate::diagnose::{culled_visible, CulledVisible};
use crate::maxdepth::MaxDepthKind;
use crate::woc::{
    accuracy, cull_against_depth_with, max_over_footprints, nocull, twophase_with, vfc_cull_with, visible_from_items,
    woc_with, CullAccuracy, CullResult, CullStats, CullTimings, PrevFrame, WocParams, DEPTH_TOLERANCE,
};

/// The culling methods compared in seed 000 Table 5 / Table 7 and thesis Table 3.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Draw everything.
    NoCull,
    /// View-frustum culling only.
    Vfc,
    /// Warping-based occlusion culling (far-depth holes).
    Woc,
    /// Approximate WOC (AWOC hole fill, Sec. 5.3).
    Awoc,
    /// Previous depth without reprojection (unsafe baseline).
    LastFrame,
    /// Two geometry passes (previous visible set, then the newly visible).
    TwoPhase,
    /// Screen-space AABB test against the true depth of the frame (ideal screen-space bound).
    Ideal,
    /// REF: the exact visible set read from the item buffer of the full render (an oracle; its
    /// culling cost is not counted).
    Ref,
}

impl Method {
    /// Every method, in the order of the tables.
    pub const ALL: [Method; 8] = [
        Method::NoCull,
        Method::Vfc,
        Method::Woc,
        Method::Awoc,
        Method::LastFrame,
        Method::TwoPhase,
        Method::Ideal,
        Method::Ref,
    ];

    /// Short lower-case name (`nocull`, `vfc`, `woc`, `awoc`, `lastframe`, `twophase`, `ideal`).
    pub fn name(self) -> &'static str {
        match self {
            Method::NoCull => "nocull",
            Method::Vfc => "vfc",
            Method::Woc => "woc",
            Method::Awoc => "awoc",
            Method::LastFrame => "lastframe",
            Method::TwoPhase => "twophase",
            Method::Ideal => "ideal",
            Method::Ref => "ref",
        }
    }

    /// Parses a [`Method::name`].
    pub fn parse(s: &str) -> Result<Self> {
        Method::ALL.into_iter().find(|m| m.name() == s).ok_or_else(|| {
            Error::invalid(format!(
                "unknown culling method '{s}' (expected {})",
                Method::ALL.map(|m| m.name()).join("|")
            ))
        })
    }
}

/// One frame of [`run_sequence`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FrameReport {
    /// Frame index along the path.
    pub frame: usize,
    /// Scene time.
    pub t: f32,
    /// Objects drawn.
    pub visible: usize,
    /// Their ids (increasing), e.g. to shade the frame afterwards for image-quality metrics.
    #[serde(skip)]
    pub visible_ids: Vec<u32>,
    /// Against REF (the item buffer of the full render of this frame).
    pub accuracy: CullAccuracy,
    /// Pixels whose depth differs from the full render (thesis Table 1 "pixel error").
    pub pixel_error: usize,
    /// Culling cost by stage (two-phase: its draws are in `draw_ms` below, not here).
    pub cull: CullTimings,
    /// Classification counts.
    pub stats: CullStats,
    /// Time to draw the visible set (depth + items).
    pub draw_ms: f64,
    /// Time to draw everything in the same run (the NOCULL frame, also the REF render).
    pub full_draw_ms: f64,
    /// Triangles drawn.
    pub triangles: usize,
    /// Triangles of the whole scene.
    pub full_triangles: usize,
    /// Every object REF shows that the method culled, with why (size in pixels, speed, stage,
    /// predicted vs true depth; see [`CulledVisible`]).
    pub culled_visible: Vec<CulledVisible>,
    /// `true` for frame 0 of the history-based methods, which has no previous frame and falls
    /// back to VFC.
    pub bootstrap: bool,
    /// Accuracy of the method's occlusion map against the true depth (WOC, AWOC, last frame,
    /// ideal; `None` for methods without a map), thesis Sec. V.1 / Fig. 8.
    pub map_accuracy: Option<MapAccuracy>,
}

/// Occlusion-map accuracy of one frame (seed 002 thesis Sec. V.1, Fig. 8): the method's map
/// against the full render's depth, reduced by max to the map's resolution (what each map texel
/// must bound). A texel *nearer* than that by more than the test's [`DEPTH_TOLERANCE`] is an
/// **error** (unsafe: it can cull a visible object); one farther is an **over-estimation**
/// (safe, it only culls less: far holes, erosion). Stored depth in `[0, 1]`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct MapAccuracy {
    /// Fraction of texels nearer than the truth (unsafe).
    pub error_fraction: f64,
    /// Fraction of texels farther than the truth (safe).
    pub overestimation_fraction: f64,
    /// PSNR (dB) of the nearer-than-truth part of the difference (`inf` when none).
    pub error_psnr: f64,
    /// PSNR (dB) of the farther-than-truth part.
    pub overestimation_psnr: f64,
}

impl MapAccuracy {
    /// `map` (any non-empty size up to the reference's) against the true depth `reference`.
    pub fn of(map: &Image<f32>, reference: &Image<f32>) -> Result<Self> {
        let (w, h) = map.size();
        if w == 0 || h == 0 || w > reference.width() || h > reference.height() {
            return Err(Error::invalid(format!(
                "occlusion map is {w}x{h} but the reference depth {}x{}",
                reference.width(),
                reference.height()
            )));
        }
        let reduced;
        let truth = if map.size() == reference.size() {
            reference
        } else {
            reduced = max_over_footprints(reference, (w, h));
            &reduced
        };
        let e = zwarp_metrics::signed_depth_errors(map, truth, DEPTH_TOLERANCE, 1.0)?;
        Ok(MapAccuracy {
            error_fraction: e.nearer_fraction(),
            overestimation_fraction: e.farther_fraction(),
            error_psnr: e.psnr_nearer,
            overestimation_psnr: e.psnr_farther,
        })
    }
}

fn ms(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

fn draw(scene: &Scene, cam: &Camera, t: f32, visible: &[u32]) -> Result<(Frame, f64)> {
    let t0 = Instant::now();
    let f = render_frame(scene, cam, t, &FrameOptions { color: false, objects: Some(visible) })?;
    Ok((f, ms(t0)))
}

/// Culls and draws every frame of `frames` (`(time, camera)`, all cameras of one size) with
/// `method`; `params` configures WOC/AWOC (its `max_depth` is also used by the other
/// screen-space methods). Errors on an empty scene or path, mixed image sizes, or any stage
/// error.
pub fn run_sequence(
    scene: &Scene,
    frames: &[(f32, Camera)],
    method: Method,
    params: &WocParams,
) -> Result<Vec<FrameReport>> {
    run_sequence_repeated(scene, frames, method, params, 1)
}

/// [`run_sequence`] with every frame culled `repeat` times (at least once) from the same
/// inputs and the repetition of median cost kept (its decision is the same every time):
/// the per-frame cost along the path without the machine's one-off hiccups, for the
/// stable-cost measurement (`zwarp cull --repeat`).
pub fn run_sequence_repeated(
    scene: &Scene,
    frames: &[(f32, Camera)],
    method: Method,
    params: &WocParams,
    repeat: usize,
) -> Result<Vec<FrameReport>> {
    scene.check_nonempty()?;
    params.validate()?;
    check_frames(frames)?;
    // Warm-up: the same loop over frame 0 twice, untimed and discarded, so that the first
    // timed frame is not charged for first-touch page faults and cold caches (CB 960x540:
    // WOC's first frame took 1.4-1.6x the median of the others without it).
    run_timed(scene, &[frames[0], frames[0]], method, params, 1)?;
    let timed = run_timed(scene, frames, method, params, repeat)?;

    // Pass 2, the evaluation: the full render of every frame (REF / NOCULL, timed as the
    // comparison), the kept set drawn again (the renderer is deterministic: the same depth and
    // items as pass 1 drew) and everything compared.
    let mut out = Vec::with_capacity(frames.len());
    let mut prev: Option<Frame> = None;
    for (k, ((t, cam), mut f)) in frames.iter().zip(timed).enumerate() {
        let t0 = Instant::now();
        let full = render_frame(scene, cam, *t, &FrameOptions::default())?;
        let full_draw_ms = ms(t0);
        let drawn = if f.visible.len() == scene.instances.len() {
            Frame { depth: full.depth.clone(), items: full.items.clone(), color: None }
        } else {
            render_frame(scene, cam, *t, &FrameOptions { color: false, objects: Some(&f.visible) })?
        };
        let occ = f.occ.take();
        let prev_frame = prev.as_ref().map(|p| (&p.depth, &p.items));
        out.push(frame_report(
            scene,
            frames,
            k,
            f,
            (&full.depth, &full.items),
            full_draw_ms,
            &drawn.depth,
            occ.as_ref(),
            prev_frame,
        )?);
        prev = Some(drawn);
    }
    Ok(out)
}

/// The first frame's camera, after checking that the path has frames and that every frame
/// renders at its size.
pub(crate) fn check_frames(frames: &[(f32, Camera)]) -> Result<&Camera> {
    let (_, first) = frames.first().ok_or_else(|| Error::invalid("camera path has no frames"))?;
    if let Some((k, (_, c))) =
        frames.iter().enumerate().find(|(_, (_, c))| (c.width, c.height) != (first.width, first.height))
    {
        return Err(Error::invalid(format!(
            "frame {k} renders {}x{} but frame 0 renders {}x{}",
            c.width, c.height, first.width, first.height
        )));
    }
    Ok(first)
}

/// Pass 2 of a culling sequence on either backend, for frame `k` of `frames`: the timed pass's
/// kept set `f` against the full render `full` (depth, items; timed `full_draw_ms`), the pixels
/// where the frame drawn from the kept set (`shown`) differs from it, the visible objects
/// culled and why (against the method's occlusion map `occ` and the previous drawn frame
/// `prev`), the occlusion map's accuracy.
#[allow(clippy::too_many_arguments)]
pub(crate) fn frame_report(
    scene: &Scene,
    frames: &[(f32, Camera)],
    k: usize,
    f: TimedFrame,
    full: (&Image<f32>, &Image<u32>),
    full_draw_ms: f64,
    shown: &Image<f32>,
    occ: Option<&Image<f32>>,
    prev: Option<(&Image<f32>, &Image<u32>)>,
) -> Result<FrameReport> {
    let (t, cam) = &frames[k];
    let n = scene.instances.len();
    let reference = visible_from_items(full.1, n);
    let pixel_error = shown.data().iter().zip(full.0.data()).filter(|(a, b)| a != b).count();
    let pf = prev.map(|(depth, items)| PrevFrame { depth, items, cam: &frames[k - 1].1, t: frames[k - 1].0 });
    let culled = culled_visible(scene, &f.visible, full.1, full.0, occ, cam, *t, pf.as_ref());
    let map_accuracy = occ.map(|m| MapAccuracy::of(m, full.0)).transpose()?;
    let triangles =
        f.visible.iter().map(|&id| scene.meshes[scene.instances[id as usize].mesh as usize].triangle_count()).sum();
    Ok(FrameReport {
        frame: k,
        t: *t,
        visible: f.visible.len(),
        accuracy: accuracy(&f.visible, &reference, n),
        triangles,
        visible_ids: f.visible,
        pixel_error,
        cull: f.cull,
        stats: f.stats,
        draw_ms: f.draw_ms,
        full_draw_ms,
        full_triangles: scene.triangle_count(),
        culled_visible: culled,
        bootstrap: f.bootstrap,
        map_accuracy,
    })
}

/// What the timed pass of a culling sequence (either backend) keeps of a frame.
pub(crate) struct TimedFrame {
    pub(crate) visible: Vec<u32>,
    pub(crate) cull: CullTimings,
    pub(crate) stats: CullStats,
    pub(crate) draw_ms: f64,
    /// The method's occlusion map (at the culling resolution).
    pub(crate) occ: Option<Image<f32>>,
    pub(crate) bootstrap: bool,
}

/// One culling decision of [`run_timed`] (before the kept set is drawn).
struct CullStep {
    visible: Vec<u32>,
    cull: CullTimings,
    stats: CullStats,
    /// Two-phase draws as part of culling: its final depth, the time of its draws and the set
    /// the next frame draws first.
    twophase: Option<(Image<f32>, f64, Vec<u32>)>,
    occ: Option<Image<f32>>,
}

/// Pass 1 of [`run_sequence`], the engine's loop and the only timed one: each frame is culled
/// and its kept set drawn, and that drawing is the next frame's previous frame. Nothing else
/// runs in between: a full render of every object (evaluation only) placed before each cull
/// leaves after-effects (caches, a busy second core) that a 2-core machine charges to the cull
/// (CB, 960x540: WOC's worst/median cull time 1.5-1.8 with it, 1.1-1.65 without). The oracles (`ideal`, `ref`) render the frame in
/// full here because that render is their input. With `repeat > 1` every frame is culled
/// `repeat` times from the same inputs (the decision is deterministic) and the repetition with
/// the median total time is kept: the cost of that frame, free of one-off machine hiccups.
fn run_timed(
    scene: &Scene,
    frames: &[(f32, Camera)],
    method: Method,
    params: &WocParams,
    repeat: usize,
) -> Result<Vec<TimedFrame>> {
    let n = scene.instances.len();
    // The objects' boxes, kept across frames as an engine keeps them (static ones stored once),
    // shared by every method.
    let bounds = ObjectBounds::new(scene);
    let mut prev: Option<(Frame, Vec<u32>)> = None;
    let mut out = Vec::with_capacity(frames.len());
    for (k, (t, cam)) in frames.iter().enumerate() {
        let t = *t;
        let oracle = match method {
            Method::Ideal | Method::Ref => Some(render_frame(scene, cam, t, &FrameOptions::default())?),
            _ => None,
        };
        let history = matches!(method, Method::Woc | Method::Awoc | Method::LastFrame | Method::TwoPhase);
        let bootstrap = history && prev.is_none();
        let cull_once = || -> Result<CullStep> {
            let plain = |r: CullResult| CullStep {
                visible: r.visible,
                cull: r.timings,
                stats: r.stats,
                twophase: None,
                occ: r.occlusion_map,
            };
            if bootstrap && method != Method::TwoPhase {
                return Ok(plain(vfc_cull_with(scene, &bounds, cam, t)?));
            }
            Ok(match method {
                Method::TwoPhase => {
                    // For two-phase, `prev`'s set is the re-tested `next_visible` (see below).
                    let pv = prev.as_ref().map(|(_, v)| v.as_slice()).unwrap_or(&[]);
                    let r = twophase_with(scene, &bounds, pv, cam, t, params.max_depth)?;
                    let mut cull = r.timings;
                    let draw_ms = cull.draw_ms;
                    cull.draw_ms = 0.0;
                    cull.total_ms -= draw_ms;
                    let stats = CullStats { objects: n, ..CullStats::default() };
                    CullStep {
                        visible: r.visible,
                        cull,
                        stats,
                        twophase: Some((r.depth, draw_ms, r.next_visible)),
                        occ: None,
                    }
                }
                Method::NoCull => plain(nocull(scene)),
                Method::Vfc => plain(vfc_cull_with(scene, &bounds, cam, t)?),
                Method::Ideal => {
                    let full = oracle.as_ref().expect("oracle rendered");
                    plain(cull_against_depth_with(scene, &bounds, &full.depth, cam, t, MaxDepthKind::NBuffer, None)?)
                }
                Method::Ref => plain(CullResult {
                    visible: visible_from_items(&oracle.as_ref().expect("oracle rendered").items, n),
                    timings: CullTimings::default(),
                    stats: CullStats { objects: n, ..CullStats::default() },
                    predrawn: Vec::new(),
                    occlusion_map: None,
                }),
                Method::LastFrame => {
                    let (pf, _) = prev.as_ref().expect("not bootstrap");
                    plain(cull_against_depth_with(scene, &bounds, &pf.depth, cam, t, params.max_depth, None)?)
                }
                Method::Woc | Method::Awoc => {
                    let (pf, _) = prev.as_ref().expect("not bootstrap");
                    let (t_prev, pcam) = &frames[k - 1];
                    let p = PrevFrame { depth: &pf.depth, items: &pf.items, cam: pcam, t: *t_prev };
                    let wp = WocParams { awoc: method == Method::Awoc, ..*params };
                    plain(woc_with(scene, &bounds, &p, cam, t, &wp)?)
                }
            })
        };
        let mut steps = (0..repeat.max(1)).map(|_| cull_once()).collect::<Result<Vec<_>>>()?;
        debug_assert!(steps.iter().all(|s| s.visible == steps[0].visible), "repeated culls disagree");
        steps.sort_by(|a, b| a.cull.total_ms.total_cmp(&b.cull.total_ms));
        let step = steps.swap_remove(steps.len() / 2);
        drop(steps);
        drop(oracle);
        let (drawn, draw_ms, next_first) = match step.twophase {
            // Two-phase reads no previous frame, only the previous visible set: its final depth
            // stands for the drawn frame (no items needed).
            Some((depth, draw_ms, next)) => {
                let items = Image::new(cam.width, cam.height, NO_ITEM);
                (Frame { depth, items, color: None }, draw_ms, Some(next))
            }
            None => {
                let (f, d) = draw(scene, cam, t, &step.visible)?;
                (f, d, None)
            }
        };
        let occ = step.occ;
        prev = Some((drawn, next_first.unwrap_or_else(|| step.visible.clone())));
        out.push(TimedFrame { visible: step.visible, cull: step.cull, stats: step.stats, draw_ms, occ, bootstrap });
    }
    Ok(out)
}

/// Medians and totals over the non-bootstrap frames of a [`run_sequence`] run.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct SequenceSummary {
    /// Frames summarized.
    pub frames: usize,
    /// Median culling time (ms).
    pub cull_ms: f64,
    /// Median draw time of the visible set (ms).
    pub draw_ms: f64,
    /// Median full draw time in the same run (ms).
    pub full_draw_ms: f64,
    /// Mean culling ratio.
    pub culling_ratio: f64,
    /// Mean fraction of triangles drawn.
    pub triangle_fraction: f64,
    /// Total culling errors (visible objects culled) over all frames.
    pub false_negatives: usize,
    /// Mean object error.
    pub object_error: f64,
    /// Mean pixel error (pixels per frame).
    pub pixel_error: f64,
}

/// The median of `v` (0 if empty).
fn median(v: Vec<f64>) -> f64 {
    zwarp_metrics::Timing::of(&v).median
}

/// Summarizes the frames that are not bootstrap frames (all frames if every one is).
pub fn summarize(reports: &[FrameReport]) -> SequenceSummary {
    let steady: Vec<&FrameReport> = reports.iter().filter(|r| !r.bootstrap).collect();
    let rs: Vec<&FrameReport> = if steady.is_empty() { reports.iter().collect() } else { steady };
    let n = rs.len().max(1) as f64;
    SequenceSummary {
        frames: rs.len(),
        cull_ms: median(rs.iter().map(|r| r.cull.total_ms).collect()),
        draw_ms: median(rs.iter().map(|r| r.draw_ms).collect()),
        full_draw_ms: median(rs.iter().map(|r| r.full_draw_ms).collect()),
        culling_ratio: rs.iter().map(|r| r.accuracy.culling_ratio).sum::<f64>() / n,
        triangle_fraction: rs.iter().map(|r| r.triangles as f64 / r.full_triangles.max(1) as f64).sum::<f64>() / n,
        false_negatives: rs.iter().map(|r| r.accuracy.false_negatives).sum(),
        object_error: rs.iter().map(|r| r.accuracy.object_error).sum::<f64>() / n,
        pixel_error: rs.iter().map(|r| r.pixel_error as f64).sum::<f64>() / n,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn method_names_roundtrip() {
        for m in Method::ALL {
            assert_eq!(Method::parse(m.name()).unwrap(), m);
        }
        let e = Method::parse("chc").unwrap_err().to_string();
        assert!(e.contains("unknown culling method 'chc'") && e.contains("woc|awoc"), "{e}");
    }

    #[test]
    fn map_accuracy_splits_unsafe_from_safe_texels() {
        // 4x4 truth, one object: a map equal to it is exact; one texel nearer is one error in
        // 16, one farther one over-estimation; at 1/2 the truth is max-reduced first, so a map
        // holding each 2x2 block's max is exact and its min would be an error wherever a block
        // is not flat.
        let truth = Image::from_vec(4, 4, (0..16).map(|i| 0.5 + 0.01 * i as f32).collect()).unwrap();
        let exact = MapAccuracy::of(&truth, &truth).unwrap();
        assert_eq!((exact.error_fraction, exact.overestimation_fraction), (0.0, 0.0));
        assert!(exact.error_psnr.is_infinite() && exact.overestimation_psnr.is_infinite());
        let mut map = truth.clone();
        *map.get_mut(1, 2) -= 0.1;
        *map.get_mut(3, 0) += 0.2;
        let m = MapAccuracy::of(&map, &truth).unwrap();
        assert_eq!((m.error_fraction, m.overestimation_fraction), (1.0 / 16.0, 1.0 / 16.0));
        assert!(m.error_psnr.is_finite() && m.error_psnr > m.overestimation_psnr, "{m:?}");
        let block = |f: fn(f32, f32) -> f32| {
            let v = |x: u32, y: u32| truth.data()[(y * 4 + x) as usize];
            let d = (0..4u32)
                .map(|i| {
                    let (bx, by) = (2 * (i % 2), 2 * (i / 2));
                    f(f(v(bx, by), v(bx + 1, by)), f(v(bx, by + 1), v(bx + 1, by + 1)))
                })
                .collect();
            Image::from_vec(2, 2, d).unwrap()
        };
        let max = MapAccuracy::of(&block(f32::max), &truth).unwrap();
        assert_eq!((max.error_fraction, max.overestimation_fraction), (0.0, 0.0));
        let min = MapAccuracy::of(&block(f32::min), &truth).unwrap();
        assert_eq!((min.error_fraction, min.overestimation_fraction), (1.0, 0.0));
    }

    #[test]
    fn median_of_even_and_odd() {
        assert_eq!(median(vec![3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(vec![4.0, 1.0, 2.0, 3.0]), 2.5);
        assert_eq!(median(vec![]), 0.0);
    }
}
