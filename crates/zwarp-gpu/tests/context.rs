//! Context, adapter listing and timer.

use zwarp_testkit as common;

use common::*;
use zwarp_gpu::{list_adapters, test_context, DepthTarget, GpuContext, GpuScene, GpuTimer, Renderer, TimingMethod};

#[test]
fn adapters_are_listed_and_context_wraps_a_device() {
    let Some(ctx) = test_context() else { return };
    let adapters = list_adapters();
    assert!(!adapters.is_empty(), "a context exists, so an adapter must be listed");
    assert!(adapters.iter().any(|a| a.name == ctx.adapter.name), "{adapters:?} vs {}", ctx.adapter);
    assert!(!ctx.adapter.to_string().is_empty());
    // An engine's own device: same adapter, usable for rendering.
    let wrapped = GpuContext::from_device(ctx.device.clone(), ctx.queue.clone());
    assert_eq!(wrapped.adapter.name, ctx.adapter.name);
    let gs = GpuScene::upload(&wrapped, &test_scene()).unwrap();
    let d = Renderer::new(&wrapped).unwrap().render_depth(&gs, &camera_a(), 0.0).unwrap();
    assert!(d.data().iter().any(|&z| z < 1.0));
}

#[test]
fn timer_measures_a_depth_pass() {
    let Some(ctx) = test_context() else { return };
    let gs = GpuScene::upload(&ctx, &test_scene()).unwrap();
    let r = Renderer::new(&ctx).unwrap();
    let cam = camera_a();
    let target = DepthTarget::new(&ctx, cam.width, cam.height).unwrap();
    let auto = GpuTimer::new(&ctx);
    let expect = if ctx.has_timestamps() && ctx.adapter.device_type != "Cpu" {
        TimingMethod::Timestamps
    } else {
        TimingMethod::FencedWallClock
    };
    assert_eq!(auto.method(), expect);
    let stamped = GpuTimer::with_timestamps(&ctx);
    assert_eq!(stamped.is_some(), ctx.has_timestamps());
    for timer in [Some(auto), stamped, Some(GpuTimer::wall_clock(&ctx))].into_iter().flatten() {
        let t = timer.measure(|enc| r.encode_depth(enc, &gs, &cam, 0.0, &target)).unwrap();
        assert!(t.as_secs_f64() < 10.0, "{t:?}");
        // Errors inside the recorded closure propagate.
        let bad = DepthTarget::new(&ctx, 8, 8).unwrap();
        assert!(timer.measure(|enc| r.encode_depth(enc, &gs, &cam, 0.0, &bad)).is_err());
    }
    assert_eq!(GpuTimer::wall_clock(&ctx).method(), TimingMethod::FencedWallClock);
}
