//! GPU motion field vs `zwarp_core::motion_field` (the same function; seed 000 Sec. 3.1).

use zwarp_testkit as common;

use common::*;
use glam::{DVec2, DVec4, Mat4, Vec3};
use proptest::prelude::*;
use zwarp_core::{motion_field, Camera, Image, Motion, EMPTY_DEPTH, NO_ITEM};
use zwarp_gpu::readback::read_buffer;
use zwarp_gpu::{test_context, FrameOptions, GpuScene, LayerTargets, PeelOptions, Renderer};
use zwarp_warp::gpu::{GpuImage, MotionKernel, SourceKernel};

/// The bar: 1e-3 px in motion and 1e-5 in target depth; behind-eye samples identical.
fn assert_close(gpu: &Image<Motion>, cpu: &Image<Motion>) {
    assert_eq!(gpu.size(), cpu.size());
    for (i, (g, c)) in gpu.data().iter().zip(cpu.data()).enumerate() {
        if c.v.x >= 1e8 {
            assert_eq!((g.v.x, g.v.y, g.depth), (1e9, 1e9, 1.0), "pixel {i}");
            continue;
        }
        assert!((g.v - c.v).abs().max_element() < 1e-3, "pixel {i}: gpu {g:?} cpu {c:?}");
        assert!((g.depth - c.depth).abs() < 1e-5, "pixel {i}: gpu {g:?} cpu {c:?}");
    }
}

#[test]
fn motion_of_rendered_frame_matches_cpu_with_object_motion() {
    let Some(ctx) = test_context() else { return };
    let scene = test_scene();
    let gs = GpuScene::upload(&ctx, &scene).unwrap();
    let r = Renderer::new(&ctx).unwrap();
    let (a, b) = (camera_a(), camera_b());
    let (ta, tb) = (0.0, 0.5);
    let frame = r.render_frame(&gs, &a, ta, &FrameOptions::default()).unwrap();
    let deltas = scene.object_deltas(ta, tb);
    let k = MotionKernel::new(&ctx).unwrap();
    let gpu = k.motion_field(&frame.depth, Some(&frame.items), &a, &b, &deltas).unwrap();
    let cpu = motion_field(&frame.depth, Some(&frame.items), &a, &b, &deltas).unwrap();
    assert_close(&gpu, &cpu);
    // Object motion is used: the moving sphere's pixels move differently with and without it.
    let no_obj = k.motion_field(&frame.depth, None, &a, &b, &[]).unwrap();
    let sphere = frame.items.data().iter().position(|&id| id == 3).expect("sphere visible");
    assert!((no_obj.data()[sphere].v - gpu.data()[sphere].v).length() > 0.5);
    // Empty pixels keep depth 1.
    for (d, m) in frame.depth.data().iter().zip(gpu.data()) {
        if *d >= EMPTY_DEPTH {
            assert_eq!(m.depth, 1.0);
        }
    }
}

