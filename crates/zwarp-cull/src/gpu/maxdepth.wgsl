// Building max-depth structures on the GPU (seed 000 Sec. 5.2; thesis seed 002 Sec. III.2 and
// IV.1), the WGSL twins of zwarp_cull::{reduce_max_2x2, NBuffer, erode_max}; max is exact, so
// every level equals the CPU level bit for bit. Host code: maxdepth.rs. The query functions
// (maxquery.wgsl) are prepended to this file.

struct Step {
    // Offset (in floats) and size of the level read.
    src_off: u32,
    src_w: u32,
    src_h: u32,
    // N-buffer step: square side s of the level read (level i+1 = 4 lookups at +0 / +s).
    s: u32,
    // Offset of the level written (its size: `dst_w x dst_h`).
    dst_off: u32,
    dst_w: u32,
    dst_h: u32,
    // Number of rects of `query_rects`.
    n: u32,
};

@group(0) @binding(0) var<uniform> step: Step;
@group(0) @binding(1) var<storage, read> md_levels: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read_write> md_data: array<f32>;
// `query_rects`: rects in, answers out. `erode`: the source image (level 0 is written).
@group(0) @binding(3) var<storage, read> rects: array<vec4<u32>>;
@group(0) @binding(4) var<storage, read_write> answers: array<f32>;

// zwarp_cull::reduce_max_2x2: each texel the max of the (up to) 2x2 texels below it; the
// indices clamp to the last row/column, so an odd last row/column is its own texel.
@compute @workgroup_size(8, 8, 1)
fn reduce_2x2(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= step.dst_w || gid.y >= step.dst_h) {
        return;
    }
    let x0 = min(2u * gid.x, step.src_w - 1u);
    let x1 = min(2u * gid.x + 1u, step.src_w - 1u);
    let y0 = min(2u * gid.y, step.src_h - 1u);
    let y1 = min(2u * gid.y + 1u, step.src_h - 1u);
    let r0 = step.src_off + y0 * step.src_w;
    let r1 = step.src_off + y1 * step.src_w;
    let m = max(max(md_data[r0 + x0], md_data[r0 + x1]), max(md_data[r1 + x0], md_data[r1 + x1]));
    md_data[step.dst_off + gid.y * step.dst_w + gid.x] = m;
}

// zwarp_cull::NBuffer level i+1 from level i: the 2s square at p is the union of the four s
// squares at p, p + (s, 0), p + (0, s), p + (s, s); clamping to the last column/row reads a
// square inside the clipped one, so clamping stays exact.
@compute @workgroup_size(8, 8, 1)
fn nbuf_step(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= step.src_w || gid.y >= step.src_h) {
        return;
    }
    let w = step.src_w;
    let xs = min(gid.x + step.s, w - 1u);
    let ys = min(gid.y + step.s, step.src_h - 1u);
    let r0 = step.src_off + gid.y * w;
    let r1 = step.src_off + ys * w;
    let m = max(max(md_data[r0 + gid.x], md_data[r0 + xs]), max(md_data[r1 + gid.x], md_data[r1 + xs]));
    md_data[step.dst_off + gid.y * w + gid.x] = m;
}

// Answers `md_max_depth` for each rect (the CPU-twin test of the queries).
@compute @workgroup_size(64, 1, 1)
fn query_rects(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= step.n) {
        return;
    }
    answers[gid.x] = md_max_depth(rects[gid.x]);
}
