// Depth / item / colour rendering and depth peeling (seed 000, Sec. 3.4: the deep depth buffer
// is built by depth peeling [Everitt 2001]). Host code: depth.rs.
//
// Conventions (zwarp_core::Camera): the projection maps view depth to [0, 1]; wgpu's viewport maps NDC
// y = +1 to framebuffer row 0, which is zwarp's "row 0 = top", so no flip is needed anywhere.

struct Object {
    // view_proj * model, computed on the CPU in f32 exactly like the CPU rasterizer does, so both
    // rasterizers see the same clip-space vertices.
    mvp: mat4x4<f32>,
    // object -> world at time t (world position of shaded fragments).
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

// Shading inputs of the colour pipelines (host: scene.rs).
struct ShadeObject {
    // Object -> world at rest (the instance transform without animation): the pattern's space.
    rest: mat4x4<f32>,
    // Normal matrices (inverse transpose of the upper 3x3) at time t and at rest.
    nmat: mat3x3<f32>,
    nrest: mat3x3<f32>,
};

struct MaterialGpu {
    // xyz = linear base colour.
    base: vec4<f32>,
    // 0 = pattern, 1 = texture `tex`, 2 = uniform base colour.
    kind: u32,
    tex: u32,
    _pad0: u32,
    _pad1: u32,
};

struct TexInfo {
    // First texel in `texels`, size, wrap codes (u | v << 2; 0 repeat, 1 clamp, 2 mirror).
    offset: u32,
    width: u32,
    height: u32,
    wrap: u32,
};

@group(2) @binding(0) var<storage, read> shade_objects: array<ShadeObject>;
@group(2) @binding(1) var<storage, read> materials: array<MaterialGpu>;
@group(2) @binding(2) var<storage, read> tex_info: array<TexInfo>;
// Linear RGBA texels of every base-colour texture, row 0 at the top.
@group(2) @binding(3) var<storage, read> texels: array<vec4<f32>>;

@vertex
fn vs_depth(@location(0) pos: vec3<f32>, @builtin(instance_index) inst: u32) -> @builtin(position) vec4<f32> {
    return objects[draw_ids[inst]].mvp * vec4<f32>(pos, 1.0);
}

// Item-only pipelines (frames and peels without colour).
struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) @interpolate(flat) id: u32,
};

@vertex
fn vs_frame(@location(0) pos: vec3<f32>, @builtin(instance_index) inst: u32) -> VsOut {
    let id = draw_ids[inst];
    var out: VsOut;
    out.clip = objects[id].mvp * vec4<f32>(pos, 1.0);
    out.id = id;
    return out;
}

// Colour pipelines: object-space position, normal and UV interpolated perspective-correctly
// (the CPU resolve interpolates the same object-space quantities at the pixel centre).
struct VsShade {
    @builtin(position) clip: vec4<f32>,
    @location(0) obj: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) @interpolate(flat) id: u32,
    @location(4) @interpolate(flat) material: u32,
};

@vertex
fn vs_shade(
    @location(0) pos: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) uv: vec2<f32>,
    @location(3) material: u32,
    @builtin(instance_index) inst: u32,
) -> VsShade {
    let id = draw_ids[inst];
    var out: VsShade;
    out.clip = objects[id].mvp * vec4<f32>(pos, 1.0);
    out.obj = pos;
    out.normal = normal;
    out.uv = uv;
    out.id = id;
    out.material = material;
    return out;
}

struct FsOut {
    @location(0) item: u32,
    @location(1) color: vec4<f32>,
};

// ---- WGSL twins of zwarp_raster::shading (same constants, same operation order) ----

fn hash3(x: u32, y: u32, s: u32) -> u32 {
    var h = (x * 0x8da6b343u) ^ (y * 0xd8163841u) ^ (s * 0xcb1ab31fu);
    h = h ^ (h >> 16u);
    h = h * 0x7feb352du;
    h = h ^ (h >> 15u);
    h = h * 0x846ca68bu;
    h = h ^ (h >> 16u);
    return h;
}

fn hash_unit(x: u32, y: u32, s: u32) -> f32 {
    return f32(hash3(x, y, s) >> 8u) * (1.0 / 16777216.0);
}

