//! The facade against the stages it calls, on both backends, and its error paths.

use zwarp::warp::synth::SynthScene;
use zwarp::warp::{holes, warp_depth, WarpLayer};
use zwarp::{Backend, Camera, Error, HolePolicy, Image, Vec3, WarpParams, Warper};

fn cameras(w: u32, h: u32) -> (Camera, Camera) {
    SynthScene::city_views(w, h).unwrap()
}

fn scene() -> SynthScene {
    SynthScene::moving_city()
}

#[test]
fn cpu_prediction_is_the_eval_pipeline_by_hand() {
    let (w, h) = (96, 64);
    let (a, b) = cameras(w, h);
    let scene = scene();
    let src = scene.render(&a, 0.0, 3, true);
    let deltas = scene.object_deltas(0.0, 0.25);
    let params = Warper::default_params();
    let mut warper = Warper::new(Backend::Cpu, params).unwrap();
    warper.prepare(&a, &src.depth, Some(&src.items)).unwrap();
    let got = warper.warp_to(&b, &deltas).unwrap().clone();
    // By hand: motion per layer, the warp with far holes, the background fill.
    let motions: Vec<_> = src
        .depth
        .iter()
        .zip(&src.items)
        .map(|(d, i)| zwarp::core::motion_field(d, Some(i), &a, &b, &deltas).unwrap())
        .collect();
    let layers: Vec<WarpLayer> =
        src.depth.iter().zip(&motions).map(|(depth, motion)| WarpLayer { depth, motion }).collect();
    let mut want = warp_depth(&layers, &WarpParams { holes: HolePolicy::FarDepth, ..params }).unwrap();
    holes::fill_background(&layers, &mut want, 64, &params.search()).unwrap();
    assert_eq!(got.depth, want.depth);
    assert_eq!(got.state, want.state);
    assert!(got.converged_fraction() > 0.95, "{}", got.converged_fraction());
    // The recycled buffers give the same answer again, and a new source replaces the old one.
    assert_eq!(warper.warp_to(&b, &deltas).unwrap(), &got);
    warper.prepare(&b, &scene.render(&b, 0.25, 3, true).depth, None).unwrap();
    let back = warper.warp_to(&b, &[]).unwrap();
    // The same view: the source again, up to the reprojection's rounding in the motion field.
    let direct = scene.render(&b, 0.25, 1, false).depth.remove(0);
    let differ = back.depth.data().iter().zip(direct.data()).filter(|(x, y)| (**x - **y).abs() > 1e-5).count();
    assert_eq!(differ, 0, "zero motion returns the source");
}

#[test]
fn object_motion_moves_the_box() {
    let (w, h) = (96, 64);
    let (a, _) = cameras(w, h);
    let scene = scene();
    let src = scene.render(&a, 0.0, 3, true);
    let reference = scene.render(&a, 0.25, 1, false).depth.remove(0);
    let mut warper = Warper::new(Backend::Cpu, Warper::default_params()).unwrap();
    warper.prepare(&a, &src.depth, Some(&src.items)).unwrap();
    let err = |p: &Image<f32>| p.data().iter().zip(reference.data()).filter(|(x, y)| (**x - **y).abs() > 1e-3).count();
    let moved = err(&warper.warp_to(&a, &scene.object_deltas(0.0, 0.25)).unwrap().depth);
    let still = err(&warper.warp_to(&a, &[]).unwrap().depth);
    assert!(moved * 3 < still, "moved {moved} still {still}");
}

#[test]
fn gpu_prediction_matches_cpu() {
    let Some(ctx) = zwarp::gpu::test_context() else { return };
    let (w, h) = (96, 64);
    let (a, b) = cameras(w, h);
    let scene = scene();
    let src = scene.render(&a, 0.0, 3, true);
    let deltas = scene.object_deltas(0.0, 0.25);
    let mut cpu = Warper::new(Backend::Cpu, Warper::default_params()).unwrap();
    let mut gpu = Warper::new(Backend::Gpu(ctx), Warper::default_params()).unwrap();
    for wp in [&mut cpu, &mut gpu] {
        wp.prepare(&a, &src.depth, Some(&src.items)).unwrap();
    }
    let c = cpu.warp_to(&b, &deltas).unwrap();
    let g = gpu.warp_to(&b, &deltas).unwrap();
    let n = c.depth.len() as f64;
    let same_state = c.state.data().iter().zip(g.state.data()).filter(|(x, y)| x == y).count() as f64 / n;
    let same_depth = c.depth.data().iter().zip(g.depth.data()).filter(|(x, y)| x == y).count() as f64 / n;
    assert!(same_state >= 0.995 && same_depth >= 0.98, "state {same_state} depth {same_depth}");
}

#[test]
fn bad_input_is_a_one_line_error() {
    let (w, h) = (32, 16);
    let (a, b) = cameras(w, h);
    let invalid = |e: Error| {
        assert!(matches!(e, Error::Invalid(_)), "{e}");
        assert!(!e.to_string().contains('\n'));
    };
    invalid(Warper::new(Backend::Cpu, WarpParams { n_seeds: 0, ..Warper::default_params() }).err().unwrap());
    let mut warper = Warper::new(Backend::Cpu, Warper::default_params()).unwrap();
    invalid(warper.warp_to(&b, &[]).unwrap_err());
    invalid(warper.prepare(&a, &[], None).unwrap_err());
    invalid(warper.prepare(&a, &[Image::new(w + 1, h, 1.0)], None).unwrap_err());
    invalid(warper.prepare(&a, &[Image::new(w, h, 1.0), Image::new(w, h + 1, 1.0)], None).unwrap_err());
    invalid(warper.prepare(&a, &[Image::new(w, h, 1.0)], Some(&[])).unwrap_err());
    warper.prepare(&a, &[Image::new(w, h, 0.5)], None).unwrap();
    let small = Camera::perspective(Vec3::ZERO, Vec3::NEG_Z, Vec3::Y, 1.0, 0.5, 100.0, w / 2, h).unwrap();
    invalid(warper.warp_to(&small, &[]).unwrap_err());
    // An all-far source predicts an all-far view (sky seen everywhere), not an error.
    warper.prepare(&a, &[Image::new(w, h, 1.0)], None).unwrap();
    let p = warper.warp_to(&b, &[]).unwrap();
    assert!(p.depth.data().iter().all(|&z| z == 1.0));
    if let Some(ctx) = zwarp::gpu::test_context() {
        let e = Warper::new(Backend::Gpu(ctx), WarpParams { record_source: true, ..Warper::default_params() });
        invalid(e.err().unwrap());
    }
}
