//! File loaders: glTF 2.0 (`.gltf`/`.glb`), Wavefront OBJ, PLY, the raw soup folder format and
//! folders of mesh files. They produce the objects the renderer, warper and culler work on
//! (seed 000 Sec. 4-5: per-object item buffers and occlusion queries).
//!
//! Surface data for textured colour (colour warping needs detail to resample): per-vertex
//! normals (glTF `NORMAL`, OBJ `vn`, PLY `nx ny nz`), texture coordinates (glTF `TEXCOORD_n`,
//! OBJ `vt` with `v` flipped to glTF's top-left origin) and materials (glTF
//! `baseColorFactor` / `baseColorTexture` with its sampler's wrap modes, OBJ `Kd` / `map_Kd`,
//! the map's path relative to its `.mtl`). Textures are decoded (PNG, JPEG) from sRGB to linear
//! RGBA `f32` once per file and shared. A texture that is missing or cannot be decoded is an
//! error, not a silent fallback. Meshes without a file material get the renderer's pattern.
//!
//! Every error is one line naming the offending file (`Error::Parse { path, msg }` or
//! `Error::Io`).

use std::cell::RefCell;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{DMat4, DQuat, DVec3, Mat3, Mat4, Vec2, Vec3};
use rayon::prelude::*;
use zwarp_core::{
    srgb_to_linear, Animation, ColorMap, Error, Image, Material, Mesh, MeshPart, Result, Scene, Texture, Wrap,
};

use crate::{albedo_for_id, is_ground_name, ply, soup, SceneOptions, GROUND_ALBEDO};

/// Mesh file kinds the loaders understand.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kind {
    Gltf,
    Obj,
    Ply,
}

pub(crate) fn kind_of(path: &Path) -> Option<Kind> {
    let ext = path.extension()?.to_str()?.to_ascii_lowercase();
    match ext.as_str() {
        "gltf" | "glb" => Some(Kind::Gltf),
        "obj" => Some(Kind::Obj),
        "ply" => Some(Kind::Ply),
        _ => None,
    }
}

/// Up axis of a file format: glTF and OBJ are Y up, PLY (and the raw soups) Z up.
pub(crate) fn up_of(kind: Kind) -> Vec3 {
    match kind {
        Kind::Gltf | Kind::Obj => Vec3::Y,
        Kind::Ply => Vec3::Z,
    }
}

/// One object as read from a file, before it goes into a [`Scene`].
pub(crate) struct Part {
    pub name: String,
    /// Mesh key: parts with the same key share one mesh (glTF meshes used by several nodes).
    pub mesh_key: usize,
    pub transform: Mat4,
    /// The file gives this part's mesh materials (then the instance tint is white).
    pub has_material: bool,
    /// A piece of the previous part's object, split off for culling ([`split_single`]): it
    /// keeps that object's tint.
    pub piece: bool,
}

/// Meshes + parts of one file.
pub(crate) struct FileObjects {
    pub meshes: Vec<Mesh>,
    pub parts: Vec<Part>,
    /// Where the meshes' coordinate origin lies in the file's coordinates: zero, except for
    /// files read in `f64` (OBJ, PLY) that lie far from their origin, whose `f32` positions are
    /// kept relative to it.
    pub anchor: DVec3,
}

impl FileObjects {
    /// Moves the objects from this file's anchor to `origin` (a scene's: whole units, like the
    /// anchor, so the shift is exact in `f32` and the coordinates stay small): the positions of
    /// meshes only untransformed parts use, the transforms of the other parts
    /// ([`zwarp_core::translate_placed`]).
    fn move_to(&mut self, origin: DVec3) {
        let d = self.anchor - origin;
        if d != DVec3::ZERO {
            let mut placed: Vec<(u32, &mut Mat4)> =
                self.parts.iter_mut().map(|p| (p.mesh_key as u32, &mut p.transform)).collect();
            zwarp_core::translate_placed(&mut self.meshes, &mut placed, d);
        }
        self.anchor = origin;
    }

    /// The file-coordinate bounds of the meshes, in `f64`: `(lo, hi)`, `None` without vertices.
    fn file_bounds(&self) -> Option<(DVec3, DVec3)> {
        let b = self.meshes.iter().fold(zwarp_core::Aabb::EMPTY, |b, m| b.union(m.bounds));
        (!b.is_empty()).then(|| (b.min.as_dvec3() + self.anchor, b.max.as_dvec3() + self.anchor))
    }
}

/// Turns an `Error::Invalid` from mesh validation into a parse error naming `path`.
fn at(path: &Path) -> impl Fn(Error) -> Error + '_ {
    move |e| match e {
        Error::Invalid(msg) => Error::parse(path, msg),
        other => other,
    }
}

/// Loads a PLY file as one mesh (no object structure in PLY), with its positions' anchor
/// ([`ply::PlyMesh::anchor`]).
pub(crate) fn load_ply(path: &Path) -> Result<(Mesh, DVec3)> {
    let m = ply::read_ply(path)?;
    let mesh = Mesh::new(m.positions, m.indices).map_err(at(path))?;
    match m.normals {
        Some(n) => Ok((mesh.with_normals(n).map_err(at(path))?, m.anchor)),
        None => Ok((mesh, m.anchor)),
    }
}

