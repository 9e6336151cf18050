//! Single- and multi-layer backward depth warping (seed 000 Sec. 3.2-3.4, Fig. 3-6).
//!
//! For every target pixel and every layer: tighten the search bound in that layer's motion
//! mipmap (skipping the layer at once when its region holds no valid sample — hidden layers are
//! mostly empty), place seeds, run [`fixed_point_search`](crate::search::fixed_point_search), and keep the candidate of minimal
//! target depth over all layers. Layers are the peeled depth layers of the source view, nearest
//! first; the ground / background is best passed as a separate **last** layer (Sec. 3.4: it
//! widens the connected search area at negligible cost).
//!
//! Cross-layer seeding (Fig. 6), when [`WarpParams::cross_layer`] is set: when an iterate of
//! layer k lands on an empty texel, the walk borrows the sample of the nearest non-empty layer
//! above (towards the camera) at the same position; landing in empty space a second time makes
//! the seed non-convergent. In addition, the converged position of an earlier layer seeds the
//! search of the later ones (it replaces the last stratified seed when it lies in the region).
//!
//! Pruning: once a layer converged, a later layer is searched only if the min-depth mipmap says
//! some sample of its search region is nearer than the best candidate (exact for the layer's
//! own samples; a later layer's cross-layer borrowing from earlier layers is then skipped too,
//! which only drops duplicates of what those layers' own searches could find).

use rayon::prelude::*;
use zwarp_core::{Error, Image, Motion, Result, EMPTY_DEPTH};

use crate::bounds::MotionScales;
use crate::holes::{fill_holes, FillRule, HolePolicy};
use crate::kernel::{Kernel, TILE};
pub use crate::prepare::{PreparedLayer, SurfaceMotion};
use crate::sampling::LayerSampler;
use crate::{PixelState, SourcePos, WarpOutput, WarpParams};

/// One peeled source layer: its depth buffer (`1.0` = empty) and motion buffer (motion to the
/// target and target depth per pixel, e.g. from `zwarp_core::motion_field`).
#[derive(Clone, Copy, Debug)]
pub struct WarpLayer<'a> {
    /// Source depth of the layer (`[0, 1]`, 1 = no surface).
    pub depth: &'a Image<f32>,
    /// Motion of the layer's samples to the target view.
    pub motion: &'a Image<Motion>,
}

