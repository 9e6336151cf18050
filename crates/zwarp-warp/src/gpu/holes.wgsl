// Hole filling of a warped depth buffer as a post-pass (seed 000 Sec. 3.5, Fig. 8; Sec. 4's
// background fill): the WGSL twin of zwarp_warp::fill_holes with FillRule::Nearest
// (HolePolicy::Dilate, zwarp_warp::dilate_holes) and FillRule::Background (`fill`), and of
// zwarp_warp::holes::fill_background: the measurements of the source layers (`surfaces`,
// `limits`: the empty-background mask and BackgroundLimits), holes that see the source's empty
// background (`sky`), bracketed holes and strips open to the image border (`fill_measured` with
// rule 1 and 2, radius and reach from `limits`), after the lone revealed pixels became holes
// (`lone`). Only converged pixels are read by the fills,
// so one pass over a copy gives the CPU's order-independent result; `sky` reads only its own
// pixel and runs in place. Host code: holes.rs.

struct Params {
    width: u32,
    height: u32,
    radius: u32,
    // `fill`: 0 = Nearest (Fig. 8 dilation), 1 = Background, 2 = border strips.
    rule: u32,
    // `sky`: the fixed-point search's T, threshold and Newton flag (zwarp_warp::SearchParams).
    iterations: u32,
    threshold: f32,
    // rule 2: BackgroundLimits::reach.
    reach: u32,
    accelerate: u32,
    // `sky`: the source layers' size (multisample * (width, height)) and the samples per pixel
    // and axis as a float (zwarp_warp::WarpParams::multisample).
    src_width: u32,
    src_height: u32,
    multisample: f32,
    // `surfaces`: the index of the source layer measured (0 starts the empty mask).
    layer: u32,
};

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> in_depth: array<f32>;
@group(0) @binding(2) var<storage, read> in_state: array<u32>;
@group(0) @binding(3) var<storage, read_write> out_depth: array<f32>;
@group(0) @binding(4) var<storage, read_write> out_state: array<u32>;
// Per source sample, 1 where no source layer has a surface: written by `surfaces`, read by `sky`
// (writer and reader declared apart, so `sky` binds it read-only).
@group(0) @binding(5) var<storage, read> empty: array<u32>;
@group(0) @binding(5) var<storage, read_write> empty_out: array<u32>;
// A source layer's motion in the byte layout of zwarp_core::Motion (v.x, v.y, target depth per
// sample): layer 0's for `sky`, the measured layer's for `surfaces`.
@group(0) @binding(6) var<storage, read> motion: array<f32>;
// `surfaces`: the measured layer's source depth.
@group(0) @binding(7) var<storage, read> layer_depth: array<f32>;
// The measurements (zwarp_warp::holes::BackgroundLimits): 0, 1: the smallest surface motion
// (x, y) as complemented order keys; 2, 3: the largest as order keys (0 = no surface yet, the
// host clears the buffer); 4: bracket; 5: reach. `surfaces` and `limits` write it, the fills
// read it.
@group(0) @binding(8) var<storage, read_write> range: array<atomic<u32>, 8>;
@group(0) @binding(8) var<storage, read> measured: array<u32, 8>;

const CONVERGED: u32 = 0u;
const FILLED: u32 = 1u;
const HOLE: u32 = 2u;
// Converged on a layer after the first (zwarp_warp::WarpOutput::revealed), as the warp writes it
// (fill_rule.wgsl's is_converged takes both).
const REVEALED: u32 = 3u;

// Horizontal, vertical, both diagonals (zwarp_warp::FILL_DIRECTIONS), each probed both ways.
const DIRS = array<vec2<i32>, 4>(vec2<i32>(1, 0), vec2<i32>(0, 1), vec2<i32>(1, 1), vec2<i32>(1, -1));

// Nearest converged pixel from (x, y) along (dx, dy) within the radius: (k, depth), k = 0 if
// none (the image edge or the radius ends the probe).
fn probe(x: i32, y: i32, dx: i32, dy: i32, radius: u32) -> vec2<f32> {
    let w = i32(params.width);
    let h = i32(params.height);
    for (var k = 1; k <= i32(radius); k++) {
        let xx = x + dx * k;
        let yy = y + dy * k;
        if (xx < 0 || yy < 0 || xx >= w || yy >= h) {
            return vec2<f32>(0.0, 0.0);
        }
        let i = u32(yy * w + xx);
        if (is_converged(in_state[i])) {
            return vec2<f32>(f32(k), in_depth[i]);
        }
    }
    return vec2<f32>(0.0, 0.0);
}

