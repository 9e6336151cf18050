//! Times `zwarp_core::motion_field_into` (one output buffer reused, warm) on one frame of a
//! scene, with the scene's per-object deltas and with none, repeated: the loop to profile the
//! motion stage with. The hashes tell a bit-identical change from one that changes the field.
//!
//! `motion_loop SCENE PATH.json|- W H reps`
use std::time::Instant;
use zwarp_core::{motion_field, motion_field_into, Image, Motion};
use zwarp_raster::{render_frame, FrameOptions};

fn main() {
    let args = zwarp_tools::common::LoopArgs::from_env("motion_loop");
    let (reps, scene) = (args.reps, &args.loaded.scene);
    let ((t0, c0), (t1, c1)) = args.pair(0);
    let f = render_frame(scene, &c0, t0, &FrameOptions::default()).unwrap();
    let deltas = scene.object_deltas(t0, t1);
    // Into one buffer reused across calls (an engine's steady state).
    let time = |d: &[glam::Mat4]| {
        let mut out = Image::new(0, 0, Motion::default());
        let v: Vec<f64> = (0..reps + 1)
            .map(|_| {
                let t = Instant::now();
                motion_field_into(&f.depth, Some(&f.items), &c0, &c1, d, &mut out).unwrap();
                std::hint::black_box(&out);
                t.elapsed().as_secs_f64() * 1e3
            })
            .skip(1)
            .collect();
        zwarp_tools::common::median_min_max(v)
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
