// Backward depth warp (seed 000 Sec. 3, Fig. 3, 5, 6): the WGSL twin of
// zwarp_warp::warp_depth (every BoundKind; the oriented frame per layer comes from the host). Every function
// below mirrors a CPU function of crates/zwarp-warp (named in its comment) operation by
// operation, so that both backends compute the same function. Host code: warp.rs.
//
// Buffers (L layers of w x h source samples, wh = w * h; the target is (w / m) x (h / m) pixels
// for WarpParams::multisample = m, target pixel (x, y) searched at m * (x + 0.5, y + 0.5)):
// - samples: L * wh texels (v.x, v.y, target depth or 2.0 if invalid, raw source depth),
//   the CPU's `validated_samples` (invalid samples have target depth outside [0, 1)).
// - mip / zmin: per layer `level_total` texels, levels 1..=top packed at params.levels[l-1].x;
//   mip texel = (lo.x, lo.y, hi.x, hi.y) of the valid motion, zmin texel = (min target depth,
//   component-wise largest bound of the cells whose top-left texel it covers, 0): the fold
//   (gradient::cell_fold, twice) with FLAG_MONOTONE, else gradient::cell_gradient.
// - out_depth / out_state: the warped depth and PixelState (0 converged, 1 filled, 2 hole,
//   3 converged on a layer after the first: WarpOutput::revealed), one per target pixel.

struct Params {
    // Source layer size (the space of q, the motion and the mipmaps).
    size: vec2<u32>,
    layers: u32,
    top: u32,
    // Layer of a prepare / mip dispatch.
    layer: u32,
    // Level (2..=top) written by a mip_up dispatch.
    level: u32,
    n_seeds: u32,
    iterations: u32,
    threshold: f32,
    bound_iterations: u32,
    flags: u32,
    radius: u32,
    seed_offset: vec2<f32>,
    expand: f32,
    level_total: u32,
    // (+inf, -inf): WGSL has no infinity literal.
    inf: vec2<f32>,
    // WarpParams::motion_scale: factor on every fetched motion and every mipmap bound.
    motion_scale: vec2<f32>,
    // Target image size (size / multisample): the pixels of `warp` and `dilate`.
    target_size: vec2<u32>,
    // WarpParams::multisample as a float (depth_warp::Kernel::m).
    multisample: f32,
    // WarpParams::cover_radius squared.
    cover2: f32,
    // WarpParams::extra_iterations (and padding to the arrays' 16-byte alignment).
    extra_iterations: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
    // Per level l - 1: (offset within a layer's block, width, height, 0).
    levels: array<vec4<u32>, 16>,
    // Bound frame axis (c, s) per layer in .xy ((1, 0) = axis-aligned).
    axes: array<vec4<f32>, 8>,
    // bounds::ImageClip per layer in its frame: (lo.x, lo.y, hi.x, hi.y), +-inf for none.
    clips: array<vec4<f32>, 8>,
};

const FLAG_CROSS: u32 = 1u;
const FLAG_ACCEL: u32 = 2u;
const FLAG_ADAPTIVE: u32 = 4u;
const FLAG_FIRST: u32 = 8u;
const FLAG_SEED_PIXEL: u32 = 16u;
const FLAG_SEED_OFFSET: u32 = 32u;
const FLAG_BACKGROUND: u32 = 64u;
// HolePolicy::Awoc (Sec. 5.3): non-converged pixels take the nearest sample at the corners of
// the first searched layer's tight region.
const FLAG_AWOC: u32 = 128u;
// WarpParams::ground_layer: the last layer is the ground peeled alone.
const FLAG_GROUND: u32 = 256u;
// The preparation serves motion scales >= 1 (MotionScales::AtLeastOne): the gradient mipmap
// holds the fold and the one-seed test is monotonicity (gradient::OneSeedTest::Monotone).
const FLAG_MONOTONE: u32 = 512u;
const EMPTY_Z: f32 = 2.0;
// zwarp_warp::RETRY_SEED_FACTOR and zwarp_warp::MAX_SEEDS.
const RETRY_SEED_FACTOR: u32 = 4u;
const MAX_SEEDS: u32 = 64u;
// zwarp_warp::COVER_DEPTH_RATIO.
const COVER_DEPTH_RATIO: f32 = 1.1;
// zwarp_warp::kernel::CONTINUATION_MIN_DET.
const CONTINUATION_MIN_DET: f32 = 0.25;
// search::STRADDLE_SPAN and search::STRADDLE_DEPTH_RATIO.
const STRADDLE_SPAN: f32 = 16.0;
const STRADDLE_DEPTH_RATIO: f32 = 1.5;
// zwarp_warp::sampling::CONTINUITY_PX, DEPTH_CONTINUITY and SURFACE_DEPTH_STEP.
const CONTINUITY: f32 = 1.0;
const DEPTH_CONTINUITY: f32 = 2.0;
const SURFACE_DEPTH_STEP: f32 = 0.05;
// zwarp_warp::gradient::UNIQUE_GRADIENT.
const UNIQUE_GRADIENT: f32 = 0.5;
const R2: vec2<f32> = vec2<f32>(0.7548777, 0.5698403);
// f32::EPSILON.
const EPS: f32 = 1.1920929e-7;

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> depth_in: array<f32>;
@group(0) @binding(2) var<storage, read> motion_in: array<f32>;
// Writers and readers of the same buffers are declared apart: an entry point that only reads
// a buffer gets a read-only binding (the compiler may then reorder and cache its loads).
@group(0) @binding(3) var<storage, read_write> samples_out: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> samples: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> mip: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> zmin: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> mip_ro: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read> zmin_ro: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read_write> out_depth: array<f32>;
@group(0) @binding(7) var<storage, read_write> out_state: array<u32>;
@group(0) @binding(8) var<storage, read_write> fill_depth: array<f32>;
@group(0) @binding(9) var<storage, read_write> fill_state: array<u32>;

fn finite2(v: vec2<f32>) -> bool {
    let big = 3.4028235e38;
    return abs(v.x) <= big && abs(v.y) <= big;
}

fn valid_z(z: f32) -> bool {
    return z >= 0.0 && z < 1.0;
}

// BoundFrame of layer k: u = R v with R = [[c, s], [-s, c]].
fn is_identity(k: u32) -> bool {
    let a = params.axes[k].xy;
    return a.x == 1.0 && a.y == 0.0;
}

fn to_frame(k: u32, v: vec2<f32>) -> vec2<f32> {
    let c = params.axes[k].x;
    let s = params.axes[k].y;
    return vec2<f32>(c * v.x + s * v.y, -s * v.x + c * v.y);
}

fn from_frame(k: u32, u: vec2<f32>) -> vec2<f32> {
    let c = params.axes[k].x;
    let s = params.axes[k].y;
    return vec2<f32>(c * u.x - s * u.y, s * u.x + c * u.y);
}

