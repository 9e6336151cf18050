//! Surface colour of meshes: materials, base-colour textures and the sRGB transfer curve.
//!
//! Colour warping (seed 001) is judged by how well it resamples detail, so every rendered
//! surface carries detail: a base-colour texture where a file provides one, otherwise the
//! renderer's procedural triplanar pattern ([`ColorMap::Pattern`]).
//!
//! Conventions: colours are **linear** RGB(A) `f32`; sRGB appears only in files (decoded with
//! [`srgb_to_linear`], written with [`linear_to_srgb`]). Texture coordinates follow glTF:
//! `(0, 0)` is the top-left corner of image row 0, `u` grows to the right, `v` downwards; texel
//! `(i, j)` has its centre at `((i + 0.5) / width, (j + 0.5) / height)`.

use std::sync::Arc;

use glam::{Vec2, Vec3};

use crate::{Error, Image, Result};

/// sRGB-encoded value in `[0, 1]` -> linear light (IEC 61966-2-1 transfer curve).
#[inline]
pub fn srgb_to_linear(s: f32) -> f32 {
    if s <= 0.040_45 {
        s / 12.92
    } else {
        ((s + 0.055) / 1.055).powf(2.4)
    }
}

/// Linear light -> sRGB-encoded value, clamped to `[0, 1]` (NaN -> 0); the inverse of
/// [`srgb_to_linear`].
#[inline]
pub fn linear_to_srgb(v: f32) -> f32 {
    if v.is_nan() {
        return 0.0;
    }
    let v = v.clamp(0.0, 1.0);
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// How texture coordinates outside `[0, 1]` map into the image (glTF sampler wrap modes).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Wrap {
    /// Tiles the image (glTF `REPEAT`, the default).
    #[default]
    Repeat,
    /// Repeats the edge texels (glTF `CLAMP_TO_EDGE`).
    Clamp,
    /// Tiles the image, every other copy mirrored (glTF `MIRRORED_REPEAT`).
    Mirror,
}

impl Wrap {
    /// Texel index `i` wrapped into `[0, n)`.
    #[inline]
    pub fn index(self, i: i32, n: i32) -> i32 {
        match self {
            Wrap::Repeat => i.rem_euclid(n),
            Wrap::Clamp => i.clamp(0, n - 1),
            Wrap::Mirror => {
                let m = i.rem_euclid(2 * n);
                if m >= n {
                    2 * n - 1 - m
                } else {
                    m
                }
            }
        }
    }
    /// Code of the mode in the GPU renderer's texture table (0 repeat, 1 clamp, 2 mirror).
    pub fn code(self) -> u32 {
        match self {
            Wrap::Repeat => 0,
            Wrap::Clamp => 1,
            Wrap::Mirror => 2,
        }
    }
}

/// A base-colour texture: linear RGBA `f32` texels (row 0 at the top, as [`Image`]) sampled
/// bilinearly with a wrap mode per axis. Alpha is carried but the renderer draws opaque.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    image: Image<[f32; 4]>,
    wrap: [Wrap; 2],
}

impl Texture {
    /// A texture from linear RGBA texels; errors on a zero-size image or non-finite texels.
    pub fn new(image: Image<[f32; 4]>, wrap_u: Wrap, wrap_v: Wrap) -> Result<Self> {
        image.check_nonempty("texture")?;
        if image.width() > i32::MAX as u32 / 2 || image.height() > i32::MAX as u32 / 2 {
            return Err(Error::invalid(format!("texture {}x{} is too large", image.width(), image.height())));
        }
        if let Some(i) = image.data().iter().position(|t| !t.iter().all(|c| c.is_finite())) {
            return Err(Error::invalid(format!("texel {i} of the texture is not finite ({:?})", image.data()[i])));
        }
        Ok(Texture { image, wrap: [wrap_u, wrap_v] })
    }

    /// A texture from 8-bit sRGB-encoded RGBA bytes (`width * height * 4`, row 0 at the top),
    /// decoded to linear light (alpha stays linear, as in glTF and PNG).
    pub fn from_srgb8(width: u32, height: u32, rgba: &[u8], wrap_u: Wrap, wrap_v: Wrap) -> Result<Self> {
        if rgba.len() != width as usize * height as usize * 4 {
            return Err(Error::invalid(format!(
                "texture data has {} bytes, expected {width}x{height}x4 = {}",
                rgba.len(),
                width as usize * height as usize * 4
            )));
        }
        let lut: Vec<f32> = (0..256).map(|b| srgb_to_linear(b as f32 / 255.0)).collect();
        let texels = rgba
            .chunks_exact(4)
            .map(|c| [lut[c[0] as usize], lut[c[1] as usize], lut[c[2] as usize], c[3] as f32 / 255.0])
            .collect();
        Texture::new(Image::from_vec(width, height, texels)?, wrap_u, wrap_v)
    }

