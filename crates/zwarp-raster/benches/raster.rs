//! Criterion benchmark of the CPU rasterizer (depth-only, frame, peeling) on procedural scenes
//! and, if `ZWARP_SPONZA` points at `shared/scenes/sponza`, on Crytek Sponza at 1920x1080.

use criterion::{criterion_group, criterion_main, Criterion};
use zwarp_raster::{render_depth, render_frame, render_layers, scenes, FrameOptions, PeelOptions};

fn bench(c: &mut Criterion) {
    let (w, h) = (1920, 1080);
    let mut g = c.benchmark_group("raster_1080p");
    g.sample_size(10);
    if let Ok(dir) = std::env::var("ZWARP_SPONZA") {
        let s = scenes::load_raw_sponza(std::path::Path::new(&dir)).expect("sponza");
        let cam = scenes::sponza_camera(w, h).unwrap();
        g.bench_function("sponza_depth", |b| b.iter(|| render_depth(&s, &cam, 0.0).unwrap()));
        g.bench_function("sponza_frame_color", |b| {
            b.iter(|| render_frame(&s, &cam, 0.0, &FrameOptions { color: true, objects: None }).unwrap())
        });
        g.bench_function("sponza_peel4", |b| {
            b.iter(|| render_layers(&s, &cam, 0.0, &PeelOptions { layers: 4, ..Default::default() }).unwrap())
        });
    }
    let (s, cam) = scenes::sphere_field(16, 48, w, h).unwrap();
    g.bench_function("spheres_depth", |b| b.iter(|| render_depth(&s, &cam, 0.0).unwrap()));
    let (s, cam) = scenes::box_city(100, w, h).unwrap();
    g.bench_function("city_depth", |b| b.iter(|| render_depth(&s, &cam, 0.0).unwrap()));
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
