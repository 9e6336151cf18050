//! Culling methods run along a camera path on the GPU (seed 000 Sec. 5.3, thesis Sec. V): the
//! GPU twin of [`crate::run_sequence`], reporting the same [`FrameReport`]s so that
//! `zwarp cull --backend gpu` prints the same JSON fields. As on the CPU, the engine's loop runs
//! first and alone, on one device: per frame the method's cull (timed: CPU-side AABB/flag
//! uploads + GPU work, fenced wall clock) and the indirect draw of the kept objects (depth +
//! items, timed), which is the next frame's previous frame; then a second pass renders every
//! frame in full (REF, timed as the comparison), draws each kept set again and compares.
//! Read-backs for the statistics are not timed.
//!
//! Methods: NOCULL, VFC (cull kernel against an empty map), LASTFRAME (max structure of the
//! previous drawn depth), WOC and AWOC ([`GpuWoc`]), IDEAL (N-buffer of the true depth) and
//! REF. Two-phase culling is CPU-only ([`gpu_supports`]).

use std::time::Instant;

use zwarp_core::{Camera, Error, Image, Result, Scene};
use zwarp_gpu::{GpuContext, GpuScene, LayerTargets, PeelOptions, Renderer};

use super::{
    rapid_flags, CullKernel, CullObjects, CullOutput, CullParams, GpuCullClass, GpuMaxDepth, GpuWoc, GpuWocParams,
    MaxDepthKernel,
};
use crate::sequence::{frame_report, TimedFrame};
use crate::{visible_from_items, CullStats, CullTimings, FrameReport, MaxDepthKind, Method, WocParams};

/// `true` for the methods [`run_gpu_sequence`] implements.
pub fn gpu_supports(method: Method) -> bool {
    method != Method::TwoPhase
}

fn ms(t0: Instant) -> f64 {
    t0.elapsed().as_secs_f64() * 1e3
}

/// Device state shared by the frames of a run.
struct Run<'a> {
    ctx: &'a GpuContext,
    scene: &'a Scene,
    gs: GpuScene,
    r: Renderer,
    max_k: MaxDepthKernel,
    cull_k: CullKernel,
    objects: CullObjects,
    out: CullOutput,
    /// Slot arguments for CPU-chosen sets (NOCULL, REF).
    set_args: wgpu::Buffer,
    /// A depth buffer copy (for max structures over a rendered depth target).
    depth_buf: wgpu::Buffer,
    map: GpuMaxDepth,
    empty_map: GpuMaxDepth,
    woc: Option<GpuWoc>,
}

impl Run<'_> {
    /// Submits `enc` and waits: the fenced wall-clock end of a timed step.
    fn finish(&self, enc: wgpu::CommandEncoder) -> Result<()> {
        self.ctx.queue.submit([enc.finish()]);
        self.ctx.wait()
    }

    fn encoder(&self) -> wgpu::CommandEncoder {
        self.ctx.device.create_command_encoder(&Default::default())
    }

    /// Slot arguments drawing exactly `ids` (one instance for each listed object).
    fn write_set(&self, ids: &[u32]) {
        let mut keep = vec![false; self.scene.instances.len()];
        for &id in ids {
            keep[id as usize] = true;
        }
        let mut args = vec![wgpu::util::DrawIndexedIndirectArgs::default(); keep.len()];
        for (id, d) in self.gs.draws().iter().enumerate() {
            args[d[3] as usize] = wgpu::util::DrawIndexedIndirectArgs {
                index_count: d[1],
                instance_count: keep[id] as u32,
                first_index: d[0],
                base_vertex: d[2] as i32,
                first_instance: d[3],
            };
        }
        let bytes: Vec<u8> = args.iter().flat_map(|a| a.as_bytes().to_vec()).collect();
        self.ctx.queue.write_buffer(&self.set_args, 0, &bytes);
    }

    /// Culls against `map` (built over `depth` first when given), returning the wall time.
    fn cull_against(&self, cam: &Camera, t: f32, depth: Option<&LayerTargets>, map: &GpuMaxDepth) -> Result<f64> {
        let t0 = Instant::now();
        self.objects.write_scene_aabbs(self.ctx, self.scene, t)?;
        self.objects.write_forced(self.ctx, None)?;
        let mut enc = self.encoder();
        if let Some(d) = depth {
            self.r.encode_depth_copy(&mut enc, &d.depth[0], &self.depth_buf, cam.width)?;
            self.max_k.encode(&mut enc, &self.depth_buf, map)?;
        }
        self.cull_k.encode(
            &mut enc,
            &self.objects,
            &cam.view_proj(),
            cam.width,
            cam.height,
            &CullParams::default(),
            map,
            &self.out,
        )?;
        self.finish(enc)?;
        Ok(ms(t0))
    }
}