// Fig. 8 dilation (FillRule::Nearest) at hole (x, y): (depth, 1) when surrounded along all
// four directions, the nearest neighbour winning (ties: the farther depth); (0, 0) otherwise.
fn nearest_fill(x: i32, y: i32, radius: u32) -> vec2<f32> {
    var best_d = -1.0;
    var best_z = 0.0;
    for (var j = 0; j < 4; j++) {
        let dir = DIRS[j];
        let step = select(1.0, 1.4142135, dir.x != 0 && dir.y != 0);
        let a = probe(x, y, dir.x, dir.y, radius);
        let b = probe(x, y, -dir.x, -dir.y, radius);
        if (a.x == 0.0 || b.x == 0.0) {
            return vec2<f32>(0.0, 0.0);
        }
        for (var e = 0; e < 2; e++) {
            let p = select(a, b, e == 1);
            let dist = p.x * step;
            let keep = best_d >= 0.0 && (best_d < dist || (best_d == dist && best_z >= p.y));
            if (!keep) {
                best_d = dist;
                best_z = p.y;
            }
        }
    }
    return vec2<f32>(best_z, select(0.0, 1.0, best_d >= 0.0));
}

// Sec. 4 background fill (FillRule::Background) at hole (x, y): (depth, 1) when bracketed along
// at least one direction, the far sides of the directions bracketed within BRACKET_SPAN_RATIO
// times the narrowest bracket averaged over those within FAR_SIDE_SPREAD of the farthest
// (inverse-distance weights); (0, 0) otherwise.
fn background_fill(x: i32, y: i32, radius: u32) -> vec2<f32> {
    var span = array<f32, 4>(-1.0, -1.0, -1.0, -1.0);
    var far = array<f32, 4>(0.0, 0.0, 0.0, 0.0);
    var far_d = array<f32, 4>(0.0, 0.0, 0.0, 0.0);
    var narrowest = -1.0;
    for (var j = 0; j < 4; j++) {
        let dir = DIRS[j];
        let step = select(1.0, 1.4142135, dir.x != 0 && dir.y != 0);
        let a = probe(x, y, dir.x, dir.y, radius);
        let b = probe(x, y, -dir.x, -dir.y, radius);
        if (a.x == 0.0 || b.x == 0.0) {
            continue;
        }
        span[j] = (a.x + b.x) * step;
        far[j] = max(a.y, b.y);
        far_d[j] = select(b.x, a.x, a.y >= b.y) * step;
        narrowest = select(span[j], min(narrowest, span[j]), narrowest >= 0.0);
    }
    return far_sides(span, far, far_d, narrowest);
}

// Step 3 of fill_background (zwarp_warp::holes::fill_border_holes) at hole (x, y): a hole whose
// row or column runs to the image border within `reach` takes the nearest converged depth
// inwards (ties: the farther): (depth, 1); (0, 0) otherwise.
fn border_fill(x: i32, y: i32, reach_px: u32) -> vec2<f32> {
    let w = i32(params.width);
    let h = i32(params.height);
    let reach = i32(reach_px);
    let dirs = array<vec3<i32>, 4>(
        vec3<i32>(-1, 0, x), vec3<i32>(1, 0, w - 1 - x), vec3<i32>(0, -1, y), vec3<i32>(0, 1, h - 1 - y));
    var best_k = 0;
    var best_z = 0.0;
    for (var j = 0; j < 4; j++) {
        let dx = dirs[j].x;
        let dy = dirs[j].y;
        let to_border = dirs[j].z;
        if (to_border >= reach) {
            continue;
        }
        var open = true;
        for (var k = 1; k <= to_border; k++) {
            if (is_converged(in_state[u32((y + dy * k) * w + x + dx * k)])) {
                open = false;
                break;
            }
        }
        if (!open) {
            continue;
        }
        for (var k = 1; k <= reach; k++) {
            let xx = x - dx * k;
            let yy = y - dy * k;
            if (xx < 0 || yy < 0 || xx >= w || yy >= h) {
                break;
            }
            let n = u32(yy * w + xx);
            if (is_converged(in_state[n])) {
                let z = in_depth[n];
                if (best_k == 0 || k < best_k || (k == best_k && z > best_z)) {
                    best_k = k;
                    best_z = z;
                }
                break;
            }
        }
    }
    return vec2<f32>(best_z, select(0.0, 1.0, best_k != 0));
}

