//! Colour resolve (visibility-buffer style): after the depth + handle pass, every covered
//! pixel names its triangle; one parallel pass over the pixels computes the perspective-correct
//! barycentrics of the pixel centre on that triangle, interpolates position, normal and UV, and
//! shades. Only colour renders run it: the depth-only path never touches this module.
//!
//! Every pixel's colour is a function of its handle and its coordinates alone, so the image does
//! not depend on the thread count.

use glam::{DMat4, DVec3, Mat3, Mat4, Vec2, Vec3};
use rayon::prelude::*;
use zwarp_core::{Camera, ColorMap, Image, Mesh, Projection, Scene, NO_ITEM};

use crate::setup::Binned;

/// Shading model of the colour output, shared with the GPU renderer (`zwarp-gpu`'s
/// `depth.wgsl` holds the WGSL twin of every function here; a test compares the two).
///
/// `colour = albedo * (AMBIENT + (1 - AMBIENT) * max(0, n . l))` with the headlight `l`
/// ([`LIGHT_DIR_VIEW`](shading::LIGHT_DIR_VIEW)), `n` the interpolated vertex normal (flat triangle normal without
/// normals) turned to the eye's side of the triangle, and
/// `albedo = Instance::albedo * Material::base_color * (texture(uv) | pattern | 1)`.
pub mod shading {
    use glam::{Mat3, Mat4, Vec2, Vec3};

    /// Direction *towards* the light in view space (camera looks down -z): a headlight from
    /// slightly above-left of the eye, so faces turned towards the camera are lit.
    pub const LIGHT_DIR_VIEW: Vec3 = Vec3::new(-0.3, 0.5, 0.812404);
    /// Ambient term: `colour = albedo * (AMBIENT + (1 - AMBIENT) * max(0, n . l))`.
    pub const AMBIENT: f32 = 0.25;
    /// Colour of empty pixels.
    pub const SKY_COLOR: [f32; 3] = [0.55, 0.7, 0.9];
    /// Frequencies (cycles per scene unit; the scenes are in metres) of the pattern's two
    /// value-noise octaves: cells of 1/32 m and 1/8 m, a few pixels wide at the evaluation views
    /// (1080p, surfaces 3-30 m away).
    pub const NOISE_FREQ: [f32; 2] = [32.0, 8.0];
    /// Frequencies of the pattern's three stripe scales: periods 0.05 m, 0.25 m and 1.5 m.
    pub const STRIPE_FREQ: [f32; 3] = [20.0, 4.0, 0.6666667];
    /// Stripe directions (in each projection plane), one per scale.
    pub const STRIPE_DIR: [Vec2; 3] = [Vec2::new(0.8, 0.6), Vec2::new(-0.6, 0.8), Vec2::new(1.0, 0.0)];

    /// 32-bit integer hash of `(x, y, s)` (multiply-xorshift finalizer; wrapping u32 arithmetic,
    /// the same bits in WGSL).
    #[inline]
    pub fn hash(x: u32, y: u32, s: u32) -> u32 {
        let mut h = x.wrapping_mul(0x8da6_b343) ^ y.wrapping_mul(0xd816_3841) ^ s.wrapping_mul(0xcb1a_b31f);
        h ^= h >> 16;
        h = h.wrapping_mul(0x7feb_352d);
        h ^= h >> 15;
        h = h.wrapping_mul(0x846c_a68b);
        h ^= h >> 16;
        h
    }

    /// `hash` as a number in `[0, 1)` (its top 24 bits).
    #[inline]
    pub fn hash_unit(x: u32, y: u32, s: u32) -> f32 {
        (hash(x, y, s) >> 8) as f32 * (1.0 / 16_777_216.0)
    }

