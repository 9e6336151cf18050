//! GPU rasterization of a [`zwarp_core::Scene`]: depth-only (REF), depth + item + colour, and
//! depth peeling to L layers (seed 000 Sec. 3.4).

mod depth;
mod scene;

pub use depth::{
    DepthTarget, FrameOptions, GpuFrame, IndirectMode, LayerTargets, PeelOptions, Renderer, Shading, Umbra,
    COLOR_FORMAT, COLOR_FORMAT_FALLBACK, DEPTH_FORMAT, ITEM_FORMAT,
};
pub use scene::GpuScene;
