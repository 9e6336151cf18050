//! The facade against the stages it calls, on both backends, and its error paths.

use zwarp::warp::synth::SynthScene;
use zwarp::warp::{holes, warp_depth, WarpLayer};
use zwarp::{Backend, Camera, Error, HolePolicy, Image, Vec3, WarpParams, Warper};

fn cameras(w: u32, h: u32) -> (Camera, Camera) {
    SynthScene::city_views(w, h).unwrap()
}

fn scene() -> SynthScene {
    SynthScene::moving_city()
}

#[test]
fn cpu_prediction_is_the_eval_pipeline_by_hand() {
    let (w, h) = (96, 64);
    let (a, b) = cameras(w, h);
    let scene = scene();
    let src = scene.render(&a, 0.0, 3, true);
    let deltas = scene.object_deltas(0.0, 0.25);
    let params = Warper::default_params();
    let mut warper = Warper::new(Backend::Cpu, params).unwrap();
    warper.prepare(&a, &src.depth, Some(&src.items)).unwrap();
    let got = warper.warp_to(&b, &deltas).unwrap().clone();
    // By hand: motion per layer, the warp with far holes, the background fill.
    let motions: Vec<_> = src
        .depth
        .iter()
        .zip(&src.items)
        .map(|(d, i)| zwarp::core::motion_field(d, Some(i), &a, &b, &deltas).unwrap())
        .collect();
    let layers: Vec<WarpLayer> =
        src.depth.iter().zip(&motions).map(|(depth, motion)| WarpLayer { depth, motion }).collect();
    let mut want = warp_depth(&layers, &WarpParams { holes: HolePolicy::FarDepth, ..params }).unwrap();
    holes::fill_background(&layers, &mut want, 64, &params.search()).unwrap();
    assert_eq!(got.depth, want.depth);
    assert_eq!(got.state, want.state);
    assert!(got.converged_fraction() > 0.95, "{}", got.converged_fraction());
    // The recycled buffers give the same answer again, and a new source replaces the old one.
    assert_eq!(warper.warp_to(&b, &deltas).unwrap(), &got);
    warper.prepare(&b, &scene.render(&b, 0.25, 3, true).depth, None).unwrap();
    let back = warper.warp_to(&b, &[]).unwrap();
    // The same view: the source again, up to the reprojection's rounding in the motion field.
    let direct = scene.render(&b, 0.25, 1, false).depth.remove(0);
    let differ = back.depth.data().iter().zip(direct.data()).filter(|(x, y)| (**x - **y).abs() > 1e-5).count();
    assert_eq!(differ, 0, "zero motion returns the source");
    // The first source again, copied into the buffers of the second (items back): its answer.
    warper.prepare(&a, &src.depth, Some(&src.items)).unwrap();
    assert_eq!(warper.warp_to(&b, &deltas).unwrap(), &got);
}

#[test]
fn object_motion_moves_the_box() {
    let (w, h) = (96, 64);
    let (a, _) = cameras(w, h);
    let scene = scene();
    let src = scene.render(&a, 0.0, 3, true);
    let reference = scene.render(&a, 0.25, 1, false).depth.remove(0);
    let mut warper = Warper::new(Backend::Cpu, Warper::default_params()).unwrap();
    warper.prepare(&a, &src.depth, Some(&src.items)).unwrap();
    let err = |p: &Image<f32>| p.data().iter().zip(reference.data()).filter(|(x, y)| (**x - **y).abs() > 1e-3).count();
    let moved = err(&warper.warp_to(&a, &scene.object_deltas(0.0, 0.25)).unwrap().depth);
    let still = err(&warper.warp_to(&a, &[]).unwrap().depth);
    assert!(moved * 3 < still, "moved {moved} still {still}");
}

#[test]
fn gpu_prediction_matches_cpu() {
    let Some(ctx) = zwarp::gpu::test_context() else { return };
    let (w, h) = (96, 64);
    let (a, b) = cameras(w, h);
    let scene = scene();
    let src = scene.render(&a, 0.0, 3, true);
    let deltas = scene.object_deltas(0.0, 0.25);
    let mut cpu = Warper::new(Backend::Cpu, Warper::default_params()).unwrap();
    let mut gpu = Warper::new(Backend::Gpu(ctx), Warper::default_params()).unwrap();
    for wp in [&mut cpu, &mut gpu] {
        wp.prepare(&a, &src.depth, Some(&src.items)).unwrap();
    }
    let c = cpu.warp_to(&b, &deltas).unwrap();
    let g = gpu.warp_to(&b, &deltas).unwrap();
    let n = c.depth.len() as f64;
    let same_state = c.state.data().iter().zip(g.state.data()).filter(|(x, y)| x == y).count() as f64 / n;
    let same_depth = c.depth.data().iter().zip(g.depth.data()).filter(|(x, y)| x == y).count() as f64 / n;
    assert!(same_state >= 0.995 && same_depth >= 0.98, "state {same_state} depth {same_depth}");
}

