//! zwarp-scene: the scenes zwarp is evaluated on — file loaders, the procedural versions of
//! the depth-warping paper's four scenes, and recorded camera paths.
//!
//! Seed 000 (Iterative Depth Warping), Sec. 4 and Fig. 9, tests four scenes with pre-defined
//! camera movements of 7-13 s: YR (few objects, high polygon count, high depth complexity),
//! MO (game-like, ~6.3K objects on terrain), BL (~35K balloons with tiny baskets, no ground)
//! and CB (urban, ~94K objects). [`load_scene`] builds them procedurally (`yr`, `mo`, `bl`,
//! `cb`, seeded and deterministic) or loads real meshes (glTF, OBJ, PLY, raw soups, folders).
//!
//! Conventions: the procedural scenes, PLY files and raw soups are Z up (ground at z = 0);
//! glTF and OBJ are Y up ([`Scene::up`] says which). Objects are [`zwarp_core::Instance`]s,
//! their index is the item-buffer id.
//!
//! Surfaces (for colour warping, seed 001): meshes from glTF / OBJ / PLY keep their normals,
//! UVs and materials (base-colour factors, textures); everything else (procedural scenes, raw
//! soups, untextured files) is coloured by the renderer's triplanar pattern
//! ([`zwarp_core::ColorMap::Pattern`]) tinted per object.

#![deny(missing_docs)]

pub mod loaders;
pub mod path;
pub mod ply;
pub mod procedural;
pub mod shapes;
pub mod soup;

use std::path::Path;

use glam::{DVec3, Vec3};
use zwarp_core::{Aabb, Error, Result, Scene};

pub use path::{motion_profile, street_level_path, CameraPath, MotionProfile, PathKey};

/// How a triangle soup (raw `VertexBuffer.bin`/`IndexBuffer.bin` folder or a standalone PLY
/// file, which have no object structure) is split into objects for per-object culling
/// (seed 000 Sec. 5). See [`soup`] for the exact rules.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum SplitMode {
    /// The whole soup is one object.
    None,
    /// Connected components by shared vertex index, capped at [`soup::MAX_OBJECTS`] objects by
    /// merging the small ones into spatial clusters.
    #[default]
    Components,
    /// `k` spatially compact clusters of about equal triangle count (connectivity ignored).
    Clusters(usize),
}

/// Options of [`load_scene`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneOptions {
    /// Seed of the procedural generators (same seed = same scene).
    pub seed: u64,
    /// Multiplies the object count of the procedural generators (1.0 = the paper's counts);
    /// ignored by file loaders.
    pub scale: f32,
    /// Splitting of triangle soups into objects.
    pub split: SplitMode,
}

impl Default for SceneOptions {
    fn default() -> Self {
        SceneOptions { seed: 1, scale: 1.0, split: SplitMode::Components }
    }
}

/// A loaded or generated scene and, for the procedural scenes, its recorded camera path
/// (files get none: use [`CameraPath::default_for`] or a JSON path).
#[derive(Clone, Debug)]
pub struct LoadedScene {
    /// The scene.
    pub scene: Scene,
    /// The recorded camera path of a generator, if any.
    pub path: Option<CameraPath>,
}

impl LoadedScene {
    /// The recorded path, or [`CameraPath::default_for`] the scene.
    pub fn path_or_default(&self) -> CameraPath {
        self.path.clone().unwrap_or_else(|| CameraPath::default_for(&self.scene))
    }
}

/// Names accepted as procedural scene specs (seed 000, Fig. 9).
pub const PROCEDURAL: [&str; 4] = ["yr", "mo", "bl", "cb"];

