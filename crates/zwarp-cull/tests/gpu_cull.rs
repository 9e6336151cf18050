//! GPU AABB culling (seed 000 Sec. 5.2, thesis seed 002 Sec. III.2 and IV.3) vs its CPU twin in
//! zwarp-cull: per-object decisions on random boxes and depth buffers for every max-depth
//! kind, the visible list of a generated city vs `cull_against_depth`, and the indirect draw of
//! the kept set vs renders of the same set; error paths.

use glam::{Mat4, Vec3};
use zwarp_core::{Aabb, Camera, Image, Scene, EMPTY_DEPTH};
use zwarp_cull::gpu::{CullKernel, CullObjects, CullOutput, CullParams, GpuCullClass, MaxDepthKernel};
use zwarp_cull::{
    cull_against_depth, screen_rect_with, Frustum, MaxDepthKind, MaxDepthMap, MaxDepthQuery, ScreenRect,
    DEPTH_TOLERANCE,
};
use zwarp_gpu::{test_context, GpuScene, IndirectMode, Renderer};

const W: u32 = 97;
const H: u32 = 61;

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }
    fn range(&mut self, a: f32, b: f32) -> f32 {
        a + (b - a) * self.next()
    }
}

fn camera() -> Camera {
    Camera::perspective(Vec3::new(0.5, -6.0, 1.5), Vec3::new(0.0, 4.0, 0.8), Vec3::Z, 1.0, 0.5, 60.0, W, H).unwrap()
}

/// A blocky depth buffer of surfaces at view distances 2..30 (9x7-pixel blocks, ~12% holes),
/// so that random boxes are sometimes hidden and sometimes not.
fn blocky_depth(cam: &Camera, seed: u64) -> Image<f32> {
    let mut rng = Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
    let (bw, bh) = (W.div_ceil(9), H.div_ceil(7));
    let eye = cam.eye();
    let fwd = (Vec3::new(0.0, 4.0, 0.8) - eye).normalize();
    let blocks: Vec<f32> = (0..bw * bh)
        .map(|_| if rng.next() < 0.12 { EMPTY_DEPTH } else { cam.project(eye + fwd * rng.range(2.0, 30.0)).unwrap().z })
        .collect();
    Image::from_fn(W, H, |x, y| blocks[((y / 7) * bw + x / 9) as usize])
}

/// Random world boxes around the view: small and large, some behind the eye, some crossing
/// the near plane, some off-screen, plus an empty and a NaN box.
fn random_boxes(n: usize, seed: u64) -> Vec<Aabb> {
    let mut rng = Rng(seed.wrapping_mul(0xD1B5_4A32_D192_ED03) | 1);
    let mut out: Vec<Aabb> = (0..n)
        .map(|_| {
            let c = Vec3::new(rng.range(-12.0, 12.0), rng.range(-8.0, 30.0), rng.range(-3.0, 5.0));
            let e = Vec3::new(rng.range(0.02, 1.5), rng.range(0.02, 1.5), rng.range(0.02, 1.5));
            Aabb::new(c - e, c + e)
        })
        .collect();
    out.push(Aabb::EMPTY);
    out.push(Aabb::new(Vec3::NAN, Vec3::ONE));
    out
}

/// The CPU decision, as `zwarp_cull::woc`'s `test_objects` makes it, plus the occlusion
/// margin `max_depth - (nearest - tolerance)` of objects that reach the depth test.
fn cpu_class(b: &Aabb, cam: &Camera, map: &impl MaxDepthQuery) -> (GpuCullClass, Option<f32>) {
    let vp = cam.view_proj();
    if !Frustum::from_view_proj(&vp).intersects(b) {
        return (GpuCullClass::Frustum, None);
    }
    match screen_rect_with(b, &vp, cam.width, cam.height) {
        ScreenRect::CrossesNear => (GpuCullClass::CrossesNear, None),
        ScreenRect::Outside => (GpuCullClass::Frustum, None),
        ScreenRect::Rect { rect, nearest } => {
            let m = map.max_depth(rect);
            let margin = m - (nearest - DEPTH_TOLERANCE);
            let c = if map.is_occluded(rect, nearest - DEPTH_TOLERANCE) {
                GpuCullClass::Occluded
            } else {
                GpuCullClass::Visible
            };
            (c, Some(margin))
        }
    }
}

