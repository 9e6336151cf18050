//! zwarp-warp: iterative depth warping (Lee, Kim, Eisemann, TOG 2018 — seed 000, Sec. 3) and
//! its forward-warping baselines (Sec. 4.1).
//!
//! Given the depth buffer(s) of a source view and their motion buffers (`zwarp_core::Motion`:
//! motion in pixels source -> target plus the point's depth in the target view), predict the
//! depth buffer of the target view by *backward* warping: for every target pixel `p`, search a
//! source position `q` with `q + v(q) = p` by fixed-point iteration `q_{i+1} = p - v(q_i)`
//! (Bowles et al. 2012, seed 001) started from N seeds placed in a tight search region derived
//! from a min-max motion mipmap (Sec. 3.3), over L peeled layers (Sec. 3.4).
//!
//! Conventions (ARCHITECTURE.md "Conventions", "Motion"): depth is post-projection depth in
//! `[0, 1]`, `1.0` = no surface; pixel `(x, y)` covers `[x, x+1) x [y, y+1)` with its sample at
//! the centre; motion vectors are in pixels. A warp writes the moved sample's **target** depth
//! (`Motion::depth`), never the source depth.
//!
//! Modules (one idea each):
//! - [`bounds`]: min-max motion mipmap, iterative bound tightening (Fig. 5), PCA-oriented bounds.
//! - [`sampling`]: how the search samples a layer's motion (adaptive bilinear / nearest, Bowles
//!   Fig. 4) and the interface of every source it searches.
//! - [`search`]: THE fixed-point search kernel (Fig. 3), shared by every backward warp.
//! - [`depth_warp`]: single- and multi-layer depth warping with cross-layer seeding (Fig. 6).
//! - [`holes`]: hole policies (far depth, dilation of Fig. 8, AWOC of Sec. 5.3).
//! - [`baselines`]: VFW and AFW forward warps (Sec. 4.1).
//! - [`synth`]: an analytic ray-cast scene (ground + boxes) producing peeled layers, used by
//!   tests and benchmarks.
//! - `gpu` (feature `gpu`): the WGSL twins of the motion field, the motion mipmap, the warp and
//!   the hole policies on a `zwarp_gpu::GpuContext`.

#![deny(missing_docs)]
pub mod baselines;
pub mod bounds;
pub mod depth_warp;
pub mod floor;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod gradient;
pub mod holes;
mod kernel;
mod prepare;
pub mod sampling;
pub mod search;
pub mod simd;
mod simd_warp;
pub mod stats;
pub mod synth;

pub use baselines::{afw, afw_layers, afw_layers_into, vfw, vfw_layers, vfw_layers_into, FORWARD_SUPPORT_EXPANSION};
pub use bounds::{clip_margin, Bound, BoundFrame, MotionPyramid, MotionScales, TightBound, CLIP_MARGIN};
pub use depth_warp::{
    predict_into, target_size, warp_depth, warp_pixels, warp_prepared, warp_prepared_into, PreparedLayer,
    SurfaceMotion, WarpLayer,
};
pub use holes::{dilate_holes, fill_holes, hole_fill, FillRule, HolePolicy, FILL_DIRECTIONS};
pub use sampling::{LayerSampler, MotionSource, Sample, SamplePlanes, Sampling};
pub use search::{
    fixed_point_search, fixed_point_search_closest, Approach, Candidate, CandidateChoice, SearchParams, SeedStrategy,
};

use zwarp_core::{Error, Image, Result};

/// Largest supported number of search seeds N per pixel and layer (seeds live in a fixed-size
/// stack buffer so the per-pixel kernel never allocates).
pub const MAX_SEEDS: u32 = 64;

/// Largest [`WarpParams::multisample`] (an 8 x 8 grid: 64 source samples per target pixel).
pub const MAX_MULTISAMPLE: u32 = 8;