#[test]
fn bad_input_is_a_one_line_error() {
    let (w, h) = (32, 16);
    let (a, b) = cameras(w, h);
    let invalid = |e: Error| {
        assert!(matches!(e, Error::Invalid(_)), "{e}");
        assert!(!e.to_string().contains('\n'));
    };
    invalid(Warper::new(Backend::Cpu, WarpParams { n_seeds: 0, ..Warper::default_params() }).err().unwrap());
    let mut warper = Warper::new(Backend::Cpu, Warper::default_params()).unwrap();
    invalid(warper.warp_to(&b, &[]).unwrap_err());
    invalid(warper.prepare(&a, &[], None).unwrap_err());
    invalid(warper.prepare(&a, &[Image::new(w + 1, h, 1.0)], None).unwrap_err());
    invalid(warper.prepare(&a, &[Image::new(w, h, 1.0), Image::new(w, h + 1, 1.0)], None).unwrap_err());
    invalid(warper.prepare(&a, &[Image::new(w, h, 1.0)], Some(&[])).unwrap_err());
    warper.prepare(&a, &[Image::new(w, h, 0.5)], None).unwrap();
    let small = Camera::perspective(Vec3::ZERO, Vec3::NEG_Z, Vec3::Y, 1.0, 0.5, 100.0, w / 2, h).unwrap();
    invalid(warper.warp_to(&small, &[]).unwrap_err());
    // An all-far source predicts an all-far view (sky seen everywhere), not an error.
    warper.prepare(&a, &[Image::new(w, h, 1.0)], None).unwrap();
    let p = warper.warp_to(&b, &[]).unwrap();
    assert!(p.depth.data().iter().all(|&z| z == 1.0));
    if let Some(ctx) = zwarp::gpu::test_context() {
        let e = Warper::new(Backend::Gpu(ctx), WarpParams { record_source: true, ..Warper::default_params() });
        invalid(e.err().unwrap());
    }
}

// The GPU-resident path: the engine's own textures and buffers in, a prediction on the GPU out.

use zwarp::gpu::{wgpu, GpuContext};
use zwarp::{GpuImage, GpuSourceLayer, PixelState};

/// A texture of `format` holding `bytes` (4 per texel), with `TEXTURE_BINDING` usage.
fn texture(ctx: &GpuContext, w: u32, h: u32, format: wgpu::TextureFormat, bytes: &[u8]) -> wgpu::Texture {
    let t = ctx.device.create_texture(&wgpu::TextureDescriptor {
        label: Some("test source"),
        size: wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    ctx.queue.write_texture(
        wgpu::TexelCopyTextureInfo {
            texture: &t,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        bytes,
        wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(w * 4), rows_per_image: Some(h) },
        wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
    );
    t
}

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn u32_bytes(v: &[u32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// A `Depth32Float` texture holding `depth` exactly, as an engine's depth pass leaves it (depth
/// formats cannot be written by copies): a full-screen triangle writes every texel's depth
/// (`frag_depth`, compare `Always`) from a storage buffer.
fn depth_texture(ctx: &GpuContext, depth: &Image<f32>) -> wgpu::Texture {
    let (w, h) = depth.size();
    let dev = &ctx.device;
    let t = dev.create_texture(&wgpu::TextureDescriptor {
        label: Some("test depth attachment"),
        size: wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Depth32Float,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
        view_formats: &[],
    });
    let src = ctx.buffer_with("test depth values", &f32_bytes(depth.data()), wgpu::BufferUsages::STORAGE).unwrap();
    let module = ctx
        .shader(
            "test depth writer",
            &format!(
                "@group(0) @binding(0) var<storage, read> src: array<f32>;
                 @vertex fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {{
                     let p = vec2<f32>(f32((i << 1u) & 2u), f32(i & 2u));
                     return vec4<f32>(p * 2.0 - 1.0, 0.0, 1.0);
                 }}
                 @fragment fn fs(@builtin(position) pos: vec4<f32>) -> @builtin(frag_depth) f32 {{
                     return src[u32(pos.y) * {w}u + u32(pos.x)];
                 }}"
            ),
        )
        .unwrap();
    let pipeline = dev.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("test depth writer"),
        layout: None,
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vs"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: Default::default(),
        depth_stencil: Some(wgpu::DepthStencilState {
            format: wgpu::TextureFormat::Depth32Float,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Always),
            stencil: Default::default(),
            bias: Default::default(),
        }),
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module: &module,
            entry_point: Some("fs"),
            compilation_options: Default::default(),
            targets: &[],
        }),
        multiview_mask: None,
        cache: None,
    });
    let bind = dev.create_bind_group(&wgpu::BindGroupDescriptor {
        label: None,
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[wgpu::BindGroupEntry { binding: 0, resource: src.as_entire_binding() }],
    });
    let view = t.create_view(&Default::default());
    let mut enc = dev.create_command_encoder(&Default::default());
    {
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: None,
            color_attachments: &[],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &view,
                depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(1.0), store: wgpu::StoreOp::Store }),
                stencil_ops: None,
            }),
            ..Default::default()
        });
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.draw(0..3, 0..1);
    }
    ctx.queue.submit([enc.finish()]);
    t
}