    /// 2-D value noise in `[0, 1]`: lattice values `hash_unit` at integer points, blended with
    /// the smoothstep `t^2 (3 - 2 t)` (continuous, C1).
    #[inline]
    pub fn value_noise(q: Vec2, seed: u32) -> f32 {
        let (fx, fy) = (zwarp_core::round::floor(q.x), zwarp_core::round::floor(q.y));
        let (x0, y0) = (fx as i32 as u32, fy as i32 as u32);
        let (tx, ty) = (q.x - fx, q.y - fy);
        let sx = tx * tx * (3.0 - 2.0 * tx);
        let sy = ty * ty * (3.0 - 2.0 * ty);
        let (x1, y1) = (x0.wrapping_add(1), y0.wrapping_add(1));
        let a = hash_unit(x0, y0, seed) * (1.0 - sx) + hash_unit(x1, y0, seed) * sx;
        let b = hash_unit(x0, y1, seed) * (1.0 - sx) + hash_unit(x1, y1, seed) * sx;
        a * (1.0 - sy) + b * sy
    }

    /// Smooth stripes in `[0, 1]`: the triangle wave of `q . dir * freq`, smoothstepped
    /// (continuous and C1, so tiny position differences give tiny colour differences).
    #[inline]
    pub fn stripe(q: Vec2, dir: Vec2, freq: f32) -> f32 {
        let t = (q.x * dir.x + q.y * dir.y) * freq;
        let f = t - zwarp_core::round::floor(t);
        let tri = (2.0 * f - 1.0).abs();
        tri * tri * (3.0 - 2.0 * tri)
    }

    /// One projection plane of the pattern (`axis` 0..3 names it) for object `id`, whose
    /// stripe tints are `ta = tint(id, 0)` and `tb = tint(id, 1)`.
    #[inline]
    pub fn pattern_plane(q: Vec2, axis: u32, id: u32, ta: Vec3, tb: Vec3) -> Vec3 {
        let seed = id.wrapping_mul(16).wrapping_add(axis * 4);
        let n1 = value_noise(q * NOISE_FREQ[0], seed);
        let n2 = value_noise(q * NOISE_FREQ[1], seed + 1);
        let s1 = stripe(q, STRIPE_DIR[0], STRIPE_FREQ[0]);
        let s2 = stripe(q, STRIPE_DIR[1], STRIPE_FREQ[1]);
        let s3 = stripe(q, STRIPE_DIR[2], STRIPE_FREQ[2]);
        let g = 0.45 + 0.3 * n1 + 0.17 * n2 + 0.08 * s1;
        let ka = 0.35 * s2;
        let kb = 0.3 * s3;
        Vec3::new(
            g * (1.0 + ka * (ta.x - 1.0)) * (1.0 + kb * (tb.x - 1.0)),
            g * (1.0 + ka * (ta.y - 1.0)) * (1.0 + kb * (tb.y - 1.0)),
            g * (1.0 + ka * (ta.z - 1.0)) * (1.0 + kb * (tb.z - 1.0)),
        )
    }

    /// Per-object stripe tint `k` (components in `[0.55, 1.35)`): the pattern's colour varies
    /// with the object id.
    #[inline]
    pub fn tint(id: u32, k: u32) -> Vec3 {
        let c = |ch: u32| 0.55 + 0.8 * hash_unit(id, k * 3 + ch, 0x9e37_79b9);
        Vec3::new(c(0), c(1), c(2))
    }

    /// The procedural surface detail of [`zwarp_core::ColorMap::Pattern`]: a deterministic RGB
    /// multiplier (about `[0.33, 1.24]`) of the rest-pose world position `p` (the instance's
    /// `transform` without animation, so the pattern moves with animated objects), its normal
    /// `n` (any non-zero length, any sign; zero or non-finite = equal weights) and the object id.
    ///
    /// Triplanar: the planes x (`(p.y, p.z)`), y (`(p.z, p.x)`) and z (`(p.x, p.y)`) are
    /// blended with weights `|n_i|^4 / sum`; each plane is fine value noise ([`NOISE_FREQ`])
    /// plus smooth stripes at three scales ([`STRIPE_FREQ`]), the two coarser stripe scales
    /// tinted per object ([`tint`]). Fixed world-space scales (metres), not relative to the
    /// scene, so detail has the same size everywhere; planes of weight 0 are skipped.
    pub fn pattern(p: Vec3, n: Vec3, id: u32) -> Vec3 {
        let l2 = n.length_squared();
        let w = if l2 > 0.0 && l2 < 3.0e38 {
            let a = (n / l2.sqrt()).abs();
            let mut w = a * a;
            w *= w;
            w / (w.x + w.y + w.z)
        } else {
            Vec3::splat(1.0 / 3.0)
        };
        let (ta, tb) = (tint(id, 0), tint(id, 1));
        let mut c = Vec3::ZERO;
        if w.x > 0.0 {
            c += w.x * pattern_plane(Vec2::new(p.y, p.z), 0, id, ta, tb);
        }
        if w.y > 0.0 {
            c += w.y * pattern_plane(Vec2::new(p.z, p.x), 1, id, ta, tb);
        }
        if w.z > 0.0 {
            c += w.z * pattern_plane(Vec2::new(p.x, p.y), 2, id, ta, tb);
        }
        c
    }

