//! Mesh primitives for the procedural scenes (seed 000, Sec. 4: YR, MO, BL, CB).
//!
//! Every builder returns a [`MeshBuilder`] in object space so several parts can be appended
//! into one mesh (a tree = trunk cylinder + crown cone) before it is turned into a
//! [`zwarp_core::Mesh`]. All shapes are closed and wound counter-clockwise seen from outside;
//! the renderer draws both sides anyway, so winding only matters for normals.

use glam::{Mat4, Vec3};
use zwarp_core::{Mesh, Result};

/// Positions + triangles being assembled; [`MeshBuilder::build`] validates into a [`Mesh`].
#[derive(Clone, Debug, Default)]
pub struct MeshBuilder {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Triangles (indices into `positions`).
    pub indices: Vec<[u32; 3]>,
}

impl MeshBuilder {
    /// Empty builder.
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends `other` transformed by `m`.
    pub fn append(&mut self, other: &MeshBuilder, m: Mat4) -> &mut Self {
        let base = self.positions.len() as u32;
        self.positions.extend(other.positions.iter().map(|p| m.transform_point3(*p)));
        self.indices.extend(other.indices.iter().map(|t| [t[0] + base, t[1] + base, t[2] + base]));
        self
    }

    /// Validates (finite positions, in-range indices) and computes bounds.
    pub fn build(self) -> Result<Mesh> {
        Mesh::new(self.positions, self.indices)
    }

    /// Adds a quad `a b c d` (counter-clockwise) as two triangles.
    fn quad(&mut self, a: u32, b: u32, c: u32, d: u32) {
        self.indices.push([a, b, c]);
        self.indices.push([a, c, d]);
    }
}

/// Axis-aligned unit box `[-0.5, 0.5]^2 x [0, 1]` (base on z = 0, so a scale
/// `(w, d, h)` plus a translation to the footprint centre places a building on the ground).
/// 8 vertices, 12 triangles.
pub fn unit_box() -> MeshBuilder {
    let mut m = MeshBuilder::new();
    for &z in &[0.0f32, 1.0] {
        for &(x, y) in &[(-0.5f32, -0.5f32), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)] {
            m.positions.push(Vec3::new(x, y, z));
        }
    }
    m.quad(0, 3, 2, 1); // bottom (faces -z)
    m.quad(4, 5, 6, 7); // top
    m.quad(0, 1, 5, 4);
    m.quad(1, 2, 6, 5);
    m.quad(2, 3, 7, 6);
    m.quad(3, 0, 4, 7);
    m
}

/// Gable roof prism on the unit footprint `[-0.5, 0.5]^2`, from z = 0 to the ridge at z = 1
/// (ridge along x). 6 vertices, 8 triangles.
pub fn gable_roof() -> MeshBuilder {
    let mut m = MeshBuilder::new();
    m.positions.extend([
        Vec3::new(-0.5, -0.5, 0.0),
        Vec3::new(0.5, -0.5, 0.0),
        Vec3::new(0.5, 0.5, 0.0),
        Vec3::new(-0.5, 0.5, 0.0),
        Vec3::new(-0.5, 0.0, 1.0),
        Vec3::new(0.5, 0.0, 1.0),
    ]);
    m.quad(0, 3, 2, 1);
    m.quad(0, 1, 5, 4);
    m.quad(2, 3, 4, 5);
    m.indices.push([1, 2, 5]);
    m.indices.push([3, 0, 4]);
    m
}

