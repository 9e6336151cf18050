// Max-depth queries over a GPU max structure (seed 000 Sec. 5.2; thesis seed 002 Sec. III.2):
// the WGSL twin of `MaxDepthQuery::max_depth` of zwarp_cull's MaxMipmap / NBuffer / YMap.
// Included (prepended) by maxdepth.wgsl and cull.wgsl, which declare the two globals:
//   md_levels: array<vec4<u32>>  [0] = (kind, n_mip, n_nbuf, switch), [1] = (width, height, 0, 0),
//                                [2 + i] = (offset, width, height, 0) of level i: the n_mip mip
//                                levels first, then the n_nbuf N-buffer levels.
//   md_data:   array<f32>        every level, row-major, at its offset.
// Kinds: 0 = max mipmap, 1 = N-buffer, 2 = Y-map (mip levels 0..switch, N-buffer over mip
// level `switch`). Max is exact in f32, so every answer equals the CPU one bit for bit.

const MD_EMPTY_DEPTH: f32 = 1.0;

fn md_level(i: u32) -> vec4<u32> {
    return md_levels[2u + i];
}

// Max over the texels of mip level `k` holding the (clamped) rect [r.x, r.z) x [r.y, r.w).
fn md_mip_max_at(r: vec4<u32>, k: u32) -> f32 {
    let l = md_level(k);
    let tx0 = r.x >> k;
    let ty0 = r.y >> k;
    let tx1 = min((r.z - 1u) >> k, l.y - 1u);
    let ty1 = min((r.w - 1u) >> k, l.z - 1u);
    var m = md_data[l.x + ty0 * l.y + tx0];
    for (var ty = ty0; ty <= ty1; ty++) {
        let row = l.x + ty * l.y;
        for (var tx = tx0; tx <= tx1; tx++) {
            m = max(m, md_data[row + tx]);
        }
    }
    return m;
}

// zwarp_cull::MaxMipmap::query_level: finest level where the rect spans <= 2x2 texels.
fn md_mip_query(r: vec4<u32>, n_levels: u32) -> f32 {
    let x1 = r.z - 1u;
    let y1 = r.w - 1u;
    var k = 0u;
    loop {
        if (k + 1u >= n_levels) {
            break;
        }
        if ((x1 >> k) - (r.x >> k) <= 1u && (y1 >> k) - (r.y >> k) <= 1u) {
            break;
        }
        k++;
    }
    return md_mip_max_at(r, k);
}

fn md_floor_log2(v: u32) -> u32 {
    return 31u - countLeadingZeros(v);
}

// zwarp_cull::NBuffer::max_exact over N-buffer levels starting at list index `base`: the
// ceil(a/s) x ceil(b/s) squares of side s = 2^floor(log2 min(a, b)) cover the rect exactly
// (the last square of a row/column is pulled back to end at the rect's edge).
fn md_nbuf_exact(r: vec4<u32>, base: u32, n_levels: u32) -> f32 {
    let a = r.z - r.x;
    let b = r.w - r.y;
    let m = min(md_floor_log2(min(a, b)), n_levels - 1u);
    let s = 1u << m;
    let l = md_level(base + m);
    let nx = (a + s - 1u) / s;
    let ny = (b + s - 1u) / s;
    var best = md_data[l.x + r.y * l.y + r.x];
    for (var j = 0u; j < ny; j++) {
        let ty = min(r.y + j * s, r.w - s);
        let row = l.x + ty * l.y;
        for (var i = 0u; i < nx; i++) {
            let tx = min(r.x + i * s, r.z - s);
            best = max(best, md_data[row + tx]);
        }
    }
    return best;
}

// MaxDepthQuery::max_depth: upper bound (exact for N-buffers) of the max depth over the pixel
// rect [r.x, r.z) x [r.y, r.w) (not yet clamped); EMPTY_DEPTH when nothing is left after
// clamping to the image.
fn md_max_depth(rect: vec4<u32>) -> f32 {
    let head = md_levels[0];
    let size = md_levels[1].xy;
    let r = vec4<u32>(rect.xy, min(rect.zw, size));
    if (r.x >= r.z || r.y >= r.w) {
        return MD_EMPTY_DEPTH;
    }
    let kind = head.x;
    if (kind == 0u) {
        return md_mip_query(r, head.y);
    }
    if (kind == 1u) {
        return md_nbuf_exact(r, 0u, head.z);
    }
    // Y-map: a mip level below the switch when the rect spans <= 2x2 texels there.
    let k = head.w;
    let x1 = r.z - 1u;
    let y1 = r.w - 1u;
    for (var j = 0u; j < k; j++) {
        if ((x1 >> j) - (r.x >> j) <= 1u && (y1 >> j) - (r.y >> j) <= 1u) {
            return md_mip_max_at(r, j);
        }
    }
    // The switch-level texels containing the rect, queried exactly in the N-buffer.
    let t = vec4<u32>(r.x >> k, r.y >> k, (x1 >> k) + 1u, (y1 >> k) + 1u);
    return md_nbuf_exact(t, head.y, head.z);
}
