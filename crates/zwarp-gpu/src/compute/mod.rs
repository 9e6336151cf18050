//! GPU compute kernels, each the WGSL twin of a CPU function (ARCHITECTURE.md design rule 2,
//! "One implementation of each idea": tests compare them on the same inputs).

use zwarp_core::Result;

use crate::GpuContext;

mod colorwarp;
mod cull;
mod holes;
mod maxdepth;
mod motion;
mod pyramid;
mod warp;
mod woc;

pub use colorwarp::ColorWarpKernel;
pub use cull::{CullKernel, CullObjects, CullOutput, CullParams, CullReadback, GpuCullClass};
pub use holes::{predict, HoleFillKernel};
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

/// A compiled WGSL module whose entry points get automatic pipeline layouts (each entry binds only
/// the buffers it uses, which keeps every pipeline within the default limit of 8 storage buffers
/// per stage): the set-up of every multi-entry kernel here.
pub(crate) struct AutoPipelines<'a> {
    ctx: &'a GpuContext,
    module: wgpu::ShaderModule,
    what: &'static str,
}

impl<'a> AutoPipelines<'a> {
    /// Compiles `source` (named `label` in errors and debuggers); `what` names the kernel in
    /// pipeline-building errors.
    pub(crate) fn new(ctx: &'a GpuContext, label: &'static str, source: &str, what: &'static str) -> Result<Self> {
        let module = ctx.shader(label, source)?;
        Ok(AutoPipelines { ctx, module, what })
    }

    /// The compute pipeline of entry point `entry`.
    pub(crate) fn pipeline(&self, entry: &str) -> Result<wgpu::ComputePipeline> {
        self.ctx.catch(&format!("building the {} pipelines", self.what), || {
            self.ctx.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: None,
                module: &self.module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        })
    }
}