/// `image` in a buffer of 4-byte texels with `stride` texels per row (the rest filled with a
/// value that would show if read).
fn strided_buffer(ctx: &GpuContext, image: &[u32], w: u32, stride: u32) -> wgpu::Buffer {
    let rows = image.chunks(w as usize);
    let padded: Vec<u32> =
        rows.flat_map(|r| r.iter().copied().chain(std::iter::repeat_n(0x7fc0_0000, (stride - w) as usize))).collect();
    ctx.buffer_with("test strided", &u32_bytes(&padded), wgpu::BufferUsages::STORAGE).unwrap()
}

/// The bar of `gpu_prediction_matches_cpu` (equal states on >= 99.5 % of the pixels, equal depth
/// on >= 98 %) with depth equal to within `tol`: the GPU-resident path computes the motion on
/// the GPU, whose target depths differ from the CPU's by float rounding (about 60 % of the
/// predicted depths differ in the last bits). Returns (state agreement, depth agreement).
fn assert_close(g: &zwarp::Prediction, c: &zwarp::Prediction, tol: f32, what: &str) -> (f64, f64) {
    assert_eq!(g.depth.size(), c.depth.size(), "{what}");
    let n = c.depth.len() as f64;
    let same_state = c.state.data().iter().zip(g.state.data()).filter(|(x, y)| x == y).count() as f64 / n;
    let near = |(x, y): (&f32, &f32)| (x - y).abs() <= tol;
    let same_depth = c.depth.data().iter().zip(g.depth.data()).filter(|&p| near(p)).count() as f64 / n;
    assert!(same_state >= 0.995 && same_depth >= 0.98, "{what}: state {same_state} depth {same_depth}");
    (same_state, same_depth)
}