    /// The texels (linear RGBA).
    pub fn image(&self) -> &Image<[f32; 4]> {
        &self.image
    }

    /// Wrap modes `[u, v]`.
    pub fn wrap(&self) -> [Wrap; 2] {
        self.wrap
    }

    /// Bilinear sample at texture coordinate `uv` (glTF convention, see the module docs):
    /// `x = u w - 0.5`, `y = v h - 0.5`, the four texels around `(x, y)` wrapped and blended as
    /// `a (1 - f) + b f`, first along x, then along y. The GPU renderer's WGSL twin
    /// (`sample_texture` in `depth.wgsl`) computes the same expression.
    pub fn sample(&self, uv: Vec2) -> [f32; 4] {
        let (w, h) = (self.image.width() as i32, self.image.height() as i32);
        let x = uv.x * w as f32 - 0.5;
        let y = uv.y * h as f32 - 0.5;
        let (fx, fy) = (crate::round::floor(x), crate::round::floor(y));
        let (ax, ay) = (x - fx, y - fy);
        let (x0, y0) = (fx as i32, fy as i32);
        let xs = [self.wrap[0].index(x0, w), self.wrap[0].index(x0.saturating_add(1), w)];
        let ys = [self.wrap[1].index(y0, h), self.wrap[1].index(y0.saturating_add(1), h)];
        let t = |i: usize, j: usize| *self.image.get(xs[i] as u32, ys[j] as u32);
        let lerp = |a: [f32; 4], b: [f32; 4], f: f32| [0, 1, 2, 3].map(|k| a[k] * (1.0 - f) + b[k] * f);
        lerp(lerp(t(0, 0), t(1, 0), ax), lerp(t(0, 1), t(1, 1), ax), ay)
    }
}

/// Where the albedo of a surface comes from (multiplied by [`Material::base_color`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub enum ColorMap {
    /// The renderer's deterministic triplanar pattern (fine value noise and stripes at several
    /// fixed world-space scales, `zwarp_raster::shading::pattern`): detail on every surface of
    /// scenes without textures.
    #[default]
    Pattern,
    /// A base-colour texture addressed by the mesh's UVs (meshes without UVs get the pattern).
    Texture(Arc<Texture>),
    /// The base colour alone (no detail; for analytic tests and flat-coloured figures).
    Uniform,
}

/// The surface of a run of triangles: albedo = `Instance::albedo * base_color * map`.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Linear RGB factor (glTF `baseColorFactor`, OBJ `Kd`).
    pub base_color: Vec3,
    /// Texture, pattern or nothing.
    pub map: ColorMap,
    /// How much of the light behind the surface it blocks: 1 opaque, below 1 translucent (glTF
    /// `alphaMode: BLEND` with the `baseColorFactor` alpha). The renderers draw every surface
    /// opaque; `zwarp vr` puts mostly translucent meshes in the A-buffer (seed 003 Sec. 4.2,
    /// [`crate::Mesh::translucent_color`]).
    pub opacity: f32,
}

impl Default for Material {
    fn default() -> Self {
        DEFAULT_MATERIAL
    }
}

/// The material of triangles no [`MeshPart`] covers: white base colour with the pattern.
pub const DEFAULT_MATERIAL: Material = Material { base_color: Vec3::ONE, map: ColorMap::Pattern, opacity: 1.0 };

