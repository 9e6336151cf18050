//! GPU rasterization of a [`zwarp_core::Scene`]: depth-only (REF), depth + item + colour, and
//! depth peeling to L layers (seed 000 Sec. 3.4); and of seed 003's warped grid
//! ([`GridWarpKernel`]).

mod depth;
mod gridwarp;
mod scene;

pub use depth::{
    DepthTarget, FrameOptions, GpuFrame, IndirectMode, LayerTargets, PeelOptions, Renderer, Shading, Umbra,
    COLOR_FORMAT, COLOR_FORMAT_FALLBACK, DEPTH_FORMAT, ITEM_FORMAT,
};
pub use gridwarp::GridWarpKernel;
pub use scene::GpuScene;
