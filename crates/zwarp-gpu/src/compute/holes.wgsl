// Hole filling of a warped depth buffer as a post-pass (seed 000 Sec. 3.5, Fig. 8; Sec. 4's
// background fill): the WGSL twin of zwarp_warp::fill_holes with FillRule::Nearest
// (HolePolicy::Dilate, zwarp_warp::dilate_holes) and FillRule::Background. Only converged
// pixels are read, so one pass over a copy gives the CPU's order-independent result. Host
// code: holes.rs.

struct Params {
    width: u32,
    height: u32,
    radius: u32,
    // 0 = Nearest (Fig. 8 dilation), 1 = Background.
    rule: u32,
};

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> in_depth: array<f32>;
@group(0) @binding(2) var<storage, read> in_state: array<u32>;
@group(0) @binding(3) var<storage, read_write> out_depth: array<f32>;
@group(0) @binding(4) var<storage, read_write> out_state: array<u32>;

const CONVERGED: u32 = 0u;
const FILLED: u32 = 1u;
const HOLE: u32 = 2u;

// Nearest converged pixel from (x, y) along (dx, dy) within the radius: (k, depth), k = 0 if
// none (the image edge or the radius ends the probe).
fn probe(x: i32, y: i32, dx: i32, dy: i32) -> vec2<f32> {
    let w = i32(params.width);
    let h = i32(params.height);
    for (var k = 1; k <= i32(params.radius); k++) {
        let xx = x + dx * k;
        let yy = y + dy * k;
        if (xx < 0 || yy < 0 || xx >= w || yy >= h) {
            return vec2<f32>(0.0, 0.0);
        }
        let i = u32(yy * w + xx);
        if (in_state[i] == CONVERGED) {
            return vec2<f32>(f32(k), in_depth[i]);
        }
    }
    return vec2<f32>(0.0, 0.0);
}

@compute @workgroup_size(8, 8, 1)
fn fill(@builtin(global_invocation_id) gid: vec3<u32>) {
    if (gid.x >= params.width || gid.y >= params.height) {
        return;
    }
    let i = gid.y * params.width + gid.x;
    var d = in_depth[i];
    var s = in_state[i];
    if (s == HOLE) {
        let x = i32(gid.x);
        let y = i32(gid.y);
        // Horizontal, vertical, both diagonals (zwarp_warp's DIRS order), each probed both ways.
        let dirs = array<vec2<i32>, 4>(vec2<i32>(1, 0), vec2<i32>(0, 1), vec2<i32>(1, 1), vec2<i32>(1, -1));
        if (params.rule == 0u) {
            // Surrounded along all four directions; nearest neighbour wins, ties the farther.
            var best_d = -1.0;
            var best_z = 0.0;
            var surrounded = true;
            for (var j = 0; j < 4; j++) {
                let dir = dirs[j];
                let step = select(1.0, 1.4142135, dir.x != 0 && dir.y != 0);
                let a = probe(x, y, dir.x, dir.y);
                let b = probe(x, y, -dir.x, -dir.y);
                if (a.x == 0.0 || b.x == 0.0) {
                    surrounded = false;
                    break;
                }
                for (var e = 0; e < 2; e++) {
                    let p = select(a, b, e == 1);
                    let dist = p.x * step;
                    let keep = best_d >= 0.0 && (best_d < dist || (best_d == dist && best_z >= p.y));
                    if (!keep) {
                        best_d = dist;
                        best_z = p.y;
                    }
                }
            }
            if (surrounded && best_d >= 0.0) {
                d = best_z;
                s = FILLED;
            }
        } else {
            // Bracketed along at least one direction; the farthest probe result wins.
            var found = false;
            var farthest = 0.0;
            var bracketed = false;
            for (var j = 0; j < 4; j++) {
                let dir = dirs[j];
                let a = probe(x, y, dir.x, dir.y);
                let b = probe(x, y, -dir.x, -dir.y);
                bracketed = bracketed || (a.x != 0.0 && b.x != 0.0);
                if (a.x != 0.0) {
                    farthest = select(a.y, max(farthest, a.y), found);
                    found = true;
                }
                if (b.x != 0.0) {
                    farthest = select(b.y, max(farthest, b.y), found);
                    found = true;
                }
            }
            if (found && bracketed) {
                d = farthest;
                s = FILLED;
            }
        }
    }
    out_depth[i] = d;
    out_state[i] = s;
}