impl Material {
    /// A material with base colour `base_color` and the triplanar pattern.
    pub fn pattern(base_color: Vec3) -> Self {
        Material { base_color, map: ColorMap::Pattern, opacity: 1.0 }
    }
    /// A material with a plain base colour.
    pub fn uniform(base_color: Vec3) -> Self {
        Material { base_color, map: ColorMap::Uniform, opacity: 1.0 }
    }
    /// A textured material (`base_color` multiplies the texture).
    pub fn textured(base_color: Vec3, texture: Arc<Texture>) -> Self {
        Material { base_color, map: ColorMap::Texture(texture), opacity: 1.0 }
    }
    /// The material with `opacity` (see [`Material::opacity`]).
    pub fn with_opacity(self, opacity: f32) -> Self {
        Material { opacity, ..self }
    }
    /// `true` if the surface lets light through (opacity below 1).
    pub fn is_translucent(&self) -> bool {
        self.opacity < 1.0
    }
    /// The texture, if the map is one.
    pub fn texture(&self) -> Option<&Arc<Texture>> {
        match &self.map {
            ColorMap::Texture(t) => Some(t),
            _ => None,
        }
    }
    pub(crate) fn validate(&self) -> Result<()> {
        if !self.base_color.is_finite() {
            return Err(Error::invalid(format!("material base colour is not finite ({})", self.base_color)));
        }
        if !(0.0..=1.0).contains(&self.opacity) {
            return Err(Error::invalid(format!("material opacity {} is outside [0, 1]", self.opacity)));
        }
        Ok(())
    }
}

/// Triangles `first_triangle..` (up to the next part's first triangle, or the end) of a mesh
/// and their material (glTF primitives, OBJ `usemtl` groups).
#[derive(Clone, Debug, PartialEq)]
pub struct MeshPart {
    /// Index of the part's first triangle in [`crate::Mesh::indices`].
    pub first_triangle: u32,
    /// The part's material.
    pub material: Material,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Mesh;

    fn checker() -> Texture {
        // 2x2: red, green / blue, white (linear values).
        let img = Image::from_vec(
            2,
            2,
            vec![[1.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 1.0], [0.0, 0.0, 1.0, 1.0], [1.0, 1.0, 1.0, 1.0]],
        )
        .unwrap();
        Texture::new(img, Wrap::Repeat, Wrap::Repeat).unwrap()
    }