/// Loads an OBJ file: each model (`o`/`g`, split by tobj at every `usemtl`) is one object,
/// polygons triangulated, with the file's normals and texture coordinates; a model with a
/// material gets `Kd` (times `map_Kd` where given) as its material. A missing or broken `.mtl`
/// only costs the materials; a `map_Kd` that is missing or undecodable is an error naming the
/// `.mtl` and the texture.
pub(crate) fn load_obj(path: &Path) -> Result<FileObjects> {
    if !path.is_file() {
        return Err(Error::parse(path, "file not found"));
    }
    let dir = path.parent().unwrap_or(Path::new("."));
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut reader = std::io::BufReader::new(file);
    let opts = tobj::LoadOptions { triangulate: true, single_index: true, ignore_points: true, ignore_lines: true };
    // Which .mtl each material comes from (tobj appends the libraries' materials in order).
    let libs: RefCell<Vec<(PathBuf, usize)>> = RefCell::new(Vec::new());
    let (models, materials) = tobj::load_obj_buf(&mut reader, &opts, |p| {
        let full = dir.join(p);
        let r = tobj::load_mtl(&full);
        libs.borrow_mut().push((full, r.as_ref().map_or(0, |(m, _)| m.len())));
        r
    })
    .map_err(|e| Error::parse(path, format!("OBJ: {e}")))?;
    let materials = materials.unwrap_or_default();
    let libs = libs.into_inner();
    let mtl_of = |i: usize| -> PathBuf {
        let mut first = 0;
        for (p, n) in &libs {
            if i < first + n {
                return p.clone();
            }
            first += n;
        }
        path.to_path_buf()
    };
    let mut textures: HashMap<PathBuf, Arc<Texture>> = HashMap::new();
    let mut built: HashMap<usize, Material> = HashMap::new();
    // Positions are read in f64 and kept relative to the file's anchor: geo-referenced files
    // (UTM metres) would otherwise step by up to 0.5 m in f32.
    let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
    for c in models.iter().flat_map(|m| m.mesh.positions.chunks_exact(3)) {
        let p = DVec3::new(c[0], c[1], c[2]);
        (lo, hi) = (lo.min(p), hi.max(p));
    }
    let anchor = if lo.cmple(hi).all() { crate::far_offset(lo, hi) } else { DVec3::ZERO };
    let mut out = FileObjects { meshes: Vec::new(), parts: Vec::new(), anchor };
    for model in models {
        let m = &model.mesh;
        if m.positions.len() % 3 != 0 || m.indices.len() % 3 != 0 {
            return Err(Error::parse(path, format!("OBJ model '{}' has malformed arrays", model.name)));
        }
        let positions: Vec<Vec3> =
            m.positions.chunks_exact(3).map(|c| (DVec3::new(c[0], c[1], c[2]) - anchor).as_vec3()).collect();
        let indices: Vec<[u32; 3]> = m.indices.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
        if indices.is_empty() {
            continue;
        }
        let in_model = |e: Error| Error::parse(path, format!("OBJ model '{}': {}", model.name, strip(e)));
        let mut mesh = Mesh::new(positions, indices).map_err(in_model)?;
        if !m.normals.is_empty() {
            let n = m.normals.chunks_exact(3).map(|c| DVec3::new(c[0], c[1], c[2]).as_vec3()).collect();
            mesh = mesh.with_normals(n).map_err(in_model)?;
        }
        if !m.texcoords.is_empty() {
            // OBJ's v runs up from the bottom of the image; zwarp's UVs are glTF's (top-left origin).
            let uv = m.texcoords.chunks_exact(2).map(|c| Vec2::new(c[0] as f32, (1.0 - c[1]) as f32)).collect();
            mesh = mesh.with_uvs(uv).map_err(in_model)?;
        }
        let material = match m.material_id.filter(|&i| i < materials.len()) {
            Some(i) => {
                if let std::collections::hash_map::Entry::Vacant(e) = built.entry(i) {
                    e.insert(obj_material(&materials[i], &mtl_of(i), &mut textures)?);
                }
                Some(built[&i].clone())
            }
            None => None,
        };
        let has_material = material.is_some();
        if let Some(mat) = material {
            let has_uvs = mesh.uvs.is_some();
            mesh = mesh.with_material(fallback_without_uvs(mat, has_uvs));
        }
        out.parts.push(Part {
            name: model.name.clone(),
            mesh_key: out.meshes.len(),
            transform: Mat4::IDENTITY,
            has_material,
            piece: false,
        });
        out.meshes.push(mesh);
    }
    Ok(out)
}

