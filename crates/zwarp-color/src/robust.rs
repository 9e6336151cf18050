//! The robust colour warp (seed 001 Sec. 3.4, Fig. 5, Appendix A, Algorithm 1):
//!
//! 1. the convergence term `rho` per cell (the square between four texel centres): the
//!    spectral radius of the Jacobian of `G(x) = x_w - V(x)` from finite differences
//!    (Appendix A, eq. 11; evaluated at the cell's four corners, the largest kept) —
//!    [`rho_cells`], or its maximum over several fields for many reprojections (eq. 9,
//!    [`rho_cells_max`]);
//! 2. max-reductions of `rho` over power-of-two blocks of texels (a block's value covers every
//!    cell its footprint touches: the paper's "occasional over-subdivision" along borders);
//! 3. adaptive quad subdivision: tiles of `tile x tile` texels split until no quad straddles
//!    `rho >= 1`, down to single texels ([`Subdivision`]);
//! 4. every leaf quad warped to the bounding box of its corner texels' warped positions
//!    (expanded by a margin for the texel footprint and the pixel coverage) and rasterised with
//!    a depth test: each covered pixel starts the shared fixed-point search from the position
//!    interpolated in the quad, keeps the result only if it converged inside the quad's
//!    footprint and is nearer than what the pixel holds (ties: the earlier quad).
//!
//! Cells with `rho >= 1` are sampled nearest (Fig. 4: the signal is extrapolated into the
//! discontinuity). Pixels no quad covers (disocclusions) get the heuristic warp's search
//! (Sec. 3.3) and, where that does not converge either, its orbit in-painting (or the
//! push-pull pyramid, [`HoleFill`]). They are reported non-converged unless the heuristic
//! search converged.

use glam::Vec2;
use rayon::prelude::*;
use zwarp_core::{Error, Image, Result};
use zwarp_warp::search::{fixed_point_search, CandidateChoice, SearchParams};

use crate::field::Field;
use crate::heuristic::{check_color, heuristic_pixel};
use crate::params::HeuristicParams;
use crate::sampler::{ColorSampler, Continuity, Recorder};
use crate::ColorWarpOutput;

/// Largest tile side of the subdivision.
pub const MAX_TILE: u32 = 64;

/// Parameters of the robust warp.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RobustParams {
    /// Fixed-point iterations per rasterised pixel.
    pub iterations: u32,
    /// Convergence threshold in pixels.
    pub threshold: f32,
    /// Side of the initial coarse quads in texels (a power of two, 1..=[`MAX_TILE`]).
    pub tile: u32,
    /// Largest expansion of each warped quad's bounding box, in pixels per side: the box holds
    /// the warped footprint of the quad (half a texel beyond its corner texels' centres through
    /// the quad's Jacobian, at least half a pixel), capped at this (also taken whole by quads one
    /// texel wide or high, and by magnifying ones).
    pub margin: f32,
    /// Newton steps where the field is smooth (`SearchParams::accelerate`; on by default: plain
    /// iteration contracts only by `rho` per step, so a magnifying quad needs many iterations
    /// near its footprint's edge).
    pub accelerate: bool,
    /// The heuristic warp that fills the pixels no quad covers (its seed strategy matters).
    pub fallback: HeuristicParams,
    /// What the pixels that neither a quad nor the fallback search solved show.
    pub fill: HoleFill,
}

/// How the robust warp fills the pixels no converged search reached (disocclusions, strips
/// off the source's border).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum HoleFill {
    /// The fallback heuristic's orbit in-painting (seed 001 Sec. 3.3: the farthest iterate, a
    /// clone of the background); on the procedural scenes and Sponza it is 0.5-2 dB closer to
    /// the reference at disocclusions than the push-pull fill.
    #[default]
    Orbit,
    /// The push-pull pyramid over every converged pixel ([`crate::push_pull`], the in-painting
    /// of the baselines).
    PushPull,
}

impl Default for RobustParams {
    fn default() -> Self {
        RobustParams {
            iterations: 4,
            threshold: 0.5,
            tile: 16,
            margin: 1.0,
            accelerate: true,
            fallback: HeuristicParams::default(),
            fill: HoleFill::Orbit,
        }
    }
}