/// Every kind, random boxes and depths: identical decisions except objects whose depth test
/// is within 1e-6 of flipping (f32 projection rounding may differ between CPU and GPU).
#[test]
fn decisions_equal_the_cpu_test_on_random_boxes() {
    let Some(ctx) = test_context() else { return };
    let mk = MaxDepthKernel::new(&ctx).unwrap();
    let ck = CullKernel::new(&ctx).unwrap();
    let cam = camera();
    let mut tally = std::collections::HashMap::new();
    let mut margin_diffs = 0;
    for seed in 1..4u64 {
        let depth = blocky_depth(&cam, seed);
        let boxes = random_boxes(1500, seed);
        let objs = CullObjects::new(&ctx, boxes.len()).unwrap();
        objs.write_aabbs(&ctx, &boxes).unwrap();
        let out = CullOutput::new(&ctx, boxes.len()).unwrap();
        for kind in [MaxDepthKind::Mipmap, MaxDepthKind::NBuffer, MaxDepthKind::YMap { switch: 2 }] {
            let map = mk.build(&depth, kind).unwrap();
            let gpu = ck.cull(&objs, &cam, &map, &out).unwrap();
            let cpu_map = MaxDepthMap::build(kind, &depth).unwrap();
            let mut kept = Vec::new();
            for (id, b) in boxes.iter().enumerate() {
                let (c, margin) = cpu_class(b, &cam, &cpu_map);
                *tally.entry(c).or_insert(0) += 1;
                let g = gpu.classes[id];
                if g != c {
                    let m = margin.unwrap_or(f32::INFINITY);
                    assert!(m.abs() <= 1e-6, "{kind:?} seed {seed} box {id} {b:?}: GPU {g:?}, CPU {c:?} (margin {m})");
                    margin_diffs += 1;
                }
                if g.is_kept() {
                    kept.push(id as u32);
                }
            }
            assert_eq!(gpu.visible, kept, "{kind:?}: the compacted list holds exactly the kept objects");
        }
    }
    eprintln!("classes {tally:?}; decisions within the 1e-6 margin that differ: {margin_diffs}");
    // The random set exercises every branch.
    for c in [GpuCullClass::Frustum, GpuCullClass::CrossesNear, GpuCullClass::Occluded, GpuCullClass::Visible] {
        assert!(tally.get(&c).copied().unwrap_or(0) > 20, "too few {c:?}: {tally:?}");
    }
    assert!(margin_diffs <= 3, "{margin_diffs} margin decisions differ");
}

