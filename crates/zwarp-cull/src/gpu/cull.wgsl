// AABB occlusion culling (seed 000 Sec. 5.2; thesis seed 002 Sec. III.2 and IV.3): per object,
// view-frustum test of its world AABB, then the screen rectangle + nearest depth of its 8
// projected corners against a max-depth structure (maxquery.wgsl, prepended). The WGSL twin of
// zwarp_cull's Frustum::intersects + screen_rect_with + MaxDepthQuery::is_occluded(rect,
// nearest - tolerance), i.e. of the classification inside zwarp_cull::cull_against_depth.
// Visible objects are appended to a compacted id list (atomic counter) with one
// DrawIndexedIndirectArgs each; every object also writes its fixed draw slot (instance count
// 0 when culled) for adapters without multi_draw_indirect_count. Host code: cull.rs.

struct Params {
    view_proj: mat4x4<f32>,
    // Frustum planes (n, d), n . x + d >= 0 inside: left, right, bottom, top, near, far.
    planes: array<vec4<f32>, 6>,
    // (image width, image height) as floats, depth tolerance, silhouette-test square slack.
    size_tol: vec4<f32>,
    // (object count, image width, image height, silhouette test on (1) / off (0)).
    counts: vec4<u32>,
};

// Per-object draw record: (first_index, index_count, base_vertex (i32 bits), draw slot).
struct Draw {
    first_index: u32,
    index_count: u32,
    base_vertex: i32,
    slot: u32,
};

struct DrawArgs {
    index_count: u32,
    instance_count: u32,
    first_index: u32,
    base_vertex: i32,
    first_instance: u32,
};

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> md_levels: array<vec4<u32>>;
@group(0) @binding(2) var<storage, read> md_data: array<f32>;
// World AABBs: (min.xyz, 0), (max.xyz, 0) per object.
@group(0) @binding(3) var<storage, read> aabbs: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> draws: array<Draw>;
// Non-zero: kept without a test (WOC's rapid-motion objects, drawn into the map already).
@group(0) @binding(5) var<storage, read> forced: array<u32>;
@group(0) @binding(6) var<storage, read_write> classes: array<u32>;
@group(0) @binding(7) var<storage, read_write> visible: array<u32>;
@group(0) @binding(8) var<storage, read_write> counter: array<atomic<u32>>;
@group(0) @binding(9) var<storage, read_write> draw_args: array<DrawArgs>;
@group(0) @binding(10) var<storage, read_write> slot_args: array<DrawArgs>;

// Classes (zwarp_cull::woc's Class): culled by the frustum (or projecting outside), forced,
// crossing the near plane, occluded, visible.
const C_FRUSTUM: u32 = 0u;
const C_FORCED: u32 = 1u;
const C_CROSSES_NEAR: u32 = 2u;
const C_OCCLUDED: u32 = 3u;
const C_VISIBLE: u32 = 4u;

// NaN / infinity by bit pattern: comparisons with NaN may be folded away by shader compilers.
fn is_nan3(v: vec3<f32>) -> bool {
    let b = bitcast<vec3<u32>>(v) & vec3<u32>(0x7fffffffu);
    return any(b > vec3<u32>(0x7f800000u));
}
fn is_finite3(v: vec3<f32>) -> bool {
    let b = bitcast<vec3<u32>>(v) & vec3<u32>(0x7fffffffu);
    return all(b < vec3<u32>(0x7f800000u));
}
fn is_finite1(v: f32) -> bool {
    return (bitcast<u32>(v) & 0x7fffffffu) < 0x7f800000u;
}

// zwarp_cull::Frustum::intersects (the positive-vertex test with relative slack).
fn in_frustum(lo: vec3<f32>, hi: vec3<f32>) -> bool {
    for (var i = 0u; i < 6u; i++) {
        let p = params.planes[i];
        let pv = select(lo, hi, p.xyz >= vec3<f32>(0.0));
        let nd = p.x * pv.x + p.y * pv.y + p.z * pv.z;
        let dist = nd + p.w;
        if (dist < -1e-6 * (abs(nd) + abs(p.w))) {
            return false;
        }
    }
    return true;
}

