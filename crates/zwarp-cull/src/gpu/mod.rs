//! Occlusion culling on a wgpu device (feature `gpu`): WGSL twins of this crate's CPU functions,
//! each tested against its CPU twin on Mesa lavapipe (`tests/gpu_*.rs`).
//!
//! - [`MaxDepthKernel`]: max mipmap, N-buffer and Y-map (seed 000 Sec. 5.2), bit-identical to
//!   [`MaxMipmap`](crate::MaxMipmap), [`NBuffer`](crate::NBuffer) and [`YMap`](crate::YMap).
//! - [`CullKernel`]: VFC + screen-space AABB test per object into a visible list and indirect
//!   draw arguments ([`CullOutput`], drawn by `zwarp_gpu::Renderer::encode_depth_indirect`),
//!   the twin of [`cull_against_depth`](crate::cull_against_depth).
//! - [`GpuWoc`]: the whole WOC pipeline (seed 000 Sec. 5, thesis seed 002) on an engine's own
//!   device, textures and matrices, no CPU round trip; the twin of [`woc`](crate::woc()). Its
//!   motion and warp stages are `zwarp_warp::gpu`'s kernels.
//! - [`run_gpu_sequence`]: a culling method along a camera path on one device, the twin of
//!   [`run_sequence`](crate::run_sequence) (`zwarp cull --backend gpu`).

mod cull;
mod maxdepth;
mod sequence;
mod woc;

pub use cull::{CullKernel, CullObjects, CullOutput, CullParams, CullReadback, GpuCullClass};
pub use maxdepth::{GpuMaxDepth, MaxDepthKernel, MaxDepthLayout};
pub use sequence::{gpu_supports, run_gpu_sequence};
pub use woc::{rapid_flags, GpuPrevFrame, GpuWoc, GpuWocParams, WocStage};