impl RobustParams {
    /// Errors on invalid values.
    pub fn validate(&self) -> Result<()> {
        if self.iterations == 0 || self.iterations > 64 {
            return Err(Error::invalid(format!("robust warp: iterations must be 1..=64, got {}", self.iterations)));
        }
        if !(self.threshold.is_finite() && self.threshold > 0.0) {
            return Err(Error::invalid(format!("robust warp: threshold must be positive, got {}", self.threshold)));
        }
        if !self.tile.is_power_of_two() || self.tile > MAX_TILE {
            return Err(Error::invalid(format!(
                "robust warp: tile must be a power of two up to {MAX_TILE}, got {}",
                self.tile
            )));
        }
        if !(self.margin.is_finite() && (0.0..=8.0).contains(&self.margin)) {
            return Err(Error::invalid(format!("robust warp: margin must be in [0, 8], got {}", self.margin)));
        }
        self.fallback.validate()
    }

    fn search(&self) -> SearchParams {
        SearchParams {
            iterations: self.iterations,
            // Seed 001 walks exactly T (its GPU twin too).
            extra_iterations: 0,
            threshold: self.threshold,
            choice: CandidateChoice::FirstConverged,
            accelerate: self.accelerate,
        }
    }
}

/// Spectral radius `max |lambda_i|` of the 2x2 matrix with columns `dx`, `dy` (eq. 11).
#[inline]
pub fn spectral_radius(dx: Vec2, dy: Vec2) -> f32 {
    let (a, b, c, d) = (dx.x, dy.x, dx.y, dy.y);
    let tr = a + d;
    let det = a * d - b * c;
    let disc = 0.25 * tr * tr - det;
    if disc >= 0.0 {
        0.5 * tr.abs() + disc.sqrt()
    } else {
        det.max(0.0).sqrt()
    }
}

/// The convergence term `rho` of every cell of `field` (Appendix A): cell `(cx, cy)` spans the
/// texel centres `(cx, cy)..(cx + 1, cy + 1)`; its value is the largest spectral radius of the
/// finite-difference Jacobian at its four corners (`G' = -V'`, same radius). `(w - 1) x (h - 1)`
/// values, row-major (none for a one-texel-wide image).
pub fn rho_cells(field: &Field<'_>) -> Vec<f32> {
    let (w, h) = field.size();
    if w < 2 || h < 2 {
        return Vec::new();
    }
    let (cw, ch) = ((w - 1) as usize, (h - 1) as usize);
    let wu = w as usize;
    let mut out = vec![0.0f32; cw * ch];
    // The field on texel row y (x components, then y components), term by term in the order of
    // Field::v (the same sums, so the same values), as plain slice loops the compiler vectorises.
    let fill = |y: usize, o: &mut [f32]| {
        let (ox, oy) = o.split_at_mut(wu);
        ox.fill(0.0);
        oy.fill(0.0);
        for t in field.terms() {
            for (o, &v) in ox.iter_mut().zip(&t.x[y * wu..(y + 1) * wu]) {
                *o += t.scale.x * v;
            }
            for (o, &v) in oy.iter_mut().zip(&t.y[y * wu..(y + 1) * wu]) {
                *o += t.scale.y * v;
            }
        }
    };
    // Bands of cell rows: each texel row is evaluated once per band, not once per cell row.
    out.par_chunks_mut(cw * RHO_BAND).enumerate().for_each(|(b, band)| {
        let (mut top, mut bottom) = (vec![0.0f32; 2 * wu], vec![0.0f32; 2 * wu]);
        fill(b * RHO_BAND, &mut top);
        for (r, row) in band.chunks_mut(cw).enumerate() {
            fill(b * RHO_BAND + r + 1, &mut bottom);
            let (ax, ay) = top.split_at(wu);
            let (bx, by) = bottom.split_at(wu);
            rho_row(ax, ay, bx, by, row);
            std::mem::swap(&mut top, &mut bottom);
        }
    });
    out
}

