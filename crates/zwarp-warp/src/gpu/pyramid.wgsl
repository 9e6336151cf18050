// Min-max motion mipmap (seed 000, Sec. 3.3, Fig. 5): texel (i, j) of level l holds the
// component-wise min and max of the (frame-rotated) motion of the valid samples in the pixel
// block [i 2^l, (i+1) 2^l) x [j 2^l, (j+1) 2^l), clipped to the image. The GPU twin of
// zwarp_warp::bounds::MotionPyramid: levels 1..=top, level l is ceil(w_{l-1} / 2) wide (odd
// sizes keep their last row/column), texel = (lo.x, lo.y, hi.x, hi.y), empty = (+inf, -inf).
// Host code: pyramid.rs.

struct Params {
    // Size of the source (motion buffer for level 1, previous level otherwise).
    src_size: vec2<u32>,
    // Size of the level being written.
    dst_size: vec2<u32>,
    // Bound frame axis (c, s): u = (c v.x + s v.y, -s v.x + c v.y).
    axis: vec2<f32>,
    // (+inf, -inf): the empty bound, passed in because WGSL has no infinity literal.
    empty: vec2<f32>,
};

@group(0) @binding(0) var<uniform> params: Params;
// Level 1: motion samples, 3 floats each (v.x, v.y, depth). Higher levels: unused.
@group(0) @binding(1) var<storage, read> motion: array<f32>;
// Higher levels: the previous level's texels. Level 1: unused.
@group(0) @binding(2) var<storage, read> prev: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> dst: array<vec4<f32>>;

// zwarp_warp::bounds::is_valid_sample: target depth in [0, 1) and finite motion.
fn valid(v: vec2<f32>, d: f32) -> bool {
    let big = 3.4028235e38;
    return d >= 0.0 && d < 1.0 && abs(v.x) <= big && abs(v.y) <= big;
}

@compute @workgroup_size(8, 8, 1)
fn level_from_motion(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= params.dst_size.x || gid.y >= params.dst_size.y) {
        return;
    }
    var lo = vec2<f32>(params.empty.x);
    var hi = vec2<f32>(params.empty.y);
    let c = params.axis.x;
    let s = params.axis.y;
    for (var dy = 0u; dy < 2u; dy++) {
        let y = gid.y * 2u + dy;
        for (var dx = 0u; dx < 2u; dx++) {
            let x = gid.x * 2u + dx;
            if (x < params.src_size.x && y < params.src_size.y) {
                let i = 3u * (y * params.src_size.x + x);
                let v = vec2<f32>(motion[i], motion[i + 1u]);
                if (valid(v, motion[i + 2u])) {
                    let u = vec2<f32>(c * v.x + s * v.y, -s * v.x + c * v.y);
                    lo = min(lo, u);
                    hi = max(hi, u);
                }
            }
        }
    }
    dst[gid.y * params.dst_size.x + gid.x] = vec4<f32>(lo, hi);
}

@compute @workgroup_size(8, 8, 1)
fn level_from_level(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= params.dst_size.x || gid.y >= params.dst_size.y) {
        return;
    }
    var lo = vec2<f32>(params.empty.x);
    var hi = vec2<f32>(params.empty.y);
    for (var dy = 0u; dy < 2u; dy++) {
        let y = gid.y * 2u + dy;
        for (var dx = 0u; dx < 2u; dx++) {
            let x = gid.x * 2u + dx;
            if (x < params.src_size.x && y < params.src_size.y) {
                let t = prev[y * params.src_size.x + x];
                lo = min(lo, t.xy);
                hi = max(hi, t.zw);
            }
        }
    }
    dst[gid.y * params.dst_size.x + gid.x] = vec4<f32>(lo, hi);
}
