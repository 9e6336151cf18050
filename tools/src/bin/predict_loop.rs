//! The complete prediction (`zwarp_warp::predict_into`, `zwarp eval`'s pipeline) of one frame
//! pair of a scene, repeated, beside its streaming floor in the same run: the loop to profile
//! with `perf` and to compare kernel changes on.
//!
//! `cargo run --release -p zwarp-tools --bin predict_loop -- [scene=cb] [w=1920] [h=1080]
//! [l=1] [n=4] [reps=30] [frame=0] [speed=1] [part=all|prepare|warp|fill|afw|vfw] [bi=6] [path=FILE.json] [render=1] [sampling=adaptive|nearest] [bound=oriented|tight|global] [avx512=1]`
//!
//! `bi` is `WarpParams::bound_iterations`; `render=0` leaves the depth render out of the loop (to
//! profile the prediction alone).
//!
//! Prints the median and min..max wall ms of `part` (all threads) over `reps` warm runs, the
//! floor's and a depth render's of the target view (zwarp-raster), interleaved, their ratios, and an FNV fingerprint of the output (depth bits and states) that
//! tells a bit-identical optimisation from one that changes the function.

use std::time::Instant;

use zwarp_core::{motion_field, Image, Motion};
use zwarp_raster::{render_frame, render_source_layers, FrameOptions, UmbraPeeling, ViewRegion};
use zwarp_scene::SceneOptions;
use zwarp_warp::*;

fn stats(mut t: Vec<f64>) -> (f64, f64, f64) {
    t.sort_by(f64::total_cmp);
    (t[t.len() / 2], t[0], t[t.len() - 1])
}

