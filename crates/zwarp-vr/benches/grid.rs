//! Stereo grid-warp benchmark (seed 003 Sec. 5) at 1280x720: the centre view of the procedural
//! MO scene (rendered once with zwarp-raster, colour and depth) warped to the right eye 64 mm
//! away, stage by stage — the surface-estimation quadtree, the adaptive grid's cells, the warp
//! (quads rasterised with a depth test and the colour fetch), the depth-aware low-pass hole fill
//! — beside rendering that eye (depth and colour) in the same run, the alternative it replaces.
//!
//! `cargo bench -p zwarp-vr --bench grid` (set RAYON_NUM_THREADS to pin the core count).

use criterion::Criterion;
use glam::{Mat4, Vec3};
use zwarp_core::Camera;
use zwarp_raster::{render_frame, FrameOptions};
use zwarp_vr::grid::{raster, Mesh, Source, WarpParams};
use zwarp_vr::{fill_holes, HoleMethod, Method, QuadTree, Reduction};

fn main() {
    let (w, h) = (1280, 720);
    let loaded = zwarp_scene::load_scene("mo", &zwarp_scene::SceneOptions::default()).expect("procedural scene");
    let path = loaded.path_or_default();
    let t = path.time_of_frame(10, 1.0);
    let centre = path.camera_at(t, w, h).expect("camera");
    // The right eye: half the 64 mm interpupillary distance along the camera's right axis.
    let right = Camera { view: Mat4::from_translation(Vec3::new(-0.032, 0.0, 0.0)) * centre.view, ..centre };
    let opts = FrameOptions { color: true, objects: None };
    let frame = render_frame(&loaded.scene, &centre, t, &opts).expect("render");
    let color = frame.color.expect("colour is requested");
    let src = Source { cam: &centre, depth: &frame.depth, color: &color };
    let p = WarpParams::default();
    let method = Method::Grid(Reduction::Irregular);
    let mesh = Mesh::build(&src, &right, method, &p).expect("mesh");
    let warped = raster(&src, &right, &mesh).expect("warp");

    let mut c = Criterion::default().configure_from_args().sample_size(20);
    let mut g = c.benchmark_group("grid_warp_1280x720");
    g.bench_function("quadtree", |b| {
        b.iter(|| QuadTree::build(&frame.depth, Reduction::Irregular, &p.collinearity).expect("quadtree"))
    });
    let tree = QuadTree::build(&frame.depth, Reduction::Irregular, &p.collinearity).expect("quadtree");
    g.bench_function("cells", |b| b.iter(|| Mesh::grid(&src, &right, tree.clone(), &p).expect("cells")));
    g.bench_function("warp", |b| b.iter(|| raster(&src, &right, &mesh).expect("warp")));
    g.bench_function("holes_lowpass", |b| {
        b.iter(|| fill_holes(&warped, &src, &right, HoleMethod::LowPass).expect("holes"))
    });
    g.bench_function("render_eye", |b| b.iter(|| render_frame(&loaded.scene, &right, t, &opts).expect("render")));
    g.finish();
    c.final_summary();
}
