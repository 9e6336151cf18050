// Colour warps of seed 001 (Bowles et al. 2012): the WGSL twin of zwarp_color's heuristic warp
// (Sec. 3.3) and of the raster stage of its robust warp (Sec. 3.4, Fig. 5). Same operations in
// the same order as the CPU code (crates/zwarp-color/src/{sampler,heuristic,robust}.rs and
// zwarp_warp::search::fixed_point_search).
//
// planes: [depth | term0.x | term0.y | term1.x | term1.y | term2.x | term2.y], w*h each.
// color:  w*h*3 linear RGB. rho: (w-1)*(h-1) cell terms (robust only).

struct Params {
    width: u32,
    height: u32,
    n_terms: u32,
    iterations: u32,
    threshold: f32,
    // Heuristic seed: 0 pixel, 1 upstream (k = seed.x), 2 offset (seed).
    seed_mode: u32,
    // 0: range test (heuristic), 1: rho cells (robust).
    continuity: u32,
    accelerate: u32,
    seed: vec2<f32>,
    n_leaves: u32,
    margin: f32,
    // Fallback (hole) heuristic of the robust warp.
    f_iterations: u32,
    f_threshold: f32,
    leaf_offset: u32,
    _pad: u32,
    scale0: vec2<f32>,
    scale1: vec2<f32>,
    scale2: vec2<f32>,
    _pad2: vec2<f32>,
}

@group(0) @binding(0) var<uniform> P: Params;
@group(0) @binding(1) var<storage, read> planes: array<f32>;
@group(0) @binding(2) var<storage, read> color: array<f32>;
@group(0) @binding(3) var<storage, read> rho: array<f32>;
@group(0) @binding(4) var<storage, read_write> out_color: array<f32>;
@group(0) @binding(5) var<storage, read_write> out_depth: array<f32>;
@group(0) @binding(6) var<storage, read_write> out_residual: array<f32>;
@group(0) @binding(7) var<storage, read> leaves: array<vec4<u32>>;
@group(0) @binding(8) var<storage, read_write> zkey: array<atomic<u32>>;
@group(0) @binding(9) var<storage, read_write> winner: array<atomic<u32>>;

const CONTINUITY_PX: f32 = 1.0;
const MAX_RECORDED: u32 = 16u;
const NONE: u32 = 0xffffffffu;

fn npix() -> u32 {
    return P.width * P.height;
}

fn term_scale(k: u32) -> vec2<f32> {
    if k == 0u {
        return P.scale0;
    } else if k == 1u {
        return P.scale1;
    }
    return P.scale2;
}

// Field::v: v = 0; v += scale * (x, y) per term.
fn field_v(i: u32) -> vec2<f32> {
    var v = vec2<f32>(0.0, 0.0);
    let n = npix();
    for (var k = 0u; k < P.n_terms; k++) {
        let xy = vec2<f32>(planes[n * (1u + 2u * k) + i], planes[n * (2u + 2u * k) + i]);
        v = v + term_scale(k) * xy;
    }
    return v;
}

fn depth_at(i: u32) -> f32 {
    return planes[i];
}

struct Loc {
    i0: u32,
    i1: u32,
    i2: u32,
    i3: u32,
    ax: f32,
    ay: f32,
    cell: u32,
    near: u32,
}

fn inside(q: vec2<f32>) -> bool {
    return q.x >= 0.0 && q.y >= 0.0 && q.x < f32(P.width) && q.y < f32(P.height);
}

fn clamp_q(q: vec2<f32>) -> vec2<f32> {
    let hi = vec2<f32>(f32(P.width), f32(P.height)) - vec2<f32>(1.0e-3, 1.0e-3);
    return clamp(q, vec2<f32>(0.0, 0.0), hi);
}

fn sat_sub1(a: u32) -> u32 {
    if a == 0u {
        return 0u;
    }
    return a - 1u;
}

fn locate(q: vec2<f32>) -> Loc {
    let wm = P.width - 1u;
    let hm = P.height - 1u;
    let tx = q.x + 0.5;
    let ty = q.y + 0.5;
    let ix = u32(tx);
    let iy = u32(ty);
    var l: Loc;
    l.ax = tx - f32(ix);
    l.ay = ty - f32(iy);
    let x0 = min(sat_sub1(ix), wm);
    let y0 = min(sat_sub1(iy), hm);
    let x1 = min(ix, wm);
    let y1 = min(iy, hm);
    l.cell = NONE;
    if x0 != x1 && y0 != y1 {
        l.cell = y0 * wm + x0;
    }
    l.near = min(u32(q.y), hm) * P.width + min(u32(q.x), wm);
    l.i0 = y0 * P.width + x0;
    l.i1 = y0 * P.width + x1;
    l.i2 = y1 * P.width + x0;
    l.i3 = y1 * P.width + x1;
    return l;
}

