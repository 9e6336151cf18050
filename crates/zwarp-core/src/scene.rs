//! Scene description: meshes, instances (with optional animation), lights.
//! Loaders and procedural generators live in `zwarp-scene`; this is only the data.

use glam::{Mat4, Quat, Vec3};
use serde::{Deserialize, Serialize};

use crate::{Aabb, Error, Result};

/// Item-buffer value of pixels that show no object.
pub const NO_ITEM: u32 = u32::MAX;

/// A triangle mesh in its object space.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Triangles as vertex indices (counter-clockwise = front, but the renderer draws both sides).
    pub indices: Vec<[u32; 3]>,
    /// Object-space bounds of `positions` (fill with [`Mesh::compute_bounds`]).
    pub bounds: Aabb,
}

impl Mesh {
    /// A mesh from positions and triangles, with bounds computed and all data validated:
    /// finite positions and in-range indices.
    pub fn new(positions: Vec<Vec3>, indices: Vec<[u32; 3]>) -> Result<Self> {
        if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
            return Err(Error::invalid(format!("vertex {i} is not finite ({:?})", positions[i])));
        }
        let n = positions.len() as u32;
        if let Some(t) = indices.iter().position(|t| t.iter().any(|&i| i >= n)) {
            return Err(Error::invalid(format!(
                "triangle {t} indexes vertex {:?} but there are only {n} vertices",
                indices[t]
            )));
        }
        let mut m = Mesh { positions, indices, bounds: Aabb::EMPTY };
        m.compute_bounds();
        Ok(m)
    }
    /// Recomputes [`Mesh::bounds`] from the positions.
    pub fn compute_bounds(&mut self) {
        self.bounds = Aabb::from_points(self.positions.iter().copied());
    }
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len()
    }
}

/// Per-instance rigid animation: the instance transform as a function of time `t` (seconds).
/// `transform_at(t) = animation(t) * base_transform`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, Default)]
pub enum Animation {
    /// Does not move.
    #[default]
    Static,
    /// Constant velocity (world units per second).
    Linear {
        /// Velocity.
        velocity: Vec3,
    },
    /// Sinusoidal drift `amplitude * sin(2 pi frequency t + phase)` (balloons bobbing).
    Bob {
        /// Peak offset.
        amplitude: Vec3,
        /// Hz.
        frequency: f32,
        /// Radians.
        phase: f32,
    },
    /// Rotation about a world axis through `center` at `angular_speed` rad/s.
    Spin {
        /// Point on the axis.
        center: Vec3,
        /// Axis direction (normalized on use).
        axis: Vec3,
        /// Radians per second.
        angular_speed: f32,
    },
}

impl Animation {
    /// The world-space motion applied at time `t` (identity for [`Animation::Static`]).
    pub fn matrix_at(&self, t: f32) -> Mat4 {
        match *self {
            Animation::Static => Mat4::IDENTITY,
            Animation::Linear { velocity } => Mat4::from_translation(velocity * t),
            Animation::Bob { amplitude, frequency, phase } => {
                Mat4::from_translation(amplitude * (std::f32::consts::TAU * frequency * t + phase).sin())
            }
            Animation::Spin { center, axis, angular_speed } => {
                Mat4::from_translation(center)
                    * Mat4::from_quat(Quat::from_axis_angle(axis.normalize_or(Vec3::Z), angular_speed * t))
                    * Mat4::from_translation(-center)
            }
        }
    }
    /// `true` unless static.
    pub fn is_animated(&self) -> bool {
        !matches!(self, Animation::Static)
    }
}

/// One object of the scene: a mesh placed in the world. Its object id is its index in
/// [`Scene::instances`]; that id is what the item buffer stores.
#[derive(Clone, Debug)]
pub struct Instance {
    /// Index into [`Scene::meshes`].
    pub mesh: u32,
    /// Object -> world at `t = 0` (before animation).
    pub transform: Mat4,
    /// Optional motion over time.
    pub animation: Animation,
    /// World bounds at `t = 0` (kept in sync by [`Scene::update_bounds`]).
    pub world_aabb: Aabb,
    /// Diffuse albedo (linear RGB) for the simple Lambert shading.
    pub albedo: Vec3,
    /// `true` for ground / background geometry (may be peeled into its own last layer).
    pub is_ground: bool,
}

