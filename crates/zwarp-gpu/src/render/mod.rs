//! GPU rasterization of a [`zwarp_core::Scene`]: depth-only (REF), depth + item + colour, depth
//! peeling to L layers (seed 000 Sec. 3.4), and depth-only draws from a culling pass's indirect
//! arguments ([`IndirectDraws`]).

mod depth;
mod scene;

pub use depth::{
    DepthTarget, FrameOptions, GpuFrame, IndirectDraws, IndirectMode, LayerTargets, PeelOptions, Renderer, Shading,
    Umbra, COLOR_FORMAT, COLOR_FORMAT_FALLBACK, DEPTH_FORMAT, ITEM_FORMAT,
};
pub use scene::GpuScene;
