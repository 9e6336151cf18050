//! Geometry front end: instance selection, vertex transform, near/guard-band clipping, exact
//! fixed-point triangle setup and binning into screen tiles.
//!
//! Everything here runs once per render call; the per-tile back end (`kernel.rs`) only reads the
//! resulting [`Binned`] structure, so several raster passes (depth peeling) share one setup.

use glam::{DMat4, DVec4, Mat4, Vec3};
use rayon::prelude::*;
use zwarp_core::{Camera, Error, Result, Scene};

/// Tile width in pixels (multiple of the 8-lane chunk width of the kernel).
pub(crate) const TILE_W: usize = 64;
/// Tile height in pixels.
pub(crate) const TILE_H: usize = 32;
/// Sub-pixel precision: vertex positions are snapped to 1/256 pixel (8 sub-pixel bits).
pub(crate) const SUBPIXEL_BITS: u32 = 8;
const SUB: f64 = (1u32 << SUBPIXEL_BITS) as f64;
/// Guard band in pixels around the viewport. Triangles reaching beyond it are clipped in clip
/// space; inside it snapped coordinates stay below 2^23 sub-pixel units, which keeps the
/// per-row i32 edge evaluation of the kernel overflow-free (see `kernel.rs`).
const GUARD_PX: f64 = 4096.0;
/// Largest image side the fixed-point pipeline supports (bounding boxes are stored as u16 and the
/// kernel's i32 range argument assumes it).
pub(crate) const MAX_SIDE: u32 = 16384;
/// Source triangles per setup chunk. Fixed (not derived from the thread count) so that the order
/// in which a tile sees its triangles, and thus the tie-breaking of equal depths, is
/// deterministic.
const CHUNK_TRIS: usize = 4096;
/// Vertices per parallel transform task.
const CHUNK_VERTS: usize = 16384;

/// One set-up triangle, ready for the tile kernel.
///
/// Coverage: pixel `(x, y)` (integer indices, sample at the centre) is covered iff
/// `a[i] * x + b[i] * y + c[i] >= 0` for the three edges. The top-left fill rule and the
/// sub-pixel offset of the pixel centre are folded into `c` (see [`setup_projected`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Tri {
    pub a: [i32; 3],
    pub b: [i32; 3],
    pub c: [i64; 3],
    /// Depth plane at pixel centres: `z(x, y) = z0 + zx * x + zy * y` (x, y pixel indices).
    pub z0: f64,
    pub zx: f64,
    pub zy: f64,
    /// Conservative lower bound of the triangle's depth (early-z).
    pub zmin: f32,
    /// Conservative upper bound of the triangle's depth (peeling: skip triangles entirely in
    /// front of a tile's threshold).
    pub zmax: f32,
    /// Inclusive pixel bounding box of the covered pixel centres, clamped to the viewport.
    pub x0: u16,
    pub y0: u16,
    pub x1: u16,
    pub y1: u16,
    /// Instance id (item-buffer value).
    pub inst: u32,
}

/// Clamps an interpolated depth at 0 (rounding can dip a hair below the near plane). Written as a
/// compare + select (not `f32::max`, whose NaN handling costs extra instructions per lane); the
/// tile kernel and [`Tri::depth_at`] both use it, so every evaluation agrees bit for bit.
#[inline(always)]
pub(crate) fn clamp_depth(z: f32) -> f32 {
    if z > 0.0 {
        z
    } else {
        0.0
    }
}

impl Tri {
    /// Depth of this triangle at pixel `(x, y)`, computed exactly as the tile kernel does
    /// (row value at the tile's left edge in f64, then one f32 multiply-add), so that the same
    /// fragment always gets the same bits whichever function evaluates it.
    #[inline]
    pub fn depth_at(&self, x: u32, y: u32) -> f32 {
        let tx = x - x % TILE_W as u32;
        let row = self.row_depth(tx, y);
        clamp_depth(row + self.zx as f32 * (x - tx) as f32)
    }
    /// Depth at the left edge `tx` of a tile row (f64 plane rounded once to f32).
    #[inline]
    pub fn row_depth(&self, tx: u32, y: u32) -> f32 {
        (self.z0 + self.zx * tx as f64 + self.zy * y as f64) as f32
    }
    /// Edge `i` at pixel `(x, y)` in exact 64-bit arithmetic.
    #[inline]
    pub fn edge_at(&self, i: usize, x: i64, y: i64) -> i64 {
        self.a[i] as i64 * x + self.b[i] as i64 * y + self.c[i]
    }
}

/// Viewport constants shared by setup.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Viewport {
    pub width: u32,
    pub height: u32,
    /// Guard-band limits in NDC (`|x_ndc| <= gx`).
    gx: f64,
    gy: f64,
}

