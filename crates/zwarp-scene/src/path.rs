//! Recorded camera paths (seed 000, Sec. 4: "All scenes used a pre-defined camera movement of
//! 7-13 seconds"; Fig. 11 scales the recorded motion up to 8x).
//!
//! A path is a list of timed keys (eye, target) plus the projection; it is interpolated with a
//! Catmull-Rom spline whose knots are the key times, so it passes through every key and has
//! a continuous velocity. JSON form (exactly):
//! `{"fov_y_deg", "near", "far", "up": [x,y,z], "fps", "keys": [{"t", "eye": [x,y,z], "target": [x,y,z]}]}`.

use std::path::Path;

use glam::{DVec3, Vec3};
use serde::{Deserialize, Serialize};
use zwarp_core::{Camera, Error, Result, Scene};

/// One key of a [`CameraPath`]: where the eye is and what it looks at, at time `t` (seconds).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PathKey {
    /// Time in seconds.
    pub t: f32,
    /// Eye position (world).
    pub eye: Vec3,
    /// Look-at point (world).
    pub target: Vec3,
}

/// A recorded camera movement (seed 000, Sec. 4) with its projection parameters.
///
/// Speed factor (seed 000, Fig. 11 "pre-recorded movements ... scaled up to 8x"): frame `k`
/// is shown at time `t0 + k * speed / fps`, so a speed of 4 moves the camera (and the
/// animated objects, which use the same time) 4x further between consecutive frames.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraPath {
    /// Vertical field of view in degrees, in (0, 180).
    pub fov_y_deg: f32,
    /// Near plane distance (> 0).
    pub near: f32,
    /// Far plane distance (> near).
    pub far: f32,
    /// World up vector for the look-at frame.
    pub up: Vec3,
    /// Frames per second of the recording (> 0).
    pub fps: f32,
    /// Keys with strictly increasing `t` (at least 2).
    pub keys: Vec<PathKey>,
}

/// The JSON form of a [`CameraPath`] with its key positions in `f64`: paths are written in the
/// coordinates of their scene's file, which [`Scene::recentre`](zwarp_core::Scene::recentre)
/// may have moved far from the scene's `f32` coordinates.
#[derive(Serialize, Deserialize)]
struct PathJson {
    fov_y_deg: f32,
    near: f32,
    far: f32,
    up: Vec3,
    fps: f32,
    keys: Vec<KeyJson>,
}

/// One key of [`PathJson`].
#[derive(Serialize, Deserialize)]
struct KeyJson {
    t: f32,
    eye: [f64; 3],
    target: [f64; 3],
}

impl CameraPath {
    /// Reads and validates a JSON path file whose positions are in the scene's own coordinates
    /// ([`CameraPath::from_json_file_at`] with origin zero).
    pub fn from_json_file(path: impl AsRef<Path>) -> Result<Self> {
        Self::from_json_file_at(path, DVec3::ZERO)
    }

