//! The GPU WOC pipeline (seed 000 Sec. 5; thesis seed 002 Sec. III-IV) vs `zwarp_cull::woc` on
//! a small animated scene (BL: every balloon bobs or drifts) along its recorded path, both
//! started from the same GPU-rendered previous frame; its per-pixel stages (opening rims,
//! erosion) vs their CPU twins on random inputs; error paths.

use zwarp_testkit as common;

use glam::Vec2;
use zwarp_core::{Camera, Image, Motion, Scene, EMPTY_DEPTH, NO_ITEM};
use zwarp_cull::gpu::{rapid_flags, CullObjects, CullOutput, GpuPrevFrame, GpuWoc, GpuWocParams};
use zwarp_cull::{erode_max, opening_rims, woc, PrevFrame, WocParams};
use zwarp_gpu::{test_context, GpuContext, GpuScene, LayerTargets, PeelOptions, Renderer};

const W: u32 = 157;
const H: u32 = 93;

use common::rng;

#[test]
fn erosion_and_rims_equal_their_cpu_twins() {
    let Some(ctx) = test_context() else { return };
    for (w, h, seed) in [(1u32, 1u32, 1u64), (2, 5, 2), (37, 23, 3), (64, 40, 4)] {
        let k = GpuWoc::new(&ctx, w, h, GpuWocParams::default()).unwrap();
        let mut r = rng(seed);
        // Blocky objects (ids per 4x3 block), some empty, with per-object motion + jitter.
        let bw = w.div_ceil(4);
        let blocks: Vec<(u32, f32, Vec2)> = (0..bw * h.div_ceil(3))
            .map(|i| {
                let empty = r() < 0.15;
                (
                    if empty { NO_ITEM } else { i },
                    if empty { EMPTY_DEPTH } else { 0.1 + 0.8 * r() },
                    Vec2::new(4.0 * r() - 2.0, 4.0 * r() - 2.0),
                )
            })
            .collect();
        let at = |x: u32, y: u32| blocks[((y / 3) * bw + x / 4) as usize];
        let depth = Image::from_fn(w, h, |x, y| at(x, y).1);
        let items = Image::from_fn(w, h, |x, y| at(x, y).0);
        let mut r2 = rng(seed + 100);
        let motion =
            Image::from_fn(w, h, |x, y| Motion { v: at(x, y).2 + Vec2::splat(0.05 * r2()), depth: at(x, y).1 });
        assert_eq!(k.erode_image(&depth).unwrap(), erode_max(&depth), "erosion {w}x{h}");
        for sep in [0.0, 0.1, 1.0] {
            let gpu = k.opening_rims_image(&depth, &items, &motion, sep).unwrap();
            let cpu = opening_rims(&depth, &items, &motion, sep).unwrap();
            assert_eq!(gpu, cpu, "rims {w}x{h} sep {sep}");
            if w > 8 && sep == 0.0 {
                assert!(gpu.data().iter().zip(depth.data()).filter(|(a, b)| a != b).count() > 0, "no rim opened");
            }
        }
    }
}

/// Renders the previous frame on the GPU into textures (what an engine has) and reads the
/// same buffers back for the CPU pipeline.
fn prev_frame(
    ctx: &GpuContext,
    r: &Renderer,
    gs: &GpuScene,
    cam: &Camera,
    t: f32,
) -> (LayerTargets, Image<f32>, Image<u32>) {
    let targets = LayerTargets::new(r, W, H, 1, false).unwrap();
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    let opts = PeelOptions { layers: 1, ..Default::default() };
    r.encode_layers(&mut enc, gs, cam, t, &opts, &targets).unwrap();
    ctx.queue.submit([enc.finish()]);
    let f = r.render_frame(gs, cam, t, &Default::default()).unwrap();
    (targets, f.depth, f.items)
}

/// GPU WOC and CPU WOC (its twin parameters) from the same previous frame: the same visible
/// set except objects at the conservative margin, predicted depths equal on >= 99% of pixels.
#[test]
fn decisions_equal_the_cpu_woc_on_an_animated_scene() {
    compare_with_cpu_woc(false);
}

/// The same for AWOC (seed 000 Sec. 5.3: holes filled from the search-region corners).
#[test]
fn decisions_equal_the_cpu_awoc_on_an_animated_scene() {
    compare_with_cpu_woc(true);
}