/// The silhouette test (WOC's `hull_test`) on random boxes against a random depth: the CPU
/// rule (`refine_by_hull`: rectangle-kept objects up to `HULL_TEST_MAX_AREA` pixels culled when
/// no unoccluded pixel centre lies in the box's projected hull) gives the same decisions up to
/// the 1e-6 margin, and culls something the rectangle test keeps.
#[test]
fn silhouette_test_equals_the_cpu_rule() {
    let Some(ctx) = test_context() else { return };
    let cam = camera();
    let depth = blocky_depth(&cam, 7);
    let boxes = random_boxes(3000, 7);
    let objs = CullObjects::new(&ctx, boxes.len()).unwrap();
    objs.write_aabbs(&ctx, &boxes).unwrap();
    let out = CullOutput::new(&ctx, boxes.len()).unwrap();
    let kind = MaxDepthKind::YMap { switch: 2 };
    let map = MaxDepthKernel::new(&ctx).unwrap().build(&depth, kind).unwrap();
    let ck = CullKernel::new(&ctx).unwrap();
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    let params = CullParams { hull_test: true, ..CullParams::default() };
    ck.encode(&mut enc, &objs, &cam.view_proj(), W, H, &params, &map, &out).unwrap();
    ctx.queue.submit([enc.finish()]);
    let gpu = out.read(&ctx).unwrap();
    let cpu_map = MaxDepthMap::build(kind, &depth).unwrap();
    let vp = cam.view_proj();
    let (mut refined, mut differ) = (0, 0);
    for (id, b) in boxes.iter().enumerate() {
        let (mut c, margin) = cpu_class(b, &cam, &cpu_map);
        if c == GpuCullClass::Visible {
            let ScreenRect::Rect { rect, nearest } = screen_rect_with(b, &vp, W, H) else { unreachable!() };
            if rect.area() <= zwarp_cull::woc::HULL_TEST_MAX_AREA {
                let (hull, n) = zwarp_cull::screen::screen_hull_with(b, &vp, W, H).unwrap();
                let limit = nearest - DEPTH_TOLERANCE;
                let seen = (rect.y0..rect.y1).any(|y| {
                    (rect.x0..rect.x1).any(|x| {
                        *depth.get(x, y) >= limit
                            && zwarp_cull::screen::square_meets_hull(x as f32, y as f32, -0.49, &hull, n)
                    })
                });
                if !seen {
                    c = GpuCullClass::Occluded;
                    refined += 1;
                }
            }
        }
        if gpu.classes[id] != c {
            let m = margin.unwrap_or(f32::INFINITY);
            assert!(m.abs() <= 1e-6, "box {id} {b:?}: GPU {:?}, CPU {c:?} (margin {m})", gpu.classes[id]);
            differ += 1;
        }
    }
    eprintln!("silhouette test culled {refined} rectangle-kept boxes; {differ} margin decisions differ");
    assert!(refined > 10, "the silhouette test culled only {refined}");
    assert!(differ <= 2);
}

#[test]
fn forced_objects_are_kept_untested() {
    let Some(ctx) = test_context() else { return };
    let cam = camera();
    // Everything at depth 0: every box in view is occluded unless forced.
    let map = MaxDepthKernel::new(&ctx).unwrap().build(&Image::new(W, H, 0.0f32), MaxDepthKind::Default).unwrap();
    let boxes = vec![Aabb::new(Vec3::new(-0.5, 4.5, 0.0), Vec3::new(0.5, 5.5, 1.0)); 3];
    let objs = CullObjects::new(&ctx, 3).unwrap();
    objs.write_aabbs(&ctx, &boxes).unwrap();
    objs.write_forced(&ctx, Some(&[false, true, false])).unwrap();
    let out = CullOutput::new(&ctx, 3).unwrap();
    let r = CullKernel::new(&ctx).unwrap().cull(&objs, &cam, &map, &out).unwrap();
    assert_eq!(r.classes, vec![GpuCullClass::Occluded, GpuCullClass::Forced, GpuCullClass::Occluded]);
    assert_eq!(r.visible, vec![1]);
    assert!(objs.write_forced(&ctx, Some(&[true])).unwrap_err().to_string().contains("1 entries for 3 objects"));
}