    /// Normal matrix of an object -> world transform: the inverse transpose of its upper 3x3
    /// (the 3x3 itself where that is singular). The GPU renderer uploads these same matrices.
    pub fn normal_matrix(m: Mat4) -> Mat3 {
        let a = Mat3::from_mat4(m);
        let n = a.inverse().transpose();
        if n.is_finite() {
            n
        } else {
            a
        }
    }

    /// Two-sided Lambert factor `AMBIENT + (1 - AMBIENT) * max(0, n . l)` with the geometric
    /// normal `g` (any length) turned towards `to_eye` and the shading normal `s` (any length,
    /// zero = use `g`) turned to the same side as `g`. `l` is the unit light direction.
    pub fn lambert(g: Vec3, s: Vec3, to_eye: Vec3, l: Vec3, ambient: f32) -> f32 {
        let g = if g.dot(to_eye) < 0.0 { -g } else { g };
        let n = if s.length_squared() > 1e-30 {
            let s = s.normalize();
            if s.dot(g) < 0.0 {
                -s
            } else {
                s
            }
        } else {
            g.normalize_or_zero()
        };
        ambient + (1.0 - ambient) * n.dot(l).max(0.0)
    }
}

/// Per-draw shading data (matrices formed once per render).
struct DrawShade {
    mvp: DMat4,
    model: Mat4,
    rest: Mat4,
    nmat: Mat3,
    nrest: Mat3,
}

/// The world-space light direction, the eye (perspective) and the direction to the camera
/// (orthographic) of `cam`, exactly as the GPU renderer's frame uniform forms them.
pub(crate) fn light_and_eye(cam: &Camera, light_dir_view: Vec3) -> (Vec3, Option<Vec3>, Vec3) {
    let inv_view = cam.view.inverse();
    let l = inv_view.transform_vector3(light_dir_view.normalize()).normalize();
    match cam.projection {
        Projection::Perspective { .. } => (l, Some(cam.eye()), Vec3::ZERO),
        Projection::Orthographic { .. } => (l, None, inv_view.z_axis.truncate().normalize()),
    }
}

/// Shades every pixel of the visibility buffer `handles` (see `kernel::Targets::handles`);
/// sky where empty.
pub(crate) fn resolve(binned: &Binned, scene: &Scene, cam: &Camera, handles: &Image<u32>) -> Image<[f32; 3]> {
    let view_proj = cam.view_proj().as_dmat4();
    let draws: Vec<DrawShade> = binned
        .draws
        .par_iter()
        .map(|d| {
            let rest = scene.instances[d.inst as usize].transform;
            DrawShade {
                mvp: view_proj * d.model.as_dmat4(),
                model: d.model,
                rest,
                nmat: shading::normal_matrix(d.model),
                nrest: shading::normal_matrix(rest),
            }
        })
        .collect();
    let (light, eye, ortho_dir) = light_and_eye(cam, shading::LIGHT_DIR_VIEW);
    let (w, h) = (cam.width as usize, cam.height as usize);
    let mut out = Image::filled(cam.width, cam.height, shading::SKY_COLOR);
    out.data_mut().par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let ndc_y = 1.0 - (y as f64 + 0.5) * 2.0 / h as f64;
        // Neighbouring pixels mostly show the same triangle: keep its barycentric set-up.
        let mut last = NO_ITEM;
        let mut setup = [DVec3::ZERO; 3];
        for (x, px) in row.iter_mut().enumerate() {
            let hnd = handles.data()[y * w + x];
            if hnd == NO_ITEM {
                continue;
            }
            let ndc_x = (x as f64 + 0.5) * 2.0 / w as f64 - 1.0;
            let (inst, [d, t]) = binned.meta(hnd);
            let mesh = &scene.meshes[binned.draws[d as usize].mesh as usize];
            let ds = &draws[d as usize];
            if hnd != last {
                setup = barycentric_setup(mesh, t as usize, ds);
                last = hnd;
            }
            let b = barycentrics(&setup, ndc_x, ndc_y);
            *px = shade_pixel(scene, inst, mesh, t as usize, ds, b, light, eye, ortho_dir);
        }
    });
    out
}