/// An OBJ material: `Kd` (white if absent) times `map_Kd` (path relative to the `.mtl`; the
/// last word of the statement when the whole is not a file, so `-o`/`-s` options are skipped).
fn obj_material(m: &tobj::Material, mtl: &Path, cache: &mut HashMap<PathBuf, Arc<Texture>>) -> Result<Material> {
    let kd = m.diffuse.map(|d| DVec3::from_array(d).as_vec3()).filter(|c| c.is_finite()).unwrap_or(Vec3::ONE);
    let Some(map) = m.diffuse_texture.as_deref().map(str::trim).filter(|s| !s.is_empty()) else {
        return Ok(Material::pattern(kd));
    };
    let base = mtl.parent().unwrap_or(Path::new("."));
    let whole = base.join(map.replace('\\', "/"));
    let file = if whole.is_file() {
        whole
    } else {
        let last = map.split_whitespace().last().unwrap_or(map);
        let f = base.join(last.replace('\\', "/"));
        if !f.is_file() {
            return Err(Error::parse(mtl, format!("material '{}': map_Kd texture {} not found", m.name, f.display())));
        }
        f
    };
    if let Some(t) = cache.get(&file) {
        return Ok(Material::textured(kd, t.clone()));
    }
    let img = image::open(&file).map_err(|e| Error::parse(&file, format!("texture: {e}")))?;
    let rgba = img.to_rgba32f();
    let (w, h) = rgba.dimensions();
    let tex = Arc::new(texture_from_encoded(w, h, rgba.as_raw(), 4, true, [Wrap::Repeat; 2]).map_err(at(&file))?);
    cache.insert(file, tex.clone());
    Ok(Material::textured(kd, tex))
}

/// A textured material on a mesh without UVs shows the pattern instead (with its base colour).
fn fallback_without_uvs(m: Material, has_uvs: bool) -> Material {
    match m.map {
        ColorMap::Texture(_) if !has_uvs => Material::pattern(m.base_color).with_opacity(m.opacity),
        _ => m,
    }
}

/// A texture from `channels` interleaved encoded values in `[0, 1]` per texel (1 = grey,
/// 2 = grey + alpha, 3 = RGB, 4 = RGBA), colour channels sRGB-decoded when `srgb`.
fn texture_from_encoded(w: u32, h: u32, v: &[f32], channels: usize, srgb: bool, wrap: [Wrap; 2]) -> Result<Texture> {
    if channels == 0 || v.len() != w as usize * h as usize * channels {
        return Err(Error::invalid(format!("texture data does not match its {w}x{h} size")));
    }
    let dec = |x: f32| if srgb { srgb_to_linear(x) } else { x };
    let texels = v
        .chunks_exact(channels)
        .map(|c| match channels {
            1 => [dec(c[0]), dec(c[0]), dec(c[0]), 1.0],
            2 => [dec(c[0]), dec(c[0]), dec(c[0]), c[1]],
            3 => [dec(c[0]), dec(c[1]), dec(c[2]), 1.0],
            _ => [dec(c[0]), dec(c[1]), dec(c[2]), c[3]],
        })
        .collect();
    Texture::new(Image::from_vec(w, h, texels)?, wrap[0], wrap[1])
}

/// Decoded glTF image -> linear RGBA texture (8/16-bit channels are sRGB, float ones linear).
fn gltf_texture(data: &gltf::image::Data, wrap: [Wrap; 2]) -> Result<Texture> {
    use gltf::image::Format as F;
    let (channels, bytes) = match data.format {
        F::R8 => (1, 1),
        F::R8G8 => (2, 1),
        F::R8G8B8 => (3, 1),
        F::R8G8B8A8 => (4, 1),
        F::R16 => (1, 2),
        F::R16G16 => (2, 2),
        F::R16G16B16 => (3, 2),
        F::R16G16B16A16 => (4, 2),
        F::R32G32B32FLOAT => (3, 4),
        F::R32G32B32A32FLOAT => (4, 4),
    };
    let v: Vec<f32> = match bytes {
        1 => data.pixels.iter().map(|&b| b as f32 / 255.0).collect(),
        2 => data.pixels.chunks_exact(2).map(|b| u16::from_ne_bytes([b[0], b[1]]) as f32 / 65535.0).collect(),
        _ => data.pixels.chunks_exact(4).map(|b| f32::from_ne_bytes([b[0], b[1], b[2], b[3]])).collect(),
    };
    texture_from_encoded(data.width, data.height, &v, channels, bytes < 4, wrap)
}

fn gltf_wrap(m: gltf::texture::WrappingMode) -> Wrap {
    match m {
        gltf::texture::WrappingMode::ClampToEdge => Wrap::Clamp,
        gltf::texture::WrappingMode::MirroredRepeat => Wrap::Mirror,
        gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
    }
}

fn strip(e: Error) -> String {
    match e {
        Error::Invalid(m) => m,
        other => other.to_string(),
    }
}

