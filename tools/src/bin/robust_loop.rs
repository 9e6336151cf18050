//! Times the robust colour warp's stages (rho + subdivision, quads, whole) against the heuristic
//! warp on one frame of a scene (`zwarp upsample --factor 2`'s temporal field at t = 0.5).
//!
//! `robust_loop SCENE [PATH.json|-] W H reps`
use zwarp_color::{
    heuristic_warp_into, robust_warp_with, ColorWarpOutput, FieldParams, HeuristicParams, RobustParams, Seed,
    Subdivision, WarpBasis,
};
use zwarp_core::motion_field;
use zwarp_raster::{render_frame, FrameOptions};

fn main() {
    let args = zwarp_tools::common::LoopArgs::from_env("robust_loop");
    let (reps, loaded) = (args.reps, &args.loaded);
    let ((t0, c0), (t1, c1)) = args.pair(args.path.frame_count_at(1.0) / 3);
    let f = render_frame(&loaded.scene, &c0, t0, &FrameOptions { color: true, objects: None }).unwrap();
    let color = f.color.as_ref().unwrap();
    let m = motion_field(&f.depth, Some(&f.items), &c0, &c1, &loaded.scene.object_deltas(t0, t1)).unwrap();
    let basis = WarpBasis::temporal(&f.depth, &m).unwrap();
    let field = basis.field(FieldParams::temporal(0.5)).unwrap();
    let hp = HeuristicParams { seed: Seed::Upstream(1.0), ..HeuristicParams::default() };
    let rp = RobustParams { fallback: hp, ..RobustParams::default() };
    let mut out = ColorWarpOutput::empty();
    let time = |f: &mut dyn FnMut()| zwarp_tools::common::time_ms(reps, f);
    let th = time(&mut || {
        heuristic_warp_into(&field, color, &hp, &mut out).unwrap();
    });
    let ts = time(&mut || {
        std::hint::black_box(Subdivision::of_field(&field, rp.tile).unwrap());
    });
    let sub = Subdivision::of_field(&field, rp.tile).unwrap();
    let tq = time(&mut || {
        robust_warp_with(&sub, &field, color, &rp, &mut out).unwrap();
    });
    let st = robust_warp_with(&sub, &field, color, &rp, &mut out).unwrap();

    let mut fp = 0xcbf29ce484222325u64;
    for c in out.color.data() {
        for v in c {
            for b in v.to_bits().to_le_bytes() {
                fp = (fp ^ b as u64).wrapping_mul(0x100000001b3);
            }
        }
    }
    println!(
        "heuristic {:.2} [{:.2},{:.2}]  subdivision {:.2} [{:.2},{:.2}]  quads {:.2} [{:.2},{:.2}]  robust/heuristic {:.2}  {:?}  hash {fp:016x}",
        th.0, th.1, th.2, ts.0, ts.1, ts.2, tq.0, tq.1, tq.2, (ts.0 + tq.0) / th.0, st
    );
}
