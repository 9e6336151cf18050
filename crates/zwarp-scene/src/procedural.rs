//! Procedural versions of the four scenes of seed 000 (Sec. 4, Fig. 9), seeded with
//! `rand_pcg` and deterministic, each with a recorded camera path of 10-11 s at 30 Hz:
//!
//! | spec | paper scene | what is built (scale 1) |
//! | --- | --- | --- |
//! | `yr` | Yeahrights: few objects, high polygon count, high depth complexity | 20 overlapping, finely tessellated displaced blobs, tori and torus knots (~147K triangles each, ~2.9M in all) on a ground plane; a third spin slowly; the camera circles the cluster, closing in |
//! | `mo` | Monsters: game-like, ~6.3K objects | 6300 rocks, trees, houses and hopping "monsters" on a 256x256-cell height-field terrain (the terrain is ground); low fly-over |
//! | `bl` | Balloons: ~35K balloons with tiny baskets, no ground | 35000 objects, each one balloon envelope + its basket as one mesh (so one object per balloon, as the paper counts them), all animated (half bob, half drift); the camera flies through the cloud |
//! | `cb` | Cityblock: urban, ~94K objects | a 26x26 grid of city blocks: buildings on lots along the block edges (some with roofs, roof units, antennas), sidewalks, lamp posts, trees, benches, bins, parked cars, and a few hundred moving cars (Linear); driving camera at 2 m eye height turning at a corner |
//!
//! `scale` multiplies the object count (the area grows with it so the density stays). All
//! scenes are Z up with the ground at z = 0 (the MO terrain undulates between 0 and ~12 m).
//! Meshes are shared: every building is the same unit box scaled by its instance transform.

use std::f32::consts::{PI, TAU};

use glam::{Mat4, Quat, Vec3};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg32;
use rayon::prelude::*;
use zwarp_core::{Animation, AreaLight, Error, LightShape, Mesh, Result, Scene};

use crate::path::{CameraPath, PathKey};
use crate::shapes::{self, MeshBuilder};
use crate::{hsv, LoadedScene, SceneOptions, GROUND_ALBEDO};

/// Builds `yr`, `mo`, `bl` or `cb` (see the module docs).
pub fn generate(name: &str, opts: &SceneOptions) -> Result<LoadedScene> {
    let loaded = match name {
        "yr" => yr(opts),
        "mo" => mo(opts),
        "bl" => bl(opts),
        "cb" => cb(opts),
        other => return Err(Error::invalid(format!("unknown procedural scene '{other}' (expected yr|mo|bl|cb)"))),
    }?;
    loaded.scene.check_nonempty()?;
    if let Some(p) = &loaded.path {
        p.validate()?;
    }
    Ok(loaded)
}

/// A generator's RNG: one stream per (seed, purpose) so adding objects of one kind does not
/// reshuffle the others.
fn rng(seed: u64, stream: u64) -> Pcg32 {
    Pcg32::seed_from_u64(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ stream.wrapping_mul(0xD1B5_4A32_D192_ED03))
}

fn count(base: f32, scale: f32) -> usize {
    ((base * scale).round() as usize).max(1)
}

/// Object -> world for a shape placed at `pos`, turned by `yaw` about z, scaled by `s`.
fn place(pos: Vec3, yaw: f32, s: Vec3) -> Mat4 {
    Mat4::from_scale_rotation_translation(s, Quat::from_rotation_z(yaw), pos)
}

fn mesh(b: MeshBuilder) -> Result<Mesh> {
    b.build()
}

/// Keys every `dt` seconds over `[0, duration]` from a parametric `eye(t)`/`target(t)`.
fn sample_keys(duration: f32, dt: f32, f: impl Fn(f32) -> (Vec3, Vec3)) -> Vec<PathKey> {
    let n = (duration / dt).round() as usize;
    (0..=n)
        .map(|i| {
            let t = i as f32 * dt;
            let (eye, target) = f(t);
            PathKey { t, eye, target }
        })
        .collect()
}

/// Time step of the clearance test of [`clear_path`] (s).
const CLEAR_DT: f32 = 1.0 / 60.0;

/// Removes every non-ground object whose box (animated: at that time) comes within `margin`
/// of the eye at any time of the path (sampled every [`CLEAR_DT`] s), so the recorded camera
/// never flies through a balloon, roof or car. Frames at any speed factor use times inside
/// the path's range, so they are covered too.
fn clear_path(scene: &mut Scene, path: &CameraPath, margin: f32) {
    let n = (path.duration() / CLEAR_DT).ceil() as usize;
    let samples: Vec<(f32, Vec3)> = (0..=n)
        .map(|k| {
            let t = (path.start() + k as f32 * CLEAR_DT).min(path.end());
            (t, path.eye_target_at(t).0)
        })
        .collect();
    let reach = zwarp_core::Aabb::from_points(samples.iter().map(|s| s.1));
    let meshes = &scene.meshes;
    let near = |b: &zwarp_core::Aabb, p: Vec3, m: f32| {
        p.x >= b.min.x - m
            && p.x <= b.max.x + m
            && p.y >= b.min.y - m
            && p.y <= b.max.y + m
            && p.z >= b.min.z - m
            && p.z <= b.max.z + m
    };
    scene.instances.retain(|inst| {
        if inst.is_ground {
            return true;
        }
        let animated = inst.animation.is_animated();
        // Cheap reject: animated objects here move at most ~25 m during a path.
        let slack = if animated { 25.0 } else { 0.0 } + margin;
        let b0 = inst.world_aabb;
        let overlaps = b0.min.cmple(reach.max + slack).all() && b0.max.cmpge(reach.min - slack).all();
        if !overlaps {
            return true;
        }
        !samples.iter().any(|&(t, e)| {
            let b = if animated { meshes[inst.mesh as usize].bounds.transformed(&inst.transform_at(t)) } else { b0 };
            near(&b, e, margin)
        })
    });
}