    #[test]
    fn srgb_round_trip() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
        assert!((srgb_to_linear(0.5) - 0.214_041).abs() < 1e-5);
        for i in 0..=255 {
            let s = i as f32 / 255.0;
            assert!((linear_to_srgb(srgb_to_linear(s)) - s).abs() < 1e-5, "{i}");
        }
        assert_eq!(linear_to_srgb(f32::NAN), 0.0);
        assert!((linear_to_srgb(2.0) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn bilinear_sampling_hits_texel_centres_and_wraps() {
        let t = checker();
        assert_eq!(t.sample(Vec2::new(0.25, 0.25)), [1.0, 0.0, 0.0, 1.0]);
        assert_eq!(t.sample(Vec2::new(0.75, 0.25)), [0.0, 1.0, 0.0, 1.0]);
        assert_eq!(t.sample(Vec2::new(0.25, 0.75)), [0.0, 0.0, 1.0, 1.0]);
        // Halfway between red and green.
        assert_eq!(t.sample(Vec2::new(0.5, 0.25)), [0.5, 0.5, 0.0, 1.0]);
        // Repeat: u = 1.25 is u = 0.25; u = 0 blends the last and first columns.
        assert_eq!(t.sample(Vec2::new(1.25, -0.75)), t.sample(Vec2::new(0.25, 0.25)));
        assert_eq!(t.sample(Vec2::new(0.0, 0.25)), [0.5, 0.5, 0.0, 1.0]);
        let c = Texture::new(t.image().clone(), Wrap::Clamp, Wrap::Mirror).unwrap();
        assert_eq!(c.sample(Vec2::new(-3.0, 0.25)), [1.0, 0.0, 0.0, 1.0]);
        // Mirror: v in [1, 2] reads the image upside down.
        assert_eq!(c.sample(Vec2::new(0.25, 1.75)), [1.0, 0.0, 0.0, 1.0]);
        assert_eq!(Wrap::Mirror.index(-1, 3), 0);
        assert_eq!(Wrap::Mirror.index(3, 3), 2);
        assert_eq!(Wrap::Repeat.index(-1, 3), 2);
    }

    #[test]
    fn srgb8_textures_decode_to_linear() {
        let t = Texture::from_srgb8(1, 1, &[255, 128, 0, 51], Wrap::Repeat, Wrap::Repeat).unwrap();
        let p = t.sample(Vec2::new(0.3, 0.9));
        assert!((p[0] - 1.0).abs() < 1e-6 && (p[1] - 0.2158605).abs() < 1e-5 && p[2] == 0.0);
        assert!((p[3] - 0.2).abs() < 1e-6);
        assert!(Texture::from_srgb8(2, 1, &[0; 4], Wrap::Repeat, Wrap::Repeat).is_err());
        assert!(Texture::new(Image::new(0, 3, [0.0; 4]), Wrap::Repeat, Wrap::Repeat).is_err());
        let e = Texture::new(Image::new(1, 1, [f32::NAN; 4]), Wrap::Repeat, Wrap::Repeat).unwrap_err();
        assert!(e.to_string().contains("not finite"), "{e}");
    }

    fn tri() -> Mesh {
        Mesh::new(vec![Vec3::ZERO, Vec3::X, Vec3::Y], vec![[0, 1, 2]]).unwrap()
    }

    #[test]
    fn mesh_attributes_are_validated() {
        let m = tri().with_normals(vec![Vec3::Z; 3]).unwrap().with_uvs(vec![Vec2::ZERO; 3]).unwrap();
        m.validate().unwrap();
        assert_eq!(m.material_of(0), &DEFAULT_MATERIAL);
        let e = tri().with_uvs(vec![Vec2::ZERO; 2]).unwrap_err().to_string();
        assert_eq!(e, "invalid input: mesh has 2 uvs for 3 vertices (need one per vertex)");
        let e = tri().with_normals(vec![Vec3::Z, Vec3::NAN, Vec3::Z]).unwrap_err().to_string();
        assert_eq!(e, "invalid input: normal 1 is not finite");
        let mut bad = tri();
        bad.normals = Some(vec![Vec3::Z]);
        assert!(bad.validate().is_err());
        assert!(!e.contains('\n'));
    }

    #[test]
    fn mostly_translucent_meshes_have_one_premultiplied_colour() {
        let m = Mesh::new(vec![Vec3::ZERO, Vec3::X, Vec3::Y], vec![[0, 1, 2]; 4]).unwrap();
        assert_eq!(m.translucent_color(), None);
        let glass = Material::uniform(Vec3::new(1.0, 0.5, 0.0)).with_opacity(0.5);
        let part = |f, material: &Material| MeshPart { first_triangle: f, material: material.clone() };
        // Three of four triangles at opacity 0.5: premultiplied (0.5, 0.25, 0, 0.5).
        let t = m.clone().with_parts(vec![part(0, &Material::default()), part(1, &glass)]).unwrap();
        assert_eq!(t.translucent_color(), Some([0.5, 0.25, 0.0, 0.5]));
        // Half of the triangles is not most of them.
        let h = m.clone().with_parts(vec![part(0, &Material::default()), part(2, &glass)]).unwrap();
        assert_eq!(h.translucent_color(), None);
        let e = m.with_parts(vec![part(0, &glass.with_opacity(1.5))]).unwrap_err().to_string();
        assert!(e.contains("opacity 1.5 is outside [0, 1]"), "{e}");
    }

    #[test]
    fn mesh_parts_pick_materials() {
        let m = Mesh::new(vec![Vec3::ZERO, Vec3::X, Vec3::Y], vec![[0, 1, 2]; 5]).unwrap();
        let red = Material::uniform(Vec3::X);
        let m = m
            .with_parts(vec![
                MeshPart { first_triangle: 0, material: Material::default() },
                MeshPart { first_triangle: 3, material: red.clone() },
            ])
            .unwrap();
        assert_eq!(m.material_of(2), &DEFAULT_MATERIAL);
        assert_eq!(m.material_of(3), &red);
        assert_eq!(m.material_of(4), &red);
        assert_eq!(m.part_of(4), Some(1));
        let base = Mesh::new(vec![Vec3::ZERO, Vec3::X, Vec3::Y], vec![[0, 1, 2]; 5]).unwrap();
        let part = |f| MeshPart { first_triangle: f, material: Material::default() };
        assert!(base.clone().with_parts(vec![part(1)]).is_err());
        assert!(base.clone().with_parts(vec![part(0), part(0)]).is_err());
        assert!(base.clone().with_parts(vec![part(0), part(5)]).is_err());
        let nan = MeshPart { first_triangle: 0, material: Material::pattern(Vec3::NAN) };
        let e = base.with_parts(vec![nan]).unwrap_err().to_string();
        assert!(e.contains("mesh part 0: material base colour is not finite"), "{e}");
    }
}