fn compare_with_cpu_woc(awoc: bool) {
    let Some(ctx) = test_context() else { return };
    let loaded = zwarp_scene::procedural::bl(&zwarp_scene::SceneOptions { scale: 0.02, ..Default::default() }).unwrap();
    let scene: Scene = loaded.scene;
    let frames = loaded.path.unwrap().frames(W, H, 1.0).unwrap();
    let gs = GpuScene::upload(&ctx, &scene).unwrap();
    let r = Renderer::new(&ctx).unwrap();
    let base = WocParams { awoc, ..WocParams::default() };
    let cpu_params = GpuWocParams::cpu_twin(&base);
    let woc_gpu = GpuWoc::new(&ctx, W, H, GpuWocParams::from_cpu(&base).unwrap()).unwrap();
    assert_eq!(woc_gpu.params().awoc, awoc);
    let objects = CullObjects::for_scene(&ctx, &gs).unwrap();
    let out = CullOutput::new(&ctx, objects.len()).unwrap();
    let n = scene.instances.len();
    let (mut differ, mut culled, mut pixels_differ) = (0usize, 0usize, 0usize);
    let steps = [1usize, 5, 9, 13];
    for &k in &steps {
        let ((t0, cam0), (t1, cam1)) = (frames[k - 1], frames[k]);
        let (targets, d0, i0) = prev_frame(&ctx, &r, &gs, &cam0, t0);
        let pf = PrevFrame { depth: &d0, items: &i0, cam: &cam0, t: t0 };
        let cpu = woc(&scene, &pf, &cam1, t1, &cpu_params).unwrap();
        objects.write_scene_aabbs(&ctx, &scene, t1).unwrap();
        objects.write_forced(&ctx, Some(&rapid_flags(&scene, &cam0, t0, &cam1, t1, &cpu_params))).unwrap();
        let depth_view = &targets.depth[0].view;
        let items_view = targets.items[0].create_view(&Default::default());
        let prev = GpuPrevFrame { depth: depth_view, items: &items_view, cam: &cam0, t: t0 };
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        woc_gpu.encode(&mut enc, &gs, &prev, &gs.object_deltas(t0, t1), &cam1, t1, &objects, &out).unwrap();
        ctx.queue.submit([enc.finish()]);
        let gpu = out.read(&ctx).unwrap();
        let d: Vec<u32> = (0..n as u32)
            .filter(|id| gpu.visible.binary_search(id).is_ok() != cpu.visible.binary_search(id).is_ok())
            .collect();
        eprintln!(
            "awoc {awoc} frame {k}: {n} objects, CPU keeps {} (rapid {}), GPU keeps {}, differ {d:?}",
            cpu.visible.len(),
            cpu.stats.rapid,
            gpu.visible.len()
        );
        differ += d.len();
        culled += n - gpu.visible.len();
        let predicted = zwarp_gpu_read(&ctx, &woc_gpu);
        let map = cpu.occlusion_map.as_ref().unwrap();
        pixels_differ += predicted.data().iter().zip(map.data()).filter(|(a, b)| (**a - **b).abs() > 1e-5).count();
    }
    let total = (W * H) as usize * steps.len();
    eprintln!(
        "differing decisions {differ} of {} ; predicted pixels differing {pixels_differ} of {total}",
        n * steps.len()
    );
    assert!(culled > 0, "WOC culled nothing");
    assert!(differ * 200 <= n * steps.len(), "{differ} decisions differ");
    assert!(pixels_differ * 100 <= total, "{pixels_differ} predicted pixels differ");
}

fn zwarp_gpu_read(ctx: &GpuContext, w: &GpuWoc) -> Image<f32> {
    // The predicted depth is a plain storage buffer: copy it to a mappable one.
    let bytes = (W * H * 4) as u64;
    let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: None,
        size: bytes,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    enc.copy_buffer_to_buffer(w.predicted(), 0, &staging, 0, bytes);
    ctx.queue.submit([enc.finish()]);
    staging.map_async(wgpu::MapMode::Read, .., |r| r.unwrap());
    ctx.wait().unwrap();
    let data = bytemuck::pod_collect_to_vec::<u8, f32>(&staging.get_mapped_range(..).unwrap());
    Image::from_vec(W, H, data).unwrap()
}

#[test]
fn bad_input_is_an_error() {
    let Some(ctx) = test_context() else { return };
    let p = WocParams { awoc: true, ..WocParams::default() };
    assert!(GpuWocParams::from_cpu(&p).unwrap().awoc, "AWOC runs on the GPU");
    let p = WocParams { downsample: 2, ..WocParams::default() };
    assert!(GpuWocParams::from_cpu(&p).unwrap_err().to_string().contains("downsample"));
    assert!(GpuWoc::new(&ctx, 0, 4, GpuWocParams::default()).is_err());
    let k = GpuWoc::new(&ctx, 8, 6, GpuWocParams::default()).unwrap();
    let e = k.erode_image(&Image::new(7, 6, 0.5f32)).unwrap_err().to_string();
    assert!(e.contains("7x6 but the WOC pipeline is 8x6"), "{e}");
    let (d, i) = (Image::new(8, 6, 0.5f32), Image::new(8, 6, 0u32));
    let m = Image::new(8, 6, Motion::default());
    assert!(k.opening_rims_image(&d, &i, &m, -1.0).unwrap_err().to_string().contains(">= 0 pixels"));
}