fn sun(center: Vec3, target: Vec3, size: f32) -> AreaLight {
    AreaLight { center, target, up: Vec3::Y, shape: LightShape::Rect { width: size, height: size }, directional: false }
}

// ---------------------------------------------------------------------------------------
// YR: few objects, very high polygon count, high depth complexity.

/// YR: `20 * scale` finely tessellated overlapping objects (~147K triangles each) on a
/// 60 m ground plane; the camera circles the cluster at 2.5-4.5 m height, closing in from
/// 1.35x its radius to 1.5 m outside it.
pub fn yr(opts: &SceneOptions) -> Result<LoadedScene> {
    let n = count(20.0, opts.scale);
    let mut r = rng(opts.seed, 1);
    struct Spec {
        kind: u32,
        seed: u32,
        pos: Vec3,
        size: f32,
        rot: Quat,
        spin: bool,
        color: Vec3,
    }
    // Objects sit in a disc whose area grows with n, so density (and overlap) stays.
    let radius = 5.0 * (n as f32 / 20.0).sqrt().max(0.3);
    let specs: Vec<Spec> = (0..n)
        .map(|i| {
            let a = r.random::<f32>() * TAU;
            let d = radius * r.random::<f32>().sqrt();
            let size = r.random_range(1.0..2.2f32);
            Spec {
                kind: i as u32 % 3,
                seed: r.random::<u32>() % 1000,
                pos: Vec3::new(d * a.cos(), d * a.sin(), size * r.random_range(0.7..1.6f32)),
                size,
                rot: Quat::from_euler(glam::EulerRot::XYZ, r.random::<f32>() * TAU, r.random::<f32>() * TAU, 0.0),
                spin: i % 3 == 1,
                color: hsv(r.random::<f32>(), 0.5, 0.85),
            }
        })
        .collect();
    // The heavy part: tessellating ~1.5M vertices; one object per rayon task.
    let meshes: Vec<Result<Mesh>> = specs
        .par_iter()
        .map(|s| {
            let sd = s.seed;
            mesh(match s.kind {
                // Displaced blob: 384 x 192 -> 146,688 triangles.
                0 => shapes::sphere_with(384, 192, |d| 1.0 + 0.18 * shapes::wave_noise(d * 3.0, sd)),
                // Bumpy torus: 768 x 96 -> 147,456 triangles.
                1 => shapes::tube(
                    768,
                    96,
                    0.32,
                    |u| Vec3::new((u * TAU).cos(), (u * TAU).sin(), 0.0) * 0.75,
                    |u, v| 1.0 + 0.25 * (u * TAU * 12.0).sin() * (v * TAU * 3.0).cos(),
                ),
                // (p, q) torus knot: 1536 x 48 -> 147,456 triangles.
                _ => {
                    let (p, q) = [(2.0, 3.0), (3.0, 5.0), (2.0, 5.0)][sd as usize % 3];
                    shapes::tube(
                        1536,
                        48,
                        0.12,
                        move |u| {
                            let a = u * TAU;
                            let rr = 0.55 + 0.25 * (q * a).cos();
                            Vec3::new(rr * (p * a).cos(), rr * (p * a).sin(), 0.3 * (q * a).sin())
                        },
                        |u, _| 1.0 + 0.3 * (u * TAU * 40.0).sin(),
                    )
                }
            })
        })
        .collect();
    let mut scene = Scene { name: "yr".into(), up: Vec3::Z, ..Default::default() };
    let ext = 30.0 * (radius / 5.0).max(1.0);
    let ground = scene.add_mesh(mesh(shapes::height_field(-ext, -ext, ext, ext, 64, 64, |_, _| 0.0))?);
    scene.add_instance(ground, Mat4::IDENTITY, GROUND_ALBEDO, Animation::Static, true);
    for (s, m) in specs.iter().zip(meshes) {
        let id = scene.add_mesh(m?);
        let transform = Mat4::from_scale_rotation_translation(Vec3::splat(s.size), s.rot, s.pos);
        let animation = if s.spin {
            Animation::Spin { center: s.pos, axis: Vec3::Z, angular_speed: 0.3 }
        } else {
            Animation::Static
        };
        scene.add_instance(id, transform, s.color, animation, false);
    }
    scene.lights.push(sun(Vec3::new(8.0, -6.0, 20.0), Vec3::new(0.0, 0.0, 1.5), 3.0));
    // Orbit half a turn while closing in from 1.35x the cluster's outer radius to 1.5 m
    // outside it, 2.5-4.5 m high: the view sweeps across the overlapping objects, which hide
    // each other (high depth complexity). `outer` is the largest horizontal reach of any object.
    let outer = scene
        .instances
        .iter()
        .filter(|i| !i.is_ground)
        .flat_map(|i| i.world_aabb.corners())
        .map(|c| c.truncate().length())
        .fold(0.0f32, f32::max);
    let path = CameraPath {
        fov_y_deg: 60.0,
        near: 0.1,
        far: 100.0,
        up: Vec3::Z,
        fps: 30.0,
        keys: sample_keys(10.0, 0.5, |t| {
            let u = t / 10.0;
            let a = -0.4 + PI * u;
            let rr = outer * (1.0 + 0.35 * (1.0 - u)) + 1.5;
            let eye = Vec3::new(rr * a.cos(), rr * a.sin(), 2.5 + 2.0 * (PI * u).sin());
            let target = Vec3::new(0.6 * (2.0 * a).sin(), 0.6 * (2.0 * a).cos(), 1.8);
            (eye, target)
        }),
    };
    // Spinning objects sweep a little beyond their t = 0 boxes; never let one graze the eye.
    clear_path(&mut scene, &path, 1.0);
    Ok(LoadedScene { scene, path: Some(path) })
}