fn classify(i: u32) -> u32 {
    let lo = aabbs[2u * i].xyz;
    let hi = aabbs[2u * i + 1u].xyz;
    let nan = is_nan3(lo) || is_nan3(hi);
    let empty = lo.x > hi.x || lo.y > hi.y || lo.z > hi.z;
    // Frustum::intersects: NaN boxes are kept, empty boxes culled.
    if (!nan && (empty || !in_frustum(lo, hi))) {
        return C_FRUSTUM;
    }
    if (forced[i] != 0u) {
        return C_FORCED;
    }
    // screen_rect_with: an unbounded proxy cannot be tested.
    if (nan || (!is_finite3(lo) && !empty)) {
        return C_CROSSES_NEAR;
    }
    let w = params.size_tol.x;
    let h = params.size_tol.y;
    var lo_s = vec2<f32>(3.4028235e38);
    var hi_s = vec2<f32>(-3.4028235e38);
    var nearest = 3.4028235e38;
    for (var k = 0u; k < 8u; k++) {
        let c = vec3<f32>(select(lo.x, hi.x, (k & 1u) != 0u), select(lo.y, hi.y, (k & 2u) != 0u),
                          select(lo.z, hi.z, (k & 4u) != 0u));
        let clip = params.view_proj * vec4<f32>(c, 1.0);
        // project_with: behind the eye (w <= 0) or nearer than the near plane (z < 0).
        if (!(clip.w > 0.0)) {
            return C_CROSSES_NEAR;
        }
        let inv_w = 1.0 / clip.w;
        let s = vec3<f32>((clip.x * inv_w + 1.0) * 0.5 * w, (1.0 - clip.y * inv_w) * 0.5 * h, clip.z * inv_w);
        if (!(s.z >= 0.0) || !is_finite3(s)) {
            return C_CROSSES_NEAR;
        }
        lo_s = min(lo_s, s.xy);
        hi_s = max(hi_s, s.xy);
        nearest = min(nearest, s.z);
    }
    if (nearest > 1.0) {
        return C_FRUSTUM;
    }
    // Pixel x covers [x, x + 1): columns floor(lo) ..= ceil(hi) - 1, widened by the slack.
    let slack = 1e-3;
    let x0 = max(floor(lo_s.x - slack), 0.0);
    let y0 = max(floor(lo_s.y - slack), 0.0);
    let x1 = min(ceil(hi_s.x + slack), w);
    let y1 = min(ceil(hi_s.y + slack), h);
    if (x0 >= x1 || y0 >= y1) {
        return C_FRUSTUM;
    }
    let rect = vec4<u32>(u32(x0), u32(y0), u32(x1), u32(y1));
    let limit = nearest - params.size_tol.z;
    if (md_max_depth(rect) < limit) {
        return C_OCCLUDED;
    }
    if (params.counts.w != 0u && (rect.z - rect.x) * (rect.w - rect.y) <= HULL_TEST_MAX_AREA
        && !silhouette_seen(lo, hi, rect, limit)) {
        return C_OCCLUDED;
    }
    return C_VISIBLE;
}

// zwarp_cull's silhouette test (WocParams::hull_test, `refine_by_hull`): rectangles up to this
// many pixels are scanned.
const HULL_TEST_MAX_AREA: u32 = 16384u;

fn perp_dot(a: vec2<f32>, b: vec2<f32>) -> f32 {
    return a.x * b.y - a.y * b.x;
}

fn cross3(o: vec2<f32>, a: vec2<f32>, b: vec2<f32>) -> f32 {
    return perp_dot(a - o, b - o);
}