/// A generated city, culled against its own rendered depth (the ideal screen-space test): the
/// GPU visible list equals `cull_against_depth`'s up to margin objects, something is culled, and
/// the indirect draw of the kept set (both draw modes) equals the GPU render of a scene made
/// of exactly those objects bit for bit, the CPU render of the set on >= 99.9% of pixels, and
/// the full render (nothing visible was culled).
#[test]
fn indirect_draw_of_the_kept_set_equals_its_render() {
    let Some(ctx) = test_context() else { return };
    let (scene, cam) = zwarp_raster::scenes::box_city(7, W, H).unwrap();
    let gs = GpuScene::upload(&ctx, &scene).unwrap();
    let r = Renderer::new(&ctx).unwrap();
    let full = r.render_depth(&gs, &cam, 0.0).unwrap();
    let mk = MaxDepthKernel::new(&ctx).unwrap();
    let ck = CullKernel::new(&ctx).unwrap();
    let objs = CullObjects::for_scene(&ctx, &gs).unwrap();
    objs.write_scene_aabbs(&ctx, &scene, 0.0).unwrap();
    let out = CullOutput::new(&ctx, objs.len()).unwrap();
    let map = mk.build(&full, MaxDepthKind::Default).unwrap();
    let gpu = ck.cull(&objs, &cam, &map, &out).unwrap();
    let cpu = cull_against_depth(&scene, &full, &cam, 0.0, MaxDepthKind::Default, None).unwrap();
    let differ: Vec<u32> = (0..scene.instances.len() as u32)
        .filter(|id| gpu.visible.binary_search(id).is_ok() != cpu.visible.binary_search(id).is_ok())
        .collect();
    eprintln!(
        "{} objects, GPU keeps {}, CPU keeps {}, differ {differ:?}",
        scene.instances.len(),
        gpu.visible.len(),
        cpu.visible.len()
    );
    assert!(differ.len() <= 1, "decisions differ for {differ:?}");
    assert!(gpu.visible.len() < scene.instances.len(), "nothing culled");
    // The same objects as a scene of their own, rendered by the ordinary path.
    let subset = Scene {
        instances: gpu.visible.iter().map(|&id| scene.instances[id as usize].clone()).collect(),
        ..scene.clone()
    };
    let sub = r.render_depth(&GpuScene::upload(&ctx, &subset).unwrap(), &cam, 0.0).unwrap();
    let mut cpu_sub = Image::new(W, H, EMPTY_DEPTH);
    zwarp_raster::draw_into(&mut cpu_sub, None, &scene, &cam, 0.0, &gpu.visible).unwrap();
    let mut modes = vec![IndirectMode::Slots];
    if r.indirect_mode() == IndirectMode::Count {
        modes.push(IndirectMode::Count);
    }
    for mode in modes {
        let ind = r.render_depth_indirect(&gs, &cam, 0.0, &out, mode).unwrap();
        assert_eq!(ind, sub, "{mode:?}: indirect draw vs render of the kept set");
        assert_eq!(ind, full, "{mode:?}: culling removed something visible");
        let same = ind.data().iter().zip(cpu_sub.data()).filter(|(a, b)| (**a - **b).abs() < 1e-6).count();
        assert!(same as f64 >= 0.999 * ind.len() as f64, "{mode:?}: {same} of {} pixels agree with the CPU", ind.len());
    }
}

#[test]
fn bad_input_is_an_error() {
    let Some(ctx) = test_context() else { return };
    let mk = MaxDepthKernel::new(&ctx).unwrap();
    let ck = CullKernel::new(&ctx).unwrap();
    let cam = camera();
    assert!(CullObjects::new(&ctx, 0).unwrap_err().to_string().contains("at least one object"));
    let objs = CullObjects::new(&ctx, 4).unwrap();
    let e = objs.write_aabbs(&ctx, &[Aabb::EMPTY]).unwrap_err().to_string();
    assert!(e.contains("1 AABBs for 4 objects"), "{e}");
    let out = CullOutput::new(&ctx, 4).unwrap();
    let wrong = mk.build(&Image::new(W - 1, H, 1.0f32), MaxDepthKind::Mipmap).unwrap();
    let e = ck.cull(&objs, &cam, &wrong, &out).unwrap_err().to_string();
    assert!(e.contains("96x61 but the camera renders 97x61"), "{e}");
    let map = mk.build(&Image::new(W, H, 1.0f32), MaxDepthKind::Mipmap).unwrap();
    let e = ck.cull(&objs, &cam, &map, &CullOutput::new(&ctx, 5).unwrap()).unwrap_err().to_string();
    assert!(e.contains("5 objects, 4 given"), "{e}");
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    let e = ck.encode(&mut enc, &objs, &Mat4::NAN, W, H, &CullParams::default(), &map, &out).unwrap_err().to_string();
    assert!(e.contains("not finite"), "{e}");
}