// ---------------------------------------------------------------------------------------
// MO: ~6.3K medium objects on terrain.

/// Terrain height of MO at `(x, y)`: sums of sines, in about `[0, 12]` metres.
pub fn mo_terrain_height(x: f32, y: f32) -> f32 {
    6.0 + 3.5 * (x / 37.0).sin() * (y / 53.0).cos() + 1.5 * ((x + y) / 19.0).sin() + 1.0 * (x / 7.3 - y / 11.0).sin()
}

/// MO: `6300 * scale` rocks, trees, houses and hopping monsters on a height-field terrain of
/// side `400 * sqrt(scale)` m; the camera flies 16 m above the terrain (above the tallest
/// objects, ~11 m).
pub fn mo(opts: &SceneOptions) -> Result<LoadedScene> {
    let n = count(6300.0, opts.scale);
    let side = (400.0 * opts.scale.sqrt()).max(40.0);
    let half = side * 0.5;
    let mut scene = Scene { name: "mo".into(), up: Vec3::Z, ..Default::default() };
    let terrain = scene.add_mesh(mesh(shapes::height_field(-half, -half, half, half, 256, 256, mo_terrain_height))?);
    scene.add_instance(terrain, Mat4::IDENTITY, Vec3::new(0.30, 0.42, 0.22), Animation::Static, true);

    let mut r = rng(opts.seed, 2);
    // Mesh variants, shared by all instances of a kind.
    let mut trees = Vec::new();
    for v in 0..4 {
        let mut b = MeshBuilder::new();
        b.append(&shapes::cylinder(8), place(Vec3::ZERO, 0.0, Vec3::new(0.08, 0.08, 0.45)));
        let layers = 2 + v % 2;
        for l in 0..layers {
            let z = 0.3 + 0.22 * l as f32;
            let rad = 0.38 - 0.08 * l as f32;
            b.append(&shapes::cone(12), place(Vec3::new(0.0, 0.0, z), 0.0, Vec3::new(rad, rad, 0.45)));
        }
        trees.push(scene.add_mesh(mesh(b)?));
    }
    let mut rocks = Vec::new();
    for v in 0..4u32 {
        rocks.push(scene.add_mesh(mesh(shapes::sphere_with(16, 10, |d| {
            (1.0 + 0.25 * shapes::wave_noise(d * 2.5, v + 17)).max(0.3) * if d.z < -0.3 { 0.6 } else { 1.0 }
        }))?));
    }
    let mut houses = Vec::new();
    for v in 0..3 {
        let mut b = MeshBuilder::new();
        let wall = 0.55 + 0.1 * v as f32;
        b.append(&shapes::unit_box(), place(Vec3::ZERO, 0.0, Vec3::new(1.0, 0.8, wall)));
        b.append(&shapes::gable_roof(), place(Vec3::new(0.0, 0.0, wall), 0.0, Vec3::new(1.1, 0.9, 0.35)));
        b.append(&shapes::unit_box(), place(Vec3::new(0.3, 0.2, wall), 0.0, Vec3::new(0.1, 0.1, 0.4)));
        b.append(&shapes::unit_box(), place(Vec3::new(-0.2, -0.42, 0.0), 0.0, Vec3::new(0.15, 0.05, 0.3)));
        houses.push(scene.add_mesh(mesh(b)?));
    }
    let mut monsters = Vec::new();
    for v in 0..3u32 {
        let mut b = MeshBuilder::new();
        let body = shapes::sphere_with(20, 12, |d| 1.0 + 0.1 * shapes::wave_noise(d * 4.0, v + 3));
        b.append(&body, place(Vec3::new(0.0, 0.0, 0.55), 0.0, Vec3::new(0.45, 0.32, 0.3)));
        b.append(&shapes::sphere(12, 8), place(Vec3::new(0.45, 0.0, 0.85), 0.0, Vec3::splat(0.18)));
        for (lx, ly) in [(-0.25, -0.2), (-0.25, 0.2), (0.25, -0.2), (0.25, 0.2)] {
            b.append(&shapes::cylinder(6), place(Vec3::new(lx, ly, 0.0), 0.0, Vec3::new(0.06, 0.06, 0.4)));
        }
        b.append(&shapes::cone(8), place(Vec3::new(0.5, 0.08, 0.98), 0.0, Vec3::new(0.04, 0.04, 0.2)));
        b.append(&shapes::cone(8), place(Vec3::new(0.5, -0.08, 0.98), 0.0, Vec3::new(0.04, 0.04, 0.2)));
        monsters.push(scene.add_mesh(mesh(b)?));
    }
    let margin = half * 0.97;
    for _ in 0..n {
        let x = r.random_range(-margin..margin);
        let y = r.random_range(-margin..margin);
        let z = mo_terrain_height(x, y);
        let yaw = r.random::<f32>() * TAU;
        let kind = r.random::<f32>();
        let jitter = r.random_range(0.85..1.15f32);
        if kind < 0.45 {
            let h = r.random_range(4.0..11.0f32);
            let m = trees[r.random_range(0..trees.len())];
            let c = Vec3::new(0.12, 0.35, 0.1) * jitter;
            scene.add_instance(m, place(Vec3::new(x, y, z - 0.2), yaw, Vec3::splat(h)), c, Animation::Static, false);
        } else if kind < 0.75 {
            let s = r.random_range(0.5..3.0f32);
            let m = rocks[r.random_range(0..rocks.len())];
            let sc = Vec3::new(s, s * r.random_range(0.6..1.2f32), s * r.random_range(0.4..0.9f32));
            let c = Vec3::splat(0.45) * jitter;
            scene.add_instance(m, place(Vec3::new(x, y, z), yaw, sc), c, Animation::Static, false);
        } else if kind < 0.9 {
            let s = r.random_range(6.0..9.0f32);
            let m = houses[r.random_range(0..houses.len())];
            let c = Vec3::new(0.7, 0.55, 0.4) * jitter;
            scene.add_instance(m, place(Vec3::new(x, y, z - 0.3), yaw, Vec3::splat(s)), c, Animation::Static, false);
        } else {
            // Monsters hop in place (Bob), so they never sink into the terrain.
            let s = r.random_range(1.5..3.0f32);
            let m = monsters[r.random_range(0..monsters.len())];
            let c = hsv(r.random::<f32>(), 0.7, 0.75);
            let anim = Animation::Bob {
                amplitude: Vec3::new(0.0, 0.0, 0.25 * s),
                frequency: r.random_range(0.5..1.5f32),
                phase: r.random::<f32>() * TAU,
            };
            // Lift by the bob amplitude so the lowest point of the hop touches the ground.
            let pos = Vec3::new(x, y, z + 0.25 * s);
            scene.add_instance(m, place(pos, yaw, Vec3::splat(s)), c, anim, false);
        }
    }
    scene.lights.push(sun(Vec3::new(half * 0.5, -half * 0.5, 150.0), Vec3::ZERO, 20.0));
    // Low fly-over: 8 m/s along a gentle S-curve, 16 m above the terrain, looking 40 m ahead
    // and down to the ground.
    let len = (0.75 * side).min(80.0);
    let curve = move |t: f32| {
        let u = t / 10.0;
        let x = -0.5 * len + len * u;
        let y = 0.12 * len * (PI * 1.5 * u).sin();
        Vec3::new(x, y, 0.0)
    };
    let keys = sample_keys(10.0, 0.5, |t| {
        let p = curve(t);
        let ahead = curve(t + 2.5);
        let eye = Vec3::new(p.x, p.y, mo_terrain_height(p.x, p.y) + 16.0);
        let target = Vec3::new(ahead.x, ahead.y, mo_terrain_height(ahead.x, ahead.y) + 2.0);
        (eye, target)
    });
    let path = CameraPath { fov_y_deg: 60.0, near: 0.5, far: 1000.0, up: Vec3::Z, fps: 30.0, keys };
    clear_path(&mut scene, &path, 2.0);
    Ok(LoadedScene { scene, path: Some(path) })
}