// One pass over a copy: every hole gets the fill of `params.rule` (0 Fig. 8 dilation,
// 1 background fill within `radius`, 2 border strips within `reach`) when that rule finds one.
fn fill_at(gid: vec3<u32>, radius: u32, reach: u32) {
    if (gid.x >= params.width || gid.y >= params.height) {
        return;
    }
    let i = gid.y * params.width + gid.x;
    var d = in_depth[i];
    var s = in_state[i];
    if (s == HOLE) {
        let x = i32(gid.x);
        let y = i32(gid.y);
        var f = vec2<f32>(0.0, 0.0);
        if (params.rule == 0u) {
            f = nearest_fill(x, y, radius);
        } else if (params.rule == 1u) {
            f = background_fill(x, y, radius);
        } else {
            f = border_fill(x, y, reach);
        }
        if (f.y != 0.0) {
            d = f.x;
            s = FILLED;
        }
    }
    out_depth[i] = d;
    out_state[i] = s;
}

// The fill with the caller's radius and reach (HolePolicy::Dilate / Background post-passes).
@compute @workgroup_size(8, 8, 1)
fn fill(@builtin(global_invocation_id) gid: vec3<u32>) {
    fill_at(gid, params.radius, params.reach);
}

// Steps 2 and 3 of fill_background: the fill with the bracket and reach that `limits` measured
// on the source layers (no read-back to set them as uniforms).
@compute @workgroup_size(8, 8, 1)
fn fill_measured(@builtin(global_invocation_id) gid: vec3<u32>) {
    fill_at(gid, measured[4], measured[5]);
}

// Step 0 of fill_background (zwarp_warp::holes::lone_revealed), from a copy: a revealed pixel
// with a hole among its 8-neighbours, at least one converged neighbour and every converged one
// nearer by more than FAR_SIDE_SPREAD becomes a hole; every other pixel is copied.
@compute @workgroup_size(8, 8, 1)
fn lone(@builtin(global_invocation_id) gid: vec3<u32>) {
    let w = params.width;
    let h = params.height;
    if (gid.x >= w || gid.y >= h) {
        return;
    }
    let i = gid.y * w + gid.x;
    var d = in_depth[i];
    var s = in_state[i];
    if (s == REVEALED) {
        var hole = false;
        var nearer = false;
        var on_surface = false;
        for (var ny = select(gid.y - 1u, 0u, gid.y == 0u); ny <= min(gid.y + 1u, h - 1u); ny++) {
            for (var nx = select(gid.x - 1u, 0u, gid.x == 0u); nx <= min(gid.x + 1u, w - 1u); nx++) {
                let j = ny * w + nx;
                let t = in_state[j];
                if (j == i) {
                    continue;
                }
                if (t == HOLE) {
                    hole = true;
                } else if (is_converged(t)) {
                    if (d - in_depth[j] <= FAR_SIDE_SPREAD * (1.0 - d)) {
                        on_surface = true;
                    } else {
                        nearer = true;
                    }
                }
            }
        }
        if (hole && nearer && !on_surface) {
            d = 1.0;
            s = HOLE;
        }
    }
    out_depth[i] = d;
    out_state[i] = s;
}

// Motion of source sample i (the Motion layout: 3 floats per sample).
fn motion_at(i: u32) -> vec2<f32> {
    return vec2<f32>(motion[3u * i], motion[3u * i + 1u]);
}

// The empty-background sample at q (the CPU's EmptyBackground): (v, 1) on an empty texel, nearest
// sampled; (0, 0, 0) outside the image or on a surface.
fn background_sample(q: vec2<f32>) -> vec3<f32> {
    let sw = params.src_width;
    let sh = params.src_height;
    if (!(q.x >= 0.0 && q.y >= 0.0 && q.x < f32(sw) && q.y < f32(sh))) {
        return vec3<f32>(0.0);
    }
    let i = min(u32(q.y), sh - 1u) * sw + min(u32(q.x), sw - 1u);
    if (empty[i] == 0u) {
        return vec3<f32>(0.0);
    }
    return vec3<f32>(motion_at(i), 1.0);
}

// Step 1 of fill_background, in place: a hole whose fixed-point search (zwarp_warp's
// fixed_point_search on the empty-background samples, whose Jacobian is zero, from the seeds of
// background_seeds) converges sees the empty background: far depth, converged. The search runs
// in source samples from p = multisample * (x + 0.5, y + 0.5), the second seed displaced by the
// motion of the source sample p falls in.
@compute @workgroup_size(8, 8, 1)
fn sky(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= params.width || gid.y >= params.height) {
        return;
    }
    let i = gid.y * params.width + gid.x;
    if (out_state[i] != HOLE) {
        return;
    }
    let p = vec2<f32>(f32(gid.x) + 0.5, f32(gid.y) + 0.5) * params.multisample;
    let back = motion_at(u32(p.y) * params.src_width + u32(p.x));
    let max_q = vec2<f32>(f32(params.src_width), f32(params.src_height)) - vec2<f32>(1e-3);
    let thr2 = params.threshold * params.threshold;
    var converged = false;
    for (var k = 0u; k < 2u; k++) {
        var q = clamp(select(p, p - back, k == 1u), vec2<f32>(0.0), max_q);
        for (var t = 0u; t < params.iterations; t++) {
            let s = background_sample(q);
            if (s.z == 0.0) {
                break;
            }
            let w = p - s.xy;
            let step = w - q;
            if (step.x * step.x + step.y * step.y < thr2) {
                converged = true;
                break;
            }
            // Plain step, or the Newton step with a zero Jacobian (q + step), as on the CPU.
            q = select(w, q + step, params.accelerate != 0u);
        }
    }
    if (converged) {
        out_depth[i] = 1.0;
        out_state[i] = CONVERGED;
    }
}

