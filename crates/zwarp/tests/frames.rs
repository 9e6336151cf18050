//! The facade's frame warper (colour, seed 001) against the stages it calls, against the
//! target view's truth, on both backends, and its error paths.

use zwarp::color::{heuristic_warp, robust_warp, FieldParams, WarpBasis};
use zwarp::warp::synth::SynthScene;
use zwarp::{Backend, Camera, ColorMethod, ColorWarpOutput, Error, FrameWarper, HeuristicParams, Image, Vec3};

const W: u32 = 96;
const H: u32 = 64;

/// The renderer's colour of a view: a pattern on each surface (varying over a few pixels, so
/// that resampling errors show) fixed to its object — the world position taken back to time 0
/// by the inverse of the object's motion `to_start[id]` (none: static) — and a flat sky.
fn shade(cam: &Camera, depth: &Image<f32>, items: &Image<u32>, to_start: &[zwarp::Mat4]) -> Image<[f32; 3]> {
    Image::from_fn(cam.width, cam.height, |x, y| {
        let z = *depth.get(x, y);
        if z >= 1.0 {
            return [0.2, 0.4, 0.8];
        }
        let world = cam.unproject(x as f32 + 0.5, y as f32 + 0.5, z);
        let p = to_start.get(*items.get(x, y) as usize).map_or(world, |m| m.transform_point3(world));
        let s = 0.5 + 0.5 * (0.8 * p.x).sin() * (0.8 * p.z).cos() * (1.5 * p.y).cos();
        [s, 0.5 * s + 0.25, 0.25]
    })
}

struct Views {
    a: Camera,
    b: Camera,
    scene: SynthScene,
    depth: Image<f32>,
    items: Image<u32>,
    color: Image<[f32; 3]>,
    deltas: Vec<zwarp::Mat4>,
    /// View B rendered (colour), the truth, and its item buffer.
    truth: Image<[f32; 3]>,
    target_items: Image<u32>,
}

/// View A of the moving city rendered, and view B with its objects a quarter of a time unit on.
fn views() -> Views {
    let (a, b) = SynthScene::city_views(W, H).unwrap();
    let scene = SynthScene::moving_city();
    let src = scene.render(&a, 0.0, 1, false);
    let (depth, items) = (src.depth[0].clone(), src.items[0].clone());
    let color = shade(&a, &depth, &items, &[]);
    let deltas = scene.object_deltas(0.0, 0.25);
    let to_start: Vec<zwarp::Mat4> = deltas.iter().map(|m| m.inverse()).collect();
    let target = scene.render(&b, 0.25, 1, false);
    let truth = shade(&b, &target.depth[0], &target.items[0], &to_start);
    Views { a, b, scene, depth, items, color, deltas, truth, target_items: target.items[0].clone() }
}

/// Mean absolute error of the red channel against `truth` over the pixels of `mask`.
fn mae(img: &Image<[f32; 3]>, truth: &Image<[f32; 3]>, mask: &[bool]) -> f64 {
    let sum: f64 = img
        .data()
        .iter()
        .zip(truth.data())
        .zip(mask)
        .filter(|(_, &m)| m)
        .map(|((p, q), _)| (p[0] - q[0]).abs() as f64)
        .sum();
    sum / mask.iter().filter(|&&m| m).count().max(1) as f64
}

#[test]
fn cpu_frames_are_the_colour_pipeline_by_hand() {
    let v = views();
    let motion = zwarp::core::motion_field(&v.depth, Some(&v.items), &v.a, &v.b, &v.deltas).unwrap();
    let basis = WarpBasis::temporal(&v.depth, &motion).unwrap();
    let field = basis.field(FieldParams::temporal(1.0)).unwrap();
    let want_h = heuristic_warp(&field, &v.color, &HeuristicParams::default()).unwrap();
    let (want_r, _) = robust_warp(&field, &v.color, &Default::default()).unwrap();
    for (method, want) in [(ColorMethod::heuristic(), &want_h), (ColorMethod::robust(), &want_r)] {
        let mut frames = FrameWarper::new(Backend::Cpu, method).unwrap();
        frames.prepare(&v.a, &v.depth, &v.color, Some(&v.items)).unwrap();
        let got = frames.warp_to(&v.b, &v.deltas).unwrap().clone();
        assert_eq!(&got, want, "{method:?}");
        // Its buffers reused: the same answer again.
        assert_eq!(frames.warp_to(&v.b, &v.deltas).unwrap(), &got);
    }
}