// ---------------------------------------------------------------------------------------
// BL: ~35K balloons with tiny baskets, no ground.

/// BL: `35000 * scale` hot-air balloons (envelope + basket = one mesh, 204-300 triangles,
/// 4 variants) in a box of `400 x 400 x 120 m * cbrt(scale)`, no ground. Every balloon is
/// animated: even ids bob vertically, odd ids drift with the wind (Linear). The camera flies
/// through the middle of the cloud.
pub fn bl(opts: &SceneOptions) -> Result<LoadedScene> {
    let n = count(35000.0, opts.scale);
    let k = opts.scale.cbrt();
    let (hx, hz) = ((200.0 * k).max(20.0), (120.0 * k).max(15.0));
    let mut scene = Scene { name: "bl".into(), up: Vec3::Z, ..Default::default() };
    let mut variants = Vec::new();
    for v in 0..4u32 {
        let seg = 12 + 2 * v;
        // Envelope: teardrop (narrow towards the bottom), radius 1 around the origin.
        let env = shapes::sphere_with(seg, 9, move |d| {
            let taper = if d.z < 0.0 { 1.0 - 0.45 * d.z * d.z } else { 1.0 };
            taper * (1.0 + 0.04 * (d.x.atan2(d.y) * seg as f32).cos().abs())
        });
        let mut b = MeshBuilder::new();
        b.append(&env, Mat4::from_scale(Vec3::new(1.0, 1.0, 1.15 + 0.05 * v as f32)));
        // The tiny basket hangs below the envelope.
        b.append(&shapes::unit_box(), place(Vec3::new(0.0, 0.0, -1.75), 0.0, Vec3::new(0.28, 0.28, 0.22)));
        variants.push(scene.add_mesh(mesh(b)?));
    }
    let mut r = rng(opts.seed, 3);
    let wind = Vec3::new(1.2, 0.5, 0.0);
    for i in 0..n {
        let pos = Vec3::new(r.random_range(-hx..hx), r.random_range(-hx..hx), r.random_range(5.0..5.0 + hz));
        let s = r.random_range(2.0..3.5f32);
        let m = variants[r.random_range(0..variants.len())];
        let c = hsv(r.random::<f32>(), r.random_range(0.55..0.9f32), 0.9);
        let anim = if i % 2 == 0 {
            Animation::Bob {
                amplitude: Vec3::new(0.0, 0.0, r.random_range(0.5..1.5f32)),
                frequency: r.random_range(0.05..0.2f32),
                phase: r.random::<f32>() * TAU,
            }
        } else {
            Animation::Linear {
                velocity: wind * r.random_range(0.5..1.5f32) + Vec3::new(0.0, 0.0, r.random_range(-0.2..0.2f32)),
            }
        };
        let yaw = r.random::<f32>() * TAU;
        scene.add_instance(m, place(pos, yaw, Vec3::splat(s)), c, anim, false);
    }
    scene.lights.push(sun(Vec3::new(0.0, -hx, 5.0 + 3.0 * hz), Vec3::new(0.0, 0.0, 5.0 + 0.5 * hz), 30.0));
    // Through the cloud: 8 m/s across the box at mid height, slowly climbing and weaving.
    let len = (1.4 * hx).min(80.0);
    let mid = 5.0 + 0.5 * hz;
    let curve = move |t: f32| {
        let u = t / 10.0;
        Vec3::new(-0.5 * len + len * u, 0.15 * len * (TAU * 0.5 * u).sin(), mid - 8.0 + 16.0 * u)
    };
    let keys = sample_keys(10.0, 0.5, |t| {
        let ahead = curve(t + 2.0);
        (curve(t), ahead + Vec3::new(0.0, 0.0, -1.0))
    });
    let path = CameraPath { fov_y_deg: 60.0, near: 0.5, far: 1000.0, up: Vec3::Z, fps: 30.0, keys };
    clear_path(&mut scene, &path, 3.0);
    Ok(LoadedScene { scene, path: Some(path) })
}

