//! GPU culling figures at 1920x1080 on CB (scale 1, its recorded path) on the current adapter
//! (lavapipe on a machine without GPU): the max-depth structures (seed 000 Sec. 5.2: max mipmap,
//! N-buffer, Y-map), the AABB cull kernel against each, the whole GPU WOC pipeline (seed 000
//! Sec. 5, thesis seed 002) and the indirect draw of the kept objects, next to the GPU depth
//! render of the same frame in the same run (ARCHITECTURE.md "Timings": ratios measured side by
//! side are the figure). The CPU twins (zwarp-cull) are timed in the same run. Also prints the
//! minimum memory traffic of each kernel and what it would take at a GTX 1080's 320 GB/s (the
//! paper's GPU), so the sub-millisecond claim can be judged on real hardware.
//!
//! Usage: `cargo run --release -p zwarp-tools --bin gpu_cull_table -- [runs] [frame]`

use std::time::{Duration, Instant};

use zwarp_core::Result;
use zwarp_cull::gpu::{
    rapid_flags, CullKernel, CullObjects, CullOutput, CullParams, GpuPrevFrame, GpuWoc, GpuWocParams, MaxDepthKernel,
    MaxDepthLayout, WocStage,
};
use zwarp_cull::{MaxDepthKind, MaxDepthMap, WocParams};
use zwarp_gpu::{
    DepthTarget, GpuContext, GpuScene, GpuTimer, IndirectMode, LayerTargets, PeelOptions, Renderer, TimingStats,
};

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// GTX 1080 memory bandwidth (bytes/s), the GPU of seed 000's measurements.
const GTX1080: f64 = 320e9;

fn row(name: &str, gpu: &TimingStats, cpu: Option<Duration>, bytes: Option<f64>) {
    let cpu = cpu.map_or("-".to_string(), |c| format!("{:.2}", ms(c)));
    let (mb, at) = match bytes {
        Some(b) => (format!("{:.1}", b / 1e6), format!("{:.3}", b / GTX1080 * 1e3)),
        None => ("-".into(), "-".into()),
    };
    println!("| {name} | {:.2} | {:.2} | {cpu} | {mb} | {at} |", ms(gpu.median), ms(gpu.min));
}

/// Minimum traffic of a max-structure build: the level-0 copy (read + write) and, per further
/// level, one read of its source level and one write of itself.
fn build_bytes(l: &MaxDepthLayout) -> f64 {
    let (w, h) = l.size;
    let mut sizes: Vec<(u32, u32)> = l.mip.clone();
    sizes.extend((0..l.nbuf_levels).map(|_| l.nbuf_size));
    let px = |s: &(u32, u32)| s.0 as f64 * s.1 as f64;
    8.0 * w as f64 * h as f64 + sizes.windows(2).map(|p| 4.0 * (px(&p[0]) + px(&p[1]))).sum::<f64>()
}