// depth_warp::validated_samples for layer params.layer: valid iff source depth < 1, target
// depth in [0, 1) and finite motion.
@compute @workgroup_size(8, 8, 1)
fn prepare(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= params.size.x || gid.y >= params.size.y) {
        return;
    }
    let wh = params.size.x * params.size.y;
    let i = gid.y * params.size.x + gid.x;
    let d = depth_in[i];
    let v = vec2<f32>(motion_in[3u * i], motion_in[3u * i + 1u]);
    let z = motion_in[3u * i + 2u];
    var s = vec4<f32>(0.0, 0.0, EMPTY_Z, d);
    if (d < 1.0 && valid_z(z) && finite2(v)) {
        s = vec4<f32>(v, z, d);
    }
    samples_out[params.layer * wh + i] = s;
}

// bounds::ImageClip::block_centres: the frame-coordinate box (lo, hi) of the sample centres of
// level-1 block b of layer k (its first centre plus BlockExtent, the frame's extent of the unit
// square).
fn block_centres(k: u32, b: vec2<u32>) -> vec4<f32> {
    var r0 = vec2<f32>(2.0 * f32(b.x) + 0.5, 2.0 * f32(b.y) + 0.5);
    if (!is_identity(k)) {
        r0 = to_frame(k, r0);
    }
    let c = params.axes[k].x;
    let s = params.axes[k].y;
    let ext_lo = vec2<f32>(min(c, 0.0) + min(s, 0.0), min(-s, 0.0) + min(c, 0.0));
    let ext_hi = vec2<f32>(max(c, 0.0) + max(s, 0.0), max(-s, 0.0) + max(c, 0.0));
    return vec4<f32>(r0 + ext_lo, r0 + ext_hi);
}

// bounds::ImageClip::clip_texel: the level-1 texel (lo, hi) of a block whose sample centres lie
// in rq = (lo, hi) as it enters the mipmap; an empty texel stays empty.
fn clip_texel(box: vec4<f32>, rq: vec4<f32>, lo: vec2<f32>, hi: vec2<f32>) -> vec4<f32> {
    if (lo.x > hi.x) {
        return vec4<f32>(lo, hi);
    }
    return vec4<f32>(min(max(lo, box.xy - rq.zw), box.zw - rq.zw), min(max(hi, box.xy - rq.xy), box.zw - rq.xy));
}

// MotionPyramid::from_samples level 1 for layer params.layer, over the samples of
// PreparedLayer::prepare_stack: a sample of layer k > 0 whose source depth equals an earlier
// layer's at the same pixel is left out of the mipmap.
@compute @workgroup_size(8, 8, 1)
fn mip_base(@builtin(global_invocation_id) gid: vec3<u32>) {
    let lv = params.levels[0];
    if (gid.x >= lv.y || gid.y >= lv.z) {
        return;
    }
    let w = params.size.x;
    let h = params.size.y;
    let wh = w * h;
    let k = params.layer;
    var lo = vec2<f32>(params.inf.x);
    var hi = vec2<f32>(params.inf.y);
    var z = params.inf.x;
    for (var dy = 0u; dy < 2u; dy++) {
        let y = gid.y * 2u + dy;
        for (var dx = 0u; dx < 2u; dx++) {
            let x = gid.x * 2u + dx;
            if (x < w && y < h) {
                let i = y * w + x;
                let s = samples[k * wh + i];
                var keep = valid_z(s.z);
                for (var j = 0u; j < k; j++) {
                    if (samples[j * wh + i].w == s.w) {
                        keep = false;
                    }
                }
                if (keep) {
                    var u = s.xy;
                    if (!is_identity(k)) {
                        u = to_frame(k, s.xy);
                    }
                    lo = min(lo, u);
                    hi = max(hi, u);
                    z = min(z, s.z);
                }
            }
        }
    }
    // gradient::GradientMip level 1: the cells whose top-left texel lies in the block (clamped
    // at the right and bottom border).
    var g = vec2<f32>(params.inf.y);
    for (var dy = 0u; dy < 2u; dy++) {
        let y = gid.y * 2u + dy;
        for (var dx = 0u; dx < 2u; dx++) {
            let x = gid.x * 2u + dx;
            if (x < w && y < h) {
                let x1 = min(x + 1u, w - 1u);
                let y1 = min(y + 1u, h - 1u);
                let a = samples[k * wh + y * w + x].xyz;
                let b = samples[k * wh + y * w + x1].xyz;
                let c = samples[k * wh + y1 * w + x].xyz;
                let d = samples[k * wh + y1 * w + x1].xyz;
                if ((params.flags & FLAG_MONOTONE) != 0u) {
                    g = max(g, vec2<f32>(cell_fold(a, b, c, d)));
                } else {
                    g = max(g, cell_gradient(a, b, c, d));
                }
            }
        }
    }
    let o = k * params.level_total + lv.x + gid.y * lv.y + gid.x;
    mip[o] = clip_texel(params.clips[k], block_centres(k, gid.xy), lo, hi);
    zmin[o] = vec4<f32>(z, g, 0.0);
}

// gradient::cell_gradient: the squared norms of the rows of the bilinear fetch's Jacobian over
// the cell a b / c d (motion .xy, target depth .z), +inf where the depths stop the fetch from
// interpolating it.
fn cell_gradient(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>, d: vec3<f32>) -> vec2<f32> {
    let gx = max(abs(b.xy - a.xy), abs(d.xy - c.xy));
    let gy = max(abs(c.xy - a.xy), abs(d.xy - b.xy));
    let z_lo = min(min(a.z, b.z), min(c.z, d.z));
    let z_hi = max(max(a.z, b.z), max(c.z, d.z));
    if ((z_hi - z_lo) < DEPTH_CONTINUITY * (1.0 - z_hi)) {
        return gx * gx + gy * gy;
    }
    return vec2<f32>(params.inf.x);
}

// gradient::cell_fold: a bound of |dvx/dy + dvy/dx| / 2 - min(dvx/dx, dvy/dy) of the bilinear
// fetch over the cell a b / c d (Gershgorin on the symmetric part of I + Dv); at least the
// motion range where the cell is not one surface, +inf where the fetch never interpolates it.
fn cell_fold(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>, d: vec3<f32>) -> f32 {
    // Differences along x (b - a, d - c) and y (c - a, d - b), motion x and y.
    let ex = b.xy - a.xy;
    let fx = d.xy - c.xy;
    let ey = c.xy - a.xy;
    let fy = d.xy - b.xy;
    let shear_lo = min(ey.x, fy.x) + min(ex.y, fx.y);
    let shear_hi = max(ey.x, fy.x) + max(ex.y, fx.y);
    let fold = 0.5 * max(abs(shear_lo), abs(shear_hi)) - min(min(ex.x, fx.x), min(ey.y, fy.y));
    let z_lo = min(min(a.z, b.z), min(c.z, d.z));
    let z_hi = max(max(a.z, b.z), max(c.z, d.z));
    let step = z_hi - z_lo;
    let room = 1.0 - z_hi;
    if (step < SURFACE_DEPTH_STEP * room) {
        return fold;
    }
    if (step < DEPTH_CONTINUITY * room) {
        let range = max(max(a.xy, b.xy), max(c.xy, d.xy)) - min(min(a.xy, b.xy), min(c.xy, d.xy));
        return max(fold, max(range.x, range.y));
    }
    return params.inf.x;
}

