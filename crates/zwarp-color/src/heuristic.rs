//! The heuristic colour warp (seed 001 Sec. 3.3 and 4): one seed per target pixel — the pixel
//! itself, a fixed offset (stereo) or upstream in the flow (temporal) — and a fixed number of
//! fixed-point iterations (3 in the paper), run by the shared search
//! (`zwarp_warp::search::fixed_point_search`). Where the walk does not converge it orbits the
//! disocclusion between foreground and background (Fig. 1e), and the farthest iterate — the
//! background — gives the colour: the "rudimentary in-painting" of Sec. 3.3.
//!
//! Per pixel the output holds the colour (bilinear on surfaces, nearest across discontinuities,
//! [`crate::sampler`]), the chosen sample's source depth and the residual `|q + V(q) - p|`
//! ([`crate::ColorWarpOutput`]: converged where it is below the threshold).

use glam::Vec2;
use rayon::prelude::*;
use zwarp_core::{Error, Image, Result};
use zwarp_warp::search::{fixed_point_search, SearchParams};

use crate::field::Field;
use crate::params::{HeuristicParams, Seed};
use crate::sampler::{ColorSampler, Continuity, Recorder};
use crate::ColorWarpOutput;

/// The fixed seed offset of Sec. 3.3 ("a simple fixed offset worked well", [`Seed::Offset`]) for
/// the warp `field`: minus the field at the texel of the 2nd-percentile depth, i.e. towards where
/// near surfaces come from; zero without surfaces or with a non-finite field there.
pub fn fixed_offset(field: &Field<'_>) -> Vec2 {
    let d = field.depth();
    let mut idx: Vec<u32> = (0..d.len() as u32).filter(|&i| d[i as usize] < 1.0).collect();
    if idx.is_empty() {
        return Vec2::ZERO;
    }
    let k = idx.len() / 50;
    idx.select_nth_unstable_by(k, |&a, &b| d[a as usize].total_cmp(&d[b as usize]));
    let v = -field.v(idx[k] as usize);
    if v.is_finite() && v.length() < 1.0e4 {
        v
    } else {
        Vec2::ZERO
    }
}

/// One output pixel: colour, source depth of the chosen sample, residual.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Px {
    pub color: [f32; 3],
    pub depth: f32,
    pub residual: f32,
}

/// The heuristic warp of target position `p` (Sec. 3.3): seed, search, orbit fallback.
#[inline(always)]
pub(crate) fn heuristic_pixel(
    s: &ColorSampler<'_>,
    color: &[[f32; 3]],
    p: Vec2,
    params: &HeuristicParams,
    sp: &SearchParams,
) -> Px {
    let seed = match params.seed {
        Seed::Pixel => p,
        Seed::Upstream(k) => match s.fetch(p) {
            Some(m) => p - k * m.v,
            None => p,
        },
        Seed::Offset(d) => p + d,
    };
    // A seed outside the image starts at the nearest texel inside.
    let seed = s.clamp(seed);
    let rec = Recorder::new(s);
    if let Some(c) = fixed_point_search(&rec, p, &[seed], sp) {
        let last = rec.last().expect("a converged search sampled");
        // The next iterate `p - V(q)` is closer by a factor rho: the colour is read there.
        let q1 = p - last.v;
        return Px { color: s.color(color, q1), depth: last.depth, residual: (c.q + last.v - p).length() };
    }
    // Orbit around a disocclusion (Fig. 1e): the farthest iterate is the background.
    let mut best: Option<crate::sampler::Visit> = None;
    for v in rec.visits() {
        if best.is_none_or(|b| v.depth >= b.depth) {
            best = Some(v);
        }
    }
    match best {
        Some(b) => Px { color: s.color(color, b.q), depth: b.depth, residual: (b.q + b.v - p).length() },
        None => {
            // The seed left the image at once: the nearest source texel inwards.
            let q = s.clamp(seed);
            Px { color: s.color(color, q), depth: s.depth_near(q), residual: f32::INFINITY }
        }
    }
}

pub(crate) fn check_color(field: &Field<'_>, color: &Image<[f32; 3]>) -> Result<()> {
    if field.size() != color.size() {
        return Err(Error::invalid(format!(
            "colour warp: colour image is {}x{} but the warp field is {}x{}",
            color.width(),
            color.height(),
            field.size().0,
            field.size().1
        )));
    }
    Ok(())
}

/// The heuristic colour warp of `color` by `field` (seed 001 Sec. 3.3, 4) into a new output of
/// the source's size. Errors on invalid parameters or a size mismatch.
pub fn heuristic_warp(field: &Field<'_>, color: &Image<[f32; 3]>, params: &HeuristicParams) -> Result<ColorWarpOutput> {
    let mut out = ColorWarpOutput::empty();
    heuristic_warp_into(field, color, params, &mut out)?;
    Ok(out)
}

/// [`heuristic_warp`] into `out`, reusing its buffers when they have the right size (an
/// engine's steady state).
pub fn heuristic_warp_into(
    field: &Field<'_>,
    color: &Image<[f32; 3]>,
    params: &HeuristicParams,
    out: &mut ColorWarpOutput,
) -> Result<()> {
    params.validate()?;
    check_color(field, color)?;
    let (w, h) = field.size();
    out.resize(w, h, params.threshold);
    let s = ColorSampler::new(*field, Continuity::Range);
    let sp = params.search();
    let src = color.data();
    let wu = w as usize;
    out.color
        .data_mut()
        .par_chunks_mut(wu)
        .zip(out.depth.data_mut().par_chunks_mut(wu))
        .zip(out.residual.data_mut().par_chunks_mut(wu))
        .enumerate()
        .for_each(|(y, ((c, d), r))| {
            let py = y as f32 + 0.5;
            // The AVX2 lanes take the row while eight pixels remain, the portable path the rest.
            #[cfg(target_arch = "x86_64")]
            let x0 = if crate::lanes::simd_enabled() {
                // SAFETY: AVX2 is present (checked); the rows are the field's rows.
                unsafe { crate::lanes::avx2::heuristic_row(field, src, params, y, c, d, r) }
            } else {
                0
            };
            #[cfg(not(target_arch = "x86_64"))]
            let x0 = 0;
            for x in x0..wu {
                let px = heuristic_pixel(&s, src, Vec2::new(x as f32 + 0.5, py), params, &sp);
                c[x] = px.color;
                d[x] = px.depth;
                r[x] = px.residual;
            }
        });
    Ok(())
}