/// Loads a glTF 2.0 file (`.gltf` with external or embedded base64 buffers, or `.glb`): every
/// node with a mesh is one object with its world transform; all triangle primitives of a mesh
/// form one [`Mesh`] (one [`MeshPart`] per primitive), shared by the nodes that use it.
/// Base-colour textures are decoded once per (image, sampler).
pub(crate) fn load_gltf(path: &Path) -> Result<FileObjects> {
    if !path.is_file() {
        return Err(Error::parse(path, "file not found"));
    }
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let g = gltf::Gltf::from_slice(&bytes).map_err(|e| Error::parse(path, format!("glTF: {e}")))?;
    let base = path.parent().unwrap_or(Path::new("."));
    let doc = g.document;
    let buffers =
        gltf::import_buffers(&doc, Some(base), g.blob).map_err(|e| Error::parse(path, format!("glTF buffers: {e}")))?;

    let mut mesh_slot: HashMap<usize, usize> = HashMap::new();
    let mut textures = GltfTextures { base, buffers: &buffers, cache: HashMap::new() };
    let mut out = FileObjects { meshes: Vec::new(), parts: Vec::new(), anchor: DVec3::ZERO };
    let roots: Vec<gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(s) => s.nodes().collect(),
        None => {
            // No scene: every node that is nobody's child is a root.
            let children: std::collections::HashSet<usize> =
                doc.nodes().flat_map(|n| n.children().map(|c| c.index()).collect::<Vec<_>>()).collect();
            doc.nodes().filter(|n| !children.contains(&n.index())).collect()
        }
    };
    // The nodes' transforms in f64 as the file writes them (gltf parses them into f32, which
    // steps by 0.5 m at 4,000 km: geo-referenced files place their objects that way).
    let exact = gltf_node_transforms(&bytes);
    let local_of = |node: &gltf::Node| {
        exact
            .get(node.index())
            .copied()
            .flatten()
            .unwrap_or_else(|| Mat4::from_cols_array_2d(&node.transform().matrix()).as_dmat4())
    };
    // World transforms in f64 beside each part, for the file's anchor.
    let mut worlds: Vec<DMat4> = Vec::new();
    // Iterative DFS with a depth guard: glTF forbids cycles but a malformed file could hold one.
    let mut stack: Vec<(gltf::Node, Mat4, DMat4, usize)> =
        roots.into_iter().map(|n| (n, Mat4::IDENTITY, DMat4::IDENTITY, 0)).collect();
    while let Some((node, parent, parent_d, depth)) = stack.pop() {
        if depth > 256 {
            return Err(Error::parse(path, "glTF node hierarchy deeper than 256 (cycle?)"));
        }
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        let world_d = parent_d * local_of(&node);
        if !world.is_finite() || !world_d.is_finite() {
            return Err(Error::parse(path, format!("glTF node {} has a non-finite transform", node.index())));
        }
        if let Some(mesh) = node.mesh() {
            let slot = match mesh_slot.get(&mesh.index()) {
                Some(&s) => Some(s),
                None => {
                    let m = gltf_mesh(path, &mesh, &buffers, &mut textures)?;
                    if m.indices.is_empty() {
                        None
                    } else {
                        out.meshes.push(m);
                        mesh_slot.insert(mesh.index(), out.meshes.len() - 1);
                        Some(out.meshes.len() - 1)
                    }
                }
            };
            if let Some(slot) = slot {
                let has_material = mesh.primitives().any(|p| p.material().index().is_some());
                let name = node.name().or(mesh.name()).unwrap_or("").to_string();
                out.parts.push(Part { name, mesh_key: slot, transform: world, has_material, piece: false });
                worlds.push(world_d);
            }
        }
        for c in node.children() {
            stack.push((c, world, world_d, depth + 1));
        }
    }
    // Objects placed far from the file's origin: their transforms relative to the anchor, from
    // the f64 ones (near the origin the f32 walk stands, as it always did).
    let (lo, hi) = worlds
        .iter()
        .map(|w| w.w_axis.truncate())
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), t| (lo.min(t), hi.max(t)));
    if lo.cmple(hi).all() {
        out.anchor = crate::far_offset(lo, hi);
    }
    if out.anchor != DVec3::ZERO {
        let to_anchor = DMat4::from_translation(-out.anchor);
        for (p, w) in out.parts.iter_mut().zip(&worlds) {
            p.transform = (to_anchor * *w).as_mat4();
        }
    }
    Ok(out)
}

/// Every node's local transform as the file writes it, read in `f64` from the glTF JSON (the
/// `.gltf` file's `bytes` or a `.glb`'s JSON chunk): `matrix`, or `translation` x `rotation` x
/// `scale`; `None` for a node whose numbers are not all there (the caller falls back to gltf's
/// `f32`), none at all where gltf accepted what this does not parse.
fn gltf_node_transforms(bytes: &[u8]) -> Vec<Option<DMat4>> {
    let json: &[u8] = if bytes.starts_with(b"glTF") {
        // GLB: 12-byte header, then the JSON chunk (length, type "JSON", data).
        let len = bytes.get(12..16).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize);
        match len.and_then(|n| bytes.get(20..20 + n)) {
            Some(j) if bytes.get(16..20) == Some(b"JSON") => j,
            _ => return Vec::new(), // gltf has read it: anything else is its business
        }
    } else {
        bytes
    };
    let Ok(root) = serde_json::from_slice::<serde_json::Value>(json) else { return Vec::new() };
    let nums = |v: Option<&serde_json::Value>, n: usize| -> Option<Vec<f64>> {
        let a = v?.as_array()?;
        (a.len() == n).then(|| a.iter().map(|x| x.as_f64()).collect::<Option<Vec<f64>>>()).flatten()
    };
    let nodes = root.get("nodes").and_then(|n| n.as_array()).map(|n| n.as_slice()).unwrap_or(&[]);
    nodes
        .iter()
        .map(|n| {
            if n.get("matrix").is_some() {
                return nums(n.get("matrix"), 16).map(|m| DMat4::from_cols_slice(&m));
            }
            let t = match n.get("translation") {
                Some(v) => DVec3::from_slice(&nums(Some(v), 3)?),
                None => DVec3::ZERO,
            };
            let r = match n.get("rotation") {
                Some(v) => DQuat::from_slice(&nums(Some(v), 4)?),
                None => DQuat::IDENTITY,
            };
            let s = match n.get("scale") {
                Some(v) => DVec3::from_slice(&nums(Some(v), 3)?),
                None => DVec3::ONE,
            };
            Some(DMat4::from_scale_rotation_translation(s, r, t))
        })
        .collect()
}

