//! File loaders: glTF 2.0 (`.gltf`/`.glb`), Wavefront OBJ, PLY, the raw soup folder format and
//! folders of mesh files. They produce the objects the renderer, warper and culler work on
//! (seed 000 Sec. 4-5: per-object item buffers and occlusion queries).
//!
//! Every error is one line naming the offending file (`Error::Parse { path, msg }` or
//! `Error::Io`).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{Mat4, Vec3};
use rayon::prelude::*;
use zwarp_core::{Animation, Error, Mesh, Result, Scene};

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
    pub albedo: Option<Vec3>,
}

/// Meshes + parts of one file.
pub(crate) struct FileObjects {
    pub meshes: Vec<Mesh>,
    pub parts: Vec<Part>,
}

/// Turns an `Error::Invalid` from mesh validation into a parse error naming `path`.
fn at(path: &Path) -> impl Fn(Error) -> Error + '_ {
    move |e| match e {
        Error::Invalid(msg) => Error::parse(path, msg),
        other => other,
    }
}

/// Loads a PLY file as one mesh (no object structure in PLY).
pub(crate) fn load_ply(path: &Path) -> Result<Mesh> {
    let m = ply::read_ply(path)?;
    Mesh::new(m.positions, m.indices).map_err(at(path))
}

/// Loads an OBJ file: each model (`o`/`g`) is one object, polygons triangulated; the albedo
/// is the material's diffuse colour when the `.mtl` is present.
pub(crate) fn load_obj(path: &Path) -> Result<FileObjects> {
    if !path.is_file() {
        return Err(Error::parse(path, "file not found"));
    }
    let opts = tobj::LoadOptions { triangulate: true, single_index: false, ignore_points: true, ignore_lines: true };
    let (models, materials) = tobj::load_obj(path, &opts).map_err(|e| Error::parse(path, format!("OBJ: {e}")))?;
    // A missing or broken .mtl only costs the colours.
    let materials = materials.unwrap_or_default();
    let mut out = FileObjects { meshes: Vec::new(), parts: Vec::new() };
    for model in models {
        let m = &model.mesh;
        if m.positions.len() % 3 != 0 || m.indices.len() % 3 != 0 {
            return Err(Error::parse(path, format!("OBJ model '{}' has malformed arrays", model.name)));
        }
        let positions: Vec<Vec3> = m.positions.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect();
        let indices: Vec<[u32; 3]> = m.indices.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
        if indices.is_empty() {
            continue;
        }
        let mesh = Mesh::new(positions, indices)
            .map_err(|e| Error::parse(path, format!("OBJ model '{}': {}", model.name, strip(e))))?;
        let albedo = m
            .material_id
            .and_then(|i| materials.get(i))
            .and_then(|mat| mat.diffuse)
            .map(Vec3::from_array)
            .filter(|c| c.is_finite());
        out.parts.push(Part {
            name: model.name.clone(),
            mesh_key: out.meshes.len(),
            transform: Mat4::IDENTITY,
            albedo,
        });
        out.meshes.push(mesh);
    }
    Ok(out)
}

fn strip(e: Error) -> String {
    match e {
        Error::Invalid(m) => m,
        other => other.to_string(),
    }
}

