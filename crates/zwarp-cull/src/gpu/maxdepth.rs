//! Max-depth structures on the GPU (seed 000 Sec. 5.2; thesis seed 002 Sec. III.2): the max
//! mipmap (HOM), Décoret's N-buffer and the Y-map, the WGSL twins of
//! [`crate::MaxMipmap`], [`crate::NBuffer`] and [`crate::YMap`]. Shaders:
//! `maxdepth.wgsl` (build) and `maxquery.wgsl` (queries, shared with the cull kernel).
//!
//! A structure lives in one storage buffer holding every level (row-major, each at its own
//! offset) plus a small table of level offsets and sizes, so one binding serves any kind and
//! any number of levels. Max is exact in f32: every level and every query answer equals the
//! CPU structure's bit for bit.

use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;
use zwarp_core::{Error, Image, Result};
use zwarp_gpu::readback::read_buffer;
use zwarp_gpu::GpuContext;

use crate::maxdepth::MAX_YMAP_SWITCH;
use crate::{MaxDepthKind, PixelRect};

/// Uniform of one build step (layout of `Step` in `maxdepth.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable, Default)]
struct Step {
    src_off: u32,
    src_w: u32,
    src_h: u32,
    s: u32,
    dst_off: u32,
    dst_w: u32,
    dst_h: u32,
    n: u32,
}

/// `floor(log2(v))` for `v >= 1`.
fn floor_log2(v: u32) -> u32 {
    31 - v.leading_zeros()
}

/// Level sizes of a max mipmap of `w x h`: the image itself, then `ceil` halvings down to 1x1
/// (as `crate::MaxMipmap`), at most `max_level + 1` levels.
fn mip_sizes(w: u32, h: u32, max_level: u32) -> Vec<(u32, u32)> {
    let mut sizes = vec![(w, h)];
    while (sizes.len() as u32) <= max_level {
        let &(lw, lh) = sizes.last().expect("level 0 exists");
        if (lw, lh) == (1, 1) {
            break;
        }
        sizes.push((lw.div_ceil(2).max(1), lh.div_ceil(2).max(1)));
    }
    sizes
}

/// The level layout of a structure: which kind, how many mip and N-buffer levels, their sizes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MaxDepthLayout {
    /// The kind ([`MaxDepthKind::Default`] resolved to `YMap { switch: 2 }`; a Y-map switch
    /// beyond the mip chain clamped to it, as on the CPU).
    pub kind: MaxDepthKind,
    /// `(width, height)` of the depth buffer.
    pub size: (u32, u32),
    /// Sizes of the mip levels used by queries (all levels of a mipmap; levels `0..switch` of a
    /// Y-map; none for an N-buffer).
    pub mip: Vec<(u32, u32)>,
    /// Number of N-buffer levels (all of the N-buffer's size; for a Y-map the size of mip level
    /// `switch`).
    pub nbuf_levels: u32,
    /// Size of the N-buffer levels (`(0, 0)` for a mipmap).
    pub nbuf_size: (u32, u32),
}

impl MaxDepthLayout {
    /// The layout of `kind` over a `width x height` depth buffer. Errors on a zero size or a
    /// Y-map switch above [`MAX_YMAP_SWITCH`].
    pub fn new(kind: MaxDepthKind, width: u32, height: u32) -> Result<Self> {
        if width == 0 || height == 0 {
            return Err(Error::invalid(format!("max-depth structure of a zero-size image {width}x{height}")));
        }
        let kind = if kind == MaxDepthKind::Default { MaxDepthKind::YMap { switch: 2 } } else { kind };
        Ok(match kind {
            MaxDepthKind::Mipmap => MaxDepthLayout {
                kind,
                size: (width, height),
                mip: mip_sizes(width, height, u32::MAX),
                nbuf_levels: 0,
                nbuf_size: (0, 0),
            },
            MaxDepthKind::NBuffer => MaxDepthLayout {
                kind,
                size: (width, height),
                mip: Vec::new(),
                nbuf_levels: floor_log2(width.min(height)) + 1,
                nbuf_size: (width, height),
            },
            MaxDepthKind::YMap { switch } => {
                if switch > MAX_YMAP_SWITCH {
                    return Err(Error::invalid(format!("Y-map switch level {switch} exceeds {MAX_YMAP_SWITCH}")));
                }
                let mut mip = mip_sizes(width, height, switch);
                // When the image reaches 1x1 before `switch`, the top level is the switch level.
                let switch = mip.len() as u32 - 1;
                let top = mip.pop().expect("level 0 exists");
                MaxDepthLayout {
                    kind: MaxDepthKind::YMap { switch },
                    size: (width, height),
                    mip,
                    nbuf_levels: floor_log2(top.0.min(top.1)) + 1,
                    nbuf_size: top,
                }
            }
            MaxDepthKind::Default => unreachable!("resolved above"),
        })
    }