impl Viewport {
    pub fn new(width: u32, height: u32) -> Result<Self> {
        if width == 0 || height == 0 {
            return Err(Error::invalid(format!("zero-size image {width}x{height}")));
        }
        if width > MAX_SIDE || height > MAX_SIDE {
            return Err(Error::invalid(format!(
                "image {width}x{height} exceeds the rasterizer's maximum side of {MAX_SIDE} pixels"
            )));
        }
        Ok(Viewport {
            width,
            height,
            gx: 1.0 + 2.0 * GUARD_PX / width as f64,
            gy: 1.0 + 2.0 * GUARD_PX / height as f64,
        })
    }
    pub fn tiles_x(&self) -> usize {
        (self.width as usize).div_ceil(TILE_W)
    }
    pub fn tiles_y(&self) -> usize {
        (self.height as usize).div_ceil(TILE_H)
    }
    pub fn tile_count(&self) -> usize {
        self.tiles_x() * self.tiles_y()
    }
}

/// A clip-space vertex. The front end works in f64: vertices are transformed by the f64 copy of
/// `proj * view * model`, so depth far from the vertices (large triangles, clipped triangles) keeps
/// ~1e-7 relative accuracy instead of inheriting f32 rounding amplified by extrapolation.
type Clip = DVec4;

/// Signed distances of a clip-space vertex to the clip planes we may need: near (z >= 0) and the
/// four guard-band planes. Positive = inside.
#[inline]
fn plane_dist(v: Clip, plane: usize, vp: &Viewport) -> f64 {
    match plane {
        0 => v.z,
        1 => vp.gx * v.w - v.x,
        2 => vp.gx * v.w + v.x,
        3 => vp.gy * v.w - v.y,
        _ => vp.gy * v.w + v.y,
    }
}

/// Output of the set-up of one source triangle (0..=6 screen triangles after clipping).
pub(crate) trait TriSink {
    fn push(&mut self, t: Tri);
}

impl TriSink for Vec<Tri> {
    #[inline]
    fn push(&mut self, t: Tri) {
        Vec::push(self, t)
    }
}

/// Clips (if needed) and sets up the clip-space triangle `v`, pushing the resulting screen
/// triangles into `out`. Returns nothing: rejected triangles simply push nothing.
///
/// Trivial rejection: all three vertices outside the same frustum plane (left/right/top/bottom,
/// near, or beyond the far plane — the depth of a triangle is affine in screen space, so if all
/// vertices are beyond `z = 1` every fragment is, and fragments with depth > 1 are discarded).
/// Triangles crossing the near plane are clipped against `z_clip = 0` (exact: the visible part is
/// drawn with its true depths); triangles reaching beyond the guard band are clipped against it,
/// which only moves edges outside the viewport.
#[inline(always)]
pub(crate) fn setup_clip_triangle(v: [Clip; 3], vp: &Viewport, inst: u32, out: &mut impl TriSink) {
    // Outcodes against the view frustum (with w > 0 implied by z >= 0 for our projections).
    let code = |p: Clip| -> u32 {
        (p.x < -p.w) as u32
            | ((p.x > p.w) as u32) << 1
            | ((p.y < -p.w) as u32) << 2
            | ((p.y > p.w) as u32) << 3
            | ((p.z < 0.0) as u32) << 4
            | ((p.z > p.w) as u32) << 5
    };
    let (c0, c1, c2) = (code(v[0]), code(v[1]), code(v[2]));
    if c0 & c1 & c2 != 0 {
        return;
    }
    // Which clip planes (near + guard band) are crossed?
    let mut need = 0u32;
    for p in v {
        if p.z < 0.0 {
            need |= 1;
        }
        if p.x > vp.gx * p.w {
            need |= 2;
        }
        if p.x < -vp.gx * p.w {
            need |= 4;
        }
        if p.y > vp.gy * p.w {
            need |= 8;
        }
        if p.y < -vp.gy * p.w {
            need |= 16;
        }
    }
    if need == 0 {
        if v.iter().all(|p| p.is_finite() && p.w > 0.0) {
            setup_projected([project(v[0], vp), project(v[1], vp), project(v[2], vp)], None, vp, inst, out);
        }
        return;
    }
    // Sutherland-Hodgman against the crossed planes. A triangle clipped by 5 planes has at most
    // 8 vertices.
    let mut poly = [DVec4::ZERO; 9];
    let mut tmp = [DVec4::ZERO; 9];
    poly[..3].copy_from_slice(&v);
    let mut n = 3usize;
    for plane in 0..5 {
        if need & (1 << plane) == 0 {
            continue;
        }
        let mut m = 0usize;
        for i in 0..n {
            let a = poly[i];
            let b = poly[(i + 1) % n];
            let (da, db) = (plane_dist(a, plane, vp), plane_dist(b, plane, vp));
            if da >= 0.0 {
                tmp[m] = a;
                m += 1;
            }
            if (da >= 0.0) != (db >= 0.0) {
                // Interpolate in a canonical direction (lexicographically smaller endpoint first)
                // so the two triangles sharing this edge compute bit-identical intersection points:
                // the clipped shared edge then stays exactly shared (no cracks, no double hits).
                let (p0, p1, d0, d1) = if lex_less(a, b) { (a, b, da, db) } else { (b, a, db, da) };
                let t = d0 / (d0 - d1);
                let mut p = p0 + (p1 - p0) * t;
                if plane == 0 {
                    // Land exactly on the near plane so clipped depth is exactly 0, never < 0.
                    p.z = 0.0;
                }
                tmp[m] = p;
                m += 1;
            }
        }
        n = m;
        poly[..n].copy_from_slice(&tmp[..n]);
        if n < 3 {
            return;
        }
    }
    if !poly[..n].iter().all(|p| p.is_finite() && p.w > 0.0) {
        return; // NaN input or a projection where z >= 0 does not imply w > 0
    }
    for i in 1..n - 1 {
        let sv = [project(poly[0], vp), project(poly[i], vp), project(poly[i + 1], vp)];
        setup_projected(sv, Some(&v), vp, inst, out);
    }
}

