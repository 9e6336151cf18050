//! The objects one culling pass tests (seed 000 Sec. 5.2: every object's AABB against the
//! predicted depth), as the WOC pipeline reads them: a box and a rigid motion per object id,
//! the id being what the previous frame's item buffer stores.
//!
//! Two sources implement [`CullObjects`]: a zwarp [`Scene`] at a pair of times
//! ([`SceneObjects`], with triangles for the steps that draw or query them) and plain boxes
//! with their previous and current transforms ([`BoxObject`] slices), which is what an engine
//! hands over.

use glam::Mat4;
use zwarp_core::{Aabb, Camera, Scene};

use crate::bounds::ObjectBounds;

/// The objects of one WOC frame: ids `0..len()`, each with a world box in the current frame
/// and a rigid motion from the previous frame to the current one.
pub trait CullObjects: Sync {
    /// Number of objects.
    fn len(&self) -> usize;
    /// `true` without objects.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Whether object `id` moves between the two frames (its own motion, not the camera's).
    fn is_animated(&self, id: u32) -> bool;
    /// World-space box of object `id` in the current frame.
    fn world_box(&self, id: u32) -> Aabb;
    /// World-space motion of object `id` from the previous frame to the current one (the
    /// per-object matrix of the motion field, seed 000 Sec. 3.1); identity when static.
    fn delta(&self, id: u32) -> Mat4;
    /// Object-space box of object `id` and its object -> world transforms in the previous and
    /// the current frame (the corners' screen speed of the rapid-motion test).
    fn transforms(&self, id: u32) -> (Aabb, Mat4, Mat4);
    /// The scene with triangles and the current time, for the steps that draw or query
    /// triangles (rapid-motion objects drawn exactly, the hybrid object-space query, hole
    /// bounds); `None` for bounds-only objects, which skip those steps.
    fn geometry(&self) -> Option<(&Scene, f32)>;
}

/// The instances of a scene between times `t_prev` and `t` (boxes from [`ObjectBounds`]).
#[derive(Clone, Copy, Debug)]
pub struct SceneObjects<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// Its object boxes ([`ObjectBounds::new`] of the same scene).
    pub bounds: &'a ObjectBounds,
    /// Time of the previous frame.
    pub t_prev: f32,
    /// Time of the current frame.
    pub t: f32,
}

impl CullObjects for SceneObjects<'_> {
    fn len(&self) -> usize {
        self.scene.instances.len()
    }
    #[inline]
    fn is_animated(&self, id: u32) -> bool {
        self.bounds.is_animated(id)
    }
    #[inline]
    fn world_box(&self, id: u32) -> Aabb {
        self.bounds.at(self.scene, id, self.t)
    }
    fn delta(&self, id: u32) -> Mat4 {
        self.scene.instances[id as usize].delta(self.t_prev, self.t)
    }
    fn transforms(&self, id: u32) -> (Aabb, Mat4, Mat4) {
        let inst = &self.scene.instances[id as usize];
        (self.scene.meshes[inst.mesh as usize].bounds, inst.transform_at(self.t_prev), inst.transform_at(self.t))
    }
    fn geometry(&self) -> Option<(&Scene, f32)> {
        Some((self.scene, self.t))
    }
}

/// An object as an engine knows it: its object-space bounding box and its object -> world
/// transforms in the previous and the current frame. Its index in the slice is its id, the
/// value the previous frame's item buffer stores on its pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoxObject {
    /// Object-space bounding box.
    pub bounds: Aabb,
    /// Object -> world in the previous frame.
    pub prev_transform: Mat4,
    /// Object -> world in the current frame.
    pub transform: Mat4,
}

impl BoxObject {
    /// A static object whose world-space box is `world`.
    pub fn fixed(world: Aabb) -> Self {
        BoxObject { bounds: world, prev_transform: Mat4::IDENTITY, transform: Mat4::IDENTITY }
    }
}

impl CullObjects for [BoxObject] {
    fn len(&self) -> usize {
        <[BoxObject]>::len(self)
    }
    #[inline]
    fn is_animated(&self, id: u32) -> bool {
        let o = &self[id as usize];
        o.prev_transform != o.transform
    }
    #[inline]
    fn world_box(&self, id: u32) -> Aabb {
        let o = &self[id as usize];
        o.bounds.transformed(&o.transform)
    }
    fn delta(&self, id: u32) -> Mat4 {
        let o = &self[id as usize];
        if o.prev_transform == o.transform {
            Mat4::IDENTITY
        } else {
            o.transform * o.prev_transform.inverse()
        }
    }
    fn transforms(&self, id: u32) -> (Aabb, Mat4, Mat4) {
        let o = &self[id as usize];
        (o.bounds, o.prev_transform, o.transform)
    }
    fn geometry(&self) -> Option<(&Scene, f32)> {
        None
    }
}

/// Screen-space speed (pixels per frame) of object `id` between two views: the largest
/// displacement of its object-space box corners, each moved with the object's transform in
/// each frame (so rotating objects are tracked point by point). Infinite when a corner is
/// behind or in front of the near plane in either view. Pass the same camera twice for the
/// object's own motion only (0 for static objects).
pub fn object_screen_speed(objects: &(impl CullObjects + ?Sized), id: u32, cam_a: &Camera, cam_b: &Camera) -> f32 {
    let animated = objects.is_animated(id);
    if !animated && cam_a == cam_b {
        return 0.0;
    }
    corner_speed(objects.transforms(id), cam_a, cam_b)
}

/// The corner displacement of [`object_screen_speed`] for an object-space box moved by `ma`
/// in view `cam_a` and by `mb` in view `cam_b`.
pub(crate) fn corner_speed((bounds, ma, mb): (Aabb, Mat4, Mat4), cam_a: &Camera, cam_b: &Camera) -> f32 {
    if bounds.is_empty() {
        return 0.0;
    }
    let (vpa, vpb) = (cam_a.view_proj(), cam_b.view_proj());
    let mut speed = 0.0f32;
    for c in bounds.corners() {
        let pa = zwarp_core::camera::project_with(&vpa, cam_a.width, cam_a.height, ma.transform_point3(c));
        let pb = zwarp_core::camera::project_with(&vpb, cam_b.width, cam_b.height, mb.transform_point3(c));
        match (pa, pb) {
            (Some(a), Some(b)) if a.z >= 0.0 && b.z >= 0.0 => {
                speed = speed.max((b.truncate() - a.truncate()).length());
            }
            _ => return f32::INFINITY,
        }
    }
    speed
}
