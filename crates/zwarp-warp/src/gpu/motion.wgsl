// Motion field (seed 000, Sec. 3.1): v(q) = C P^-1 q - q in pixels, object motion through the
// item buffer, plus each sample's depth in the target view. The GPU twin of
// zwarp_core::motion_field / reproject_pixel: same arithmetic, same conventions (pixel centres,
// empty pixels = far-plane points moving with the camera only, behind-eye -> v = 1e9, depth 1).
// Host code: motion.rs.

struct Params {
    // Inverse view-projection of the source camera A.
    inv_a: mat4x4<f32>,
    // View-projection of the target camera B (static objects, empty pixels, unknown ids).
    vp_b: mat4x4<f32>,
    // Source size (w, h), target size (w, h).
    size_a: vec2<u32>,
    size_b: vec2<u32>,
    // Elements per input row (>= width: inputs may be 256-byte padded texture copies).
    row_stride: u32,
    // Number of entries in `deltas` that are real (the array has at least one element).
    n_deltas: u32,
    // 1 if `items` holds an item buffer.
    has_items: u32,
    _pad: u32,
};

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> depth: array<f32>;
@group(0) @binding(2) var<storage, read> items: array<u32>;
// vp_b * object_delta per object id.
@group(0) @binding(3) var<storage, read> deltas: array<mat4x4<f32>>;
// 3 floats per pixel (v.x, v.y, depth): the byte layout of zwarp_core::Motion.
@group(0) @binding(4) var<storage, read_write> motion: array<f32>;

fn store(i: u32, v: vec2<f32>, d: f32) {
    motion[3u * i] = v.x;
    motion[3u * i + 1u] = v.y;
    motion[3u * i + 2u] = d;
}

@compute @workgroup_size(8, 8, 1)
fn motion_field(@builtin(global_invocation_id) gid: vec3<u32>) {
    let wa = params.size_a.x;
    let ha = params.size_a.y;
    if (gid.x >= wa || gid.y >= ha) {
        return;
    }
    let src = gid.y * params.row_stride + gid.x;
    let out_i = gid.y * wa + gid.x;
    let d = depth[src];
    var m = params.vp_b;
    if (d < 1.0 && params.has_items != 0u) {
        let id = items[src];
        if (id < params.n_deltas) {
            m = deltas[id];
        }
    }
    // Unproject the pixel centre (camera.rs unproject_with).
    let px = f32(gid.x) + 0.5;
    let py = f32(gid.y) + 0.5;
    let nx = px / f32(wa) * 2.0 - 1.0;
    let ny = 1.0 - py / f32(ha) * 2.0;
    let p = params.inv_a * vec4<f32>(nx, ny, min(d, 1.0), 1.0);
    let world = p.xyz / p.w;
    // Project into B (camera.rs project_with).
    let c = m * vec4<f32>(world, 1.0);
    if (c.w <= 0.0) {
        // Behind the target eye: send it far off-screen so no fixed-point search converges.
        store(out_i, vec2<f32>(1.0e9, 1.0e9), 1.0);
        return;
    }
    let inv_w = 1.0 / c.w;
    let sx = (c.x * inv_w + 1.0) * 0.5 * f32(params.size_b.x);
    let sy = (1.0 - c.y * inv_w) * 0.5 * f32(params.size_b.y);
    var nd = c.z * inv_w;
    if (d >= 1.0) {
        nd = 1.0;
    }
    store(out_i, vec2<f32>(sx - px, sy - py), nd);
}
