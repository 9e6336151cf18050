//! Depth-only rendering, depth + item + colour rendering, and depth peeling to L layers
//! (seed 000, Sec. 3.4 "deep depth buffer ... by depth peeling"; the reference REF of Sec. 4 is
//! the depth-only pass). Shaders: `depth.wgsl`.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use wgpu::util::DeviceExt;
use zwarp_core::{Camera, Error, Image, Projection, Result, NO_ITEM};

use super::GpuScene;
use crate::readback::{copy_texture, read_buffer};
use crate::GpuContext;

/// Depth format of every render: 32-bit float, the same `[0, 1]` values the CPU rasterizer
/// stores (ARCHITECTURE.md "Conventions": 0 = near, 1 = far / empty).
pub const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Item-buffer format (object id per pixel, [`NO_ITEM`] where empty).
pub const ITEM_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Uint;
/// Preferred colour format: 32-bit float RGBA, so the linear RGB matches the CPU renderer's
/// `[f32; 3]` colour buffer without quantization. Adapters that cannot render to it (GLES)
/// get [`COLOR_FORMAT_FALLBACK`]; see [`Renderer::color_format`].
pub const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
/// Colour format where [`COLOR_FORMAT`] is not renderable (half floats, ~3 decimal digits).
pub const COLOR_FORMAT_FALLBACK: wgpu::TextureFormat = wgpu::TextureFormat::Rgba16Float;

/// Lighting of the colour target, the CPU renderer's model (`zwarp_raster::shading`): the
/// interpolated vertex normal (flat triangle normal without normals) on the eye's side of the
/// triangle, headlight given in view space, `albedo * (ambient + (1 - ambient) * max(0, n . l))`
/// with the textured / patterned albedo of `depth.wgsl`'s `shade`, sky colour where nothing is
/// drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shading {
    /// Direction towards the light in view space (camera looks down -z); normalized on use.
    pub light_dir_view: Vec3,
    /// Ambient term.
    pub ambient: f32,
    /// Colour of empty pixels (linear RGB).
    pub sky: [f32; 3],
}

impl Default for Shading {
    /// The CPU renderer's constants (`zwarp_raster::shading::{LIGHT_DIR_VIEW, AMBIENT,
    /// SKY_COLOR}`; a test checks they agree).
    fn default() -> Self {
        Shading { light_dir_view: Vec3::new(-0.3, 0.5, 0.812404), ambient: 0.25, sky: [0.55, 0.7, 0.9] }
    }
}

/// What a frame render produces besides depth.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct FrameOptions {
    /// Also shade and read back a colour image.
    pub color: bool,
    /// Light and sky for the colour image.
    pub shading: Shading,
}

/// Options of [`Renderer::render_layers`] (depth peeling).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct PeelOptions {
    /// Number of depth layers L (>= 1).
    pub layers: u32,
    /// Seed 000 Sec. 3.4 / 4: ground instances (`Instance::is_ground`) are left out of the L
    /// peeled layers and rendered alone into one extra last layer (the result then has L + 1
    /// layers), as `zwarp_raster::PeelOptions::ground_separate`.
    pub ground_separate: bool,
    /// Generalized umbra culling (seed 000 Sec. 3.4, eq. (1)); `None` = standard peeling.
    pub umbra: Option<Umbra>,
    /// Item buffer / colour options of every layer.
    pub frame: FrameOptions,
}

/// Buffers of one rendered (or peeled) layer, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct GpuFrame {
    /// Depth in `[0, 1]`, 1 = empty.
    pub depth: Image<f32>,
    /// Object id per pixel ([`NO_ITEM`] where empty).
    pub items: Image<u32>,
    /// Linear RGB colour, if asked for (same layout as `zwarp_raster::Frame::color`).
    pub color: Option<Image<[f32; 3]>>,
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct FrameUniform {
    eye: [f32; 4],
    light: [f32; 4],
    ortho: u32,
    umbra: u32,
    _pad: [u32; 2],
    cam0: [f32; 4],
    cam1: [f32; 4],
}

/// The expected range of novel viewpoints for generalized umbra culling (seed 000, Sec. 3.4,
/// eq. (1), Fig. 7), in the reference camera's view space; same meaning and formulas as
/// `zwarp_raster::ViewRegion` so both peelers produce the same layers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Umbra {
    /// Novel viewpoints anywhere in a disc of radius `e` perpendicular to the view axis at view
    /// depth `c`: per pixel `x = (d - c) s / ((e + h) - s)` (eq. (1)), `x = inf` (nothing behind
    /// that pixel is peeled) when `e + h <= s`.
    Disc {
        /// Eq. (1) `e`: radius of the viewpoint region around the centre ray.
        e: f32,
        /// Eq. (1) `c`: view depth of the viewpoint region.
        c: f32,
    },
    /// Orthographic novel views within `max_angle` radians of the view direction:
    /// `x = s / tan(max_angle)`.
    Directions {
        /// Largest angle between a novel view direction and the reference direction.
        max_angle: f32,
    },
}

impl Umbra {
    fn validate(&self) -> Result<()> {
        match *self {
            Umbra::Disc { e, c } if !(e.is_finite() && e >= 0.0 && c.is_finite()) => {
                Err(Error::invalid(format!("umbra region needs finite e >= 0 and finite c, got e={e} c={c}")))
            }
            Umbra::Directions { max_angle }
                if !(max_angle.is_finite() && (0.0..std::f32::consts::FRAC_PI_2).contains(&max_angle)) =>
            {
                Err(Error::invalid(format!("umbra max_angle must be in [0, pi/2), got {max_angle}")))
            }
            _ => Ok(()),
        }
    }
}