/// Which search-region bound seeds are placed in (Sec. 3.3, Table 2/3).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum BoundKind {
    /// The global motion bound (top mipmap texel) for every pixel: no tightening.
    Global,
    /// Axis-aligned bound tightened per pixel with `bound_iterations` mipmap look-ups (Fig. 5).
    Tight,
    /// Tight bound in the PCA frame of ~64 sampled motion vectors (Sec. 3.3); per frame the
    /// axis-aligned (AAB) or the oriented (OB) frame is chosen, whichever global bound has the
    /// smaller area ("we can always use a tighter bound by selecting the one that has smaller
    /// area for every frame"). The paper's default for its quality figures.
    #[default]
    Oriented,
}

/// Per-pixel outcome of a warp.
#[repr(u8)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum PixelState {
    /// A fixed-point search converged: the depth is a warped sample.
    Converged = 0,
    /// No search converged; the hole policy filled the pixel with an approximation
    /// (dilation, Fig. 8, or AWOC, Sec. 5.3).
    Filled = 1,
    /// No search converged and the pixel holds the far depth `1.0` (conservative for culling).
    #[default]
    Hole = 2,
}

/// Where a converged output pixel came from (recorded when [`WarpParams::record_source`] is
/// set): the source position `q` (continuous pixel coordinates) and the layer index. Colour
/// warping uses it to fetch the colour at `q`.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct SourcePos {
    /// Converged source position (pixel coordinates of the source view).
    pub q: glam::Vec2,
    /// Index of the layer whose sample was chosen (`u32::MAX` if none).
    pub layer: u32,
}

/// The default of [`WarpParams::extra_iterations`]: with T = 3, a walk may take six samples
/// if each step at least halves (measured on a camera moving 0.5 m per frame along a wall
/// half a metre away, 960x540, N = 4: the walks that fail at T = 3 converge by the fifth).
pub const EXTRA_ITERATIONS: u32 = 3;

/// The most [`WarpParams::extra_iterations`] accepted.
pub const MAX_EXTRA_ITERATIONS: u32 = 64;

/// How much farther than a covering front surface (in linear depth, `WarpParams::cover_radius`)
/// a deeper layer's candidate must be to count as hidden behind it.
pub const COVER_DEPTH_RATIO: f32 = 1.1;

/// How many times N seeds a front layer gets when it searches again behind a deeper layer's
/// candidate that lies [`hidden_behind`] the far side of its failed walks: a disocclusion is
/// only accepted from a deeper layer once the front layers failed with this many seeds too
/// (seed 000 Sec. 3.4: a deeper layer fills what the front layers disocclude).
pub const RETRY_SEED_FACTOR: u32 = 4;

/// `true` if a candidate at target depth `z` lies behind a covering surface at depth `cover`
/// by more than [`COVER_DEPTH_RATIO`] in linear depth: for a perspective depth buffer `1 - z`
/// is inversely proportional to linear depth where the far plane is far beyond the point, so
/// the test needs no camera (for orthographic depth it is a margin on the distance to the far
/// plane).
#[inline(always)]
pub fn hidden_behind(z: f32, cover: f32) -> bool {
    (1.0 - z) * COVER_DEPTH_RATIO < 1.0 - cover
}