/// Loads a glTF 2.0 file (`.gltf` with external or embedded base64 buffers, or `.glb`): every
/// node with a mesh is one object with its world transform; all triangle primitives of a mesh
/// form one [`Mesh`], shared by the nodes that use it. Images are not decoded.
pub(crate) fn load_gltf(path: &Path) -> Result<FileObjects> {
    if !path.is_file() {
        return Err(Error::parse(path, "file not found"));
    }
    let g = gltf::Gltf::open(path).map_err(|e| Error::parse(path, format!("glTF: {e}")))?;
    let base = path.parent().unwrap_or(Path::new("."));
    let doc = g.document;
    let buffers =
        gltf::import_buffers(&doc, Some(base), g.blob).map_err(|e| Error::parse(path, format!("glTF buffers: {e}")))?;

    let mut mesh_slot: HashMap<usize, usize> = HashMap::new();
    let mut out = FileObjects { meshes: Vec::new(), parts: Vec::new() };
    let roots: Vec<gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(s) => s.nodes().collect(),
        None => {
            // No scene: every node that is nobody's child is a root.
            let children: std::collections::HashSet<usize> =
                doc.nodes().flat_map(|n| n.children().map(|c| c.index()).collect::<Vec<_>>()).collect();
            doc.nodes().filter(|n| !children.contains(&n.index())).collect()
        }
    };
    // Iterative DFS with a depth guard: glTF forbids cycles but a malformed file could hold one.
    let mut stack: Vec<(gltf::Node, Mat4, usize)> = roots.into_iter().map(|n| (n, Mat4::IDENTITY, 0)).collect();
    while let Some((node, parent, depth)) = stack.pop() {
        if depth > 256 {
            return Err(Error::parse(path, "glTF node hierarchy deeper than 256 (cycle?)"));
        }
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        if !world.is_finite() {
            return Err(Error::parse(path, format!("glTF node {} has a non-finite transform", node.index())));
        }
        if let Some(mesh) = node.mesh() {
            let slot = match mesh_slot.get(&mesh.index()) {
                Some(&s) => Some(s),
                None => {
                    let m = gltf_mesh(path, &mesh, &buffers)?;
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
                let albedo = mesh.primitives().next().map(|p| {
                    let c = p.material().pbr_metallic_roughness().base_color_factor();
                    Vec3::new(c[0], c[1], c[2])
                });
                let name = node.name().or(mesh.name()).unwrap_or("").to_string();
                out.parts.push(Part { name, mesh_key: slot, transform: world, albedo });
            }
        }
        for c in node.children() {
            stack.push((c, world, depth + 1));
        }
    }
    Ok(out)
}

fn gltf_mesh(path: &Path, mesh: &gltf::Mesh, buffers: &[gltf::buffer::Data]) -> Result<Mesh> {
    let mut positions: Vec<Vec3> = Vec::new();
    let mut indices: Vec<[u32; 3]> = Vec::new();
    for prim in mesh.primitives() {
        // Check the accessors against their buffers first: the gltf reader silently yields
        // nothing for an accessor that overruns its buffer, which would drop geometry or
        // turn an indexed primitive into a non-indexed one.
        let Some(pos_acc) = prim.get(&gltf::Semantic::Positions) else { continue };
        check_accessor(&pos_acc, buffers)
            .map_err(|m| Error::parse(path, format!("glTF mesh {}: {m}", mesh.index())))?;
        if let Some(ia) = prim.indices() {
            check_accessor(&ia, buffers).map_err(|m| Error::parse(path, format!("glTF mesh {}: {m}", mesh.index())))?;
        }
        let reader = prim.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
        let Some(pos) = reader.read_positions() else {
            return Err(Error::parse(path, format!("glTF mesh {}: unreadable POSITION accessor", mesh.index())));
        };
        let base = positions.len() as u32;
        let start = positions.len();
        positions.extend(pos.map(Vec3::from_array));
        let n = (positions.len() - start) as u32;
        let idx: Vec<u32> = match (prim.indices(), reader.read_indices()) {
            (_, Some(i)) => i.into_u32().collect(),
            (None, None) => (0..n).collect(),
            (Some(_), None) => {
                return Err(Error::parse(path, format!("glTF mesh {}: unreadable index accessor", mesh.index())))
            }
        };
        if let Some(&bad) = idx.iter().find(|&&i| i >= n) {
            return Err(Error::parse(
                path,
                format!("glTF mesh {} indexes vertex {bad} but the primitive has only {n} vertices", mesh.index()),
            ));
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
        indices.extend(tris.into_iter().map(|t| [t[0] + base, t[1] + base, t[2] + base]));
    }
    Mesh::new(positions, indices).map_err(|e| Error::parse(path, format!("glTF mesh {}: {}", mesh.index(), strip(e))))
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
            let m = load_ply(path)?;
            let name = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
            Ok(FileObjects {
                meshes: vec![m],
                parts: vec![Part { name, mesh_key: 0, transform: Mat4::IDENTITY, albedo: None }],
            })
        }
    }
}

