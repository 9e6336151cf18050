// The adaptive grid warp of seed 003 Sec. 5.1 with the GPU's rasteriser: the twin of
// `zwarp_vr::grid::raster`. Each instance is one cell (two triangles, corners in
// `zwarp_vr::grid::CELL_TRIANGLES` order) or one splat; vertices go through the one combined
// warp matrix; the fragment fetches colour with the mesh's filter and writes the source
// texel's own reprojected depth.

struct Params {
    // Source pixel + depth -> target (X w, Y w, z, w), target pixel units.
    matrix: mat4x4<f32>,
    // Target width, height; source width, height.
    size: vec4<f32>,
    // 0 nearest, 1 bilinear, 2 adaptive (connectivity bits).
    filter_mode: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
// Source linear RGB, 3 floats per pixel.
@group(0) @binding(1) var<storage, read> color: array<f32>;
// Source depth per pixel.
@group(0) @binding(2) var<storage, read> depth: array<f32>;
// Connectivity bits per pixel (zwarp_vr::quadtree::DIRS order).
@group(0) @binding(3) var<storage, read> links: array<u32>;

struct VsOut {
    @builtin(position) pos: vec4<f32>,
    // Source position (pixel units), perspective-correct.
    @location(0) uv: vec2<f32>,
    // The primitive's source rectangle; texture coordinates stay inside it.
    @location(1) @interpolate(flat) rect: vec4<f32>,
}

// Target (X w, Y w, z, w) -> clip space. z is halved so that target depths up to 2 stay inside
// the clip volume (the CPU rasteriser keeps depths beyond the far plane, e.g. the sky's); the
// depth test order is unchanged (halving is exact).
fn to_clip(h: vec4<f32>) -> vec4<f32> {
    return vec4<f32>(2.0 * h.x / params.size.x - h.w, h.w - 2.0 * h.y / params.size.y, 0.5 * h.z, h.w);
}

@vertex
fn vs_cell(@builtin(vertex_index) vi: u32, @location(0) r: vec4<u32>, @location(1) d: vec4<f32>) -> VsOut {
    let order = array<u32, 6>(0u, 1u, 3u, 0u, 3u, 2u);
    let c = order[vi];
    let x = select(r.x, r.z, c % 2u == 1u);
    let y = select(r.y, r.w, c >= 2u);
    let p = vec2<f32>(f32(x), f32(y));
    let h = params.matrix * vec4<f32>(p, d[c], 1.0);
    // The CPU drops a triangle with a corner behind the target eye (w <= 1e-9): collapse it.
    let tri = vi / 3u;
    var behind = false;
    for (var j = 0u; j < 3u; j++) {
        let cj = order[tri * 3u + j];
        let pj = vec2<f32>(f32(select(r.x, r.z, cj % 2u == 1u)), f32(select(r.y, r.w, cj >= 2u)));
        let hj = params.matrix * vec4<f32>(pj, d[cj], 1.0);
        if !(hj.w > 1e-9) {
            behind = true;
        }
    }
    var out: VsOut;
    out.pos = select(to_clip(h), vec4<f32>(0.0, 0.0, 0.0, 1.0), behind);
    out.uv = p;
    out.rect = vec4<f32>(f32(r.x), f32(r.y), f32(r.z), f32(r.w));
    return out;
}

@vertex
fn vs_point(@builtin(instance_index) ii: u32) -> VsOut {
    let sw = u32(params.size.z);
    let p = vec2<f32>(f32(ii % sw) + 0.5, f32(ii / sw) + 0.5);
    let h = params.matrix * vec4<f32>(p, depth[ii], 1.0);
    var out: VsOut;
    // Behind the eye: outside the clip volume.
    out.pos = select(vec4<f32>(0.0, 0.0, -1.0, 1.0), to_clip(h), h.w > 1e-9);
    out.uv = p;
    out.rect = vec4<f32>(floor(p), floor(p) + 1.0);
    return out;
}

fn texel(x: i32, y: i32) -> vec3<f32> {
    let i = 3u * (u32(y) * u32(params.size.z) + u32(x));
    return vec3<f32>(color[i], color[i + 1u], color[i + 2u]);
}

// zwarp_vr::quadtree::dir_bit.
fn dir_bit(dx: i32, dy: i32) -> u32 {
    var i = 0u;
    if dx == -1 && dy == 0 { i = 1u; }
    if dx == 0 && dy == 1 { i = 2u; }
    if dx == 0 && dy == -1 { i = 3u; }
    if dx == 1 && dy == 1 { i = 4u; }
    if dx == -1 && dy == 1 { i = 5u; }
    if dx == 1 && dy == -1 { i = 6u; }
    if dx == -1 && dy == -1 { i = 7u; }
    return 1u << i;
}

// QuadTree::connected.
fn connected(x: i32, y: i32, dx: i32, dy: i32) -> bool {
    let w = i32(params.size.z);
    let h = i32(params.size.w);
    let inside = x >= 0 && y >= 0 && x < w && y < h && x + dx >= 0 && y + dy >= 0 && x + dx < w && y + dy < h;
    return inside && (links[u32(y) * u32(w) + u32(x)] & dir_bit(dx, dy)) != 0u;
}

// zwarp_vr::grid::sample: nearest, bilinear, or bilinear over the texels connected to the
// nearest one.
fn sample(uv: vec2<f32>) -> vec3<f32> {
    let w = i32(params.size.z);
    let h = i32(params.size.w);
    let nx = clamp(i32(floor(uv.x)), 0, w - 1);
    let ny = clamp(i32(floor(uv.y)), 0, h - 1);
    if params.filter_mode == 0u {
        return texel(nx, ny);
    }
    let f = uv - vec2<f32>(0.5);
    let x0 = i32(floor(f.x));
    let y0 = i32(floor(f.y));
    let ax = f.x - f32(x0);
    let ay = f.y - f32(y0);
    var acc = vec3<f32>(0.0);
    var wsum = 0.0;
    for (var k = 0; k < 4; k++) {
        let dx = k % 2;
        let dy = k / 2;
        let wt = select(1.0 - ax, ax, dx == 1) * select(1.0 - ay, ay, dy == 1);
        let tx = clamp(x0 + dx, 0, w - 1);
        let ty = clamp(y0 + dy, 0, h - 1);
        let ok = (tx == nx && ty == ny) || params.filter_mode == 1u || connected(nx, ny, tx - nx, ty - ny);
        if ok && wt > 0.0 {
            acc += wt * texel(tx, ty);
            wsum += wt;
        }
    }
    if wsum <= 0.0 {
        return texel(nx, ny);
    }
    return acc / wsum;
}

struct FsOut {
    // Linear RGB, alpha 1 where covered (0 = hole).
    @location(0) color: vec4<f32>,
    // Target depth of the surface shown.
    @location(1) depth: f32,
}

@fragment
fn fs_main(v: VsOut) -> FsOut {
    // Inside the primitive's rectangle, off its border by a hair (the nearest texel stays in it).
    let q = clamp(v.uv, v.rect.xy + vec2<f32>(1e-3), v.rect.zw - vec2<f32>(1e-3));
    let w = i32(params.size.z);
    let h = i32(params.size.w);
    let nx = clamp(i32(floor(q.x)), 0, w - 1);
    let ny = clamp(i32(floor(q.y)), 0, h - 1);
    // The source texel's own depth reprojected (zwarp_vr::grid::resolve).
    let hz = params.matrix * vec4<f32>(f32(nx) + 0.5, f32(ny) + 0.5, depth[u32(ny) * u32(w) + u32(nx)], 1.0);
    var z = clamp(2.0 * v.pos.z, 0.0, 1.0);
    if hz.w > 1e-9 {
        let zt = hz.z / hz.w;
        // Finite (the rasteriser's own depth otherwise).
        if zt == zt && abs(zt) < 3.0e38 {
            z = clamp(zt, 0.0, 1.0);
        }
    }
    var out: FsOut;
    out.color = vec4<f32>(sample(q), 1.0);
    out.depth = z;
    return out;
}
