//! GPU colour warps (seed 001 Sec. 3.3, 3.4), the WGSL twins of `crate::heuristic_warp`
//! and of the raster stage of `crate::robust_warp_with`. Shader: `colorwarp.wgsl`.
//!
//! - `heuristic`: one invocation per target pixel runs the seed, the fixed-point walk (the
//!   shared search's arithmetic, `zwarp_warp::search::fixed_point_search`) and the orbit
//!   in-painting, sampling the field and the colour like `crate::ColorSampler`.
//! - robust: the subdivision (`rho`, max-reductions, quad tree) comes from
//!   `crate::Subdivision` on the CPU (built once per source, or once for many
//!   reprojections as in seed 001 Sec. 4); the GPU rasterises the leaf quads with a depth test
//!   in three passes — the nearest converged depth per pixel (atomic min), the first quad
//!   reaching it (atomic min on the quad index: the CPU's "earlier quad wins" tie rule), a
//!   resolve that recomputes the winner's colour and in-paints uncovered pixels with the
//!   heuristic walk; the push-pull fill of pixels nothing solved (`HoleFill::PushPull`) runs on
//!   the host after the readback.
//!
//! Results agree with the CPU up to float rounding of the shader compiler (tests: the same
//! colour on at least 99.5 % of the pixels of real frames; see `tests`).

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;
use zwarp_core::{Error, Image, Result};
use zwarp_gpu::kernel::AutoPipelines;
use zwarp_gpu::readback::read_buffer;
use zwarp_gpu::GpuContext;

use crate::{ColorWarpOutput, Field, HeuristicParams, RobustParams, Seed, Subdivision};

/// Mirror of `Params` in colorwarp.wgsl.
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Default)]
struct Params {
    width: u32,
    height: u32,
    n_terms: u32,
    iterations: u32,
    threshold: f32,
    seed_mode: u32,
    continuity: u32,
    accelerate: u32,
    seed: [f32; 2],
    n_leaves: u32,
    margin: f32,
    f_iterations: u32,
    f_threshold: f32,
    leaf_offset: u32,
    _pad: u32,
    scales: [[f32; 2]; 3],
    _pad2: [f32; 2],
}

/// Compute pipelines of the colour warps.
pub struct ColorWarpKernel {
    ctx: GpuContext,
    heuristic: wgpu::ComputePipeline,
    quads_depth: wgpu::ComputePipeline,
    quads_winner: wgpu::ComputePipeline,
    resolve: wgpu::ComputePipeline,
}

fn seed_code(s: Seed) -> (u32, [f32; 2]) {
    match s {
        Seed::Pixel => (0, [0.0; 2]),
        Seed::Upstream(k) => (1, [k, 0.0]),
        Seed::Offset(d) => (2, [d.x, d.y]),
    }
}

/// The device-side inputs of one warp.
struct Inputs {
    params: wgpu::Buffer,
    planes: wgpu::Buffer,
    color: wgpu::Buffer,
    rho: wgpu::Buffer,
    out_color: wgpu::Buffer,
    out_depth: wgpu::Buffer,
    out_residual: wgpu::Buffer,
}