/// Cell rows per task of [`rho_cells`].
const RHO_BAND: usize = 16;

/// The `rho` of one row of cells from the field on its two texel rows (`a`: top, `b`: bottom,
/// `row.len() + 1` values each).
fn rho_row(ax: &[f32], ay: &[f32], bx: &[f32], by: &[f32], row: &mut [f32]) {
    let mut cx0 = 0;
    #[cfg(target_arch = "x86_64")]
    if crate::lanes::simd_enabled() {
        // SAFETY: AVX2 checked; rows hold w = cw + 1 values.
        cx0 = unsafe { crate::lanes::avx2::rho_row(ax, ay, bx, by, row) };
    }
    for (cx, o) in row.iter_mut().enumerate().skip(cx0) {
        let va = Vec2::new(ax[cx], ay[cx]);
        let vb = Vec2::new(ax[cx + 1], ay[cx + 1]);
        let vc = Vec2::new(bx[cx], by[cx]);
        let vd = Vec2::new(bx[cx + 1], by[cx + 1]);
        let (dxt, dxb, dyl, dyr) = (vb - va, vd - vc, vc - va, vd - vb);
        *o = spectral_radius(dxt, dyl)
            .max(spectral_radius(dxt, dyr))
            .max(spectral_radius(dxb, dyl))
            .max(spectral_radius(dxb, dyr));
    }
}

/// `max` of [`rho_cells`] over several fields of one source (eq. 9: `rho_max = max_{t,u,v} rho`,
/// one subdivision for many reprojections; pass the fields at the corners of the parameter
/// ranges). Errors on an empty list or fields of different sizes.
pub fn rho_cells_max(fields: &[Field<'_>]) -> Result<Vec<f32>> {
    let first = fields.first().ok_or_else(|| Error::invalid("rho_cells_max: no fields"))?;
    if fields.iter().any(|f| f.size() != first.size()) {
        return Err(Error::invalid("rho_cells_max: fields differ in size"));
    }
    let mut acc = rho_cells(first);
    for f in &fields[1..] {
        let r = rho_cells(f);
        acc.par_iter_mut().zip(&r).for_each(|(a, b)| *a = a.max(*b));
    }
    Ok(acc)
}

/// A leaf quad of the subdivision: the source texels `[x0, x1) x [y0, y1)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Leaf {
    /// First texel column.
    pub x0: u32,
    /// First texel row.
    pub y0: u32,
    /// One past the last column.
    pub x1: u32,
    /// One past the last row.
    pub y1: u32,
}

/// The adaptive quad subdivision of a source image (seed 001 Sec. 3.4 "Adaptive
/// Subdivision", Algorithm 1 lines 2-4): the cells' `rho`, their max-reductions and the leaf
/// quads in a fixed order (tiles row-major, then top-left, top-right, bottom-left,
/// bottom-right). Built once, it serves every reprojection whose `rho` it bounds (Sec. 4).
#[derive(Clone, Debug)]
pub struct Subdivision {
    width: u32,
    height: u32,
    tile: u32,
    rho: Vec<f32>,
    leaves: Vec<Leaf>,
}