fn lerp2(a: vec2<f32>, b: vec2<f32>, s: f32) -> vec2<f32> {
    // glam: self * (1 - s) + rhs * s
    return a * (1.0 - s) + b * s;
}

fn smooth_at(l: Loc, v0: vec2<f32>, v1: vec2<f32>, v2: vec2<f32>, v3: vec2<f32>) -> bool {
    if P.continuity == 0u {
        let lo = min(min(v0, v1), min(v2, v3));
        let hi = max(max(v0, v1), max(v2, v3));
        let d = hi - lo;
        return max(d.x, d.y) < CONTINUITY_PX;
    }
    return l.cell != NONE && rho[l.cell] < 1.0;
}

struct Smp {
    v: vec2<f32>,
    depth: f32,
    dvdx: vec2<f32>,
    dvdy: vec2<f32>,
    is_smooth: bool,
}

// ColorSampler::fetch_at (q inside).
fn fetch(q: vec2<f32>) -> Smp {
    let l = locate(q);
    let v0 = field_v(l.i0);
    let v1 = field_v(l.i1);
    let v2 = field_v(l.i2);
    let v3 = field_v(l.i3);
    var s: Smp;
    if smooth_at(l, v0, v1, v2, v3) {
        let z0 = depth_at(l.i0);
        let z1 = depth_at(l.i1);
        let z2 = depth_at(l.i2);
        let z3 = depth_at(l.i3);
        let top = lerp2(v0, v1, l.ax);
        let bot = lerp2(v2, v3, l.ax);
        let zt = z0 + (z1 - z0) * l.ax;
        let zb = z2 + (z3 - z2) * l.ax;
        s.dvdx = lerp2(v1 - v0, v3 - v2, l.ay);
        s.dvdy = bot - top;
        s.v = lerp2(top, bot, l.ay);
        s.depth = zt + (zb - zt) * l.ay;
        s.is_smooth = true;
    } else {
        s.v = field_v(l.near);
        s.depth = depth_at(l.near);
        s.dvdx = vec2<f32>(0.0, 0.0);
        s.dvdy = vec2<f32>(0.0, 0.0);
        s.is_smooth = false;
    }
    return s;
}

fn col(i: u32) -> vec3<f32> {
    return vec3<f32>(color[3u * i], color[3u * i + 1u], color[3u * i + 2u]);
}

// ColorSampler::color.
fn sample_color(q_in: vec2<f32>) -> vec3<f32> {
    let q = clamp_q(q_in);
    let l = locate(q);
    let v0 = field_v(l.i0);
    let v1 = field_v(l.i1);
    let v2 = field_v(l.i2);
    let v3 = field_v(l.i3);
    if smooth_at(l, v0, v1, v2, v3) {
        let c0 = col(l.i0);
        let c1 = col(l.i1);
        let c2 = col(l.i2);
        let c3 = col(l.i3);
        let top = c0 + (c1 - c0) * l.ax;
        let bot = c2 + (c3 - c2) * l.ax;
        return top + (bot - top) * l.ay;
    }
    return col(l.near);
}

struct Visit {
    q: vec2<f32>,
    v: vec2<f32>,
    depth: f32,
}

struct Search {
    converged: bool,
    q: vec2<f32>,
    n: u32,
}

var<private> visits: array<Visit, 16>;

// zwarp_warp::search::fixed_point_search with one seed, FirstConverged, recording the
// visited samples (the Recorder of the CPU code).
fn search(p: vec2<f32>, seed: vec2<f32>, iterations: u32, threshold: f32, accelerate: bool) -> Search {
    let thr2 = threshold * threshold;
    var q = seed;
    var r: Search;
    r.converged = false;
    r.n = 0u;
    for (var it = 0u; it < iterations; it++) {
        if !inside(q) {
            break;
        }
        let s = fetch(q);
        if r.n < MAX_RECORDED {
            visits[r.n] = Visit(q, s.v, s.depth);
            r.n = r.n + 1u;
        }
        let w = p - s.v;
        let step = w - q;
        let r2 = step.x * step.x + step.y * step.y;
        if r2 < thr2 {
            r.converged = true;
            r.q = q;
            return r;
        }
        var next = w;
        if accelerate {
            let m00 = 1.0 + s.dvdx.x;
            let m01 = s.dvdy.x;
            let m10 = s.dvdx.y;
            let m11 = 1.0 + s.dvdy.y;
            let det = m00 * m11 - m01 * m10;
            if abs(det) > 0.05 {
                let d = vec2<f32>(m11 * step.x - m01 * step.y, -m10 * step.x + m00 * step.y) / det;
                next = q + d;
            }
        }
        q = next;
    }
    return r;
}

