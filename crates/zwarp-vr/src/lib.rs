//! zwarp-vr: hybrid image warping for stereo and VR (Schollmeyer et al., "Efficient Hybrid
//! Image Warping for High Frame-Rate Stereoscopic Rendering", seed 003): predict the views of
//! both eyes from one rendered view instead of rendering the scene twice.
//!
//! - [`quadtree`]: the surface-estimation quadtree per 32x32 tile (Sec. 4.1): the
//!   epsilon-tolerant collinearity test (eq. 1-2), the cross-kernel, partial cross-kernel and
//!   irregular-grid reductions, 8 connectivity bits per node, merge types, accumulated
//!   estimation error.
//! - [`grid`]: the adaptive grid warp (Sec. 4.1.4, 5.1): cells from the quadtree, vertices
//!   shared where pixels are connected and separate across discontinuities, one combined warp
//!   matrix per view, a CPU rasteriser with a depth test, bilinear or the paper's adaptive
//!   texture filtering ([`ColorFilter`]); the baselines `points`, `quads` and Didyk et al.
//!   2010's disparity quadtree.
//! - [`holes`]: depth-aware low-pass pyramid hole filling with an epipolar border search
//!   (Sec. 5.2); baselines rubber sheets, stretch in-painting (Table 2) and push-pull.
//! - [`abuffer`]: the A-buffer of transparent fragments with its min-max quadtree (Sec. 4.2) and
//!   stackless ray casting with front-to-back compositing (Sec. 5.3).
//! - `gpu` (feature `gpu`): the grid warp's meshes drawn by the GPU's rasteriser on a
//!   `zwarp_gpu::GpuContext`.
//!
//! Conventions (zwarp-core): depth is post-projection depth in `[0, 1]` (1 = no surface, the
//! sky, warped as the far plane); pixel `(x, y)` is centred at `(x + 0.5, y + 0.5)`, row 0 on
//! top; colour is linear RGB. The warps here reproject with the cameras only (a static scene
//! between source and target, as in seed 003).

#![deny(missing_docs)]

pub mod abuffer;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod grid;
pub mod holes;
pub mod quadtree;

pub use abuffer::{ray_cast, ABuffer, Fragment, MinMaxTree, RayCastParams, MAX_FRAGMENTS};
pub use grid::{raster_where, warp, ColorFilter, Method, WarpMatrix, WarpOutput};
pub use holes::{fill_holes, HoleMethod};
pub use quadtree::{Collinearity, QuadTree, Reduction};

#[cfg(test)]
mod tests;