    /// Every stored level in buffer order (mip levels, then N-buffer levels) with its offset in
    /// floats; the total number of floats last.
    fn offsets(&self) -> (Vec<(u32, u32, u32)>, u64) {
        let mut out = Vec::new();
        let mut off = 0u64;
        let nb = (0..self.nbuf_levels).map(|_| self.nbuf_size);
        for (w, h) in self.mip.iter().copied().chain(nb) {
            out.push((off as u32, w, h));
            off += w as u64 * h as u64;
        }
        (out, off)
    }

    /// Bytes the structure occupies on the GPU (all levels).
    pub fn bytes(&self) -> u64 {
        self.offsets().1 * 4
    }

    /// The level table of `maxquery.wgsl`: header, size, then `(offset, w, h, 0)` per level.
    fn table(&self) -> Vec<[u32; 4]> {
        let (kind, switch) = match self.kind {
            MaxDepthKind::Mipmap => (0, 0),
            MaxDepthKind::NBuffer => (1, 0),
            MaxDepthKind::YMap { switch } => (2, switch),
            MaxDepthKind::Default => unreachable!("resolved in new"),
        };
        let mut t = vec![[kind, self.mip.len() as u32, self.nbuf_levels, switch], [self.size.0, self.size.1, 0, 0]];
        t.extend(self.offsets().0.into_iter().map(|(o, w, h)| [o, w, h, 0]));
        t
    }
}

/// Levels read back by [`GpuMaxDepth::read_levels`]: `(mip levels, N-buffer levels)`.
pub type MaxDepthLevels = (Vec<Image<f32>>, Vec<Image<f32>>);

/// A max-depth structure resident on the GPU (see the module docs), built by
/// [`MaxDepthKernel::encode`] from a depth buffer and read by the cull kernel.
#[derive(Debug)]
pub struct GpuMaxDepth {
    /// Its level layout.
    pub layout: MaxDepthLayout,
    /// All levels, f32, each at its offset (`STORAGE | COPY_SRC | COPY_DST`).
    pub data: wgpu::Buffer,
    /// The level table (`STORAGE`).
    pub table: wgpu::Buffer,
    /// Build steps: (N-buffer step?, bind group, dispatch size).
    steps: Vec<(bool, wgpu::BindGroup, (u32, u32))>,
}

impl GpuMaxDepth {
    /// Reads every level back: `(mip levels, N-buffer levels)`, in the order of
    /// `crate::{MaxMipmap, NBuffer, YMap}`'s level accessors.
    pub fn read_levels(&self, ctx: &GpuContext) -> Result<MaxDepthLevels> {
        let (offs, total) = self.layout.offsets();
        let all = read_buffer::<f32>(ctx, &self.data, total as usize)?;
        let mut imgs: Vec<Image<f32>> = offs
            .iter()
            .map(|&(o, w, h)| Image::from_vec(w, h, all[o as usize..o as usize + (w * h) as usize].to_vec()))
            .collect::<Result<_>>()?;
        let nbuf = imgs.split_off(self.layout.mip.len());
        Ok((imgs, nbuf))
    }
}

/// Builds and queries [`GpuMaxDepth`] structures.
pub struct MaxDepthKernel {
    ctx: GpuContext,
    reduce: wgpu::ComputePipeline,
    nbuf: wgpu::ComputePipeline,
    query: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    /// Placeholders for the query bindings of build steps (two: a read-only and a read-write
    /// binding of one buffer would conflict).
    dummy: [wgpu::Buffer; 2],
}