/// Base-colour textures of one glTF file, decoded on first use.
struct GltfTextures<'a> {
    base: &'a Path,
    buffers: &'a [gltf::buffer::Data],
    cache: HashMap<(usize, Option<usize>), Arc<Texture>>,
}

impl GltfTextures<'_> {
    fn get(&mut self, path: &Path, tex: &gltf::Texture) -> Result<Arc<Texture>> {
        let img = tex.source();
        let key = (img.index(), tex.sampler().index());
        if let Some(t) = self.cache.get(&key) {
            return Ok(t.clone());
        }
        let data = gltf::image::Data::from_source(img.source(), Some(self.base), self.buffers)
            .map_err(|e| Error::parse(path, format!("glTF image {}: {e}", img.index())))?;
        let wrap = [gltf_wrap(tex.sampler().wrap_s()), gltf_wrap(tex.sampler().wrap_t())];
        let t = Arc::new(
            gltf_texture(&data, wrap)
                .map_err(|e| Error::parse(path, format!("glTF image {}: {}", img.index(), strip(e))))?,
        );
        self.cache.insert(key, t.clone());
        Ok(t)
    }
}

/// The material of a glTF primitive: `baseColorFactor` times `baseColorTexture` when the
/// primitive has the texture's `TEXCOORD_n`, else the pattern. `alphaMode: BLEND` makes it
/// translucent with the factor's alpha as opacity ([`Material::opacity`]); `OPAQUE` and `MASK`
/// are opaque (the texture's alpha is not read).
fn gltf_material(path: &Path, prim: &gltf::Primitive, textures: &mut GltfTextures) -> Result<(Material, Option<u32>)> {
    let mat = prim.material();
    let pbr = mat.pbr_metallic_roughness();
    let c = pbr.base_color_factor();
    let base = Vec3::new(c[0], c[1], c[2]);
    let opacity = if mat.alpha_mode() == gltf::material::AlphaMode::Blend { c[3].clamp(0.0, 1.0) } else { 1.0 };
    let (m, uv) = match pbr.base_color_texture() {
        Some(info) => (Material::textured(base, textures.get(path, &info.texture())?), Some(info.tex_coord())),
        None => (Material::pattern(base), None),
    };
    Ok((m.with_opacity(opacity), uv))
}

