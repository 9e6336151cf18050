//! Times `zwarp_core::motion_field_into` (one output buffer reused, warm) on one frame of a
//! scene, with the scene's per-object deltas and with none, repeated: the loop to profile the
//! motion stage with. The hashes tell a bit-identical change from one that changes the field.
//!
//! `motion_loop SCENE PATH.json|- W H reps`
use std::time::Instant;
use zwarp_core::{motion_field, motion_field_into, Image, Motion};
use zwarp_raster::{render_frame, FrameOptions};
use zwarp_scene::{load_scene, CameraPath, SceneOptions};

fn main() {
    let a: Vec<String> = std::env::args().collect();
    if a.len() != 6 {
        eprintln!("usage: motion_loop SCENE PATH.json|- W H reps");
        std::process::exit(1);
    }
    let (w, h, reps): (u32, u32, usize) = (a[3].parse().unwrap(), a[4].parse().unwrap(), a[5].parse().unwrap());
    let loaded = load_scene(&a[1], &SceneOptions::default()).unwrap();
    let path = if a[2] == "-" { loaded.path_or_default() } else { CameraPath::from_json_file(&a[2]).unwrap() };
    let (t0, t1) = (path.time_of_frame(0, 1.0), path.time_of_frame(1, 1.0));
    let (c0, c1) = (path.camera_at(t0, w, h).unwrap(), path.camera_at(t1, w, h).unwrap());
    let f = render_frame(&loaded.scene, &c0, t0, &FrameOptions::default()).unwrap();
    let deltas = loaded.scene.object_deltas(t0, t1);
    // Into one buffer reused across calls (an engine's steady state).
    let time = |d: &[glam::Mat4]| {
        let mut out = Image::new(0, 0, Motion::default());
        let mut v: Vec<f64> = (0..reps + 1)
            .map(|_| {
                let t = Instant::now();
                motion_field_into(&f.depth, Some(&f.items), &c0, &c1, d, &mut out).unwrap();
                std::hint::black_box(&out);
                t.elapsed().as_secs_f64() * 1e3
            })
            .skip(1)
            .collect();
        v.sort_by(f64::total_cmp);
        (v[v.len() / 2], v[0], v[v.len() - 1])
    };
    let fp = |d: &[glam::Mat4]| {
        let m = motion_field(&f.depth, Some(&f.items), &c0, &c1, d).unwrap();
        let mut h = 0xcbf29ce484222325u64;
        for s in m.data() {
            for b in [s.v.x, s.v.y, s.depth].map(f32::to_bits) {
                h = (h ^ b as u64).wrapping_mul(0x100000001b3);
            }
        }
        h
    };
    let (a1, b1) = (time(&deltas), time(&[]));
    println!(
        "{} deltas: {:.2} ms [{:.2}, {:.2}] hash {:016x}   none: {:.2} ms [{:.2}, {:.2}] hash {:016x}",
        deltas.len(),
        a1.0,
        a1.1,
        a1.2,
        fp(&deltas),
        b1.0,
        b1.1,
        b1.2,
        fp(&[])
    );
}
