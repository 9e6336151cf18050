// Copies a Depth32Float texture into a storage buffer of f32 (row stride in elements). Used
// instead of copy_texture_to_buffer, which GLES-class adapters cannot do for depth formats
// (missing DEPTH_TEXTURE_AND_BUFFER_COPIES); one path everywhere, bit-exact. Host: depth.rs.

struct CopyParams {
    width: u32,
    height: u32,
    stride: u32,
    _pad: u32,
};

@group(0) @binding(0) var src: texture_2d<f32>;
@group(0) @binding(1) var<storage, read_write> dst: array<f32>;
@group(0) @binding(2) var<uniform> params: CopyParams;

@compute @workgroup_size(8, 8, 1)
fn copy_depth(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= params.width || gid.y >= params.height) {
        return;
    }
    dst[gid.y * params.stride + gid.x] = textureLoad(src, vec2<i32>(gid.xy), 0).x;
}