// ---------------------------------------------------------------------------------------
// CB: urban, ~94K objects.

/// Street layout of CB: block `(i, j)` spans `x0 + i * PITCH_X + STREET / 2 ..` etc.
const BLOCK_X: f32 = 80.0;
const BLOCK_Y: f32 = 60.0;
/// Street width between blocks (10 m road + two 3 m sidewalks).
const STREET: f32 = 16.0;
const PITCH_X: f32 = BLOCK_X + STREET;
const PITCH_Y: f32 = BLOCK_Y + STREET;

/// Meshes shared by all CB instances.
struct CbMeshes {
    cube: u32,
    roof: u32,
    lamp: u32,
    tree: u32,
    bench: u32,
    bin: u32,
    car: u32,
    antenna: u32,
}

/// One object to add: mesh, transform, albedo, animation.
type Obj = (u32, Mat4, Vec3, Animation);

/// CB: a `n x n` grid of city blocks with `n = round(26 * sqrt(scale))` (~138 objects per
/// block: buildings, roof details, sidewalk, lamp posts, trees, benches, bins, parked cars)
/// on a ground plane at z = 0, plus ~0.3 moving cars per block driving along the streets.
/// The camera drives along a street at 2 m eye height and turns left at a corner.
pub fn cb(opts: &SceneOptions) -> Result<LoadedScene> {
    let n = ((26.0 * opts.scale.sqrt()).round() as usize).max(1);
    let mut scene = Scene { name: "cb".into(), up: Vec3::Z, ..Default::default() };
    let mut car = MeshBuilder::new();
    car.append(&shapes::unit_box(), place(Vec3::new(0.0, 0.0, 0.3), 0.0, Vec3::new(1.0, 1.0, 0.45)));
    car.append(&shapes::unit_box(), place(Vec3::new(-0.08, 0.0, 0.75), 0.0, Vec3::new(0.55, 0.9, 0.4)));
    for (wx, wy) in [(-0.32, -0.45), (-0.32, 0.45), (0.32, -0.45), (0.32, 0.45)] {
        car.append(&shapes::unit_box(), place(Vec3::new(wx, wy, 0.0), 0.0, Vec3::new(0.16, 0.1, 0.3)));
    }
    let mut lamp = MeshBuilder::new();
    lamp.append(&shapes::cylinder(6), place(Vec3::ZERO, 0.0, Vec3::new(0.012, 0.012, 1.0)));
    lamp.append(&shapes::unit_box(), place(Vec3::new(0.06, 0.0, 0.97), 0.0, Vec3::new(0.16, 0.05, 0.04)));
    let mut tree = MeshBuilder::new();
    tree.append(&shapes::cylinder(6), place(Vec3::ZERO, 0.0, Vec3::new(0.04, 0.04, 0.5)));
    tree.append(&shapes::sphere(10, 6), place(Vec3::new(0.0, 0.0, 0.68), 0.0, Vec3::new(0.3, 0.3, 0.32)));
    let mut bench = MeshBuilder::new();
    bench.append(&shapes::unit_box(), place(Vec3::new(0.0, 0.0, 0.4), 0.0, Vec3::new(1.0, 0.3, 0.06)));
    bench.append(&shapes::unit_box(), place(Vec3::new(0.0, 0.16, 0.4), 0.0, Vec3::new(1.0, 0.04, 0.45)));
    for lx in [-0.42, 0.42] {
        bench.append(&shapes::unit_box(), place(Vec3::new(lx, 0.0, 0.0), 0.0, Vec3::new(0.05, 0.28, 0.4)));
    }
    let m = CbMeshes {
        cube: scene.add_mesh(mesh(shapes::unit_box())?),
        roof: scene.add_mesh(mesh(shapes::gable_roof())?),
        lamp: scene.add_mesh(mesh(lamp)?),
        tree: scene.add_mesh(mesh(tree)?),
        bench: scene.add_mesh(mesh(bench)?),
        bin: scene.add_mesh(mesh(shapes::cylinder(10))?),
        car: scene.add_mesh(mesh(car)?),
        antenna: scene.add_mesh(mesh(shapes::frustum(6, 1.0, 0.3))?),
    };
    // City centred on the origin: street centre lines at x0 + i * PITCH_X, y0 + j * PITCH_Y.
    let (x0, y0) = (-(n as f32) * PITCH_X * 0.5, -(n as f32) * PITCH_Y * 0.5);
    let ground_half = Vec3::new(n as f32 * PITCH_X * 0.5 + 100.0, n as f32 * PITCH_Y * 0.5 + 100.0, 0.0);
    let ground = scene.add_mesh(mesh(shapes::height_field(
        -ground_half.x,
        -ground_half.y,
        ground_half.x,
        ground_half.y,
        64,
        64,
        |_, _| 0.0,
    ))?);
    scene.add_instance(ground, Mat4::IDENTITY, Vec3::splat(0.25), Animation::Static, true);

    // Blocks are independent: generate them in parallel, each with its own RNG stream, then
    // add in block order so ids are deterministic.
    let blocks: Vec<Vec<Obj>> = (0..n * n)
        .into_par_iter()
        .map(|b| {
            let (i, j) = (b % n, b / n);
            let mut r = rng(opts.seed, 1000 + b as u64);
            let min = Vec3::new(x0 + i as f32 * PITCH_X + STREET * 0.5, y0 + j as f32 * PITCH_Y + STREET * 0.5, 0.0);
            city_block(&m, &mut r, min, n, x0)
        })
        .collect();
    for objs in blocks {
        for (mesh, t, c, a) in objs {
            scene.add_instance(mesh, t, c, a, false);
        }
    }
    scene.lights.push(sun(Vec3::new(200.0, -300.0, 400.0), Vec3::ZERO, 40.0));

    // Driving path: along the street y = yc 1.5 m right of the centre line (slow driving)
    // at 6 m/s, left turn of radius 6 m at the crossing x = xc, then along +y. Eye at 2 m.
    let (xc, yc) = (x0 + (n / 2) as f32 * PITCH_X, y0 + (n / 2) as f32 * PITCH_Y);
    let lane = 1.5;
    let turn_r = 6.0;
    let speed = 6.0;
    let start = Vec3::new(xc + lane - turn_r - 35.0, yc - lane, 2.0);
    let arc_len = 0.5 * PI * turn_r;
    let pos_at = move |s: f32| -> (Vec3, Vec3) {
        let straight = 35.0;
        if s <= straight {
            (start + Vec3::X * s, Vec3::X)
        } else if s <= straight + arc_len {
            let a = (s - straight) / turn_r;
            let c = Vec3::new(xc + lane - turn_r, yc - lane + turn_r, 2.0);
            (c + Vec3::new(a.sin(), -a.cos(), 0.0) * turn_r, Vec3::new(a.cos(), a.sin(), 0.0))
        } else {
            let e = Vec3::new(xc + lane, yc - lane + turn_r, 2.0);
            (e + Vec3::Y * (s - straight - arc_len), Vec3::Y)
        }
    };
    let keys = sample_keys(11.0, 0.25, |t| {
        let (eye, _) = pos_at(speed * t);
        // Look where the car will be in 1.5 s (smooth anticipation of the turn), slightly down.
        let (ahead, dir) = pos_at(speed * (t + 1.5));
        (eye, ahead + dir * 8.0 - Vec3::new(0.0, 0.0, 0.6))
    });
    let path = CameraPath { fov_y_deg: 60.0, near: 0.25, far: 2000.0, up: Vec3::Z, fps: 30.0, keys };
    // 0.5 m keeps the parked cars beside the driving lane (1.6 m away) but removes moving
    // cars that would drive through the camera.
    clear_path(&mut scene, &path, 0.5);
    Ok(LoadedScene { scene, path: Some(path) })
}