fn stats_of(classes: &[GpuCullClass]) -> CullStats {
    let mut st = CullStats { objects: classes.len(), ..CullStats::default() };
    for c in classes {
        match c {
            GpuCullClass::Frustum => st.frustum_culled += 1,
            GpuCullClass::Occluded => st.occlusion_culled += 1,
            GpuCullClass::CrossesNear => st.crosses_near += 1,
            GpuCullClass::Forced => st.rapid += 1,
            GpuCullClass::Visible => {}
        }
    }
    st
}

/// Runs `method` along `frames` on `ctx`'s device (see the module docs). `params` as for the
/// CPU: the GPU WOC runs [`GpuWocParams::from_cpu`]`(params)`, i.e. the CPU's
/// [`GpuWocParams::cpu_twin`]. Errors: unsupported methods, no frames, differing frame sizes,
/// parameters the GPU cannot run.
pub fn run_gpu_sequence(
    ctx: &GpuContext,
    scene: &Scene,
    frames: &[(f32, Camera)],
    method: Method,
    params: &WocParams,
) -> Result<Vec<FrameReport>> {
    if !gpu_supports(method) {
        return Err(Error::invalid(format!("culling method '{}' is CPU-only", method.name())));
    }
    let first = crate::sequence::check_frames(frames)?;
    let (w, h) = (first.width, first.height);
    let gs = GpuScene::upload(ctx, scene)?;
    let n = scene.instances.len();
    let max_k = MaxDepthKernel::new(ctx)?;
    let depth_buf = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("zwarp sequence depth"),
        size: w as u64 * h as u64 * 4,
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    // VFC is the cull kernel against a map that never occludes (every texel far).
    let empty_map = max_k.build(&Image::new(w, h, zwarp_core::EMPTY_DEPTH), MaxDepthKind::Mipmap)?;
    let woc = match method {
        Method::Woc | Method::Awoc => {
            let p = WocParams { awoc: method == Method::Awoc, ..*params };
            Some(GpuWoc::new(ctx, w, h, GpuWocParams::from_cpu(&p)?)?)
        }
        _ => None,
    };
    let run = Run {
        ctx,
        scene,
        r: Renderer::new(ctx)?,
        // IDEAL is the exact N-buffer test (as `crate::ideal_screen_space`).
        map: max_k.create(if method == Method::Ideal { MaxDepthKind::NBuffer } else { params.max_depth }, w, h)?,
        max_k,
        cull_k: CullKernel::new(ctx)?,
        objects: CullObjects::for_scene(ctx, &gs)?,
        out: CullOutput::new(ctx, n)?,
        set_args: ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("zwarp sequence set args"),
            size: n as u64 * std::mem::size_of::<wgpu::util::DrawIndexedIndirectArgs>() as u64,
            usage: wgpu::BufferUsages::INDIRECT | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        }),
        depth_buf,
        empty_map,
        woc,
        gs,
    };
    let full_targets = LayerTargets::new(&run.r, w, h, 1, false)?;
    // The drawn frame of the previous and the current frame (swapped every frame).
    let drawn = [LayerTargets::new(&run.r, w, h, 1, false)?, LayerTargets::new(&run.r, w, h, 1, false)?];
    let history = matches!(method, Method::Woc | Method::Awoc | Method::LastFrame);

    // Pass 1, the engine's loop and the only timed one (as `crate::run_sequence`): cull,
    // then draw the kept objects (depth + items), which is the next frame's previous frame. The
    // oracles (IDEAL, REF) render the frame in full first because that render is their input.
    // The occlusion map kept is WOC's predicted depth (read back, untimed) for the diagnostics.
    let pass1 = |frames: &[(f32, Camera)]| -> Result<Vec<TimedFrame>> {
        let mut timed: Vec<TimedFrame> = Vec::with_capacity(frames.len());
        for (k, (t, cam)) in frames.iter().enumerate() {
            let t = *t;
            let bootstrap = history && k == 0;
            let (cur, prev) = (k % 2, (k + 1) % 2);
            let oracle = matches!(method, Method::Ideal | Method::Ref);
            if oracle {
                let mut enc = run.encoder();
                let full_opts = PeelOptions { layers: 1, ..Default::default() };
                run.r.encode_layers(&mut enc, &run.gs, cam, t, &full_opts, &full_targets)?;
                run.finish(enc)?;
            }
            // (visible ids, cull ms, stats, occlusion map, args from the cull kernel?)
            let (visible, cull_ms, stats, occ, from_kernel) = if bootstrap || method == Method::Vfc {
                let c = run.cull_against(cam, t, None, &run.empty_map)?;
                let r = run.out.read(ctx)?;
                (r.visible, c, stats_of(&r.classes), None, true)
            } else {
                match method {
                    Method::NoCull | Method::Ref => {
                        let ids: Vec<u32> = if method == Method::Ref {
                            visible_from_items(&run.r.read_layer(&full_targets, 0)?.items, n)
                        } else {
                            (0..n as u32).collect()
                        };
                        run.write_set(&ids);
                        (ids, 0.0, CullStats { objects: n, ..CullStats::default() }, None, false)
                    }
                    Method::Ideal | Method::LastFrame => {
                        let src = if method == Method::Ideal { &full_targets } else { &drawn[prev] };
                        let c = run.cull_against(cam, t, Some(src), &run.map)?;
                        let r = run.out.read(ctx)?;
                        (r.visible, c, stats_of(&r.classes), None, true)
                    }
                    Method::Woc | Method::Awoc => {
                        let woc = run.woc.as_ref().expect("built for WOC");
                        let (t_prev, cam_prev) = &frames[k - 1];
                        let t0 = Instant::now();
                        run.objects.write_scene_aabbs(ctx, scene, t)?;
                        let flags = rapid_flags(scene, cam_prev, *t_prev, cam, t, params);
                        run.objects.write_forced(ctx, Some(&flags))?;
                        let items_view = drawn[prev].items[0].create_view(&Default::default());
                        let pf = super::GpuPrevFrame {
                            depth: &drawn[prev].depth[0].view,
                            items: &items_view,
                            cam: cam_prev,
                            t: *t_prev,
                        };
                        let mut enc = run.encoder();
                        woc.encode(
                            &mut enc,
                            &run.gs,
                            &pf,
                            &run.gs.object_deltas(*t_prev, t),
                            cam,
                            t,
                            &run.objects,
                            &run.out,
                        )?;
                        run.finish(enc)?;
                        let c = ms(t0);
                        let r = run.out.read(ctx)?;
                        let occ = zwarp_gpu::readback::read_buffer::<f32>(ctx, woc.predicted(), (w * h) as usize)?;
                        (r.visible, c, stats_of(&r.classes), Some(Image::from_vec(w, h, occ)?), true)
                    }
                    Method::Vfc | Method::TwoPhase => unreachable!("handled above / rejected"),
                }
            };
            // Draw the kept objects (depth + items): the frame the engine shows, and the next
            // frame's history.
            let t0 = Instant::now();
            let mut enc = run.encoder();
            let args = if from_kernel { &run.out.slot_args } else { &run.set_args };
            run.r.encode_frame_from_args(&mut enc, &run.gs, cam, t, &drawn[cur], args, None)?;
            run.finish(enc)?;
            let draw_ms = ms(t0);
            let cull = CullTimings { total_ms: cull_ms, ..CullTimings::default() };
            timed.push(TimedFrame { visible, cull, stats, draw_ms, occ, bootstrap });
        }
        Ok(timed)
    };
    // Warm-up over frame 0 twice, untimed and discarded (as on the CPU).
    pass1(&[frames[0], frames[0]])?;
    let timed = pass1(frames)?;

    // Pass 2, the evaluation: the full render (REF / NOCULL, timed as the comparison), the kept
    // set drawn again from its ids (the same slots in the same order: the same depth and items)
    // and everything compared.
    let mut prev_cpu: Option<(Image<f32>, Image<u32>)> = None;
    let mut reports = Vec::with_capacity(frames.len());
    for (k, ((t, cam), mut f)) in frames.iter().zip(timed).enumerate() {
        let t = *t;
        let t0 = Instant::now();
        let mut enc = run.encoder();
        run.r.encode_layers(
            &mut enc,
            &run.gs,
            cam,
            t,
            &PeelOptions { layers: 1, ..Default::default() },
            &full_targets,
        )?;
        run.finish(enc)?;
        let full_draw_ms = ms(t0);
        let full = run.r.read_layer(&full_targets, 0)?;
        run.write_set(&f.visible);
        let mut enc = run.encoder();
        run.r.encode_frame_from_args(&mut enc, &run.gs, cam, t, &drawn[0], &run.set_args, None)?;
        run.finish(enc)?;
        let shown = run.r.read_layer(&drawn[0], 0)?;
        let occ = match method {
            Method::Ideal => Some(full.depth.clone()),
            Method::LastFrame if !f.bootstrap => prev_cpu.as_ref().map(|(d, _)| d.clone()),
            _ => f.occ.take(),
        };
        let prev = prev_cpu.as_ref().map(|(d, i)| (d, i));
        reports.push(frame_report(
            scene,
            frames,
            k,
            f,
            (&full.depth, &full.items),
            full_draw_ms,
            &shown.depth,
            occ.as_ref(),
            prev,
        )?);
        prev_cpu = Some((shown.depth, shown.items));
    }
    Ok(reports)
}