/// Strict lexicographic order of clip-space points (x, y, z, w).
#[inline]
fn lex_less(a: Clip, b: Clip) -> bool {
    (a.x, a.y, a.z, a.w) < (b.x, b.y, b.z, b.w)
}

/// A vertex projected to the screen in f64 (pixels, y down; depth `z / w`) and snapped to the
/// 1/256 sub-pixel grid.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct ScreenVert {
    pub x: f64,
    pub y: f64,
    pub z: f64,
    pub fx: i32,
    pub fy: i32,
}

impl ScreenVert {
    /// Marker in `fx`: the vertex lies behind the near plane or outside the guard band, so its
    /// triangles take the clipping path.
    const NEEDS_CLIP: i32 = i32::MIN;
    #[inline(always)]
    pub fn needs_clip(&self) -> bool {
        self.fx == Self::NEEDS_CLIP
    }
}

/// Projects a clip-space vertex (w > 0) to the screen and snaps it. One function for every path
/// (per-vertex fast path, clipped triangles, occlusion queries) so equal inputs give equal bits.
#[inline(always)]
fn project(c: Clip, vp: &Viewport) -> ScreenVert {
    let iw = 1.0 / c.w;
    let x = (c.x * iw + 1.0) * 0.5 * vp.width as f64;
    let y = (1.0 - c.y * iw) * 0.5 * vp.height as f64;
    ScreenVert { x, y, z: c.z * iw, fx: round_fast(x * SUB) as i32, fy: round_fast(y * SUB) as i32 }
}

/// Per-vertex projection for the fast path: vertices in front of the near plane and inside the
/// guard band are projected once and shared by all their triangles; others are marked
/// [`ScreenVert::NEEDS_CLIP`].
#[inline(always)]
pub(crate) fn project_vertex(c: Clip, vp: &Viewport) -> ScreenVert {
    let inside = c.z >= 0.0 && c.w > 0.0 && c.x.abs() <= vp.gx * c.w && c.y.abs() <= vp.gy * c.w;
    if inside && c.is_finite() {
        project(c, vp)
    } else {
        ScreenVert { fx: ScreenVert::NEEDS_CLIP, ..Default::default() }
    }
}

