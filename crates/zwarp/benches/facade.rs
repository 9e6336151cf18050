//! The facade per frame, as an engine calls it, beside the kernels it wraps on the same inputs
//! (1920x1080, a synthetic city of 6x6 boxes ray cast analytically, the camera moving a metre):
//! - depth: `Warper::prepare` + `warp_to` (copy of the source, motion field, preparation,
//!   search, hole protocol; L = 1) against `zwarp_warp::predict_into` given the motion;
//! - colour: `FrameWarper::warp_to` (motion field, warp basis, seed 001's heuristic or robust
//!   warp) against the warp alone on a prebuilt field.
//!
//! The ratio of each pair is what the facade adds (motion, buffers, copies): a regression in
//! that glue (a per-frame allocation, a second pass) shows here, not in the kernel benches.
//!
//! `cargo bench -p zwarp --bench facade` (set RAYON_NUM_THREADS to pin the core count).

use criterion::Criterion;
use zwarp::color::{heuristic_warp_into, robust_warp_with, FieldParams, Subdivision, WarpBasis};
use zwarp::warp::synth::SynthScene;
use zwarp::warp::{predict_into, WarpLayer, WarpOutput};
use zwarp::{Backend, Camera, ColorMethod, ColorWarpOutput, FrameWarper, Image, Vec3, Warper};

fn main() {
    let (w, h) = (1920, 1080);
    let scene = SynthScene::city(6);
    let a = Camera::perspective(Vec3::new(0.0, 9.0, 22.0), Vec3::ZERO, Vec3::Y, 1.0, 0.5, 200.0, w, h).unwrap();
    let b = Camera::perspective(Vec3::new(0.8, 9.2, 21.0), Vec3::new(0.3, 0.0, 0.0), Vec3::Y, 1.0, 0.5, 200.0, w, h)
        .unwrap();
    let src = scene.render(&a, 0.0, 1, true);
    let (depth, items) = (&src.depth[0], &src.items[0]);
    // The renderer's colour: a pattern on the world position (detail down to a few pixels).
    let color = Image::from_fn(w, h, |x, y| {
        let d = *depth.get(x, y);
        let p = a.unproject(x as f32 + 0.5, y as f32 + 0.5, d);
        let s = 0.5 + 0.5 * (3.1 * p.x).sin() * (2.3 * p.z).cos() * (1.7 * p.y).sin();
        if d < 1.0 {
            [s, 0.6 * s, 0.3]
        } else {
            [0.2, 0.4, 0.8]
        }
    });
    let motion = zwarp::core::motion_field(depth, Some(items), &a, &b, &[]).unwrap();

    let mut c = Criterion::default().configure_from_args().sample_size(20);
    let mut g = c.benchmark_group("facade_1920x1080");
    let params = Warper::default_params();
    let mut warper = Warper::new(Backend::Cpu, params).unwrap();
    g.bench_function("depth/warper_prepare_warp_to", |bch| {
        bch.iter(|| {
            warper.prepare(&a, std::slice::from_ref(depth), Some(std::slice::from_ref(items))).unwrap();
            warper.warp_to(&b, &[]).unwrap().depth.width()
        })
    });
    let layers = [WarpLayer { depth, motion: &motion }];
    let (mut out, mut recycled) = (WarpOutput::empty(), Vec::new());
    g.bench_function("depth/predict_into", |bch| {
        bch.iter(|| {
            recycled = predict_into(&layers, &params, std::mem::take(&mut recycled), &mut out).unwrap();
        })
    });
    let basis = WarpBasis::temporal(depth, &motion).unwrap();
    let field = basis.field(FieldParams::temporal(1.0)).unwrap();
    for (name, method) in [("heuristic", ColorMethod::heuristic()), ("robust", ColorMethod::robust())] {
        let mut frames = FrameWarper::new(Backend::Cpu, method).unwrap();
        frames.prepare(&a, depth, &color, Some(items)).unwrap();
        g.bench_function(format!("colour/frame_warper_{name}"), |bch| {
            bch.iter(|| frames.warp_to(&b, &[]).unwrap().color.width())
        });
        let mut alone = ColorWarpOutput::empty();
        g.bench_function(format!("colour/{name}_alone"), |bch| {
            bch.iter(|| match &method {
                ColorMethod::Heuristic(p) => heuristic_warp_into(&field, &color, p, &mut alone).unwrap(),
                ColorMethod::Robust(p) => {
                    let sub = Subdivision::of_field(&field, p.tile).unwrap();
                    robust_warp_with(&sub, &field, &color, p, &mut alone).unwrap();
                }
            })
        });
    }
    g.finish();
    c.final_summary();
}