/// The GPU-resident prediction from the engine's images (a `Depth32Float` attachment, an
/// `R32Float` texture and a strided buffer for depth; `R32Uint` textures and a strided buffer
/// for the items) equals the CPU warper's on the moving city, one and 2x2 samples per pixel:
/// the prediction of `warp_to` with `BoundKind::Tight` (what the GPU-resident path computes
/// for the default oriented bound), up to the GPU motion field's float rounding.
#[test]
fn gpu_resident_prediction_matches_cpu() {
    let Some(ctx) = zwarp::gpu::test_context() else { return };
    let (w, h) = (96, 64);
    let (a, b) = cameras(w, h);
    let scene = scene();
    let deltas = scene.object_deltas(0.0, 0.25);
    for m in [1u32, 2] {
        let params = WarpParams { multisample: m, ..Warper::default_params() };
        let src = scene.render(&a.with_size(w * m, h * m).unwrap(), 0.0, 3, true);
        let (sw, sh) = src.depth[0].size();
        let depth0 = depth_texture(&ctx, &src.depth[0]);
        let depth1 = texture(&ctx, sw, sh, wgpu::TextureFormat::R32Float, &f32_bytes(src.depth[1].data()));
        let bits: Vec<u32> = src.depth[2].data().iter().map(|z| z.to_bits()).collect();
        let depth2 = strided_buffer(&ctx, &bits, sw, sw + 13);
        let items: Vec<wgpu::Texture> = src.items[..2]
            .iter()
            .map(|i| texture(&ctx, sw, sh, wgpu::TextureFormat::R32Uint, &u32_bytes(i.data())))
            .collect();
        let items2 = strided_buffer(&ctx, src.items[2].data(), sw, sw + 64);
        let layers = [
            GpuSourceLayer { depth: GpuImage::Texture(&depth0), items: Some(GpuImage::Texture(&items[0])) },
            GpuSourceLayer { depth: GpuImage::Texture(&depth1), items: Some(GpuImage::Texture(&items[1])) },
            GpuSourceLayer {
                depth: GpuImage::Buffer { buffer: &depth2, row_stride: sw + 13 },
                items: Some(GpuImage::Buffer { buffer: &items2, row_stride: sw + 64 }),
            },
        ];
        let mut gpu = Warper::new(Backend::Gpu(ctx.clone()), params).unwrap();
        gpu.prepare_gpu(&a, &layers).unwrap();
        let resident = gpu.warp_to_gpu(&b, &deltas).unwrap();
        assert_eq!(resident.size(), (w, h));
        let g = resident.read(&ctx).unwrap();
        // The same through warp_to (a GPU source is predicted on the GPU and read back).
        assert_eq!(gpu.warp_to(&b, &deltas).unwrap(), &g, "m {m}");

        let tight = WarpParams { bound: zwarp::warp::BoundKind::Tight, ..params };
        let mut cpu = Warper::new(Backend::Cpu, tight).unwrap();
        cpu.prepare(&a, &src.depth, Some(&src.items)).unwrap();
        let c = cpu.warp_to(&b, &deltas).unwrap();
        let (state, depth) = assert_close(&g, c, 1e-6, &format!("GPU-resident vs CPU, m {m}"));
        eprintln!("m {m}: state agreement {state:.5}, depth within 1e-6 on {depth:.5}");
        assert!(g.converged_fraction() > 0.9, "{}", g.converged_fraction());
        let filled = g.state.data().iter().filter(|s| **s == PixelState::Filled).count();
        assert!(filled > 0, "the hole protocol filled something");
        // Against the default (oriented) CPU prediction: the same view, a few seeds apart.
        let mut oriented = Warper::new(Backend::Cpu, params).unwrap();
        oriented.prepare(&a, &src.depth, Some(&src.items)).unwrap();
        let o = oriented.warp_to(&b, &deltas).unwrap();
        let agree =
            o.state.data().iter().zip(g.state.data()).filter(|(x, y)| x == y).count() as f64 / o.state.len() as f64;
        eprintln!("m {m}: oriented CPU vs GPU-resident states agree on {agree:.5}");
        assert!(agree >= 0.99, "m {m}: oriented CPU vs GPU-resident states agree on {agree}");
    }
}

/// A second source of the same size reuses the warper's buffers and replaces the first; a
/// source without item images moves with the camera only (the CPU with `items: None`).
#[test]
fn gpu_resident_source_is_replaced_and_items_are_optional() {
    let Some(ctx) = zwarp::gpu::test_context() else { return };
    let (w, h) = (64, 48);
    let (a, b) = cameras(w, h);
    let scene = scene();
    let tight = WarpParams { bound: zwarp::warp::BoundKind::Tight, ..Warper::default_params() };
    let mut gpu = Warper::new(Backend::Gpu(ctx.clone()), tight).unwrap();
    let mut cpu = Warper::new(Backend::Cpu, tight).unwrap();
    for t in [0.0, 0.5] {
        let src = scene.render(&a, t, 1, false);
        let d = depth_texture(&ctx, &src.depth[0]);
        gpu.prepare_gpu(&a, &[GpuSourceLayer { depth: GpuImage::Texture(&d), items: None }]).unwrap();
        cpu.prepare(&a, &src.depth, None).unwrap();
        let g = gpu.warp_to_gpu(&b, &scene.object_deltas(t, t + 0.25)).unwrap().read(&ctx).unwrap();
        let c = cpu.warp_to(&b, &scene.object_deltas(t, t + 0.25)).unwrap();
        assert_close(&g, c, 1e-6, &format!("t {t}"));
    }
}