/// Parameters of the backward depth warp (seed 000 Sec. 3, names follow the paper).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WarpParams {
    /// N: search seeds per pixel and layer (1..=[`MAX_SEEDS`]). Fewer are used where the local
    /// bound is narrow (adaptive early exit, Sec. 3.3).
    pub n_seeds: u32,
    /// T: fixed-point iterations per seed (>= 1). Independent of `bound_iterations`.
    pub iterations: u32,
    /// Convergence threshold in pixels: a seed converged when `|q_{i+1} - q_i| < threshold`.
    pub threshold: f32,
    /// Which search-region bound seeds are drawn from.
    pub bound: BoundKind,
    /// Number of mipmap tightening steps (Fig. 5, "typically 2-4"). Independent of T.
    pub bound_iterations: u32,
    /// What to do with pixels where no search converged.
    pub holes: HolePolicy,
    /// How seeds are placed.
    pub seeding: SeedStrategy,
    /// How the motion buffer is sampled between texels.
    pub sampling: Sampling,
    /// Candidate choice among converged seeds (paper: minimal depth).
    pub choice: CandidateChoice,
    /// Cross-layer seeding (Fig. 6): when an iterate of layer k lands in an empty texel, borrow
    /// the sample of the nearest non-empty layer above (under [`Sampling::Adaptive`] only a
    /// bilinear one: a nearest sample sits on that layer's silhouette); a second empty landing
    /// fails the seed.
    /// Also seeds layer k+1 with layer k's converged position.
    pub cross_layer: bool,
    /// Record the converged source position per pixel in [`WarpOutput::source`].
    pub record_source: bool,
    /// Newton-accelerated fixed-point iteration (see [`search::fixed_point_search`]): converges
    /// under strong magnification where plain iteration needs many more than T iterations.
    pub accelerate: bool,
    /// Up to this many iterations beyond T for a walk whose steps still at least halve
    /// ([`search::EXTRA_STEP_RATIO`]): a surface magnified so strongly that Newton's steps from
    /// a distant seed need four or five iterations converges instead of leaving the pixel to a
    /// deeper layer or the hole fill. Default [`EXTRA_ITERATIONS`]; 0 runs exactly T (the
    /// paper's). The background hole fill's sky test walks exactly T.
    pub extra_iterations: u32,
    /// Per-axis factor applied to every motion fetch: the warp follows `motion_scale * v(q)`
    /// (component-wise) instead of `v(q)`, and every motion bound of Sec. 3.3 is scaled alike
    /// (min and max swap for a negative factor); the samples' target depths are unchanged.
    /// With an axis-aligned bound frame the result is exactly the warp of the explicitly scaled
    /// motion buffer, so one [`PreparedLayer`] (one mipmap) serves every multiple of a reference
    /// field: soft-shadow sample maps whose parallax is a per-axis multiple of one field, or
    /// frame interpolation by a fraction of the motion. A non-uniform scale (`x != y`) needs
    /// the identity (AAB) frame — use [`BoundKind::Tight`] — and is rejected otherwise; a
    /// uniform one works in any frame. Default `Vec2::ONE`.
    pub motion_scale: glam::Vec2,
    /// Multisampled source (seed 000 Sec. 7: "a potential improvement can be made using the
    /// multisampling of the depth buffers, yet at higher cost"): the source layers hold an
    /// ordered `m x m` grid of depth / motion samples per target pixel (rendered at `m` times
    /// the target's width and height, motion in source-sample units), and target pixel `(x, y)`
    /// is searched at the source position `m * (x + 0.5, y + 0.5)`. The output is
    /// `(w / m) x (h / m)`. A converged search then returns the sample nearest its fixed point
    /// on a grid `m` times finer, so silhouettes land within `1 / (2m)` of a target pixel
    /// instead of half a pixel. Odd m put a sample at every pixel centre (where the motion
    /// vanishes the warp returns exactly what a render samples); even m do not, and pick a sample
    /// up to `1 / (2m)` px off even there. The threshold and the bounds stay in source samples. Default 1
    /// (one sample per pixel: the source and target grids coincide). The WGSL twin
    /// (`gpu::WarpKernel`) supports every m.
    pub multisample: u32,
    /// Coverage radius of the multi-layer choice, in source samples (0 disables it). Sec. 3.4
    /// takes the nearest converged candidate over the layers, which assumes a layer that failed
    /// has no surface at `p`. Where a front layer's search failed although one of its walks had
    /// a smooth (bilinear) sample landing within this radius of `p` (the surface maps next to
    /// `p`: a steep, magnified part of it defeated the iteration), a deeper layer's candidate
    /// more than [`COVER_DEPTH_RATIO`] farther than that sample is one the front layer hides;
    /// the pixel is left to the hole policy instead, as with a single layer. In a disocclusion
    /// the front layer's walks end on nearest samples at the occluder's edge, far from `p`, or
    /// on the background next to the gap at the revealed surface's own depth, and deeper layers
    /// fill it as in the paper — except within the radius of an occluder's trailing edge, where
    /// the pixel goes to the hole policy too. The same radius decides the second test, made at
    /// the candidate's own source position: a front layer whose sample *there* lands within
    /// the radius of `p` and is nearer by [`COVER_DEPTH_RATIO`] still covers `p` (its search
    /// only missed, e.g. on a crack between the samples of two layers), so the candidate is
    /// hidden too; so is one where a front layer's sample one fixed-point step further
    /// (`q' = p - v(q)` with that front sample's motion), or a texel of the cell around `q'`
    /// (from its centre), lands within the radius and is nearer (a texel-wide sliver at the seam
    /// between two layers' views of one wall). Third, with the radius non-zero: a candidate
    /// behind a front sample at its source position is hidden where that front surface,
    /// continued with its motion Jacobian to the point that would land on `p`, may still be
    /// there — every front layer sees its depth or nearer at that point, i.e. it can run on
    /// behind an occluder of the source view (a wall behind a column). Default 3.5.
    pub cover_radius: f32,
    /// The last layer is a ground layer peeled alone, without the objects standing on it
    /// (seed 000 Sec. 3.4 and 4: "the last layer was peeled without foreground objects"). Its
    /// samples do not know what stands in front of them, so its candidate at a pixel where every
    /// layer searched before it failed is hidden (the pixel goes to the hole policy) when those
    /// failed walks sampled a surface it lies [`hidden_behind`]: that surface is the far side of
    /// the disocclusion, and the region it bounds is that surface continued more often than
    /// ground seen through every object (the candidate of a peeled layer knows its occluders and
    /// is kept). Default `false`; `zwarp eval` and `zwarp_shadows` set it when they peel the ground
    /// separately (and, for shadows, the ground layer is kept behind object layers).
    pub ground_layer: bool,
}