    /// Reads and validates a JSON path file written in the coordinates of a scene's file, for
    /// the scene whose [`origin`](zwarp_core::Scene::origin) is `origin`: key positions are
    /// read in `f64` and moved by `-origin` before they become `f32`.
    pub fn from_json_file_at(path: impl AsRef<Path>, origin: DVec3) -> Result<Self> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Self::from_json_str_at(&text, origin).map_err(|e| match e {
            Error::Invalid(msg) => Error::parse(path, msg),
            other => other,
        })
    }

    /// Parses and validates a JSON path in the scene's own coordinates.
    pub fn from_json_str(text: &str) -> Result<Self> {
        Self::from_json_str_at(text, DVec3::ZERO)
    }

    /// Parses and validates a JSON path written in the coordinates of a scene's file (see
    /// [`CameraPath::from_json_file_at`]).
    pub fn from_json_str_at(text: &str, origin: DVec3) -> Result<Self> {
        let j: PathJson =
            serde_json::from_str(text).map_err(|e| Error::invalid(format!("bad camera path JSON: {e}")))?;
        let local = |v: [f64; 3]| (DVec3::from_array(v) - origin).as_vec3();
        let p = CameraPath {
            fov_y_deg: j.fov_y_deg,
            near: j.near,
            far: j.far,
            up: j.up,
            fps: j.fps,
            keys: j.keys.iter().map(|k| PathKey { t: k.t, eye: local(k.eye), target: local(k.target) }).collect(),
        };
        p.validate()?;
        Ok(p)
    }

    /// Pretty JSON in the documented format, in the scene's own coordinates.
    pub fn to_json(&self) -> String {
        self.to_json_at(DVec3::ZERO)
    }

    /// Pretty JSON in the documented format, in the coordinates of the file of a scene whose
    /// [`origin`](zwarp_core::Scene::origin) is `origin` (what [`CameraPath::from_json_str_at`]
    /// reads back).
    pub fn to_json_at(&self, origin: DVec3) -> String {
        // Each f32 as its shortest decimal (what it was read from), then moved in f64.
        let short = |x: f32| x.to_string().parse::<f64>().unwrap_or(x as f64);
        let file = |v: Vec3| (DVec3::new(short(v.x), short(v.y), short(v.z)) + origin).to_array();
        let j = PathJson {
            fov_y_deg: self.fov_y_deg,
            near: self.near,
            far: self.far,
            up: self.up,
            fps: self.fps,
            keys: self.keys.iter().map(|k| KeyJson { t: k.t, eye: file(k.eye), target: file(k.target) }).collect(),
        };
        // Serializing plain numbers cannot fail.
        serde_json::to_string_pretty(&j).unwrap_or_default()
    }

    /// Writes [`CameraPath::to_json`] to a file.
    pub fn write_json_file(&self, path: impl AsRef<Path>) -> Result<()> {
        self.write_json_file_at(path, DVec3::ZERO)
    }

    /// Writes [`CameraPath::to_json_at`] to a file.
    pub fn write_json_file_at(&self, path: impl AsRef<Path>, origin: DVec3) -> Result<()> {
        let path = path.as_ref();
        std::fs::write(path, self.to_json_at(origin)).map_err(|e| Error::io(path, e))
    }

    /// Checks: >= 2 keys, strictly increasing finite `t`, finite eyes/targets, eye != target,
    /// 0 < near < far, 0 < fov < 180, fps > 0, and `up` not parallel to any key's view direction.
    pub fn validate(&self) -> Result<()> {
        let fin = |v: f32| v.is_finite();
        if !(fin(self.fov_y_deg) && self.fov_y_deg > 0.0 && self.fov_y_deg < 180.0) {
            return Err(Error::invalid(format!("camera path: fov_y_deg must be in (0, 180), got {}", self.fov_y_deg)));
        }
        if !(fin(self.near) && fin(self.far) && self.near > 0.0 && self.near < self.far) {
            return Err(Error::invalid(format!(
                "camera path: need 0 < near < far, got near={} far={}",
                self.near, self.far
            )));
        }
        if !(fin(self.fps) && self.fps > 0.0) {
            return Err(Error::invalid(format!("camera path: fps must be > 0, got {}", self.fps)));
        }
        if !self.up.is_finite() || self.up.length_squared() < 1e-12 {
            return Err(Error::invalid(format!("camera path: up must be a finite non-zero vector, got {:?}", self.up)));
        }
        if self.keys.len() < 2 {
            return Err(Error::invalid(format!("camera path: need at least 2 keys, got {}", self.keys.len())));
        }
        let up = self.up.normalize();
        for (i, k) in self.keys.iter().enumerate() {
            if !(fin(k.t) && k.eye.is_finite() && k.target.is_finite()) {
                return Err(Error::invalid(format!("camera path: key {i} has a non-finite number")));
            }
            if i > 0 && k.t <= self.keys[i - 1].t {
                return Err(Error::invalid(format!(
                    "camera path: key times must increase strictly (key {i}: t={} after t={})",
                    k.t,
                    self.keys[i - 1].t
                )));
            }
            let d = k.target - k.eye;
            if d.length_squared() < 1e-12 {
                return Err(Error::invalid(format!("camera path: key {i} has eye == target")));
            }
            if d.normalize().cross(up).length() < 1e-4 {
                return Err(Error::invalid(format!("camera path: key {i} looks along the up vector")));
            }
        }
        Ok(())
    }

    /// Time of the first key.
    pub fn start(&self) -> f32 {
        self.keys.first().map_or(0.0, |k| k.t)
    }

    /// Time of the last key.
    pub fn end(&self) -> f32 {
        self.keys.last().map_or(0.0, |k| k.t)
    }

    /// Length of the path in seconds.
    pub fn duration(&self) -> f32 {
        self.end() - self.start()
    }

    /// Frames in the recording at speed 1: `floor(duration * fps) + 1` (both ends included).
    pub fn frame_count(&self) -> usize {
        self.frame_count_at(1.0)
    }

    /// Frames needed to cover the path at a motion speed factor (see [`CameraPath::frames`]).
    pub fn frame_count_at(&self, speed: f32) -> usize {
        if !(speed > 0.0 && speed.is_finite()) {
            return 0;
        }
        // The small epsilon keeps the last key when duration * fps is integral up to rounding.
        (self.duration() * self.fps / speed + 1e-3).floor() as usize + 1
    }

    /// Time of frame `k` at speed factor `speed`: `t0 + k * speed / fps` (not clamped).
    pub fn time_of_frame(&self, k: usize, speed: f32) -> f32 {
        self.start() + k as f32 * speed / self.fps
    }

    /// Interpolated eye and target at time `t` (clamped to the path's time range).
    pub fn eye_target_at(&self, t: f32) -> (Vec3, Vec3) {
        let keys = &self.keys;
        match keys.len() {
            0 => return (Vec3::ZERO, Vec3::NEG_Z),
            1 => return (keys[0].eye, keys[0].target),
            _ => {}
        }
        let t = if t.is_finite() { t.clamp(self.start(), self.end()) } else { self.start() };
        // Segment i spans [t_i, t_{i+1}]; partition_point finds the first key after t.
        let i = keys.partition_point(|k| k.t <= t).clamp(1, keys.len() - 1) - 1;
        let eye = catmull_rom(keys, i, t, |k| k.eye);
        let target = catmull_rom(keys, i, t, |k| k.target);
        (eye, target)
    }

    /// The camera at time `t` rendering a `width x height` image.
    pub fn camera_at(&self, t: f32, width: u32, height: u32) -> Result<Camera> {
        let (eye, target) = self.eye_target_at(t);
        Camera::perspective(eye, target, self.up, self.fov_y_deg.to_radians(), self.near, self.far, width, height)
    }

    /// Every frame `(t, camera)` of the path at speed factor `speed` (1x..16x), up to the
    /// path's end. Errors on a non-positive speed or a bad image size.
    pub fn frames(&self, width: u32, height: u32, speed: f32) -> Result<Vec<(f32, Camera)>> {
        if !(speed > 0.0 && speed.is_finite()) {
            return Err(Error::invalid(format!("camera path: speed factor must be > 0, got {speed}")));
        }
        (0..self.frame_count_at(speed))
            .map(|k| {
                let t = self.time_of_frame(k, speed).min(self.end());
                self.camera_at(t, width, height).map(|c| (t, c))
            })
            .collect()
    }

    /// A sensible default path for any scene: a 10 s, 30 Hz half orbit around the centre of
    /// the bounds, **outside** them — horizontal radius one bounds diagonal `d`, eye `d / 4`
    /// above the centre along `scene.up` — looking at the centre. The bounding sphere (radius
    /// `d / 2`) then fits the 60 degree field of view from every eye, and the camera never starts
    /// inside a closed model (an orbit inside the bounds put it in the walls of a building such
    /// as Sponza, whose depth buffers then showed one wall from a few centimetres). Near is
    /// `d / 20` (no geometry is nearer than `d / 2`), far `2 d`.
    pub fn default_for(scene: &Scene) -> CameraPath {
        let b = scene.bounds();
        let (b_min, b_max) = if b.is_empty() { (Vec3::splat(-1.0), Vec3::splat(1.0)) } else { (b.min, b.max) };
        let up = scene.up.normalize_or(Vec3::Z);
        let centre = (b_min + b_max) * 0.5;
        let diag = (b_max - b_min).length().max(1e-3);
        // Horizontal frame (u, v) perpendicular to up.
        let u = up.any_orthonormal_vector();
        let v = up.cross(u);
        let fps = 30.0;
        let keys = (0..=10)
            .map(|i| {
                let a = std::f32::consts::PI * i as f32 / 10.0;
                let eye = centre + up * (0.25 * diag) + (u * a.cos() + v * a.sin()) * diag;
                PathKey { t: i as f32, eye, target: centre }
            })
            .collect();
        CameraPath { fov_y_deg: 60.0, near: diag * 0.05, far: diag * 2.0, up, fps, keys }
    }
}