// MotionPyramid::from_samples, level params.level from the level below.
@compute @workgroup_size(8, 8, 1)
fn mip_up(@builtin(global_invocation_id) gid: vec3<u32>) {
    let lv = params.levels[params.level - 1u];
    let pv = params.levels[params.level - 2u];
    if (gid.x >= lv.y || gid.y >= lv.z) {
        return;
    }
    let base = params.layer * params.level_total;
    var lo = vec2<f32>(params.inf.x);
    var hi = vec2<f32>(params.inf.y);
    var z = params.inf.x;
    var g = vec2<f32>(params.inf.y);
    for (var dy = 0u; dy < 2u; dy++) {
        let y = gid.y * 2u + dy;
        for (var dx = 0u; dx < 2u; dx++) {
            let x = gid.x * 2u + dx;
            if (x < pv.y && y < pv.z) {
                let o = base + pv.x + y * pv.y + x;
                let t = mip[o];
                lo = min(lo, t.xy);
                hi = max(hi, t.zw);
                z = min(z, zmin[o].x);
                g = max(g, zmin[o].yz);
            }
        }
    }
    let o = base + lv.x + gid.y * lv.y + gid.x;
    mip[o] = vec4<f32>(lo, hi);
    zmin[o] = vec4<f32>(z, g, 0.0);
}

// ---------------------------------------------------------------------------------------
// Bounds (zwarp_warp::bounds) in each layer's BoundFrame.

fn ceil_log2(n: u32) -> u32 {
    if (n <= 1u) {
        return 0u;
    }
    return 32u - countLeadingZeros(n - 1u);
}

struct Range {
    ok: bool,
    r: vec4<u32>,
};

// MotionPyramid::pixel_range.
fn pixel_range(k: u32, rlo: vec2<f32>, rhi: vec2<f32>, expand: f32) -> Range {
    var lo = rlo;
    var hi = rhi;
    if (!is_identity(k)) {
        // Image-space AABB of the rotated box.
        let c0 = from_frame(k, rlo);
        let c1 = from_frame(k, rhi);
        let c2 = from_frame(k, vec2<f32>(rlo.x, rhi.y));
        let c3 = from_frame(k, vec2<f32>(rhi.x, rlo.y));
        lo = min(min(min(c0, c1), c2), c3);
        hi = max(max(max(c0, c1), c2), c3);
    }
    lo -= vec2<f32>(expand);
    hi += vec2<f32>(expand);
    let w = f32(params.size.x);
    let h = f32(params.size.y);
    if (!(hi.x >= 0.0 && hi.y >= 0.0 && lo.x < w && lo.y < h)) {
        return Range(false, vec4<u32>(0u));
    }
    let ix0 = u32(max(lo.x, 0.0));
    let iy0 = u32(max(lo.y, 0.0));
    let ix1 = min(u32(min(hi.x, w - 1.0)), params.size.x - 1u);
    let iy1 = min(u32(min(hi.y, h - 1.0)), params.size.y - 1u);
    return Range(true, vec4<u32>(ix0, iy0, ix1, iy1));
}

// MotionPyramid::level_for_range.
fn level_for_range(r: vec4<u32>) -> u32 {
    let e = max(r.z - r.x, r.w - r.y);
    return clamp(ceil_log2(e), 1u, params.top);
}

// MotionPyramid::lookup_range: union of the texels the range touches at its level.
fn lookup_range(k: u32, r: vec4<u32>) -> vec4<f32> {
    let l = level_for_range(r);
    let lv = params.levels[l - 1u];
    let base = k * params.level_total + lv.x;
    let tx0 = r.x >> l;
    let tx1 = min(r.z >> l, lv.y - 1u);
    let ty0 = r.y >> l;
    let ty1 = min(r.w >> l, lv.z - 1u);
    var b = vec4<f32>(params.inf.x, params.inf.x, params.inf.y, params.inf.y);
    for (var ty = ty0; ty <= ty1; ty++) {
        for (var tx = tx0; tx <= tx1; tx++) {
            let t = mip_ro[base + ty * lv.y + tx];
            b = vec4<f32>(min(b.xy, t.xy), max(b.zw, t.zw));
        }
    }
    return b;
}

// MotionPyramid::lookup_min_depth (.x) and PreparedLayer::lookup_gradient (.yz): the min-depth
// texels the range touches at its level, reduced by min and max.
fn lookup_zmin(k: u32, r: vec4<u32>) -> vec3<f32> {
    let l = level_for_range(r);
    let lv = params.levels[l - 1u];
    let base = k * params.level_total + lv.x;
    let tx0 = r.x >> l;
    let tx1 = min(r.z >> l, lv.y - 1u);
    let ty0 = r.y >> l;
    let ty1 = min(r.w >> l, lv.z - 1u);
    var z = params.inf.x;
    var g = vec2<f32>(params.inf.y);
    for (var ty = ty0; ty <= ty1; ty++) {
        for (var tx = tx0; tx <= tx1; tx++) {
            let t = zmin_ro[base + ty * lv.y + tx];
            z = min(z, t.x);
            g = max(g, t.yz);
        }
    }
    return vec3<f32>(z, g);
}

fn is_empty(b: vec4<f32>) -> bool {
    return !(b.x <= b.z && b.y <= b.w);
}

// Bound::scaled: the bound of motion_scale * v (lo and hi swap per negative factor; empty
// stays empty).
fn scale_bound(b: vec4<f32>) -> vec4<f32> {
    if (is_empty(b)) {
        return vec4<f32>(params.inf.x, params.inf.x, params.inf.y, params.inf.y);
    }
    let s = params.motion_scale;
    let a = s * b.xy;
    let c = s * b.zw;
    let neg = s < vec2<f32>(0.0);
    return vec4<f32>(select(a, c, neg), select(c, a, neg));
}

struct Tight {
    ok: bool,
    // Motion bound (lo.xy, hi.xy) and search region (lo.xy, hi.xy).
    motion: vec4<f32>,
    region: vec4<f32>,
};

fn region_of(c_lo: vec2<f32>, c_hi: vec2<f32>, b: vec4<f32>) -> vec4<f32> {
    return vec4<f32>(c_lo - b.zw, c_hi - b.xy);
}