impl ColorWarpKernel {
    /// Compiles `colorwarp.wgsl`.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let p = AutoPipelines::new(ctx, "colorwarp.wgsl", include_str!("colorwarp.wgsl"), "colour-warp")?;
        Ok(ColorWarpKernel {
            ctx: ctx.clone(),
            heuristic: p.pipeline("heuristic")?,
            quads_depth: p.pipeline("quads_depth")?,
            quads_winner: p.pipeline("quads_winner")?,
            resolve: p.pipeline("resolve")?,
        })
    }

    fn storage(&self, label: &str, bytes: &[u8]) -> Result<wgpu::Buffer> {
        self.ctx.buffer_with(label, bytes, wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC)
    }

    fn inputs(&self, field: &Field<'_>, color: &Image<[f32; 3]>, rho: &[f32], params: &Params) -> Result<Inputs> {
        let (w, h) = field.size();
        if color.size() != (w, h) {
            return Err(Error::invalid(format!(
                "GPU colour warp: colour image is {}x{} but the warp field is {w}x{h}",
                color.width(),
                color.height()
            )));
        }
        self.ctx.check_texture_size(w, h, "GPU colour warp")?;
        let n = w as usize * h as usize;
        let mut planes = Vec::with_capacity(n * (1 + 2 * field.terms().len()));
        planes.extend_from_slice(field.depth());
        for t in field.terms() {
            planes.extend_from_slice(t.x);
            planes.extend_from_slice(t.y);
        }
        let zeros = vec![0.0f32; n * 3];
        let dev = &self.ctx.device;
        Ok(Inputs {
            params: dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("zwarp colour warp params"),
                contents: bytemuck::bytes_of(params),
                usage: wgpu::BufferUsages::UNIFORM,
            }),
            planes: self.storage("zwarp colour warp field", bytemuck::cast_slice(&planes))?,
            color: self.storage("zwarp colour warp colour", bytemuck::cast_slice(color.data()))?,
            rho: self.storage("zwarp colour warp rho", bytemuck::cast_slice(rho))?,
            out_color: self.storage("zwarp colour warp out colour", bytemuck::cast_slice(&zeros))?,
            out_depth: self.storage("zwarp colour warp out depth", bytemuck::cast_slice(&zeros[..n]))?,
            out_residual: self.storage("zwarp colour warp out residual", bytemuck::cast_slice(&zeros[..n]))?,
        })
    }

    fn base_params(field: &Field<'_>) -> Params {
        let (w, h) = field.size();
        let mut p = Params { width: w, height: h, n_terms: field.terms().len() as u32, ..Params::default() };
        for (s, t) in p.scales.iter_mut().zip(field.terms()) {
            *s = [t.scale.x, t.scale.y];
        }
        p
    }

    fn dispatch(
        &self,
        enc: &mut wgpu::CommandEncoder,
        pipeline: &wgpu::ComputePipeline,
        entries: &[(u32, &wgpu::Buffer)],
        groups: (u32, u32),
    ) {
        let entries: Vec<wgpu::BindGroupEntry> = entries
            .iter()
            .map(|(b, buf)| wgpu::BindGroupEntry { binding: *b, resource: buf.as_entire_binding() })
            .collect();
        let bind = self.ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("zwarp colour warp"),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &entries,
        });
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("zwarp colour warp"),
            timestamp_writes: None,
        });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups(groups.0, groups.1, 1);
    }

    fn read(&self, inp: &Inputs, w: u32, h: u32, threshold: f32) -> Result<ColorWarpOutput> {
        let n = w as usize * h as usize;
        let c: Vec<f32> = read_buffer(&self.ctx, &inp.out_color, n * 3)?;
        let color: Vec<[f32; 3]> = c.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
        Ok(ColorWarpOutput {
            color: Image::from_vec(w, h, color)?,
            depth: Image::from_vec(w, h, read_buffer(&self.ctx, &inp.out_depth, n)?)?,
            residual: Image::from_vec(w, h, read_buffer(&self.ctx, &inp.out_residual, n)?)?,
            threshold,
        })
    }

    /// The heuristic warp (twin of `crate::heuristic_warp`): same validation, same
    /// output up to float rounding.
    pub fn heuristic(
        &self,
        field: &Field<'_>,
        color: &Image<[f32; 3]>,
        hp: &HeuristicParams,
    ) -> Result<ColorWarpOutput> {
        hp.validate()?;
        let (w, h) = field.size();
        let (seed_mode, seed) = seed_code(hp.seed);
        let params =
            Params { iterations: hp.iterations, threshold: hp.threshold, seed_mode, seed, ..Self::base_params(field) };
        let inp = self.inputs(field, color, &[], &params)?;
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        self.dispatch(
            &mut enc,
            &self.heuristic,
            &[
                (0, &inp.params),
                (1, &inp.planes),
                (2, &inp.color),
                (3, &inp.rho),
                (4, &inp.out_color),
                (5, &inp.out_depth),
                (6, &inp.out_residual),
            ],
            (w.div_ceil(8), h.div_ceil(8)),
        );
        self.ctx.queue.submit([enc.finish()]);
        self.read(&inp, w, h, hp.threshold)
    }

    /// The robust warp with a given subdivision (twin of `crate::robust_warp_with`).
    pub fn robust_with(
        &self,
        sub: &Subdivision,
        field: &Field<'_>,
        color: &Image<[f32; 3]>,
        rp: &RobustParams,
    ) -> Result<ColorWarpOutput> {
        rp.validate()?;
        let (w, h) = field.size();
        if sub.size() != (w, h) {
            return Err(Error::invalid("GPU robust warp: subdivision and field differ in size"));
        }
        let leaves: Vec<[u32; 4]> = sub.leaves().iter().map(|l| [l.x0, l.y0, l.x1, l.y1]).collect();
        let (seed_mode, seed) = seed_code(rp.fallback.seed);
        let params = Params {
            iterations: rp.iterations,
            threshold: rp.threshold,
            seed_mode,
            seed,
            continuity: 1,
            accelerate: rp.accelerate as u32,
            n_leaves: leaves.len() as u32,
            margin: rp.margin,
            f_iterations: rp.fallback.iterations,
            f_threshold: rp.fallback.threshold,
            ..Self::base_params(field)
        };
        let inp = self.inputs(field, color, sub.rho(), &params)?;
        let n = w as usize * h as usize;
        let leaves_buf = self.storage("zwarp colour warp quads", bytemuck::cast_slice(&leaves))?;
        let zkey = self.storage("zwarp colour warp depth keys", bytemuck::cast_slice(&vec![u32::MAX; n]))?;
        let winner = self.storage("zwarp colour warp winners", bytemuck::cast_slice(&vec![u32::MAX; n]))?;
        let groups = (leaves.len() as u32).div_ceil(64).max(1);
        let gx = groups.min(65_535);
        let gy = groups.div_ceil(gx);
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        let quad_entries = [(0, &inp.params), (1, &inp.planes), (3, &inp.rho), (7, &leaves_buf), (8, &zkey)];
        self.dispatch(&mut enc, &self.quads_depth, &quad_entries, (gx, gy));
        let winner_entries =
            [(0, &inp.params), (1, &inp.planes), (3, &inp.rho), (7, &leaves_buf), (8, &zkey), (9, &winner)];
        self.dispatch(&mut enc, &self.quads_winner, &winner_entries, (gx, gy));
        self.dispatch(
            &mut enc,
            &self.resolve,
            &[
                (0, &inp.params),
                (1, &inp.planes),
                (2, &inp.color),
                (3, &inp.rho),
                (4, &inp.out_color),
                (5, &inp.out_depth),
                (6, &inp.out_residual),
                (7, &leaves_buf),
                (9, &winner),
            ],
            (w.div_ceil(8), h.div_ceil(8)),
        );
        self.ctx.queue.submit([enc.finish()]);
        let mut out = self.read(&inp, w, h, rp.threshold)?;
        if rp.fill == crate::HoleFill::PushPull && out.converged_fraction() < 1.0 {
            // The push-pull fill of what no search solved runs on the host after the readback.
            let valid = out.converged_mask();
            crate::push_pull(&mut out.color, &valid)?;
        }
        Ok(out)
    }

    /// The robust warp (twin of `crate::robust_warp`): the subdivision on the CPU, the
    /// quads on the GPU.
    pub fn robust(&self, field: &Field<'_>, color: &Image<[f32; 3]>, rp: &RobustParams) -> Result<ColorWarpOutput> {
        rp.validate()?;
        let sub = Subdivision::of_field(field, rp.tile)?;
        self.robust_with(&sub, field, color, rp)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{FieldParams, WarpBasis};
    use glam::{Vec2, Vec3};
    use zwarp_core::Camera;

    /// A small real frame (procedural MO) and its motion towards the next frame.
    fn frame() -> (Image<f32>, Image<zwarp_core::Motion>, Image<[f32; 3]>, Camera) {
        let opts = zwarp_scene::SceneOptions { scale: 0.03, ..Default::default() };
        let loaded = zwarp_scene::load_scene("mo", &opts).unwrap();
        let path = loaded.path_or_default();
        let (ta, tb) = (path.time_of_frame(10, 1.0), path.time_of_frame(13, 1.0));
        let (ca, cb) = (path.camera_at(ta, 160, 96).unwrap(), path.camera_at(tb, 160, 96).unwrap());
        let f = zwarp_raster::render_frame(
            &loaded.scene,
            &ca,
            ta,
            &zwarp_raster::FrameOptions { color: true, objects: None },
        )
        .unwrap();
        let m =
            zwarp_core::motion_field(&f.depth, Some(&f.items), &ca, &cb, &loaded.scene.object_deltas(ta, tb)).unwrap();
        (f.depth, m, f.color.unwrap(), ca)
    }

    fn agreement(a: &ColorWarpOutput, b: &ColorWarpOutput) -> f64 {
        let same = a
            .color
            .data()
            .iter()
            .zip(b.color.data())
            .filter(|(x, y)| (0..3).all(|k| (x[k] - y[k]).abs() <= 1e-4))
            .count();
        same as f64 / a.color.len() as f64
    }

    #[test]
    fn gpu_colour_warps_match_the_cpu() {
        let Some(ctx) = zwarp_gpu::test_context() else { return };
        let k = ColorWarpKernel::new(&ctx).unwrap();
        let (depth, m, color, cam) = frame();
        let basis = WarpBasis::temporal(&depth, &m).unwrap().with_spatial(&cam, None).unwrap();
        for params in [FieldParams::temporal(0.5), FieldParams::temporal(-1.0), FieldParams { t: 1.0, u: 0.3, v: 0.1 }]
        {
            let f = basis.field(params).unwrap();
            for seed in [Seed::Upstream(1.0), Seed::Pixel, Seed::Offset(Vec2::new(3.0, 0.0))] {
                let hp = HeuristicParams { seed, ..HeuristicParams::default() };
                let cpu = crate::heuristic_warp(&f, &color, &hp).unwrap();
                let gpu = k.heuristic(&f, &color, &hp).unwrap();
                let a = agreement(&cpu, &gpu);
                eprintln!("heuristic {params:?} {seed:?}: {a:.5} of the pixels agree to 1e-4");
                assert!(a >= 0.995, "heuristic {params:?} {seed:?}: {a}");
                assert!((cpu.converged_fraction() - gpu.converged_fraction()).abs() < 0.005);
            }
            let rp = RobustParams::default();
            let (cpu, _) = crate::robust_warp(&f, &color, &rp).unwrap();
            let gpu = k.robust(&f, &color, &rp).unwrap();
            let a = agreement(&cpu, &gpu);
            eprintln!("robust {params:?}: {a:.5} of the pixels agree to 1e-4");
            assert!(a >= 0.995, "robust {params:?}: {a}");
        }
        // Bad input: one clear line.
        let small = Image::new(4, 4, [0.0f32; 3]);
        let f = basis.field(FieldParams::temporal(0.5)).unwrap();
        assert!(k.heuristic(&f, &small, &HeuristicParams::default()).unwrap_err().to_string().contains("colour image"));
        let _ = Vec3::ZERO;
    }
}