impl Subdivision {
    /// Subdivides a `width x height` source with cell terms `rho` (from [`rho_cells`] or
    /// [`rho_cells_max`]) into tiles of `tile` texels. Errors on a size mismatch or a bad tile.
    pub fn new(width: u32, height: u32, rho: Vec<f32>, tile: u32) -> Result<Self> {
        if width == 0 || height == 0 {
            return Err(Error::invalid(format!("subdivision: zero-size image {width}x{height}")));
        }
        if rho.len() != (width.saturating_sub(1) * height.saturating_sub(1)) as usize {
            return Err(Error::invalid("subdivision: rho plane does not match the image size"));
        }
        if !tile.is_power_of_two() || tile > MAX_TILE {
            return Err(Error::invalid(format!(
                "subdivision: tile must be a power of two up to {MAX_TILE}, got {tile}"
            )));
        }
        let (w, h) = (width as usize, height as usize);
        // Level 0: per texel, the max over the (up to four) cells its footprint touches.
        let (cw, ch) = (w.saturating_sub(1), h.saturating_sub(1));
        let mut level: Vec<f32> = if cw == 0 || ch == 0 {
            vec![f32::INFINITY; w * h]
        } else {
            // Per texel row: the cell rows above and below (clamped) maxed per column, then
            // each texel takes the max of the two columns of cells beside it (clamped).
            let mut l0 = vec![0.0f32; w * h];
            l0.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
                let a = &rho[y.saturating_sub(1).min(ch - 1) * cw..][..cw];
                let b = &rho[y.min(ch - 1) * cw..][..cw];
                for ((o, a), b) in out[1..].iter_mut().zip(a).zip(b) {
                    *o = a.max(*b);
                }
                out[0] = out[1];
                for x in 1..cw {
                    out[x] = out[x].max(out[x + 1]);
                }
            });
            l0
        };
        let mut levels: Vec<Vec<f32>> = Vec::new();
        let (mut lw, mut lh) = (w, h);
        let steps = tile.trailing_zeros();
        for _ in 0..steps {
            let (nw, nh) = (lw.div_ceil(2), lh.div_ceil(2));
            let prev = &level;
            let mut next = vec![0.0f32; nw * nh];
            next.par_chunks_mut(nw).enumerate().for_each(|(ny, out)| {
                // The 2x2 block's max; the last row and column may be one texel thick.
                let r0 = &prev[2 * ny * lw..][..lw];
                let r1 = if 2 * ny + 1 < lh { &prev[(2 * ny + 1) * lw..][..lw] } else { r0 };
                let full = lw / 2;
                for ((o, a), b) in out[..full].iter_mut().zip(r0.chunks_exact(2)).zip(r1.chunks_exact(2)) {
                    *o = a[0].max(a[1]).max(b[0]).max(b[1]);
                }
                if lw % 2 == 1 {
                    out[full] = r0[lw - 1].max(r1[lw - 1]);
                }
            });
            levels.push(std::mem::replace(&mut level, next));
            (lw, lh) = (nw, nh);
        }
        levels.push(level);
        let widths: Vec<usize> = (0..=steps).map(|l| w.div_ceil(1 << l)).collect();
        let (tx, ty) = (width.div_ceil(tile), height.div_ceil(tile));
        let per_tile: Vec<Vec<Leaf>> = (0..tx * ty)
            .into_par_iter()
            .map(|t| {
                let mut leaves = Vec::new();
                let mut stack = vec![(steps, (t % tx) * tile, (t / tx) * tile)];
                while let Some((l, x0, y0)) = stack.pop() {
                    let size = 1u32 << l;
                    let m = levels[l as usize][(y0 >> l) as usize * widths[l as usize] + (x0 >> l) as usize];
                    if l == 0 || m < 1.0 {
                        leaves.push(Leaf { x0, y0, x1: (x0 + size).min(width), y1: (y0 + size).min(height) });
                        continue;
                    }
                    let half = size / 2;
                    // Pushed in reverse: popped top-left, top-right, bottom-left, bottom-right.
                    for (dx, dy) in [(half, half), (0, half), (half, 0), (0, 0)] {
                        let (cx, cy) = (x0 + dx, y0 + dy);
                        if cx < width && cy < height {
                            stack.push((l - 1, cx, cy));
                        }
                    }
                }
                leaves
            })
            .collect();
        Ok(Subdivision { width, height, tile, rho, leaves: per_tile.into_iter().flatten().collect() })
    }

    /// The subdivision of one field ([`rho_cells`]).
    pub fn of_field(field: &Field<'_>, tile: u32) -> Result<Self> {
        let (w, h) = field.size();
        Self::new(w, h, rho_cells(field), tile)
    }

    /// The subdivision bounding several fields of one source (eq. 9, [`rho_cells_max`]).
    pub fn of_fields(fields: &[Field<'_>], tile: u32) -> Result<Self> {
        let first = fields.first().ok_or_else(|| Error::invalid("subdivision: no fields"))?;
        let (w, h) = first.size();
        Self::new(w, h, rho_cells_max(fields)?, tile)
    }

    /// Source size.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }
    /// Initial quad side.
    pub fn tile(&self) -> u32 {
        self.tile
    }
    /// The cells' convergence terms.
    pub fn rho(&self) -> &[f32] {
        &self.rho
    }
    /// The leaf quads.
    pub fn leaves(&self) -> &[Leaf] {
        &self.leaves
    }
}

