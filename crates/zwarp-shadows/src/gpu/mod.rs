//! Soft shadows on a wgpu device (feature `gpu`): [`GpuShadows`], the WGSL twin of this crate's
//! [`run_shadows`](crate::run_shadows) (seed 000 Sec. 6) — reference and zwarp sample maps with
//! the visibility accumulated on the GPU, the warps run by `zwarp_warp::gpu::WarpKernel` —
//! tested against it on Mesa lavapipe (`tests/gpu_shadows.rs`); [`run_shadows_gpu`] and
//! [`evaluate_gpu`] are the GPU paths of [`run_shadows`](crate::run_shadows) and
//! [`evaluate`](crate::evaluate).

mod shadows;

pub use shadows::{
    evaluate_gpu, gpu_peel_options, reference_shift, run_shadows_gpu, sample_warp_params, GpuReceivers,
    GpuShadowLayers, GpuShadows,
};