/// UV sphere of radius 1 centred at the origin with `segments` around z and `rings` from pole
/// to pole; `displace(unit_dir) -> radius` shapes it (rocks, blobs). Triangles:
/// `2 * segments * (rings - 1)`.
pub fn sphere_with(segments: u32, rings: u32, displace: impl Fn(Vec3) -> f32) -> MeshBuilder {
    let (segments, rings) = (segments.max(3), rings.max(2));
    let mut m = MeshBuilder::new();
    m.positions.push(Vec3::new(0.0, 0.0, -1.0) * displace(Vec3::NEG_Z));
    for r in 1..rings {
        let theta = std::f32::consts::PI * r as f32 / rings as f32;
        let (st, ct) = theta.sin_cos();
        for s in 0..segments {
            let phi = std::f32::consts::TAU * s as f32 / segments as f32;
            let d = Vec3::new(st * phi.cos(), st * phi.sin(), -ct);
            m.positions.push(d * displace(d));
        }
    }
    m.positions.push(Vec3::Z * displace(Vec3::Z));
    let top = m.positions.len() as u32 - 1;
    let ring = |r: u32, s: u32| 1 + (r - 1) * segments + s % segments;
    for s in 0..segments {
        m.indices.push([0, ring(1, s + 1), ring(1, s)]);
        m.indices.push([top, ring(rings - 1, s), ring(rings - 1, s + 1)]);
    }
    for r in 1..rings - 1 {
        for s in 0..segments {
            m.quad(ring(r, s), ring(r, s + 1), ring(r + 1, s + 1), ring(r + 1, s));
        }
    }
    m
}

/// Plain unit sphere (see [`sphere_with`]).
pub fn sphere(segments: u32, rings: u32) -> MeshBuilder {
    sphere_with(segments, rings, |_| 1.0)
}

/// Closed cylinder of radius 1 from z = 0 to z = 1 with `segments` sides (capped).
/// Triangles: `4 * segments`.
pub fn cylinder(segments: u32) -> MeshBuilder {
    frustum(segments, 1.0, 1.0)
}

/// Closed cone of base radius 1 on z = 0 with its apex at z = 1 (capped base).
pub fn cone(segments: u32) -> MeshBuilder {
    frustum(segments, 1.0, 0.0)
}

/// Capped frustum with bottom radius `r0` at z = 0 and top radius `r1` at z = 1.
pub fn frustum(segments: u32, r0: f32, r1: f32) -> MeshBuilder {
    let n = segments.max(3);
    let mut m = MeshBuilder::new();
    for &(z, r) in &[(0.0f32, r0), (1.0, r1)] {
        for s in 0..n {
            let phi = std::f32::consts::TAU * s as f32 / n as f32;
            m.positions.push(Vec3::new(r * phi.cos(), r * phi.sin(), z));
        }
    }
    let (cb, ct) = (m.positions.len() as u32, m.positions.len() as u32 + 1);
    m.positions.push(Vec3::ZERO);
    m.positions.push(Vec3::Z);
    for s in 0..n {
        let s1 = (s + 1) % n;
        m.quad(s, s1, n + s1, n + s);
        m.indices.push([cb, s1, s]);
        m.indices.push([ct, n + s, n + s1]);
    }
    m
}

/// Tube of radius `tube` swept along a closed curve `center(u)`, `u` in `[0, 1)`, with
/// `along x around` quads; `radius_scale(u, v)` modulates the tube radius (bumps). The frame
/// is a rotation-minimising approximation from finite differences, good enough for smooth
/// knots and tori. Triangles: `2 * along * around`.
pub fn tube(
    along: u32,
    around: u32,
    tube: f32,
    center: impl Fn(f32) -> Vec3,
    radius_scale: impl Fn(f32, f32) -> f32,
) -> MeshBuilder {
    let (along, around) = (along.max(3), around.max(3));
    let mut m = MeshBuilder::new();
    // Parallel-transport frame: start from any normal, project it onto each new tangent's
    // normal plane. Closing twist is hidden because the cross section is a circle.
    let tangent = |u: f32| {
        let h = 1e-3;
        (center(u + h) - center(u - h)).normalize_or(Vec3::X)
    };
    let t0 = tangent(0.0);
    let mut normal = t0.any_orthonormal_vector();
    for i in 0..along {
        let u = i as f32 / along as f32;
        let t = tangent(u);
        normal = (normal - t * normal.dot(t)).normalize_or(t.any_orthonormal_vector());
        let binormal = t.cross(normal);
        let c = center(u);
        for j in 0..around {
            let v = j as f32 / around as f32;
            let a = std::f32::consts::TAU * v;
            let r = tube * radius_scale(u, v);
            m.positions.push(c + (normal * a.cos() + binormal * a.sin()) * r);
        }
    }
    let idx = |i: u32, j: u32| (i % along) * around + j % around;
    for i in 0..along {
        for j in 0..around {
            m.quad(idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1));
        }
    }
    m
}

