//! Criterion benchmark of the CPU rasterizer at 1920x1080: depth-only renders of the four
//! procedural scenes of seed 000 Sec. 4 (`zwarp_scene`, reduced scale so the benchmark stays
//! quick: the `raster_table` tool runs them at full scale) from the frame at 1/3 of their recorded camera
//! paths, and, if `ZWARP_SPONZA` points at `shared/scenes/sponza`, Crytek Sponza from the
//! committed `sponza_court.json` walk (depth only, frame with colour, peeling L = 4).

use criterion::{criterion_group, criterion_main, Criterion};
use zwarp_core::Camera;
use zwarp_raster::{render_depth, render_frame, render_layers, FrameOptions, PeelOptions};
use zwarp_scene::{load_scene, CameraPath, SceneOptions};

const SPONZA_COURT: &str = include_str!("../../zwarp-scene/paths/sponza_court.json");

/// Camera and time of the frame at 1/3 of `path`.
fn third(path: &CameraPath, w: u32, h: u32) -> (Camera, f32) {
    let t = path.start() + path.duration() / 3.0;
    (path.camera_at(t, w, h).expect("camera"), t)
}

fn bench(c: &mut Criterion) {
    let (w, h) = (1920, 1080);
    let mut g = c.benchmark_group("raster_1080p");
    g.sample_size(10);
    if let Ok(dir) = std::env::var("ZWARP_SPONZA") {
        let s = load_scene(&dir, &SceneOptions::default()).expect("sponza").scene;
        let (cam, t) = third(&CameraPath::from_json_str(SPONZA_COURT).expect("sponza path"), w, h);
        g.bench_function("sponza_depth", |b| b.iter(|| render_depth(&s, &cam, t).unwrap()));
        g.bench_function("sponza_frame_color", |b| {
            b.iter(|| render_frame(&s, &cam, t, &FrameOptions { color: true, objects: None }).unwrap())
        });
        g.bench_function("sponza_peel4", |b| {
            b.iter(|| render_layers(&s, &cam, t, &PeelOptions { layers: 4, ..Default::default() }).unwrap())
        });
    }
    // Scales: yr 0.1 = 2 of its ~147K-triangle objects, mo 0.1 = 630 objects, bl 0.05 = 1750
    // balloons, cb 0.1 = an 8x8 block city.
    for (name, scale) in [("yr", 0.1), ("mo", 0.1), ("bl", 0.05), ("cb", 0.1)] {
        let loaded = load_scene(name, &SceneOptions { scale, ..Default::default() }).expect("generator");
        let (cam, t) = third(&loaded.path_or_default(), w, h);
        let s = loaded.scene;
        g.bench_function(format!("{name}_x{scale}_depth"), |b| b.iter(|| render_depth(&s, &cam, t).unwrap()));
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