/// What one robust warp did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RobustStats {
    /// Leaf quads rasterised.
    pub quads: usize,
    /// Pixel searches run by the quads (the rasterised area).
    pub searches: u64,
    /// Pixels no quad covered (filled by the heuristic in-painting).
    pub holes: u64,
}

/// A leaf warped to the target: pixel range and the linear map from target to source used
/// for the interpolated starting point.
#[derive(Clone, Copy, Debug)]
struct Warped {
    px0: i32,
    py0: i32,
    px1: i32,
    py1: i32,
    dst_lo: Vec2,
    dst_ext: Vec2,
    src_lo: Vec2,
    src_ext: Vec2,
}

/// The expansion (pixels per side, per axis) of a leaf's warped box that holds the warped
/// footprint of its corner texels: half a texel beyond their centres, mapped by the quad's
/// Jacobian `I + DV`, whose x half-extent is at most `0.5 + (|dVx/dx| + |dVx/dy|) / 2` (triangle
/// inequality); `DV` is estimated from the corners' warped positions `warped` (`[x0 y0, x1 y0,
/// x0 y1, x1 y1]`) over the quad's texel extent `ext`, the larger of its two edges. Capped at
/// `cap` (the footprint plus the convergence threshold of a translating quad), which quads one
/// texel wide or high (no difference to estimate from) take whole. The pixels this leaves out
/// of a smooth quad's box could only take an approximate solution from it (residual at least
/// their distance to its footprint's image); a neighbouring quad or the fallback search covers
/// them.
pub(crate) fn footprint_margin(warped: [Vec2; 4], ext: Vec2, cap: f32) -> Vec2 {
    if ext.x < 1.0 || ext.y < 1.0 {
        return Vec2::splat(cap);
    }
    let [p00, p10, p01, p11] = warped;
    let dx = ((p10 - p00) / ext.x - Vec2::X).abs().max(((p11 - p01) / ext.x - Vec2::X).abs());
    let dy = ((p01 - p00) / ext.y - Vec2::Y).abs().max(((p11 - p10) / ext.y - Vec2::Y).abs());
    (Vec2::splat(0.5) + 0.5 * (dx + dy)).min(Vec2::splat(cap))
}

fn warp_leaf(field: &Field<'_>, leaf: &Leaf, margin: f32, size: (u32, u32)) -> Warped {
    let w = size.0 as usize;
    let corners = [(leaf.x0, leaf.y0), (leaf.x1 - 1, leaf.y0), (leaf.x0, leaf.y1 - 1), (leaf.x1 - 1, leaf.y1 - 1)];
    let warped = corners.map(|(x, y)| Vec2::new(x as f32 + 0.5, y as f32 + 0.5) + field.v(y as usize * w + x as usize));
    let lo = warped.into_iter().fold(Vec2::splat(f32::INFINITY), Vec2::min);
    let hi = warped.into_iter().fold(Vec2::splat(f32::NEG_INFINITY), Vec2::max);
    let src_lo = Vec2::new(leaf.x0 as f32 + 0.5, leaf.y0 as f32 + 0.5);
    let src_ext = Vec2::new((leaf.x1 - leaf.x0 - 1) as f32, (leaf.y1 - leaf.y0 - 1) as f32);
    let m = footprint_margin(warped, src_ext, margin);
    let (elo, ehi) = (lo - m, hi + m);
    // Pixel centres x + 0.5 in [elo, ehi]; far-off quads (behind the eye: 1e9) are empty.
    let clampi = |v: f32, m: u32| v.clamp(-1.0, m as f32 + 1.0) as i32;
    Warped {
        px0: clampi(zwarp_core::round::ceil(elo.x - 0.5), size.0).max(0),
        py0: clampi(zwarp_core::round::ceil(elo.y - 0.5), size.1).max(0),
        px1: (clampi(zwarp_core::round::floor(ehi.x - 0.5), size.0) + 1).min(size.0 as i32),
        py1: (clampi(zwarp_core::round::floor(ehi.y - 0.5), size.1) + 1).min(size.1 as i32),
        dst_lo: lo,
        dst_ext: hi - lo,
        src_lo,
        src_ext,
    }
}