/// The objects of one CB block whose minimum corner (at street level) is `min`.
fn city_block(m: &CbMeshes, r: &mut Pcg32, min: Vec3, n: usize, x0: f32) -> Vec<Obj> {
    let mut out: Vec<Obj> = Vec::with_capacity(160);
    let st = Animation::Static;
    let max = min + Vec3::new(BLOCK_X, BLOCK_Y, 0.0);
    let centre = (min + max) * 0.5;
    // Sidewalk slab around the block (3 m wide, 15 cm high).
    out.push((m.cube, place(centre, 0.0, Vec3::new(BLOCK_X + 6.0, BLOCK_Y + 6.0, 0.15)), Vec3::splat(0.5), st));
    // Buildings on lots along the four edges, facing outwards; the corners are taken by the
    // x-edges, the y-edges fill between them.
    let depth_max = 18.0;
    // (start, direction along the edge, edge length) for the south, north, west, east edges.
    let edges: [(Vec3, Vec3, f32); 4] = [
        (min, Vec3::X, BLOCK_X),
        (Vec3::new(min.x, max.y, 0.0), Vec3::X, BLOCK_X),
        (Vec3::new(min.x, min.y + depth_max, 0.0), Vec3::Y, BLOCK_Y - 2.0 * depth_max),
        (Vec3::new(max.x, min.y + depth_max, 0.0), Vec3::Y, BLOCK_Y - 2.0 * depth_max),
    ];
    for (k, &(start, dir, len)) in edges.iter().enumerate() {
        let inward = match k {
            0 => Vec3::Y,
            1 => -Vec3::Y,
            2 => Vec3::X,
            _ => -Vec3::X,
        };
        let mut s = 0.0;
        while s < len - 4.0 {
            let w = r.random_range(7.0..15.0f32).min(len - s);
            let d = r.random_range(10.0..depth_max);
            let tall = r.random::<f32>() < 0.08;
            let h = if tall { r.random_range(35.0..80.0f32) } else { r.random_range(6.0..28.0f32) };
            let c = start + dir * (s + 0.5 * w) + inward * (0.5 * d);
            let size = if dir == Vec3::X { Vec3::new(w - 0.4, d, h) } else { Vec3::new(d, w - 0.4, h) };
            let tone = r.random_range(0.45..0.8f32);
            let albedo = [Vec3::new(0.8, 0.72, 0.6), Vec3::new(0.6, 0.32, 0.25), Vec3::new(0.7, 0.7, 0.72)]
                [r.random_range(0..3usize)]
                * tone
                / 0.65;
            out.push((m.cube, place(Vec3::new(c.x, c.y, 0.0), 0.0, size), albedo, st));
            let roof_top = Vec3::new(c.x, c.y, h);
            let roll = r.random::<f32>();
            if h < 14.0 && roll < 0.5 {
                // Pitched roof on low buildings, ridge along the street.
                let rs = if dir == Vec3::X { Vec3::new(size.x, size.y, 3.0) } else { Vec3::new(size.y, size.x, 3.0) };
                let yaw = if dir == Vec3::X { 0.0 } else { 0.5 * PI };
                out.push((m.roof, place(roof_top, yaw, rs), Vec3::new(0.45, 0.2, 0.15), st));
            } else {
                // Flat roof: 1-3 roof units (AC boxes, stair houses) and sometimes an antenna.
                for _ in 0..r.random_range(1..4u32) {
                    let off = Vec3::new(
                        r.random_range(-0.35..0.35f32) * size.x,
                        r.random_range(-0.35..0.35f32) * size.y,
                        0.0,
                    );
                    let us = Vec3::new(
                        r.random_range(1.0..3.5f32),
                        r.random_range(1.0..3.5f32),
                        r.random_range(0.8..2.5f32),
                    );
                    out.push((m.cube, place(roof_top + off, 0.0, us), Vec3::splat(0.55), st));
                }
                if roll > 0.8 {
                    out.push((
                        m.antenna,
                        place(roof_top, 0.0, Vec3::new(0.15, 0.15, r.random_range(3.0..8.0f32))),
                        Vec3::splat(0.3),
                        st,
                    ));
                }
            }
            s += w;
        }
    }
    // Street furniture on the sidewalk strip (0.5-3 m outside the block edge) and parked cars
    // in the parking lane (4 m outside), walking around the perimeter.
    let perimeter: [(Vec3, Vec3, f32, Vec3); 4] = [
        (min, Vec3::X, BLOCK_X, -Vec3::Y),
        (Vec3::new(max.x, min.y, 0.0), Vec3::Y, BLOCK_Y, Vec3::X),
        (max, -Vec3::X, BLOCK_X, Vec3::Y),
        (Vec3::new(min.x, max.y, 0.0), -Vec3::Y, BLOCK_Y, -Vec3::X),
    ];
    for &(start, dir, len, out_dir) in &perimeter {
        let yaw = dir.y.atan2(dir.x);
        let mut s = 4.0;
        while s < len - 2.0 {
            let p = start + dir * s;
            out.push((m.lamp, place(p + out_dir * 2.6, yaw, Vec3::new(1.0, 1.0, 5.5)), Vec3::splat(0.2), st));
            let tp = p + dir * 6.0 + out_dir * 1.6;
            if s + 6.0 < len - 2.0 {
                let th = r.random_range(5.0..8.0f32);
                out.push((m.tree, place(tp, r.random::<f32>() * TAU, Vec3::splat(th)), Vec3::new(0.15, 0.4, 0.12), st));
            }
            if r.random::<f32>() < 0.25 {
                out.push((
                    m.bench,
                    place(p + dir * 3.0 + out_dir * 0.8, yaw, Vec3::new(1.6, 1.0, 1.0)),
                    Vec3::new(0.4, 0.3, 0.2),
                    st,
                ));
            }
            if r.random::<f32>() < 0.25 {
                out.push((
                    m.bin,
                    place(p + dir * 9.0 + out_dir * 2.6, 0.0, Vec3::new(0.3, 0.3, 0.9)),
                    Vec3::splat(0.25),
                    st,
                ));
            }
            s += 12.0;
        }
        // Parked cars, about half of the 6 m slots taken.
        let mut s = 3.0;
        while s < len - 3.0 {
            if r.random::<f32>() < 0.5 {
                let p = start + dir * s + out_dir * 4.0;
                out.push((m.car, place(p, yaw, Vec3::new(4.3, 1.8, 1.5)), car_colour(r), st));
            }
            s += 6.0;
        }
    }
    // A few moving cars: in the right-hand lane of the street south of the block, driving
    // along +x or -x through the whole city at 8-14 m/s.
    if r.random::<f32>() < 0.3 {
        let forward = r.random::<bool>();
        let street_y = min.y - STREET * 0.5;
        let lane_y = street_y + if forward { -2.5 } else { 2.5 };
        let x = x0 + r.random::<f32>() * n as f32 * PITCH_X;
        let v = r.random_range(8.0..14.0f32) * if forward { 1.0 } else { -1.0 };
        let yaw = if forward { 0.0 } else { PI };
        out.push((
            m.car,
            place(Vec3::new(x, lane_y, 0.0), yaw, Vec3::new(4.3, 1.8, 1.5)),
            car_colour(r),
            Animation::Linear { velocity: Vec3::new(v, 0.0, 0.0) },
        ));
    }
    out
}

