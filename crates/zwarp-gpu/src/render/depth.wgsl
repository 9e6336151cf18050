// Depth / item / colour rendering and depth peeling (seed 000, Sec. 3.4: the deep depth buffer
// is built by depth peeling [Everitt 2001]). Host code: depth.rs.
//
// Conventions (DESIGN.md): the projection maps view depth to [0, 1]; wgpu's viewport maps NDC
// y = +1 to framebuffer row 0, which is zwarp's "row 0 = top", so no flip is needed anywhere.

struct Object {
    // view_proj * model, computed on the CPU in f32 exactly like the CPU rasterizer does, so both
    // rasterizers see the same clip-space vertices.
    mvp: mat4x4<f32>,
    // object -> world, for world-space shading normals.
    model: mat4x4<f32>,
    // xyz = linear albedo.
    albedo: vec4<f32>,
};

struct Frame {
    // xyz = world-space eye (perspective) or the unit direction towards the camera (orthographic).
    eye: vec4<f32>,
    // xyz = unit world direction towards the light, w = ambient term.
    light: vec4<f32>,
    // 1 = orthographic camera.
    ortho: u32,
    // Umbra culling of the peel pass: 0 = none (standard peeling), 1 = disc, 2 = directions.
    umbra: u32,
    _pad0: u32,
    _pad1: u32,
    // (width, height, near, far).
    cam0: vec4<f32>,
    // (tan(fov_y / 2) | 0, half_height | 0, e | tan(max_angle), c).
    cam1: vec4<f32>,
};

@group(0) @binding(0) var<storage, read> objects: array<Object>;
// Object id of each drawn instance: draws are batched per mesh and `instance_index` walks this
// list, so the item buffer stores the scene's object id (its index in Scene::instances).
@group(0) @binding(1) var<storage, read> draw_ids: array<u32>;
@group(0) @binding(2) var<uniform> frame: Frame;

// Depth of the previously peeled layer (peel pass only), bound as an unfilterable float
// texture: `textureLoad` from `texture_depth_2d` has no GLSL translation (GLES backend).
@group(1) @binding(0) var prev_depth: texture_2d<f32>;

@vertex
fn vs_depth(@location(0) pos: vec3<f32>, @builtin(instance_index) inst: u32) -> @builtin(position) vec4<f32> {
    return objects[draw_ids[inst]].mvp * vec4<f32>(pos, 1.0);
}

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) @interpolate(flat) id: u32,
};

@vertex
fn vs_frame(@location(0) pos: vec3<f32>, @builtin(instance_index) inst: u32) -> VsOut {
    let id = draw_ids[inst];
    let o = objects[id];
    var out: VsOut;
    out.clip = o.mvp * vec4<f32>(pos, 1.0);
    out.world = (o.model * vec4<f32>(pos, 1.0)).xyz;
    out.id = id;
    return out;
}

struct FsOut {
    @location(0) item: u32,
    @location(1) color: vec4<f32>,
};

// Flat two-sided Lambert, albedo * (ambient + (1 - ambient) * max(0, n . l)) as on the CPU: the derivatives of the perspective-correct world position lie in the
// triangle's plane, so their cross product is the flat triangle normal; it is turned towards
// the viewer so back faces shade like front faces (the renderer draws both sides).
fn shade(world: vec3<f32>, id: u32) -> vec4<f32> {
    var n = cross(dpdx(world), dpdy(world));
    let len = length(n);
    var to_eye = frame.eye.xyz - world;
    if (frame.ortho != 0u) {
        to_eye = frame.eye.xyz;
    }
    if (len > 0.0) {
        n = n / len;
    } else {
        n = normalize(to_eye);
    }
    if (dot(n, to_eye) < 0.0) {
        n = -n;
    }
    let ambient = frame.light.w;
    let k = ambient + (1.0 - ambient) * max(dot(n, frame.light.xyz), 0.0);
    return vec4<f32>(objects[id].albedo.xyz * k, 1.0);
}