impl Warped {
    /// The starting point for target position `p`: its relative position in the warped box
    /// of the corner texels mapped linearly into their source box (seed 001 Fig. 5b,
    /// "interpolating the starting point x_0 from the source image locations of the quad
    /// vertices"), extended past the corner texels and clamped to the quad's footprint.
    #[inline(always)]
    fn seed(&self, p: Vec2) -> Vec2 {
        let rel = Vec2::new(
            if self.dst_ext.x > 1e-6 { (p.x - self.dst_lo.x) / self.dst_ext.x } else { 0.5 },
            if self.dst_ext.y > 1e-6 { (p.y - self.dst_lo.y) / self.dst_ext.y } else { 0.5 },
        );
        let s = self.src_lo + rel * self.src_ext;
        s.clamp(self.src_lo - Vec2::splat(0.5), self.src_lo + self.src_ext + Vec2::splat(0.499))
    }
}

/// Target rows per raster band (each band is one task; its quads are processed in order).
const BAND: usize = 16;

/// The robust colour warp of `color` by `field` (seed 001 Sec. 3.4): subdivision of this
/// field, then [`robust_warp_with`].
pub fn robust_warp(
    field: &Field<'_>,
    color: &Image<[f32; 3]>,
    params: &RobustParams,
) -> Result<(ColorWarpOutput, RobustStats)> {
    params.validate()?;
    let sub = Subdivision::of_field(field, params.tile)?;
    let mut out = ColorWarpOutput::empty();
    let stats = robust_warp_with(&sub, field, color, params, &mut out)?;
    Ok((out, stats))
}

