//! zwarp-color: colour warping by fixed-point iteration (Bowles et al. 2012, "Iterative Image
//! Warping", seed 001) — the frame-generation stage of zwarp: predict a colour frame at a new
//! time or viewpoint from one already rendered, without drawing the scene again.
//!
//! - [`field`]: the warp fields of Sec. 3.1 (temporal `t M`, second-order `t M + t^2/2 A`,
//!   spatial eq. 4, combinations) as a per-frame [`WarpBasis`] evaluated at `(t, u, v)`.
//! - [`sampler`]: bilinear sampling on surfaces, nearest across discontinuities (Sec. 3.4,
//!   Fig. 4); the [`ColorSampler`] is a `zwarp_warp::sampling::MotionSource`, so every warp here
//!   runs the project's one fixed-point search.
//! - [`params`]: the heuristic warp's seed strategy, iterations and threshold.
//! - [`heuristic`]: the heuristic variant (Sec. 3.3, 4): one seed (pixel, fixed offset,
//!   upstream), 3 iterations, the orbit at disocclusions picks the background.
//! - [`robust`]: the robust variant (Sec. 3.4, Appendix A, Algorithm 1): convergence term
//!   `rho` from the finite-difference Jacobian, max-reductions, adaptive quad subdivision until
//!   no quad straddles `rho >= 1`, warped quads rasterised with a depth test.
//! - [`combine`]: two-frame interpolation (Sec. 6).
//! - [`baselines`]: repeat-the-last-frame, per-pixel forward mesh warp (Mark et al. 1997),
//!   reverse reprojection caching (Nehab et al. 2007), an FSR3-like forward scatter with a
//!   push-pull in-painting pyramid.
//! - [`floor`]: the streaming floor of a colour warp (ARCHITECTURE.md "The floor is the yardstick").
//! - `gpu` (feature `gpu`): the WGSL twins of the heuristic and robust warps on a
//!   `zwarp_gpu::GpuContext`.
//!
//! Conventions (ARCHITECTURE.md "Conventions", "Colour", "Motion"): colour is linear RGB `f32`;
//! depth is post-projection depth in `[0, 1]`, 1 = no surface (sky, a valid sample for colour:
//! it moves with the camera); pixel `(x, y)` samples at `(x + 0.5, y + 0.5)`, row 0 on top;
//! fields are in pixels, source -> target. Every warp returns a [`ColorWarpOutput`]: colour, the
//! chosen sample's source depth, and the per-pixel residual that says how far the result is from
//! a solution of eq. 1 (its confidence).

#![deny(missing_docs)]

pub mod baselines;
pub mod combine;
pub mod field;
pub mod floor;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod heuristic;
pub mod lanes;
pub mod params;
pub mod robust;
pub mod sampler;

pub use baselines::{mesh_warp, push_pull, repeat, reproject, scatter_warp, source_visibility};
pub use combine::{combine_interpolated, confidence_weights};
pub use field::{Field, FieldParams, Planes, Term, WarpBasis};
pub use heuristic::{fixed_offset, heuristic_warp, heuristic_warp_into};
pub use lanes::{set_simd, simd_enabled};
pub use params::{HeuristicParams, Seed};
pub use robust::{
    rho_cells, rho_cells_max, robust_warp, robust_warp_with, spectral_radius, HoleFill, Leaf, RobustParams,
    RobustStats, Subdivision,
};
pub use sampler::{ColorSampler, Continuity};

use zwarp_core::{Error, Image, Result};

/// The result of a colour warp (seed 001 eq. 1 solved per target pixel) with its per-pixel
/// confidence (ARCHITECTURE.md "Colour").
#[derive(Clone, Debug, PartialEq)]
pub struct ColorWarpOutput {
    /// Predicted linear RGB colour.
    pub color: Image<[f32; 3]>,
    /// Source depth of the sample each pixel shows (`[0, 1]`, 1 = sky): the order that
    /// resolved overlaps (Sec. 3.1, minimum depth); the target's depth for [`reproject`].
    pub depth: Image<f32>,
    /// `|q + V(q) - p|` in pixels for the sample shown (0 for an exact solution); `+inf` where
    /// no sample was found (border strips, baseline holes) and the pixel was in-painted.
    pub residual: Image<f32>,
    /// Convergence threshold of the warp: a pixel is converged where `residual < threshold`.
    pub threshold: f32,
}

impl ColorWarpOutput {
    /// An output with no pixels (buffers are sized by the warp that fills it).
    pub fn empty() -> Self {
        ColorWarpOutput {
            color: Image::new(0, 0, [0.0; 3]),
            depth: Image::new(0, 0, 1.0),
            residual: Image::new(0, 0, f32::INFINITY),
            threshold: 0.5,
        }
    }

    /// Makes the buffers `w x h` (reallocating only on a size change) and sets the threshold.
    pub(crate) fn resize(&mut self, w: u32, h: u32, threshold: f32) {
        if self.color.size() != (w, h) {
            self.color = Image::new(w, h, [0.0; 3]);
        }
        if self.depth.size() != (w, h) {
            self.depth = Image::new(w, h, 1.0);
        }
        if self.residual.size() != (w, h) {
            self.residual = Image::new(w, h, f32::INFINITY);
        }
        self.threshold = threshold;
    }

    /// `true` if pixel `(x, y)` holds a converged solution of eq. 1.
    pub fn converged(&self, x: u32, y: u32) -> bool {
        *self.residual.get(x, y) < self.threshold
    }

    /// Per-pixel converged mask.
    pub fn converged_mask(&self) -> Image<bool> {
        let t = self.threshold;
        self.residual.map(|&r| r < t)
    }

    /// Fraction of converged pixels (1 for an empty image).
    pub fn converged_fraction(&self) -> f64 {
        let n = self.residual.len();
        if n == 0 {
            return 1.0;
        }
        self.residual.data().iter().filter(|&&r| r < self.threshold).count() as f64 / n as f64
    }
}

/// The colour buffer of a rendered frame, or a one-line error naming `what` when the frame was
/// rendered without colour (e.g. `zwarp_raster::FrameOptions { color: false, .. }`).
pub fn require_color<'a>(color: Option<&'a Image<[f32; 3]>>, what: &str) -> Result<&'a Image<[f32; 3]>> {
    color.ok_or_else(|| Error::invalid(format!("{what} has no colour buffer (render it with colour on)")))
}

#[cfg(test)]
mod tests;