fn gltf_mesh(
    path: &Path,
    mesh: &gltf::Mesh,
    buffers: &[gltf::buffer::Data],
    textures: &mut GltfTextures,
) -> Result<Mesh> {
    let mut positions: Vec<Vec3> = Vec::new();
    let mut normals: Vec<Vec3> = Vec::new();
    let mut uvs: Vec<Vec2> = Vec::new();
    let (mut any_normals, mut any_uvs) = (false, false);
    let mut indices: Vec<[u32; 3]> = Vec::new();
    let mut parts: Vec<MeshPart> = Vec::new();
    let in_mesh = |m: String| Error::parse(path, format!("glTF mesh {}: {m}", mesh.index()));
    for prim in mesh.primitives() {
        // Check the accessors against their buffers first: the gltf reader silently yields
        // nothing for an accessor that overruns its buffer, which would drop geometry or
        // turn an indexed primitive into a non-indexed one.
        let Some(pos_acc) = prim.get(&gltf::Semantic::Positions) else { continue };
        check_accessor(&pos_acc, buffers).map_err(in_mesh)?;
        if let Some(ia) = prim.indices() {
            check_accessor(&ia, buffers).map_err(in_mesh)?;
        }
        let (material, uv_set) = gltf_material(path, &prim, textures)?;
        for sem in [Some(gltf::Semantic::Normals), uv_set.map(gltf::Semantic::TexCoords)].into_iter().flatten() {
            if let Some(acc) = prim.get(&sem) {
                check_accessor(&acc, buffers).map_err(in_mesh)?;
            }
        }
        let reader = prim.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
        let Some(pos) = reader.read_positions() else {
            return Err(in_mesh("unreadable POSITION accessor".into()));
        };
        let base = positions.len() as u32;
        let start = positions.len();
        positions.extend(pos.map(Vec3::from_array));
        let n = (positions.len() - start) as u32;
        // Attributes: missing ones are zeros (a zero normal shades flat; a textured material
        // without its UVs shows the pattern).
        if let Some(it) = reader.read_normals() {
            normals.extend(it.map(Vec3::from_array));
            any_normals = true;
        }
        let mut has_uv = false;
        if let Some(set) = uv_set {
            if let Some(it) = reader.read_tex_coords(set) {
                uvs.extend(it.into_f32().map(Vec2::from_array));
                has_uv = true;
                any_uvs = true;
            }
        }
        for (what, len) in [("NORMAL", normals.len()), ("TEXCOORD", uvs.len())] {
            if len > positions.len() || (len > start && len != positions.len()) {
                return Err(in_mesh(format!(
                    "{what} accessor has {} elements but POSITION has {n}",
                    len as i64 - start as i64
                )));
            }
        }
        normals.resize(positions.len(), Vec3::ZERO);
        uvs.resize(positions.len(), Vec2::ZERO);
        let idx: Vec<u32> = match (prim.indices(), reader.read_indices()) {
            (_, Some(i)) => i.into_u32().collect(),
            (None, None) => (0..n).collect(),
            (Some(_), None) => return Err(in_mesh("unreadable index accessor".into())),
        };
        if let Some(&bad) = idx.iter().find(|&&i| i >= n) {
            return Err(in_mesh(format!("indexes vertex {bad} but the primitive has only {n} vertices")));
        }
        let tris: Vec<[u32; 3]> = match prim.mode() {
            gltf::mesh::Mode::Triangles => idx.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            gltf::mesh::Mode::TriangleStrip => (2..idx.len())
                .map(|k| if k % 2 == 0 { [idx[k - 2], idx[k - 1], idx[k]] } else { [idx[k - 1], idx[k - 2], idx[k]] })
                .collect(),
            gltf::mesh::Mode::TriangleFan => (2..idx.len()).map(|k| [idx[0], idx[k - 1], idx[k]]).collect(),
            // Points and lines have no depth footprint in a triangle rasterizer.
            _ => Vec::new(),
        };
        if !tris.is_empty() {
            parts.push(MeshPart {
                first_triangle: indices.len() as u32,
                material: fallback_without_uvs(material, has_uv),
            });
        }
        indices.extend(tris.into_iter().map(|t| [t[0] + base, t[1] + base, t[2] + base]));
    }
    let e = |e: Error| in_mesh(strip(e));
    let mut m = Mesh::new(positions, indices).map_err(e)?;
    if any_normals {
        m = m.with_normals(normals).map_err(e)?;
    }
    if any_uvs {
        m = m.with_uvs(uvs).map_err(e)?;
    }
    m.with_parts(parts).map_err(e)
}

/// `Err(message)` unless accessor `a` lies inside its buffer view and the view inside its
/// buffer (sparse accessors without a view are rejected: not used for positions in practice).
fn check_accessor(a: &gltf::Accessor, buffers: &[gltf::buffer::Data]) -> std::result::Result<(), String> {
    let view =
        a.view().ok_or_else(|| format!("accessor {} has no buffer view (sparse-only is unsupported)", a.index()))?;
    let elem = a.size();
    let stride = view.stride().unwrap_or(elem);
    let need = if a.count() == 0 { 0 } else { a.offset() + (a.count() - 1) * stride + elem };
    if need > view.length() {
        return Err(format!(
            "accessor {} needs {need} bytes but its buffer view has {} (truncated?)",
            a.index(),
            view.length()
        ));
    }
    let buf_len = buffers.get(view.buffer().index()).map_or(0, |b| b.0.len());
    if view.offset() + view.length() > buf_len {
        return Err(format!(
            "buffer view {} ends at byte {} but its buffer has {buf_len} bytes (truncated?)",
            view.index(),
            view.offset() + view.length()
        ));
    }
    Ok(())
}

/// Loads any supported single mesh file into its objects.
pub(crate) fn load_file_objects(path: &Path, kind: Kind) -> Result<FileObjects> {
    match kind {
        Kind::Gltf => load_gltf(path),
        Kind::Obj => load_obj(path),
        Kind::Ply => {
            let (m, anchor) = load_ply(path)?;
            let name = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
            Ok(FileObjects {
                anchor,
                meshes: vec![m],
                parts: vec![Part { name, mesh_key: 0, transform: Mat4::IDENTITY, has_material: false, piece: false }],
            })
        }
    }
}

/// Adds file objects to a scene; ground is detected by the part name or the file name.
/// The meshes move from the file's anchor to the scene's origin.
pub(crate) fn add_objects(scene: &mut Scene, file: &Path, mut objs: FileObjects) {
    objs.move_to(scene.origin);
    let file_ground = is_ground_name(&file.to_string_lossy());
    let base = scene.meshes.len() as u32;
    scene.meshes.extend(objs.meshes);
    for p in objs.parts {
        let id = scene.instances.len() as u32;
        let ground = file_ground || is_ground_name(&p.name);
        let albedo = if let (true, Some(prev)) = (p.piece, scene.instances.last()) {
            prev.albedo
        } else if p.has_material {
            Vec3::ONE
        } else if ground {
            GROUND_ALBEDO
        } else {
            albedo_for_id(id)
        };
        scene.add_instance(base + p.mesh_key as u32, p.transform, albedo, Animation::Static, ground);
    }
}

