//! Where the robust colour warp and reverse reprojection differ: on one in-between frame of
//! `zwarp upsample --factor 2` (exact motion), the mean squared error (mean of RGB) of both
//! against the render, split into the pixels the source saw and the ones it did not (and
//! those by what the robust warp did there: converged or filled).
//!
//! `colour_gap SCENE PATH.json|- W H frame` (frame: the source frame k; the target is halfway
//! to k + 1). `GAP_IMAGES=DIR` also writes the render, both predictions, the unseen mask and the
//! classes (black: seen, red: unseen where the robust warp converged, blue: unseen and filled);
//! `NO_SIMD=1` runs the portable colour warp.
use zwarp_color::{
    reproject, robust_warp_with, source_visibility, ColorWarpOutput, FieldParams, HeuristicParams, RobustParams, Seed,
    Subdivision, WarpBasis,
};
use zwarp_core::motion_field;
use zwarp_raster::{render_frame, FrameOptions};

fn main() {
    let args = zwarp_tools::common::LoopArgs::from_env("colour_gap");
    if std::env::var_os("NO_SIMD").is_some() {
        zwarp_color::set_simd(false);
    }
    let k = args.reps;
    let loaded = &args.loaded;
    let scene = &loaded.scene;
    let ((t0, c0), (t1, _)) = args.pair(k);
    let tt = 0.5 * (t0 + t1);
    let ct = args.path.camera_at(tt, args.width, args.height).unwrap();
    let opts = FrameOptions { color: true, objects: None };
    let src = render_frame(scene, &c0, t0, &opts).unwrap();
    let tgt = render_frame(scene, &ct, tt, &opts).unwrap();
    let (sc, tc) = (src.color.as_ref().unwrap(), tgt.color.as_ref().unwrap());
    let m = motion_field(&src.depth, Some(&src.items), &c0, &ct, &scene.object_deltas(t0, tt)).unwrap();
    let basis = WarpBasis::temporal(&src.depth, &m).unwrap();
    let field = basis.field(FieldParams::temporal(1.0)).unwrap();
    let hp = HeuristicParams { seed: Seed::Upstream(1.0), ..HeuristicParams::default() };
    let rp = RobustParams { fallback: hp, ..RobustParams::default() };
    let sub = Subdivision::of_field(&field, rp.tile).unwrap();
    let mut rob = ColorWarpOutput::empty();
    robust_warp_with(&sub, &field, sc, &rp, &mut rob).unwrap();
    let to_src = motion_field(&tgt.depth, Some(&tgt.items), &ct, &c0, &scene.object_deltas(tt, t0)).unwrap();
    let rep = reproject(&tgt.depth, &to_src, &src.depth, sc, &c0).unwrap();
    let seen = source_visibility(&tgt.depth, &to_src, &src.depth, &c0).unwrap();
    let se = |a: &[f32; 3], b: &[f32; 3]| (0..3).map(|i| ((a[i] - b[i]) as f64).powi(2)).sum::<f64>() / 3.0;
    // Classes: 0 seen, 1 unseen where the robust warp converged, 2 unseen and filled; seen
    // pixels also split by a depth step to a 4-neighbour of the render (3: at one, 4: not).
    let mut acc = [[0f64; 3]; 5];
    let (w, h) = (args.width, args.height);
    let edge = |x: u32, y: u32| {
        let z = *tgt.depth.get(x, y);
        let nb = [(x.saturating_sub(1), y), ((x + 1).min(w - 1), y), (x, y.saturating_sub(1)), (x, (y + 1).min(h - 1))]
            .map(|(a, b)| *tgt.depth.get(a, b));
        let room = 1.0 - nb.iter().fold(z, |m, &d| m.max(d));
        nb.iter().any(|&d| (d - z).abs() > zwarp_warp::sampling::DEPTH_CONTINUITY * room.max(0.0))
    };
    let n = tc.len();
    for j in 0..n {
        let (x, y) = ((j % args.width as usize) as u32, (j / args.width as usize) as u32);
        let c = if *seen.get(x, y) {
            0
        } else if rob.converged(x, y) {
            1
        } else {
            2
        };
        let r = tc.get(x, y);
        let err = [1.0, se(r, rob.color.get(x, y)), se(r, rep.color.get(x, y))];
        let edge_class = (c == 0).then(|| if edge(x, y) { 3 } else { 4 });
        for k in std::iter::once(c).chain(edge_class) {
            for (a, e) in acc[k].iter_mut().zip(err) {
                *a += e;
            }
        }
    }
    let db = |s: f64| -10.0 * (s / n as f64).log10();
    let tot_r: f64 = acc[..3].iter().map(|a| a[1]).sum();
    let tot_p: f64 = acc[..3].iter().map(|a| a[2]).sum();
    println!(
        "total: robust {:.3} dB  reproject {:.3} dB  robust with reproject's colour where the source did not see {:.3} dB",
        db(tot_r),
        db(tot_p),
        db(acc[0][1] + acc[1][2] + acc[2][2])
    );
    for (i, name) in ["seen", "unseen conv", "unseen fill", "seen edge", "seen inside"].iter().enumerate() {
        let a = acc[i];
        println!(
            "{name:12} px {:7}  share of SE: robust {:.4}e-4 reproject {:.4}e-4  (per px mse robust {:.5} reproject {:.5})",
            a[0],
            a[1] / n as f64 * 1e4,
            a[2] / n as f64 * 1e4,
            a[1] / a[0].max(1.0),
            a[2] / a[0].max(1.0)
        );
    }
    if let Ok(dir) = std::env::var("GAP_IMAGES") {
        let p = std::path::Path::new(&dir);
        std::fs::create_dir_all(p).unwrap();
        zwarp_viz::write_png(p.join("ref.png"), &zwarp_viz::color_to_rgb8(tc)).unwrap();
        zwarp_viz::write_png(p.join("robust.png"), &zwarp_viz::color_to_rgb8(&rob.color)).unwrap();
        zwarp_viz::write_png(p.join("reproject.png"), &zwarp_viz::color_to_rgb8(&rep.color)).unwrap();
        zwarp_viz::write_png(p.join("unseen.png"), &zwarp_viz::mask_to_rgb8(&seen.map(|v| !v))).unwrap();
        let cls = zwarp_core::Image::from_fn(args.width, args.height, |x, y| {
            if *seen.get(x, y) {
                [0.0f32, 0.0, 0.0]
            } else if rob.converged(x, y) {
                [1.0, 0.0, 0.0]
            } else {
                [0.0, 0.0, 1.0]
            }
        });
        zwarp_viz::write_png(p.join("classes.png"), &zwarp_viz::color_to_rgb8(&cls)).unwrap();
    }
}
