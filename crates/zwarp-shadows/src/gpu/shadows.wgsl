// Soft shadows on the GPU (seed 000, Sec. 6): the visibility accumulation of
// zwarp_shadows::Receivers::accumulate and the closed-form parallax motion of
// zwarp_shadows::LightRig::parallax_field. Host code: shadows.rs.

// ---------------------------------------------------------------------------------------------
// accumulate: one thread per receiver, no atomics (each thread owns its lit counter).

struct AccParams {
    // Shadow-map size (mw, mh).
    map_size: vec2<u32>,
    // Number of receivers.
    count: u32,
    // Threads per row of the 2D dispatch (workgroups.x * 256).
    row: u32,
    // Per-sample pixel shift K_i.
    shift: vec2<f32>,
    _pad: vec2<f32>,
};

@group(0) @binding(0) var<uniform> acc: AccParams;
// Per receiver: (p_c.x, p_c.y, g, threshold), Receivers::list order.
@group(0) @binding(1) var<storage, read> receivers: array<vec4<f32>>;
// Shadow map, row-major f32 (1 = empty).
@group(0) @binding(2) var<storage, read> smap: array<f32>;
@group(0) @binding(3) var<storage, read_write> lit: array<u32>;

@compute @workgroup_size(256, 1, 1)
fn accumulate(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = gid.y * acc.row + gid.x;
    if (k >= acc.count) {
        return;
    }
    let r = receivers[k];
    // texel_xy: p = p_c + K_i g, floor inside [0, mw) x [0, mh) (truncation there), else lit.
    let p = r.xy + acc.shift * r.z;
    var lit_here = 1u;
    if (p.x >= 0.0 && p.y >= 0.0 && p.x < f32(acc.map_size.x) && p.y < f32(acc.map_size.y)) {
        let x = u32(p.x);
        let y = u32(p.y);
        lit_here = select(0u, 1u, smap[y * acc.map_size.x + x] >= r.w);
    }
    lit[k] = lit[k] + lit_here;
}

// ---------------------------------------------------------------------------------------------
// parallax: motion of a centre-map layer towards the reference emitter offset, v = K_ref g(z),
// target depth = source depth (every sample map measures the same view depth); empty texels get
// zero motion and depth 1. Also counts the layer's covered texels (Layer::coverage).

struct ParParams {
    size: vec2<u32>,
    // 1 for directional lights (orthographic maps): g = z - pivot; else g = 1 / z.
    directional: u32,
    // Which coverage counter to add to.
    layer: u32,
    k_ref: vec2<f32>,
    // Perspective: far * near, far - near, far; orthographic: near, far - near (third unused).
    fxn: f32,
    fmn: f32,
    far: f32,
    near: f32,
    pivot: f32,
    _pad: f32,
};

@group(0) @binding(4) var<uniform> par: ParParams;
@group(0) @binding(5) var<storage, read> depth: array<f32>;
// Motion, 3 f32 per texel (zwarp_core::Motion: v.x, v.y, depth).
@group(0) @binding(6) var<storage, read_write> motion: array<f32>;
@group(0) @binding(7) var<storage, read_write> coverage: array<atomic<u32>>;

var<workgroup> covered: atomic<u32>;

@compute @workgroup_size(8, 8, 1)
fn parallax(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    if (li == 0u) {
        atomicStore(&covered, 0u);
    }
    workgroupBarrier();
    if (gid.x < par.size.x && gid.y < par.size.y) {
        let i = gid.y * par.size.x + gid.x;
        let d = depth[i];
        var m = vec3<f32>(0.0, 0.0, 1.0);
        if (d < 1.0) {
            var z: f32;
            var g: f32;
            if (par.directional == 1u) {
                // Camera::linear_depth (orthographic): near + d (far - near).
                z = par.near + d * par.fmn;
                g = z - par.pivot;
            } else {
                // Camera::linear_depth (perspective): f n / (f - d (f - n)).
                z = par.fxn / (par.far - d * par.fmn);
                g = 1.0 / z;
            }
            m = vec3<f32>(par.k_ref * g, d);
            atomicAdd(&covered, 1u);
        }
        motion[3u * i] = m.x;
        motion[3u * i + 1u] = m.y;
        motion[3u * i + 2u] = m.z;
    }
    workgroupBarrier();
    if (li == 0u) {
        let c = atomicLoad(&covered);
        if (c > 0u) {
            atomicAdd(&coverage[par.layer], c);
        }
    }
}