/// A file that is one object (an OBJ without `o`/`g` groups, a glTF with one mesh node) split
/// into objects by `opts.split`, as a soup is ([`soup::split_soup`], connectivity by shared
/// position, so UV seams and normal creases do not cut a surface): per-object culling has
/// nothing to cull in a one-object scene. The pieces keep the object's transform, attributes,
/// materials and tint. Files of several objects keep their author's structure.
fn split_single(objs: FileObjects, opts: &SceneOptions) -> FileObjects {
    let [part] = objs.parts.as_slice() else { return objs };
    let mesh = &objs.meshes[part.mesh_key];
    // Vertices at the same position (bit for bit) are one for connectivity.
    let mut first: HashMap<[u32; 3], u32> = HashMap::with_capacity(mesh.positions.len());
    let weld: Vec<u32> = (0..mesh.positions.len() as u32)
        .map(|v| *first.entry(mesh.positions[v as usize].to_array().map(f32::to_bits)).or_insert(v))
        .collect();
    let welded: Vec<[u32; 3]> = mesh.indices.iter().map(|t| t.map(|v| weld[v as usize])).collect();
    let groups = soup::split_soup(&mesh.positions, &welded, opts.split);
    if groups.len() <= 1 {
        return objs;
    }
    // Groups list their triangles in ascending order: a material's triangles stay one run.
    let meshes: Vec<Mesh> = groups.par_iter().map(|g| mesh.subset(g)).collect();
    let parts = (0..meshes.len())
        .map(|k| Part {
            name: part.name.clone(),
            mesh_key: k,
            transform: part.transform,
            has_material: part.has_material,
            piece: k > 0,
        })
        .collect();
    FileObjects { meshes, parts, anchor: objs.anchor }
}

/// Loads a single mesh file as a scene; a PLY (one soup) is split into objects by
/// `opts.split`, and so is an OBJ or glTF file that holds one object ([`split_single`]).
pub(crate) fn load_single_file(path: &Path, kind: Kind, opts: &SceneOptions) -> Result<Scene> {
    let mut scene = Scene { name: display_name(path), up: up_of(kind), ..Default::default() };
    if kind == Kind::Ply {
        let m = ply::read_ply(path)?;
        scene.origin = m.anchor;
        let ground = is_ground_name(&display_name(path));
        add_soup(&mut scene, path, m.positions, m.normals, m.indices, ground, opts)?;
    } else {
        let objs = split_single(load_file_objects(path, kind)?, opts);
        scene.origin = objs.anchor;
        // Only the file name decides "ground", not the folders above it.
        add_objects(&mut scene, Path::new(&display_name(path)), objs);
    }
    Ok(scene)
}

/// Splits a soup ([`soup::split_soup`]) and adds one object per group, each with its own
/// compacted mesh in world space (with the soup's normals, if any).
pub(crate) fn add_soup(
    scene: &mut Scene,
    path: &Path,
    positions: Vec<Vec3>,
    normals: Option<Vec<Vec3>>,
    indices: Vec<[u32; 3]>,
    ground: bool,
    opts: &SceneOptions,
) -> Result<()> {
    let groups = soup::split_soup(&positions, &indices, opts.split);
    let mut soup = Mesh::new(positions, indices).map_err(at(path))?;
    if let Some(n) = normals {
        soup = soup.with_normals(n).map_err(at(path))?;
    }
    let meshes: Vec<Mesh> = groups.par_iter().map(|g| soup.subset(g)).collect();
    for m in meshes {
        let mesh = scene.add_mesh(m);
        let id = scene.instances.len() as u32;
        let albedo = if ground { GROUND_ALBEDO } else { albedo_for_id(id) };
        scene.add_instance(mesh, Mat4::IDENTITY, albedo, Animation::Static, ground);
    }
    Ok(())
}