struct Px {
    color: vec3<f32>,
    depth: f32,
    residual: f32,
}

// heuristic_pixel.
fn heuristic_pixel(p: vec2<f32>, mode: u32, seed_param: vec2<f32>, iterations: u32, threshold: f32) -> Px {
    var seed = p;
    if mode == 1u {
        if inside(p) {
            seed = p - seed_param.x * fetch(p).v;
        }
    } else if mode == 2u {
        seed = p + seed_param;
    }
    seed = clamp_q(seed);
    let r = search(p, seed, iterations, threshold, false);
    var o: Px;
    if r.converged {
        let last = visits[r.n - 1u];
        let q1 = p - last.v;
        o.color = sample_color(q1);
        o.depth = last.depth;
        o.residual = length(r.q + last.v - p);
        return o;
    }
    if r.n > 0u {
        var b = visits[0];
        for (var i = 1u; i < r.n; i++) {
            if visits[i].depth >= b.depth {
                b = visits[i];
            }
        }
        o.color = sample_color(b.q);
        o.depth = b.depth;
        o.residual = length(b.q + b.v - p);
        return o;
    }
    let q = clamp_q(seed);
    o.color = sample_color(q);
    o.depth = depth_at(locate(q).near);
    o.residual = bitcast<f32>(0x7f800000u);
    return o;
}

fn write_px(i: u32, o: Px) {
    out_color[3u * i] = o.color.x;
    out_color[3u * i + 1u] = o.color.y;
    out_color[3u * i + 2u] = o.color.z;
    out_depth[i] = o.depth;
    out_residual[i] = o.residual;
}

@compute @workgroup_size(8, 8)
fn heuristic(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= P.width || gid.y >= P.height {
        return;
    }
    let p = vec2<f32>(f32(gid.x) + 0.5, f32(gid.y) + 0.5);
    write_px(gid.y * P.width + gid.x, heuristic_pixel(p, P.seed_mode, P.seed, P.iterations, P.threshold));
}

// ---- Robust warp: quads rasterised with a depth test (three passes, min (depth, quad)) ----

struct Warped {
    px0: i32,
    py0: i32,
    px1: i32,
    py1: i32,
    dst_lo: vec2<f32>,
    dst_ext: vec2<f32>,
    src_lo: vec2<f32>,
    src_ext: vec2<f32>,
}

fn clampi(v: f32, m: u32) -> i32 {
    return i32(clamp(v, -1.0, f32(m) + 1.0));
}

// robust.rs footprint_margin.
fn footprint_margin(p: array<vec2<f32>, 4>, ext: vec2<f32>, cap: f32) -> vec2<f32> {
    if ext.x < 1.0 || ext.y < 1.0 {
        return vec2<f32>(cap, cap);
    }
    let dx = max(abs((p[1] - p[0]) / ext.x - vec2<f32>(1.0, 0.0)), abs((p[3] - p[2]) / ext.x - vec2<f32>(1.0, 0.0)));
    let dy = max(abs((p[2] - p[0]) / ext.y - vec2<f32>(0.0, 1.0)), abs((p[3] - p[1]) / ext.y - vec2<f32>(0.0, 1.0)));
    return min(vec2<f32>(0.5, 0.5) + 0.5 * (dx + dy), vec2<f32>(cap, cap));
}

// robust.rs warp_leaf.
fn warp_leaf(l: vec4<u32>) -> Warped {
    var lo = vec2<f32>(bitcast<f32>(0x7f800000u), bitcast<f32>(0x7f800000u));
    var hi = -lo;
    var corners: array<vec2<f32>, 4>;
    for (var k = 0u; k < 4u; k++) {
        var x = l.x;
        var y = l.y;
        if k == 1u || k == 3u {
            x = l.z - 1u;
        }
        if k >= 2u {
            y = l.w - 1u;
        }
        let c = vec2<f32>(f32(x) + 0.5, f32(y) + 0.5);
        let p = c + field_v(y * P.width + x);
        corners[k] = p;
        lo = min(lo, p);
        hi = max(hi, p);
    }
    var o: Warped;
    o.src_lo = vec2<f32>(f32(l.x) + 0.5, f32(l.y) + 0.5);
    o.src_ext = vec2<f32>(f32(l.z - l.x - 1u), f32(l.w - l.y - 1u));
    let m = footprint_margin(corners, o.src_ext, P.margin);
    let elo = lo - m;
    let ehi = hi + m;
    o.px0 = max(clampi(ceil(elo.x - 0.5), P.width), 0);
    o.py0 = max(clampi(ceil(elo.y - 0.5), P.height), 0);
    o.px1 = min(clampi(floor(ehi.x - 0.5), P.width) + 1, i32(P.width));
    o.py1 = min(clampi(floor(ehi.y - 0.5), P.height) + 1, i32(P.height));
    o.dst_lo = lo;
    o.dst_ext = hi - lo;
    return o;
}

