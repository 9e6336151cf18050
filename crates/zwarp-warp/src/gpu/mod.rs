//! The warp on a wgpu device (feature `gpu`): WGSL twins of this crate's CPU functions and of
//! [`zwarp_core::motion_field`] (the warp's input), each tested against its CPU twin on Mesa
//! lavapipe (`tests/gpu_*.rs`).
//!
//! - [`MotionKernel`]: the motion field (seed 000 Sec. 3.1), twin of [`zwarp_core::motion_field`].
//! - [`PyramidKernel`]: the min-max motion mipmap (Sec. 3.3), twin of
//!   [`MotionPyramid::build_in_frame`](crate::MotionPyramid::build_in_frame).
//! - [`WarpKernel`]: the backward depth warp (Sec. 3, Fig. 3, 5, 6), twin of
//!   [`warp_depth`](crate::warp_depth).
//! - [`HoleFillKernel`]: hole filling as a post-pass (Fig. 8 dilation, background fill, Sec. 4's
//!   background protocol), twin of [`fill_holes`](crate::fill_holes) and
//!   [`holes::fill_background`](crate::holes::fill_background).
//! - [`encode_predict`]: the warp and its hole policy from GPU-resident layers, nothing read
//!   back, twin of [`predict_into`](crate::predict_into); [`predict`] runs it on CPU buffers.
//! - [`SourceKernel`]: an engine's depth and item images (textures or strided buffers,
//!   [`GpuImage`]) copied into the buffers the motion kernel and the warp read.
//!
//! They run on a [`zwarp_gpu::GpuContext`] and build on its renderer, read-back and shared
//! kernel set-up ([`zwarp_gpu::kernel`]).

mod holes;
mod motion;
mod pyramid;
mod source;
mod warp;

pub use holes::{encode_predict, predict, GpuBackgroundLimits, HoleFillKernel};
pub use motion::{MotionInput, MotionKernel};
pub use pyramid::{pyramid_level_sizes, GpuMotionPyramid, PyramidKernel};
pub use source::{GpuImage, SourceKernel};
pub use warp::{GpuPreparedWarp, GpuWarpLayer, GpuWarpOutput, WarpKernel, MAX_GPU_LAYERS};