/// Loads a folder: the raw soup format if it holds `VertexBuffer.bin` + `IndexBuffer.bin`,
/// otherwise every mesh file found recursively (sorted by path) is one object. The up axis is
/// the one of the most common file kind (Z for PLY, Y for glTF/OBJ).
pub(crate) fn load_folder(dir: &Path, opts: &SceneOptions) -> Result<Scene> {
    let mut scene = Scene { name: display_name(dir), up: Vec3::Z, ..Default::default() };
    if dir.join("VertexBuffer.bin").is_file() && dir.join("IndexBuffer.bin").is_file() {
        let (p, t) = soup::read_raw_soup(dir)?;
        let ground = is_ground_name(&display_name(dir));
        add_soup(&mut scene, &dir.join("IndexBuffer.bin"), p, None, t, ground, opts)?;
        return Ok(scene);
    }
    let mut files = Vec::new();
    collect_mesh_files(dir, &mut files, 0)?;
    files.sort_by(|a, b| a.0.cmp(&b.0));
    let count = |k: Kind| files.iter().filter(|(_, kk)| *kk == k).count();
    let (np, no, ng) = (count(Kind::Ply), count(Kind::Obj), count(Kind::Gltf));
    scene.up = if np >= no.max(ng) { Vec3::Z } else { Vec3::Y };
    // Parse in parallel (Munich: 2367 files), then add in sorted order so ids are stable.
    let loaded: Vec<Result<(PathBuf, FileObjects)>> =
        files.par_iter().map(|(f, k)| load_file_objects(f, *k).map(|o| (f.clone(), merge_parts(o)))).collect();
    let loaded: Vec<(PathBuf, FileObjects)> = loaded.into_iter().collect::<Result<_>>()?;
    // One origin for all files: the far axes of their union's centre, as for one file.
    let (lo, hi) = loaded
        .iter()
        .filter_map(|(_, o)| o.file_bounds())
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), (a, b)| (lo.min(a), hi.max(b)));
    if lo.cmple(hi).all() && loaded.iter().any(|(_, o)| o.anchor != DVec3::ZERO) {
        scene.origin = crate::far_offset(lo, hi);
    }
    for (f, objs) in loaded {
        if objs.parts.is_empty() {
            continue;
        }
        let rel = f.strip_prefix(dir).unwrap_or(&f).to_path_buf();
        add_objects(&mut scene, &rel, objs);
    }
    Ok(scene)
}

/// Merges all parts of a file into one object (a folder's file = one object), baking each
/// part's transform into the merged mesh (normals by its normal matrix) and keeping every part's
/// materials as runs of the merged mesh. Parts without normals or UVs get zeros there (flat
/// shading; textured materials of such parts show the pattern).
fn merge_parts(objs: FileObjects) -> FileObjects {
    if objs.parts.len() <= 1 {
        return objs;
    }
    let any_normals = objs.parts.iter().any(|p| objs.meshes[p.mesh_key].normals.is_some());
    let any_uvs = objs.parts.iter().any(|p| objs.meshes[p.mesh_key].uvs.is_some());
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    let mut uvs = Vec::new();
    let mut indices = Vec::new();
    let mut parts: Vec<MeshPart> = Vec::new();
    for p in &objs.parts {
        let m = &objs.meshes[p.mesh_key];
        let base = positions.len() as u32;
        let first = indices.len() as u32;
        positions.extend(m.positions.iter().map(|v| p.transform.transform_point3(*v)));
        indices.extend(m.indices.iter().map(|t| [t[0] + base, t[1] + base, t[2] + base]));
        if any_normals {
            let nm = Mat3::from_mat4(p.transform).inverse().transpose();
            let nm = if nm.is_finite() { nm } else { Mat3::from_mat4(p.transform) };
            match &m.normals {
                Some(n) => normals.extend(n.iter().map(|v| nm * *v)),
                None => normals.resize(positions.len(), Vec3::ZERO),
            }
        }
        if any_uvs {
            match &m.uvs {
                Some(u) => uvs.extend_from_slice(u),
                None => uvs.resize(positions.len(), Vec2::ZERO),
            }
        }
        if m.indices.is_empty() {
            continue;
        }
        let has_uv = m.uvs.is_some();
        if m.parts.is_empty() {
            parts.push(MeshPart { first_triangle: first, material: Material::default() });
        }
        for mp in &m.parts {
            parts.push(MeshPart {
                first_triangle: first + mp.first_triangle,
                material: fallback_without_uvs(mp.material.clone(), has_uv),
            });
        }
    }
    let has_material = objs.parts.iter().any(|p| p.has_material);
    // A merged file is ground if its path says so (checked by the caller) or if every part
    // is named as ground; one ground part among walls does not make the whole file ground.
    let name = if objs.parts.iter().all(|p| is_ground_name(&p.name)) { "ground".to_string() } else { String::new() };
    let mut mesh = Mesh {
        positions,
        indices,
        bounds: Default::default(),
        normals: any_normals.then_some(normals),
        uvs: any_uvs.then_some(uvs),
        parts: if has_material { parts } else { Vec::new() },
    };
    mesh.compute_bounds();
    FileObjects {
        meshes: vec![mesh],
        parts: vec![Part { name, mesh_key: 0, transform: Mat4::IDENTITY, has_material, piece: false }],
        anchor: objs.anchor,
    }
}

fn collect_mesh_files(dir: &Path, out: &mut Vec<(PathBuf, Kind)>, depth: usize) -> Result<()> {
    if depth > 32 {
        return Err(Error::parse(dir, "folder nesting deeper than 32 (symlink loop?)"));
    }
    let rd = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    for entry in rd {
        let entry = entry.map_err(|e| Error::io(dir, e))?;
        let p = entry.path();
        if p.is_dir() {
            collect_mesh_files(&p, out, depth + 1)?;
        } else if let Some(k) = kind_of(&p) {
            out.push((p, k));
        }
    }
    Ok(())
}

pub(crate) fn display_name(path: &Path) -> String {
    path.file_name().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| path.display().to_string())
}