/// A depth target that stays on the GPU (for timing loops and for chaining GPU kernels).
pub struct DepthTarget {
    /// The `Depth32Float` texture (render attachment, texture binding, copy source).
    pub texture: wgpu::Texture,
    /// Its default view.
    pub view: wgpu::TextureView,
}

impl DepthTarget {
    /// A `width x height` depth target.
    pub fn new(ctx: &GpuContext, width: u32, height: u32) -> Result<Self> {
        ctx.check_texture_size(width, height, "depth target")?;
        let texture = ctx.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("zwarp depth"),
            size: wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: DEPTH_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let view = texture.create_view(&Default::default());
        Ok(DepthTarget { texture, view })
    }
}

fn color_target(ctx: &GpuContext, w: u32, h: u32, format: wgpu::TextureFormat, label: &str) -> wgpu::Texture {
    ctx.device.create_texture(&wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        // TEXTURE_BINDING: the item target of the previous frame is an input of the GPU WOC.
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT
            | wgpu::TextureUsages::COPY_SRC
            | wgpu::TextureUsages::TEXTURE_BINDING,
        view_formats: &[],
    })
}

/// How culled objects are drawn from indirect arguments (see [`Renderer::indirect_mode`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IndirectMode {
    /// `multi_draw_indexed_indirect_count` over the compacted arguments (needs
    /// `MULTI_DRAW_INDIRECT_COUNT`).
    Count,
    /// `multi_draw_indexed_indirect` over one argument slot per object, zero instances for
    /// culled ones.
    Slots,
}

/// Indirect draw arguments of a scene's objects, as a culling pass leaves them on the GPU
/// (`zwarp_cull::gpu::CullOutput`): what [`Renderer::encode_depth_indirect`] draws.
pub trait IndirectDraws {
    /// Number of draw slots (the objects of the scene the arguments were built for).
    fn slot_count(&self) -> usize;
    /// The argument buffer of `DrawIndexedIndirectArgs` that `mode` draws from, and its u32 draw
    /// count buffer: for [`IndirectMode::Count`] the compacted arguments of the kept objects
    /// and their count, for [`IndirectMode::Slots`] one argument per draw slot and no count.
    fn args(&self, mode: IndirectMode) -> (&wgpu::Buffer, Option<&wgpu::Buffer>);
}

/// The GPU rasterizer: pipelines for depth-only, frame (depth + item + colour) and peel passes.
pub struct Renderer {
    ctx: GpuContext,
    scene_layout: wgpu::BindGroupLayout,
    peel_layout: wgpu::BindGroupLayout,
    shade_layout: wgpu::BindGroupLayout,
    /// Bound at group 1 by colour frames (which have no peel input).
    empty_bind: wgpu::BindGroup,
    depth_pipeline: wgpu::RenderPipeline,
    /// `[item only, item + colour]` for the first layer / plain frames.
    frame_pipeline: [wgpu::RenderPipeline; 2],
    /// `[item only, item + colour]` for peeled layers.
    peel_pipeline: [wgpu::RenderPipeline; 2],
    uniform: wgpu::Buffer,
    color_format: wgpu::TextureFormat,
    copy_layout: wgpu::BindGroupLayout,
    copy_pipeline: wgpu::ComputePipeline,
}

const VERTEX_LAYOUT: wgpu::VertexBufferLayout<'static> = wgpu::VertexBufferLayout {
    array_stride: 12,
    step_mode: wgpu::VertexStepMode::Vertex,
    attributes: &[wgpu::VertexAttribute { format: wgpu::VertexFormat::Float32x3, offset: 0, shader_location: 0 }],
};

/// Vertex stream 1 of the colour pipelines (`AttrGpu` in scene.rs): normal, UV, material.
const ATTRIBUTE_LAYOUT: wgpu::VertexBufferLayout<'static> = wgpu::VertexBufferLayout {
    array_stride: 24,
    step_mode: wgpu::VertexStepMode::Vertex,
    attributes: &[
        wgpu::VertexAttribute { format: wgpu::VertexFormat::Float32x3, offset: 0, shader_location: 1 },
        wgpu::VertexAttribute { format: wgpu::VertexFormat::Float32x2, offset: 12, shader_location: 2 },
        wgpu::VertexAttribute { format: wgpu::VertexFormat::Uint32, offset: 20, shader_location: 3 },
    ],
};