// MotionPyramid::frame_box: the box of target positions [p_lo, p_hi] in layer k's frame.
fn frame_box(k: u32, p_lo: vec2<f32>, p_hi: vec2<f32>) -> vec4<f32> {
    var c_lo = p_lo;
    var c_hi = p_hi;
    if (!is_identity(k)) {
        if (all(p_lo == p_hi)) {
            c_lo = to_frame(k, p_lo);
            c_hi = c_lo;
        } else {
            let c0 = to_frame(k, p_lo);
            let c1 = to_frame(k, p_hi);
            let c2 = to_frame(k, vec2<f32>(p_lo.x, p_hi.y));
            let c3 = to_frame(k, vec2<f32>(p_hi.x, p_lo.y));
            c_lo = min(min(min(c0, c1), c2), c3);
            c_hi = max(max(max(c0, c1), c2), c3);
        }
    }
    return vec4<f32>(c_lo, c_hi);
}

// Kernel::unique_solution for layer 0's tile bound b over [p_lo, p_hi]
// (PreparedLayer::unique_solution): a bound wider than a pixel, stratified seeds, the adaptive
// fetch, and q + S v(q) monotone on the box's region (FLAG_MONOTONE) or the scaled motion a
// contraction there.
fn unique_solution(p_lo: vec2<f32>, p_hi: vec2<f32>, b: vec4<f32>) -> bool {
    let e = b.zw - b.xy;
    if ((e.x <= 1.0 && e.y <= 1.0) || (params.flags & (FLAG_SEED_PIXEL | FLAG_SEED_OFFSET)) != 0u
        || (params.flags & FLAG_ADAPTIVE) == 0u) {
        return false;
    }
    let c = frame_box(0u, p_lo, p_hi);
    let region = region_of(c.xy, c.zw, b);
    let r = pixel_range(0u, region.xy, region.zw, 0.5);
    if (!r.ok) {
        return false;
    }
    let g = lookup_zmin(0u, r.r).yz;
    let s = params.motion_scale;
    if ((params.flags & FLAG_MONOTONE) != 0u) {
        return s.x > 0.0 && s.y > 0.0 && max(s.x, s.y) * g.x < 1.0;
    }
    return s.x * s.x * g.x + s.y * s.y * g.y < UNIQUE_GRADIENT;
}

// MotionPyramid::tight_bound_box (Fig. 5): tightening from `start` for the box of target
// positions [c_lo, c_hi], stopping at the fixed point.
fn tight_bound_box(k: u32, p_lo: vec2<f32>, p_hi: vec2<f32>, start: vec4<f32>, iterations: u32, expand: f32) -> Tight {
    var b = start;
    let none = Tight(false, vec4<f32>(0.0), vec4<f32>(0.0));
    if (is_empty(b)) {
        return none;
    }
    let c = frame_box(k, p_lo, p_hi);
    let c_lo = c.xy;
    let c_hi = c.zw;
    var region = region_of(c_lo, c_hi, b);
    var range = pixel_range(k, region.xy, region.zw, expand);
    if (!range.ok) {
        return none;
    }
    for (var i = 0u; i < iterations; i++) {
        let m = scale_bound(lookup_range(k, range.r));
        let nb = vec4<f32>(max(b.xy, m.xy), min(b.zw, m.zw));
        if (is_empty(nb)) {
            return none;
        }
        if (all(nb == b)) {
            break;
        }
        b = nb;
        region = region_of(c_lo, c_hi, b);
        range = pixel_range(k, region.xy, region.zw, expand);
        if (!range.ok) {
            return none;
        }
    }
    return Tight(true, b, region);
}

// ---------------------------------------------------------------------------------------
// Sampling (zwarp_warp::sampling::LayerSampler::fetch and depth_warp::StackSampler).

struct Smp {
    ok: bool,
    v: vec2<f32>,
    depth: f32,
    tag: u32,
    dvdx: vec2<f32>,
    dvdy: vec2<f32>,
    // A bilinear sample of a smooth neighbourhood (Sample::smooth).
    bilinear: bool,
};

// One texel with its motion scaled by motion_scale (LayerSampler::with_scale).
fn at(k: u32, x: u32, y: u32) -> vec4<f32> {
    let t = samples[k * params.size.x * params.size.y + y * params.size.x + x];
    return vec4<f32>(params.motion_scale * t.xy, t.zw);
}

// glam's Vec2::lerp: a * (1 - s) + b * s.
fn lerp2(a: vec2<f32>, b: vec2<f32>, s: f32) -> vec2<f32> {
    return a * (1.0 - s) + b * s;
}

fn fetch(k: u32, q: vec2<f32>) -> Smp {
    let wm = params.size.x - 1u;
    let hm = params.size.y - 1u;
    let xn = min(u32(q.x), wm);
    let yn = min(u32(q.y), hm);
    let zero = vec2<f32>(0.0);
    if ((params.flags & FLAG_ADAPTIVE) != 0u) {
        let tx = q.x + 0.5;
        let ty = q.y + 0.5;
        let ix = u32(tx);
        let iy = u32(ty);
        let ax = tx - f32(ix);
        let ay = ty - f32(iy);
        let x0 = min(select(ix - 1u, 0u, ix == 0u), wm);
        let y0 = min(select(iy - 1u, 0u, iy == 0u), hm);
        let x1 = min(ix, wm);
        let y1 = min(iy, hm);
        let s00 = at(k, x0, y0);
        let s10 = at(k, x1, y0);
        let s01 = at(k, x0, y1);
        let s11 = at(k, x1, y1);
        if (valid_z(s00.z) && valid_z(s10.z) && valid_z(s01.z) && valid_z(s11.z)) {
            let lo = min(min(s00.xy, s10.xy), min(s01.xy, s11.xy));
            let hi = max(max(s00.xy, s10.xy), max(s01.xy, s11.xy));
            let d = hi - lo;
            // sampling::continuous_cell: motions within a pixel or one surface (a small relative
            // depth step), and no large relative depth step.
            let z_lo = min(min(s00.z, s10.z), min(s01.z, s11.z));
            let z_hi = max(max(s00.z, s10.z), max(s01.z, s11.z));
            let step = z_hi - z_lo;
            let room = 1.0 - z_hi;
            if ((max(d.x, d.y) < CONTINUITY || step < SURFACE_DEPTH_STEP * room) && step < DEPTH_CONTINUITY * room) {
                let top_v = lerp2(s00.xy, s10.xy, ax);
                let bot_v = lerp2(s01.xy, s11.xy, ax);
                let top_d = s00.z + (s10.z - s00.z) * ax;
                let bot_d = s01.z + (s11.z - s01.z) * ax;
                let dvdx = lerp2(s10.xy - s00.xy, s11.xy - s01.xy, ay);
                let dvdy = bot_v - top_v;
                return Smp(true, lerp2(top_v, bot_v, ay), top_d + (bot_d - top_d) * ay, k, dvdx, dvdy, true);
            }
        }
    }
    let m = at(k, xn, yn);
    return Smp(valid_z(m.z), m.xy, m.z, k, zero, zero, false);
}