fn value_noise(q: vec2<f32>, seed: u32) -> f32 {
    let fx = floor(q.x);
    let fy = floor(q.y);
    let x0 = bitcast<u32>(i32(fx));
    let y0 = bitcast<u32>(i32(fy));
    let tx = q.x - fx;
    let ty = q.y - fy;
    let sx = tx * tx * (3.0 - 2.0 * tx);
    let sy = ty * ty * (3.0 - 2.0 * ty);
    let x1 = x0 + 1u;
    let y1 = y0 + 1u;
    let a = hash_unit(x0, y0, seed) * (1.0 - sx) + hash_unit(x1, y0, seed) * sx;
    let b = hash_unit(x0, y1, seed) * (1.0 - sx) + hash_unit(x1, y1, seed) * sx;
    return a * (1.0 - sy) + b * sy;
}

fn stripe(q: vec2<f32>, dir: vec2<f32>, freq: f32) -> f32 {
    let t = (q.x * dir.x + q.y * dir.y) * freq;
    let f = t - floor(t);
    let tri = abs(2.0 * f - 1.0);
    return tri * tri * (3.0 - 2.0 * tri);
}

fn tint(id: u32, k: u32) -> vec3<f32> {
    return vec3<f32>(
        0.55 + 0.8 * hash_unit(id, k * 3u, 0x9e3779b9u),
        0.55 + 0.8 * hash_unit(id, k * 3u + 1u, 0x9e3779b9u),
        0.55 + 0.8 * hash_unit(id, k * 3u + 2u, 0x9e3779b9u),
    );
}

fn pattern_plane(q: vec2<f32>, axis: u32, id: u32, ta: vec3<f32>, tb: vec3<f32>) -> vec3<f32> {
    let seed = id * 16u + axis * 4u;
    let n1 = value_noise(q * 32.0, seed);
    let n2 = value_noise(q * 8.0, seed + 1u);
    let s1 = stripe(q, vec2<f32>(0.8, 0.6), 20.0);
    let s2 = stripe(q, vec2<f32>(-0.6, 0.8), 4.0);
    let s3 = stripe(q, vec2<f32>(1.0, 0.0), 0.6666667);
    let g = 0.45 + 0.3 * n1 + 0.17 * n2 + 0.08 * s1;
    let ka = 0.35 * s2;
    let kb = 0.3 * s3;
    return g * (vec3<f32>(1.0) + ka * (ta - vec3<f32>(1.0))) * (vec3<f32>(1.0) + kb * (tb - vec3<f32>(1.0)));
}

fn pattern(p: vec3<f32>, n: vec3<f32>, id: u32) -> vec3<f32> {
    let l2 = dot(n, n);
    var w = vec3<f32>(1.0 / 3.0);
    if (l2 > 0.0 && l2 < 3.0e38) {
        let a = abs(n / sqrt(l2));
        var ww = a * a;
        ww = ww * ww;
        w = ww / (ww.x + ww.y + ww.z);
    }
    let ta = tint(id, 0u);
    let tb = tint(id, 1u);
    var c = vec3<f32>(0.0);
    if (w.x > 0.0) {
        c += w.x * pattern_plane(vec2<f32>(p.y, p.z), 0u, id, ta, tb);
    }
    if (w.y > 0.0) {
        c += w.y * pattern_plane(vec2<f32>(p.z, p.x), 1u, id, ta, tb);
    }
    if (w.z > 0.0) {
        c += w.z * pattern_plane(vec2<f32>(p.x, p.y), 2u, id, ta, tb);
    }
    return c;
}

fn lambert(g0: vec3<f32>, s0: vec3<f32>, to_eye: vec3<f32>, l: vec3<f32>, ambient: f32) -> f32 {
    var g = g0;
    if (dot(g, to_eye) < 0.0) {
        g = -g;
    }
    var n = vec3<f32>(0.0);
    if (dot(s0, s0) > 1e-30) {
        n = normalize(s0);
        if (dot(n, g) < 0.0) {
            n = -n;
        }
    } else if (dot(g, g) > 0.0) {
        n = normalize(g);
    }
    return ambient + (1.0 - ambient) * max(dot(n, l), 0.0);
}

