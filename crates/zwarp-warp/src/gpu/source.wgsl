// An engine's own source images copied into the tight buffers the motion kernel and the warp
// read (seed 000 Sec. 3: the source view's depth layers and item buffer), bit-exact: a depth
// texture (Depth32Float or R32Float, textureLoad, as GLES-class adapters cannot copy depth
// textures to buffers), an item texture (R32Uint), or a buffer of 4-byte texels with a row
// stride. Host code: source.rs.

struct Params {
    width: u32,
    height: u32,
    // `words`: texels per source row (>= width).
    stride: u32,
    _pad: u32,
};

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> dst: array<u32>;
@group(0) @binding(2) var depth_tex: texture_2d<f32>;
@group(0) @binding(3) var item_tex: texture_2d<u32>;
@group(0) @binding(4) var<storage, read> words: array<u32>;

@compute @workgroup_size(8, 8, 1)
fn depth_texture(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= params.width || gid.y >= params.height) {
        return;
    }
    dst[gid.y * params.width + gid.x] = bitcast<u32>(textureLoad(depth_tex, vec2<i32>(gid.xy), 0).x);
}

@compute @workgroup_size(8, 8, 1)
fn item_texture(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= params.width || gid.y >= params.height) {
        return;
    }
    dst[gid.y * params.width + gid.x] = textureLoad(item_tex, vec2<i32>(gid.xy), 0).x;
}

@compute @workgroup_size(8, 8, 1)
fn strided_buffer(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= params.width || gid.y >= params.height) {
        return;
    }
    dst[gid.y * params.width + gid.x] = words[gid.y * params.stride + gid.x];
}
