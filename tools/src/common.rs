//! Set-up shared by the GPU tools: the Crytek Sponza scene and the atrium view pair used
//! for every side-by-side table (seed 000 Sec. 4 measures at 1920x1080).

use glam::Vec3;
use zwarp_core::{Camera, Result, Scene};
use zwarp_scene::{load_scene, SceneOptions, SplitMode};

/// The Sponza folder (raw `VertexBuffer.bin` + `IndexBuffer.bin`, see `shared/scenes/README.md`)
/// as ONE object: the tools time whole-scene draws, not per-object culling.
pub fn load_sponza(dir: &str) -> Result<Scene> {
    Ok(load_scene(dir, &SceneOptions { split: SplitMode::None, ..Default::default() })?.scene)
}

/// The atrium view at 1920x1080, shifted `dx` metres to the right: eye (dx,-11,2) looking at
/// (dx,11,3), up +z, fov 60, near 0.1, far 100. `dx = 0` is the source view, `0.1` the target.
pub fn atrium_camera(dx: f32) -> Result<Camera> {
    Camera::perspective(
        Vec3::new(dx, -11.0, 2.0),
        Vec3::new(dx, 11.0, 3.0),
        Vec3::Z,
        60f32.to_radians(),
        0.1,
        100.0,
        1920,
        1080,
    )
}
