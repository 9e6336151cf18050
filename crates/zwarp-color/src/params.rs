//! The parameters of the heuristic colour warp (seed 001 Sec. 3.3): where each walk starts
//! ([`Seed`]), how many fixed-point iterations it takes and when it counts as converged
//! ([`HeuristicParams`]). Their own module because both builds of the warp read them: the
//! portable one ([`crate::heuristic`]) and the AVX2 lanes ([`crate::lanes`]).

use glam::Vec2;
use zwarp_core::{Error, Result};
use zwarp_warp::search::{CandidateChoice, SearchParams};

use crate::sampler::MAX_RECORDED;

/// Where the heuristic warp starts its iteration (seed 001 Sec. 3.3).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Seed {
    /// `x_0 = x_w`: the target pixel itself (Fig. 2b: misses overlapping foreground).
    Pixel,
    /// `x_0 = x_w - s V(x_w)`: upstream in the flow by `s` times the source motion at the
    /// target pixel ("an additional frame up-stream in the visual flow", temporal warps).
    Upstream(f32),
    /// `x_0 = x_w + delta`: a fixed offset in pixels (Fig. 2c, stereo: towards the side the
    /// foreground comes from).
    Offset(Vec2),
}

/// Parameters of the heuristic warp.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeuristicParams {
    /// Seed strategy.
    pub seed: Seed,
    /// Fixed-point iterations T (Sec. 4: 3, unrolled); at most 16.
    pub iterations: u32,
    /// Convergence threshold in pixels: a pixel is converged where its residual
    /// `|q + V(q) - p|` is below it (the output's confidence).
    pub threshold: f32,
}

impl Default for HeuristicParams {
    fn default() -> Self {
        HeuristicParams { seed: Seed::Upstream(1.0), iterations: 3, threshold: 0.5 }
    }
}

impl HeuristicParams {
    /// Errors on a zero or too large iteration count, a non-positive threshold or a non-finite
    /// seed parameter.
    pub fn validate(&self) -> Result<()> {
        if self.iterations == 0 || self.iterations as usize > MAX_RECORDED {
            return Err(Error::invalid(format!(
                "heuristic warp: iterations must be 1..={MAX_RECORDED}, got {}",
                self.iterations
            )));
        }
        if !(self.threshold.is_finite() && self.threshold > 0.0) {
            return Err(Error::invalid(format!("heuristic warp: threshold must be positive, got {}", self.threshold)));
        }
        let ok = match self.seed {
            Seed::Pixel => true,
            Seed::Upstream(s) => s.is_finite(),
            Seed::Offset(d) => d.is_finite(),
        };
        if !ok {
            return Err(Error::invalid(format!("heuristic warp: seed {:?} is not finite", self.seed)));
        }
        Ok(())
    }

    pub(crate) fn search(&self) -> SearchParams {
        SearchParams {
            iterations: self.iterations,
            // Seed 001 walks exactly T (its GPU twin too).
            extra_iterations: 0,
            threshold: self.threshold,
            choice: CandidateChoice::FirstConverged,
            accelerate: false,
        }
    }
}