/// Regular grid height field over `[x0, x1] x [y0, y1]` with `nx x ny` cells and height
/// `h(x, y)` (terrain, ground plane). Triangles: `2 * nx * ny`.
pub fn height_field(x0: f32, y0: f32, x1: f32, y1: f32, nx: u32, ny: u32, h: impl Fn(f32, f32) -> f32) -> MeshBuilder {
    let (nx, ny) = (nx.max(1), ny.max(1));
    let mut m = MeshBuilder::new();
    for j in 0..=ny {
        let y = y0 + (y1 - y0) * j as f32 / ny as f32;
        for i in 0..=nx {
            let x = x0 + (x1 - x0) * i as f32 / nx as f32;
            m.positions.push(Vec3::new(x, y, h(x, y)));
        }
    }
    let idx = |i: u32, j: u32| j * (nx + 1) + i;
    for j in 0..ny {
        for i in 0..nx {
            m.quad(idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1));
        }
    }
    m
}

/// Smooth deterministic pseudo-noise in about `[-1, 1]`: a sum of a few sines with
/// incommensurate frequencies and per-seed phases. Cheap and seedable; only used to displace
/// procedural geometry, so spectral quality does not matter.
pub fn wave_noise(p: Vec3, seed: u32) -> f32 {
    let s = seed as f32 * 0.618_034;
    let a = (p.x * 1.7 + p.y * 0.9 + s * 3.1).sin() * (p.z * 1.3 - p.x * 0.4 + s * 1.7).cos();
    let b = (p.y * 2.9 - p.z * 1.1 + s * 5.3).sin() * (p.x * 2.3 + s * 0.7).sin();
    let c = (p.z * 4.1 + p.x * 3.7 - p.y * 2.3 + s * 2.9).sin();
    0.55 * a + 0.3 * b + 0.15 * c
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every edge of a closed 2-manifold mesh is shared by exactly two triangles, once in
    /// each direction (consistent winding).
    fn assert_closed(m: &MeshBuilder) {
        let mut edges = std::collections::HashMap::new();
        for t in &m.indices {
            for k in 0..3 {
                *edges.entry((t[k], t[(k + 1) % 3])).or_insert(0) += 1;
            }
        }
        for (&(a, b), &n) in &edges {
            assert_eq!(n, 1, "edge {a}->{b} used {n} times");
            assert_eq!(edges.get(&(b, a)), Some(&1), "edge {a}->{b} has no twin");
        }
    }

    #[test]
    fn triangle_counts_match_formulas_and_shapes_are_closed() {
        let b = unit_box();
        assert_eq!((b.positions.len(), b.indices.len()), (8, 12));
        assert_closed(&b);
        let s = sphere(16, 8);
        assert_eq!(s.indices.len(), 2 * 16 * 7);
        assert_closed(&s);
        let c = cylinder(10);
        assert_eq!(c.indices.len(), 40);
        assert_closed(&c);
        let r = gable_roof();
        assert_eq!(r.indices.len(), 8);
        assert_closed(&r);
        let t = tube(
            32,
            8,
            0.2,
            |u| Vec3::new((u * std::f32::consts::TAU).cos(), (u * std::f32::consts::TAU).sin(), 0.0),
            |_, _| 1.0,
        );
        assert_eq!(t.indices.len(), 2 * 32 * 8);
        assert_closed(&t);
        let h = height_field(0.0, 0.0, 1.0, 1.0, 3, 2, |_, _| 0.0);
        assert_eq!((h.positions.len(), h.indices.len()), (12, 12));
    }

    #[test]
    fn unit_sphere_and_box_bounds() {
        let s = sphere(24, 12).build().unwrap();
        assert!((s.bounds.min.z + 1.0).abs() < 1e-6 && (s.bounds.max.z - 1.0).abs() < 1e-6);
        for p in &s.positions {
            assert!((p.length() - 1.0).abs() < 1e-5);
        }
        let b = unit_box().build().unwrap();
        assert_eq!(b.bounds.min, Vec3::new(-0.5, -0.5, 0.0));
        assert_eq!(b.bounds.max, Vec3::new(0.5, 0.5, 1.0));
    }
}
