//! A [`Scene`] uploaded to the GPU once: all meshes in one vertex and one index buffer, and
//! per-object data (transform at time t, albedo) in a storage buffer rewritten per render.

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec3};
use wgpu::util::DeviceExt;
use zwarp_core::{Camera, Error, Instance, Result, Scene};

use crate::GpuContext;

/// Per-object GPU record (layout of `Object` in `depth.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(crate) struct ObjectGpu {
    mvp: [[f32; 4]; 4],
    model: [[f32; 4]; 4],
    albedo: [f32; 4],
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
    pub(crate) indices: wgpu::Buffer,
    pub(crate) draw_ids: wgpu::Buffer,
    pub(crate) objects: wgpu::Buffer,
    pub(crate) batches: Vec<Batch>,
    /// Per object id: `(first_index, index_count, base_vertex as u32, draw slot)`, the draw
    /// the batches issue for it (slot = its position in `draw_ids`); the cull kernel's
    /// indirect arguments are built from these.
    pub(crate) draws: Vec<[u32; 4]>,
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
        // Concatenate meshes; remember where each one starts.
        let mut positions: Vec<[f32; 3]> = Vec::new();
        let mut indices: Vec<u32> = Vec::new();
        let mut mesh_ranges = Vec::with_capacity(scene.meshes.len());
        for m in &scene.meshes {
            let base_vertex = positions.len();
            let first_index = indices.len();
            positions.extend(m.positions.iter().map(|p| p.to_array()));
            indices.extend(m.indices.iter().flatten());
            mesh_ranges.push((first_index as u32, (m.indices.len() * 3) as u32, base_vertex as i32));
        }
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
        let max_buf = ctx.device.limits().max_buffer_size;
        if (positions.len() * 12) as u64 > max_buf || (indices.len() * 4) as u64 > max_buf {
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
            indices: indices_buf,
            draw_ids,
            objects,
            batches,
            draws,
            instances: scene.instances.clone(),
            triangles: scene.triangle_count(),
        })
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
}
