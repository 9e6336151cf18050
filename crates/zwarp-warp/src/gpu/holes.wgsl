// Hole filling of a warped depth buffer as a post-pass (seed 000 Sec. 3.5, Fig. 8; Sec. 4's
// background fill): the WGSL twin of zwarp_warp::fill_holes with FillRule::Nearest
// (HolePolicy::Dilate, zwarp_warp::dilate_holes) and FillRule::Background (`fill`), and of
// zwarp_warp::holes::fill_background's other two steps: holes that see the source's empty
// background (`sky`) and strips open to the image border (`fill` with rule 2). Only converged
// pixels are read by `fill`, so one pass over a copy gives the CPU's order-independent result;
// `sky` reads only its own pixel and runs in place. Host code: holes.rs.

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
    pad: u32,
};

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> in_depth: array<f32>;
@group(0) @binding(2) var<storage, read> in_state: array<u32>;
@group(0) @binding(3) var<storage, read_write> out_depth: array<f32>;
@group(0) @binding(4) var<storage, read_write> out_state: array<u32>;
// `sky`: per source sample, 1 where no source layer has a surface; layer 0's motion (samples).
@group(0) @binding(5) var<storage, read> empty: array<u32>;
@group(0) @binding(6) var<storage, read> motion: array<vec2<f32>>;

const CONVERGED: u32 = 0u;
const FILLED: u32 = 1u;
const HOLE: u32 = 2u;

// Horizontal, vertical, both diagonals (zwarp_warp::FILL_DIRECTIONS), each probed both ways.
const DIRS = array<vec2<i32>, 4>(vec2<i32>(1, 0), vec2<i32>(0, 1), vec2<i32>(1, 1), vec2<i32>(1, -1));

// Nearest converged pixel from (x, y) along (dx, dy) within the radius: (k, depth), k = 0 if
// none (the image edge or the radius ends the probe).
// zwarp_warp::holes::BRACKET_SPAN_RATIO.
const BRACKET_SPAN_RATIO: f32 = 4.0;

fn probe(x: i32, y: i32, dx: i32, dy: i32) -> vec2<f32> {
    let w = i32(params.width);
    let h = i32(params.height);
    for (var k = 1; k <= i32(params.radius); k++) {
        let xx = x + dx * k;
        let yy = y + dy * k;
        if (xx < 0 || yy < 0 || xx >= w || yy >= h) {
            return vec2<f32>(0.0, 0.0);
        }
        let i = u32(yy * w + xx);
        if (in_state[i] == CONVERGED) {
            return vec2<f32>(f32(k), in_depth[i]);
        }
    }
    return vec2<f32>(0.0, 0.0);
}

// Fig. 8 dilation (FillRule::Nearest) at hole (x, y): (depth, 1) when surrounded along all
// four directions, the nearest neighbour winning (ties: the farther depth); (0, 0) otherwise.
fn nearest_fill(x: i32, y: i32) -> vec2<f32> {
    var best_d = -1.0;
    var best_z = 0.0;
    for (var j = 0; j < 4; j++) {
        let dir = DIRS[j];
        let step = select(1.0, 1.4142135, dir.x != 0 && dir.y != 0);
        let a = probe(x, y, dir.x, dir.y);
        let b = probe(x, y, -dir.x, -dir.y);
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
// at least one direction, the farthest side of the directions bracketed within
// BRACKET_SPAN_RATIO times the narrowest bracket winning; (0, 0) otherwise.
fn background_fill(x: i32, y: i32) -> vec2<f32> {
    var span = array<f32, 4>(-1.0, -1.0, -1.0, -1.0);
    var far = array<f32, 4>(0.0, 0.0, 0.0, 0.0);
    var narrowest = -1.0;
    for (var j = 0; j < 4; j++) {
        let dir = DIRS[j];
        let step = select(1.0, 1.4142135, dir.x != 0 && dir.y != 0);
        let a = probe(x, y, dir.x, dir.y);
        let b = probe(x, y, -dir.x, -dir.y);
        if (a.x == 0.0 || b.x == 0.0) {
            continue;
        }
        span[j] = (a.x + b.x) * step;
        far[j] = max(a.y, b.y);
        narrowest = select(span[j], min(narrowest, span[j]), narrowest >= 0.0);
    }
    var found = false;
    var z = 0.0;
    for (var j = 0; j < 4; j++) {
        if (span[j] >= 0.0 && span[j] <= BRACKET_SPAN_RATIO * narrowest) {
            z = select(far[j], max(z, far[j]), found);
            found = true;
        }
    }
    return vec2<f32>(z, select(0.0, 1.0, found));
}

// Step 3 of fill_background (zwarp_warp::holes::fill_border_holes) at hole (x, y): a hole whose
// row or column runs to the image border within `reach` takes the nearest converged depth
// inwards (ties: the farther): (depth, 1); (0, 0) otherwise.
fn border_fill(x: i32, y: i32) -> vec2<f32> {
    let w = i32(params.width);
    let h = i32(params.height);
    let reach = i32(params.reach);
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
            if (in_state[u32((y + dy * k) * w + x + dx * k)] == CONVERGED) {
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
            if (in_state[n] == CONVERGED) {
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
// 1 background fill, 2 border strips) when that rule finds one.
@compute @workgroup_size(8, 8, 1)
fn fill(@builtin(global_invocation_id) gid: vec3<u32>) {
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
            f = nearest_fill(x, y);
        } else if (params.rule == 1u) {
            f = background_fill(x, y);
        } else {
            f = border_fill(x, y);
        }
        if (f.y != 0.0) {
            d = f.x;
            s = FILLED;
        }
    }
    out_depth[i] = d;
    out_state[i] = s;
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
    return vec3<f32>(motion[i], 1.0);
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
    let back = motion[u32(p.y) * params.src_width + u32(p.x)];
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
