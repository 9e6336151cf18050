//! Colour warping on a wgpu device (feature `gpu`): [`ColorWarpKernel`], the WGSL twins of this
//! crate's [`heuristic_warp`](crate::heuristic_warp) and of the raster stage of
//! [`robust_warp_with`](crate::robust_warp_with) (seed 001 Sec. 3.3, 3.4), tested against them
//! on Mesa lavapipe. Runs on a [`zwarp_gpu::GpuContext`].

mod colorwarp;

pub use colorwarp::ColorWarpKernel;