impl Default for WarpParams {
    /// N = 8, T = 3 (Table 3 uses T = 3; "2-3 iterations suffice"), threshold 0.5 px, oriented
    /// tight bound with up to 6 tightening steps (the paper's "two to three narrowing steps"
    /// leave most pixels of a 1080p frame with ~40 px motion with a multi-pixel bound; more
    /// steps cost four texel reads each, stop early at the fixed point, and halve the seeds
    /// actually searched on the synthetic city — see the crate README/report), far-depth
    /// holes (the conservative WOC setting), stratified seeds, adaptive bilinear sampling,
    /// minimal-depth candidates, cross-layer seeding on.
    fn default() -> Self {
        WarpParams {
            n_seeds: 8,
            iterations: 3,
            threshold: 0.5,
            bound: BoundKind::Oriented,
            bound_iterations: 6,
            holes: HolePolicy::FarDepth,
            seeding: SeedStrategy::Stratified,
            sampling: Sampling::Adaptive,
            choice: CandidateChoice::MinDepth,
            cross_layer: true,
            record_source: false,
            accelerate: true,
            extra_iterations: EXTRA_ITERATIONS,
            motion_scale: glam::Vec2::ONE,
            multisample: 1,
            cover_radius: 3.5,
            ground_layer: false,
        }
    }
}

impl WarpParams {
    /// The settings of the fixed-point search these parameters run (T, threshold, candidate
    /// choice, Newton steps), for callers of [`fixed_point_search`] such as the background fill.
    pub fn search(&self) -> SearchParams {
        SearchParams {
            iterations: self.iterations,
            extra_iterations: self.extra_iterations,
            threshold: self.threshold,
            choice: self.choice,
            accelerate: self.accelerate,
        }
    }

