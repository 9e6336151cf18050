//! GPU max-depth structures (seed 000 Sec. 5.2) vs their CPU twins in zwarp-cull: every level of
//! the max mipmap, N-buffer and Y-map bit-identical, and every query answer equal, on random
//! depth buffers of power-of-two, odd and prime sizes; error paths.

use zwarp_testkit as common;

use proptest::prelude::*;
use zwarp_core::{Image, EMPTY_DEPTH};
use zwarp_cull::gpu::MaxDepthKernel;
use zwarp_cull::{MaxDepthKind, MaxDepthMap, MaxDepthQuery, MaxMipmap, NBuffer, PixelRect, YMap};
use zwarp_gpu::{test_context, GpuContext};

/// A deterministic pseudo-random depth buffer: surfaces in `[0.05, 0.95)`, ~15% far holes.
pub fn random_depth(w: u32, h: u32, seed: u64) -> Image<f32> {
    let mut next = common::rng(seed);
    Image::from_fn(w, h, |_, _| {
        let u = next();
        if u < 0.15 {
            EMPTY_DEPTH
        } else {
            0.05 + 0.9 * u
        }
    })
}

const KINDS: [MaxDepthKind; 6] = [
    MaxDepthKind::Mipmap,
    MaxDepthKind::NBuffer,
    MaxDepthKind::YMap { switch: 0 },
    MaxDepthKind::YMap { switch: 1 },
    MaxDepthKind::YMap { switch: 2 },
    MaxDepthKind::YMap { switch: 3 },
];

fn check_levels(ctx: &GpuContext, k: &MaxDepthKernel, depth: &Image<f32>, kind: MaxDepthKind) {
    let gpu = k.build(depth, kind).unwrap();
    let (mip, nbuf) = gpu.read_levels(ctx).unwrap();
    let (cpu_mip, cpu_nbuf): (Vec<Image<f32>>, Vec<Image<f32>>) = match kind {
        MaxDepthKind::Mipmap => (MaxMipmap::build(depth).unwrap().levels().to_vec(), Vec::new()),
        MaxDepthKind::NBuffer => (Vec::new(), NBuffer::build(depth).unwrap().levels().to_vec()),
        MaxDepthKind::YMap { switch } => {
            let y = YMap::build(depth, switch).unwrap();
            assert_eq!(gpu.layout.kind, MaxDepthKind::YMap { switch: y.switch() });
            (y.mip_levels().to_vec(), y.nbuffer().levels().to_vec())
        }
        MaxDepthKind::Default => unreachable!(),
    };
    assert_eq!(mip.len(), cpu_mip.len(), "{kind:?} {:?}: mip level count", depth.size());
    assert_eq!(nbuf.len(), cpu_nbuf.len(), "{kind:?} {:?}: N-buffer level count", depth.size());
    for (i, (g, c)) in mip.iter().zip(&cpu_mip).chain(nbuf.iter().zip(&cpu_nbuf)).enumerate() {
        assert_eq!(g, c, "{kind:?} {:?}: stored level {i} differs", depth.size());
    }
}

#[test]
fn levels_equal_the_cpu_structures() {
    let Some(ctx) = test_context() else { return };
    let k = MaxDepthKernel::new(&ctx).unwrap();
    for (i, (w, h)) in
        [(1, 1), (2, 1), (5, 3), (13, 11), (16, 16), (17, 31), (64, 48), (97, 61)].into_iter().enumerate()
    {
        let d = random_depth(w, h, i as u64 + 1);
        for kind in KINDS {
            check_levels(&ctx, &k, &d, kind);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(12))]

    /// Random sizes and rects (partly or fully outside the image too): the GPU query answers
    /// exactly what the CPU structure answers, for every kind, and the N-buffer answer is the
    /// brute-force maximum.
    #[test]
    fn queries_equal_the_cpu_answers(w in 1u32..90, h in 1u32..70, seed in 0u64..1000,
                                     rects in prop::collection::vec((0u32..100, 0u32..80, 1u32..60, 1u32..60), 40)) {
        let Some(ctx) = test_context() else { return Ok(()) };
        let k = MaxDepthKernel::new(&ctx).unwrap();
        let d = random_depth(w, h, seed);
        let rects: Vec<PixelRect> =
            rects.iter().map(|&(x, y, a, b)| PixelRect::new(x, y, x + a, y + b).unwrap()).collect();
        for kind in KINDS.into_iter().chain([MaxDepthKind::Default]) {
            let gpu = k.query(&k.build(&d, kind).unwrap(), &rects).unwrap();
            let cpu = MaxDepthMap::build(kind, &d).unwrap();
            for (r, g) in rects.iter().zip(&gpu) {
                prop_assert_eq!(*g, cpu.max_depth(*r), "{:?} {}x{} rect {:?}", kind, w, h, r);
                if kind == MaxDepthKind::NBuffer {
                    prop_assert_eq!(*g, zwarp_cull::max_in_rect(&d, *r));
                }
            }
        }
    }
}

#[test]
fn bad_input_is_an_error() {
    let Some(ctx) = test_context() else { return };
    let k = MaxDepthKernel::new(&ctx).unwrap();
    let e = k.build(&Image::new(0, 3, 0.5f32), MaxDepthKind::Mipmap).unwrap_err().to_string();
    assert!(e.contains("zero-size"), "{e}");
    let mut d = Image::new(3, 3, 0.5f32);
    *d.get_mut(1, 2) = f32::NAN;
    let e = k.build(&d, MaxDepthKind::NBuffer).unwrap_err().to_string();
    assert!(e.contains("NaN at pixel (1, 2)"), "{e}");
    let e = k.build(&Image::new(4, 4, 0.5f32), MaxDepthKind::YMap { switch: 17 }).unwrap_err().to_string();
    assert!(e.contains("exceeds"), "{e}");
    // A depth buffer smaller than the structure's image, or without COPY_SRC.
    let map = k.create(MaxDepthKind::Mipmap, 8, 8).unwrap();
    let small = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: 16,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    let e = k.encode(&mut enc, &small, &map).unwrap_err().to_string();
    assert!(e.contains("16 < 256 bytes"), "{e}");
}