/// Target eye inside the scene, looking back: many samples are behind it, many lie within a
/// unit of it (ill-conditioned: unprojection cancels ~far/near digits, then 1/w amplifies them).
/// Behind-eye flags and unknown-id handling must match exactly; on-screen motion is checked
/// against an f64 evaluation: the GPU must be as accurate as the CPU f32 twin.
#[test]
fn behind_eye_and_unknown_ids_match_cpu() {
    let Some(ctx) = test_context() else { return };
    let a = camera_a();
    let b = Camera::perspective(Vec3::new(0.0, 1.0, 1.0), Vec3::new(0.0, -5.0, 1.0), Vec3::Z, 1.0, 0.1, 100.0, 64, 80)
        .unwrap();
    let depth = Image::from_fn(W, H, |x, y| if (x + y) % 7 == 0 { 1.0 } else { 0.9 + 0.0009 * (x % 97) as f32 });
    let items = Image::from_fn(W, H, |x, _| if x % 5 == 0 { NO_ITEM } else { x % 4 });
    let deltas = [Mat4::IDENTITY, Mat4::from_translation(Vec3::new(0.5, 0.0, 0.0)), Mat4::from_rotation_z(0.2)];
    let k = MotionKernel::new(&ctx).unwrap();
    let gpu = k.motion_field(&depth, Some(&items), &a, &b, &deltas).unwrap();
    let cpu = motion_field(&depth, Some(&items), &a, &b, &deltas).unwrap();
    let inv_a = a.view_proj().as_dmat4().inverse();
    let vp_b = b.view_proj().as_dmat4();
    let (mut err_gpu, mut err_cpu, mut behind, mut on_screen) = (0f64, 0f64, 0, 0);
    for i in 0..depth.len() {
        let (g, c) = (gpu.data()[i], cpu.data()[i]);
        assert_eq!(g.v.x >= 1e8, c.v.x >= 1e8, "pixel {i}: behind-eye flag differs: gpu {g:?} cpu {c:?}");
        if c.v.x >= 1e8 {
            assert_eq!((g.v.x, g.v.y, g.depth), (1e9, 1e9, 1.0));
            behind += 1;
            continue;
        }
        let d = depth.data()[i] as f64;
        let (x, y) = ((i % W as usize) as f64 + 0.5, (i / W as usize) as f64 + 0.5);
        let id = items.data()[i] as usize;
        let m = if d < 1.0 && id < deltas.len() { vp_b * deltas[id].as_dmat4() } else { vp_b };
        let p = inv_a * DVec4::new(x / W as f64 * 2.0 - 1.0, 1.0 - y / H as f64 * 2.0, d, 1.0);
        let cl = m * (p / p.w);
        let v = DVec2::new((cl.x / cl.w + 1.0) * 32.0 - x, (1.0 - cl.y / cl.w) * 40.0 - y);
        if (v + DVec2::new(x, y)).abs().max_element() > 256.0 {
            continue; // far off-screen: unreachable for any search
        }
        on_screen += 1;
        err_gpu = err_gpu.max((g.v.as_dvec2() - v).abs().max_element());
        err_cpu = err_cpu.max((c.v.as_dvec2() - v).abs().max_element());
    }
    assert!(behind > 100 && on_screen > 1000, "behind {behind}, on screen {on_screen}");
    assert!(err_gpu <= 1.5 * err_cpu + 1e-3, "gpu error {err_gpu} px vs cpu error {err_cpu} px");
}

#[test]
fn motion_input_errors() {
    let Some(ctx) = test_context() else { return };
    let k = MotionKernel::new(&ctx).unwrap();
    let a = camera_a();
    let bad_size = Image::new(W - 1, H, 0.5f32);
    assert!(k.motion_field(&bad_size, None, &a, &a, &[]).is_err());
    let mut nan = Image::new(W, H, 0.5f32);
    nan.data_mut()[7] = f32::NAN;
    assert!(k.motion_field(&nan, None, &a, &a, &[]).unwrap_err().to_string().contains("NaN"));
    let d = Image::new(W, H, 0.5f32);
    assert!(k.motion_field(&d, Some(&Image::new(W, H + 1, 0u32)), &a, &a, &[]).is_err());
    assert!(k.motion_field(&Image::new(0, 0, 0.5f32), None, &a, &a, &[]).is_err());
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 6, ..ProptestConfig::default() })]
    /// Random camera pairs and depths: GPU and CPU compute the same function.
    #[test]
    fn random_cameras_match_cpu(
        ex in -3.0f32..3.0, ey in -6.0f32..-2.0, ez in 0.5f32..4.0,
        dx in -1.0f32..1.0, dy in -1.0f32..1.0, dz in -0.5f32..0.5,
        fov in 0.5f32..1.8, seed in 0u32..1000,
    ) {
        let Some(ctx) = test_context() else { return Ok(()) };
        let a = Camera::perspective(Vec3::new(ex, ey, ez), Vec3::ZERO, Vec3::Z, fov, 0.1, 50.0, 40, 24).unwrap();
        let b = Camera::perspective(Vec3::new(ex + dx, ey + dy, ez + dz), Vec3::new(dx, 0.0, 0.0), Vec3::Z, fov, 0.1, 50.0, 40, 24)
            .unwrap();
        let depth = Image::from_fn(40, 24, |x, y| {
            let h = (x * 7919 + y * 104729 + seed * 31) % 1000;
            if h < 50 { 1.0 } else { 0.95 + 0.049 * h as f32 / 1000.0 }
        });
        let k = MotionKernel::new(&ctx).unwrap();
        let gpu = k.motion_field(&depth, None, &a, &b, &[]).unwrap();
        let cpu = motion_field(&depth, None, &a, &b, &[]).unwrap();
        assert_close(&gpu, &cpu);
    }
}