    /// Checks the parameters, returning a one-line [`Error::Invalid`] for bad values.
    pub fn validate(&self) -> Result<()> {
        if self.n_seeds == 0 || self.n_seeds > MAX_SEEDS {
            return Err(Error::invalid(format!("n_seeds (N) must be in 1..={MAX_SEEDS}, got {}", self.n_seeds)));
        }
        if self.iterations == 0 {
            return Err(Error::invalid("iterations (T) must be at least 1"));
        }
        if self.extra_iterations > MAX_EXTRA_ITERATIONS {
            return Err(Error::invalid(format!(
                "extra iterations must be at most {MAX_EXTRA_ITERATIONS}, got {}",
                self.extra_iterations
            )));
        }
        if !(self.threshold.is_finite() && self.threshold > 0.0) {
            return Err(Error::invalid(format!("convergence threshold must be > 0, got {}", self.threshold)));
        }
        if !(1..=MAX_MULTISAMPLE).contains(&self.multisample) {
            return Err(Error::invalid(format!(
                "multisample must be in 1..={MAX_MULTISAMPLE} source samples per pixel and axis, got {}",
                self.multisample
            )));
        }
        if !(self.cover_radius.is_finite() && self.cover_radius >= 0.0) {
            return Err(Error::invalid(format!("cover_radius must be finite and >= 0, got {}", self.cover_radius)));
        }
        if !self.motion_scale.is_finite() {
            return Err(Error::invalid(format!("motion_scale must be finite, got {}", self.motion_scale)));
        }
        if let SeedStrategy::Offset(d) = self.seeding {
            if !d.is_finite() {
                return Err(Error::invalid("seed offset must be finite"));
            }
        }
        if let HolePolicy::Dilate { radius } | HolePolicy::Background { radius } = self.holes {
            if radius == 0 || radius > 64 {
                return Err(Error::invalid(format!("dilation radius must be in 1..=64, got {radius}")));
            }
        }
        Ok(())
    }
}

/// Result of a depth warp: the predicted depth buffer of the target view and a per-pixel state.
#[derive(Clone, Debug, PartialEq)]
pub struct WarpOutput {
    /// Predicted depth (`[0, 1]`, `1.0` = hole/no surface under [`HolePolicy::FarDepth`]).
    pub depth: Image<f32>,
    /// Per-pixel outcome.
    pub state: Image<PixelState>,
    /// Converged source positions, when [`WarpParams::record_source`] was set.
    pub source: Option<Image<SourcePos>>,
    /// The [`PixelState::Converged`] pixels whose candidate comes from a layer after the first
    /// (row-major indices, ascending): what the deeper layers revealed where the front layers
    /// failed (seed 000 Sec. 3.4). The background protocol reads it
    /// ([`holes::fill_background`] step 0); empty for a single layer.
    pub revealed: Vec<u32>,
}

impl WarpOutput {
    /// An empty output (`0 x 0`), for callers that keep one across frames and hand it to the
    /// `*_into` warps.
    pub fn empty() -> Self {
        WarpOutput {
            depth: Image::new(0, 0, zwarp_core::EMPTY_DEPTH),
            state: Image::new(0, 0, PixelState::Hole),
            source: None,
            revealed: Vec::new(),
        }
    }

    /// Counts of `(converged, filled, hole)` pixels.
    pub fn counts(&self) -> (usize, usize, usize) {
        let mut c = [0usize; 3];
        for s in self.state.data() {
            c[*s as usize] += 1;
        }
        (c[0], c[1], c[2])
    }
    /// Fraction of pixels that are not [`PixelState::Converged`] (ARCHITECTURE.md "Evaluation
    /// protocol").
    pub fn non_converged_fraction(&self) -> f64 {
        let (c, _, _) = self.counts();
        1.0 - c as f64 / self.state.len().max(1) as f64
    }
}
