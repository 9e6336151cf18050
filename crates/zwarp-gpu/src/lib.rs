//! zwarp-gpu: the wgpu / WGSL backend of zwarp (ARCHITECTURE.md "Backends"), headless, tested on
//! Mesa lavapipe.
//!
//! - [`GpuContext`]: device + queue ([`GpuContext::new`] or an engine's own via
//!   [`GpuContext::from_device`]); [`list_adapters`] for `zwarp info`.
//! - [`Renderer`] + [`GpuScene`]: depth-only render (the paper's REF pass), depth + item +
//!   colour, depth peeling to L layers (seed 000 Sec. 3.4). Same conventions as the CPU
//!   rasterizer: depth in `[0, 1]` (1 = empty), pixel centres, row 0 at the top.
//! - [`MotionKernel`]: the WGSL twin of [`zwarp_core::motion_field`] (seed 000 Sec. 3.1).
//! - [`PyramidKernel`]: the min-max motion mipmap (seed 000 Sec. 3.3) on the GPU.
//! - [`WarpKernel`]: the backward depth warp (seed 000 Sec. 3, Fig. 3, 5, 6), the twin of
//!   `zwarp_warp::warp_depth` with axis-aligned bounds.
//! - [`HoleFillKernel`]: hole filling as a post-pass (Fig. 8 dilation, background fill), the
//!   twin of `zwarp_warp::fill_holes`.
//! - [`ColorWarpKernel`]: the colour warps of seed 001 (heuristic Sec. 3.3, robust Sec. 3.4),
//!   twins of `zwarp_color::{heuristic_warp, robust_warp}`.
//! - [`MaxDepthKernel`]: max mipmap, N-buffer and Y-map (seed 000 Sec. 5.2), bit-identical to
//!   `zwarp_cull::{MaxMipmap, NBuffer, YMap}`.
//! - [`CullKernel`]: VFC + screen-space AABB test per object into a visible list and indirect
//!   draw arguments ([`Renderer::encode_depth_indirect`] draws them), the twin of
//!   `zwarp_cull::cull_against_depth`.
//! - [`GpuWoc`]: the whole WOC pipeline (seed 000 Sec. 5, thesis seed 002) on an engine's own
//!   device, textures and matrices, no CPU round trip; the twin of `zwarp_cull::woc`.
//! - [`GpuShadows`]: soft shadows (seed 000 Sec. 6) — reference and zwarp sample maps with the
//!   visibility accumulated on the GPU, the twin of `zwarp_shadows::run_shadows`.
//! - [`GridWarpKernel`]: seed 003's adaptive grid warp (and its quads / Didyk / points
//!   baselines) drawn by the GPU's rasteriser, the twin of `zwarp_vr::grid::raster`.
//! - [`run_gpu_sequence`]: a culling method along a camera path on one device, the twin of
//!   `zwarp_cull::run_sequence` (`zwarp cull --backend gpu`).
//! - [`GpuTimer`]: GPU timestamps where supported, else fenced wall clock.
//!
//! Every WGSL file sits next to its host code and is loaded with `include_str!`.
//!
//! Backends: Vulkan/Metal/DX12 first (lavapipe through Vulkan on a GPU-less Linux box), GLES as
//! a last resort. Everything also runs on GLES (llvmpipe through EGL): depth is read back
//! with a compute copy (GLES cannot copy depth textures to buffers) and colour falls back to
//! half floats where 32-bit float targets are not renderable. Device errors while building
//! pipelines come back as `Error::Unavailable` instead of wgpu's default panic.
#![deny(missing_docs)]

pub mod compute;
pub mod context;
mod readback;
pub mod render;
pub mod sequence;
pub mod shadows;
pub mod timer;

pub use compute::{
    predict, rapid_flags, ColorWarpKernel, CullKernel, CullObjects, CullOutput, CullParams, CullReadback, GpuCullClass,
    GpuMaxDepth, GpuMotionPyramid, GpuPreparedWarp, GpuPrevFrame, GpuWarpLayer, GpuWarpOutput, GpuWoc, GpuWocParams,
    HoleFillKernel, MaxDepthKernel, MaxDepthLayout, MotionInput, MotionKernel, PyramidKernel, WarpKernel, WocStage,
    MAX_GPU_LAYERS,
};
pub use context::{list_adapters, test_context, AdapterSummary, GpuContext};
pub use render::{
    DepthTarget, FrameOptions, GpuFrame, GpuScene, GridWarpKernel, IndirectMode, LayerTargets, PeelOptions, Renderer,
    Shading, Umbra,
};
pub use sequence::{gpu_supports, run_gpu_sequence};
pub use shadows::{evaluate_gpu, run_shadows_gpu, GpuReceivers, GpuShadowLayers, GpuShadows};
pub use timer::{GpuTimer, TimingMethod, TimingStats};
/// The wgpu version zwarp is built with (engines pass their own device of this version).
pub use wgpu;