impl Renderer {
    /// Compiles the shaders and builds the pipelines.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let dev = &ctx.device;
        let module = ctx.shader("depth.wgsl", include_str!("depth.wgsl"))?;
        let storage = |binding, stages| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: stages,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only: true },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let vf = wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT;
        let scene_layout = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("zwarp scene"),
            entries: &[
                storage(0, vf),
                storage(1, wgpu::ShaderStages::VERTEX),
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
            ],
        });
        let peel_layout = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("zwarp peel"),
            entries: &[wgpu::BindGroupLayoutEntry {
                binding: 0,
                visibility: wgpu::ShaderStages::FRAGMENT,
                ty: wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable: false },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled: false,
                },
                count: None,
            }],
        });
        let fs = wgpu::ShaderStages::FRAGMENT;
        let shade_layout = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("zwarp shading"),
            entries: &[storage(0, fs), storage(1, fs), storage(2, fs), storage(3, fs)],
        });
        // Group 1 is the peel input; plain colour frames bind an empty group there.
        let empty_layout =
            dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some("zwarp empty"), entries: &[] });
        let empty_bind = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("zwarp empty"),
            layout: &empty_layout,
            entries: &[],
        });
        let layout_scene_color = dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("zwarp scene colour"),
            bind_group_layouts: &[Some(&scene_layout), Some(&empty_layout), Some(&shade_layout)],
            immediate_size: 0,
        });
        let layout_peel_color = dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("zwarp peel colour"),
            bind_group_layouts: &[Some(&scene_layout), Some(&peel_layout), Some(&shade_layout)],
            immediate_size: 0,
        });
        let layout_scene = dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("zwarp scene"),
            bind_group_layouts: &[Some(&scene_layout)],
            immediate_size: 0,
        });
        let layout_peel = dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("zwarp peel"),
            bind_group_layouts: &[Some(&scene_layout), Some(&peel_layout)],
            immediate_size: 0,
        });
        // No culling (the renderer draws both sides, like the CPU rasterizer); strict `Less`
        // so that, as on the CPU, the first drawn of two equal depths wins.
        let primitive = wgpu::PrimitiveState {
            topology: wgpu::PrimitiveTopology::TriangleList,
            cull_mode: None,
            ..Default::default()
        };
        let depth_state = Some(wgpu::DepthStencilState {
            format: DEPTH_FORMAT,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Less),
            stencil: wgpu::StencilState::default(),
            bias: wgpu::DepthBiasState::default(),
        });
        let depth_pipeline = ctx.catch("building the depth-only pipeline", || {
            dev.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some("zwarp depth-only"),
                layout: Some(&layout_scene),
                vertex: wgpu::VertexState {
                    module: &module,
                    entry_point: Some("vs_depth"),
                    compilation_options: Default::default(),
                    buffers: &[Some(VERTEX_LAYOUT)],
                },
                primitive,
                depth_stencil: depth_state.clone(),
                multisample: Default::default(),
                fragment: None,
                multiview_mask: None,
                cache: None,
            })
        })?;
        // Item-only variants (no colour attachment: cheaper, and no 16-byte colour texel per
        // pixel and layer when only the deep depth buffer is wanted).
        let frame_like = |label, layout, entry: &str, color_format| {
            let targets = [
                Some(wgpu::ColorTargetState { format: ITEM_FORMAT, blend: None, write_mask: wgpu::ColorWrites::ALL }),
                Some(wgpu::ColorTargetState { format: color_format, blend: None, write_mask: wgpu::ColorWrites::ALL }),
            ];
            let items_only = entry.ends_with("_item");
            let n_targets = if items_only { 1 } else { 2 };
            let (vs, buffers): (&str, &[Option<wgpu::VertexBufferLayout>]) = if items_only {
                ("vs_frame", &[Some(VERTEX_LAYOUT)])
            } else {
                ("vs_shade", &[Some(VERTEX_LAYOUT), Some(ATTRIBUTE_LAYOUT)])
            };
            dev.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(label),
                layout: Some(layout),
                vertex: wgpu::VertexState {
                    module: &module,
                    entry_point: Some(vs),
                    compilation_options: Default::default(),
                    buffers,
                },
                primitive,
                depth_stencil: depth_state.clone(),
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some(entry),
                    compilation_options: Default::default(),
                    targets: &targets[..n_targets],
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        let frame_pipeline = ctx.catch("building the frame pipeline", || {
            frame_like("zwarp frame (items)", &layout_scene, "fs_frame_item", COLOR_FORMAT)
        })?;
        let peel_pipeline = ctx.catch("building the peel pipeline", || {
            frame_like("zwarp peel (items)", &layout_peel, "fs_peel_item", COLOR_FORMAT)
        })?;
        // Colour pipelines: f32 colour where renderable, else half floats.
        let mut color_format = COLOR_FORMAT;
        let mut colour = ctx.catch("building the colour pipelines", || {
            [
                frame_like("zwarp frame", &layout_scene_color, "fs_frame", color_format),
                frame_like("zwarp peel", &layout_peel_color, "fs_peel", color_format),
            ]
        });
        if colour.is_err() {
            color_format = COLOR_FORMAT_FALLBACK;
            colour = ctx.catch("building the colour pipelines", || {
                [
                    frame_like("zwarp frame", &layout_scene_color, "fs_frame", color_format),
                    frame_like("zwarp peel", &layout_peel_color, "fs_peel", color_format),
                ]
            });
        }
        let [frame_color, peel_color] = colour?;
        let frame_pipeline = [frame_pipeline, frame_color];
        let peel_pipeline = [peel_pipeline, peel_color];
        let copy_module = ctx.shader("depth_copy.wgsl", include_str!("depth_copy.wgsl"))?;
        let cs = wgpu::ShaderStages::COMPUTE;
        let copy_layout = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("zwarp depth copy"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: cs,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: false },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: cs,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Storage { read_only: false },
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: cs,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
            ],
        });
        let copy_pl = dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("zwarp depth copy"),
            bind_group_layouts: &[Some(&copy_layout)],
            immediate_size: 0,
        });
        let copy_pipeline = ctx.catch("building the depth copy pipeline", || {
            dev.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("zwarp depth copy"),
                layout: Some(&copy_pl),
                module: &copy_module,
                entry_point: Some("copy_depth"),
                compilation_options: Default::default(),
                cache: None,
            })
        })?;
        let uniform = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("zwarp frame uniform"),
            size: std::mem::size_of::<FrameUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Ok(Renderer {
            ctx: ctx.clone(),
            scene_layout,
            peel_layout,
            shade_layout,
            empty_bind,
            depth_pipeline,
            frame_pipeline,
            peel_pipeline,
            uniform,
            color_format,
            copy_layout,
            copy_pipeline,
        })
    }

    /// The colour target format: [`COLOR_FORMAT`], or [`COLOR_FORMAT_FALLBACK`] on adapters that
    /// cannot render to 32-bit float RGBA.
    pub fn color_format(&self) -> wgpu::TextureFormat {
        self.color_format
    }

    /// The context this renderer draws with.
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    fn scene_bind_group(&self, scene: &GpuScene) -> wgpu::BindGroup {
        self.ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("zwarp scene"),
            layout: &self.scene_layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: scene.objects.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: scene.draw_ids.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: self.uniform.as_entire_binding() },
            ],
        })
    }

    fn shade_bind_group(&self, scene: &GpuScene) -> wgpu::BindGroup {
        self.ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("zwarp shading"),
            layout: &self.shade_layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: scene.shade_objects.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: scene.materials.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: scene.tex_info.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 3, resource: scene.texels.as_entire_binding() },
            ],
        })
    }

    fn check_camera(&self, camera: &Camera) -> Result<()> {
        self.ctx.check_texture_size(camera.width, camera.height, "render")?;
        if !camera.view_proj().is_finite() {
            return Err(Error::invalid("camera matrices are not finite"));
        }
        Ok(())
    }

    /// Draws the batches (all, or only ground / non-ground ones); `attributes` binds the
    /// shading vertex stream of the colour pipelines.
    fn draw(pass: &mut wgpu::RenderPass<'_>, scene: &GpuScene, ground: Option<bool>, attributes: bool) {
        pass.set_vertex_buffer(0, scene.vertices.slice(..));
        if attributes {
            pass.set_vertex_buffer(1, scene.attributes.slice(..));
        }
        pass.set_index_buffer(scene.indices.slice(..), wgpu::IndexFormat::Uint32);
        for b in scene.batches.iter().filter(|b| ground.is_none_or(|g| g == b.ground)) {
            pass.draw_indexed(
                b.first_index..b.first_index + b.index_count,
                b.base_vertex,
                b.first_instance..b.first_instance + b.instance_count,
            );
        }
    }

    /// Records a depth-only pass of `scene` at time `t` seen by `camera` into `target` (cleared
    /// to 1). Writes the per-object matrices now (queue write), so submit before encoding a
    /// render of the same scene with another camera.
    pub fn encode_depth(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        scene: &GpuScene,
        camera: &Camera,
        t: f32,
        target: &DepthTarget,
    ) -> Result<()> {
        let mut pass = self.begin_depth_pass(encoder, scene, camera, t, target, "zwarp depth-only")?;
        Self::draw(&mut pass, scene, None, false);
        Ok(())
    }

    /// How [`Renderer::encode_depth_indirect`] draws on this device: with
    /// `multi_draw_indexed_indirect_count` over the compacted arguments when the device has
    /// `MULTI_DRAW_INDIRECT_COUNT`, else one `multi_draw_indexed_indirect` over every draw slot
    /// (culled slots hold zero instances).
    pub fn indirect_mode(&self) -> IndirectMode {
        if self.ctx.device.features().contains(wgpu::Features::MULTI_DRAW_INDIRECT_COUNT) {
            IndirectMode::Count
        } else {
            IndirectMode::Slots
        }
    }

    /// Records a depth-only pass (as [`Renderer::encode_depth`]) that draws only the objects a
    /// culling kernel (`zwarp_cull::gpu::CullKernel`) kept, straight from its indirect arguments
    /// in `culled` (thesis seed 002 Sec. IV.3: the visible list becomes indirect draw commands,
    /// no CPU round trip). `culled` must be built for this scene's draws
    /// ([`GpuScene::draws`], `zwarp_cull::gpu::CullObjects::for_scene`). Needs the
    /// `INDIRECT_FIRST_INSTANCE` feature (each draw names its object through its first
    /// instance); `mode` [`IndirectMode::Count`] also needs `MULTI_DRAW_INDIRECT_COUNT`.
    #[allow(clippy::too_many_arguments)]
    pub fn encode_depth_indirect(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        scene: &GpuScene,
        camera: &Camera,
        t: f32,
        target: &DepthTarget,
        culled: &impl IndirectDraws,
        mode: IndirectMode,
    ) -> Result<()> {
        if culled.slot_count() != scene.object_count() {
            return Err(Error::invalid(format!(
                "cull output holds {} objects but the scene has {}",
                culled.slot_count(),
                scene.object_count()
            )));
        }
        let (args, count) = culled.args(mode);
        self.encode_depth_from_args(encoder, scene, camera, t, target, args, count)
    }

    /// Checks `camera` and `target`, writes the per-object matrices for `camera` at `t` and opens
    /// a depth-only pass on `target` (cleared to 1) with the depth pipeline and scene bound: the
    /// start of every depth-only draw, direct or indirect.
    fn begin_depth_pass<'e>(
        &self,
        encoder: &'e mut wgpu::CommandEncoder,
        scene: &GpuScene,
        camera: &Camera,
        t: f32,
        target: &DepthTarget,
        label: &'static str,
    ) -> Result<wgpu::RenderPass<'e>> {
        self.check_camera(camera)?;
        if (target.texture.width(), target.texture.height()) != (camera.width, camera.height) {
            return Err(Error::invalid(format!(
                "depth target is {}x{} but the camera renders {}x{}",
                target.texture.width(),
                target.texture.height(),
                camera.width,
                camera.height
            )));
        }
        scene.write_objects(&self.ctx, camera, t)?;
        let bind = self.scene_bind_group(scene);
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some(label),
            color_attachments: &[],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &target.view,
                depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                stencil_ops: None,
            }),
            ..Default::default()
        });
        pass.set_pipeline(&self.depth_pipeline);
        pass.set_bind_group(0, &bind, &[]);
        Ok(pass)
    }

    /// Checks what the `*_from_args` draws need: `INDIRECT_FIRST_INSTANCE` (the first instance
    /// carries the object's draw slot), `MULTI_DRAW_INDIRECT_COUNT` when a count buffer is given,
    /// and an `INDIRECT` argument buffer with one `DrawIndexedIndirectArgs` per object. Returns
    /// the object count.
    fn check_indirect(&self, scene: &GpuScene, args: &wgpu::Buffer, count: Option<&wgpu::Buffer>) -> Result<u32> {
        let features = self.ctx.device.features();
        if !features.contains(wgpu::Features::INDIRECT_FIRST_INSTANCE) {
            return Err(Error::Unavailable(format!(
                "{} lacks INDIRECT_FIRST_INSTANCE, needed for culled indirect draws",
                self.ctx.adapter.name
            )));
        }
        if count.is_some() && !features.contains(wgpu::Features::MULTI_DRAW_INDIRECT_COUNT) {
            return Err(Error::Unavailable(format!("{} lacks MULTI_DRAW_INDIRECT_COUNT", self.ctx.adapter.name)));
        }
        let n = scene.object_count() as u32;
        let need = n as u64 * std::mem::size_of::<wgpu::util::DrawIndexedIndirectArgs>() as u64;
        if args.size() < need || !args.usage().contains(wgpu::BufferUsages::INDIRECT) {
            return Err(Error::invalid(format!(
                "indirect argument buffer needs INDIRECT usage and {need} bytes, has {}",
                args.size()
            )));
        }
        Ok(n)
    }

    /// Records a depth-only pass (target cleared to 1) drawing `scene` from indirect arguments:
    /// `args` holds one `DrawIndexedIndirectArgs` per object (first instance = the object's draw
    /// slot); with `count` (a u32 draw count, needs `MULTI_DRAW_INDIRECT_COUNT`) only the first
    /// `count` are drawn. Needs `INDIRECT_FIRST_INSTANCE`. Writes the per-object matrices now
    /// (queue write), so submit before encoding a render of the same scene with another camera.
    #[allow(clippy::too_many_arguments)]
    pub fn encode_depth_from_args(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        scene: &GpuScene,
        camera: &Camera,
        t: f32,
        target: &DepthTarget,
        args: &wgpu::Buffer,
        count: Option<&wgpu::Buffer>,
    ) -> Result<()> {
        let n = self.check_indirect(scene, args, count)?;
        let mut pass = self.begin_depth_pass(encoder, scene, camera, t, target, "zwarp depth-only indirect")?;
        pass.set_vertex_buffer(0, scene.vertices.slice(..));
        pass.set_index_buffer(scene.indices.slice(..), wgpu::IndexFormat::Uint32);
        match count {
            Some(c) => pass.multi_draw_indexed_indirect_count(args, 0, c, 0, n),
            None => pass.multi_draw_indexed_indirect(args, 0, n),
        }
        Ok(())
    }

    /// Records a depth + item pass into layer 0 of `targets` (cleared to 1 / [`NO_ITEM`])
    /// drawing `scene` from indirect arguments, as [`Renderer::encode_depth_from_args`]: the
    /// frame an engine draws for the kept objects, whose depth and items are the next frame's
    /// WOC input. Same requirements as [`Renderer::encode_depth_from_args`].
    #[allow(clippy::too_many_arguments)]
    pub fn encode_frame_from_args(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        scene: &GpuScene,
        camera: &Camera,
        t: f32,
        targets: &LayerTargets,
        args: &wgpu::Buffer,
        count: Option<&wgpu::Buffer>,
    ) -> Result<()> {
        let n = self.check_indirect(scene, args, count)?;
        self.check_camera(camera)?;
        if targets.size() != (camera.width, camera.height) {
            return Err(Error::invalid(format!(
                "layer targets are {}x{} but the camera renders {}x{}",
                targets.width, targets.height, camera.width, camera.height
            )));
        }
        scene.write_objects(&self.ctx, camera, t)?;
        let opts = PeelOptions { layers: 1, ..Default::default() };
        let uni = self.frame_uniform(camera, &opts);
        self.ctx.queue.write_buffer(&self.uniform, 0, bytemuck::bytes_of(&uni));
        let bind = self.scene_bind_group(scene);
        let item_view = targets.items[0].create_view(&Default::default());
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("zwarp frame indirect"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &item_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color { r: NO_ITEM as f64, g: 0.0, b: 0.0, a: 0.0 }),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &targets.depth[0].view,
                depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                stencil_ops: None,
            }),
            ..Default::default()
        });
        pass.set_pipeline(&self.frame_pipeline[0]);
        pass.set_bind_group(0, &bind, &[]);
        pass.set_vertex_buffer(0, scene.vertices.slice(..));
        pass.set_index_buffer(scene.indices.slice(..), wgpu::IndexFormat::Uint32);
        match count {
            Some(c) => pass.multi_draw_indexed_indirect_count(args, 0, c, 0, n),
            None => pass.multi_draw_indexed_indirect(args, 0, n),
        }
        Ok(())
    }

    /// Reads layer `k` of `targets` back as a [`GpuFrame`] (depth and items; no colour).
    pub fn read_layer(&self, targets: &LayerTargets, k: usize) -> Result<GpuFrame> {
        if k >= targets.layers() {
            return Err(Error::invalid(format!("layer {k} of {} layers", targets.layers())));
        }
        let (w, h) = targets.size();
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        let pd = self.depth_to_buffer(&mut enc, &targets.depth[k])?;
        let pi = copy_texture(&self.ctx, &mut enc, &targets.items[k], wgpu::TextureAspect::All, 4);
        self.ctx.queue.submit([enc.finish()]);
        Ok(GpuFrame { depth: self.read_depth(&pd, w, h)?, items: pi.read(&self.ctx)?, color: None })
    }

    /// Depth-only render of the objects `culled` kept (see [`Renderer::encode_depth_indirect`]),
    /// read back. The cull must have been submitted before (or recorded into the same queue).
    pub fn render_depth_indirect(
        &self,
        scene: &GpuScene,
        camera: &Camera,
        t: f32,
        culled: &impl IndirectDraws,
        mode: IndirectMode,
    ) -> Result<Image<f32>> {
        let target = DepthTarget::new(&self.ctx, camera.width, camera.height)?;
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        self.encode_depth_indirect(&mut enc, scene, camera, t, &target, culled, mode)?;
        let buf = self.depth_to_buffer(&mut enc, &target)?;
        self.ctx.queue.submit([enc.finish()]);
        self.read_depth(&buf, camera.width, camera.height)
    }

    /// Records a copy of `depth` into `dst` as f32 with `stride` elements per row (bit-exact;
    /// a compute pass, because GLES-class adapters cannot copy depth textures to buffers).
    /// `dst` needs `STORAGE` usage and `stride * (height - 1) + width` floats.
    pub fn encode_depth_copy(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        depth: &DepthTarget,
        dst: &wgpu::Buffer,
        stride: u32,
    ) -> Result<()> {
        let (w, h) = (depth.texture.width(), depth.texture.height());
        let need = (stride as u64 * (h as u64 - 1) + w as u64) * 4;
        if stride < w || dst.size() < need {
            return Err(Error::invalid(format!(
                "depth copy: stride {stride} for width {w} or buffer of {} < {need} bytes",
                dst.size()
            )));
        }
        let dev = &self.ctx.device;
        let params = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("zwarp depth copy params"),
            contents: bytemuck::cast_slice(&[w, h, stride, 0u32]),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let bind = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("zwarp depth copy"),
            layout: &self.copy_layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: wgpu::BindingResource::TextureView(&depth.view) },
                wgpu::BindGroupEntry { binding: 1, resource: dst.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: params.as_entire_binding() },
            ],
        });
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("zwarp depth copy"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.copy_pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups(w.div_ceil(8), h.div_ceil(8), 1);
        Ok(())
    }

    /// Records the depth copy into a fresh buffer of `width * height` floats.
    fn depth_to_buffer(&self, encoder: &mut wgpu::CommandEncoder, depth: &DepthTarget) -> Result<wgpu::Buffer> {
        let (w, h) = (depth.texture.width(), depth.texture.height());
        let bytes = w as u64 * h as u64 * 4;
        self.ctx.check_storage_size(bytes, "depth read-back")?;
        let buf = self.ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("zwarp depth read-back"),
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        self.encode_depth_copy(encoder, depth, &buf, w)?;
        Ok(buf)
    }

    fn read_depth(&self, buf: &wgpu::Buffer, w: u32, h: u32) -> Result<Image<f32>> {
        Image::from_vec(w, h, read_buffer::<f32>(&self.ctx, buf, w as usize * h as usize)?)
    }

    /// Depth-only render (the paper's REF pass): depth in `[0, 1]`, 1 where empty, row 0 at
    /// the top; the GPU twin of `zwarp_raster::render_depth`.
    pub fn render_depth(&self, scene: &GpuScene, camera: &Camera, t: f32) -> Result<Image<f32>> {
        let target = DepthTarget::new(&self.ctx, camera.width, camera.height)?;
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        self.encode_depth(&mut enc, scene, camera, t, &target)?;
        let buf = self.depth_to_buffer(&mut enc, &target)?;
        self.ctx.queue.submit([enc.finish()]);
        self.read_depth(&buf, camera.width, camera.height)
    }

    /// One pass with depth, item ids and (optionally) colour: the GPU twin of
    /// `zwarp_raster::render_frame`.
    pub fn render_frame(&self, scene: &GpuScene, camera: &Camera, t: f32, opts: &FrameOptions) -> Result<GpuFrame> {
        let peel = PeelOptions { layers: 1, ground_separate: false, umbra: None, frame: *opts };
        let mut layers = self.render_layers(scene, camera, t, &peel)?;
        Ok(layers.remove(0))
    }

    fn frame_uniform(&self, camera: &Camera, opts: &PeelOptions) -> FrameUniform {
        let inv_view = camera.view.inverse();
        let (eye, ortho) = match camera.projection {
            Projection::Perspective { .. } => (camera.eye(), 0u32),
            // Orthographic: every ray has the same direction; pass the direction to the camera.
            Projection::Orthographic { .. } => (inv_view.z_axis.truncate().normalize(), 1u32),
        };
        let sh = &opts.frame.shading;
        // The headlight is given in view space; shade in world space with its world direction.
        let l = inv_view.transform_vector3(sh.light_dir_view.normalize()).normalize();
        let (tan_half, half_height) = match camera.projection {
            Projection::Perspective { fov_y } => ((fov_y * 0.5).tan(), 0.0),
            Projection::Orthographic { half_height } => (0.0, half_height),
        };
        let (umbra, a, b) = match opts.umbra {
            None => (0u32, 0.0, 0.0),
            Some(Umbra::Disc { e, c }) => (1, e, c),
            Some(Umbra::Directions { max_angle }) => (2, max_angle.tan(), 0.0),
        };
        FrameUniform {
            eye: eye.extend(1.0).to_array(),
            light: [l.x, l.y, l.z, sh.ambient],
            ortho,
            umbra,
            _pad: [0; 2],
            cam0: [camera.width as f32, camera.height as f32, camera.near, camera.far],
            cam1: [tan_half, half_height, a, b],
        }
    }

    /// Records depth peeling (seed 000 Sec. 3.4, [Everitt 2001]) into one encoder: layer k of
    /// `targets` receives depth, item ids (and colour if `targets` has colour). Semantics as
    /// [`Renderer::render_layers`]; `targets.layers()` must equal L (+1 with
    /// [`PeelOptions::ground_separate`]). Writes per-object matrices and the frame uniform now
    /// (queue writes), so submit before encoding another camera.
    pub fn encode_layers(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        scene: &GpuScene,
        camera: &Camera,
        t: f32,
        opts: &PeelOptions,
        targets: &LayerTargets,
    ) -> Result<()> {
        check_peel(opts)?;
        self.check_camera(camera)?;
        let sh = &opts.frame.shading;
        let total = opts.layers as usize + opts.ground_separate as usize;
        if targets.layers() != total || targets.size() != (camera.width, camera.height) {
            return Err(Error::invalid(format!(
                "layer targets hold {} layers of {}x{}, the render needs {total} of {}x{}",
                targets.layers(),
                targets.width,
                targets.height,
                camera.width,
                camera.height
            )));
        }
        if opts.frame.color && targets.color.is_empty() {
            return Err(Error::invalid("colour requested but the layer targets have no colour textures"));
        }
        scene.write_objects(&self.ctx, camera, t)?;
        let uni = self.frame_uniform(camera, opts);
        self.ctx.queue.write_buffer(&self.uniform, 0, bytemuck::bytes_of(&uni));
        let bind = self.scene_bind_group(scene);
        let with_color = !targets.color.is_empty();
        let shade_bind = with_color.then(|| {
            scene.write_shading(&self.ctx, t);
            self.shade_bind_group(scene)
        });
        let variant = with_color as usize;
        let sky = sh.sky;
        let peeled = if opts.ground_separate { Some(false) } else { None };
        for k in 0..total {
            let ground_layer = k == opts.layers as usize;
            let item_view = targets.items[k].create_view(&Default::default());
            let color_view = targets.color.get(k).map(|c| c.create_view(&Default::default()));
            let mut attachments = vec![Some(wgpu::RenderPassColorAttachment {
                view: &item_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color { r: NO_ITEM as f64, g: 0.0, b: 0.0, a: 0.0 }),
                    store: wgpu::StoreOp::Store,
                },
            })];
            if let Some(cv) = &color_view {
                attachments.push(Some(wgpu::RenderPassColorAttachment {
                    view: cv,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color {
                            r: sky[0] as f64,
                            g: sky[1] as f64,
                            b: sky[2] as f64,
                            a: 1.0,
                        }),
                        store: wgpu::StoreOp::Store,
                    },
                }));
            }
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("zwarp layer"),
                color_attachments: &attachments,
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &targets.depth[k].view,
                    depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                    stencil_ops: None,
                }),
                ..Default::default()
            });
            pass.set_bind_group(0, &bind, &[]);
            if let Some(sb) = &shade_bind {
                pass.set_bind_group(1, &self.empty_bind, &[]);
                pass.set_bind_group(2, sb, &[]);
            }
            if ground_layer {
                // The ground alone, not a peel (Sec. 3.4: the separate last layer).
                pass.set_pipeline(&self.frame_pipeline[variant]);
                Self::draw(&mut pass, scene, Some(true), with_color);
            } else if k == 0 {
                pass.set_pipeline(&self.frame_pipeline[variant]);
                Self::draw(&mut pass, scene, peeled, with_color);
            } else {
                // Layer k reads layer k-1's depth texture.
                pass.set_pipeline(&self.peel_pipeline[variant]);
                pass.set_bind_group(1, &targets.peel_binds[k - 1], &[]);
                Self::draw(&mut pass, scene, peeled, with_color);
            }
        }
        Ok(())
    }

    /// Depth peeling (seed 000 Sec. 3.4, [Everitt 2001]), the GPU twin of
    /// `zwarp_raster::render_layers`: layer 0 is the ordinary frame; layer k keeps, per pixel,
    /// the nearest fragment strictly behind layer k-1 (plus the umbra extent of eq. (1) with
    /// [`PeelOptions::umbra`]); a pixel empty in a layer stays empty in all later ones. With
    /// [`PeelOptions::ground_separate`] the ground is left out of the L layers and rendered
    /// alone as layer L (L + 1 layers in all). All layers are drawn in one submission.
    pub fn render_layers(
        &self,
        scene: &GpuScene,
        camera: &Camera,
        t: f32,
        opts: &PeelOptions,
    ) -> Result<Vec<GpuFrame>> {
        check_peel(opts)?;
        let total = opts.layers as usize + opts.ground_separate as usize;
        self.check_camera(camera)?;
        let (w, h) = (camera.width, camera.height);
        let targets = LayerTargets::new(self, w, h, total, opts.frame.color)?;
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        self.encode_layers(&mut enc, scene, camera, t, opts, &targets)?;
        let pending: Vec<_> = (0..total)
            .map(|k| {
                Ok((
                    self.depth_to_buffer(&mut enc, &targets.depth[k])?,
                    copy_texture(&self.ctx, &mut enc, &targets.items[k], wgpu::TextureAspect::All, 4),
                    targets.color.get(k).map(|c| {
                        let texel = if self.color_format == COLOR_FORMAT { 16 } else { 8 };
                        copy_texture(&self.ctx, &mut enc, c, wgpu::TextureAspect::All, texel)
                    }),
                ))
            })
            .collect::<Result<_>>()?;
        self.ctx.queue.submit([enc.finish()]);
        pending
            .into_iter()
            .map(|(pd, pi, pc)| {
                let color = match pc {
                    None => None,
                    Some(p) if self.color_format == COLOR_FORMAT => {
                        Some(p.read::<[f32; 4]>(&self.ctx)?.map(|p| [p[0], p[1], p[2]]))
                    }
                    Some(p) => Some(p.read::<[u16; 4]>(&self.ctx)?.map(|p| [0, 1, 2].map(|k| f16_to_f32(p[k])))),
                };
                Ok(GpuFrame { depth: self.read_depth(&pd, w, h)?, items: pi.read(&self.ctx)?, color })
            })
            .collect()
    }
}

