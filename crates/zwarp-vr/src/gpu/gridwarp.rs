//! The adaptive grid warp of seed 003 (Sec. 4.1.4, 5.1) drawn by the GPU's rasteriser: the
//! vertex/fragment twin of `crate::grid::raster`. Shader: `gridwarp.wgsl`.
//!
//! The mesh ([`crate::grid::Mesh`]: quadtree, cells, corner depths) is built on the CPU as
//! in seed 003, where the grid comes from the quadtree each frame; the GPU draws one instance
//! per cell (two triangles through the combined warp matrix, a depth test) or one point per
//! source pixel, and the fragment fetches colour with the mesh's filter (nearest, bilinear, or
//! adaptive over the connected texels) and writes the source texel's reprojected depth.
//!
//! Results agree with the CPU rasteriser up to coverage at triangle edges (the CPU closes
//! sub-pixel T-junction slivers with a 0.02 px tolerance the hardware rule lacks) and float
//! rounding of the shader compiler; the tests bound the difference.

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;
use zwarp_core::{Camera, Error, Image, Result};
use zwarp_gpu::readback::copy_texture;
use zwarp_gpu::GpuContext;

use crate::grid::{corner_depths, ColorFilter, Mesh, Primitives, Source, StageMs, WarpOutput};

/// Mirror of `Params` in gridwarp.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct Params {
    matrix: [f32; 16],
    size: [f32; 4],
    filter: u32,
    _pad: [u32; 3],
}

/// One cell instance: its source rectangle and corner depths.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct CellInstance {
    rect: [u32; 4],
    depth: [f32; 4],
}

const COLOR: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
const DEPTH_OUT: wgpu::TextureFormat = wgpu::TextureFormat::R32Float;
const DEPTH_TEST: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// Render pipelines of the grid warp (cells and points).
pub struct GridWarpKernel {
    ctx: GpuContext,
    cells: wgpu::RenderPipeline,
    points: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
}