/// The depth `z_ndc = z / w` of the triangle's plane as an affine function of NDC,
/// `z_ndc = a x_ndc + b y_ndc + c`, solved in f64 from the *unclipped* homogeneous vertices
/// (2-D homogeneous rasterization, Olano & Greer 1997): on the triangle's plane `z` is a linear
/// function `a x + b y + c w` of the clip coordinates, so `[a b c] = [z0 z1 z2] M^-1` with
/// `M = [x; y; w]` per vertex. No division by `w` is involved, so near-plane clipping (which
/// creates new vertices by f32 interpolation between very different `w`) cannot perturb the
/// depth: both halves of a clipped triangle share this exact plane. `None` when `M` is singular
/// (plane through the eye: the triangle is seen edge-on).
fn depth_plane_ndc(v: &[Clip; 3]) -> Option<[f64; 3]> {
    let col = |p: Clip| glam::DVec3::new(p.x, p.y, p.w);
    let (c0, c1, c2) = (col(v[0]), col(v[1]), col(v[2]));
    // Rows of M^-1 are (c1 x c2, c2 x c0, c0 x c1) / det, so M^-T z is their z-weighted sum.
    let (k0, k1, k2) = (c1.cross(c2), c2.cross(c0), c0.cross(c1));
    let det = c0.dot(k0);
    let scale = c0.length_squared() * c1.length_squared() * c2.length_squared();
    // (NaN-safe: a NaN determinant also takes this branch.)
    if det * det <= 1e-24 * scale || det.is_nan() {
        return None;
    }
    let r = (k0 * v[0].z + k1 * v[1].z + k2 * v[2].z) / det;
    Some([r.x, r.y, r.z])
}

/// Floor division by 256 (arithmetic shift; no i64 division in the hot path).
#[inline]
fn floor_div256(a: i64) -> i64 {
    a >> 8
}

/// Round to nearest (ties to even) for |x| < 2^51 without a libm call: adding and subtracting
/// 1.5 * 2^52 leaves x rounded to an integer in the f64 mantissa.
#[inline]
fn round_fast(x: f64) -> i64 {
    const MAGIC: f64 = 6755399441055744.0;
    ((x + MAGIC) - MAGIC) as i64
}