/// The all-GPU chain (render A, copy, motion kernel) vs `zwarp_raster::render_motion`.
#[test]
fn render_motion_matches_zwarp_raster() {
    let Some(ctx) = test_context() else { return };
    let scene = test_scene();
    let gs = GpuScene::upload(&ctx, &scene).unwrap();
    let r = Renderer::new(&ctx).unwrap();
    let k = MotionKernel::new(&ctx).unwrap();
    let (a, b) = (camera_a(), camera_b());
    let (gf, gm) = k.render_motion(&r, &gs, &a, 0.1, &b, 0.6).unwrap();
    let (cf, cm) = zwarp_raster::render_motion(&scene, &a, 0.1, &b, 0.6).unwrap();
    assert_eq!(gf.depth, r.render_depth(&gs, &a, 0.1).unwrap(), "readback through the padded buffer");
    let mut compared = 0;
    for i in 0..gm.len() {
        if (gf.depth.data()[i] - cf.depth.data()[i]).abs() < 1e-6 && gf.items.data()[i] == cf.items.data()[i] {
            compared += 1;
            let (g, c) = (gm.data()[i], cm.data()[i]);
            assert!((g.v - c.v).abs().max_element() < 1e-3, "pixel {i}: gpu {g:?} cpu {c:?}");
            assert!((g.depth - c.depth).abs() < 1e-5, "pixel {i}: gpu {g:?} cpu {c:?}");
        }
    }
    assert!(compared as f64 >= 0.999 * gm.len() as f64);
    assert!(k.render_motion(&r, &gs, &a, 0.0, &b, f32::INFINITY).is_err());
}

/// The paper's procedural scenes from zwarp-scene (scaled down), on their recorded camera paths:
/// GPU vs `zwarp_raster` depth and item ids, and GPU vs CPU motion between two path frames.
#[test]
fn procedural_scenes_match_zwarp_raster() {
    let Some(ctx) = test_context() else { return };
    let r = Renderer::new(&ctx).unwrap();
    let mk = MotionKernel::new(&ctx).unwrap();
    for name in ["mo", "bl", "cb"] {
        let opts = zwarp_scene::SceneOptions { seed: 7, scale: 0.02, ..Default::default() };
        let loaded = zwarp_scene::load_scene(name, &opts).unwrap();
        let (scene, path) = (&loaded.scene, loaded.path_or_default());
        let gs = GpuScene::upload(&ctx, scene).unwrap();
        let (t0, t1) = (path.start() + 0.3 * path.duration(), path.start() + 0.3 * path.duration() + 1.0 / 30.0);
        let (a, b) = (path.camera_at(t0, W, H).unwrap(), path.camera_at(t1, W, H).unwrap());
        let gpu = r.render_frame(&gs, &a, t0, &FrameOptions::default()).unwrap();
        let cpu = zwarp_raster::render_frame(scene, &a, t0, &Default::default()).unwrap();
        let agree = agreement(&gpu.depth, &cpu.depth, 1e-6);
        assert!(agree >= 0.999, "{name}: only {:.4}% of pixels agree", agree * 100.0);
        let covered = cpu.depth.data().iter().filter(|d| **d < EMPTY_DEPTH).count();
        let objects: std::collections::HashSet<u32> = cpu.items.data().iter().copied().collect();
        assert!(covered > 200 && objects.len() > 3, "{name}: {covered} px, {} ids visible", objects.len());
        let same_ids = (0..gpu.depth.len())
            .filter(|&i| (gpu.depth.data()[i] - cpu.depth.data()[i]).abs() < 1e-6)
            .all(|i| gpu.items.data()[i] == cpu.items.data()[i]);
        assert!(same_ids, "{name}: item ids differ where depths agree");
        let deltas = gs.object_deltas(t0, t1);
        assert_eq!(deltas, scene.object_deltas(t0, t1));
        let gm = mk.motion_field(&gpu.depth, Some(&gpu.items), &a, &b, &deltas).unwrap();
        let cm = zwarp_core::motion_field(&gpu.depth, Some(&gpu.items), &a, &b, &deltas).unwrap();
        for (g, c) in gm.data().iter().zip(cm.data()) {
            assert!((g.v - c.v).abs().max_element() < 1e-3 || c.v.x >= 1e8, "{name}: gpu {g:?} cpu {c:?}");
        }
    }
}