impl GridWarpKernel {
    /// Compiles `gridwarp.wgsl`.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let dev = &ctx.device;
        let module = ctx.shader("gridwarp.wgsl", include_str!("gridwarp.wgsl"))?;
        let vf = wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT;
        let entry = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: vf,
            ty: wgpu::BindingType::Buffer { ty, has_dynamic_offset: false, min_binding_size: None },
            count: None,
        };
        let storage = wgpu::BufferBindingType::Storage { read_only: true };
        let layout = dev.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("zwarp grid warp"),
            entries: &[
                entry(0, wgpu::BufferBindingType::Uniform),
                entry(1, storage),
                entry(2, storage),
                entry(3, storage),
            ],
        });
        let pl = dev.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("zwarp grid warp"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let targets = [
            Some(wgpu::ColorTargetState { format: COLOR, blend: None, write_mask: wgpu::ColorWrites::ALL }),
            Some(wgpu::ColorTargetState { format: DEPTH_OUT, blend: None, write_mask: wgpu::ColorWrites::ALL }),
        ];
        let instance = [Some(wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<CellInstance>() as u64,
            step_mode: wgpu::VertexStepMode::Instance,
            attributes: &wgpu::vertex_attr_array![0 => Uint32x4, 1 => Float32x4],
        })];
        let pipeline = |label, entry, topology, buffers: &[Option<wgpu::VertexBufferLayout>]| {
            ctx.catch(label, || {
                dev.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                    label: Some(label),
                    layout: Some(&pl),
                    vertex: wgpu::VertexState {
                        module: &module,
                        entry_point: Some(entry),
                        compilation_options: Default::default(),
                        buffers,
                    },
                    // Both sides (a warped cell may flip); strict `Less`: as on the CPU, the
                    // first drawn of two equal depths wins.
                    primitive: wgpu::PrimitiveState { topology, cull_mode: None, ..Default::default() },
                    depth_stencil: Some(wgpu::DepthStencilState {
                        format: DEPTH_TEST,
                        depth_write_enabled: Some(true),
                        depth_compare: Some(wgpu::CompareFunction::Less),
                        stencil: wgpu::StencilState::default(),
                        bias: wgpu::DepthBiasState::default(),
                    }),
                    multisample: wgpu::MultisampleState::default(),
                    fragment: Some(wgpu::FragmentState {
                        module: &module,
                        entry_point: Some("fs_main"),
                        compilation_options: Default::default(),
                        targets: &targets,
                    }),
                    multiview_mask: None,
                    cache: None,
                })
            })
        };
        let cells = pipeline("zwarp grid warp cells", "vs_cell", wgpu::PrimitiveTopology::TriangleList, &instance)?;
        let points = pipeline("zwarp grid warp points", "vs_point", wgpu::PrimitiveTopology::PointList, &[])?;
        Ok(GridWarpKernel { ctx: ctx.clone(), cells, points, layout })
    }

    fn target(&self, label: &str, format: wgpu::TextureFormat, w: u32, h: u32) -> Result<wgpu::Texture> {
        self.ctx.catch(label, || {
            self.ctx.device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
                view_formats: &[],
            })
        })
    }

    /// Draws `mesh` (built for `src` and `dst`) on the GPU: the twin of `crate::grid::raster`
    /// (stage `warp`: instance upload, draw and readback; the mesh's own stage times are kept).
    pub fn raster(&self, src: &Source<'_>, dst: &Camera, mesh: &Mesh) -> Result<WarpOutput> {
        let t = std::time::Instant::now();
        src.check()?;
        let (sw, sh) = src.depth.size();
        let (tw, th) = (dst.width, dst.height);
        self.ctx.check_texture_size(tw, th, "GPU grid warp target")?;
        let filter = match (&mesh.primitives, &mesh.tree, mesh.filter) {
            (Primitives::Points, _, _) => 0,
            (_, Some(_), ColorFilter::Adaptive) => 2,
            _ => 1,
        };
        let links: Vec<u32> = match &mesh.tree {
            Some(tree) => {
                if tree.size() != (sw, sh) {
                    return Err(Error::invalid("GPU grid warp: the quadtree was built for another image size"));
                }
                (0..sh).flat_map(|y| (0..sw).map(move |x| tree.pixel_links(x, y) as u32)).collect()
            }
            None => Vec::new(),
        };
        let params = Params {
            matrix: mesh.matrix.0.to_cols_array(),
            size: [tw as f32, th as f32, sw as f32, sh as f32],
            filter,
            _pad: [0; 3],
        };
        let rgb: &[f32] = bytemuck::cast_slice(src.color.data());
        let usage = wgpu::BufferUsages::STORAGE;
        let dev = &self.ctx.device;
        let uniform = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("zwarp grid warp params"),
            contents: bytemuck::bytes_of(&params),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let color = self.ctx.buffer_with("zwarp grid warp colour", bytemuck::cast_slice(rgb), usage)?;
        let depth = self.ctx.buffer_with("zwarp grid warp depth", bytemuck::cast_slice(src.depth.data()), usage)?;
        let links = self.ctx.buffer_with("zwarp grid warp links", bytemuck::cast_slice(&links), usage)?;
        let instances: Option<(wgpu::Buffer, u32)> = match &mesh.primitives {
            Primitives::Cells(cells) => {
                let tree = mesh.tree.as_ref();
                let data: Vec<CellInstance> = cells
                    .iter()
                    .map(|c| CellInstance { rect: [c.x0, c.y0, c.x1, c.y1], depth: corner_depths(src.depth, tree, c) })
                    .collect();
                let buf = self.ctx.buffer_with(
                    "zwarp grid warp cells",
                    bytemuck::cast_slice(&data),
                    wgpu::BufferUsages::VERTEX,
                )?;
                Some((buf, cells.len() as u32))
            }
            Primitives::Points => None,
        };
        let bind = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("zwarp grid warp"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: uniform.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: color.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: depth.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 3, resource: links.as_entire_binding() },
            ],
        });
        let out_color = self.target("zwarp grid warp colour target", COLOR, tw, th)?;
        let out_depth = self.target("zwarp grid warp depth target", DEPTH_OUT, tw, th)?;
        let test = self.target("zwarp grid warp depth test", DEPTH_TEST, tw, th)?;
        let view = |t: &wgpu::Texture| t.create_view(&wgpu::TextureViewDescriptor::default());
        let (cv, dv, tv) = (view(&out_color), view(&out_depth), view(&test));
        let mut enc = dev.create_command_encoder(&Default::default());
        {
            let attachment = |v, clear| {
                Some(wgpu::RenderPassColorAttachment {
                    view: v,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations { load: wgpu::LoadOp::Clear(clear), store: wgpu::StoreOp::Store },
                })
            };
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("zwarp grid warp"),
                color_attachments: &[
                    attachment(&cv, wgpu::Color::TRANSPARENT),
                    attachment(&dv, wgpu::Color { r: 1.0, g: 0.0, b: 0.0, a: 0.0 }),
                ],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &tv,
                    depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Discard }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_bind_group(0, &bind, &[]);
            match &instances {
                Some((buf, n)) => {
                    pass.set_pipeline(&self.cells);
                    pass.set_vertex_buffer(0, buf.slice(..));
                    pass.draw(0..6, 0..*n);
                }
                None => {
                    pass.set_pipeline(&self.points);
                    pass.draw(0..1, 0..sw * sh);
                }
            }
        }
        let pc = copy_texture(&self.ctx, &mut enc, &out_color, wgpu::TextureAspect::All, 16);
        let pd = copy_texture(&self.ctx, &mut enc, &out_depth, wgpu::TextureAspect::All, 4);
        self.ctx.queue.submit([enc.finish()]);
        let rgba: Image<[f32; 4]> = pc.read(&self.ctx)?;
        let depth: Image<f32> = pd.read(&self.ctx)?;
        let hole = Image::from_vec(tw, th, rgba.data().iter().map(|c| c[3] <= 0.0).collect())?;
        let color = Image::from_vec(tw, th, rgba.data().iter().map(|c| [c[0], c[1], c[2]]).collect())?;
        Ok(WarpOutput {
            color,
            depth,
            hole,
            primitives: mesh.count(src),
            cells: mesh.outline(),
            ms: StageMs { warp: t.elapsed().as_secs_f64() * 1e3, ..mesh.ms },
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::{raster, WarpParams};
    use crate::{Method, Reduction};
    use glam::{Mat4, Vec3};

    /// A small real frame (procedural MO with textured colour) and the view of an eye 0.3
    /// units to its right.
    fn frame() -> (Camera, Image<f32>, Image<[f32; 3]>, Camera) {
        let opts = zwarp_scene::SceneOptions { scale: 0.03, ..Default::default() };
        let loaded = zwarp_scene::load_scene("mo", &opts).unwrap();
        let path = loaded.path_or_default();
        let t = path.time_of_frame(10, 1.0);
        let cam = path.camera_at(t, 160, 96).unwrap();
        let f = zwarp_raster::render_frame(
            &loaded.scene,
            &cam,
            t,
            &zwarp_raster::FrameOptions { color: true, objects: None },
        )
        .unwrap();
        let eye = Camera { view: Mat4::from_translation(Vec3::new(-0.3, 0.0, 0.0)) * cam.view, ..cam };
        (cam, f.depth, f.color.unwrap(), eye)
    }

    #[test]
    fn gpu_grid_warp_matches_the_cpu_rasteriser() {
        let Some(ctx) = zwarp_gpu::test_context() else { return };
        let k = GridWarpKernel::new(&ctx).unwrap();
        let (cam, depth, color, eye) = frame();
        let src = Source { cam: &cam, depth: &depth, color: &color };
        let p = WarpParams::default();
        let adaptive = WarpParams { filter: ColorFilter::Adaptive, ..p };
        for (method, p) in [
            (Method::Grid(Reduction::Irregular), p),
            (Method::Grid(Reduction::Irregular), adaptive),
            (Method::Grid(Reduction::Cross), adaptive),
            (Method::Quads, p),
            (Method::Didyk, p),
            (Method::Points, p),
        ] {
            let mesh = Mesh::build(&src, &eye, method, &p).unwrap();
            let cpu = raster(&src, &eye, &mesh).unwrap();
            let gpu = k.raster(&src, &eye, &mesh).unwrap();
            assert_eq!((gpu.primitives, gpu.cells.len()), (cpu.primitives, cpu.cells.len()), "{method:?}");
            let n = cpu.hole.len() as f64;
            let same_hole = cpu.hole.data().iter().zip(gpu.hole.data()).filter(|(a, b)| a == b).count() as f64 / n;
            let both: Vec<usize> =
                (0..cpu.hole.len()).filter(|&i| !cpu.hole.data()[i] && !gpu.hole.data()[i]).collect();
            let share = |ok: &dyn Fn(usize) -> bool| both.iter().filter(|&&i| ok(i)).count() as f64 / both.len() as f64;
            let (c, g) = (cpu.color.data(), gpu.color.data());
            let color_within = |tol: f32| share(&|i| (0..3).all(|k| (c[i][k] - g[i][k]).abs() <= tol));
            let depth_within = |tol: f32| share(&|i| (cpu.depth.data()[i] - gpu.depth.data()[i]).abs() <= tol);
            let (c4, c2, d6, d2) = (color_within(1e-4), color_within(0.05), depth_within(1e-6), depth_within(1e-2));
            eprintln!(
                "{}: holes agree on {same_hole:.4} of the pixels; of the covered, colour within 1e-4 on {c4:.4} (0.05: {c2:.4}), depth within 1e-6 on {d6:.4} (0.01: {d2:.4})",
                method.name()
            );
            assert!(cpu.hole.data().iter().filter(|&&h| h).count() > 0, "{method:?}: the eye sees disocclusions");
            assert!(same_hole >= 0.995, "{method:?}: holes {same_hole}");
            // The interpolated source position differs by rounding; where it crosses a texel
            // centre the nearest texel (depth) or the bilinear weights (colour) change a little,
            // most often on the stretched quads of rubber sheets.
            assert!(c4 >= 0.98 && c2 >= 0.999, "{method:?}: colour {c4} {c2}");
            assert!(d6 >= 0.98 && d2 >= 0.999, "{method:?}: depth {d6} {d2}");
            // Holes are black and far on both.
            for (i, &h) in gpu.hole.data().iter().enumerate() {
                if h {
                    assert_eq!((gpu.color.data()[i], gpu.depth.data()[i]), ([0.0; 3], 1.0));
                }
            }
        }
        // Bad input: one clear line.
        let small = Image::new(8, 8, [0.0f32; 3]);
        let bad = Source { cam: &cam, depth: &depth, color: &small };
        let mesh = Mesh::build(&src, &eye, Method::Quads, &p).unwrap();
        assert!(k.raster(&bad, &eye, &mesh).unwrap_err().to_string().contains("colour"));
    }
}