/// Engine-owned outputs: a cull into buffers the caller created (`CullOutput::from_buffers`)
/// gives the same result as into ours, and a depth buffer lands bit-exactly in the caller's
/// R32Float texture; wrong buffers are named in the error.
#[test]
fn engine_owned_buffers_and_textures() {
    let Some(ctx) = test_context() else { return };
    let (w, h) = (64u32, 20u32);
    let woc = GpuWoc::new(&ctx, w, h, GpuWocParams::default()).unwrap();
    let depth =
        Image::from_fn(w, h, |x, y| if (x + y) % 7 == 0 { EMPTY_DEPTH } else { (x * 31 + y * 17) as f32 / 3000.0 });
    let dev = &ctx.device;
    let buf = |size: u64, usage: wgpu::BufferUsages| {
        dev.create_buffer(&wgpu::BufferDescriptor { label: None, size, usage, mapped_at_creation: false })
    };
    let src = buf(w as u64 * h as u64 * 4, wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST);
    ctx.queue.write_buffer(&src, 0, bytemuck::cast_slice(depth.data()));
    let tex = dev.create_texture(&wgpu::TextureDescriptor {
        usage: wgpu::TextureUsages::STORAGE_BINDING | wgpu::TextureUsages::COPY_SRC,
        ..tex_desc(w, h)
    });
    let staging = buf(w as u64 * h as u64 * 4, wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ);
    let mut enc = dev.create_command_encoder(&Default::default());
    woc.encode_depth_to_texture(&mut enc, &src, &tex.create_view(&Default::default())).unwrap();
    enc.copy_texture_to_buffer(
        tex.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &staging,
            layout: wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(w * 4), rows_per_image: None },
        },
        tex.size(),
    );
    ctx.queue.submit([enc.finish()]);
    staging.map_async(wgpu::MapMode::Read, .., |r| r.unwrap());
    ctx.wait().unwrap();
    let back = bytemuck::pod_collect_to_vec::<u8, f32>(&staging.get_mapped_range(..).unwrap());
    assert_eq!(back, depth.data());
    let wrong = dev.create_texture(&wgpu::TextureDescriptor { format: wgpu::TextureFormat::R32Uint, ..tex_desc(w, h) });
    let mut enc = dev.create_command_encoder(&Default::default());
    let e = woc.encode_depth_to_texture(&mut enc, &src, &wrong.create_view(&Default::default())).unwrap_err();
    assert!(e.to_string().contains("R32Float"), "{e}");

    // Cull into engine buffers vs into ours.
    use zwarp_cull::gpu::{CullKernel, MaxDepthKernel};
    let cam = Camera::perspective(
        glam::Vec3::new(0.0, -5.0, 1.0),
        glam::Vec3::new(0.0, 0.0, 1.0),
        glam::Vec3::Z,
        1.0,
        0.5,
        50.0,
        w,
        h,
    )
    .unwrap();
    let boxes: Vec<zwarp_core::Aabb> = (0..40)
        .map(|i| {
            let c = glam::Vec3::new((i % 8) as f32 - 4.0, (i / 8) as f32 * 2.0, 1.0);
            zwarp_core::Aabb::new(c - glam::Vec3::splat(0.3), c + glam::Vec3::splat(0.3))
        })
        .collect();
    let objs = CullObjects::new(&ctx, boxes.len()).unwrap();
    objs.write_aabbs(&ctx, &boxes).unwrap();
    let map = MaxDepthKernel::new(&ctx).unwrap().build(&depth, zwarp_cull::MaxDepthKind::Default).unwrap();
    let ck = CullKernel::new(&ctx).unwrap();
    let ours = ck.cull(&objs, &cam, &map, &CullOutput::new(&ctx, 40).unwrap()).unwrap();
    let (st, cs, ind) = (wgpu::BufferUsages::STORAGE, wgpu::BufferUsages::COPY_SRC, wgpu::BufferUsages::INDIRECT);
    let theirs = CullOutput::from_buffers(
        40,
        buf(160, st | cs),
        buf(160, st | cs),
        buf(4, st | cs | ind | wgpu::BufferUsages::COPY_DST),
        buf(800, st | ind),
        buf(800, st | ind),
    )
    .unwrap();
    assert_eq!(ck.cull(&objs, &cam, &map, &theirs).unwrap(), ours);
    assert!(ours.visible.len() > 5 && ours.visible.len() < 40, "{:?}", ours.visible);
    let e =
        CullOutput::from_buffers(40, buf(160, st), buf(160, st), buf(4, st), buf(800, st | ind), buf(800, st | ind))
            .unwrap_err()
            .to_string();
    assert!(e.contains("'counter'"), "{e}");
}

fn tex_desc(w: u32, h: u32) -> wgpu::TextureDescriptor<'static> {
    wgpu::TextureDescriptor {
        label: None,
        size: wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::R32Float,
        usage: wgpu::TextureUsages::STORAGE_BINDING,
        view_formats: &[],
    }
}