/// The GPU-resident entry points reject what does not fit with one-line `Error::Invalid`s
/// (checked before wgpu could raise a device error): a CPU warper, no or too many layers,
/// sizes that are not the camera's, formats and usages the copy cannot read, short buffers,
/// and the wrong kind of source for `warp_to_gpu`.
#[test]
fn gpu_resident_bad_input_is_a_one_line_error() {
    let (w, h) = (32, 16);
    let (a, b) = cameras(w, h);
    let invalid = |e: Error, has: &str| {
        assert!(matches!(e, Error::Invalid(_)), "{e}");
        let msg = e.to_string();
        assert!(!msg.contains('\n') && msg.contains(has), "{msg} (wanted '{has}')");
    };
    let Some(ctx) = zwarp::gpu::test_context() else { return };
    let good = texture(&ctx, w, h, wgpu::TextureFormat::R32Float, &f32_bytes(&vec![0.5; (w * h) as usize]));
    let layer = GpuSourceLayer { depth: GpuImage::Texture(&good), items: None };
    let mut cpu = Warper::new(Backend::Cpu, Warper::default_params()).unwrap();
    invalid(cpu.prepare_gpu(&a, &[layer]).unwrap_err(), "Backend::Gpu");
    invalid(cpu.warp_to_gpu(&b, &[]).unwrap_err(), "Backend::Gpu");

    let mut gpu = Warper::new(Backend::Gpu(ctx.clone()), Warper::default_params()).unwrap();
    invalid(gpu.warp_to_gpu(&b, &[]).unwrap_err(), "no source");
    invalid(gpu.prepare_gpu(&a, &[]).unwrap_err(), "at least one");
    invalid(gpu.prepare_gpu(&a, &[layer; 9]).unwrap_err(), "at most 8");
    let big = texture(&ctx, w + 1, h, wgpu::TextureFormat::R32Float, &f32_bytes(&vec![0.5; ((w + 1) * h) as usize]));
    invalid(
        gpu.prepare_gpu(&a, &[GpuSourceLayer { depth: GpuImage::Texture(&big), items: None }]).unwrap_err(),
        "33x16",
    );
    let rgba = texture(&ctx, w, h, wgpu::TextureFormat::Rgba8Unorm, &vec![0; (w * h * 4) as usize]);
    let e = gpu.prepare_gpu(&a, &[GpuSourceLayer { depth: GpuImage::Texture(&rgba), items: None }]).unwrap_err();
    invalid(e, "Rgba8Unorm");
    // Items must be R32Uint; a float texture is refused.
    let e = gpu
        .prepare_gpu(&a, &[GpuSourceLayer { depth: GpuImage::Texture(&good), items: Some(GpuImage::Texture(&good)) }]);
    invalid(e.unwrap_err(), "layer 0 items");
    let unbound = ctx.device.create_texture(&wgpu::TextureDescriptor {
        label: None,
        size: wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Depth32Float,
        usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
        view_formats: &[],
    });
    let e = gpu.prepare_gpu(&a, &[GpuSourceLayer { depth: GpuImage::Texture(&unbound), items: None }]).unwrap_err();
    invalid(e, "TEXTURE_BINDING");
    let short = strided_buffer(&ctx, &vec![0; (w * h) as usize], w, w);
    let layer_of = |row_stride| GpuSourceLayer { depth: GpuImage::Buffer { buffer: &short, row_stride }, items: None };
    invalid(gpu.prepare_gpu(&a, &[layer_of(w - 1)]).unwrap_err(), "row stride");
    invalid(gpu.prepare_gpu(&a, &[layer_of(w + 1)]).unwrap_err(), "too small");
    // A multisampled warper wants the camera's size times m.
    let mut ms =
        Warper::new(Backend::Gpu(ctx.clone()), WarpParams { multisample: 2, ..Warper::default_params() }).unwrap();
    invalid(ms.prepare_gpu(&a, &[layer]).unwrap_err(), "64x32");
    // A CPU source predicts with warp_to, not warp_to_gpu; the target size must match.
    gpu.prepare(&a, &[Image::new(w, h, 0.5)], None).unwrap();
    invalid(gpu.warp_to_gpu(&b, &[]).unwrap_err(), "prepare_gpu");
    gpu.prepare_gpu(&a, &[layer]).unwrap();
    let small = Camera::perspective(Vec3::ZERO, Vec3::NEG_Z, Vec3::Y, 1.0, 0.5, 100.0, w / 2, h).unwrap();
    invalid(gpu.warp_to_gpu(&small, &[]).unwrap_err(), "16x16");
    // After the errors the last good source still predicts: a constant plane, all converged.
    let p = gpu.warp_to_gpu(&a, &[]).unwrap().read(&ctx).unwrap();
    assert!(p.state.data().iter().all(|s| *s == PixelState::Converged));
}