/// IEEE half -> f32 (for the [`COLOR_FORMAT_FALLBACK`] read-back).
fn f16_to_f32(h: u16) -> f32 {
    let sign = if h & 0x8000 != 0 { -1.0f32 } else { 1.0 };
    let exp = ((h >> 10) & 0x1f) as i32;
    let mant = (h & 0x3ff) as f32;
    match exp {
        0 => sign * mant * 2f32.powi(-24),
        31 if mant == 0.0 => sign * f32::INFINITY,
        31 => f32::NAN,
        e => sign * (1.0 + mant / 1024.0) * 2f32.powi(e - 15),
    }
}

fn check_peel(opts: &PeelOptions) -> Result<()> {
    if opts.layers == 0 {
        return Err(Error::invalid("depth peeling needs at least one layer (L >= 1)"));
    }
    if opts.layers > 64 {
        return Err(Error::invalid(format!("depth peeling: L = {} layers is unreasonable (max 64)", opts.layers)));
    }
    if let Some(u) = &opts.umbra {
        u.validate()?;
    }
    let sh = &opts.frame.shading;
    if !sh.light_dir_view.is_finite() || sh.light_dir_view.length_squared() == 0.0 || !sh.ambient.is_finite() {
        return Err(Error::invalid("shading light direction must be finite and non-zero"));
    }
    Ok(())
}