#[test]
fn predicted_frames_approach_the_rendered_view() {
    let v = views();
    let all = vec![true; v.truth.len()];
    // The pixels of view B that show the moving box (the scene's one object with a motion).
    let moving = v.deltas.iter().position(|m| *m != zwarp::Mat4::IDENTITY).unwrap() as u32;
    let on_box: Vec<bool> = v.target_items.data().iter().map(|&i| i == moving).collect();
    assert!(on_box.iter().filter(|&&b| b).count() > 200);
    let repeat = mae(&v.color, &v.truth, &all);
    for method in [ColorMethod::heuristic(), ColorMethod::robust()] {
        let mut frames = FrameWarper::new(Backend::Cpu, method).unwrap();
        frames.prepare(&v.a, &v.depth, &v.color, Some(&v.items)).unwrap();
        let p = frames.warp_to(&v.b, &v.deltas).unwrap().clone();
        let err = mae(&p.color, &v.truth, &all);
        assert!(err < 0.4 * repeat, "{method:?}: warped {err:.4} vs repeating the frame {repeat:.4}");
        assert!(p.converged_fraction() > 0.9, "{method:?}: {}", p.converged_fraction());
        // The box's own motion matters: leaving it out puts the box in the wrong place.
        let still = frames.warp_to(&v.b, &[]).unwrap();
        let (moved_err, still_err) = (mae(&p.color, &v.truth, &on_box), mae(&still.color, &v.truth, &on_box));
        assert!(
            moved_err < 0.7 * still_err,
            "{method:?}: on the box {moved_err:.4} with its motion, {still_err:.4} without"
        );
    }
}

#[test]
fn the_same_view_returns_the_source() {
    let v = views();
    let mut frames = FrameWarper::new(Backend::Cpu, ColorMethod::robust()).unwrap();
    frames.prepare(&v.a, &v.depth, &v.color, None).unwrap();
    let p = frames.warp_to(&v.a, &[]).unwrap();
    // Zero motion: every pixel converges at its own texel centre and shows its own colour, up to
    // the reprojection's rounding in the motion field.
    assert_eq!(p.converged_fraction(), 1.0);
    let worst = p.color.data().iter().zip(v.color.data()).map(|(x, y)| (x[0] - y[0]).abs()).fold(0.0, f32::max);
    assert!(worst < 1e-3, "{worst}");
    // A new source replaces the old one (items dropped: everything moves with the camera).
    let b_depth = v.scene.render(&v.b, 0.25, 1, false).depth.remove(0);
    frames.prepare(&v.b, &b_depth, &v.truth, None).unwrap();
    let back = frames.warp_to(&v.b, &[]).unwrap();
    assert!(mae(&back.color, &v.truth, &vec![true; v.truth.len()]) < 1e-4);
}

#[test]
fn gpu_frames_match_cpu() {
    let Some(ctx) = zwarp::gpu::test_context() else { return };
    let v = views();
    for method in [ColorMethod::heuristic(), ColorMethod::robust()] {
        let mut cpu = FrameWarper::new(Backend::Cpu, method).unwrap();
        let mut gpu = FrameWarper::new(Backend::Gpu(ctx.clone()), method).unwrap();
        for f in [&mut cpu, &mut gpu] {
            f.prepare(&v.a, &v.depth, &v.color, Some(&v.items)).unwrap();
        }
        let c: ColorWarpOutput = cpu.warp_to(&v.b, &v.deltas).unwrap().clone();
        let g = gpu.warp_to(&v.b, &v.deltas).unwrap();
        // The WGSL twins: the same output up to float rounding (zwarp-color's GPU tests hold
        // the kernels to their CPU twins; here the facade's plumbing is checked).
        let n = c.color.len() as f64;
        let close = c.color.data().iter().zip(g.color.data()).filter(|(x, y)| (x[0] - y[0]).abs() < 1e-3).count();
        assert!(close as f64 / n >= 0.99, "{method:?}: {close} of {n} pixels agree");
        assert!((c.converged_fraction() - g.converged_fraction()).abs() < 0.01, "{method:?}");
    }
}

#[test]
fn bad_input_is_a_one_line_error() {
    let v = views();
    let invalid = |e: Error| {
        assert!(matches!(e, Error::Invalid(_)), "{e}");
        assert!(!e.to_string().contains('\n'));
    };
    let zero = ColorMethod::Heuristic(HeuristicParams { iterations: 0, ..HeuristicParams::default() });
    invalid(FrameWarper::new(Backend::Cpu, zero).err().unwrap());
    let mut frames = FrameWarper::new(Backend::Cpu, ColorMethod::heuristic()).unwrap();
    invalid(frames.warp_to(&v.b, &[]).unwrap_err());
    let small_color = Image::new(W - 1, H, [0.0; 3]);
    invalid(frames.prepare(&v.a, &v.depth, &small_color, None).unwrap_err());
    invalid(frames.prepare(&v.a, &Image::new(W, H + 1, 1.0), &v.color, None).unwrap_err());
    invalid(frames.prepare(&v.a, &v.depth, &v.color, Some(&Image::new(1, 1, 0))).unwrap_err());
    frames.prepare(&v.a, &v.depth, &v.color, None).unwrap();
    let small = Camera::perspective(Vec3::ZERO, Vec3::NEG_Z, Vec3::Y, 1.0, 0.5, 100.0, W / 2, H).unwrap();
    invalid(frames.warp_to(&small, &[]).unwrap_err());
    let mut nan_depth = v.depth.clone();
    *nan_depth.get_mut(3, 3) = f32::NAN;
    frames.prepare(&v.a, &nan_depth, &v.color, None).unwrap();
    invalid(frames.warp_to(&v.b, &[]).unwrap_err());
}
