//! A [`Scene`] uploaded to the GPU once: all meshes in one vertex and one index buffer, and
//! per-object data (transform at time t, albedo) in a storage buffer rewritten per render.
//!
//! For colour renders the upload also holds the shading inputs of `depth.wgsl`: a second
//! vertex stream (object-space normal, UV, material entry), the material table (one entry per
//! mesh part), the base-colour textures (linear RGBA `f32` texels in one storage buffer, with
//! an offset / size / wrap table) and per-object shading matrices written per colour render.

use std::collections::HashMap;

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec3};
use wgpu::util::DeviceExt;
use zwarp_core::{Camera, ColorMap, Error, Instance, Result, Scene, Texture};
use zwarp_raster::shading::normal_matrix;

use crate::GpuContext;

/// Per-object GPU record (layout of `Object` in `depth.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(crate) struct ObjectGpu {
    mvp: [[f32; 4]; 4],
    model: [[f32; 4]; 4],
    albedo: [f32; 4],
}

/// Per-vertex shading attributes (vertex buffer 1 of the colour pipelines): object-space
/// normal (zero = none), UV (zero when the mesh has none), material entry.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct AttrGpu {
    normal: [f32; 3],
    uv: [f32; 2],
    material: u32,
}

/// Material table entry (layout of `MaterialGpu` in `depth.wgsl`): `kind` 0 = pattern,
/// 1 = texture `tex`, 2 = uniform base colour.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct MaterialGpu {
    base: [f32; 4],
    kind: u32,
    tex: u32,
    _pad: [u32; 2],
}

/// Texture table entry (layout of `TexInfo`): first texel, size, wrap codes `u | v << 2`.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct TexInfoGpu {
    offset: u32,
    width: u32,
    height: u32,
    wrap: u32,
}

/// Per-object shading matrices (layout of `ShadeObject`): rest-pose model (the pattern's
/// space), normal matrices at time t and at rest (3 columns of 4 floats each).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(crate) struct ShadeObjectGpu {
    rest: [[f32; 4]; 4],
    nmat: [[f32; 4]; 3],
    nrest: [[f32; 4]; 3],
}

/// The material of meshes without parts.
static DEFAULT: zwarp_core::Material = zwarp_core::DEFAULT_MATERIAL;

fn mat3_cols(m: glam::Mat3) -> [[f32; 4]; 3] {
    [m.x_axis.extend(0.0).to_array(), m.y_axis.extend(0.0).to_array(), m.z_axis.extend(0.0).to_array()]
}

/// One indexed draw: every instance of one mesh (ground and non-ground instances in separate
/// batches so the ground can be peeled into its own last layer, seed 000 Sec. 4).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Batch {
    pub first_index: u32,
    pub index_count: u32,
    pub base_vertex: i32,
    pub first_instance: u32,
    pub instance_count: u32,
    pub ground: bool,
}

/// A scene resident on the GPU (meshes uploaded once; see [`crate::Renderer`]).
///
/// Object ids are the indices of [`Scene::instances`], as on the CPU: the item buffer of a GPU
/// render stores the same ids.
#[derive(Debug)]
pub struct GpuScene {
    pub(crate) vertices: wgpu::Buffer,
    /// Vertex stream 1 of the colour pipelines ([`AttrGpu`] per vertex).
    pub(crate) attributes: wgpu::Buffer,
    /// Material table, texture table and texels (bindings 1-3 of the shading group).
    pub(crate) materials: wgpu::Buffer,
    pub(crate) tex_info: wgpu::Buffer,
    pub(crate) texels: wgpu::Buffer,
    /// Per-object shading matrices (binding 0 of the shading group), written per colour render.
    pub(crate) shade_objects: wgpu::Buffer,
    pub(crate) indices: wgpu::Buffer,
    pub(crate) draw_ids: wgpu::Buffer,
    pub(crate) objects: wgpu::Buffer,
    pub(crate) batches: Vec<Batch>,
    /// See [`GpuScene::draws`].
    draws: Vec<[u32; 4]>,
    instances: Vec<Instance>,
    triangles: usize,
}