/// Per-frame screen motion of a path over a scene (seed 000 Sec. 4 reports "the averages of
/// maximal per-frame motion": 16, 35, 26 and 29 pixels/frame for YR, MO, BL, CB at full HD).
#[derive(Clone, Debug, PartialEq)]
pub struct MotionProfile {
    /// For each pair of consecutive frames, the largest motion (pixels) of a sample point
    /// that is inside the image in both frames.
    pub max_per_frame: Vec<f32>,
}

impl MotionProfile {
    /// Mean over frames of the per-frame maximum (the paper's figure).
    pub fn mean_max(&self) -> f32 {
        if self.max_per_frame.is_empty() {
            return 0.0;
        }
        self.max_per_frame.iter().sum::<f32>() / self.max_per_frame.len() as f32
    }
    /// Largest per-frame motion of the whole path.
    pub fn peak(&self) -> f32 {
        self.max_per_frame.iter().copied().fold(0.0, f32::max)
    }
}

/// Estimates the per-frame screen motion of `path` at `speed` over `scene` (camera and
/// object motion, seed 000 Sec. 3.1's motion field sampled at points). Sample points are the
/// 8 object-space box corners of every object (moved with its animation) and the vertices of
/// ground meshes; occlusion is ignored, so it is an upper-bound-style estimate of the
/// rendered motion field's per-frame maximum, good for comparing paths with the paper's.
pub fn motion_profile(scene: &Scene, path: &CameraPath, width: u32, height: u32, speed: f32) -> Result<MotionProfile> {
    use rayon::prelude::*;
    let frames = path.frames(width, height, speed)?;
    let (w, h) = (width as f32, height as f32);
    let inside =
        |p: Option<Vec3>| p.filter(|p| p.x >= 0.0 && p.x < w && p.y >= 0.0 && p.y < h && (0.0..=1.0).contains(&p.z));
    let max_per_frame = frames
        .par_windows(2)
        .map(|pair| {
            let ((ta, ca), (tb, cb)) = (pair[0], pair[1]);
            let mut best = 0.0f32;
            for inst in &scene.instances {
                let mesh = &scene.meshes[inst.mesh as usize];
                let (ma, mb) = (inst.transform_at(ta), inst.transform_at(tb));
                let mut visit = |p: Vec3| {
                    if let (Some(a), Some(b)) =
                        (inside(ca.project(ma.transform_point3(p))), inside(cb.project(mb.transform_point3(p))))
                    {
                        best = best.max((b.truncate() - a.truncate()).length());
                    }
                };
                if inst.is_ground {
                    mesh.positions.iter().for_each(|&p| visit(p));
                } else {
                    mesh.bounds.corners().into_iter().for_each(&mut visit);
                }
            }
            best
        })
        .collect();
    Ok(MotionProfile { max_per_frame })
}