fn inside(q: vec2<f32>) -> bool {
    return q.x >= 0.0 && q.y >= 0.0 && q.x < f32(params.size.x) && q.y < f32(params.size.y);
}

// Kernel::continuation_covers: the front surface f at candidate c's source position, continued
// with its motion Jacobian to the point that lands on p, may still be there (a front layer sees
// f's depth at that point, or all see nearer): c, behind f, is hidden.
fn continuation_covers(c: Cand, f: Smp, p: vec2<f32>, max_q: vec2<f32>) -> bool {
    if (!(params.cover2 > 0.0 && (1.0 - c.depth) * COVER_DEPTH_RATIO < 1.0 - f.depth)) {
        return false;
    }
    let a = 1.0 + f.dvdx.x;
    let b = f.dvdy.x;
    let e = f.dvdx.y;
    let d = 1.0 + f.dvdy.y;
    let det = a * d - b * e;
    if (!(det > CONTINUATION_MIN_DET)) {
        return false;
    }
    let r = p - (c.q + f.v);
    // Beyond the border: judged at the border texel nearest to it (Kernel::max_q).
    let q = clamp(c.q + vec2<f32>(d * r.x - b * r.y, a * r.y - e * r.x) / det, vec2<f32>(0.0), max_q);
    var all_near = true;
    for (var i = 0u; i < min(c.tag, params.layers); i++) {
        let g = fetch(i, q);
        let near = g.ok && !((1.0 - g.depth) * COVER_DEPTH_RATIO < 1.0 - f.depth);
        if (near && !((1.0 - f.depth) * COVER_DEPTH_RATIO < 1.0 - g.depth)) {
            return true;
        }
        all_near = all_near && near;
    }
    return all_near;
}

// StackSampler::sample (Fig. 6): an empty landing in layer k > 0 borrows the nearest
// non-empty layer above once (under the adaptive fetch only a bilinear sample); the second empty
// landing fails the seed.
fn stack_sample(k: u32, q: vec2<f32>, empties: ptr<function, u32>) -> Smp {
    let none = Smp(false, vec2<f32>(0.0), 0.0, 0u, vec2<f32>(0.0), vec2<f32>(0.0), false);
    if (!inside(q)) {
        return none;
    }
    let own = fetch(k, q);
    if (own.ok) {
        return own;
    }
    if ((params.flags & FLAG_CROSS) == 0u || k == 0u) {
        return none;
    }
    *empties += 1u;
    if (*empties >= 2u) {
        return none;
    }
    for (var j = i32(k) - 1; j >= 0; j--) {
        let s = fetch(u32(j), q);
        if (s.ok) {
            if (s.bilinear || (params.flags & FLAG_ADAPTIVE) == 0u) {
                return s;
            }
            return none;
        }
    }
    return none;
}

// ---------------------------------------------------------------------------------------
// Seeds (search::hash_u32, seed_key, effective_seeds, stratified_seeds).