fn leaf_seed(q: Warped, p: vec2<f32>) -> vec2<f32> {
    var rel = vec2<f32>(0.5, 0.5);
    if q.dst_ext.x > 1e-6 {
        rel.x = (p.x - q.dst_lo.x) / q.dst_ext.x;
    }
    if q.dst_ext.y > 1e-6 {
        rel.y = (p.y - q.dst_lo.y) / q.dst_ext.y;
    }
    let s = q.src_lo + rel * q.src_ext;
    return clamp(s, q.src_lo - vec2<f32>(0.5, 0.5), q.src_lo + q.src_ext + vec2<f32>(0.499, 0.499));
}

struct Hit {
    ok: bool,
    depth: f32,
    q: vec2<f32>,
    v: vec2<f32>,
}

fn leaf_hit(l: vec4<u32>, w: Warped, p: vec2<f32>) -> Hit {
    var h: Hit;
    h.ok = false;
    let r = search(p, leaf_seed(w, p), P.iterations, P.threshold, P.accelerate != 0u);
    if !r.converged {
        return h;
    }
    if !(r.q.x >= f32(l.x) && r.q.x < f32(l.z) && r.q.y >= f32(l.y) && r.q.y < f32(l.w)) {
        return h;
    }
    let last = visits[r.n - 1u];
    h.ok = true;
    h.depth = last.depth;
    h.q = r.q;
    h.v = last.v;
    return h;
}

fn leaf_index(gid: vec3<u32>, nwg: vec3<u32>) -> u32 {
    return P.leaf_offset + gid.x + gid.y * nwg.x * 64u;
}

@compute @workgroup_size(64)
fn quads_depth(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let li = leaf_index(gid, nwg);
    if li >= P.n_leaves {
        return;
    }
    let l = leaves[li];
    let w = warp_leaf(l);
    for (var py = w.py0; py < w.py1; py++) {
        for (var px = w.px0; px < w.px1; px++) {
            let p = vec2<f32>(f32(px) + 0.5, f32(py) + 0.5);
            let h = leaf_hit(l, w, p);
            if h.ok {
                atomicMin(&zkey[u32(py) * P.width + u32(px)], bitcast<u32>(max(h.depth, 0.0)));
            }
        }
    }
}

@compute @workgroup_size(64)
fn quads_winner(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let li = leaf_index(gid, nwg);
    if li >= P.n_leaves {
        return;
    }
    let l = leaves[li];
    let w = warp_leaf(l);
    for (var py = w.py0; py < w.py1; py++) {
        for (var px = w.px0; px < w.px1; px++) {
            let p = vec2<f32>(f32(px) + 0.5, f32(py) + 0.5);
            let h = leaf_hit(l, w, p);
            let i = u32(py) * P.width + u32(px);
            if h.ok && bitcast<u32>(max(h.depth, 0.0)) == atomicLoad(&zkey[i]) {
                atomicMin(&winner[i], li);
            }
        }
    }
}

@compute @workgroup_size(8, 8)
fn resolve(@builtin(global_invocation_id) gid: vec3<u32>) {
    if gid.x >= P.width || gid.y >= P.height {
        return;
    }
    let i = gid.y * P.width + gid.x;
    let p = vec2<f32>(f32(gid.x) + 0.5, f32(gid.y) + 0.5);
    let li = atomicLoad(&winner[i]);
    if li != NONE {
        let l = leaves[li];
        let w = warp_leaf(l);
        let h = leaf_hit(l, w, p);
        var o: Px;
        o.color = sample_color(p - h.v);
        o.depth = h.depth;
        o.residual = length(h.q + h.v - p);
        write_px(i, o);
        return;
    }
    write_px(i, heuristic_pixel(p, P.seed_mode, P.seed, P.f_iterations, P.f_threshold));
}
