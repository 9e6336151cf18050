//! Scene description: meshes, instances (with optional animation), lights.
//! Loaders and procedural generators live in `zwarp-scene`; this is only the data.

use glam::{DMat4, DVec3, Mat4, Quat, Vec2, Vec3};
use serde::{Deserialize, Serialize};

use crate::material::{Material, MeshPart, DEFAULT_MATERIAL};
use crate::{Aabb, Error, Result};

/// Item-buffer value of pixels that show no object.
pub const NO_ITEM: u32 = u32::MAX;

/// A triangle mesh in its object space, with optional per-vertex normals and texture
/// coordinates and a material per run of triangles ([`MeshPart`]).
///
/// Without normals the renderer shades with the flat triangle normal; without UVs or parts it
/// colours with [`DEFAULT_MATERIAL`] (the triplanar pattern), so [`Mesh::new`] alone gives a
/// fully shaded mesh.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Triangles as vertex indices (counter-clockwise = front, but the renderer draws both sides).
    pub indices: Vec<[u32; 3]>,
    /// Object-space bounds of `positions` (fill with [`Mesh::compute_bounds`]).
    pub bounds: Aabb,
    /// Per-vertex object-space normals (one per position; normalized on use, a zero normal
    /// falls back to the flat triangle normal), or `None` for flat shading.
    pub normals: Option<Vec<Vec3>>,
    /// Per-vertex texture coordinates (one per position, glTF convention: `(0, 0)` = top-left
    /// of the image), or `None`.
    pub uvs: Option<Vec<Vec2>>,
    /// Materials by triangle run, ascending `first_triangle`, the first at 0 (empty = every
    /// triangle has [`DEFAULT_MATERIAL`]).
    pub parts: Vec<MeshPart>,
}