/// Adds file objects to a scene; ground is detected by the part name or the file name.
pub(crate) fn add_objects(scene: &mut Scene, file: &Path, objs: FileObjects) {
    let file_ground = is_ground_name(&file.to_string_lossy());
    let base = scene.meshes.len() as u32;
    scene.meshes.extend(objs.meshes);
    for p in objs.parts {
        let id = scene.instances.len() as u32;
        let ground = file_ground || is_ground_name(&p.name);
        let albedo = if ground { GROUND_ALBEDO } else { p.albedo.unwrap_or_else(|| albedo_for_id(id)) };
        scene.add_instance(base + p.mesh_key as u32, p.transform, albedo, Animation::Static, ground);
    }
}

/// Loads a single mesh file as a scene; a PLY (one soup) is split into objects by
/// `opts.split`.
pub(crate) fn load_single_file(path: &Path, kind: Kind, opts: &SceneOptions) -> Result<Scene> {
    let mut scene = Scene { name: display_name(path), up: up_of(kind), ..Default::default() };
    if kind == Kind::Ply {
        let m = ply::read_ply(path)?;
        let ground = is_ground_name(&display_name(path));
        add_soup(&mut scene, path, m.positions, m.indices, ground, opts)?;
    } else {
        let objs = load_file_objects(path, kind)?;
        // Only the file name decides "ground", not the folders above it.
        add_objects(&mut scene, Path::new(&display_name(path)), objs);
    }
    Ok(scene)
}

/// Splits a soup ([`soup::split_soup`]) and adds one object per group, each with its own
/// compacted mesh in world space.
pub(crate) fn add_soup(
    scene: &mut Scene,
    path: &Path,
    positions: Vec<Vec3>,
    indices: Vec<[u32; 3]>,
    ground: bool,
    opts: &SceneOptions,
) -> Result<()> {
    let groups = soup::split_soup(&positions, &indices, opts.split);
    let meshes: Vec<Result<Mesh>> = groups
        .par_iter()
        .map(|g| {
            let mut remap: HashMap<u32, u32> = HashMap::with_capacity(g.len() * 2);
            let mut pos = Vec::new();
            let tris = g
                .iter()
                .map(|&t| {
                    indices[t as usize].map(|v| {
                        *remap.entry(v).or_insert_with(|| {
                            pos.push(positions[v as usize]);
                            (pos.len() - 1) as u32
                        })
                    })
                })
                .collect();
            Mesh::new(pos, tris).map_err(at(path))
        })
        .collect();
    for m in meshes {
        let mesh = scene.add_mesh(m?);
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
        add_soup(&mut scene, &dir.join("IndexBuffer.bin"), p, t, ground, opts)?;
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
    for r in loaded {
        let (f, objs) = r?;
        if objs.parts.is_empty() {
            continue;
        }
        let rel = f.strip_prefix(dir).unwrap_or(&f).to_path_buf();
        add_objects(&mut scene, &rel, objs);
    }
    Ok(scene)
}

/// Merges all parts of a file into one object (a folder's file = one object), baking each
/// part's transform into the merged mesh.
fn merge_parts(objs: FileObjects) -> FileObjects {
    if objs.parts.len() <= 1 {
        return objs;
    }
    let mut positions = Vec::new();
    let mut indices = Vec::new();
    for p in &objs.parts {
        let m = &objs.meshes[p.mesh_key];
        let base = positions.len() as u32;
        positions.extend(m.positions.iter().map(|v| p.transform.transform_point3(*v)));
        indices.extend(m.indices.iter().map(|t| [t[0] + base, t[1] + base, t[2] + base]));
    }
    let albedo = objs.parts[0].albedo;
    // A merged file is ground if its path says so (checked by the caller) or if every part
    // is named as ground; one ground part among walls does not make the whole file ground.
    let name = if objs.parts.iter().all(|p| is_ground_name(&p.name)) { "ground".to_string() } else { String::new() };
    let mut mesh = Mesh { positions, indices, bounds: Default::default() };
    mesh.compute_bounds();
    FileObjects { meshes: vec![mesh], parts: vec![Part { name, mesh_key: 0, transform: Mat4::IDENTITY, albedo }] }
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
