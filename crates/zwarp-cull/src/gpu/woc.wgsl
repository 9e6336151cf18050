// The per-pixel stages of the GPU WOC pipeline (seed 000 Sec. 5, thesis seed 002 Sec. IV.1)
// around the motion, warp, max-depth and cull kernels: reading the engine's previous depth and
// item textures, dropping opening rims before the warp (twin of zwarp_cull::opening_rims), the
// 1-pixel max erosion (twin of zwarp_cull::erode_max), and merging the rapid-motion objects'
// rasterized depth into the predicted depth (twin of zwarp_raster::draw_into's depth test).
// Host code: woc.rs. Bindings are per entry point (automatic layouts).

struct Params {
    width: u32,
    height: u32,
    // Opening-rim separation threshold in pixels per frame.
    min_separation: f32,
    // Objects for `forced_args`.
    n_objects: u32,
};

struct DrawArgs {
    index_count: u32,
    instance_count: u32,
    first_index: u32,
    base_vertex: i32,
    first_instance: u32,
};

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var depth_tex: texture_depth_2d;
@group(0) @binding(2) var item_tex: texture_2d<u32>;
@group(0) @binding(3) var<storage, read_write> depth_out: array<f32>;
@group(0) @binding(4) var<storage, read_write> items_out: array<u32>;
@group(0) @binding(5) var<storage, read> depth_in: array<f32>;
@group(0) @binding(6) var<storage, read> items_in: array<u32>;
// Motion samples: (v.x, v.y, target depth) per pixel.
@group(0) @binding(7) var<storage, read> motion: array<f32>;
@group(0) @binding(8) var<storage, read_write> out: array<f32>;
// Per object (first_index, index_count, base_vertex, slot), as the cull kernel reads them.
@group(0) @binding(9) var<storage, read> draws: array<vec4<u32>>;
@group(0) @binding(10) var<storage, read> forced: array<u32>;
@group(0) @binding(11) var<storage, read_write> forced_args: array<DrawArgs>;

const EMPTY_DEPTH: f32 = 1.0;
const NO_ITEM: u32 = 0xffffffffu;

// The previous frame's depth and item textures as tight row-major buffers.
@compute @workgroup_size(8, 8, 1)
fn gather(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= params.width || gid.y >= params.height) {
        return;
    }
    let i = gid.y * params.width + gid.x;
    let p = vec2<i32>(gid.xy);
    depth_out[i] = textureLoad(depth_tex, p, 0);
    items_out[i] = textureLoad(item_tex, p, 0).x;
}

// zwarp_cull::opening_rims: a surface texel next to a farther, different object that its
// motion pulls away from (by more than the threshold) becomes a far hole.
@compute @workgroup_size(8, 8, 1)
fn rims(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= params.width || gid.y >= params.height) {
        return;
    }
    let w = i32(params.width);
    let h = i32(params.height);
    let i = gid.y * params.width + gid.x;
    let d = depth_in[i];
    let id = items_in[i];
    var result = d;
    if (d < EMPTY_DEPTH && id != NO_ITEM) {
        let v = vec2<f32>(motion[3u * i], motion[3u * i + 1u]);
        let x = i32(gid.x);
        let y = i32(gid.y);
        // The CPU's neighbour order (only the first separating neighbour matters).
        let offs = array<vec2<i32>, 8>(vec2<i32>(-1, -1), vec2<i32>(0, -1), vec2<i32>(1, -1), vec2<i32>(-1, 0),
                                       vec2<i32>(1, 0), vec2<i32>(-1, 1), vec2<i32>(0, 1), vec2<i32>(1, 1));
        for (var k = 0; k < 8; k++) {
            let o = offs[k];
            let xx = x + o.x;
            let yy = y + o.y;
            if (xx < 0 || yy < 0 || xx >= w || yy >= h) {
                continue;
            }
            let j = u32(yy * w + xx);
            let dn = depth_in[j];
            let idn = items_in[j];
            if (idn == NO_ITEM || idn == id || dn >= EMPTY_DEPTH || dn <= d) {
                continue;
            }
            let rel = v - vec2<f32>(motion[3u * j], motion[3u * j + 1u]);
            if (-(rel.x * f32(o.x) + rel.y * f32(o.y)) > params.min_separation) {
                result = EMPTY_DEPTH;
                break;
            }
        }
    }
    out[i] = result;
}

// zwarp_cull::erode_max: the max over the 3x3 neighbourhood (neighbours outside ignored).
@compute @workgroup_size(8, 8, 1)
fn erode(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= params.width || gid.y >= params.height) {
        return;
    }
    let x0 = max(gid.x, 1u) - 1u;
    let x1 = min(gid.x + 1u, params.width - 1u);
    let y0 = max(gid.y, 1u) - 1u;
    let y1 = min(gid.y + 1u, params.height - 1u);
    var m = depth_in[gid.y * params.width + gid.x];
    for (var y = y0; y <= y1; y++) {
        for (var x = x0; x <= x1; x++) {
            m = max(m, depth_in[y * params.width + x]);
        }
    }
    out[gid.y * params.width + gid.x] = m;
}

// Draw arguments of the forced (rapid-motion) objects, one per draw slot, zero instances for
// the others.
@compute @workgroup_size(64, 1, 1)
fn forced_draws(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= params.n_objects) {
        return;
    }
    let d = draws[gid.x];
    let n = select(0u, 1u, forced[gid.x] != 0u);
    forced_args[d.w] = DrawArgs(d.y, n, d.x, bitcast<i32>(d.z), d.w);
}

// The rapid-motion objects' depth (rendered into a cleared target) merged by the depth test.
@compute @workgroup_size(8, 8, 1)
fn merge_min(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= params.width || gid.y >= params.height) {
        return;
    }
    let i = gid.y * params.width + gid.x;
    let z = textureLoad(depth_tex, vec2<i32>(gid.xy), 0);
    if (z < out[i]) {
        out[i] = z;
    }
}

// A depth buffer (width * height f32) into a caller's R32Float storage texture: the engine's
// own texture for a warped or predicted depth.
@group(0) @binding(12) var depth_target: texture_storage_2d<r32float, write>;

@compute @workgroup_size(8, 8, 1)
fn to_texture(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= params.width || gid.y >= params.height) {
        return;
    }
    let d = depth_in[gid.y * params.width + gid.x];
    textureStore(depth_target, vec2<i32>(gid.xy), vec4<f32>(d, 0.0, 0.0, 1.0));
}