impl Mesh {
    /// A mesh from positions and triangles, with bounds computed and all data validated:
    /// finite positions and in-range indices. No normals, no UVs, the default material.
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
        let mut m = Mesh { positions, indices, bounds: Aabb::EMPTY, normals: None, uvs: None, parts: Vec::new() };
        m.compute_bounds();
        Ok(m)
    }
    /// Adds per-vertex normals; errors unless there is one finite normal per position.
    pub fn with_normals(mut self, normals: Vec<Vec3>) -> Result<Self> {
        check_attribute("normal", normals.len(), self.positions.len(), normals.iter().position(|n| !n.is_finite()))?;
        self.normals = Some(normals);
        Ok(self)
    }
    /// Adds per-vertex texture coordinates; errors unless there is one finite UV per position.
    pub fn with_uvs(mut self, uvs: Vec<Vec2>) -> Result<Self> {
        check_attribute("uv", uvs.len(), self.positions.len(), uvs.iter().position(|n| !n.is_finite()))?;
        self.uvs = Some(uvs);
        Ok(self)
    }
    /// Gives every triangle `material`.
    pub fn with_material(mut self, material: Material) -> Self {
        self.parts = vec![MeshPart { first_triangle: 0, material }];
        self
    }
    /// Sets the material runs; errors unless they start at triangle 0, ascend strictly, start
    /// inside the mesh and have finite base colours.
    pub fn with_parts(mut self, parts: Vec<MeshPart>) -> Result<Self> {
        self.parts = parts;
        self.check_parts()?;
        Ok(self)
    }
    /// Checks everything the renderers rely on (the fields are public): finite positions,
    /// in-range indices, attribute counts and values, material runs. One-line errors.
    pub fn validate(&self) -> Result<()> {
        if let Some(i) = self.positions.iter().position(|p| !p.is_finite()) {
            return Err(Error::invalid(format!("vertex {i} is not finite ({:?})", self.positions[i])));
        }
        let n = self.positions.len() as u32;
        if let Some(t) = self.indices.iter().position(|t| t.iter().any(|&i| i >= n)) {
            return Err(Error::invalid(format!(
                "triangle {t} indexes vertex {:?} but there are only {n} vertices",
                self.indices[t]
            )));
        }
        self.check_attributes()?;
        self.check_parts()
    }
    /// Checks the normal and UV counts and values (cheaper than [`Mesh::validate`]).
    pub fn check_attributes(&self) -> Result<()> {
        if let Some(ns) = &self.normals {
            check_attribute("normal", ns.len(), self.positions.len(), ns.iter().position(|n| !n.is_finite()))?;
        }
        if let Some(uv) = &self.uvs {
            check_attribute("uv", uv.len(), self.positions.len(), uv.iter().position(|n| !n.is_finite()))?;
        }
        Ok(())
    }
    fn check_parts(&self) -> Result<()> {
        let nt = self.indices.len();
        for (k, p) in self.parts.iter().enumerate() {
            let ok_start =
                if k == 0 { p.first_triangle == 0 } else { p.first_triangle > self.parts[k - 1].first_triangle };
            if !ok_start || (p.first_triangle as usize >= nt && nt > 0) {
                return Err(Error::invalid(format!(
                    "mesh part {k} starts at triangle {} (parts must start at 0, ascend and lie inside the {nt} triangles)",
                    p.first_triangle
                )));
            }
            p.material.validate().map_err(|e| Error::invalid(format!("mesh part {k}: {}", strip_invalid(e))))?;
        }
        Ok(())
    }
    /// The mesh made of triangles `triangles` (indices into [`Mesh::indices`], in the order
    /// given), with only the vertices they use (in order of first use) and every attribute
    /// carried over: normals, UVs and each triangle's material (runs rebuilt). Splitting a mesh
    /// into objects for per-object culling (seed 000 Sec. 5) uses it. Panics on an out-of-range
    /// triangle index (a caller's bug, not input).
    pub fn subset(&self, triangles: &[u32]) -> Mesh {
        let mut remap: std::collections::HashMap<u32, u32> = std::collections::HashMap::with_capacity(triangles.len());
        let mut old = Vec::new();
        let indices: Vec<[u32; 3]> = triangles
            .iter()
            .map(|&t| {
                self.indices[t as usize].map(|v| {
                    *remap.entry(v).or_insert_with(|| {
                        old.push(v);
                        (old.len() - 1) as u32
                    })
                })
            })
            .collect();
        fn pick<T: Copy>(a: &[T], old: &[u32]) -> Vec<T> {
            old.iter().map(|&v| a[v as usize]).collect()
        }
        let mut parts: Vec<MeshPart> = Vec::new();
        let mut last = None;
        for (k, &t) in triangles.iter().enumerate() {
            let part = self.part_of(t as usize);
            if let (Some(p), true) = (part, part != last) {
                parts.push(MeshPart { first_triangle: k as u32, material: self.parts[p].material.clone() });
            }
            last = part;
        }
        let mut m = Mesh {
            positions: pick(&self.positions, &old),
            indices,
            bounds: Aabb::EMPTY,
            normals: self.normals.as_ref().map(|n| pick(n, &old)),
            uvs: self.uvs.as_ref().map(|u| pick(u, &old)),
            parts,
        };
        m.compute_bounds();
        m
    }
    /// Index into [`Mesh::parts`] of the part holding triangle `t` (`None` without parts).
    #[inline]
    pub fn part_of(&self, t: usize) -> Option<usize> {
        if self.parts.is_empty() {
            None
        } else {
            Some(self.parts.partition_point(|p| p.first_triangle as usize <= t).saturating_sub(1))
        }
    }
    /// The material of triangle `t`.
    #[inline]
    pub fn material_of(&self, t: usize) -> &Material {
        match self.part_of(t) {
            Some(k) => &self.parts[k].material,
            None => &DEFAULT_MATERIAL,
        }
    }
    /// The colour of a mostly translucent mesh as one premultiplied RGBA (linear), or `None`
    /// when translucent parts ([`Material::is_translucent`]) cover at most half of its triangles:
    /// the triangle-weighted mean of those parts' `base_color * opacity` and opacity. The
    /// A-buffer keeps one flat colour per object (seed 003 Sec. 4.2), so a mesh is translucent
    /// or opaque as a whole.
    pub fn translucent_color(&self) -> Option<[f32; 4]> {
        let nt = self.indices.len();
        let (mut sum, mut n) = ([0.0f64; 4], 0usize);
        for (k, p) in self.parts.iter().enumerate() {
            if !p.material.is_translucent() {
                continue;
            }
            let end = self.parts.get(k + 1).map_or(nt, |q| q.first_triangle as usize);
            let count = end.saturating_sub(p.first_triangle as usize);
            let (c, a) = (p.material.base_color, p.material.opacity);
            for (s, v) in sum.iter_mut().zip([c.x * a, c.y * a, c.z * a, a]) {
                *s += v as f64 * count as f64;
            }
            n += count;
        }
        (2 * n > nt).then(|| sum.map(|s| (s / n as f64) as f32))
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

fn check_attribute(what: &str, len: usize, positions: usize, non_finite: Option<usize>) -> Result<()> {
    if len != positions {
        return Err(Error::invalid(format!("mesh has {len} {what}s for {positions} vertices (need one per vertex)")));
    }
    if let Some(i) = non_finite {
        return Err(Error::invalid(format!("{what} {i} is not finite")));
    }
    Ok(())
}

fn strip_invalid(e: Error) -> String {
    match e {
        Error::Invalid(m) => m,
        other => other.to_string(),
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
    /// Per-object linear RGB tint: the renderer's albedo is `albedo * material base colour *
    /// (texture | pattern)`. Loaders give objects without a file material a colour per object
    /// id and objects with one white; flat-shading consumers (soft-shadow images) use it alone.
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

/// Moves placed meshes by `d`, in `f64`: each placement is a mesh index and the transform that
/// places it. A mesh that only identity placements use (world-space geometry) has `d` added to
/// its positions and its bounds recomputed; every other placement is composed with the
/// translation. So `d` cancels a placement's or a position's own translation exactly when both
/// are whole units below 2^24. [`Scene::recentre`] and the loaders' file anchors use it.
pub fn translate_placed(meshes: &mut [Mesh], placements: &mut [(u32, &mut Mat4)], d: DVec3) {
    let mut bake = vec![true; meshes.len()];
    for (mesh, transform) in placements.iter() {
        bake[*mesh as usize] &= **transform == Mat4::IDENTITY;
    }
    for (m, _) in meshes.iter_mut().zip(&bake).filter(|(_, &b)| b) {
        m.positions.iter_mut().for_each(|p| *p = (p.as_dvec3() + d).as_vec3());
        m.compute_bounds();
    }
    let by = DMat4::from_translation(d);
    for (_, transform) in placements.iter_mut().filter(|(mesh, _)| !bake[*mesh as usize]) {
        **transform = (by * transform.as_dmat4()).as_mat4();
    }
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
    /// Where this scene's coordinate origin lies in the coordinates it was given in (a file's
    /// geo-referenced metres, say), in `f64`: [`Scene::recentre`] moves a scene that lies far
    /// from its file's origin next to it, since `f32` depth, motion and rasterisation lose
    /// their precision on large coordinates (at 4,000 km an `f32` steps by 0.5 m), and camera
    /// paths written in the file's coordinates are moved by it when read. Zero for a scene
    /// used as given.
    pub origin: DVec3,
}

impl Default for Scene {
    fn default() -> Self {
        Scene {
            name: String::new(),
            meshes: Vec::new(),
            instances: Vec::new(),
            lights: Vec::new(),
            up: Vec3::Z,
            origin: DVec3::ZERO,
        }
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
    /// Moves the whole scene by `-offset` (its coordinates become relative to `offset`) and
    /// adds `offset` to [`Scene::origin`]. Meshes that only identity-transformed instances use
    /// (world-space meshes: every file loader's) have the offset subtracted from their
    /// positions, in `f64`; every other instance's transform is composed with the translation
    /// in `f64`, so an `offset` exactly representable in `f32` (whole units below 2^24) cancels
    /// a translation equal to it exactly. Animations (world-space matrices) are left as they
    /// are: call it before animating. Errors on a non-finite offset.
    pub fn recentre(&mut self, offset: DVec3) -> Result<()> {
        if !offset.is_finite() {
            return Err(Error::invalid(format!("scene '{}': recentring offset {offset:?} is not finite", self.name)));
        }
        let mut placed: Vec<(u32, &mut Mat4)> = self.instances.iter_mut().map(|i| (i.mesh, &mut i.transform)).collect();
        translate_placed(&mut self.meshes, &mut placed, -offset);
        let shift = |p: Vec3| (p.as_dvec3() - offset).as_vec3();
        for l in &mut self.lights {
            l.center = shift(l.center);
            l.target = shift(l.target);
        }
        self.origin += offset;
        self.update_bounds();
        Ok(())
    }
    /// Errors if the scene has nothing to draw.
    pub fn check_nonempty(&self) -> Result<()> {
        // Stops at the first instance with triangles (a full `triangle_count` visits every
        // instance's mesh: ~0.3 ms on a city of 93K instances, at every render).
        if !self.instances.iter().any(|i| self.meshes[i.mesh as usize].triangle_count() > 0) {
            Err(Error::invalid(format!("scene '{}' is empty (no triangles)", self.name)))
        } else {
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recentring_moves_world_space_meshes_transforms_and_lights_exactly() {
        // Whole metres below 2^24 are exact in f32: the offset cancels them to the bit.
        let far = Vec3::new(4.0e6, 12.0, -2.5e6);
        let offset = far.as_dvec3();
        let mut s = Scene { name: "far".into(), ..Scene::default() };
        // A world-space mesh (identity instance) and a mesh placed by a translation, instanced
        // twice, once also rotated.
        let tri = [Vec3::new(0.25, 0.0, 0.5), Vec3::new(1.75, 0.0, 0.5), Vec3::new(0.25, 2.0, 0.5)];
        let world = s.add_mesh(Mesh::new(tri.map(|p| p + far).to_vec(), vec![[0, 1, 2]]).unwrap());
        let local = s.add_mesh(Mesh::new(tri.to_vec(), vec![[0, 1, 2]]).unwrap());
        s.add_instance(world, Mat4::IDENTITY, Vec3::ONE, Animation::Static, false);
        let placed = Mat4::from_translation(far + Vec3::new(3.0, 0.0, -8.0));
        s.add_instance(local, placed, Vec3::ONE, Animation::Static, false);
        let turned = Mat4::from_translation(far) * Mat4::from_rotation_y(0.5);
        s.add_instance(local, turned, Vec3::ONE, Animation::Static, false);
        s.lights.push(AreaLight {
            center: far + Vec3::Y * 10.0,
            target: far,
            up: Vec3::Z,
            shape: LightShape::Disc { radius: 1.0 },
            directional: false,
        });
        s.recentre(offset).unwrap();
        assert_eq!(s.origin, offset);
        assert_eq!(s.meshes[world as usize].positions, tri.to_vec());
        assert_eq!(s.meshes[local as usize].positions, tri.to_vec(), "an instanced mesh is not moved");
        assert_eq!(s.instances[1].transform, Mat4::from_translation(Vec3::new(3.0, 0.0, -8.0)));
        assert!(s.instances[2].transform.abs_diff_eq(Mat4::from_rotation_y(0.5), 1e-7));
        assert_eq!((s.lights[0].center, s.lights[0].target), (Vec3::Y * 10.0, Vec3::ZERO));
        assert_eq!(s.instances[0].world_aabb, s.meshes[world as usize].bounds, "bounds follow");
        // Twice: origins add up.
        s.recentre(DVec3::new(1.0, 0.0, 0.0)).unwrap();
        assert_eq!(s.origin, offset + DVec3::X);
        assert_eq!(s.instances[1].transform, Mat4::from_translation(Vec3::new(2.0, 0.0, -8.0)));
        let e = s.recentre(DVec3::new(f64::NAN, 0.0, 0.0)).unwrap_err().to_string();
        assert!(e.contains("not finite") && !e.contains('\n'), "{e}");
    }

    #[test]
    fn a_scene_is_empty_until_an_instance_has_triangles() {
        let mut scene = Scene { name: "s".into(), ..Scene::default() };
        assert!(scene.check_nonempty().is_err());
        let none = scene.add_mesh(Mesh::new(vec![Vec3::ZERO], Vec::new()).unwrap());
        scene.add_instance(none, Mat4::IDENTITY, Vec3::ONE, Animation::Static, false);
        let e = scene.check_nonempty().unwrap_err().to_string();
        assert!(e.contains("scene 's' is empty") && !e.contains('\n'), "{e}");
        let tri = scene.add_mesh(Mesh::new(vec![Vec3::ZERO, Vec3::X, Vec3::Y], vec![[0, 1, 2]]).unwrap());
        // A mesh nobody instances does not count.
        assert!(scene.check_nonempty().is_err());
        scene.add_instance(tri, Mat4::IDENTITY, Vec3::ONE, Animation::Static, false);
        assert!(scene.check_nonempty().is_ok());
        assert_eq!(scene.triangle_count(), 1);
    }

    #[test]
    fn a_subset_keeps_each_triangles_vertices_attributes_and_material() {
        use crate::material::Material;
        let positions: Vec<Vec3> = (0..6).map(|i| Vec3::new(i as f32, (i * i) as f32, 0.5)).collect();
        let indices = vec![[0, 1, 2], [2, 3, 4], [3, 4, 5]];
        let red = Material { base_color: Vec3::X, ..Material::default() };
        let m = Mesh::new(positions.clone(), indices.clone())
            .unwrap()
            .with_normals((0..6).map(|i| Vec3::new(0.0, 0.0, i as f32 + 1.0)).collect())
            .unwrap()
            .with_uvs((0..6).map(|i| Vec2::new(i as f32 * 0.1, 0.0)).collect())
            .unwrap()
            .with_parts(vec![
                MeshPart { first_triangle: 0, material: Material::default() },
                MeshPart { first_triangle: 2, material: red.clone() },
            ])
            .unwrap();
        let s = m.subset(&[2, 0]);
        s.validate().unwrap();
        assert_eq!(s.indices, vec![[0, 1, 2], [3, 4, 5]]);
        assert_eq!(s.positions, [3, 4, 5, 0, 1, 2].map(|i| positions[i]).to_vec());
        assert_eq!(s.normals.as_ref().unwrap()[0], Vec3::new(0.0, 0.0, 4.0));
        assert_eq!(s.uvs.as_ref().unwrap()[3], Vec2::ZERO);
        assert_eq!(s.material_of(0), &red);
        assert_eq!(s.material_of(1), &Material::default());
        assert_eq!(s.bounds.max, Vec3::new(5.0, 25.0, 0.5));
        // Without parts, none are made.
        assert!(Mesh::new(positions, indices).unwrap().subset(&[1]).parts.is_empty());
    }
}