@fragment
fn fs_frame_item(v: VsOut) -> @location(0) u32 {
    return v.id;
}

@fragment
fn fs_frame(v: VsOut) -> FsOut {
    var out: FsOut;
    out.item = v.id;
    out.color = shade(v.world, v.id);
    return out;
}

fn linear_depth(d: f32) -> f32 {
    let n = frame.cam0.z;
    let f = frame.cam0.w;
    if (frame.ortho != 0u) {
        return n + d * (f - n);
    }
    return f * n / (f - d * (f - n));
}

fn stored_depth(lin: f32) -> f32 {
    let n = frame.cam0.z;
    let f = frame.cam0.w;
    if (frame.ortho != 0u) {
        return (lin - n) / (f - n);
    }
    return f * (lin - n) / ((f - n) * lin);
}

// Peel threshold of the previous layer's pixel (px, py) with stored depth d: fragments at or in
// front of it are discarded. Standard peeling: d. Umbra culling (seed 000 eq. (1)), the same
// formulas as zwarp_raster::UmbraPeeling::umbra_extent: max(stored(lin(d) + x), d), or 2 (past
// every depth: nothing is peeled behind this pixel) when x is infinite. Empty pixels (d >= 1)
// give 1, which discards everything as well.
fn peel_threshold(px: f32, py: f32, d: f32) -> f32 {
    if (frame.umbra == 0u || d >= 1.0) {
        return d;
    }
    let w = frame.cam0.x;
    let h = frame.cam0.y;
    let lin = linear_depth(d);
    let ndc_x = px / w * 2.0 - 1.0;
    let ndc_y = 1.0 - py / h * 2.0;
    let aspect = w / h;
    let radial = sqrt(ndc_x * ndc_x * aspect * aspect + ndc_y * ndc_y);
    var s: f32;
    var r: f32;
    if (frame.ortho != 0u) {
        r = frame.cam1.y * radial;
        s = frame.cam1.y / h;
    } else {
        let th = frame.cam1.x;
        r = lin * th * radial;
        s = lin * th / h;
    }
    var x: f32;
    var infinite = false;
    if (frame.umbra == 1u) {
        let e = frame.cam1.z;
        let c = frame.cam1.w;
        let dc = lin - c;
        if (dc <= 0.0) {
            x = 0.0;
        } else {
            var hh = r;
            if (frame.ortho == 0u) {
                hh = r * abs(c) / lin;
            }
            let denom = (e + hh) - s;
            if (denom <= 0.0) {
                infinite = true;
            } else {
                x = dc * s / denom;
            }
        }
    } else {
        let tn = frame.cam1.z;
        if (tn <= 0.0) {
            infinite = true;
        } else {
            x = s / tn;
        }
    }
    if (infinite) {
        return 2.0;
    }
    return max(stored_depth(lin + x), d);
}

// Depth peeling: keep only fragments strictly behind the previous layer's threshold. Where the
// previous layer is empty (depth 1) nothing can lie behind it, so the layer stays empty.
@fragment
fn fs_peel_item(v: VsOut) -> @location(0) u32 {
    let prev = textureLoad(prev_depth, vec2<i32>(v.clip.xy), 0).x;
    if (v.clip.z <= peel_threshold(v.clip.x, v.clip.y, prev)) {
        discard;
    }
    return v.id;
}

@fragment
fn fs_peel(v: VsOut) -> FsOut {
    // Shade first: derivatives must be taken while the whole 2x2 quad is still active.
    var out: FsOut;
    out.item = v.id;
    out.color = shade(v.world, v.id);
    let prev = textureLoad(prev_depth, vec2<i32>(v.clip.xy), 0).x;
    // v.clip.xy is the pixel centre (x + 0.5, y + 0.5), as on the CPU.
    if (v.clip.z <= peel_threshold(v.clip.x, v.clip.y, prev)) {
        discard;
    }
    return out;
}