/// Street-level walk for a loaded city-like scene: a camera about a person's eye height (~1.8 m)
/// above the ground walking along the streets (seed 000 Sec. 5 tests occlusion culling in such
/// street canyons).
///
/// The scene's objects (boxes at t = 0, inflated by `clearance`) are rasterized into a
/// horizontal occupancy grid at eye height; the straight axis-aligned free corridor of length
/// `speed * duration` that has walls on both sides (a street canyon) and runs along the middle
/// of its street is chosen, preferring corridors near the centre of the scene. It needs a
/// ground object (`is_ground`) or a floor at the scene's lowest point: in a soup whose floor is
/// not flagged (Sponza) the floor blocks every cell; use a hand-made path there. The camera walks it at `eye_height` above the ground
/// level (lowest point of the ground objects, or of the scene), looking ahead with a slow
/// side-to-side head turn. Works for Z-up and Y-up scenes. Errors if no corridor exists.
pub fn street_level_path(
    scene: &Scene,
    eye_height: f32,
    speed: f32,
    duration: f32,
    clearance: f32,
) -> Result<CameraPath> {
    let finite_pos = |v: f32| v.is_finite() && v > 0.0;
    if !(finite_pos(eye_height)
        && finite_pos(speed)
        && finite_pos(duration)
        && clearance.is_finite()
        && clearance >= 0.0)
    {
        return Err(Error::invalid("street-level path: eye height, speed, duration must be > 0 and clearance >= 0"));
    }
    let up = scene.up.normalize_or(Vec3::Z);
    let a_up = up.abs().max_position();
    if up.abs()[a_up] < 0.999 {
        return Err(Error::invalid("street-level path: the scene's up vector must be a coordinate axis"));
    }
    let sign = up[a_up].signum();
    let (a0, a1) = ((a_up + 1) % 3, (a_up + 2) % 3);
    let b = scene.bounds();
    if b.is_empty() {
        return Err(Error::invalid("street-level path: the scene is empty"));
    }
    // Heights are measured along `up` (sign handles a -axis up).
    let hmin = |bb: &zwarp_core::Aabb| if sign > 0.0 { bb.min[a_up] } else { -bb.max[a_up] };
    let hmax = |bb: &zwarp_core::Aabb| if sign > 0.0 { bb.max[a_up] } else { -bb.min[a_up] };
    let ground =
        scene.instances.iter().filter(|i| i.is_ground).map(|i| hmin(&i.world_aabb)).fold(f32::INFINITY, f32::min);
    let ground = if ground.is_finite() { ground } else { hmin(&b) };
    let len = speed * duration;
    let (lo0, lo1) = (b.min[a0] - 1.0, b.min[a1] - 1.0);
    let (ext0, ext1) = (b.max[a0] - lo0 + 1.0, b.max[a1] - lo1 + 1.0);
    // About 1 m cells, at most 2048 per side.
    let cell = (ext0.max(ext1) / 2048.0).max(0.5).min(len / 8.0).max(1e-3);
    let (n0, n1) = ((ext0 / cell).ceil() as usize + 1, (ext1 / cell).ceil() as usize + 1);
    let mut occ = vec![false; n0 * n1];
    let cell_of = |v: f32, lo: f32, n: usize| (((v - lo) / cell).floor().max(0.0) as usize).min(n - 1);
    for inst in scene.instances.iter().filter(|i| !i.is_ground) {
        let bb = inst.world_aabb;
        // Only what blocks a walker: reaches above the ankles and below the head.
        if hmax(&bb) < ground + 0.3 || hmin(&bb) > ground + eye_height + 1.0 {
            continue;
        }
        let (i0, i1) = (cell_of(bb.min[a0] - clearance, lo0, n0), cell_of(bb.max[a0] + clearance, lo0, n0));
        let (j0, j1) = (cell_of(bb.min[a1] - clearance, lo1, n1), cell_of(bb.max[a1] + clearance, lo1, n1));
        for j in j0..=j1 {
            occ[j * n0 + i0..=j * n0 + i1].fill(true);
        }
    }
    // The grid has a 1 m margin around the bounds: corridors must stay inside the bounds (an
    // enclosed building's outside is not a street), but the margin is no wall either.
    let inside = |i: usize, j: usize| {
        let (u, v) = (lo0 + (i as f32 + 0.5) * cell, lo1 + (j as f32 + 0.5) * cell);
        u >= b.min[a0] && u <= b.max[a0] && v >= b.min[a1] && v <= b.max[a1]
    };
    let need = (len / cell).ceil() as usize + 1;
    let reach = (20.0 / cell).ceil() as usize; // canyon walls searched up to 20 m aside
    let at = |i: usize, j: usize| occ[j * n0 + i];
    // Best corridor: (score, axis 0 or 1, fixed index, start index along the corridor).
    let mut best: Option<(f32, usize, usize, usize)> = None;
    let centre = (n0 as f32 * 0.5, n1 as f32 * 0.5);
    for axis in 0..2 {
        let (n_along, n_across) = if axis == 0 { (n0, n1) } else { (n1, n0) };
        let get = |along: usize, across: usize| if axis == 0 { at(along, across) } else { at(across, along) };
        let blocked = |along: usize, across: usize| {
            get(along, across) || if axis == 0 { !inside(along, across) } else { !inside(across, along) }
        };
        for across in 1..n_across.saturating_sub(1) {
            let mut run_start = 0;
            for along in 0..=n_along {
                if along < n_along && !blocked(along, across) {
                    continue;
                }
                let run = along - run_start;
                if run >= need {
                    let start = run_start + (run - need) / 2;
                    // Street score per sample along the corridor: a wall on both sides
                    // within `reach` (a canyon, not an open field), and the distance to the
                    // nearer wall (walk the middle of wide streets, not alleys).
                    let (mut canyon, mut middle, mut samples) = (0.0f32, 0.0f32, 0.0f32);
                    let step = (need / 16).max(1);
                    for k in (start..start + need).step_by(step) {
                        let side = |dir: i64| {
                            (1..=reach).find(|&d| {
                                let c = across as i64 + dir * d as i64;
                                c >= 0 && c < n_across as i64 && get(k, c as usize)
                            })
                        };
                        let (l, r) = (side(-1), side(1));
                        if l.is_some() && r.is_some() {
                            canyon += 1.0;
                        }
                        let near = l.unwrap_or(reach).min(r.unwrap_or(reach)) as f32 * cell;
                        middle += near.min(6.0) / 6.0;
                        samples += 1.0;
                    }
                    let mut score = (canyon + 0.5 * middle) / samples;
                    // Mild preference for the middle of the scene.
                    let mid = start as f32 + need as f32 * 0.5;
                    let (c_along, c_across) = if axis == 0 { centre } else { (centre.1, centre.0) };
                    let off = ((mid - c_along) / n_along as f32).powi(2)
                        + ((across as f32 - c_across) / n_across as f32).powi(2);
                    score *= 1.0 / (1.0 + 4.0 * off);
                    if best.is_none_or(|b| score > b.0) {
                        best = Some((score, axis, across, start));
                    }
                }
                run_start = along + 1;
            }
        }
    }
    let (_, axis, across, start) = best.ok_or_else(|| {
        Error::invalid(format!("street-level path: no free straight corridor of {len} m at eye height in the scene"))
    })?;
    let world = |along: f32, across: f32, h: f32| {
        let (u, v) = if axis == 0 { (along, across) } else { (across, along) };
        let mut p = Vec3::ZERO;
        p[a0] = lo0 + u * cell;
        p[a1] = lo1 + v * cell;
        p[a_up] = sign * h;
        p
    };
    let along0 = start as f32 + 0.5;
    let across_c = across as f32 + 0.5;
    let p0 = world(along0, across_c, ground + eye_height);
    let p1 = world(along0 + len / cell, across_c, ground + eye_height);
    let dir = (p1 - p0).normalize();
    let side = up.cross(dir);
    let keys = (0..=duration.ceil() as usize)
        .map(|k| {
            let t = (k as f32).min(duration);
            let eye = p0 + dir * (speed * t);
            // Look 15 m ahead, slightly down, turning the head +-15 degrees every ~10 s.
            let target = eye + dir * 15.0 + side * (4.0 * (0.6 * t).sin()) - up * 0.5;
            PathKey { t, eye, target }
        })
        .collect::<Vec<_>>();
    let diag = b.extent().length();
    let path = CameraPath { fov_y_deg: 60.0, near: 0.1, far: diag.max(10.0), up, fps: 30.0, keys };
    path.validate()?;
    Ok(path)
}

