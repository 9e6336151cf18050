//! Build and query time of the max-depth structures at 1920x1080 (thesis Sec. III.2: "Y-Maps with
//! two mipmap levels lead to a lower construction time (e.g., from 0.6 ms to 0.2 ms)").

use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;
use zwarp_core::Image;
use zwarp_cull::{erode_max, MaxDepthKind, MaxDepthMap, MaxDepthQuery, PixelRect};

const W: u32 = 1920;
const H: u32 = 1080;

/// Deterministic pseudo-random numbers (SplitMix64) so the bench needs no RNG crate.
fn splitmix(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

fn depth() -> Image<f32> {
    // Smooth surfaces with steps, roughly like a rendered scene.
    Image::from_fn(W, H, |x, y| 0.9 + 0.09 * (((x / 37) * 13 + (y / 23) * 7) % 17) as f32 / 17.0)
}

/// Rectangles with log-uniform sides from 1 to 512 pixels, like projected object bounds.
fn rects(n: usize) -> Vec<PixelRect> {
    let mut s = 42u64;
    (0..n)
        .map(|_| {
            let a = 1u32 << (splitmix(&mut s) % 10);
            let b = 1u32 << (splitmix(&mut s) % 10);
            let a = (a + (splitmix(&mut s) % a as u64) as u32).min(W);
            let b = (b + (splitmix(&mut s) % b as u64) as u32).min(H);
            let x0 = (splitmix(&mut s) % (W - a + 1) as u64) as u32;
            let y0 = (splitmix(&mut s) % (H - b + 1) as u64) as u32;
            PixelRect::new(x0, y0, x0 + a, y0 + b).unwrap()
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let d = depth();
    let rs = rects(10_000);
    let kinds = [
        ("mipmap", MaxDepthKind::Mipmap),
        ("nbuffer", MaxDepthKind::NBuffer),
        ("ymap1", MaxDepthKind::YMap { switch: 1 }),
        ("ymap2", MaxDepthKind::YMap { switch: 2 }),
        ("ymap3", MaxDepthKind::YMap { switch: 3 }),
    ];
    let mut g = c.benchmark_group("build_1920x1080");
    g.sample_size(10);
    for (name, kind) in kinds {
        g.bench_function(name, |b| b.iter(|| black_box(MaxDepthMap::build(kind, black_box(&d)).unwrap())));
    }
    g.bench_function("erode_max", |b| b.iter(|| black_box(erode_max(black_box(&d)))));
    g.finish();
    let mut g = c.benchmark_group("query_10k_rects");
    g.sample_size(10);
    for (name, kind) in kinds {
        let m = MaxDepthMap::build(kind, &d).unwrap();
        g.bench_function(name, |b| b.iter(|| rs.iter().filter(|r| m.is_occluded(**r, 0.95)).count()));
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
