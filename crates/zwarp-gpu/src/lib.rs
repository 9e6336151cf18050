//! zwarp-gpu: the wgpu / WGSL backend of zwarp (ARCHITECTURE.md "Backends"), headless, tested on
//! Mesa lavapipe.
//!
//! - [`GpuContext`]: device + queue ([`GpuContext::new`] or an engine's own via
//!   [`GpuContext::from_device`]); [`list_adapters`] for `zwarp info`.
//! - [`Renderer`] + [`GpuScene`]: depth-only render (the paper's REF pass), depth + item +
//!   colour, depth peeling to L layers (seed 000 Sec. 3.4), depth-only draws from a culling
//!   pass's indirect arguments ([`IndirectDraws`]). Same conventions as the CPU rasterizer:
//!   depth in `[0, 1]` (1 = empty), pixel centres, row 0 at the top.
//! - [`GpuTimer`]: GPU timestamps where supported, else fenced wall clock.
//! - [`readback`]: textures and buffers back into [`zwarp_core::Image`]s and `Vec`s;
//!   [`kernel`]: the layouts and pipelines compute kernels share.
//!
//! The compute kernels sit in the crate of the stage they accelerate, each the WGSL twin of a
//! CPU function of that crate, behind its `gpu` feature: `zwarp_warp::gpu` (motion field,
//! min-max motion mipmap, backward depth warp, hole filling, `predict`), `zwarp_color::gpu`
//! (colour warps), `zwarp_cull::gpu` (max-depth structures, AABB cull with indirect draw
//! arguments for [`Renderer::encode_depth_indirect`], the WOC pipeline, culling sequences),
//! `zwarp_shadows::gpu` (soft shadows) and `zwarp_vr::gpu` (the grid warp drawn by the GPU's
//! rasteriser). Every WGSL file sits next to its host code and is loaded with `include_str!`.
//!
//! Backends: Vulkan/Metal/DX12 first (lavapipe through Vulkan on a GPU-less Linux box), GLES as
//! a last resort. Everything also runs on GLES (llvmpipe through EGL): depth is read back
//! with a compute copy (GLES cannot copy depth textures to buffers) and colour falls back to
//! half floats where 32-bit float targets are not renderable. Device errors while building
//! pipelines come back as `Error::Unavailable` instead of wgpu's default panic.
#![deny(missing_docs)]

pub mod context;
pub mod kernel;
pub mod readback;
pub mod render;
pub mod timer;

pub use context::{list_adapters, test_context, AdapterSummary, GpuContext};
pub use render::{
    DepthTarget, FrameOptions, GpuFrame, GpuScene, IndirectDraws, IndirectMode, LayerTargets, PeelOptions, Renderer,
    Shading, Umbra,
};
pub use timer::{GpuTimer, TimingMethod, TimingStats};
/// The wgpu version zwarp is built with (engines pass their own device of this version).
pub use wgpu;