/// Minimum traffic of the per-pixel WOC stages (bytes in + out per pixel; see `woc.wgsl`),
/// the Y-map build and the cull; `None` for the warp (see gpu_warp_table's estimate) and the
/// rapid-object draw (raster work).
fn stage_bytes(stage: WocStage, w: u32, h: u32, n: usize) -> Option<f64> {
    let px = w as f64 * h as f64;
    match stage {
        WocStage::Gather => Some(px * 16.0),
        WocStage::Motion => Some(px * 20.0),
        WocStage::Rims => Some(px * 24.0),
        WocStage::Warp | WocStage::Rapid => None,
        WocStage::Erosion => Some(px * 8.0),
        WocStage::MaxDepth => MaxDepthLayout::new(MaxDepthKind::YMap { switch: 2 }, w, h).ok().map(|l| build_bytes(&l)),
        WocStage::Cull => Some(n as f64 * 364.0),
    }
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let runs: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(9).max(3);
    let frame: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(30);
    let (w, h) = (1920u32, 1080u32);
    let loaded = zwarp_scene::load_scene("cb", &zwarp_scene::SceneOptions::default())?;
    let scene = loaded.scene;
    let frames = loaded.path.expect("cb has a recorded path").frames(w, h, 1.0)?;
    let frame = frame.clamp(1, frames.len() - 1);
    let ((t0, cam0), (t1, cam1)) = (frames[frame - 1], frames[frame]);
    let ctx = GpuContext::new()?;
    let timer = GpuTimer::new(&ctx);
    let gs = GpuScene::upload(&ctx, &scene)?;
    let r = Renderer::new(&ctx)?;
    let n = scene.instances.len();
    println!("adapter: {}; timing: {}", ctx.adapter, timer.method());
    println!("scene: cb scale 1, {n} objects, {} triangles, frame {frame} of its path, {w}x{h}", gs.triangle_count());

    // The previous frame (depth + items, what an engine has) and the current true depth.
    let prev = LayerTargets::new(&r, w, h, 1, false)?;
    let cur = LayerTargets::new(&r, w, h, 1, false)?;
    for (targets, cam, t) in [(&prev, &cam0, t0), (&cur, &cam1, t1)] {
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        r.encode_layers(&mut enc, &gs, cam, t, &PeelOptions { layers: 1, ..Default::default() }, targets)?;
        ctx.queue.submit([enc.finish()]);
    }
    let true_depth = r.read_layer(&cur, 0)?.depth;
    let depth_buf = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("depth"),
        size: w as u64 * h as u64 * 4,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    r.encode_depth_copy(&mut enc, &cur.depth[0], &depth_buf, w)?;
    ctx.queue.submit([enc.finish()]);

    let target = DepthTarget::new(&ctx, w, h)?;
    let measure = |f: &mut dyn FnMut(&mut wgpu::CommandEncoder) -> Result<()>| -> Result<TimingStats> {
        timer.measure(|e| f(e))?; // warm-up
        let s: Vec<Duration> = (0..runs).map(|_| timer.measure(|e| f(e))).collect::<Result<_>>()?;
        TimingStats::from_samples(&s)
    };
    let cpu_time = |f: &mut dyn FnMut() -> Result<()>| -> Result<Duration> {
        f()?;
        let mut s: Vec<Duration> = (0..runs)
            .map(|_| {
                let t = Instant::now();
                f().map(|_| t.elapsed())
            })
            .collect::<Result<_>>()?;
        s.sort();
        Ok(s[s.len() / 2])
    };

    println!();
    println!("| pass | GPU median ms | GPU min ms | CPU twin median ms | min traffic MB | at 320 GB/s ms |");
    println!("|---|---|---|---|---|---|");
    let render = measure(&mut |e| r.encode_depth(e, &gs, &cam1, t1, &target))?;
    row("depth-only render (all objects)", &render, None, None);

    let mk = MaxDepthKernel::new(&ctx)?;
    let ck = CullKernel::new(&ctx)?;
    let objects = CullObjects::for_scene(&ctx, &gs)?;
    objects.write_scene_aabbs(&ctx, &scene, t1)?;
    objects.write_forced(&ctx, None)?;
    let out = CullOutput::new(&ctx, n)?;
    let vp = cam1.view_proj();
    let mut kept = Vec::new();
    for (name, kind) in [
        ("max mipmap", MaxDepthKind::Mipmap),
        ("N-buffer", MaxDepthKind::NBuffer),
        ("Y-map (2 mip levels)", MaxDepthKind::YMap { switch: 2 }),
    ] {
        let map = mk.create(kind, w, h)?;
        let build = measure(&mut |e| mk.encode(e, &depth_buf, &map))?;
        let cpu = cpu_time(&mut || MaxDepthMap::build(kind, &true_depth).map(|_| ()))?;
        row(&format!("build {name}"), &build, Some(cpu), Some(build_bytes(&map.layout)));
        let cull = measure(&mut |e| ck.encode(e, &objects, &vp, w, h, &CullParams::default(), &map, &out))?;
        let res = out.read(&ctx)?;
        let cpu =
            cpu_time(&mut || zwarp_cull::cull_against_depth(&scene, &true_depth, &cam1, t1, kind, None).map(|_| ()))?;
        // Per object: AABB 32 B + draw record 16 + flag 4 in; class 4 + slot args 20 out; kept
        // ones also 4 + 20 compacted; map reads: at most 9 tiles, each a 32-B sector.
        let bytes = stage_bytes(WocStage::Cull, w, h, n).unwrap_or(0.0) + res.visible.len() as f64 * 24.0;
        row(&format!("cull vs {name} (CPU: build + test)"), &cull, Some(cpu), Some(bytes));
        kept.push((name, res.visible.len()));
    }
    println!();
    for (name, k) in &kept {
        println!("kept against the true depth with {name}: {k} of {n} objects");
    }

    // The whole WOC pipeline from the previous frame's textures, and the indirect draw of its
    // kept set; CPU woc (its twin parameters) in the same run.
    let cpu_params = GpuWocParams::cpu_twin(&WocParams::default());
    let woc = GpuWoc::new(&ctx, w, h, GpuWocParams::from_cpu(&WocParams::default())?)?;
    objects.write_forced(&ctx, Some(&rapid_flags(&scene, &cam0, t0, &cam1, t1, &cpu_params)))?;
    let items_view = prev.items[0].create_view(&Default::default());
    let pf = GpuPrevFrame { depth: &prev.depth[0].view, items: &items_view, cam: &cam0, t: t0 };
    let deltas = gs.object_deltas(t0, t1);
    let woc_t = measure(&mut |e| woc.encode(e, &gs, &pf, &deltas, &cam1, t1, &objects, &out))?;
    let res = out.read(&ctx)?;
    let prev_cpu = r.read_layer(&prev, 0)?;
    let cpu_pf = zwarp_cull::PrevFrame { depth: &prev_cpu.depth, items: &prev_cpu.items, cam: &cam0, t: t0 };
    let mut cpu_keep = 0;
    let cpu = cpu_time(&mut || {
        cpu_keep = zwarp_cull::woc(&scene, &cpu_pf, &cam1, t1, &cpu_params)?.visible.len();
        Ok(())
    })?;
    // Every stage but the warp and the rapid draw (see `stage_bytes`), plus the rapid merge
    // (8 B in + 4 out per pixel).
    let stages =
        [WocStage::Gather, WocStage::Motion, WocStage::Rims, WocStage::Erosion, WocStage::MaxDepth, WocStage::Cull];
    let woc_bytes = stages.iter().filter_map(|&s| stage_bytes(s, w, h, n)).sum::<f64>() + 12.0 * w as f64 * h as f64;
    row("WOC pipeline (textures -> visible list + args)", &woc_t, Some(cpu), Some(woc_bytes));
    // Per stage, each re-run alone on the buffers the full run left (WocStage docs).
    for stage in [
        WocStage::Gather,
        WocStage::Motion,
        WocStage::Rims,
        WocStage::Warp,
        WocStage::Erosion,
        WocStage::Rapid,
        WocStage::MaxDepth,
        WocStage::Cull,
    ] {
        let s = measure(&mut |e| woc.encode_stages(e, &gs, &pf, &deltas, &cam1, t1, &objects, &out, stage..=stage))?;
        row(&format!("  WOC stage {stage:?} alone"), &s, None, stage_bytes(stage, w, h, n));
    }
    let draw = measure(&mut |e| r.encode_depth_indirect(e, &gs, &cam1, t1, &target, &out, r.indirect_mode()))?;
    row("indirect depth draw of WOC's kept set", &draw, None, None);
    let slots = measure(&mut |e| r.encode_depth_indirect(e, &gs, &cam1, t1, &target, &out, IndirectMode::Slots))?;
    row("same, one indirect slot per object", &slots, None, None);
    println!();
    println!(
        "WOC keeps {} of {n} objects (CPU twin keeps {cpu_keep}); WOC + culled draw {:.2} ms vs full draw {:.2} ms",
        res.visible.len(),
        ms(woc_t.median) + ms(draw.median),
        ms(render.median)
    );
    Ok(())
}
