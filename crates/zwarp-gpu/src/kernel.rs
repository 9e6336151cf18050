//! The set-up the stage crates' compute kernels share (`zwarp_warp::gpu`, `zwarp_color::gpu`,
//! `zwarp_cull::gpu`, `zwarp_shadows::gpu`): bind-group and pipeline layouts for buffer-only
//! kernels ([`buffer_layouts`]) and automatic pipeline layouts per entry point of a multi-entry
//! WGSL module ([`AutoPipelines`]).

use zwarp_core::Result;

use crate::GpuContext;

/// Bind-group layout with one compute-visible buffer per entry of `kinds` (bindings 0..n) and
/// its pipeline layout: the set-up every buffer-only kernel shares.
pub fn buffer_layouts(
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
/// per stage): the set-up of every multi-entry kernel.
pub struct AutoPipelines<'a> {
    ctx: &'a GpuContext,
    module: wgpu::ShaderModule,
    what: &'static str,
}

impl<'a> AutoPipelines<'a> {
    /// Compiles `source` (named `label` in errors and debuggers); `what` names the kernel in
    /// pipeline-building errors.
    pub fn new(ctx: &'a GpuContext, label: &'static str, source: &str, what: &'static str) -> Result<Self> {
        let module = ctx.shader(label, source)?;
        Ok(AutoPipelines { ctx, module, what })
    }

    /// The compute pipeline of entry point `entry`.
    pub fn pipeline(&self, entry: &str) -> Result<wgpu::ComputePipeline> {
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