impl Instance {
    /// Object -> world at time `t`.
    pub fn transform_at(&self, t: f32) -> Mat4 {
        self.animation.matrix_at(t) * self.transform
    }
    /// World-space motion from `t_a` to `t_b`: `M(t_b) * M(t_a)^-1` (identity when static).
    pub fn delta(&self, t_a: f32, t_b: f32) -> Mat4 {
        if self.animation.is_animated() {
            self.transform_at(t_b) * self.transform_at(t_a).inverse()
        } else {
            Mat4::IDENTITY
        }
    }
}

/// Shape of an area light.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum LightShape {
    /// Rectangle of the given full width/height (in the light's right/up axes).
    Rect {
        /// Full width.
        width: f32,
        /// Full height.
        height: f32,
    },
    /// Disc of the given radius.
    Disc {
        /// Radius.
        radius: f32,
    },
}

/// An area light facing `target` (seed 000, Sec. 6). `directional` lights use orthographic
/// shadow maps, local ones perspective shadow maps.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct AreaLight {
    /// Centre of the emitter.
    pub center: Vec3,
    /// Point the light faces (defines its axis).
    pub target: Vec3,
    /// Up hint for the light's frame.
    pub up: Vec3,
    /// Emitter shape.
    pub shape: LightShape,
    /// Orthographic (directional) vs perspective (local) shadow maps.
    #[serde(default)]
    pub directional: bool,
}

/// A whole scene: meshes, instances, lights. Camera paths live beside it (`zwarp-scene`).
#[derive(Clone, Debug)]
pub struct Scene {
    /// Human-readable name (e.g. `cb` or a file name).
    pub name: String,
    /// Shared meshes.
    pub meshes: Vec<Mesh>,
    /// Objects; index = object id = item-buffer value.
    pub instances: Vec<Instance>,
    /// Area lights (may be empty; applications place a default one from the bounds).
    pub lights: Vec<AreaLight>,
    /// World up axis (glTF/OBJ: +Y; Sponza, Munich and the procedural scenes: +Z).
    pub up: Vec3,
}

impl Default for Scene {
    fn default() -> Self {
        Scene { name: String::new(), meshes: Vec::new(), instances: Vec::new(), lights: Vec::new(), up: Vec3::Z }
    }
}

impl Scene {
    /// Adds a mesh, returning its index.
    pub fn add_mesh(&mut self, mesh: Mesh) -> u32 {
        self.meshes.push(mesh);
        (self.meshes.len() - 1) as u32
    }
    /// Adds an instance of `mesh` with world bounds computed; returns its object id.
    pub fn add_instance(
        &mut self,
        mesh: u32,
        transform: Mat4,
        albedo: Vec3,
        animation: Animation,
        is_ground: bool,
    ) -> u32 {
        let world_aabb = self.meshes[mesh as usize].bounds.transformed(&transform);
        self.instances.push(Instance { mesh, transform, animation, world_aabb, albedo, is_ground });
        (self.instances.len() - 1) as u32
    }
    /// Recomputes every instance's `world_aabb` at `t = 0`.
    pub fn update_bounds(&mut self) {
        for inst in &mut self.instances {
            inst.world_aabb = self.meshes[inst.mesh as usize].bounds.transformed(&inst.transform);
        }
    }
    /// World bounds of instance `id` at time `t` (animation applied).
    pub fn instance_aabb_at(&self, id: u32, t: f32) -> Aabb {
        let inst = &self.instances[id as usize];
        if inst.animation.is_animated() {
            self.meshes[inst.mesh as usize].bounds.transformed(&inst.transform_at(t))
        } else {
            inst.world_aabb
        }
    }
    /// World bounds of the whole scene at `t = 0`.
    pub fn bounds(&self) -> Aabb {
        self.instances.iter().fold(Aabb::EMPTY, |b, i| b.union(i.world_aabb))
    }
    /// Total triangles drawn (instances x mesh triangles).
    pub fn triangle_count(&self) -> usize {
        self.instances.iter().map(|i| self.meshes[i.mesh as usize].triangle_count()).sum()
    }
    /// Per-object motion from time `t_a` to `t_b`: `M(t_b) * M(t_a)^-1` for each instance
    /// (identity for static ones). Feed it to [`crate::motion_field`].
    pub fn object_deltas(&self, t_a: f32, t_b: f32) -> Vec<Mat4> {
        self.instances.iter().map(|i| i.delta(t_a, t_b)).collect()
    }
    /// Errors if the scene has nothing to draw.
    pub fn check_nonempty(&self) -> Result<()> {
        if self.instances.is_empty() || self.triangle_count() == 0 {
            Err(Error::invalid(format!("scene '{}' is empty (no triangles)", self.name)))
        } else {
            Ok(())
        }
    }
}