fn wrap_index(i: i32, n: i32, mode: u32) -> i32 {
    if (mode == 1u) {
        return clamp(i, 0, n - 1);
    }
    if (mode == 2u) {
        let p = 2 * n;
        var m = i % p;
        if (m < 0) {
            m += p;
        }
        if (m >= n) {
            return p - 1 - m;
        }
        return m;
    }
    var m = i % n;
    if (m < 0) {
        m += n;
    }
    return m;
}

fn texel(info: TexInfo, x: i32, y: i32) -> vec4<f32> {
    return texels[info.offset + u32(y) * info.width + u32(x)];
}

// zwarp_core::Texture::sample: bilinear, a (1 - f) + b f along x, then along y.
fn sample_texture(t: u32, uv: vec2<f32>) -> vec4<f32> {
    let info = tex_info[t];
    let w = i32(info.width);
    let h = i32(info.height);
    let x = uv.x * f32(w) - 0.5;
    let y = uv.y * f32(h) - 0.5;
    let fx = floor(x);
    let fy = floor(y);
    let ax = x - fx;
    let ay = y - fy;
    let x0 = i32(fx);
    let y0 = i32(fy);
    let wu = info.wrap & 3u;
    let wv = (info.wrap >> 2u) & 3u;
    let xa = wrap_index(x0, w, wu);
    let xb = wrap_index(x0 + 1, w, wu);
    let ya = wrap_index(y0, h, wv);
    let yb = wrap_index(y0 + 1, h, wv);
    let top = texel(info, xa, ya) * (1.0 - ax) + texel(info, xb, ya) * ax;
    let bottom = texel(info, xa, yb) * (1.0 - ax) + texel(info, xb, yb) * ax;
    return top * (1.0 - ay) + bottom * ay;
}

// The CPU resolve's shade_pixel: albedo = instance tint * base colour * (texture | pattern | 1),
// times the two-sided Lambert of the interpolated vertex normal (flat normal without one). The
// flat normal comes from the derivatives of the interpolated object-space position, which lie
// in the triangle's plane.
fn shade(v: VsShade) -> vec4<f32> {
    let g_obj = cross(dpdx(v.obj), dpdy(v.obj));
    let o = objects[v.id];
    let so = shade_objects[v.id];
    let world = (o.model * vec4<f32>(v.obj, 1.0)).xyz;
    var to_eye = frame.eye.xyz - world;
    if (frame.ortho != 0u) {
        to_eye = frame.eye.xyz;
    }
    let k = lambert(so.nmat * g_obj, so.nmat * v.normal, to_eye, frame.light.xyz, frame.light.w);
    let m = materials[v.material];
    let base = o.albedo.xyz * m.base.xyz;
    var albedo = base;
    if (m.kind == 1u) {
        albedo = base * sample_texture(m.tex, v.uv).xyz;
    } else if (m.kind == 0u) {
        var nr = so.nrest * g_obj;
        if (dot(v.normal, v.normal) > 1e-30) {
            nr = so.nrest * v.normal;
        }
        let rest = (so.rest * vec4<f32>(v.obj, 1.0)).xyz;
        albedo = base * pattern(rest, nr, v.id);
    }
    return vec4<f32>(albedo * k, 1.0);
}

@fragment
fn fs_frame_item(v: VsOut) -> @location(0) u32 {
    return v.id;
}

@fragment
fn fs_frame(v: VsShade) -> FsOut {
    var out: FsOut;
    out.item = v.id;
    out.color = shade(v);
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
fn fs_peel(v: VsShade) -> FsOut {
    // Shade first: derivatives must be taken while the whole 2x2 quad is still active.
    var out: FsOut;
    out.item = v.id;
    out.color = shade(v);
    let prev = textureLoad(prev_depth, vec2<i32>(v.clip.xy), 0).x;
    // v.clip.xy is the pixel centre (x + 0.5, y + 0.5), as on the CPU.
    if (v.clip.z <= peel_threshold(v.clip.x, v.clip.y, prev)) {
        discard;
    }
    return out;
}
