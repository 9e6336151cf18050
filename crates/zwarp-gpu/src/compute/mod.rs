//! GPU compute kernels, each the WGSL twin of a CPU function (DESIGN.md "One kernel, many
//! callers": tests compare them on the same inputs).

mod motion;
mod pyramid;
mod warp;

pub use motion::{MotionInput, MotionKernel};
pub use pyramid::{pyramid_level_sizes, GpuMotionPyramid, PyramidKernel};
pub use warp::{GpuWarpLayer, GpuWarpOutput, WarpKernel, MAX_GPU_LAYERS};