impl MaxDepthKernel {
    /// Compiles `maxquery.wgsl` + `maxdepth.wgsl`.
    pub fn new(ctx: &GpuContext) -> Result<Self> {
        let dev = &ctx.device;
        let module =
            ctx.shader("maxdepth.wgsl", concat!(include_str!("maxquery.wgsl"), include_str!("maxdepth.wgsl")))?;
        let ro = wgpu::BufferBindingType::Storage { read_only: true };
        let rw = wgpu::BufferBindingType::Storage { read_only: false };
        let (layout, pl) = zwarp_gpu::kernel::buffer_layouts(
            dev,
            "zwarp maxdepth",
            &[wgpu::BufferBindingType::Uniform, ro, rw, ro, rw],
        );
        let pipe = |entry| {
            ctx.catch("building the max-depth pipelines", || {
                dev.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(entry),
                    layout: Some(&pl),
                    module: &module,
                    entry_point: Some(entry),
                    compilation_options: Default::default(),
                    cache: None,
                })
            })
        };
        let dummy = [0, 1].map(|_| {
            dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some("zwarp dummy"),
                size: 16,
                usage: wgpu::BufferUsages::STORAGE,
                mapped_at_creation: false,
            })
        });
        Ok(MaxDepthKernel {
            ctx: ctx.clone(),
            reduce: pipe("reduce_2x2")?,
            nbuf: pipe("nbuf_step")?,
            query: pipe("query_rects")?,
            layout,
            dummy,
        })
    }

    fn bind(
        &self,
        step: &Step,
        table: &wgpu::Buffer,
        data: &wgpu::Buffer,
        io: Option<(&wgpu::Buffer, &wgpu::Buffer)>,
    ) -> wgpu::BindGroup {
        let dev = &self.ctx.device;
        let ubuf = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("zwarp maxdepth step"),
            contents: bytemuck::bytes_of(step),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let (a, b) = io.unwrap_or((&self.dummy[0], &self.dummy[1]));
        dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("zwarp maxdepth"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: ubuf.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 1, resource: table.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 2, resource: data.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 3, resource: a.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 4, resource: b.as_entire_binding() },
            ],
        })
    }

    /// Allocates a structure of `kind` for `width x height` depth buffers (reusable every
    /// frame: [`MaxDepthKernel::encode`] rebuilds it in place).
    pub fn create(&self, kind: MaxDepthKind, width: u32, height: u32) -> Result<GpuMaxDepth> {
        let layout = MaxDepthLayout::new(kind, width, height)?;
        self.ctx.check_storage_size(layout.bytes(), "max-depth structure")?;
        let dev = &self.ctx.device;
        let data = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("zwarp maxdepth levels"),
            size: layout.bytes(),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let table = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("zwarp maxdepth table"),
            contents: bytemuck::cast_slice(&layout.table()),
            usage: wgpu::BufferUsages::STORAGE,
        });
        // Stored level i (i >= 1) is a 2x2 reduction of level i - 1 up to and including the
        // first N-buffer level (a Y-map's N-buffer sits on mip level `switch`); the remaining
        // N-buffer levels double the square side.
        let (offs, _) = layout.offsets();
        let n_mip = layout.mip.len();
        let mut steps = Vec::new();
        for i in 1..offs.len() {
            let (so, sw, sh) = offs[i - 1];
            let (d_o, dw, dh) = offs[i];
            let nbuf_step = i > n_mip;
            let s = if nbuf_step { 1u32 << (i - n_mip - 1) } else { 0 };
            let st = Step { src_off: so, src_w: sw, src_h: sh, s, dst_off: d_o, dst_w: dw, dst_h: dh, n: 0 };
            steps.push((nbuf_step, self.bind(&st, &table, &data, None), (dw.div_ceil(8), dh.div_ceil(8))));
        }
        Ok(GpuMaxDepth { layout, data, table, steps })
    }

    /// Records the build of `map` from `depth`, a storage buffer of `width * height` f32 depths
    /// (row-major, `[0, 1]`, 1 = empty; needs `COPY_SRC`), e.g. a warp's output or
    /// [`zwarp_gpu::Renderer::encode_depth_copy`]'s. Level 0 is a plain copy; every further level
    /// one dispatch (own compute pass, so each level sees the previous one complete).
    pub fn encode(&self, encoder: &mut wgpu::CommandEncoder, depth: &wgpu::Buffer, map: &GpuMaxDepth) -> Result<()> {
        let (w, h) = map.layout.size;
        let bytes = w as u64 * h as u64 * 4;
        if depth.size() < bytes {
            return Err(Error::invalid(format!("depth buffer holds {} < {bytes} bytes for {w}x{h}", depth.size())));
        }
        if !depth.usage().contains(wgpu::BufferUsages::COPY_SRC) {
            return Err(Error::invalid("depth buffer of a max-depth build needs COPY_SRC usage"));
        }
        encoder.copy_buffer_to_buffer(depth, 0, &map.data, 0, bytes);
        for (nbuf, bind, (gx, gy)) in &map.steps {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("zwarp maxdepth"),
                timestamp_writes: None,
            });
            pass.set_pipeline(if *nbuf { &self.nbuf } else { &self.reduce });
            pass.set_bind_group(0, bind, &[]);
            pass.dispatch_workgroups(*gx, *gy, 1);
        }
        Ok(())
    }

    /// Uploads a CPU depth buffer and builds `kind` over it (submitted; stays on the GPU).
    /// Errors like the CPU build: empty buffer, NaN depths, bad Y-map switch.
    pub fn build(&self, depth: &Image<f32>, kind: MaxDepthKind) -> Result<GpuMaxDepth> {
        depth.check_nonempty("depth buffer")?;
        if let Some(i) = depth.data().iter().position(|d| d.is_nan()) {
            let (x, y) = (i as u32 % depth.width(), i as u32 / depth.width());
            return Err(Error::invalid(format!("depth buffer holds NaN at pixel ({x}, {y})")));
        }
        let map = self.create(kind, depth.width(), depth.height())?;
        let buf = self.ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("zwarp depth in"),
            contents: bytemuck::cast_slice(depth.data()),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        });
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        self.encode(&mut enc, &buf, &map)?;
        self.ctx.queue.submit([enc.finish()]);
        Ok(map)
    }

    /// `MaxDepthQuery::max_depth` of every rect, computed on the GPU by the same WGSL the cull
    /// kernel uses (rects are clamped to the image; [`zwarp_core::EMPTY_DEPTH`] when nothing
    /// is left).
    pub fn query(&self, map: &GpuMaxDepth, rects: &[PixelRect]) -> Result<Vec<f32>> {
        if rects.is_empty() {
            return Ok(Vec::new());
        }
        let dev = &self.ctx.device;
        let packed: Vec<[u32; 4]> = rects.iter().map(|r| [r.x0, r.y0, r.x1, r.y1]).collect();
        let rbuf = dev.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("zwarp query rects"),
            contents: bytemuck::cast_slice(&packed),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let abuf = dev.create_buffer(&wgpu::BufferDescriptor {
            label: Some("zwarp query answers"),
            size: rects.len() as u64 * 4,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let st = Step { n: rects.len() as u32, ..Step::default() };
        let bind = self.bind(&st, &map.table, &map.data, Some((&rbuf, &abuf)));
        let mut enc = dev.create_command_encoder(&Default::default());
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("zwarp maxdepth query"),
                timestamp_writes: None,
            });
            pass.set_pipeline(&self.query);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups((rects.len() as u32).div_ceil(64), 1, 1);
        }
        self.ctx.queue.submit([enc.finish()]);
        read_buffer::<f32>(&self.ctx, &abuf, rects.len())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layouts_follow_the_cpu_structures() {
        let m = MaxDepthLayout::new(MaxDepthKind::Mipmap, 5, 3).unwrap();
        assert_eq!(m.mip, vec![(5, 3), (3, 2), (2, 1), (1, 1)]);
        assert_eq!(m.bytes(), (15 + 6 + 2 + 1) * 4);
        let n = MaxDepthLayout::new(MaxDepthKind::NBuffer, 9, 6).unwrap();
        assert_eq!((n.nbuf_levels, n.nbuf_size), (3, (9, 6)));
        let y = MaxDepthLayout::new(MaxDepthKind::Default, 13, 11).unwrap();
        assert_eq!(y.kind, MaxDepthKind::YMap { switch: 2 });
        assert_eq!(y.mip, vec![(13, 11), (7, 6)]);
        assert_eq!((y.nbuf_levels, y.nbuf_size), (2, (4, 3)));
        // A switch beyond the chain clamps to the 1x1 level, as on the CPU.
        let y = MaxDepthLayout::new(MaxDepthKind::YMap { switch: 9 }, 13, 11).unwrap();
        assert_eq!((y.kind, y.nbuf_levels, y.nbuf_size), (MaxDepthKind::YMap { switch: 4 }, 1, (1, 1)));
        assert!(MaxDepthLayout::new(MaxDepthKind::YMap { switch: 17 }, 4, 4).is_err());
        assert!(MaxDepthLayout::new(MaxDepthKind::Mipmap, 0, 4).unwrap_err().to_string().contains("zero-size"));
    }
}