// Order key of a float: a < b <=> order_key(a) < order_key(b) (NaN aside). WGSL has no float
// atomics, so the motion range is reduced with atomicMax on keys (on complemented keys for the
// minimum, so that 0, a cleared buffer, is the identity of both).
fn order_key(f: f32) -> u32 {
    let b = bitcast<u32>(f);
    return select(b | 0x80000000u, ~b, (b & 0x80000000u) != 0u);
}

fn from_key(k: u32) -> f32 {
    return bitcast<f32>(select(~k, k & 0x7fffffffu, (k & 0x80000000u) != 0u));
}

fn finite_key(k: u32) -> bool {
    return (bitcast<u32>(from_key(k)) & 0x7f800000u) != 0x7f800000u;
}

var<workgroup> wg_range: array<atomic<u32>, 4>;

// BackgroundLimits::of_multisampled's pass over source layer `params.layer` (src_width x
// src_height samples): the empty-background mask (a sample is empty when every layer's depth is
// >= 1) and the motion range of the layer's surfaces (depth < 1), reduced per workgroup, then
// into `range`.
@compute @workgroup_size(8, 8, 1)
fn surfaces(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    if (gid.x < params.src_width && gid.y < params.src_height) {
        let i = gid.y * params.src_width + gid.x;
        let d = layer_depth[i];
        if (params.layer == 0u) {
            empty_out[i] = select(0u, 1u, d >= 1.0);
        } else if (!(d >= 1.0)) {
            empty_out[i] = 0u;
        }
        if (d < 1.0) {
            let v = motion_at(i);
            atomicMax(&wg_range[0], ~order_key(v.x));
            atomicMax(&wg_range[1], ~order_key(v.y));
            atomicMax(&wg_range[2], order_key(v.x));
            atomicMax(&wg_range[3], order_key(v.y));
        }
    }
    workgroupBarrier();
    if (li < 4u) {
        let k = atomicLoad(&wg_range[li]);
        if (k != 0u) {
            atomicMax(&range[li], k);
        }
    }
}

// BackgroundLimits::from_range on the reduced range (one invocation): motion range and largest
// motion in target pixels (source samples / multisample), bracket = min(min(ceil(range), 64) + 1,
// radius), reach = min(ceil(largest) + 1, max(width, height)); no surface: range = largest = 0.
// NaN or infinite motion (which the CPU rejects; the GPU-resident inputs are not checked) counts
// as the widest limits, and the integer clamps keep both bounded whatever the float arithmetic
// gives, so a bad input cannot make the fills loop long.
@compute @workgroup_size(1, 1, 1)
fn limits() {
    let max_wh = max(params.width, params.height);
    var bracket = min(1u, params.radius);
    var reach = min(1u, max_wh);
    let hi_x = atomicLoad(&range[2]);
    if (hi_x != 0u) {
        let lo_k = vec2<u32>(~atomicLoad(&range[0]), ~atomicLoad(&range[1]));
        let hi_k = vec2<u32>(hi_x, atomicLoad(&range[3]));
        var c_range = 64.0;
        var c_largest = f32(max_wh);
        if (finite_key(lo_k.x) && finite_key(lo_k.y) && finite_key(hi_k.x) && finite_key(hi_k.y)) {
            let lo = vec2<f32>(from_key(lo_k.x), from_key(lo_k.y));
            let hi = vec2<f32>(from_key(hi_k.x), from_key(hi_k.y));
            let m = params.multisample;
            c_range = ceil(max(hi.x - lo.x, hi.y - lo.y) / m);
            c_largest = ceil(max(max(abs(lo.x), abs(hi.x)), max(abs(lo.y), abs(hi.y))) / m);
        }
        bracket = min(min(u32(clamp(c_range, 0.0, 64.0)), 64u) + 1u, params.radius);
        reach = min(u32(clamp(c_largest, 0.0, f32(max_wh))), max_wh - 1u) + 1u;
    }
    atomicStore(&range[4], bracket);
    atomicStore(&range[5], reach);
}