// zwarp_cull::screen::square_meets_hull: the pixel square grown by `slack` meets the convex
// counter-clockwise polygon hull[..n] (separating axes; degenerate hulls by their bounds).
fn square_meets_hull(x: f32, y: f32, slack: f32, hull: ptr<function, array<vec2<f32>, 16>>, n: u32) -> bool {
    let lo = vec2<f32>(x - slack, y - slack);
    let hi = vec2<f32>(x + 1.0 + slack, y + 1.0 + slack);
    var bmin = vec2<f32>(3.4028235e38);
    var bmax = vec2<f32>(-3.4028235e38);
    for (var i = 0u; i < n; i++) {
        bmin = min(bmin, (*hull)[i]);
        bmax = max(bmax, (*hull)[i]);
    }
    if (bmax.x < lo.x || bmin.x > hi.x || bmax.y < lo.y || bmin.y > hi.y) {
        return false;
    }
    if (n < 3u) {
        return true;
    }
    let corners = array<vec2<f32>, 4>(lo, vec2<f32>(hi.x, lo.y), hi, vec2<f32>(lo.x, hi.y));
    for (var i = 0u; i < n; i++) {
        let a = (*hull)[i];
        let e = (*hull)[(i + 1u) % n] - a;
        var all_out = true;
        for (var c = 0u; c < 4u; c++) {
            if (perp_dot(e, corners[c] - a) >= 0.0) {
                all_out = false;
            }
        }
        if (all_out) {
            return false;
        }
    }
    return true;
}

// `refine_by_hull` for one object the rectangle test kept: whether some pixel of its rectangle
// whose predicted depth is not nearer than `limit` meets the convex hull of the 8 projected
// corners (zwarp_cull::screen::screen_hull_with, Andrew's monotone chain). The predicted depth
// is level 0 of the max structure (offset 0, full size, for every kind).
fn silhouette_seen(lo: vec3<f32>, hi: vec3<f32>, rect: vec4<u32>, limit: f32) -> bool {
    let w = params.size_tol.x;
    let h = params.size_tol.y;
    var pts: array<vec2<f32>, 8>;
    for (var k = 0u; k < 8u; k++) {
        let c = vec3<f32>(select(lo.x, hi.x, (k & 1u) != 0u), select(lo.y, hi.y, (k & 2u) != 0u),
                          select(lo.z, hi.z, (k & 4u) != 0u));
        let clip = params.view_proj * vec4<f32>(c, 1.0);
        let inv_w = 1.0 / clip.w;
        pts[k] = vec2<f32>((clip.x * inv_w + 1.0) * 0.5 * w, (1.0 - clip.y * inv_w) * 0.5 * h);
    }
    // Sort by x, then y (insertion sort of 8).
    for (var i = 1u; i < 8u; i++) {
        let p = pts[i];
        var j = i;
        while (j > 0u && (pts[j - 1u].x > p.x || (pts[j - 1u].x == p.x && pts[j - 1u].y > p.y))) {
            pts[j] = pts[j - 1u];
            j--;
        }
        pts[j] = p;
    }
    var hull: array<vec2<f32>, 16>;
    var k = 0u;
    for (var i = 0u; i < 8u; i++) {
        let p = pts[i];
        while (k >= 2u && cross3(hull[k - 2u], hull[k - 1u], p) <= 0.0) {
            k--;
        }
        hull[k] = p;
        k++;
    }
    let lower = k + 1u;
    for (var i = 7u; i > 0u; i--) {
        let p = pts[i - 1u];
        while (k >= lower && cross3(hull[k - 2u], hull[k - 1u], p) <= 0.0) {
            k--;
        }
        hull[k] = p;
        k++;
    }
    let n = min(max(k, 2u) - 1u, 8u);
    let slack = params.size_tol.w;
    let stride = u32(w);
    for (var y = rect.y; y < rect.w; y++) {
        for (var x = rect.x; x < rect.z; x++) {
            if (md_data[y * stride + x] >= limit && square_meets_hull(f32(x), f32(y), slack, &hull, n)) {
                return true;
            }
        }
    }
    return false;
}

@compute @workgroup_size(64, 1, 1)
fn cull(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = gid.y * groups.x * 64u + gid.x;
    if (i >= params.counts.x) {
        return;
    }
    let c = classify(i);
    classes[i] = c;
    let keep = c == C_FORCED || c == C_CROSSES_NEAR || c == C_VISIBLE;
    let d = draws[i];
    var args = DrawArgs(d.index_count, 0u, d.first_index, d.base_vertex, d.slot);
    if (keep) {
        args.instance_count = 1u;
        let at = atomicAdd(&counter[0], 1u);
        visible[at] = i;
        draw_args[at] = args;
    }
    slot_args[d.slot] = args;
}