fn hash_u32(v: u32) -> u32 {
    let state = v * 747796405u + 2891336453u;
    let word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

fn seed_key(x: u32, y: u32, layer: u32) -> u32 {
    return hash_u32(x ^ hash_u32(y ^ hash_u32(layer)));
}

fn effective_seeds(n: u32, e: vec2<f32>) -> u32 {
    if (e.x <= 1.0 && e.y <= 1.0) {
        return 1u;
    }
    let area = ceil((e.x + 1.0) * (e.y + 1.0));
    if (area < f32(n)) {
        return u32(area);
    }
    return n;
}

// Seed i of stratified_seeds(frame of layer k, region, n, key), in image coordinates.
fn stratified_seed(k: u32, i: u32, n: u32, region: vec4<f32>, key: u32) -> vec2<f32> {
    let u = stratified_seed_frame(i, n, region, key);
    if (n == 1u || !is_identity(k)) {
        return from_frame(k, u);
    }
    return u;
}

// The seed in frame coordinates.
fn stratified_seed_frame(i: u32, n: u32, region: vec4<f32>, key: u32) -> vec2<f32> {
    let lo = region.xy;
    let hi = region.zw;
    let e = hi - lo;
    if (n == 1u) {
        return lo + 0.5 * e;
    }
    var distinct = 2u;
    if (e.x > 0.0 && e.y > 0.0) {
        distinct = 4u;
    } else if (!(e.x > 0.0) && !(e.y > 0.0)) {
        distinct = 1u;
    }
    let nc = min(n / 2u, distinct);
    if (i < nc) {
        switch i {
            case 0u: { return lo; }
            case 1u: { return hi; }
            case 2u: { return vec2<f32>(lo.x, hi.y); }
            default: { return vec2<f32>(hi.x, lo.y); }
        }
    }
    let r = vec2<f32>(f32(key & 0xffffu) / 65536.0, f32(key >> 16u) / 65536.0);
    let s = fract(r + R2 * f32(i - nc));
    return lo + s * e;
}

// ---------------------------------------------------------------------------------------
// The warp (depth_warp::Kernel::pixel + search::fixed_point_search).

struct Cand {
    ok: bool,
    q: vec2<f32>,
    depth: f32,
    tag: u32,
};

// The seeds of layer k for pixel (x, y) at p (Kernel::search_layer: ns stratified seeds in
// region, plus the cross-layer seed prev_q as seed n - 1 where cross_seed) and
// search::fixed_point_search_closest over them.
struct Found {
    found: Cand,
    // The smallest squared residual of a smooth sampled iterate and that sample's depth.
    closest: f32,
    closest_z: f32,
    // The largest depth of any sample of the walks after their first step (-inf if none):
    // search::Approach::farthest.
    farthest: f32,
    // search::Approach::straddle (+inf if none).
    straddle: f32,
};

// search::straddles: two consecutive smooth samples (residuals a, b; depths za, zb) landing on
// opposite sides of p less than STRADDLE_SPAN apart, at depths within STRADDLE_DEPTH_RATIO.
fn straddles(a: vec2<f32>, za: f32, b: vec2<f32>, zb: f32) -> bool {
    let lo = min(za, zb);
    let hi = max(za, zb);
    let d = a - b;
    return dot(a, b) < 0.0 && dot(d, d) < STRADDLE_SPAN * STRADDLE_SPAN
        && 1.0 - lo < STRADDLE_DEPTH_RATIO * (1.0 - hi);
}

fn search_seeds(k: u32, x: u32, y: u32, p: vec2<f32>, region: vec4<f32>, ns: u32, n: u32, cross_seed: bool,
                prev_q: vec2<f32>, max_q: vec2<f32>, thr2: f32) -> Found {
    let key = seed_key(x, y, k);
    var found = Cand(false, vec2<f32>(0.0), 0.0, 0u);
    // search::fixed_point_search_closest: the smallest squared residual of a smooth sampled
    // iterate and that sample's depth.
    var closest = params.inf.x;
    var closest_z = params.inf.x;
    var farthest = params.inf.y;
    var straddle = params.inf.x;
    for (var i = 0u; i < n; i++) {
        var seed: vec2<f32>;
        if (cross_seed && i == n - 1u) {
            seed = prev_q;
        } else if ((params.flags & FLAG_SEED_PIXEL) != 0u) {
            seed = p;
        } else if ((params.flags & FLAG_SEED_OFFSET) != 0u) {
            seed = p + params.seed_offset;
        } else {
            seed = stratified_seed(k, i, ns, region, key);
        }
        var q = clamp(seed, vec2<f32>(0.0), max_q);
        var empties = 0u;
        var done = false;
        // The previous iterate's smooth sample and the last two samples' straddle depth.
        var prev_ok = false;
        var prev_step = vec2<f32>(0.0);
        var prev_z = 0.0;
        var pair = params.inf.x;
        // The squared step of the previous smooth sample (0: none), for the extra iterations.
        var last_r2 = 0.0;
        for (var it = 0u; it < params.iterations + params.extra_iterations; it++) {
            pair = params.inf.x;
            let s = stack_sample(k, q, &empties);
            if (!s.ok) {
                break;
            }
            let wv = p - s.v;
            let step = wv - q;
            let r2 = dot(step, step);
            if (s.bilinear && r2 < closest) {
                closest = r2;
                closest_z = s.depth;
            }
            if (s.bilinear) {
                if (prev_ok && straddles(prev_step, prev_z, step, s.depth)) {
                    pair = min(prev_z, s.depth);
                }
                prev_ok = true;
                prev_step = step;
                prev_z = s.depth;
            } else {
                prev_ok = false;
            }
            if (it > 0u) {
                farthest = max(farthest, s.depth);
            }
            var next = wv;
            if ((params.flags & FLAG_ACCEL) != 0u) {
                let m00 = 1.0 + s.dvdx.x;
                let m01 = s.dvdy.x;
                let m10 = s.dvdx.y;
                let m11 = 1.0 + s.dvdy.y;
                let det = m00 * m11 - m01 * m10;
                if (abs(det) > 0.05) {
                    next = q + vec2<f32>(m11 * step.x - m01 * step.y, -m10 * step.x + m00 * step.y) / det;
                }
            }
            if (r2 < thr2) {
                // search::fixed_point_search: the sample at q, no polishing sample.
                let c = Cand(true, q, s.depth, s.tag);
                if (!found.ok || c.depth < found.depth) {
                    found = c;
                }
                done = true;
                break;
            }
            // search::EXTRA_STEP_RATIO: after T only a walk whose smooth step at least halved
            // goes on.
            if (it + 1u >= params.iterations && (!s.bilinear || r2 >= 0.25 * last_r2)) {
                break;
            }
            last_r2 = select(0.0, r2, s.bilinear);
            q = next;
        }
        if (!done) {
            straddle = min(straddle, pair);
        }
        if (done && (params.flags & FLAG_FIRST) != 0u) {
            break;
        }
    }
    return Found(found, closest, closest_z, farthest, straddle);
}

// The CPU's 4x4 tile stage (depth_warp::Kernel::band): the 8x8 workgroup holds 4 tiles; one
// invocation per (tile, layer) tightens the tile's bound, the pixels then start from it.
var<workgroup> tile_motion: array<vec4<f32>, 32>;
var<workgroup> tile_ok: array<u32, 32>;
// Layers k > 0: min target depth over the tile's search region (Kernel::tile_bounds).
var<workgroup> tile_zmin: array<f32, 32>;
// Layer 0: StageBound::unique (Kernel::unique_solution).
var<workgroup> tile_unique: array<u32, 32>;

@compute @workgroup_size(8, 8, 1)
fn warp(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_id) lid: vec3<u32>, @builtin(workgroup_id) wid: vec3<u32>) {
    // Source size (clamping) and target size (pixels, tiles).
    let w = params.size.x;
    let h = params.size.y;
    let tw = params.target_size.x;
    let th = params.target_size.y;
    let ms = params.multisample;
    let expand = params.expand;
    let iters = params.bound_iterations;
    let task = lid.y * 8u + lid.x;
    if (task < 4u * params.layers) {
        let t = task % 4u;
        let kt = task / 4u;
        let tx0 = wid.x * 8u + 4u * (t % 2u);
        let ty0 = wid.y * 8u + 4u * (t / 2u);
        var ok = 0u;
        var motion = vec4<f32>(0.0);
        var tz = params.inf.y;
        var unique = 0u;
        if (tx0 < tw && ty0 < th) {
            let tx1 = min(tx0 + 4u, tw) - 1u;
            let ty1 = min(ty0 + 4u, th) - 1u;
            // depth_warp::Kernel::target_pos of the tile's corner pixels.
            let p_lo = vec2<f32>(f32(tx0) + 0.5, f32(ty0) + 0.5) * ms;
            let p_hi = vec2<f32>(f32(tx1) + 0.5, f32(ty1) + 0.5) * ms;
            let top = params.levels[params.top - 1u];
            let gb = scale_bound(mip_ro[kt * params.level_total + top.x]);
            let tile = tight_bound_box(kt, p_lo, p_hi, gb, iters, expand);
            ok = select(0u, 1u, tile.ok);
            motion = tile.motion;
            if (tile.ok && kt == 0u && unique_solution(p_lo, p_hi, tile.motion)) {
                unique = 1u;
            }
            if (tile.ok && kt > 0u) {
                // tight_bound_box_with_depth: the final region's range always exists here.
                let r = pixel_range(kt, tile.region.xy, tile.region.zw, expand);
                tz = lookup_zmin(kt, r.r).x;
            }
        }
        tile_ok[task] = ok;
        tile_motion[task] = motion;
        tile_zmin[task] = tz;
        tile_unique[task] = unique;
    }
    workgroupBarrier();
    let x = gid.x;
    let y = gid.y;
    if (x >= tw || y >= th) {
        return;
    }
    let tile_index = (lid.x / 4u) + 2u * (lid.y / 4u);
    // depth_warp::Kernel::target_pos: the target pixel's centre in source samples (exact).
    let p = vec2<f32>(f32(x) + 0.5, f32(y) + 0.5) * ms;
    let max_q = vec2<f32>(f32(w), f32(h)) * (1.0 - EPS) - vec2<f32>(1e-3);
    let thr2 = params.threshold * params.threshold;

    var best = Cand(false, vec2<f32>(0.0), 0.0, 0u);
    // AWOC: the frame (layer) and tight region of the first layer that reaches the search.
    var awoc_ok = false;
    var awoc_k = 0u;
    var awoc_region = vec4<f32>(0.0);
    var has_prev = false;
    var prev_q = vec2<f32>(0.0);
    // depth_warp::Kernel::pixel_from: the nearest depth of a layer that, before any candidate,
    // failed with a walk within the coverage radius of p.
    var cover = params.inf.x;
    // The farthest sample of the failed walks of the layers searched before any candidate
    // (Kernel::behind_ground_disocclusion).
    var farthest = params.inf.y;
    for (var k = 0u; k < params.layers; k++) {
        if (tile_ok[k * 4u + tile_index] == 0u) {
            continue;
        }
        let start = tile_motion[k * 4u + tile_index];
        let e = start.zw - start.xy;
        if (tile_unique[k * 4u + tile_index] != 0u && !best.ok) {
            // Kernel::pixel_from: one solution at most in the region under the tile's bound;
            // one seed at its centre, the complete search below where it fails.
            var c = p;
            if (!is_identity(k)) {
                c = to_frame(k, p);
            }
            let one = search_seeds(k, x, y, p, region_of(c, c, start), 1u, 1u, false, prev_q, max_q, thr2);
            if (one.found.ok) {
                has_prev = true;
                prev_q = one.found.q;
                best = one.found;
                continue;
            }
        }
        var tb: Tight;
        if (e.x <= 1.0 && e.y <= 1.0 && !best.ok) {
            var c = p;
            if (!is_identity(k)) {
                c = to_frame(k, p);
            }
            tb = Tight(true, start, region_of(c, c, start));
        } else if (k > 0u && best.ok) {
            // Nothing in the whole tile's region is nearer than the best: skip the layer.
            if (tile_zmin[k * 4u + tile_index] >= best.depth) {
                continue;
            }
            tb = tight_bound_box(k, p, p, start, iters, expand);
            if (!tb.ok) {
                continue;
            }
            let r = pixel_range(k, tb.region.xy, tb.region.zw, expand);
            if (!r.ok) {
                continue;
            }
            if (lookup_zmin(k, r.r).x >= best.depth) {
                continue;
            }
        } else {
            tb = tight_bound_box(k, p, p, start, iters, expand);
            if (!tb.ok) {
                continue;
            }
        }
        if ((params.flags & FLAG_AWOC) != 0u && !awoc_ok) {
            awoc_ok = true;
            awoc_k = k;
            awoc_region = tb.region;
        }
        // Seeds.
        var ns = 1u;
        if ((params.flags & (FLAG_SEED_PIXEL | FLAG_SEED_OFFSET)) == 0u) {
            ns = effective_seeds(params.n_seeds, tb.region.zw - tb.region.xy);
        }
        var n = ns;
        var cross_seed = false;
        if ((params.flags & FLAG_CROSS) != 0u && has_prev) {
            let u = to_frame(k, prev_q);
            if (u.x >= tb.region.x && u.x <= tb.region.z && u.y >= tb.region.y && u.y <= tb.region.w) {
                if (n < params.n_seeds) {
                    n += 1u;
                }
                cross_seed = true;
            }
        }
        let sr = search_seeds(k, x, y, p, tb.region, ns, n, cross_seed, prev_q, max_q, thr2);
        let found = sr.found;
        let closest = sr.closest;
        let closest_z = sr.closest_z;
        if (found.ok) {
            has_prev = true;
            prev_q = found.q;
            if (!best.ok || found.depth < best.depth) {
                best = found;
            }
        } else if (!best.ok) {
            // Covered without a candidate: a walk within the coverage radius, or one that cycled
            // across p on one surface (search::Approach::straddle).
            if (closest < params.cover2) {
                cover = min(cover, closest_z);
            }
            cover = min(cover, sr.straddle);
            farthest = max(farthest, sr.farthest);
        }
    }
    // zwarp_warp::hidden_behind: a deeper layer's candidate behind a covering front surface.
    if (best.ok && (1.0 - best.depth) * COVER_DEPTH_RATIO < 1.0 - cover) {
        best.ok = false;
    }
    // depth_warp::Kernel::retry_front: a deeper candidate behind the far side of the front
    // layers' failed walks, or with no such walk sample at all (farthest = -inf: then a front
    // candidate must be nearer too); the front layers search again with RETRY_SEED_FACTOR
    // times N seeds from their tightened bound, and the nearest front candidate found
    // replaces it.
    if (best.ok && best.tag > 0u && (farthest == params.inf.y
        || (1.0 - best.depth) * COVER_DEPTH_RATIO < 1.0 - farthest)) {
        let n_retry = min(params.n_seeds * RETRY_SEED_FACTOR, MAX_SEEDS);
        var front = Cand(false, vec2<f32>(0.0), 0.0, 0u);
        for (var k = 0u; k < min(best.tag, params.layers); k++) {
            if (tile_ok[k * 4u + tile_index] == 0u) {
                continue;
            }
            let tb = tight_bound_box(k, p, p, tile_motion[k * 4u + tile_index], iters, expand);
            if (!tb.ok) {
                continue;
            }
            var ns = 1u;
            if ((params.flags & (FLAG_SEED_PIXEL | FLAG_SEED_OFFSET)) == 0u) {
                ns = effective_seeds(n_retry, tb.region.zw - tb.region.xy);
            }
            let sr = search_seeds(k, x, y, p, tb.region, ns, ns, false, prev_q, max_q, thr2);
            if (sr.found.ok && (!front.ok || sr.found.depth < front.depth)
                && (farthest != params.inf.y || sr.found.depth < best.depth)) {
                front = sr.found;
            }
        }
        if (front.ok) {
            best = front;
        }
    }
    // depth_warp::Kernel::covered_at_source: a front layer's surface at the candidate's own
    // source position lands within the coverage radius of p, or does one fixed-point step from
    // there (its sample or a texel of the cell around that position), and hides the candidate.
    if (best.ok) {
        let hidden_z = (1.0 - best.depth) * COVER_DEPTH_RATIO;
        for (var j = 0u; j < min(best.tag, params.layers); j++) {
            let s = fetch(j, best.q);
            if (!s.ok) {
                continue;
            }
            let d = (best.q + s.v) - p;
            if (d.x * d.x + d.y * d.y < params.cover2 && hidden_z < 1.0 - s.depth) {
                best.ok = false;
                break;
            }
            if (continuation_covers(best, s, p, max_q)) {
                best.ok = false;
                break;
            }
            let q2 = p - s.v;
            if (inside(q2)) {
                // LayerSampler::cell_texels: the texels of the cell the fetch reads at q2.
                let ix = u32(q2.x + 0.5);
                let iy = u32(q2.y + 0.5);
                let cx = vec2<u32>(min(max(ix, 1u) - 1u, params.size.x - 1u), min(ix, params.size.x - 1u));
                let cy = vec2<u32>(min(max(iy, 1u) - 1u, params.size.y - 1u), min(iy, params.size.y - 1u));
                for (var i = 0u; i < min(best.tag, params.layers); i++) {
                    let g = fetch(i, q2);
                    let d2 = (q2 + g.v) - p;
                    if (g.ok && d2.x * d2.x + d2.y * d2.y < params.cover2 && hidden_z < 1.0 - g.depth) {
                        best.ok = false;
                    }
                    for (var c = 0u; c < 4u; c++) {
                        let tx = cx[c & 1u];
                        let ty = cy[c >> 1u];
                        let t = at(i, tx, ty);
                        let d3 = (vec2<f32>(f32(tx) + 0.5, f32(ty) + 0.5) + t.xy) - p;
                        if (valid_z(t.z) && d3.x * d3.x + d3.y * d3.y < params.cover2 && hidden_z < 1.0 - t.z) {
                            best.ok = false;
                        }
                    }
                }
                if (!best.ok) {
                    break;
                }
            }
        }
    }
    // Kernel::behind_ground_disocclusion: a ground layer's candidate behind the farthest sample
    // of the failed walks before it.
    if (best.ok && (params.flags & FLAG_GROUND) != 0u && best.tag + 1u == params.layers && farthest > params.inf.y
        && (1.0 - best.depth) * COVER_DEPTH_RATIO < 1.0 - farthest) {
        best.ok = false;
    }
    let i = y * tw + x;
    if (best.ok) {
        out_depth[i] = best.depth;
        // WarpOutput::revealed: converged on a deeper layer.
        out_state[i] = select(0u, 3u, best.tag > 0u);
        return;
    }
    out_depth[i] = 1.0;
    out_state[i] = 2u;
    if (awoc_ok) {
        // depth_warp::Kernel::pixel + holes::awoc_depth: the nearest valid sample over all
        // layers at the four region corners (frame -> image, clamped into the image).
        var fill = 1.0;
        for (var c = 0u; c < 4u; c++) {
            var u = awoc_region.xy;
            if (c == 1u) {
                u = vec2<f32>(awoc_region.z, awoc_region.y);
            } else if (c == 2u) {
                u = vec2<f32>(awoc_region.x, awoc_region.w);
            } else if (c == 3u) {
                u = awoc_region.zw;
            }
            let q = clamp(from_frame(awoc_k, u), vec2<f32>(0.0), max_q);
            for (var j = 0u; j < params.layers; j++) {
                let s = fetch(j, q);
                if (s.ok) {
                    fill = min(fill, s.depth);
                }
            }
        }
        if (fill < 1.0) {
            out_depth[i] = fill;
            out_state[i] = 1u;
        }
    }
}