/// Catmull-Rom (cardinal spline with tension 0) on segment `i` at time `t`, knots at the key
/// times: Hermite interpolation with tangents `(p_{i+1} - p_{i-1}) / (t_{i+1} - t_{i-1})`
/// (one-sided at the ends). It passes through every key and has continuous velocity, and it
/// equals the uniform Catmull-Rom spline when keys are evenly spaced.
fn catmull_rom(keys: &[PathKey], i: usize, t: f32, f: impl Fn(&PathKey) -> Vec3) -> Vec3 {
    let n = keys.len();
    let (k0, k1) = (&keys[i], &keys[i + 1]);
    let tangent = |j: usize| {
        let (a, b) = (j.saturating_sub(1), (j + 1).min(n - 1));
        (f(&keys[b]) - f(&keys[a])) / (keys[b].t - keys[a].t)
    };
    let h = k1.t - k0.t;
    let s = ((t - k0.t) / h).clamp(0.0, 1.0);
    let (s2, s3) = (s * s, s * s * s);
    let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
    let h10 = s3 - 2.0 * s2 + s;
    let h01 = -2.0 * s3 + 3.0 * s2;
    let h11 = s3 - s2;
    f(k0) * h00 + tangent(i) * (h10 * h) + f(k1) * h01 + tangent(i + 1) * (h11 * h)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn line_path() -> CameraPath {
        CameraPath {
            fov_y_deg: 60.0,
            near: 0.1,
            far: 100.0,
            up: Vec3::Z,
            fps: 30.0,
            keys: (0..5)
                .map(|i| PathKey {
                    t: i as f32 * 2.0,
                    eye: Vec3::new(i as f32 * 3.0, 0.0, 2.0),
                    target: Vec3::new(i as f32 * 3.0 + 10.0, 0.0, 2.0),
                })
                .collect(),
        }
    }

    #[test]
    fn json_format_is_exact_and_roundtrips() {
        let p = line_path();
        let json = p.to_json();
        let v: serde_json::Value = serde_json::from_str(&json).unwrap();
        let obj = v.as_object().unwrap();
        let mut keys: Vec<_> = obj.keys().cloned().collect();
        keys.sort();
        assert_eq!(keys, ["far", "fov_y_deg", "fps", "keys", "near", "up"]);
        assert_eq!(v["up"], serde_json::json!([0.0, 0.0, 1.0]));
        assert_eq!(v["keys"][1], serde_json::json!({"t": 2.0, "eye": [3.0, 0.0, 2.0], "target": [13.0, 0.0, 2.0]}));
        assert_eq!(CameraPath::from_json_str(&json).unwrap(), p);
    }

    #[test]
    fn linear_keys_give_exact_linear_motion() {
        // Evenly spaced collinear keys: the Catmull-Rom tangents equal the constant velocity,
        // so the spline is exactly the line (up to rounding).
        let p = line_path();
        for k in 0..=80 {
            let t = k as f32 * 0.1;
            let (eye, target) = p.eye_target_at(t);
            assert!((eye - Vec3::new(1.5 * t, 0.0, 2.0)).length() < 1e-4, "t={t} eye={eye}");
            assert!((target - eye - Vec3::new(10.0, 0.0, 0.0)).length() < 1e-4);
        }
        // Clamped outside the time range.
        assert_eq!(p.eye_target_at(-5.0).0, p.keys[0].eye);
        assert_eq!(p.eye_target_at(99.0).0, p.keys[4].eye);
    }

    #[test]
    fn frame_counts_and_times_with_speed() {
        let p = line_path(); // 8 s at 30 Hz
        assert_eq!(p.duration(), 8.0);
        assert_eq!(p.frame_count(), 241);
        assert_eq!(p.frame_count_at(4.0), 61);
        assert_eq!(p.frame_count_at(16.0), 16); // 15 * 16/30 = 8.0 s
        assert_eq!(p.frame_count_at(3.0), 81);
        assert!((p.time_of_frame(30, 1.0) - 1.0).abs() < 1e-6);
        assert!((p.time_of_frame(30, 8.0) - 8.0).abs() < 1e-5);
        let f = p.frames(32, 24, 4.0).unwrap();
        assert_eq!(f.len(), 61);
        assert!((f[1].0 - 4.0 / 30.0).abs() < 1e-6);
        assert_eq!(f.last().unwrap().0, 8.0);
        assert!((f.last().unwrap().1.eye() - Vec3::new(12.0, 0.0, 2.0)).length() < 1e-3);
        assert!(p.frames(32, 24, 0.0).is_err());
        assert!(p.frames(0, 24, 1.0).is_err());
    }

    #[test]
    fn validation_errors_are_clear() {
        let ok = line_path();
        type Mutation = Box<dyn Fn(&mut CameraPath)>;
        let cases: Vec<(Mutation, &str)> = vec![
            (Box::new(|p| p.keys.truncate(1)), "at least 2 keys"),
            (Box::new(|p| p.keys[2].t = p.keys[1].t), "increase strictly"),
            (Box::new(|p| p.near = 200.0), "near < far"),
            (Box::new(|p| p.near = 0.0), "near < far"),
            (Box::new(|p| p.fov_y_deg = 180.0), "fov_y_deg"),
            (Box::new(|p| p.fov_y_deg = 0.0), "fov_y_deg"),
            (Box::new(|p| p.fps = 0.0), "fps"),
            (Box::new(|p| p.keys[3].eye.x = f32::NAN), "non-finite"),
            (Box::new(|p| p.keys[1].target = p.keys[1].eye + Vec3::Z), "up vector"),
            (Box::new(|p| p.keys[1].target = p.keys[1].eye), "eye == target"),
            (Box::new(|p| p.up = Vec3::ZERO), "up must be"),
        ];
        for (mutate, want) in cases {
            let mut p = ok.clone();
            mutate(&mut p);
            let msg = p.validate().unwrap_err().to_string();
            assert!(msg.contains(want), "{msg:?} should mention {want:?}");
            assert!(!msg.contains('\n'));
        }
        let e = CameraPath::from_json_str("{\"fov_y_deg\": 60}").unwrap_err().to_string();
        assert!(e.contains("bad camera path JSON"), "{e}");
    }

    #[test]
    fn json_file_errors_name_the_file() {
        let guard = tempfile::Builder::new().prefix("zwarp-scene-path-").tempdir().unwrap();
        let dir = guard.path();
        let f = dir.join("bad_path.json");
        std::fs::write(
            &f,
            "{\"fov_y_deg\": 60, \"near\": 1, \"far\": 0.5, \"up\": [0,0,1], \"fps\": 30, \"keys\": []}",
        )
        .unwrap();
        let e = CameraPath::from_json_file(&f).unwrap_err().to_string();
        assert!(e.contains("bad_path.json") && e.contains("near < far"), "{e}");
        let missing = CameraPath::from_json_file(dir.join("nope.json")).unwrap_err().to_string();
        assert!(missing.contains("nope.json"), "{missing}");
        let good = dir.join("good_path.json");
        line_path().write_json_file(&good).unwrap();
        assert_eq!(CameraPath::from_json_file(&good).unwrap(), line_path());
    }

    #[test]
    fn motion_profile_of_a_sideways_camera_is_analytic() {
        // A point 10 m in front of a camera moving sideways at 1.5 m/s: per frame (1/30 s)
        // it moves 0.05 m, i.e. 0.05 / 10 / tan(30 deg) * 240 px (half height 240 px).
        let mut s = Scene::default();
        let m = s.add_mesh(zwarp_core::Mesh::new(vec![Vec3::ZERO], vec![]).unwrap());
        s.add_instance(m, glam::Mat4::from_translation(Vec3::new(0.0, 10.0, 2.0)), Vec3::ONE, Default::default(), true);
        let mut p = line_path();
        for k in &mut p.keys {
            k.eye.y = 0.0;
            k.target = k.eye + Vec3::new(0.0, 10.0, 0.0);
        }
        let prof = motion_profile(&s, &p, 640, 480, 1.0).unwrap();
        assert_eq!(prof.max_per_frame.len(), 240);
        let want = 0.05 / 10.0 / (30f32.to_radians().tan()) * 240.0;
        // The point leaves the image after a while; while visible the motion is constant.
        let visible: Vec<f32> = prof.max_per_frame.iter().copied().filter(|&m| m > 0.0).collect();
        assert!(visible.len() > 50);
        for v in visible {
            assert!((v - want).abs() < 1e-2 * want, "{v} vs {want}");
        }
        let fast = motion_profile(&s, &p, 640, 480, 4.0).unwrap();
        assert!((fast.peak() - 4.0 * want).abs() < 4e-2 * want);
    }

    #[test]
    fn street_level_path_walks_the_canyon() {
        // Two rows of 20 m tall buildings along x with a 12 m street between y = -6 and 6,
        // plus a ground plane and a narrower 4 m alley at y = 30 between the north row and a
        // third row.
        let mut s = Scene::default();
        let cube = s.add_mesh(crate::shapes::unit_box().build().unwrap());
        let quad =
            s.add_mesh(crate::shapes::height_field(-100.0, -100.0, 100.0, 100.0, 1, 1, |_, _| 0.0).build().unwrap());
        s.add_instance(quad, glam::Mat4::IDENTITY, Vec3::ONE, Default::default(), true);
        for (yc, depth) in [(-16.0, 20.0), (17.0, 22.0), (48.0, 28.0)] {
            for k in 0..8 {
                let x = -70.0 + k as f32 * 20.0;
                let t = glam::Mat4::from_scale_rotation_translation(
                    Vec3::new(19.0, depth, 20.0),
                    glam::Quat::IDENTITY,
                    Vec3::new(x, yc, 0.0),
                );
                s.add_instance(cube, t, Vec3::ONE, Default::default(), false);
            }
        }
        let p = street_level_path(&s, 1.8, 1.5, 10.0, 1.0).unwrap();
        assert_eq!(p.duration(), 10.0);
        let (a, b) = (p.keys[0].eye, p.keys.last().unwrap().eye);
        assert!(((b - a).length() - 15.0).abs() < 1e-3, "walks speed * duration");
        for k in &p.keys {
            assert!((k.eye.z - 1.8).abs() < 1e-4);
            assert!(k.eye.y.abs() < 5.0, "in the main street, got {}", k.eye);
            assert!((k.target - k.eye).x.abs() > 10.0, "looks along the street");
        }
        // No room for a 1000 m walk.
        assert!(street_level_path(&s, 1.8, 100.0, 10.0, 1.0).unwrap_err().to_string().contains("no free"));
        assert!(street_level_path(&s, 0.0, 1.0, 10.0, 1.0).is_err());
    }

    #[test]
    fn default_path_frames_the_scene() {
        let mut s = Scene::default();
        let m = s.add_mesh(crate::shapes::unit_box().build().unwrap());
        s.add_instance(m, glam::Mat4::from_scale(Vec3::new(20.0, 10.0, 4.0)), Vec3::ONE, Default::default(), false);
        let p = CameraPath::default_for(&s);
        p.validate().unwrap();
        assert_eq!(p.duration(), 10.0);
        assert_eq!(p.frame_count(), 301);
        let b = s.bounds();
        for (_, cam) in p.frames(64, 48, 1.0).unwrap() {
            // Eye above the ground and outside the bounds, scene centre in front of the
            // camera, every corner in view between near and far.
            assert!(cam.eye().z > b.min.z + 1.0);
            let e = cam.eye();
            assert!(e.cmplt(b.min).any() || e.cmpgt(b.max).any(), "eye {e} inside the bounds");
            let c = cam.project(b.center()).unwrap();
            assert!(c.x >= 0.0 && c.x <= 64.0 && c.y >= 0.0 && c.y <= 48.0 && c.z < 1.0, "{c}");
            for corner in b.corners() {
                assert!((corner - cam.eye()).length() < p.far);
                let q = cam.project(corner).unwrap();
                assert!(q.x >= 0.0 && q.x <= 64.0 && q.y >= 0.0 && q.y <= 48.0 && q.z > 0.0 && q.z < 1.0, "{q}");
            }
        }
    }

    proptest! {
        #[test]
        fn spline_passes_through_every_key(
            pts in proptest::collection::vec((-50.0f32..50.0, -50.0f32..50.0, 0.5f32..20.0, 0.1f32..3.0), 2..8)
        ) {
            let mut t = 0.0;
            let keys: Vec<PathKey> = pts.iter().map(|&(x, y, z, dt)| {
                t += dt;
                PathKey { t, eye: Vec3::new(x, y, z), target: Vec3::new(x + 5.0, y - 3.0, z * 0.5) }
            }).collect();
            let p = CameraPath { fov_y_deg: 50.0, near: 0.1, far: 500.0, up: Vec3::Z, fps: 30.0, keys };
            for k in &p.keys {
                let (e, g) = p.eye_target_at(k.t);
                prop_assert!((e - k.eye).length() < 1e-3 * (1.0 + k.eye.length()));
                prop_assert!((g - k.target).length() < 1e-3 * (1.0 + k.target.length()));
            }
        }
    }
}
