//! Object bounds kept across frames for the per-object culling loops (seed 000 Sec. 5.2: every
//! frame tests every object's AABB; thesis seed 002 Sec. IV.3 keeps the per-object data in flat
//! GPU buffers).
//!
//! [`Scene::instance_aabb_at`] reads each 160-byte [`zwarp_core::Instance`] to find its box:
//! over 93K objects that is ~15 MB of scattered cache lines per frame, and the VFC + projection
//! pass of WOC stalled on those loads (the first use of the box took a quarter of the pass in
//! `perf`). An engine keeps the boxes of static objects in a flat array and recomputes only the
//! animated ones; [`ObjectBounds`] is that array (24 bytes per object, read sequentially).

use rayon::prelude::*;
use zwarp_core::{Aabb, Error, Result, Scene};

/// World boxes of a scene's objects: the static ones stored once, the animated ones recomputed
/// at each time ([`ObjectBounds::at`]). Build it once per scene (and again after instances are
/// added, moved or re-animated: it is a snapshot). Every culling method of this crate takes the
/// same boxes from it, so the baselines measured side by side benefit alike.
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectBounds {
    /// World box at `t = 0` of every object (`Instance::world_aabb`).
    boxes: Vec<Aabb>,
    /// One bit per object: animated (box depends on time).
    animated: Vec<u64>,
}

impl ObjectBounds {
    /// Snapshot of the boxes of `scene`'s instances.
    pub fn new(scene: &Scene) -> Self {
        let n = scene.instances.len();
        let boxes: Vec<Aabb> = scene.instances.par_iter().map(|i| i.world_aabb).collect();
        let animated: Vec<u64> = (0..n.div_ceil(64))
            .into_par_iter()
            .map(|w| {
                (0..64)
                    .filter(|b| w * 64 + b < n && scene.instances[w * 64 + b].animation.is_animated())
                    .fold(0u64, |m, b| m | (1 << b))
            })
            .collect();
        ObjectBounds { boxes, animated }
    }

    /// Number of objects.
    pub fn len(&self) -> usize {
        self.boxes.len()
    }

    /// `true` for a scene without objects.
    pub fn is_empty(&self) -> bool {
        self.boxes.is_empty()
    }

    /// Whether object `id` is animated.
    #[inline]
    pub fn is_animated(&self, id: u32) -> bool {
        self.animated[id as usize / 64] >> (id % 64) & 1 != 0
    }

    /// World box of object `id` at time `t`: [`Scene::instance_aabb_at`] without reading the
    /// instance of a static object.
    #[inline]
    pub fn at(&self, scene: &Scene, id: u32, t: f32) -> Aabb {
        if self.is_animated(id) {
            scene.instance_aabb_at(id, t)
        } else {
            self.boxes[id as usize]
        }
    }

    /// World boxes of every object at time `t` (parallel).
    pub fn all_at(&self, scene: &Scene, t: f32) -> Vec<Aabb> {
        (0..self.len() as u32).into_par_iter().with_min_len(1024).map(|id| self.at(scene, id, t)).collect()
    }

    /// Errors unless these bounds were built for a scene with as many objects as `scene`.
    pub fn check(&self, scene: &Scene) -> Result<()> {
        if self.len() != scene.instances.len() {
            return Err(Error::invalid(format!(
                "object bounds hold {} objects but the scene has {}",
                self.len(),
                scene.instances.len()
            )));
        }
        Ok(())
    }
}