// holes::fill_holes. Fig. 8 (FillRule::Nearest): a hole with a converged pixel within the radius
// on both sides along all four directions takes the depth of the nearest one (ties: the farther
// depth). FLAG_BACKGROUND (FillRule::Background): a hole bracketed along at least one direction
// takes the far sides of the directions bracketed within BRACKET_SPAN_RATIO times the narrowest
// bracket, averaged over those within FAR_SIDE_SPREAD of the farthest. On the target grid.
@compute @workgroup_size(8, 8, 1)
fn dilate(@builtin(global_invocation_id) gid: vec3<u32>) {
    let w = params.target_size.x;
    let h = params.target_size.y;
    if (gid.x >= w || gid.y >= h) {
        return;
    }
    let i = gid.y * w + gid.x;
    fill_depth[i] = out_depth[i];
    fill_state[i] = out_state[i];
    if (out_state[i] != 2u) {
        return;
    }
    let background = (params.flags & FLAG_BACKGROUND) != 0u;
    let r = i32(params.radius);
    var best_ok = false;
    var best_d = 0.0;
    var best_z = 0.0;
    // FillRule::Background: per direction the bracket's span (-1: not bracketed) and farther
    // side, and the narrowest span.
    var bg_span = array<f32, 4>(-1.0, -1.0, -1.0, -1.0);
    var bg_far = array<f32, 4>(0.0, 0.0, 0.0, 0.0);
    var bg_far_d = array<f32, 4>(0.0, 0.0, 0.0, 0.0);
    var bg_min = -1.0;
    for (var dir = 0; dir < 4; dir++) {
        var dx = 1;
        var dy = 0;
        if (dir == 1) {
            dx = 0;
            dy = 1;
        } else if (dir == 2) {
            dy = 1;
        } else if (dir == 3) {
            dy = -1;
        }
        var step = 1.0;
        if (dx != 0 && dy != 0) {
            step = 1.4142135;
        }
        var hits = 0;
        var span = 0.0;
        var side_z = 0.0;
        var side_d = 0.0;
        for (var side = 0; side < 2; side++) {
            let sx = select(-dx, dx, side == 0);
            let sy = select(-dy, dy, side == 0);
            var hit = false;
            for (var kk = 1; kk <= r; kk++) {
                let xx = i32(gid.x) + sx * kk;
                let yy = i32(gid.y) + sy * kk;
                if (xx < 0 || yy < 0 || xx >= i32(w) || yy >= i32(h)) {
                    break;
                }
                let j = u32(yy) * w + u32(xx);
                if (is_converged(out_state[j])) {
                    let d = f32(kk) * step;
                    let z = out_depth[j];
                    if (!(best_ok && (best_d < d || (best_d == d && best_z >= z)))) {
                        best_ok = true;
                        best_d = d;
                        best_z = z;
                    }
                    span += f32(kk);
                    // The far side (ties: the + side, as holes::hole_fill) and its distance.
                    side_d = select(d, side_d, side == 1 && z <= side_z);
                    side_z = select(z, max(side_z, z), side == 1);
                    hit = true;
                    break;
                }
            }
            if (hit) {
                hits++;
            } else if (!background) {
                return;
            }
        }
        if (hits == 2) {
            let sp = span * step;
            bg_span[dir] = sp;
            bg_far[dir] = side_z;
            bg_far_d[dir] = side_d;
            bg_min = select(sp, min(bg_min, sp), bg_min >= 0.0);
        }
    }
    if (background) {
        // fill_rule.wgsl (holes::hole_fill).
        let f = far_sides(bg_span, bg_far, bg_far_d, bg_min);
        if (f.y > 0.0) {
            fill_depth[i] = f.x;
            fill_state[i] = 1u;
        }
    } else if (best_ok) {
        fill_depth[i] = best_z;
        fill_state[i] = 1u;
    }
}
