//! Arguments shared by the commands: scene spec, camera path, image size, backend.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use zwarp_scene::{CameraPath, LoadedScene, SceneOptions};

/// Which scene to use and how to build it.
#[derive(Args, Clone, Debug)]
pub struct SceneArgs {
    /// `yr`, `mo`, `bl`, `cb` (procedural, paper 000's scene kinds) or a path to a scene file or
    /// folder (glTF/GLB, OBJ, PLY, a folder of meshes, a raw Sponza-style buffer folder).
    #[arg(long)]
    pub scene: String,
    /// Seed of the procedural generators.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Scale of the procedural generators (multiplies the object count).
    #[arg(long, default_value_t = 1.0)]
    pub scale: f32,
    /// Camera path JSON (`{"fov_y_deg","near","far","up","fps","keys":[{"t","eye","target"}]}`);
    /// default: the generator's recorded path or one made from the scene bounds.
    #[arg(long)]
    pub path: Option<PathBuf>,
}

/// Output image size.
#[derive(Args, Clone, Copy, Debug)]
pub struct SizeArgs {
    /// Image width in pixels.
    #[arg(long, default_value_t = 1920)]
    pub width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 1080)]
    pub height: u32,
}

impl SizeArgs {
    /// Errors on a zero-size image.
    pub fn check(&self) -> Result<()> {
        if self.width == 0 || self.height == 0 {
            anyhow::bail!("image size must be positive, got {}x{}", self.width, self.height);
        }
        Ok(())
    }
}

/// Where the work runs.
#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Backend {
    /// Pure Rust on the CPU (rayon): the default.
    #[default]
    Cpu,
    /// wgpu / WGSL on the first adapter found (lavapipe on machines without a GPU).
    Gpu,
}

/// A loaded scene with the camera path to use.
pub struct Loaded {
    /// The scene.
    pub scene: zwarp_core::Scene,
    /// The camera path: `--path`, else the recorded one, else the default from the bounds.
    pub path: CameraPath,
}

impl SceneArgs {
    /// Loads the scene and resolves the camera path.
    pub fn load(&self) -> Result<Loaded> {
        if !(self.scale > 0.0 && self.scale.is_finite()) {
            anyhow::bail!("--scale must be a positive number, got {}", self.scale);
        }
        let opts = SceneOptions { seed: self.seed, scale: self.scale, ..SceneOptions::default() };
        let LoadedScene { scene, path } =
            zwarp_scene::load_scene(&self.scene, &opts).with_context(|| format!("loading scene '{}'", self.scene))?;
        if scene.origin != glam::DVec3::ZERO {
            let o = scene.origin;
            eprintln!(
                "note: scene '{}' lies far from its file's origin: moved by -({}, {}, {}) for f32 precision; --path keys are read in the file's coordinates",
                self.scene, o.x, o.y, o.z
            );
        }
        let path = match &self.path {
            // Paths are written in the coordinates of the scene's file.
            Some(p) => CameraPath::from_json_file_at(p, scene.origin)?,
            None => path.unwrap_or_else(|| CameraPath::default_for(&scene)),
        };
        Ok(Loaded { scene, path })
    }
}

/// Parses a comma-separated list (`4,8,16`).
pub fn parse_list<T: std::str::FromStr>(s: &str, what: &str) -> Result<Vec<T>> {
    let v: Result<Vec<T>> = s
        .split(',')
        .map(|x| x.trim())
        .filter(|x| !x.is_empty())
        .map(|x| x.parse::<T>().map_err(|_| anyhow::anyhow!("{what}: '{x}' is not a valid value")))
        .collect();
    let v = v?;
    if v.is_empty() {
        anyhow::bail!("{what}: empty list");
    }
    Ok(v)
}
