//! GPU compute kernels, each the WGSL twin of a CPU function (DESIGN.md "One kernel, many
//! callers": tests compare them on the same inputs).

mod cull;
mod holes;
mod maxdepth;
mod motion;
mod pyramid;
mod warp;
mod woc;

pub use cull::{CullKernel, CullObjects, CullOutput, CullParams, CullReadback, GpuCullClass};
pub use holes::HoleFillKernel;
pub use maxdepth::{GpuMaxDepth, MaxDepthKernel, MaxDepthLayout};
pub use motion::{MotionInput, MotionKernel};
pub use pyramid::{pyramid_level_sizes, GpuMotionPyramid, PyramidKernel};
pub use warp::{GpuPreparedWarp, GpuWarpLayer, GpuWarpOutput, WarpKernel, MAX_GPU_LAYERS};
pub use woc::{rapid_flags, GpuPrevFrame, GpuWoc, GpuWocParams, WocStage};

/// Bind-group layout with one compute-visible buffer per entry of `kinds` (bindings 0..n) and
/// its pipeline layout: the set-up every buffer-only kernel here shares.
pub(crate) fn buffer_layouts(
    dev: &wgpu::Device,
    label: &str,
    kinds: &[wgpu::BufferBindingType],
) -> (wgpu::BindGroupLayout, wgpu::PipelineLayout) {
    let entries: Vec<wgpu::BindGroupLayoutEntry> = kinds
        .iter()
        .enumerate()
        .map(|(i, &ty)| wgpu::BindGroupLayoutEntry {
            binding: i as u32,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer { ty, has_dynamic_offset: false, min_binding_size: None },
            count: None,
        })
        .collect();
    let layout =
        dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries: &entries });
    let pl = dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &[Some(&layout)],
        immediate_size: 0,
    });
    (layout, pl)
}