/// Exact fixed-point set-up of a triangle whose vertices all lie inside the near plane and the
/// guard band.
///
/// Vertices are snapped to 1/256 pixel. With `d = v1 - v0` (sub-pixel units, y down) the edge
/// function is `E(P) = d.x * (P.y - v0.y) - d.y * (P.x - v0.x)`, positive inside once the
/// triangle is oriented with positive area. Top-left rule: a pixel centre exactly on an edge
/// belongs to the triangle iff the edge is a *left* edge (`d.y < 0`: interior to its right) or a
/// *top* edge (`d.y == 0 && d.x > 0`: horizontal with the interior below), so `E - bias >= 0`
/// with `bias = 0` for top-left edges and 1 otherwise. A shared edge is top-left for exactly one
/// of its two triangles, so every pixel centre on it is drawn exactly once.
///
/// At the centre of pixel `(x, y)`, `P = (256 x + 128, 256 y + 128)` and
/// `E - bias = 256 * (-d.y * x + d.x * y) + K` with `K = d.x (128 - v0.y) - d.y (128 - v0.x) - bias`,
/// so `E - bias >= 0  <=>  -d.y * x + d.x * y + floor(K / 256) >= 0`: the per-pixel edge
/// function only needs whole-pixel steps.
#[inline(always)]
pub(crate) fn setup_projected(
    sv: [ScreenVert; 3],
    orig: Option<&[Clip; 3]>,
    vp: &Viewport,
    inst: u32,
    out: &mut impl TriSink,
) {
    if sv[0].z > 1.0 && sv[1].z > 1.0 && sv[2].z > 1.0 {
        return; // beyond the far plane (depth is affine on the triangle)
    }
    let (w, h) = (vp.width as f64, vp.height as f64);
    let mut sx = [sv[0].x, sv[1].x, sv[2].x];
    let mut sy = [sv[0].y, sv[1].y, sv[2].y];
    let mut sz = [sv[0].z, sv[1].z, sv[2].z];
    let mut fx = [sv[0].fx as i64, sv[1].fx as i64, sv[2].fx as i64];
    let mut fy = [sv[0].fy as i64, sv[1].fy as i64, sv[2].fy as i64];
    let area = (fx[1] - fx[0]) * (fy[2] - fy[0]) - (fy[1] - fy[0]) * (fx[2] - fx[0]);
    if area == 0 {
        return; // degenerate after snapping: covers no pixel centre (D3D/GL convention)
    }
    if area < 0 {
        sx.swap(1, 2);
        sy.swap(1, 2);
        sz.swap(1, 2);
        fx.swap(1, 2);
        fy.swap(1, 2);
    }
    // Pixel-centre bounding box: centres x with 256 x + 128 in [min fx, max fx].
    let (minx, maxx) = (fx[0].min(fx[1]).min(fx[2]), fx[0].max(fx[1]).max(fx[2]));
    let (miny, maxy) = (fy[0].min(fy[1]).min(fy[2]), fy[0].max(fy[1]).max(fy[2]));
    let x0 = floor_div256(minx - 128 + 255).max(0);
    let x1 = floor_div256(maxx - 128).min(vp.width as i64 - 1);
    let y0 = floor_div256(miny - 128 + 255).max(0);
    let y1 = floor_div256(maxy - 128).min(vp.height as i64 - 1);
    if x0 > x1 || y0 > y1 {
        return; // covers no pixel centre (tiny triangle between samples, or off-screen)
    }
    let mut a = [0i32; 3];
    let mut b = [0i32; 3];
    let mut c = [0i64; 3];
    for i in 0..3 {
        let j = (i + 1) % 3;
        let dx = fx[j] - fx[i];
        let dy = fy[j] - fy[i];
        let top_left = dy < 0 || (dy == 0 && dx > 0);
        let bias = if top_left { 0 } else { 1 };
        let k = dx * (128 - fy[i]) - dy * (128 - fx[i]) - bias;
        a[i] = (-dy) as i32;
        b[i] = dx as i32;
        c[i] = floor_div256(k);
    }
    // Depth plane in pixel-centre coordinates: z is affine in screen space (z_ndc = z_clip / w),
    // so this is the perspective-correct depth. Pixel centre x maps to
    // x_ndc = 2 x / W + (1 / W - 1) and y to y_ndc = -2 y / H + (1 - 1 / H).
    let (z0, zx, zy) = match orig.and_then(depth_plane_ndc) {
        Some([pa, pb, pc]) => (pa * (1.0 / w - 1.0) + pb * (1.0 - 1.0 / h) + pc, pa * 2.0 / w, -pb * 2.0 / h),
        None => {
            // Unclipped triangle (or edge-on plane): the plane through the f64 screen-space
            // vertices (snapped positions if even their float area vanishes).
            let (ex1, ey1, ez1) = (sx[1] - sx[0], sy[1] - sy[0], sz[1] - sz[0]);
            let (ex2, ey2, ez2) = (sx[2] - sx[0], sy[2] - sy[0], sz[2] - sz[0]);
            let det = ex1 * ey2 - ex2 * ey1;
            let (zx, zy) = if det.abs() > 1e-9 {
                ((ez1 * ey2 - ez2 * ey1) / det, (ex1 * ez2 - ex2 * ez1) / det)
            } else {
                let s = 1.0 / SUB;
                let (ax1, ay1) = ((fx[1] - fx[0]) as f64 * s, (fy[1] - fy[0]) as f64 * s);
                let (ax2, ay2) = ((fx[2] - fx[0]) as f64 * s, (fy[2] - fy[0]) as f64 * s);
                let det = ax1 * ay2 - ax2 * ay1;
                ((ez1 * ay2 - ez2 * ay1) / det, (ax1 * ez2 - ax2 * ez1) / det)
            };
            (sz[0] + zx * (0.5 - sx[0]) + zy * (0.5 - sy[0]), zx, zy)
        }
    };
    // Conservative minimum over the covered pixel centres: the plane is affine, so its minimum on
    // the triangle is at a vertex; pixel centres lie in the snapped triangle (vertices moved by
    // at most 1/512 px) and the kernel's f32 evaluation adds a few ulps.
    let at = |i: usize| z0 + zx * (sx[i] - 0.5) + zy * (sy[i] - 0.5);
    let slack = (zx.abs() + zy.abs()) / 512.0 + 1.0e-6;
    let zmin = ((at(0).min(at(1)).min(at(2)) - slack) as f32).max(0.0);
    let zmax = (at(0).max(at(1)).max(at(2)) + slack) as f32;
    out.push(Tri { a, b, c, z0, zx, zy, zmin, zmax, x0: x0 as u16, y0: y0 as u16, x1: x1 as u16, y1: y1 as u16, inst });
}

/// One instance selected for drawing.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Draw {
    pub inst: u32,
    pub mesh: u32,
    pub model: Mat4,
    pub mvp: DMat4,
    /// Offset of this draw's first vertex in the transformed vertex buffer.
    pub vert_offset: usize,
    /// Offset of this draw's first triangle in the global triangle sequence.
    pub tri_offset: usize,
}

/// A chunk of set-up triangles and its per-tile bins (CSR: `bin_start[t]..bin_start[t + 1]`
/// indexes `bin_items`, which holds indices into `tris`).
pub(crate) struct Chunk {
    pub tris: Vec<Tri>,
    /// Per-triangle source (only when colour is requested): `[index into Binned::draws,
    /// triangle index in that draw's mesh]`; clipped pieces name their unclipped source triangle.
    pub srcs: Vec<[u32; 2]>,
    /// Per-triangle instance id, compact (only when colour was requested).
    pub insts: Vec<u32>,
    pub bin_start: Vec<u32>,
    pub bin_items: Vec<u16>,
}