fn car_colour(r: &mut Pcg32) -> Vec3 {
    if r.random::<f32>() < 0.4 {
        Vec3::splat(r.random_range(0.1..0.85f32))
    } else {
        hsv(r.random::<f32>(), 0.75, 0.7)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small(seed: u64, scale: f32) -> SceneOptions {
        SceneOptions { seed, scale, ..Default::default() }
    }

    #[test]
    fn generators_are_deterministic_and_seed_dependent() {
        for name in ["mo", "bl", "cb"] {
            let a = generate(name, &small(7, 0.01)).unwrap();
            let b = generate(name, &small(7, 0.01)).unwrap();
            let c = generate(name, &small(8, 0.01)).unwrap();
            assert_eq!(a.scene.instances.len(), b.scene.instances.len());
            for (x, y) in a.scene.instances.iter().zip(&b.scene.instances) {
                assert_eq!(x.transform, y.transform);
                assert_eq!(x.animation, y.animation);
            }
            let differs = a.scene.instances.len() != c.scene.instances.len()
                || a.scene.instances.iter().zip(&c.scene.instances).any(|(x, y)| x.transform != y.transform);
            assert!(differs, "{name}: seed must change the scene");
            assert_eq!(a.path, b.path);
        }
    }

    #[test]
    fn paths_are_valid_recordings_of_8_to_12_seconds() {
        for name in ["yr", "mo", "bl", "cb"] {
            let scale = if name == "yr" { 0.05 } else { 0.01 };
            let s = generate(name, &small(1, scale)).unwrap();
            let p = s.path.unwrap();
            p.validate().unwrap();
            assert!((8.0..=12.0).contains(&p.duration()), "{name}: {}", p.duration());
            assert_eq!(p.fps, 30.0);
            assert!(p.frame_count() >= 241);
        }
    }

    #[test]
    fn object_counts_scale() {
        let bl = generate("bl", &small(1, 0.02)).unwrap().scene;
        // 700 balloons minus the few the camera path would fly through.
        assert!((650..=700).contains(&bl.instances.len()), "{}", bl.instances.len());
        assert!(bl.instances.iter().all(|i| i.animation.is_animated() && !i.is_ground));
        let mo = generate("mo", &small(1, 0.02)).unwrap().scene;
        assert!((120..=127).contains(&mo.instances.len()), "{}", mo.instances.len());
        assert_eq!(mo.instances.iter().filter(|i| i.is_ground).count(), 1);
        let yr = generate("yr", &small(1, 0.1)).unwrap().scene;
        assert_eq!(yr.instances.len(), 2 + 1);
        assert!(yr.triangle_count() > 290_000);
    }

    #[test]
    fn balloon_triangles_in_range() {
        let bl = generate("bl", &small(3, 0.001)).unwrap().scene;
        for m in &bl.meshes {
            assert!((100..=340).contains(&m.triangle_count()), "{}", m.triangle_count());
        }
    }

    #[test]
    fn cb_layout_objects_on_ground_and_camera_in_street() {
        let s = generate("cb", &small(1, 0.02)).unwrap();
        let scene = &s.scene;
        // n = round(26 * sqrt(0.02)) = 4 -> 16 blocks.
        assert!(scene.instances.len() > 16 * 100, "{}", scene.instances.len());
        for inst in &scene.instances {
            assert!(inst.world_aabb.min.z >= -1e-3, "object below the ground: {:?}", inst.world_aabb);
        }
        assert!(scene.instances.iter().any(|i| matches!(i.animation, Animation::Linear { .. })));
        // The camera stays at street level and never enters a static building box.
        let p = s.path.unwrap();
        for (t, cam) in p.frames(16, 16, 1.0).unwrap() {
            let e = cam.eye();
            assert!((e.z - 2.0).abs() < 0.05, "t={t} eye {e}");
            for inst in scene.instances.iter().filter(|i| !i.is_ground && !i.animation.is_animated()) {
                let b = inst.world_aabb;
                let inside = e.x > b.min.x && e.x < b.max.x && e.y > b.min.y && e.y < b.max.y && e.z < b.max.z;
                assert!(!inside, "t={t}: eye {e} inside object {b:?}");
            }
        }
    }

    #[test]
    fn no_object_comes_near_the_recorded_eye() {
        for (name, margin) in [("bl", 3.0), ("mo", 2.0), ("cb", 0.5), ("yr", 1.0)] {
            let s = generate(name, &small(5, if name == "yr" { 0.05 } else { 0.03 })).unwrap();
            let p = s.path.unwrap();
            for (t, cam) in p.frames(8, 8, 1.0).unwrap() {
                let e = cam.eye();
                for (id, _) in s.scene.instances.iter().enumerate().filter(|(_, i)| !i.is_ground) {
                    let b = s.scene.instance_aabb_at(id as u32, t);
                    let d = (e.clamp(b.min, b.max) - e).abs().max_element();
                    assert!(d > margin * 0.99, "{name} t={t}: eye {e} within {d} of object {id} {b:?}");
                }
            }
        }
    }

    #[test]
    fn mo_objects_stand_on_terrain() {
        let s = generate("mo", &small(2, 0.01)).unwrap();
        for inst in s.scene.instances.iter().skip(1) {
            let p = inst.transform.w_axis.truncate();
            let h = mo_terrain_height(p.x, p.y);
            assert!(p.z >= h - 0.31 && p.z <= h + 1.0, "{p} vs terrain {h}");
        }
        let p = s.path.unwrap();
        for k in &p.keys {
            assert!((k.eye.z - mo_terrain_height(k.eye.x, k.eye.y) - 16.0).abs() < 1e-3);
        }
    }
}
