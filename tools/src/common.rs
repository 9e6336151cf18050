//! Set-up shared by the tools: the culling tools' arguments, the Crytek Sponza scene and the atrium view pair used
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

/// The leading positional arguments of the culling tools, `scene scale width height frames`
/// (defaults: `scene`, 0.25, 960, 540, `frames`), and the rest by position.
pub struct CullArgs {
    args: Vec<String>,
    /// Scene name or path, optionally `@PATH.json` (see [`CullArgs::load`]).
    pub scene: String,
    /// Procedural scale.
    pub scale: f32,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Frames along the path.
    pub frames: usize,
}

impl CullArgs {
    /// Reads the process arguments with the tool's default scene and frame count.
    pub fn from_env(scene: &str, frames: &str) -> std::result::Result<Self, Box<dyn std::error::Error>> {
        let args: Vec<String> = std::env::args().skip(1).collect();
        let get = |i: usize, d: &str| args.get(i).cloned().unwrap_or_else(|| d.to_string());
        Ok(CullArgs {
            scene: get(0, scene),
            scale: get(1, "0.25").parse()?,
            width: get(2, "960").parse()?,
            height: get(3, "540").parse()?,
            frames: get(4, frames).parse()?,
            args,
        })
    }
    /// The scene (procedural at `scale`) and its camera path: `SCENE@PATH.json` takes the path
    /// from the JSON file (as `zwarp report --scenes` does), else the scene's recorded path or
    /// one made from its bounds.
    pub fn load(
        &self,
    ) -> std::result::Result<(zwarp_scene::LoadedScene, zwarp_scene::CameraPath), Box<dyn std::error::Error>> {
        let (spec, path) = match self.scene.rsplit_once('@') {
            Some((s, p)) if p.ends_with(".json") => (s, Some(p)),
            _ => (self.scene.as_str(), None),
        };
        let loaded = load_scene(spec, &SceneOptions { scale: self.scale, ..SceneOptions::default() })?;
        let path = match path {
            Some(p) => zwarp_scene::CameraPath::from_json_file_at(p, loaded.scene.origin)?,
            None => loaded.path_or_default(),
        };
        Ok((loaded, path))
    }
    /// Argument `i` (from 0), or `default`.
    pub fn arg(&self, i: usize, default: &str) -> String {
        self.args.get(i).cloned().unwrap_or_else(|| default.to_string())
    }
    /// Argument `i` if given.
    pub fn get(&self, i: usize) -> Option<&str> {
        self.args.get(i).map(String::as_str)
    }
}

/// The `key=value` arguments of the warp tools (`scenes`, `predict_loop`, `traffic_floor`); an
/// argument without `=` is a one-line error naming the keys.
pub struct KeyArgs(std::collections::HashMap<String, String>);

impl KeyArgs {
    /// Reads the process arguments; `keys` lists the tool's keys for the error line.
    pub fn from_env(keys: &str) -> Self {
        let mut args = std::collections::HashMap::new();
        for a in std::env::args().skip(1) {
            match a.split_once('=') {
                Some((k, v)) => {
                    args.insert(k.to_string(), v.to_string());
                }
                None => {
                    eprintln!("error: arguments are key=value ({keys}), got '{a}'");
                    std::process::exit(1);
                }
            }
        }
        KeyArgs(args)
    }
    /// The value of `key`, or `default`.
    pub fn get(&self, key: &str, default: &str) -> String {
        self.0.get(key).cloned().unwrap_or_else(|| default.to_string())
    }
    /// The value of `key` if given.
    pub fn opt(&self, key: &str) -> Option<&str> {
        self.0.get(key).map(String::as_str)
    }
}

/// The positional arguments `SCENE PATH.json|- W H reps` of the loop tools (`robust_loop`,
/// `motion_loop`, `facade_loop`): the loaded scene, its camera path (`-`: the scene's own) and
/// the image size and repetitions. Wrong arguments: the usage line and exit code 1.
pub struct LoopArgs {
    /// The scene (and its own path, if any).
    pub loaded: zwarp_scene::LoadedScene,
    /// The camera path.
    pub path: zwarp_scene::CameraPath,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Timed repetitions.
    pub reps: usize,
}

impl LoopArgs {
    /// Reads the process arguments of tool `name`.
    pub fn from_env(name: &str) -> Self {
        let a: Vec<String> = std::env::args().collect();
        let usage = || -> ! {
            eprintln!("usage: {name} SCENE PATH.json|- W H reps");
            std::process::exit(1)
        };
        if a.len() != 6 {
            usage();
        }
        let (Ok(width), Ok(height), Ok(reps)) = (a[3].parse(), a[4].parse(), a[5].parse::<usize>()) else { usage() };
        let loaded = load_scene(&a[1], &SceneOptions::default()).unwrap_or_else(|e| {
            eprintln!("error: {e}");
            std::process::exit(1)
        });
        let path = if a[2] == "-" {
            loaded.path_or_default()
        } else {
            zwarp_scene::CameraPath::from_json_file_at(&a[2], loaded.scene.origin).unwrap_or_else(|e| {
                eprintln!("error: {e}");
                std::process::exit(1)
            })
        };
        LoopArgs { loaded, path, width, height, reps: reps.max(1) }
    }

    /// Frames `k` and `k + 1` of the path at 1x speed: their times and cameras.
    pub fn pair(&self, k: usize) -> ((f32, Camera), (f32, Camera)) {
        let at = |k: usize| {
            let t = self.path.time_of_frame(k, 1.0);
            (t, self.path.camera_at(t, self.width, self.height).expect("a camera of the path"))
        };
        (at(k), at(k + 1))
    }
}

/// Median, min and max of `v` (not empty).
pub fn median_min_max(mut v: Vec<f64>) -> (f64, f64, f64) {
    v.sort_by(f64::total_cmp);
    (v[v.len() / 2], v[0], v[v.len() - 1])
}

/// Median, min and max wall milliseconds of `reps` runs of `f` after one untimed warm-up run.
pub fn time_ms(reps: usize, f: &mut dyn FnMut()) -> (f64, f64, f64) {
    f();
    median_min_max(
        (0..reps.max(1))
            .map(|_| {
                let t = std::time::Instant::now();
                f();
                t.elapsed().as_secs_f64() * 1e3
            })
            .collect(),
    )
}