/// Loads a scene. `spec` is `yr|mo|bl|cb` (procedural, seed 000 Sec. 4) or a path to a
/// `.gltf`/`.glb`/`.obj`/`.ply` file or a folder (raw soup or a tree of mesh files).
///
/// Errors (one line, naming the file): missing file, unknown extension, malformed or
/// truncated data, non-finite vertices, out-of-range indices, empty scene.
pub fn load_scene(spec: &str, opts: &SceneOptions) -> Result<LoadedScene> {
    if !(opts.scale.is_finite() && opts.scale > 0.0) {
        return Err(Error::invalid(format!("scene scale must be > 0, got {}", opts.scale)));
    }
    if let SplitMode::Clusters(0) = opts.split {
        return Err(Error::invalid("split into 0 clusters"));
    }
    let lower = spec.to_ascii_lowercase();
    if PROCEDURAL.contains(&lower.as_str()) {
        return procedural::generate(&lower, opts);
    }
    let path = Path::new(spec);
    let scene = if path.is_dir() {
        loaders::load_folder(path, opts)?
    } else if !path.exists() {
        return Err(Error::parse(path, "no such file or folder (scene spec must be yr|mo|bl|cb or a mesh path)"));
    } else {
        match loaders::kind_of(path) {
            Some(kind) => loaders::load_single_file(path, kind, opts)?,
            None => {
                return Err(Error::parse(
                    path,
                    format!(
                        "unsupported extension '{}' (expected .gltf, .glb, .obj, .ply or a folder)",
                        path.extension().map(|e| e.to_string_lossy().into_owned()).unwrap_or_default()
                    ),
                ))
            }
        }
    };
    if scene.instances.is_empty() || scene.triangle_count() == 0 {
        return Err(Error::parse(path, "scene is empty (no triangles)"));
    }
    let mut scene = scene;
    if let Some(offset) = recentring_offset(&scene.bounds()) {
        scene.recentre(offset).map_err(|e| Error::parse(path, e.to_string()))?;
    }
    Ok(LoadedScene { scene, path: None })
}

/// Distance from the origin (scene units) from which an `f32` coordinate steps by 2^-9 (2 mm in
/// metres) or more; a file scene whose bounds reach it along an axis is moved next to the origin
/// along that axis ([`recentring_offset`]).
pub const FAR_FROM_ORIGIN: f32 = 16384.0;

/// The offset [`load_scene`] moves a file scene by ([`Scene::recentre`]): per axis along which
/// `bounds` reach [`FAR_FROM_ORIGIN`], the bounds' centre rounded to a whole unit (exact in
/// `f32` below 2^24, so a file's own round offsets cancel exactly); `None` when no axis does
/// (every procedural scene, Sponza, Munich) or the bounds are empty. Geo-referenced data (UTM
/// metres: 10^5-10^7) would otherwise lose the depth test: at 4,000 km the depth of a point 80 m
/// away varies by more than the whole range between it and the far plane.
pub fn recentring_offset(bounds: &Aabb) -> Option<DVec3> {
    if bounds.is_empty() {
        return None;
    }
    let offset = far_offset(bounds.min.as_dvec3(), bounds.max.as_dvec3());
    (offset != DVec3::ZERO).then_some(offset)
}

/// [`recentring_offset`] of the bounds `lo..hi` in `f64` (file coordinates read in `f64`):
/// zero along the axes that stay within [`FAR_FROM_ORIGIN`].
pub(crate) fn far_offset(lo: DVec3, hi: DVec3) -> DVec3 {
    let far = lo.abs().max(hi.abs()).cmpge(DVec3::splat(FAR_FROM_ORIGIN as f64));
    DVec3::select(far, ((lo + hi) * 0.5).round(), DVec3::ZERO)
}

/// `true` if an object or file name marks ground geometry ("ground" or "terrain", any case).
pub fn is_ground_name(name: &str) -> bool {
    let n = name.to_ascii_lowercase();
    n.contains("ground") || n.contains("terrain")
}

/// Albedo of ground objects without a material colour (muted grey-green).
pub const GROUND_ALBEDO: Vec3 = Vec3::new(0.32, 0.36, 0.28);

/// Deterministic, well-spread albedo for object `id`: hue stepped by the golden ratio so
/// neighbouring ids differ clearly, moderate saturation, linear RGB in about `[0.15, 0.8]`.
pub fn albedo_for_id(id: u32) -> Vec3 {
    let h = (id as f32 * 0.618_034).fract();
    let s = 0.45 + 0.2 * ((id as f32 * 0.414_213_5).fract());
    hsv(h, s, 0.8)
}

/// HSV (all in `[0, 1]`) to RGB.
pub(crate) fn hsv(h: f32, s: f32, v: f32) -> Vec3 {
    let f = |n: f32| {
        let k = (n + h * 6.0) % 6.0;
        v - v * s * k.min(4.0 - k).clamp(0.0, 1.0)
    };
    Vec3::new(f(5.0), f(3.0), f(1.0))
}