impl Chunk {
    #[inline]
    pub fn bin(&self, tile: usize) -> &[u16] {
        &self.bin_items[self.bin_start[tile] as usize..self.bin_start[tile + 1] as usize]
    }
}

/// The whole scene transformed, clipped, set up and binned for one camera.
pub(crate) struct Binned {
    pub vp: Viewport,
    pub chunks: Vec<Chunk>,
    /// The instances drawn, in draw order (what [`Chunk::srcs`] indexes).
    pub draws: Vec<Draw>,
}

impl Binned {
    /// Instance id and source `[draw, mesh triangle]` of the triangle behind a handle written
    /// by a colour pass (compact per-chunk arrays, so the per-pixel look-ups stay in cache).
    #[inline]
    pub fn meta(&self, handle: u32) -> (u32, [u32; 2]) {
        let c = &self.chunks[(handle >> 16) as usize];
        let i = (handle & 0xffff) as usize;
        (c.insts[i], c.srcs[i])
    }
}

/// `true` if the world box may intersect the view frustum of `vp` (conservative: tests the 8
/// transformed corners against each clip plane).
fn aabb_in_frustum(vp_mat: &Mat4, min: Vec3, max: Vec3) -> bool {
    let mut all_out = [true; 6];
    for i in 0..8 {
        let p = Vec3::new(
            if i & 1 == 0 { min.x } else { max.x },
            if i & 2 == 0 { min.y } else { max.y },
            if i & 4 == 0 { min.z } else { max.z },
        );
        let c = *vp_mat * p.extend(1.0);
        let out = [c.x < -c.w, c.x > c.w, c.y < -c.w, c.y > c.w, c.z < 0.0, c.z > c.w];
        for k in 0..6 {
            all_out[k] &= out[k];
        }
    }
    !all_out.iter().any(|&o| o)
}

/// Parameters of one binning run.
pub(crate) struct SetupParams<'a> {
    pub objects: Option<&'a [u32]>,
    pub color: bool,
}