impl GpuScene {
    /// Uploads `scene`'s meshes and instance list. Errors on an empty scene or one that
    /// exceeds the device's buffer limits.
    pub fn upload(ctx: &GpuContext, scene: &Scene) -> Result<Self> {
        // Mesh indices first: `Scene::check_nonempty` indexes meshes by them.
        for (i, inst) in scene.instances.iter().enumerate() {
            if inst.mesh as usize >= scene.meshes.len() {
                return Err(Error::invalid(format!(
                    "instance {i} uses mesh {} but the scene has {} meshes",
                    inst.mesh,
                    scene.meshes.len()
                )));
            }
        }
        scene.check_nonempty()?;
        for (i, m) in scene.meshes.iter().enumerate() {
            m.validate().map_err(|e| {
                Error::invalid(format!("mesh {i}: {}", e.to_string().trim_start_matches("invalid input: ")))
            })?;
        }
        // Concatenate meshes; remember where each one starts. Every vertex carries one material
        // entry: a vertex shared by triangles of different parts is duplicated.
        let mut positions: Vec<[f32; 3]> = Vec::new();
        let mut attrs: Vec<AttrGpu> = Vec::new();
        let mut indices: Vec<u32> = Vec::new();
        let mut mesh_ranges = Vec::with_capacity(scene.meshes.len());
        let mut materials: Vec<MaterialGpu> = Vec::new();
        let mut textures: Vec<&Texture> = Vec::new();
        let mut texture_slot: HashMap<*const Texture, u32> = HashMap::new();
        for m in &scene.meshes {
            let base_vertex = positions.len();
            let first_index = indices.len();
            let first_entry = materials.len() as u32;
            let mats: Vec<&zwarp_core::Material> =
                if m.parts.is_empty() { vec![&DEFAULT] } else { m.parts.iter().map(|p| &p.material).collect() };
            for mat in mats {
                let (kind, tex) = match (&mat.map, &m.uvs) {
                    (ColorMap::Uniform, _) => (2, 0),
                    (ColorMap::Texture(t), Some(_)) => {
                        let key = std::sync::Arc::as_ptr(t);
                        let slot = *texture_slot.entry(key).or_insert_with(|| {
                            textures.push(t);
                            (textures.len() - 1) as u32
                        });
                        (1, slot)
                    }
                    _ => (0, 0),
                };
                materials.push(MaterialGpu { base: mat.base_color.extend(1.0).to_array(), kind, tex, _pad: [0; 2] });
            }
            let attr = |v: usize, material: u32| AttrGpu {
                normal: m.normals.as_ref().map_or([0.0; 3], |n| n[v].to_array()),
                uv: m.uvs.as_ref().map_or([0.0; 2], |u| u[v].to_array()),
                material,
            };
            positions.extend(m.positions.iter().map(|p| p.to_array()));
            if m.parts.len() <= 1 {
                attrs.extend((0..m.positions.len()).map(|v| attr(v, first_entry)));
                indices.extend(m.indices.iter().flatten());
            } else {
                let mut entry_of = vec![u32::MAX; m.positions.len()];
                let mut copies: HashMap<(u32, u32), u32> = HashMap::new();
                attrs.extend((0..m.positions.len()).map(|v| attr(v, first_entry)));
                for (t, tri) in m.indices.iter().enumerate() {
                    let e = first_entry + m.part_of(t).unwrap_or(0) as u32;
                    for &v in tri {
                        let slot = &mut entry_of[v as usize];
                        let local = if *slot == u32::MAX || *slot == e {
                            *slot = e;
                            attrs[base_vertex + v as usize].material = e;
                            v
                        } else {
                            *copies.entry((v, e)).or_insert_with(|| {
                                positions.push(m.positions[v as usize].to_array());
                                attrs.push(attr(v as usize, e));
                                (positions.len() - 1 - base_vertex) as u32
                            })
                        };
                        indices.push(local);
                    }
                }
            }
            mesh_ranges.push((first_index as u32, (m.indices.len() * 3) as u32, base_vertex as i32));
        }
        let mut tex_info: Vec<TexInfoGpu> = Vec::with_capacity(textures.len());
        let mut texels: Vec<[f32; 4]> = Vec::new();
        for t in &textures {
            let [wu, wv] = t.wrap();
            tex_info.push(TexInfoGpu {
                offset: u32::try_from(texels.len())
                    .map_err(|_| Error::invalid("scene textures exceed 2^32 texels on the GPU"))?,
                width: t.image().width(),
                height: t.image().height(),
                wrap: wu.code() | wv.code() << 2,
            });
            texels.extend_from_slice(t.image().data());
        }
        ctx.check_storage_size((texels.len() * 16) as u64, "scene textures (16 bytes per texel)")?;
        ctx.check_storage_size((materials.len() * 32) as u64, "material table")?;
        if positions.len() > i32::MAX as usize || indices.len() > u32::MAX as usize {
            return Err(Error::invalid("scene has too many vertices for 32-bit GPU indices"));
        }
        // Group instances by (ground, mesh), ids ascending inside a group: one draw per group,
        // `instance_index` runs over `draw_ids`.
        let mut order: Vec<u32> = (0..scene.instances.len() as u32).collect();
        order.sort_by_key(|&i| {
            let inst = &scene.instances[i as usize];
            (inst.is_ground, inst.mesh, i)
        });
        let mut batches: Vec<Batch> = Vec::new();
        let mut draws = vec![[0u32; 4]; order.len()];
        for (slot, &id) in order.iter().enumerate() {
            let inst = &scene.instances[id as usize];
            let (first_index, index_count, base_vertex) = mesh_ranges[inst.mesh as usize];
            draws[id as usize] = [first_index, index_count, base_vertex as u32, slot as u32];
            if index_count == 0 {
                continue;
            }
            match batches.last_mut() {
                Some(b)
                    if b.first_index == first_index
                        && b.base_vertex == base_vertex
                        && b.ground == inst.is_ground
                        && b.first_instance + b.instance_count == slot as u32 =>
                {
                    b.instance_count += 1
                }
                _ => batches.push(Batch {
                    first_index,
                    index_count,
                    base_vertex,
                    first_instance: slot as u32,
                    instance_count: 1,
                    ground: inst.is_ground,
                }),
            }
        }
        let objects_bytes = (scene.instances.len() * std::mem::size_of::<ObjectGpu>()) as u64;
        ctx.check_storage_size(objects_bytes, "per-object buffer")?;
        let shade_bytes = (scene.instances.len() * std::mem::size_of::<ShadeObjectGpu>()) as u64;
        ctx.check_storage_size(shade_bytes, "per-object shading buffer")?;
        let max_buf = ctx.device.limits().max_buffer_size;
        if (attrs.len() * 24) as u64 > max_buf || (indices.len() * 4) as u64 > max_buf {
            return Err(Error::invalid("scene geometry exceeds the GPU buffer size limit"));
        }
        let dev = &ctx.device;
        let vertices = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("zwarp vertices"),
            contents: bytemuck::cast_slice(&positions),
            usage: wgpu::BufferUsages::VERTEX,
        });
        let indices_buf = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("zwarp indices"),
            contents: bytemuck::cast_slice(&indices),
            usage: wgpu::BufferUsages::INDEX,
        });
        let attributes = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("zwarp vertex attributes"),
            contents: bytemuck::cast_slice(&attrs),
            usage: wgpu::BufferUsages::VERTEX,
        });
        // Storage bindings must not be empty: pad the tables with one unused element.
        let storage = |label, bytes: &[u8]| {
            dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytes,
                usage: wgpu::BufferUsages::STORAGE,
            })
        };
        let zero_tex = [TexInfoGpu::zeroed()];
        let zero_texel = [[0.0f32; 4]];
        let materials_buf = storage("zwarp materials", bytemuck::cast_slice(&materials));
        let tex_info_buf = storage(
            "zwarp texture table",
            bytemuck::cast_slice(if tex_info.is_empty() { &zero_tex } else { &tex_info }),
        );
        let texels_buf =
            storage("zwarp texels", bytemuck::cast_slice(if texels.is_empty() { &zero_texel } else { &texels }));
        let shade_objects = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("zwarp shading objects"),
            size: shade_bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let draw_ids = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("zwarp draw ids"),
            contents: bytemuck::cast_slice(&order),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let objects = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("zwarp objects"),
            size: objects_bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Ok(GpuScene {
            vertices,
            attributes,
            materials: materials_buf,
            tex_info: tex_info_buf,
            texels: texels_buf,
            shade_objects,
            indices: indices_buf,
            draw_ids,
            objects,
            batches,
            draws,
            instances: scene.instances.clone(),
            triangles: scene.triangle_count(),
        })
    }

    /// Per object id: `(first_index, index_count, base_vertex as u32, draw slot)`, the draw
    /// the batches issue for it (slot = its position in the draw-id buffer); culling kernels
    /// build their indirect arguments from these.
    pub fn draws(&self) -> &[[u32; 4]] {
        &self.draws
    }

    /// Number of objects (instances).
    pub fn object_count(&self) -> usize {
        self.instances.len()
    }

    /// Triangles drawn per full render.
    pub fn triangle_count(&self) -> usize {
        self.triangles
    }

    /// Per-object motion `M(t_b) M(t_a)^-1` (identity for static objects), as
    /// [`Scene::object_deltas`]: the `object_deltas` input of the motion kernels.
    pub fn object_deltas(&self, t_a: f32, t_b: f32) -> Vec<Mat4> {
        self.instances.iter().map(|i| i.delta(t_a, t_b)).collect()
    }

    /// `true` if some object is ground geometry (then a peeled stack can end in a ground-only
    /// layer).
    pub fn has_ground(&self) -> bool {
        self.batches.iter().any(|b| b.ground)
    }

    /// Writes every object's `view_proj * transform_at(t)` (and model matrix, albedo) for this
    /// camera. The product is formed on the CPU in f32 with glam, the same arithmetic the CPU
    /// rasterizer uses, so both see bit-identical clip-space matrices.
    pub(crate) fn write_objects(&self, ctx: &GpuContext, camera: &Camera, t: f32) -> Result<()> {
        if !t.is_finite() {
            return Err(Error::invalid(format!("render time must be finite, got {t}")));
        }
        let vp = camera.view_proj();
        let data: Vec<ObjectGpu> = self
            .instances
            .iter()
            .enumerate()
            .map(|(id, inst)| {
                let model: Mat4 = inst.transform_at(t);
                if !model.is_finite() {
                    return Err(Error::invalid(format!("instance {id} has a non-finite transform at t={t}")));
                }
                let a: Vec3 = inst.albedo;
                Ok(ObjectGpu {
                    mvp: (vp * model).to_cols_array_2d(),
                    model: model.to_cols_array_2d(),
                    albedo: [a.x, a.y, a.z, 1.0],
                })
            })
            .collect::<Result<_>>()?;
        ctx.queue.write_buffer(&self.objects, 0, bytemuck::cast_slice(&data));
        Ok(())
    }

    /// Writes every object's shading matrices for time `t` (colour renders only): the rest-pose
    /// model `transform` (the pattern's space, so it moves with animated objects) and the normal
    /// matrices ([`normal_matrix`]) of `transform_at(t)` and of the rest pose, as the CPU
    /// resolve forms them.
    pub(crate) fn write_shading(&self, ctx: &GpuContext, t: f32) {
        let data: Vec<ShadeObjectGpu> = self
            .instances
            .iter()
            .map(|inst| ShadeObjectGpu {
                rest: inst.transform.to_cols_array_2d(),
                nmat: mat3_cols(normal_matrix(inst.transform_at(t))),
                nrest: mat3_cols(normal_matrix(inst.transform)),
            })
            .collect();
        ctx.queue.write_buffer(&self.shade_objects, 0, bytemuck::cast_slice(&data));
    }
}
