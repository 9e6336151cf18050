//! The grid warp on a wgpu device (feature `gpu`): [`GridWarpKernel`], seed 003's adaptive grid
//! warp (and its quads / Didyk / points baselines) drawn by the GPU's rasteriser, the
//! vertex/fragment twin of [`grid::raster`](crate::grid::raster), tested against it on Mesa
//! lavapipe. Runs on a [`zwarp_gpu::GpuContext`].

mod gridwarp;

pub use gridwarp::GridWarpKernel;
