//! Times the facade as an engine calls it, frame after frame on one frame pair of a scene, warm,
//! buffers reused: the depth prediction (`zwarp::Warper::prepare` and `warp_to`: motion,
//! preparation, search, holes) beside a depth render of the target view, and colour frame
//! generation (`zwarp::FrameWarper::warp_to`, seed 001: motion, warp field, heuristic or robust
//! warp) beside the heuristic warp alone on the same field: the loop to profile the facade with.
//!
//! `facade_loop SCENE PATH.json|- W H reps`
use std::time::Instant;

use zwarp::{Backend, ColorMethod, FrameWarper, Warper};
use zwarp_color::{heuristic_warp_into, ColorWarpOutput, FieldParams, HeuristicParams, WarpBasis};
use zwarp_core::motion_field;
use zwarp_raster::{render_frame, FrameOptions};
use zwarp_tools::common::median_min_max as med;

fn main() {
    let args = zwarp_tools::common::LoopArgs::from_env("facade_loop");
    let (reps, loaded) = (args.reps, &args.loaded);
    let ((t0, c0), (t1, c1)) = args.pair(0);
    let f = render_frame(&loaded.scene, &c0, t0, &FrameOptions { color: true, objects: None }).unwrap();
    let color = f.color.as_ref().unwrap();
    let deltas = loaded.scene.object_deltas(t0, t1);
    let time = |f: &mut dyn FnMut()| zwarp_tools::common::time_ms(reps, f);
    // Depth: prepare + warp_to, and the render it replaces, interleaved.
    let mut wp = Warper::new(Backend::Cpu, Warper::default_params()).unwrap();
    let (mut tp, mut tw, mut tr) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..reps + 1 {
        let t = Instant::now();
        wp.prepare(&c0, std::slice::from_ref(&f.depth), Some(std::slice::from_ref(&f.items))).unwrap();
        tp.push(t.elapsed().as_secs_f64() * 1e3);
        let t = Instant::now();
        std::hint::black_box(wp.warp_to(&c1, &deltas).unwrap());
        tw.push(t.elapsed().as_secs_f64() * 1e3);
        let t = Instant::now();
        std::hint::black_box(zwarp_raster::render_depth(&loaded.scene, &c1, t1).unwrap());
        tr.push(t.elapsed().as_secs_f64() * 1e3);
    }
    let [(p, plo, phi), (wt, wlo, whi), (r, rlo, rhi)] = [tp, tw, tr].map(|v| med(v[1..].to_vec()));
    println!(
        "Warper (L = 1): prepare {p:.2} ms [{plo:.2}, {phi:.2}]  warp_to {wt:.2} ms [{wlo:.2}, {whi:.2}]  depth render {r:.2} ms [{rlo:.2}, {rhi:.2}]  render / (prepare + warp_to) {:.2}",
        r / (p + wt)
    );
    for (name, method) in [("heuristic", ColorMethod::heuristic()), ("robust", ColorMethod::robust())] {
        let mut fw = FrameWarper::new(Backend::Cpu, method).unwrap();
        fw.prepare(&c0, &f.depth, color, Some(&f.items)).unwrap();
        let (t, lo, hi) = time(&mut || {
            std::hint::black_box(fw.warp_to(&c1, &deltas).unwrap());
        });
        println!("FrameWarper {name}: {t:.2} ms [{lo:.2}, {hi:.2}]");
    }
    let mut m = motion_field(&f.depth, Some(&f.items), &c0, &c1, &deltas).unwrap();
    let (t, lo, hi) =
        time(&mut || zwarp_core::motion_field_into(&f.depth, Some(&f.items), &c0, &c1, &deltas, &mut m).unwrap());
    println!("motion_field_into (recycled): {t:.2} ms [{lo:.2}, {hi:.2}]");
    let (t, lo, hi) = time(&mut || {
        std::hint::black_box(WarpBasis::temporal(&f.depth, &m).unwrap());
    });
    println!("WarpBasis::temporal: {t:.2} ms [{lo:.2}, {hi:.2}]");
    let mut basis = WarpBasis::temporal(&f.depth, &m).unwrap();
    let (t, lo, hi) = time(&mut || basis.set_temporal(&f.depth, &m).unwrap());
    println!("WarpBasis::set_temporal (recycled): {t:.2} ms [{lo:.2}, {hi:.2}]");
    let field = basis.field(FieldParams::temporal(1.0)).unwrap();
    let mut out = ColorWarpOutput::empty();
    let (t, lo, hi) = time(&mut || heuristic_warp_into(&field, color, &HeuristicParams::default(), &mut out).unwrap());
    println!("heuristic warp alone: {t:.2} ms [{lo:.2}, {hi:.2}]");
}