/// Selects, transforms, sets up and bins the scene's instances (or `objects`) at time `t`.
pub(crate) fn bin_scene(scene: &Scene, cam: &Camera, t: f32, params: &SetupParams) -> Result<Binned> {
    let vp = Viewport::new(cam.width, cam.height)?;
    if !t.is_finite() {
        return Err(Error::invalid(format!("render time t must be finite, got {t}")));
    }
    let view_proj = cam.view_proj();
    if !view_proj.is_finite() {
        return Err(Error::invalid("camera view-projection matrix is not finite"));
    }
    let n_inst = scene.instances.len() as u32;
    let all: Vec<u32>;
    let ids: &[u32] = match params.objects {
        Some(o) => {
            if let Some(&bad) = o.iter().find(|&&i| i >= n_inst) {
                return Err(Error::invalid(format!(
                    "object id {bad} out of range (scene '{}' has {n_inst} instances)",
                    scene.name
                )));
            }
            o
        }
        None => {
            all = (0..n_inst).collect();
            &all
        }
    };
    // Instance selection with view-frustum culling of the animated world box, then front-to-back
    // order of box centres so early-z rejects more (ties keep the submission order).
    let eye = cam.eye();
    let mut sel: Vec<(f32, u32, Mat4)> = Vec::with_capacity(ids.len());
    for &id in ids {
        let inst = &scene.instances[id as usize];
        let mesh = scene
            .meshes
            .get(inst.mesh as usize)
            .ok_or_else(|| Error::invalid(format!("instance {id} references missing mesh {}", inst.mesh)))?;
        if mesh.indices.is_empty() {
            continue;
        }

        let model = inst.transform_at(t);
        if !model.is_finite() {
            return Err(Error::invalid(format!("instance {id} has a non-finite transform at t={t}")));
        }
        let b = mesh.bounds.transformed(&model);
        if !b.is_empty() && !aabb_in_frustum(&view_proj, b.min, b.max) {
            continue;
        }
        let dist = if b.is_empty() { 0.0 } else { (b.center() - eye).length_squared() };
        sel.push((dist, id, model));
    }
    sel.sort_by(|a, b| a.0.total_cmp(&b.0));
    // `Mesh::new` validates indices, but the fields are public: check every mesh in use once so
    // set-up never indexes out of range.
    let mut used = vec![false; scene.meshes.len()];
    for &(_, id, _) in &sel {
        used[scene.instances[id as usize].mesh as usize] = true;
    }
    for (mi, mesh) in scene.meshes.iter().enumerate().filter(|(mi, _)| used[*mi]) {
        let nv = mesh.positions.len() as u32;
        if mesh.indices.par_iter().any(|t| t[0] >= nv || t[1] >= nv || t[2] >= nv) {
            return Err(Error::invalid(format!("mesh {mi} has a triangle indexing beyond its {nv} vertices")));
        }
        // The colour resolve reads normals, UVs and material runs by index.
        if params.color {
            mesh.validate().map_err(|e| {
                Error::invalid(format!("mesh {mi}: {}", e.to_string().trim_start_matches("invalid input: ")))
            })?;
        }
    }
    let mut draws = Vec::with_capacity(sel.len());
    let (mut vo, mut to) = (0usize, 0usize);
    for &(_, id, model) in &sel {
        let mesh_id = scene.instances[id as usize].mesh;
        let mesh = &scene.meshes[mesh_id as usize];
        draws.push(Draw {
            inst: id,
            mesh: mesh_id,
            model,
            mvp: view_proj.as_dmat4() * model.as_dmat4(),
            vert_offset: vo,
            tri_offset: to,
        });
        vo += mesh.positions.len();
        to += mesh.indices.len();
    }
    let (total_verts, total_tris) = (vo, to);

    // Vertex transform, in parallel over fixed-size vertex chunks spanning instances.
    // Vertex transform and projection (once per vertex, shared by its triangles).
    // Every vertex is written below, so the buffer is not cleared first (at VFC's draw counts
    // the clear was as large a write as the transform's own).
    let mut clip: Vec<ScreenVert> = Vec::with_capacity(total_verts);
    clip.spare_capacity_mut()[..total_verts].par_chunks_mut(CHUNK_VERTS).enumerate().for_each(|(ci, out)| {
        let start = ci * CHUNK_VERTS;
        let mut d = draws.partition_point(|d| d.vert_offset <= start) - 1;
        let mut g = start;
        let mut k = 0;
        while k < out.len() {
            while g >= draws[d].vert_offset + scene.meshes[draws[d].mesh as usize].positions.len() {
                d += 1;
            }
            let pos = &scene.meshes[draws[d].mesh as usize].positions;
            let local = g - draws[d].vert_offset;
            let n = (pos.len() - local).min(out.len() - k);
            let m = draws[d].mvp;
            for (o, p) in out[k..k + n].iter_mut().zip(&pos[local..local + n]) {
                o.write(project_vertex(m * p.as_dvec3().extend(1.0), &vp));
            }
            k += n;
            g += n;
        }
    });
    // SAFETY: the chunks cover `0..total_verts` and every element was written above (the loop
    // runs until `k == out.len()` for each chunk).
    unsafe { clip.set_len(total_verts) };

    // Triangle set-up and binning, in parallel over fixed-size triangle chunks.
    let n_chunks = total_tris.div_ceil(CHUNK_TRIS);
    let ctx = ChunkCtx { scene, draws: &draws, clip: &clip, vp, color: params.color, total_tris };
    let avx2 = crate::simd::has_avx2();
    let chunks: Vec<Chunk> = (0..n_chunks)
        .into_par_iter()
        .map(|ci| {
            #[cfg(target_arch = "x86_64")]
            if avx2 {
                // SAFETY: AVX2 presence checked at run time. No FMA is enabled, so results are
                // bit-identical to the generic build.
                return unsafe { setup_chunk_avx2(&ctx, ci) };
            }
            let _ = avx2;
            setup_chunk(&ctx, ci)
        })
        .collect();
    Ok(Binned { vp, chunks, draws })
}

/// Everything a set-up chunk reads.
struct ChunkCtx<'a> {
    scene: &'a Scene,
    draws: &'a [Draw],
    clip: &'a [ScreenVert],
    vp: Viewport,
    color: bool,
    total_tris: usize,
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn setup_chunk_avx2(ctx: &ChunkCtx, ci: usize) -> Chunk {
    setup_chunk(ctx, ci)
}