/// `SourceKernel` copies an engine's images bit for bit: the renderer's own targets (two peeled
/// layers: `Depth32Float` depth, `R32Uint` items, as an engine leaves them) and strided
/// buffers of them (a 256-byte padded row pitch), against the renderer's read-back; wrong
/// formats and short buffers are one-line errors.
#[test]
fn source_copies_are_bit_exact() {
    let Some(ctx) = test_context() else { return };
    let scene = test_scene();
    let gs = GpuScene::upload(&ctx, &scene).unwrap();
    let r = Renderer::new(&ctx).unwrap();
    let k = SourceKernel::new(&ctx).unwrap();
    let a = camera_a();
    let (w, h) = (a.width, a.height);
    let targets = LayerTargets::new(&r, w, h, 2, false).unwrap();
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    r.encode_layers(&mut enc, &gs, &a, 0.1, &PeelOptions { layers: 2, ..Default::default() }, &targets).unwrap();
    ctx.queue.submit([enc.finish()]);
    let storage = |bytes: u64| {
        ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: None,
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    };
    let n = w as usize * h as usize;
    let stride = zwarp_gpu::readback::padded_bytes_per_row(w, 4) / 4;
    for layer in 0..2 {
        let want = r.read_layer(&targets, layer).unwrap();
        assert!(want.depth.data().iter().any(|&z| z < EMPTY_DEPTH) && want.items.data().iter().any(|&i| i != NO_ITEM));
        let (depth, items) = (storage(n as u64 * 4), storage(n as u64 * 4));
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        k.encode_depth(&mut enc, &GpuImage::Texture(&targets.depth[layer].texture), w, h, &depth, "depth").unwrap();
        k.encode_items(&mut enc, &GpuImage::Texture(&targets.items[layer]), w, h, &items, "items").unwrap();
        // The same through strided buffers: a texture-to-buffer copy of the items, then the copy.
        let padded = storage(stride as u64 * h as u64 * 4);
        enc.copy_texture_to_buffer(
            targets.items[layer].as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &padded,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(stride * 4),
                    rows_per_image: Some(h),
                },
            },
            targets.items[layer].size(),
        );
        let from_buffer = storage(n as u64 * 4);
        let src = GpuImage::Buffer { buffer: &padded, row_stride: stride };
        k.encode_items(&mut enc, &src, w, h, &from_buffer, "padded items").unwrap();
        ctx.queue.submit([enc.finish()]);
        let bits: Vec<u32> = want.depth.data().iter().map(|z| z.to_bits()).collect();
        assert_eq!(read_buffer::<u32>(&ctx, &depth, n).unwrap(), bits, "layer {layer} depth");
        assert_eq!(read_buffer::<u32>(&ctx, &items, n).unwrap(), want.items.data(), "layer {layer} items");
        assert_eq!(read_buffer::<u32>(&ctx, &from_buffer, n).unwrap(), want.items.data(), "layer {layer} padded");
    }
    let dst = storage(n as u64 * 4);
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    let mut err = |src: GpuImage, depth: bool| {
        let r = if depth {
            k.encode_depth(&mut enc, &src, w, h, &dst, "the image")
        } else {
            k.encode_items(&mut enc, &src, w, h, &dst, "the image")
        };
        let e = r.unwrap_err().to_string();
        assert!(e.starts_with("invalid input: the image") && !e.contains('\n'), "{e}");
        e
    };
    assert!(err(GpuImage::Texture(&targets.items[0]), true).contains("R32Uint is not Depth32Float or R32Float"));
    assert!(err(GpuImage::Texture(&targets.depth[0].texture), false).contains("Depth32Float is not R32Uint"));
    assert!(err(GpuImage::Buffer { buffer: &dst, row_stride: w + 1 }, true).contains("too small"));
    let mapped = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: n as u64 * 4,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    assert!(err(GpuImage::Buffer { buffer: &mapped, row_stride: w }, true).contains("STORAGE"));
}