/// The robust warp with a given [`Subdivision`] (built for this field, or bounding several:
/// Sec. 4's "quad subdivision factored out as a pre-process" for many reprojections) into
/// `out`. Sampling decisions use the subdivision's `rho`.
pub fn robust_warp_with(
    sub: &Subdivision,
    field: &Field<'_>,
    color: &Image<[f32; 3]>,
    params: &RobustParams,
    out: &mut ColorWarpOutput,
) -> Result<RobustStats> {
    params.validate()?;
    check_color(field, color)?;
    if sub.size() != field.size() {
        return Err(Error::invalid("robust warp: subdivision and field differ in size"));
    }
    let (w, h) = field.size();
    out.resize(w, h, params.threshold);
    let s = ColorSampler::new(*field, Continuity::Rho(&sub.rho));
    let sp = params.search();
    let leaves = sub.leaves();
    let warped: Vec<Warped> = leaves.par_iter().map(|l| warp_leaf(field, l, params.margin, (w, h))).collect();
    // Bin the quads into row bands (counting sort, quad order kept).
    let bands = (h as usize).div_ceil(BAND);
    let mut counts = vec![0u32; bands + 1];
    for q in &warped {
        if q.px0 < q.px1 && q.py0 < q.py1 {
            for b in q.py0 as usize / BAND..=(q.py1 as usize - 1) / BAND {
                counts[b + 1] += 1;
            }
        }
    }
    for b in 0..bands {
        counts[b + 1] += counts[b];
    }
    let mut fill = counts.clone();
    let mut binned = vec![0u32; counts[bands] as usize];
    for (i, q) in warped.iter().enumerate() {
        if q.px0 < q.px1 && q.py0 < q.py1 {
            for b in q.py0 as usize / BAND..=(q.py1 as usize - 1) / BAND {
                binned[fill[b] as usize] = i as u32;
                fill[b] += 1;
            }
        }
    }
    let src = color.data();
    let wu = w as usize;
    let fallback = params.fallback;
    let fsp = fallback.search();
    let lanes = crate::lanes::simd_enabled() && w >= 2 && h >= 2;
    let per_band: Vec<(u64, u64)> = out
        .color
        .data_mut()
        .par_chunks_mut(BAND * wu)
        .zip(out.depth.data_mut().par_chunks_mut(BAND * wu))
        .zip(out.residual.data_mut().par_chunks_mut(BAND * wu))
        .enumerate()
        .map(|(b, ((cb, db), rb))| {
            // Colour and residual are written wherever the depth is (a hit or the hole pass).
            db.fill(f32::INFINITY);
            let (y0, y1) = ((b * BAND) as i32, (b * BAND + cb.len() / wu) as i32);
            let mut searches = 0u64;
            for &qi in &binned[counts[b] as usize..counts[b + 1] as usize] {
                let (leaf, q) = (&leaves[qi as usize], &warped[qi as usize]);
                let (fx0, fy0, fx1, fy1) = (leaf.x0 as f32, leaf.y0 as f32, leaf.x1 as f32, leaf.y1 as f32);
                #[cfg(target_arch = "x86_64")]
                if lanes {
                    let quad = crate::lanes::avx2::Quad {
                        dst_lo: q.dst_lo.to_array(),
                        dst_ext: q.dst_ext.to_array(),
                        src_lo: q.src_lo.to_array(),
                        src_ext: q.src_ext.to_array(),
                        foot: [fx0, fx1, fy0, fy1],
                    };
                    let (row0, row1) = (q.py0.max(y0), q.py1.min(y1));
                    searches += (row1 - row0).max(0) as u64 * (q.px1 - q.px0) as u64;
                    // SAFETY: AVX2 checked; the field has w, h >= 2 and rho its cells.
                    unsafe {
                        crate::lanes::avx2::robust_rows(
                            field,
                            &sub.rho,
                            src,
                            &quad,
                            (q.px0, q.px1, row0, row1),
                            params.iterations,
                            params.threshold,
                            params.accelerate,
                            crate::lanes::avx2::BandOut {
                                depth: &mut *db,
                                color: &mut *cb,
                                residual: &mut *rb,
                                width: wu,
                                y0,
                            },
                        )
                    };
                    continue;
                }
                for py in q.py0.max(y0)..q.py1.min(y1) {
                    let row = (py - y0) as usize * wu;
                    for px in q.px0..q.px1 {
                        let p = Vec2::new(px as f32 + 0.5, py as f32 + 0.5);
                        searches += 1;
                        let rec = Recorder::new(&s);
                        let Some(c) = fixed_point_search(&rec, p, &[q.seed(p)], &sp) else { continue };
                        // Inside this quad's footprint only: elsewhere another quad owns it.
                        if !((c.q.x >= fx0) & (c.q.x < fx1) & (c.q.y >= fy0) & (c.q.y < fy1)) {
                            continue;
                        }
                        let last = rec.last().expect("a converged search sampled");
                        let i = row + px as usize;
                        if last.depth < db[i] {
                            db[i] = last.depth;
                            cb[i] = s.color(src, p - last.v);
                            rb[i] = (c.q + last.v - p).length();
                        }
                    }
                }
            }
            // Disocclusions: the heuristic's orbit in-painting (Sec. 3.3).
            let mut holes = 0u64;
            for (j, d) in db.iter_mut().enumerate() {
                if *d == f32::INFINITY {
                    holes += 1;
                    let p = Vec2::new((j % wu) as f32 + 0.5, (y0 as usize + j / wu) as f32 + 0.5);
                    let px = heuristic_pixel(&s, src, p, &fallback, &fsp);
                    cb[j] = px.color;
                    *d = px.depth;
                    rb[j] = px.residual;
                }
            }
            (searches, holes)
        })
        .collect();
    let (searches, holes) = per_band.iter().fold((0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    if params.fill == HoleFill::PushPull && holes > 0 {
        let valid = out.converged_mask();
        crate::push_pull(&mut out.color, &valid)?;
    }
    Ok(RobustStats { quads: leaves.len(), searches, holes })
}