/// Sets up and bins source triangles `[ci * CHUNK_TRIS, (ci + 1) * CHUNK_TRIS)` of the global
/// sequence (draws in order, each draw's triangles in mesh order).
#[inline(always)]
fn setup_chunk(ctx: &ChunkCtx, ci: usize) -> Chunk {
    let (scene, draws, vp) = (ctx.scene, ctx.draws, ctx.vp);
    let start = ci * CHUNK_TRIS;
    let end = (start + CHUNK_TRIS).min(ctx.total_tris);
    let mut tris: Vec<Tri> = Vec::with_capacity(end - start);
    let mut srcs: Vec<[u32; 2]> = Vec::new();
    let mut d = draws.partition_point(|d| d.tri_offset <= start) - 1;
    let mut g = start;
    while g < end {
        while g >= draws[d].tri_offset + scene.meshes[draws[d].mesh as usize].indices.len() {
            d += 1;
        }
        let dr = &draws[d];
        let mesh = &scene.meshes[dr.mesh as usize];
        let local = g - dr.tri_offset;
        let n = (mesh.indices.len() - local).min(end - g);
        let vb = &ctx.clip[dr.vert_offset..dr.vert_offset + mesh.positions.len()];
        for (k, tri) in mesh.indices[local..local + n].iter().enumerate() {
            let sv = [vb[tri[0] as usize], vb[tri[1] as usize], vb[tri[2] as usize]];
            let before = tris.len();
            if sv[0].needs_clip() || sv[1].needs_clip() || sv[2].needs_clip() {
                // Rare path: recompute the clip coordinates (exactly as the vertex pass did).
                let cv = tri.map(|i| dr.mvp * mesh.positions[i as usize].as_dvec3().extend(1.0));
                setup_clip_triangle(cv, &vp, dr.inst, &mut tris);
            } else {
                setup_projected(sv, None, &vp, dr.inst, &mut tris);
            }
            if ctx.color && tris.len() > before {
                srcs.resize(tris.len(), [d as u32, (local + k) as u32]);
            }
        }
        g += n;
    }
    let (bin_start, bin_items) = bin_tris(&tris, &vp);
    let insts = if ctx.color { tris.iter().map(|t| t.inst).collect() } else { Vec::new() };
    Chunk { tris, srcs, insts, bin_start, bin_items }
}

/// Bins triangles into tiles (counting sort, CSR). Triangles spanning several tiles are only
/// added to tiles their edges may reach: a tile is skipped when one edge is negative at all four
/// of its corner pixel centres (the triangle lies entirely outside that edge's half-plane there).
#[inline(always)]
pub(crate) fn bin_tris(tris: &[Tri], vp: &Viewport) -> (Vec<u32>, Vec<u16>) {
    let ntiles = vp.tile_count();
    let tx_n = vp.tiles_x();
    let mut pairs: Vec<(u32, u16)> = Vec::with_capacity(tris.len() + tris.len() / 4);
    for (i, t) in tris.iter().enumerate() {
        let (tx0, tx1) = (t.x0 as usize / TILE_W, t.x1 as usize / TILE_W);
        let (ty0, ty1) = (t.y0 as usize / TILE_H, t.y1 as usize / TILE_H);
        if tx0 == tx1 && ty0 == ty1 {
            pairs.push(((ty0 * tx_n + tx0) as u32, i as u16));
            continue;
        }
        for ty in ty0..=ty1 {
            for tx in tx0..=tx1 {
                let px0 = (tx * TILE_W).max(t.x0 as usize) as i64;
                let px1 = ((tx + 1) * TILE_W - 1).min(t.x1 as usize) as i64;
                let py0 = (ty * TILE_H).max(t.y0 as usize) as i64;
                let py1 = ((ty + 1) * TILE_H - 1).min(t.y1 as usize) as i64;
                let outside = (0..3).any(|e| {
                    t.edge_at(e, px0, py0) < 0
                        && t.edge_at(e, px1, py0) < 0
                        && t.edge_at(e, px0, py1) < 0
                        && t.edge_at(e, px1, py1) < 0
                });
                if !outside {
                    pairs.push(((ty * tx_n + tx) as u32, i as u16));
                }
            }
        }
    }
    let mut bin_start = vec![0u32; ntiles + 1];
    for &(tile, _) in &pairs {
        bin_start[tile as usize + 1] += 1;
    }
    for i in 0..ntiles {
        bin_start[i + 1] += bin_start[i];
    }
    let mut fill = bin_start.clone();
    let mut bin_items = vec![0u16; pairs.len()];
    for &(tile, i) in &pairs {
        bin_items[fill[tile as usize] as usize] = i;
        fill[tile as usize] += 1;
    }
    (bin_start, bin_items)
}

/// Transforms world-space triangles with `cam` and sets them up (used by the occlusion query and
/// by tests). Instance id is 0.
pub(crate) fn setup_world_triangles(cam: &Camera, triangles: &[[Vec3; 3]]) -> Result<(Viewport, Vec<Tri>)> {
    let vp = Viewport::new(cam.width, cam.height)?;
    let m = cam.view_proj().as_dmat4();
    let mut out = Vec::with_capacity(triangles.len());
    for t in triangles {
        let cv = [t[0], t[1], t[2]].map(|p| m * p.as_dvec3().extend(1.0));
        if cv.iter().all(|c| c.is_finite()) {
            setup_clip_triangle(cv, &vp, 0, &mut out);
        }
    }
    Ok((vp, out))
}