fn main() {
    let args = zwarp_tools::common::KeyArgs::from_env(
        "scene, w, h, l, n, reps, frame, speed, part, bi, path, render, sampling, bound, avx512",
    );
    let get = |k: &str, d: &str| args.get(k, d);
    let name = get("scene", "cb");
    let (w, h): (u32, u32) = (get("w", "1920").parse().unwrap(), get("h", "1080").parse().unwrap());
    let l: usize = get("l", "1").parse().unwrap();
    let n: u32 = get("n", "4").parse().unwrap();
    let reps: usize = get("reps", "30").parse().unwrap();
    let frame: usize = get("frame", "0").parse().unwrap();
    let speed: f32 = get("speed", "1").parse().unwrap();
    let part = get("part", "all");
    zwarp_warp::simd::set_avx512(get("avx512", "1") != "0");

    let loaded = zwarp_scene::load_scene(&name, &SceneOptions::default()).unwrap();
    let path = match args.opt("path") {
        Some(p) => zwarp_scene::CameraPath::from_json_file_at(p, loaded.scene.origin).unwrap(),
        None => loaded.path_or_default(),
    };
    let scene = loaded.scene;
    let (ta, tb) = (path.time_of_frame(frame, speed), path.time_of_frame(frame + 1, speed));
    let (ca, cb) = (path.camera_at(ta, w, h).unwrap(), path.camera_at(tb, w, h).unwrap());
    let deltas = scene.object_deltas(ta, tb);
    let bufs: Vec<(Image<f32>, Image<Motion>)> = if l == 1 {
        let f = render_frame(&scene, &ca, ta, &FrameOptions::default()).unwrap();
        let m = motion_field(&f.depth, Some(&f.items), &ca, &cb, &deltas).unwrap();
        vec![(f.depth, m)]
    } else {
        let e = (cb.eye() - ca.eye()).length() * 1.5;
        // zwarp eval's protocol: the ground alone as the last layer.
        let umbra = Some(UmbraPeeling { region: ViewRegion::Disc { e, c: 0.0 } });
        render_source_layers(&scene, &ca, ta, l, umbra)
            .unwrap()
            .into_iter()
            .map(|p| {
                let m = motion_field(&p.depth, Some(&p.items), &ca, &cb, &deltas).unwrap();
                (p.depth, m)
            })
            .collect()
    };
    let layers: Vec<WarpLayer> = bufs.iter().map(|(d, m)| WarpLayer { depth: d, motion: m }).collect();
    let bi: u32 = get("bi", "6").parse().unwrap();
    let sampling = match get("sampling", "adaptive").as_str() {
        "nearest" => Sampling::Nearest,
        _ => Sampling::Adaptive,
    };
    let bound = match get("bound", "oriented").as_str() {
        "global" => BoundKind::Global,
        "tight" => BoundKind::Tight,
        _ => BoundKind::Oriented,
    };
    let params = WarpParams {
        n_seeds: n,
        bound_iterations: bi,
        holes: HolePolicy::PAPER,
        sampling,
        bound,
        ..Default::default()
    };
    let far = WarpParams { holes: HolePolicy::FarDepth, ..params };
    let mut out = WarpOutput::empty();
    let mut rec = predict_into(&layers, &params, Vec::new(), &mut out).unwrap();
    let warped = {
        rec = PreparedLayer::prepare_stack_recycling(&layers, far.bound, rec).unwrap();
        warp_prepared_into(&rec, &far, &mut out).unwrap();
        out.clone()
    };
    let holes_in = warped.state.data().iter().filter(|&&s| s == PixelState::Hole).count();
    let mut floor_out = vec![0f32; w as usize * h as usize];
    let (mut tp, mut tf, mut tr) = (Vec::new(), Vec::new(), Vec::new());
    let mut scratch = warped.clone();
    for _ in 0..reps {
        let t0 = Instant::now();
        match part.as_str() {
            "prepare" => {
                rec = PreparedLayer::prepare_stack_recycling(&layers, far.bound, std::mem::take(&mut rec)).unwrap()
            }
            "warp" => warp_prepared_into(&rec, &far, &mut out).unwrap(),
            "fill" => {
                scratch.depth.data_mut().copy_from_slice(warped.depth.data());
                scratch.state.data_mut().copy_from_slice(warped.state.data());
                let t1 = Instant::now();
                let limits = holes::BackgroundLimits::of_prepared(&rec, w, h, 1, 4).unwrap();
                holes::fill_background_with(&layers, &mut scratch, limits, &far.search()).unwrap();
                tp.push(t1.elapsed().as_secs_f64() * 1e3);
            }
            "afw" => baselines::afw_layers_into(&layers, &mut out.depth).unwrap(),
            "vfw" => baselines::vfw_layers_into(&layers, &mut out.depth).unwrap(),
            _ => rec = predict_into(&layers, &params, std::mem::take(&mut rec), &mut out).unwrap(),
        }
        if part != "fill" {
            tp.push(t0.elapsed().as_secs_f64() * 1e3);
        }
        let t0 = Instant::now();
        floor::floor_pass(&layers, 1, w, &mut floor_out).unwrap();
        tf.push(t0.elapsed().as_secs_f64() * 1e3);
        if get("render", "1") != "0" {
            let t0 = Instant::now();
            std::hint::black_box(zwarp_raster::render_depth(&scene, &cb, tb).unwrap());
            tr.push(t0.elapsed().as_secs_f64() * 1e3);
        }
    }
    match part.as_str() {
        // The forward baselines write depth only: the fingerprint takes it with far-hole states.
        "afw" | "vfw" => out.state.data_mut().fill(PixelState::Hole),
        _ => drop(predict_into(&layers, &params, rec, &mut out).unwrap()),
    }
    let mut fp = 0xcbf29ce484222325u64;
    for (z, s) in out.depth.data().iter().zip(out.state.data()) {
        for b in z.to_bits().to_le_bytes().into_iter().chain([*s as u8]) {
            fp = (fp ^ b as u64).wrapping_mul(0x100000001b3);
        }
    }
    let (p, plo, phi) = stats(tp);
    let (f, flo, fhi) = stats(tf);
    let (r, rlo, rhi) = if tr.is_empty() { (f64::NAN, f64::NAN, f64::NAN) } else { stats(tr) };
    println!(
        "{name} {w}x{h} L={l} N={n} {part}: {p:.2} ms [{plo:.2}, {phi:.2}]  floor {f:.2} ms [{flo:.2}, {fhi:.2}]  x floor {:.1}  render {r:.2} ms [{rlo:.2}, {rhi:.2}]  render/{part} {:.2}  holes {holes_in}  hash {fp:016x}",
        p / f,
        r / p
    );
}
