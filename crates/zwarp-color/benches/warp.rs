//! Colour-warp benchmark (seed 001) at 1280x720 on the procedural MO scene (rendered once with
//! zwarp-raster): the heuristic warp (Sec. 3.3) and the robust warp (Sec. 3.4) of a temporal
//! field (the frame half-way to the next one, `zwarp upsample --factor 2`) and of a stereo field
//! (the right eye 32 mm from the rendered centre view, `zwarp stereo` cyclops), beside the
//! streaming floor of each field (`floor_pass`: read the planes and the colour once, write the
//! colour) in the same run: the figure is the ratio.
//!
//! `cargo bench -p zwarp-color --bench warp` (set RAYON_NUM_THREADS to pin the core count).

use criterion::Criterion;
use zwarp_color::{
    fixed_offset, floor::floor_pass, heuristic_warp_into, robust_warp, ColorWarpOutput, FieldParams, HeuristicParams,
    RobustParams, Seed, WarpBasis,
};
use zwarp_core::{motion_field, Image};
use zwarp_raster::{render_frame, FrameOptions};

fn main() {
    let (w, h) = (1280, 720);
    let loaded = zwarp_scene::load_scene("mo", &zwarp_scene::SceneOptions::default()).expect("procedural scene");
    let path = loaded.path_or_default();
    let (t0, t1) = (path.time_of_frame(10, 1.0), path.time_of_frame(11, 1.0));
    let (cam0, cam1) = (path.camera_at(t0, w, h).expect("camera"), path.camera_at(t1, w, h).expect("camera"));
    let frame = render_frame(&loaded.scene, &cam0, t0, &FrameOptions { color: true, objects: None }).expect("render");
    let color = frame.color.as_ref().expect("colour is requested");
    let motion = motion_field(&frame.depth, Some(&frame.items), &cam0, &cam1, &loaded.scene.object_deltas(t0, t1))
        .expect("motion");
    let temporal = WarpBasis::temporal(&frame.depth, &motion).expect("basis");
    let spatial = WarpBasis::new(&frame.depth).expect("basis").with_spatial(&cam0, None).expect("basis");
    let fields = [
        ("temporal", temporal.field(FieldParams::temporal(0.5)).expect("field"), None),
        ("stereo", spatial.field(FieldParams::spatial(0.032, 0.0)).expect("field"), Some(())),
    ];

    let mut c = Criterion::default().configure_from_args().sample_size(30);
    let mut g = c.benchmark_group("color_warp_1280x720");
    for (name, field, stereo) in &fields {
        // The seeds of the commands: upstream in the flow (temporal), the fixed offset (stereo).
        let seed = if stereo.is_some() { Seed::Offset(fixed_offset(field)) } else { Seed::Upstream(1.0) };
        let hp = HeuristicParams { seed, ..HeuristicParams::default() };
        let mut out = ColorWarpOutput::empty();
        g.bench_function(format!("{name}/heuristic"), |b| {
            b.iter(|| heuristic_warp_into(field, color, &hp, &mut out).expect("heuristic"))
        });
        let rp = RobustParams { fallback: hp, ..RobustParams::default() };
        g.bench_function(format!("{name}/robust"), |b| b.iter(|| robust_warp(field, color, &rp).expect("robust")));
        let mut floor = Image::new(0, 0, [0.0f32; 3]);
        g.bench_function(format!("{name}/floor"), |b| b.iter(|| floor_pass(field, color, &mut floor).expect("floor")));
    }
    g.finish();
    c.final_summary();
}