/// The rows of `det(M) M^-1` for triangle `t` of `mesh` drawn with `ds`, where
/// `M = [x_i; y_i; w_i]` holds the clip-space vertices (f64): what [`barycentrics`] needs.
#[inline]
fn barycentric_setup(mesh: &Mesh, t: usize, ds: &DrawShade) -> [DVec3; 3] {
    let c = mesh.indices[t].map(|i| {
        let p = ds.mvp * mesh.positions[i as usize].as_dvec3().extend(1.0);
        DVec3::new(p.x, p.y, p.w)
    });
    [c[1].cross(c[2]), c[2].cross(c[0]), c[0].cross(c[1])]
}

/// Perspective-correct barycentrics of NDC point `(x, y)` on a triangle (2-D homogeneous:
/// `b ~ M^-1 (x, y, 1)` with `M = [x_i; y_i; w_i]` its clip-space vertices, normalized to sum 1;
/// exact for clipped triangles too, since the unclipped vertices are used). `k` is
/// [`barycentric_setup`]. A degenerate (edge-on) triangle gives the centroid.
#[inline]
fn barycentrics(k: &[DVec3; 3], x: f64, y: f64) -> [f32; 3] {
    let q = DVec3::new(x, y, 1.0);
    let b = [k[0].dot(q), k[1].dot(q), k[2].dot(q)];
    let s = b[0] + b[1] + b[2];
    if s == 0.0 || !s.is_finite() {
        return [1.0 / 3.0; 3];
    }
    [(b[0] / s) as f32, (b[1] / s) as f32, (b[2] / s) as f32]
}

#[allow(clippy::too_many_arguments)]
#[inline]
fn shade_pixel(
    scene: &Scene,
    inst: u32,
    mesh: &Mesh,
    t: usize,
    ds: &DrawShade,
    b: [f32; 3],
    light: Vec3,
    eye: Option<Vec3>,
    ortho_dir: Vec3,
) -> [f32; 3] {
    let tri = mesh.indices[t];
    let p = tri.map(|i| mesh.positions[i as usize]);
    let obj = p[0] * b[0] + p[1] * b[1] + p[2] * b[2];
    let world = ds.model.transform_point3(obj);
    let rest = ds.rest.transform_point3(obj);
    let g_obj = (p[1] - p[0]).cross(p[2] - p[0]);
    let n_obj = match &mesh.normals {
        Some(ns) => ns[tri[0] as usize] * b[0] + ns[tri[1] as usize] * b[1] + ns[tri[2] as usize] * b[2],
        None => Vec3::ZERO,
    };
    let to_eye = match eye {
        Some(e) => e - world,
        None => ortho_dir,
    };
    let k = shading::lambert(ds.nmat * g_obj, ds.nmat * n_obj, to_eye, light, shading::AMBIENT);
    let mat = mesh.material_of(t);
    let base = scene.instances[inst as usize].albedo * mat.base_color;
    let pattern = || {
        let nr = if n_obj.length_squared() > 1e-30 { ds.nrest * n_obj } else { ds.nrest * g_obj };
        shading::pattern(rest, nr, inst)
    };
    let albedo = match (&mat.map, &mesh.uvs) {
        (ColorMap::Uniform, _) => base,
        (ColorMap::Texture(tex), Some(uvs)) => {
            let uv: Vec2 = uvs[tri[0] as usize] * b[0] + uvs[tri[1] as usize] * b[1] + uvs[tri[2] as usize] * b[2];
            let c = tex.sample(uv);
            base * Vec3::new(c[0], c[1], c[2])
        }
        _ => base * pattern(),
    };
    (albedo * k).to_array()
}