/// GPU-resident render targets of a stack of layers (one per peeled layer, plus the ground
/// layer): depth (`Depth32Float`, readable as a texture by the next peel), item ids (`R32Uint`)
/// and optionally colour (`Rgba32Float`). All textures allow `COPY_SRC`.
pub struct LayerTargets {
    width: u32,
    height: u32,
    /// Depth per layer.
    pub depth: Vec<DepthTarget>,
    /// Item ids per layer.
    pub items: Vec<wgpu::Texture>,
    /// Colour per layer (empty when created without colour).
    pub color: Vec<wgpu::Texture>,
    peel_binds: Vec<wgpu::BindGroup>,
}

impl LayerTargets {
    /// Targets for `layers` layers of `width x height` (with colour textures if `color`).
    pub fn new(renderer: &Renderer, width: u32, height: u32, layers: usize, color: bool) -> Result<Self> {
        let ctx = &renderer.ctx;
        ctx.check_texture_size(width, height, "layer targets")?;
        if layers == 0 {
            return Err(Error::invalid("layer targets need at least one layer"));
        }
        let depth: Vec<DepthTarget> =
            (0..layers).map(|_| DepthTarget::new(ctx, width, height)).collect::<Result<_>>()?;
        let items = (0..layers).map(|_| color_target(ctx, width, height, ITEM_FORMAT, "zwarp items")).collect();
        let color = if color {
            (0..layers).map(|_| color_target(ctx, width, height, renderer.color_format, "zwarp colour")).collect()
        } else {
            Vec::new()
        };
        let peel_binds = depth
            .iter()
            .map(|d| {
                ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("zwarp peel"),
                    layout: &renderer.peel_layout,
                    entries: &[wgpu::BindGroupEntry {
                        binding: 0,
                        resource: wgpu::BindingResource::TextureView(&d.view),
                    }],
                })
            })
            .collect();
        Ok(LayerTargets { width, height, depth, items, color, peel_binds })
    }

    /// Number of layers.
    pub fn layers(&self) -> usize {
        self.depth.len()
    }

    /// `(width, height)`.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }
}

#[cfg(test)]
mod tests {
    use super::f16_to_f32;

    #[test]
    fn half_floats_decode() {
        assert_eq!(f16_to_f32(0x0000), 0.0);
        assert_eq!(f16_to_f32(0x3c00), 1.0);
        assert_eq!(f16_to_f32(0xc000), -2.0);
        assert_eq!(f16_to_f32(0x3800), 0.5);
        assert_eq!(f16_to_f32(0x0001), 2f32.powi(-24));
        assert_eq!(f16_to_f32(0x7c00), f32::INFINITY);
        assert!(f16_to_f32(0x7e00).is_nan());
        // 0.55 as half is 0x3866 = 0.54980...
        assert!((f16_to_f32(0x3866) - 0.55).abs() < 5e-4);
    }
}