/// Backward depth warp of `layers` (nearest first, ground last if separate) to the target view
/// the motion buffers point to. Single-layer warping is `layers.len() == 1`.
///
/// Errors ([`Error::Invalid`]): empty layer list, zero-size or mismatched buffers, NaN depth or
/// motion, invalid parameters.
pub fn warp_depth(layers: &[WarpLayer<'_>], params: &WarpParams) -> Result<WarpOutput> {
    params.validate()?;
    if layers.is_empty() {
        return Err(Error::invalid("warp_depth needs at least one layer"));
    }
    let scales = MotionScales::for_scale(params.motion_scale);
    let prepared = PreparedLayer::prepare_stack_for(layers, params.bound, scales, Vec::new())?;
    warp_prepared(&prepared, params)
}

/// [`warp_depth`] on layers prepared once ([`PreparedLayer::prepare_stack`], or
/// [`PreparedLayer::new`] per layer). The bound *frame* (AAB or
/// OB) is fixed when a layer is prepared; `params.bound == Global` disables the per-pixel
/// tightening, any other kind tightens in the prepared frame.
pub fn warp_prepared(layers: &[PreparedLayer], params: &WarpParams) -> Result<WarpOutput> {
    let mut out = WarpOutput::empty();
    warp_prepared_into(layers, params, &mut out)?;
    Ok(out)
}

/// The complete prediction of seed 000 Sec. 4 from source layers with their motion: the
/// preparation (reusing the buffers of `recycled`, last frame's preparation), the warp into
/// `out`'s buffers and, under [`HolePolicy::Background`], the background protocol
/// ([`crate::holes::fill_background_with`], with the limits taken from the preparation) over
/// the warp's far holes; any other policy runs inside the warp. Returns the preparation, to be
/// recycled by the next call. `zwarp eval` and the `zwarp` facade call this.
pub fn predict_into(
    layers: &[WarpLayer<'_>],
    params: &WarpParams,
    recycled: Vec<PreparedLayer>,
    out: &mut WarpOutput,
) -> Result<Vec<PreparedLayer>> {
    params.validate()?;
    let fill = match params.holes {
        HolePolicy::Background { radius } => Some(radius),
        _ => None,
    };
    let warp_params = if fill.is_some() { WarpParams { holes: HolePolicy::FarDepth, ..*params } } else { *params };
    let scales = MotionScales::for_scale(params.motion_scale);
    let prepared = PreparedLayer::prepare_stack_for(layers, warp_params.bound, scales, recycled)?;
    warp_prepared_into(&prepared, &warp_params, out)?;
    if let Some(radius) = fill {
        let (w, h) = out.depth.size();
        let limits = crate::holes::BackgroundLimits::of_prepared(&prepared, w, h, params.multisample, radius)?;
        crate::holes::fill_background_with(layers, out, limits, &params.search())?;
    }
    Ok(prepared)
}

/// [`warp_prepared`] into the buffers of `out` (an earlier warp's output, of any size: buffers
/// that are too small are replaced), as an engine keeps its output from frame to frame. The
/// result is the same as [`warp_prepared`]'s; what it saves is allocating and faulting in fresh
/// output pages every frame.
pub fn warp_prepared_into(layers: &[PreparedLayer], params: &WarpParams, out: &mut WarpOutput) -> Result<()> {
    params.validate()?;
    let first = layers.first().ok_or_else(|| Error::invalid("warp_depth needs at least one layer"))?;
    let (w, h) = first.size();
    if let Some((i, l)) = layers.iter().enumerate().find(|(_, l)| l.size() != (w, h)) {
        return Err(Error::invalid(format!("layer {i} is {}x{} but layer 0 is {w}x{h}", l.size().0, l.size().1)));
    }
    if layers.len() > u32::MAX as usize - 1 {
        return Err(Error::invalid("too many layers"));
    }
    check_motion_scale(layers, params)?;
    let (tw, th) = target_size(w, h, params.multisample)?;
    let samplers: Vec<LayerSampler<'_>> = layers.iter().enumerate().map(|(i, l)| l.sampler(params, i as u32)).collect();
    let kernel = Kernel::new(layers, &samplers, params, (w, h), (tw, th));
    let (w, h) = (tw, th);

    let n = w as usize * h as usize;
    // Every pixel is written by the kernel; recycled buffers keep their pages.
    let take = |img: &mut Image<f32>| std::mem::replace(img, Image::new(0, 0, 0.0)).into_vec();
    let mut depth = take(&mut out.depth);
    let mut state = std::mem::replace(&mut out.state, Image::new(0, 0, PixelState::Hole)).into_vec();
    if depth.capacity() < n {
        depth = zwarp_core::pages::filled(n, EMPTY_DEPTH);
    } else {
        depth.resize(n, EMPTY_DEPTH);
    }
    if state.capacity() < n {
        state = zwarp_core::pages::filled(n, PixelState::Hole);
    } else {
        state.resize(n, PixelState::Hole);
    }
    let mut source = if params.record_source {
        let mut s = out.source.take().map(Image::into_vec).unwrap_or_default();
        s.resize(n, SourcePos::default());
        s
    } else {
        Vec::new()
    };
    // Bands of tile rows: the pixels of a tile share its bound stage. Each band lists the
    // pixels its deeper layers revealed (few: disocclusions).
    let band = (w * TILE) as usize;
    out.revealed.clear();
    if params.record_source {
        out.revealed.par_extend(
            depth
                .par_chunks_mut(band)
                .zip(state.par_chunks_mut(band))
                .zip(source.par_chunks_mut(band))
                .enumerate()
                .flat_map_iter(|(ty, ((d, s), src))| kernel.band(ty as u32, d, s, Some(src))),
        );
    } else {
        out.revealed.par_extend(
            depth
                .par_chunks_mut(band)
                .zip(state.par_chunks_mut(band))
                .enumerate()
                .flat_map_iter(|(ty, (d, s))| kernel.band(ty as u32, d, s, None)),
        );
    }
    // Bands come in order; within one the lanes write two rows at a time.
    out.revealed.sort_unstable();
    out.depth = Image::from_vec(w, h, depth)?;
    out.state = Image::from_vec(w, h, state)?;
    match params.holes {
        HolePolicy::Dilate { radius } => fill_holes(&mut out.depth, &mut out.state, radius, FillRule::Nearest),
        HolePolicy::Background { radius } => fill_holes(&mut out.depth, &mut out.state, radius, FillRule::Background),
        HolePolicy::FarDepth | HolePolicy::Awoc => {}
    }
    out.source = if params.record_source { Some(Image::from_vec(w, h, source)?) } else { None };
    Ok(())
}

/// The warp of exactly the listed target pixels (row-major indices `y * w + x`): for each one
/// the `(depth, state)` that [`warp_prepared`] writes there, bit for bit (seed 000 Sec. 3 per
/// pixel, with the same 4x4 tile stage of Sec. 3.3 / Fig. 5: the tile bound of each pixel's
/// tile is computed, and reused while consecutive listed pixels share a tile). For
/// sparse consumers (soft shadows warp only the receivers' pixels). Parallel over chunks of
/// the list; output order = input order. Pixels may repeat.
///
/// Errors ([`Error::Invalid`]): everything [`warp_prepared`] rejects, a pixel index `>= w * h`,
/// and [`HolePolicy::Dilate`] / [`HolePolicy::Background`] (they fill a hole from its converged
/// neighbours, which a sparse warp does not compute).
pub fn warp_pixels(layers: &[PreparedLayer], params: &WarpParams, pixels: &[u32]) -> Result<Vec<(f32, PixelState)>> {
    params.validate()?;
    if let HolePolicy::Dilate { .. } | HolePolicy::Background { .. } = params.holes {
        return Err(Error::invalid(
            "warp_pixels does not support HolePolicy::Dilate/Background (they need the neighbouring pixels)",
        ));
    }
    let first = layers.first().ok_or_else(|| Error::invalid("warp_pixels needs at least one layer"))?;
    let (w, h) = first.size();
    if let Some((i, l)) = layers.iter().enumerate().find(|(_, l)| l.size() != (w, h)) {
        return Err(Error::invalid(format!("layer {i} is {}x{} but layer 0 is {w}x{h}", l.size().0, l.size().1)));
    }
    check_motion_scale(layers, params)?;
    let (tw, th) = target_size(w, h, params.multisample)?;
    let n = tw as u64 * th as u64;
    if let Some(&bad) = pixels.iter().find(|&&i| i as u64 >= n) {
        return Err(Error::invalid(format!("pixel index {bad} is outside the {tw}x{th} image")));
    }
    let samplers: Vec<LayerSampler<'_>> = layers.iter().enumerate().map(|(i, l)| l.sampler(params, i as u32)).collect();
    let kernel = Kernel::new(layers, &samplers, params, (w, h), (tw, th));
    // Chunks of a few tiles' worth of pixels: large enough to amortise the tile stage when the
    // list is sorted, small enough to balance sparse, unevenly costly lists.
    const CHUNK: usize = 256;
    Ok(pixels
        .par_chunks(CHUNK)
        .flat_map_iter(|chunk| {
            let mut out = Vec::with_capacity(chunk.len());
            kernel.pixels(chunk, &mut out);
            out
        })
        .collect())
}

/// The target image of a warp from `w x h` source layers with [`WarpParams::multisample`] = `m`:
/// `(w / m, h / m)`; the source must hold exactly `m x m` samples per target pixel, else a
/// one-line [`Error::Invalid`]. The one rule of both twins (the WGSL warp's host code calls it).
pub fn target_size(w: u32, h: u32, m: u32) -> Result<(u32, u32)> {
    if m == 0 || !w.is_multiple_of(m) || !h.is_multiple_of(m) {
        return Err(Error::invalid(format!(
            "multisample {m}: the {w}x{h} source layers must hold {m}x{m} samples per target pixel (sizes divisible by {m})"
        )));
    }
    Ok((w / m, h / m))
}

/// A non-uniform [`WarpParams::motion_scale`] does not commute with the rotation of an
/// oriented bound frame, so the prepared mipmap would not bound the scaled motion; nor does a
/// scale below one bound it where the preparation clipped the samples that leave the image
/// ([`MotionScales`]).
fn check_motion_scale(layers: &[PreparedLayer], params: &WarpParams) -> Result<()> {
    let s = params.motion_scale;
    if let Some(k) = layers.iter().position(|l| !l.scales().serves(s)) {
        return Err(Error::invalid(format!(
            "motion_scale {s} is below 1, but layer {k} was prepared for scales >= 1 (prepare with MotionScales::Any)"
        )));
    }
    if s.x != s.y {
        if let Some(k) = layers.iter().position(|l| !l.pyramid().frame().is_identity()) {
            return Err(Error::invalid(format!(
                "non-uniform motion_scale {s} needs axis-aligned bounds, but layer {k} has an oriented frame (use BoundKind::Tight)"
            )));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernel::StackSampler;
    use crate::prepare::validated_samples;
    use crate::sampling::MotionSource;
    use crate::sampling::SamplePlanes;
    use crate::BoundKind;
    use crate::MotionPyramid;
    use glam::Vec2;

    fn plane_bits(p: &SamplePlanes) -> Vec<(u32, u32, u32)> {
        (0..p.len()).map(|i| (p.vx[i].to_bits(), p.vy[i].to_bits(), p.z[i].to_bits())).collect()
    }

    fn layer(vals: &[(f32, f32)]) -> Vec<Motion> {
        vals.iter().map(|&(vx, d)| Motion { v: Vec2::new(vx, 0.0), depth: d }).collect()
    }

    /// The fused one-pass preparation equals the separate passes it replaced (validated
    /// samples, repeat-free copy for layers k > 0, frame choice, mipmap from samples) bit for bit:
    /// samples, frame, every texel and the min-depth look-ups, for every bound kind, on layers
    /// with empty pixels, repeated ground samples, odd sizes and diagonal motion (PCA frame).
    #[test]
    fn fused_preparation_equals_separate_passes() {
        use crate::bounds::{choose_frame, ImageClip};
        let (w, h) = (37u32, 22u32);
        let d0 = Image::from_fn(w, h, |x, y| if (x + y) % 7 == 0 { 1.0 } else { 0.3 + 0.01 * x as f32 });
        // Layer 1 repeats layer 0's depth on a third of the pixels (a ground layer).
        let d1 = Image::from_fn(w, h, |x, y| if x % 3 == 0 { *d0.get(x, y) } else { 0.8 + 0.001 * y as f32 });
        let m = |x: u32, y: u32, d: f32| {
            let t = 0.3 * x as f32 - 0.2 * y as f32;
            Motion { v: Vec2::new(t + 0.05 * (y % 3) as f32, 0.9 * t - 2.0), depth: if x == 5 { 1.5 } else { d } }
        };
        let m0 = Image::from_fn(w, h, |x, y| m(x, y, *d0.get(x, y)));
        let m1 = Image::from_fn(w, h, |x, y| m(x, y, *d1.get(x, y)));
        let layers = [WarpLayer { depth: &d0, motion: &m0 }, WarpLayer { depth: &d1, motion: &m1 }];
        // Both ways of treating the samples that leave the image (the motion reaches 11 px on
        // a 37 px wide image: the right columns' targets lie beyond the clip's margin).
        let cases = [BoundKind::Global, BoundKind::Tight, BoundKind::Oriented]
            .into_iter()
            .flat_map(|b| [(b, MotionScales::AtLeastOne), (b, MotionScales::Any)]);
        for (bound, scales) in cases {
            let fused = PreparedLayer::prepare_stack_for(&layers, bound, scales, Vec::new()).unwrap();
            for (k, got) in fused.iter().enumerate() {
                let samples = validated_samples(&layers[k]).unwrap();
                let mip: Vec<Motion> = samples
                    .iter()
                    .enumerate()
                    .map(|(i, s)| {
                        if layers[..k].iter().any(|e| e.depth.data()[i] == layers[k].depth.data()[i]) {
                            Motion { v: Vec2::ZERO, depth: f32::INFINITY }
                        } else {
                            *s
                        }
                    })
                    .collect();
                let frame = choose_frame(&mip, w, h, bound, scales);
                if bound == BoundKind::Oriented {
                    assert!(!frame.is_identity(), "the test needs a rotated frame");
                }
                let want = MotionPyramid::from_samples(&mip, w, h, frame, ImageClip::new(w, h, frame, scales));
                assert_eq!(
                    plane_bits(got.planes()),
                    plane_bits(&SamplePlanes::from_motion(&samples)),
                    "{bound:?} layer {k}"
                );
                assert_eq!(got.pyramid().frame(), want.frame());
                assert_eq!(got.pyramid().top_level(), want.top_level());
                for level in 1..=want.top_level() {
                    let (lw, lh) = want.level_size(level);
                    for ty in 0..lh {
                        for tx in 0..lw {
                            assert_eq!(got.pyramid().texel(level, tx, ty), want.texel(level, tx, ty));
                        }
                    }
                }
                for (x0, y0, x1, y1) in [(0, 0, 0, 0), (3, 4, 9, 6), (0, 0, w - 1, h - 1), (30, 20, 36, 21)] {
                    assert_eq!(got.pyramid().lookup_min_depth(x0, y0, x1, y1), want.lookup_min_depth(x0, y0, x1, y1));
                }
            }
        }
    }

    /// The first layer of a prepared stack carries the gradient mipmap (the one-seed shortcut
    /// of `PreparedLayer::unique_solution`), the same as that layer prepared alone; the layers
    /// behind it carry none, and their look-ups say `+inf` (never one solution).
    #[test]
    fn only_the_first_prepared_layer_has_a_gradient_mipmap() {
        let (w, h) = (23u32, 14u32);
        let d0 = Image::from_fn(w, h, |x, _| 0.3 + 0.01 * x as f32);
        let d1 = Image::from_fn(w, h, |x, _| 0.6 + 0.01 * x as f32);
        let m = |d: &Image<f32>| {
            Image::from_fn(w, h, |x, y| Motion { v: Vec2::new(0.1 * x as f32, 0.05 * y as f32), depth: *d.get(x, y) })
        };
        let (m0, m1) = (m(&d0), m(&d1));
        let layers = [WarpLayer { depth: &d0, motion: &m0 }, WarpLayer { depth: &d1, motion: &m1 }];
        let stack = PreparedLayer::prepare_stack(&layers, BoundKind::Tight).unwrap();
        let want = PreparedLayer::new(&layers[0], BoundKind::Tight).unwrap();
        for (x0, y0, x1, y1) in [(0, 0, 0, 0), (3, 4, 9, 6), (0, 0, w - 1, h - 1)] {
            let g = stack[0].lookup_gradient(x0, y0, x1, y1);
            assert_eq!(g, want.lookup_gradient(x0, y0, x1, y1));
            assert!(g[0] < 0.05 && g[1] < 0.01, "{g:?}");
            assert_eq!(stack[1].lookup_gradient(x0, y0, x1, y1), [f32::INFINITY; 2]);
        }
        let b = stack[0].pyramid().global();
        let (p_lo, p_hi) = (Vec2::new(5.5, 5.5), Vec2::new(8.5, 8.5));
        assert!(stack[0].unique_solution(p_lo, p_hi, &b, Vec2::ONE));
        assert!(!stack[1].unique_solution(p_lo, p_hi, &stack[1].pyramid().global(), Vec2::ONE));
    }

    /// A stack prepared into recycled buffers equals a fresh one bit for bit (samples, frame,
    /// every mipmap texel and min-depth look-up), whether the recycled buffers are larger or
    /// smaller than needed, hold stale data from another scene, are fewer than the layers, or
    /// chose the other frame (the pass then writes the remembered frame's texels first).
    #[test]
    fn recycled_preparation_equals_a_fresh_one() {
        // `cross`: motion spread over a sheared square, whose PCA axis is rotated but whose
        // axis-aligned bound is the smaller; otherwise along a diagonal (the oriented frame wins).
        let stack = |w: u32, h: u32, seed: u32, cross: bool| {
            let d: Vec<Image<f32>> = (0..3)
                .map(|k| {
                    Image::from_fn(w, h, |x, y| {
                        if (x * 7 + y * 3 + seed + k).is_multiple_of(9) {
                            1.0
                        } else {
                            0.2 + 0.2 * k as f32 + 0.001 * ((x + seed) % 13) as f32
                        }
                    })
                })
                .collect();
            let m: Vec<Image<Motion>> = d
                .iter()
                .map(|dk| {
                    Image::from_fn(w, h, |x, y| {
                        let t = 0.25 * x as f32 - 0.15 * y as f32 + seed as f32;
                        let a = 0.5 * ((x * 5 + y) % 9) as f32;
                        let v = if cross {
                            Vec2::new(a, 0.5 * ((y * 3 + x) % 7) as f32 + 0.3 * a)
                        } else {
                            Vec2::new(t, 0.8 * t - 1.0)
                        };
                        Motion { v, depth: *dk.get(x, y) }
                    })
                })
                .collect();
            (d, m)
        };
        let same = |a: &[PreparedLayer], b: &[PreparedLayer]| {
            assert_eq!(a.len(), b.len());
            for (x, y) in a.iter().zip(b) {
                assert_eq!(x.size(), y.size());
                assert_eq!(x.surfaces(), y.surfaces());
                assert_eq!(plane_bits(x.planes()), plane_bits(y.planes()));
                let (px, py) = (x.pyramid(), y.pyramid());
                assert_eq!((px.frame(), px.top_level()), (py.frame(), py.top_level()));
                for level in 1..=px.top_level() {
                    let (lw, lh) = px.level_size(level);
                    for ty in 0..lh {
                        for tx in 0..lw {
                            assert_eq!(px.texel(level, tx, ty), py.texel(level, tx, ty));
                        }
                    }
                }
                let (w, h) = x.size();
                for (x0, y0, x1, y1) in [(0, 0, 0, 0), (1, 2, 5, 4), (0, 0, w - 1, h - 1)] {
                    assert_eq!(px.lookup_min_depth(x0, y0, x1, y1), py.lookup_min_depth(x0, y0, x1, y1));
                }
            }
        };
        let mut recycled = Vec::new();
        let sizes = [(37u32, 22u32, 3usize), (20, 11, 3), (41, 30, 2), (41, 30, 3), (37, 22, 1), (37, 22, 1)];
        for (i, &(w, h, n)) in sizes.iter().enumerate() {
            for cross in [false, true, false] {
                let (d, m) = stack(w, h, i as u32, cross);
                let layers: Vec<WarpLayer> =
                    d.iter().zip(&m).take(n).map(|(d, m)| WarpLayer { depth: d, motion: m }).collect();
                for bound in [BoundKind::Tight, BoundKind::Oriented, BoundKind::Oriented] {
                    let fresh = PreparedLayer::prepare_stack(&layers, bound).unwrap();
                    if bound == BoundKind::Oriented && w > 20 {
                        // Layer 0 chose the frame the field is made for, and the sheared square's
                        // oriented frame was a candidate: both choices follow each other (on
                        // the smallest image the fields are too coarse to say).
                        let samples = validated_samples(&layers[0]).unwrap();
                        assert_eq!(fresh[0].pyramid().frame().is_identity(), cross, "{w}x{h}");
                        assert!(!crate::bounds::pca_frame(&samples, w, h, 64).is_identity(), "{w}x{h}");
                    }
                    let got =
                        PreparedLayer::prepare_stack_recycling(&layers, bound, std::mem::take(&mut recycled)).unwrap();
                    same(&got, &fresh);
                    recycled = got;
                }
            }
        }
    }

    /// Fig. 6: an empty landing in layer k borrows the nearest non-empty layer above; the second
    /// empty landing of the same walk fails; without cross-layer seeding the first one fails.
    #[test]
    fn cross_layer_sampling_borrows_once_then_fails() {
        let inf = f32::INFINITY;
        // 4x1 images. Layer 0 valid everywhere, layer 1 empty at x = 1 and 2, layer 2 empty at
        // x = 1 only (so layer 2 borrows from layer 1? no: layer 1 is empty there too -> layer 0).
        let l0 = layer(&[(0.0, 0.1), (1.0, 0.2), (2.0, 0.3), (3.0, 0.4)]);
        let l1 = layer(&[(0.0, 0.5), (0.0, inf), (0.0, inf), (0.0, 0.6)]);
        let l2 = layer(&[(0.0, 0.7), (0.0, inf), (0.0, 0.8), (0.0, 0.9)]);
        let planes: Vec<SamplePlanes> = [&l0, &l1, &l2].iter().map(|l| SamplePlanes::from_motion(l)).collect();
        let s: Vec<LayerSampler> = planes
            .iter()
            .enumerate()
            .map(|(i, l)| LayerSampler::new(l, 4, 1, crate::Sampling::Nearest, i as u32))
            .collect();
        let q = |x: f32| Vec2::new(x, 0.5);
        let src = StackSampler { layers: &s, k: 2, cross: true };
        let mut walk = 0u8;
        assert_eq!(src.sample(q(2.5), &mut walk).unwrap().depth, 0.8);
        let b = src.sample(q(1.5), &mut walk).unwrap();
        assert_eq!((b.depth, b.tag, walk), (0.2, 0, 1));
        assert!(src.sample(q(1.5), &mut walk).is_none(), "second empty landing fails");
        // Layer 1 at x = 2 borrows from layer 0.
        let src = StackSampler { layers: &s, k: 1, cross: true };
        assert_eq!(src.sample(q(2.5), &mut 0).unwrap().tag, 0);
        // Outside the image: no borrowing.
        assert!(src.sample(q(4.5), &mut 0).is_none());
        // Without cross-layer seeding, and on the first layer, an empty landing fails at once.
        let src = StackSampler { layers: &s, k: 2, cross: false };
        assert!(src.sample(q(1.5), &mut 0).is_none());
        let e = layer(&[(0.0, inf); 4]);
        let e = SamplePlanes::from_motion(&e);
        let s0 = [LayerSampler::new(&e, 4, 1, crate::Sampling::Nearest, 0)];
        assert!(StackSampler { layers: &s0, k: 0, cross: true }.sample(q(0.5), &mut 0).is_none());
    }
}
