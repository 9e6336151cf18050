//! Loader tests on the tiny committed fixtures (tests/fixtures) and on broken files written
//! into a temp dir. None of them reads /work/shared.

use std::path::PathBuf;

use glam::Vec3;
use zwarp_core::Error;
use zwarp_scene::{load_scene, CameraPath, SceneOptions, SplitMode};

fn fixture(name: &str) -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures").join(name).to_string_lossy().into_owned()
}

fn opts(split: SplitMode) -> SceneOptions {
    SceneOptions { split, ..Default::default() }
}

/// A fresh temp dir per test, removed when the guard drops (also when the test fails).
fn temp_dir(name: &str) -> (tempfile::TempDir, PathBuf) {
    let guard = tempfile::Builder::new().prefix(&format!("zwarp-scene-{name}-")).tempdir().unwrap();
    let d = guard.path().to_path_buf();
    (guard, d)
}

fn err_of(spec: &str) -> String {
    let e = load_scene(spec, &SceneOptions::default()).unwrap_err();
    let msg = e.to_string();
    assert!(!msg.contains('\n'), "error must be one line: {msg:?}");
    msg
}

fn parse_err_file(spec: &str) -> (PathBuf, String) {
    match load_scene(spec, &SceneOptions::default()).unwrap_err() {
        Error::Parse { path, msg } => (path, msg),
        other => panic!("expected a parse error, got {other}"),
    }
}

#[test]
fn obj_models_are_objects_with_material_colours_and_ground() {
    let s = load_scene(&fixture("two_tris.obj"), &SceneOptions::default()).unwrap();
    assert!(s.path.is_none());
    let sc = &s.scene;
    assert_eq!(sc.up, Vec3::Y);
    assert_eq!(sc.instances.len(), 2);
    assert_eq!(sc.triangle_count(), 4);
    let wall = &sc.instances[0];
    assert!(!wall.is_ground);
    // The colour lives in the material (pattern times Kd); the instance tint is white.
    assert_eq!(wall.albedo, Vec3::ONE);
    let wm = &sc.meshes[wall.mesh as usize];
    assert_eq!(wm.material_of(0), &zwarp_core::Material::pattern(Vec3::new(0.8, 0.1, 0.1)));
    assert_eq!(wall.world_aabb.min, Vec3::ZERO);
    assert_eq!(wall.world_aabb.max, Vec3::new(1.0, 1.0, 0.0));
    let ground = &sc.instances[1];
    assert!(ground.is_ground);
    // OBJ's `usemtl` state carries over `o`: the ground uses "red" too, so its tint is white.
    assert_eq!(ground.albedo, Vec3::ONE);
    assert_eq!(sc.meshes[ground.mesh as usize].material_of(0).base_color, Vec3::new(0.8, 0.1, 0.1));
    assert_eq!(sc.meshes[ground.mesh as usize].triangle_count(), 2, "quad face triangulated");
}

#[test]
fn ascii_ply_is_split_by_mode() {
    let f = fixture("quad_ascii.ply");
    let comp = load_scene(&f, &opts(SplitMode::Components)).unwrap().scene;
    assert_eq!(comp.up, Vec3::Z);
    assert_eq!(comp.instances.len(), 2);
    let tris: Vec<usize> = comp.instances.iter().map(|i| comp.meshes[i.mesh as usize].triangle_count()).collect();
    assert_eq!(tris, vec![2, 1]);
    assert_eq!(comp.instances[1].world_aabb.min, Vec3::new(3.0, 0.0, 0.0));
    assert_eq!(comp.instances[1].world_aabb.max, Vec3::new(4.0, 1.0, 1.0));
    let none = load_scene(&f, &opts(SplitMode::None)).unwrap().scene;
    assert_eq!((none.instances.len(), none.triangle_count()), (1, 3));
    let cl = load_scene(&f, &opts(SplitMode::Clusters(3))).unwrap().scene;
    assert_eq!((cl.instances.len(), cl.triangle_count()), (3, 3));
    // Object ids get distinct deterministic colours.
    assert_ne!(comp.instances[0].albedo, comp.instances[1].albedo);
}

#[test]
fn binary_ply_reads_doubles_and_skips_normals() {
    let s = load_scene(&fixture("tri_binary.ply"), &SceneOptions::default()).unwrap().scene;
    assert_eq!((s.instances.len(), s.triangle_count()), (1, 1));
    assert_eq!(s.bounds().min, Vec3::ZERO);
    assert_eq!(s.bounds().max, Vec3::new(2.0, 0.0, 3.0));
}

#[test]
fn gltf_and_glb_nodes_are_instances_with_world_transforms() {
    for f in ["tiny.gltf", "tiny.glb"] {
        let s = load_scene(&fixture(f), &SceneOptions::default()).unwrap().scene;
        assert_eq!(s.up, Vec3::Y, "{f}");
        assert_eq!(s.meshes.len(), 1, "{f}: both nodes share one mesh");
        assert_eq!(s.instances.len(), 2, "{f}");
        let mut boxes: Vec<_> = s.instances.iter().map(|i| (i.world_aabb.min, i.world_aabb.max)).collect();
        boxes.sort_by(|a, b| a.0.x.total_cmp(&b.0.x));
        assert_eq!(boxes[0], (Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0)));
        // The child: parent (identity) * translate(10, 0, 0) * scale 2.
        assert_eq!(boxes[1], (Vec3::new(10.0, 0.0, 0.0), Vec3::new(12.0, 2.0, 0.0)));
        for i in &s.instances {
            assert_eq!(i.albedo, Vec3::ONE);
            let m = s.meshes[i.mesh as usize].material_of(0);
            assert!((m.base_color - Vec3::new(0.2, 0.4, 0.6)).length() < 1e-6, "{f}");
            assert_eq!(m.map, zwarp_core::ColorMap::Pattern);
        }
    }
}

#[test]
fn raw_soup_folder_splits_into_components() {
    let s = load_scene(&fixture("soup"), &SceneOptions::default()).unwrap().scene;
    assert_eq!(s.up, Vec3::Z);
    assert_eq!(s.instances.len(), 2);
    assert_eq!(s.triangle_count(), 4);
    assert_eq!(s.instances[1].world_aabb.min, Vec3::new(3.0, 0.0, 0.5));
    assert_eq!(s.instances[1].world_aabb.max, Vec3::new(4.0, 1.0, 0.5));
    let one = load_scene(&fixture("soup"), &opts(SplitMode::None)).unwrap().scene;
    assert_eq!(one.instances.len(), 1);
    // A loaded file has no recorded path; the default one is valid and frames it.
    let l = load_scene(&fixture("soup"), &SceneOptions::default()).unwrap();
    let p = l.path_or_default();
    p.validate().unwrap();
    assert_eq!(p.frame_count(), 301);
}

#[test]
fn mesh_folder_is_one_object_per_file_recursively() {
    let s = load_scene(&fixture("city"), &SceneOptions::default()).unwrap().scene;
    // house.ply, sub/ground.ply, sub/wall.obj (readme.txt ignored), sorted by path.
    assert_eq!(s.instances.len(), 3);
    let tris: Vec<usize> = s.instances.iter().map(|i| s.meshes[i.mesh as usize].triangle_count()).collect();
    assert_eq!(tris, vec![3, 1, 4], "files are not split; OBJ models merged");
    let ground: Vec<bool> = s.instances.iter().map(|i| i.is_ground).collect();
    assert_eq!(ground, vec![false, true, false]);
    assert_eq!(s.up, Vec3::Z, "two PLY files outvote one OBJ");
}

#[test]
fn missing_file_and_unknown_extension() {
    let (path, msg) = parse_err_file("/nonexistent/zwarp/scene.obj");
    assert!(path.ends_with("scene.obj") && msg.contains("no such file"), "{msg}");
    let (_dir, d) = temp_dir("ext");
    let f = d.join("model.stl");
    std::fs::write(&f, "solid x\nendsolid x\n").unwrap();
    let msg = err_of(f.to_str().unwrap());
    assert!(msg.contains("model.stl") && msg.contains("unsupported extension 'stl'"), "{msg}");
}

#[test]
fn malformed_ply_files_are_reported() {
    let (_dir, d) = temp_dir("ply");
    let good = std::fs::read(fixture("tri_binary.ply")).unwrap();
    let f = d.join("truncated.ply");
    std::fs::write(&f, &good[..good.len() - 5]).unwrap();
    let msg = err_of(f.to_str().unwrap());
    assert!(msg.contains("truncated.ply") && msg.contains("truncated binary data"), "{msg}");

    let text = std::fs::read_to_string(fixture("quad_ascii.ply")).unwrap();
    let f = d.join("nan.ply");
    std::fs::write(&f, text.replace("3 1 1 1", "3 nan 1 1")).unwrap();
    let msg = err_of(f.to_str().unwrap());
    assert!(msg.contains("nan.ply") && msg.contains("vertex 6 is not finite"), "{msg}");

    let f = d.join("oor.ply");
    std::fs::write(&f, text.replace("3 4 5 6", "3 4 5 70")).unwrap();
    let msg = err_of(f.to_str().unwrap());
    assert!(msg.contains("oor.ply") && msg.contains("indexes vertex 70"), "{msg}");

    let f = d.join("points.ply");
    std::fs::write(&f, "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n")
        .unwrap();
    let msg = err_of(f.to_str().unwrap());
    assert!(msg.contains("points.ply") && msg.contains("empty"), "{msg}");
}

#[test]
fn malformed_obj_files_are_reported() {
    let (_dir, d) = temp_dir("obj");
    let f = d.join("nan.obj");
    std::fs::write(&f, "v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n").unwrap();
    let msg = err_of(f.to_str().unwrap());
    assert!(msg.contains("nan.obj") && msg.contains("not finite"), "{msg}");
    let f = d.join("inf.obj");
    std::fs::write(&f, "v 0 0 0\nv 1 0 0\nv inf 1 0\nf 1 2 3\n").unwrap();
    let msg = err_of(f.to_str().unwrap());
    assert!(msg.contains("inf.obj") && msg.contains("not finite"), "{msg}");
    let f = d.join("oor.obj");
    std::fs::write(&f, "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 9\n").unwrap();
    let msg = err_of(f.to_str().unwrap());
    assert!(msg.contains("oor.obj"), "{msg}");
    let f = d.join("garbage.obj");
    std::fs::write(&f, "v 0 0 zero\nf 1 2 3\n").unwrap();
    let msg = err_of(f.to_str().unwrap());
    assert!(msg.contains("garbage.obj"), "{msg}");
    let f = d.join("empty.obj");
    std::fs::write(&f, "# nothing\nv 0 0 0\n").unwrap();
    let msg = err_of(f.to_str().unwrap());
    assert!(msg.contains("empty.obj") && msg.contains("empty"), "{msg}");
}

#[test]
fn malformed_gltf_files_are_reported() {
    let (_dir, d) = temp_dir("gltf");
    let f = d.join("broken.gltf");
    std::fs::write(&f, "{\"asset\": {\"version\": \"2.0\"}, \"nodes\": [").unwrap();
    let msg = err_of(f.to_str().unwrap());
    assert!(msg.contains("broken.gltf") && msg.contains("glTF"), "{msg}");
    let glb = std::fs::read(fixture("tiny.glb")).unwrap();
    let f = d.join("truncated.glb");
    std::fs::write(&f, &glb[..glb.len() - 20]).unwrap();
    let msg = err_of(f.to_str().unwrap());
    assert!(msg.contains("truncated.glb"), "{msg}");
    // Index 7 into a 3-vertex primitive.
    let text = std::fs::read_to_string(fixture("tiny.gltf")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let uri = v["buffers"][0]["uri"].as_str().unwrap();
    let b64 = uri.split(',').nth(1).unwrap();
    // Rebuild the buffer with a bad index (indices start at byte 36, u16).
    let mut bytes = decode_b64(b64);
    bytes[36] = 7;
    let mut v2 = v.clone();
    v2["buffers"][0]["uri"] = format!("data:application/octet-stream;base64,{}", encode_b64(&bytes)).into();
    let f = d.join("oor.gltf");
    std::fs::write(&f, serde_json::to_string(&v2).unwrap()).unwrap();
    let msg = err_of(f.to_str().unwrap());
    assert!(msg.contains("oor.gltf") && msg.contains("indexes vertex 7"), "{msg}");
    // Accessors overrunning their buffer views / buffers are caught, not silently dropped.
    for (k, (field, idx, key, val)) in
        [("accessors", 0, "count", 300), ("bufferViews", 0, "byteLength", 3600), ("accessors", 1, "byteOffset", 1000)]
            .into_iter()
            .enumerate()
    {
        let mut bad = v.clone();
        bad[field][idx][key] = val.into();
        let f = d.join(format!("overrun{k}.gltf"));
        std::fs::write(&f, serde_json::to_string(&bad).unwrap()).unwrap();
        let msg = err_of(f.to_str().unwrap());
        assert!(msg.contains(&format!("overrun{k}.gltf")) && msg.contains("truncated?"), "{msg}");
    }
    // A NaN position.
    let mut bytes = decode_b64(b64);
    bytes[12..16].copy_from_slice(&f32::NAN.to_le_bytes());
    let mut v3 = v.clone();
    v3["buffers"][0]["uri"] = format!("data:application/octet-stream;base64,{}", encode_b64(&bytes)).into();
    let f = d.join("nan.gltf");
    std::fs::write(&f, serde_json::to_string(&v3).unwrap()).unwrap();
    let msg = err_of(f.to_str().unwrap());
    assert!(msg.contains("nan.gltf") && msg.contains("not finite"), "{msg}");
}

#[test]
fn malformed_soups_and_empty_folders_are_reported() {
    let (_dir, d) = temp_dir("soup");
    let v = std::fs::read(fixture("soup/VertexBuffer.bin")).unwrap();
    let i = std::fs::read(fixture("soup/IndexBuffer.bin")).unwrap();
    std::fs::write(d.join("VertexBuffer.bin"), &v[..v.len() - 4]).unwrap();
    std::fs::write(d.join("IndexBuffer.bin"), &i).unwrap();
    let msg = err_of(d.to_str().unwrap());
    assert!(msg.contains("VertexBuffer.bin") && msg.contains("multiple of 16"), "{msg}");
    std::fs::write(d.join("VertexBuffer.bin"), &v).unwrap();
    let mut bad = i.clone();
    bad[0..4].copy_from_slice(&100u32.to_le_bytes());
    std::fs::write(d.join("IndexBuffer.bin"), &bad).unwrap();
    let msg = err_of(d.to_str().unwrap());
    assert!(msg.contains("IndexBuffer.bin") && msg.contains("indexes vertex"), "{msg}");
    let mut nan = v.clone();
    nan[4..8].copy_from_slice(&f32::INFINITY.to_le_bytes());
    std::fs::write(d.join("VertexBuffer.bin"), &nan).unwrap();
    std::fs::write(d.join("IndexBuffer.bin"), &i).unwrap();
    let msg = err_of(d.to_str().unwrap());
    assert!(msg.contains("vertex 0 is not finite"), "{msg}");

    let (_dir, e) = temp_dir("empty");
    std::fs::write(e.join("notes.txt"), "nothing here").unwrap();
    let msg = err_of(e.to_str().unwrap());
    assert!(msg.contains("empty") && msg.contains("zwarp-scene"), "{msg}");
    // A broken file inside a folder names that file.
    std::fs::write(e.join("bad.ply"), "ply\nformat ascii 1.0\n").unwrap();
    let msg = err_of(e.to_str().unwrap());
    assert!(msg.contains("bad.ply") && msg.contains("end_header"), "{msg}");
}

#[test]
fn bad_options_are_rejected() {
    let o = SceneOptions { scale: 0.0, ..Default::default() };
    assert!(load_scene("cb", &o).unwrap_err().to_string().contains("scale"));
    let o = SceneOptions { split: SplitMode::Clusters(0), ..Default::default() };
    assert!(load_scene(&fixture("soup"), &o).is_err());
}

#[test]
fn procedural_specs_come_with_paths() {
    let o = SceneOptions { scale: 0.005, ..Default::default() };
    for spec in ["mo", "BL", "cb"] {
        let s = load_scene(spec, &o).unwrap();
        let p: CameraPath = s.path.clone().unwrap();
        let frames = p.frames(32, 24, 8.0).unwrap();
        assert_eq!(frames.len(), p.frame_count_at(8.0));
        assert!(s.scene.instances.len() > 10, "{spec}");
    }
}

const B64: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

fn encode_b64(b: &[u8]) -> String {
    let mut s = String::new();
    for c in b.chunks(3) {
        let n = (c[0] as u32) << 16 | (*c.get(1).unwrap_or(&0) as u32) << 8 | *c.get(2).unwrap_or(&0) as u32;
        for k in 0..4 {
            if k <= c.len() {
                s.push(B64[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

fn decode_b64(s: &str) -> Vec<u8> {
    let mut out = Vec::new();
    let vals: Vec<u32> =
        s.bytes().filter(|&c| c != b'=').map(|c| B64.iter().position(|&x| x == c).unwrap() as u32).collect();
    for c in vals.chunks(4) {
        let n = c.iter().enumerate().fold(0u32, |n, (k, &v)| n | v << (18 - 6 * k));
        for k in 0..c.len() - 1 {
            out.push((n >> (16 - 8 * k)) as u8);
        }
    }
    out
}

#[test]
fn committed_paths_for_the_real_scenes_are_valid() {
    for f in ["sponza_court.json", "munich_street.json"] {
        let p = CameraPath::from_json_file(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("paths").join(f)).unwrap();
        assert_eq!(p.duration(), 10.0, "{f}");
        assert_eq!(p.frame_count(), 301, "{f}");
        assert_eq!(p.up, Vec3::Z, "{f}");
    }
}

#[test]
fn default_path_of_a_y_up_file_flies_above_it() {
    let l = load_scene(&fixture("two_tris.obj"), &SceneOptions::default()).unwrap();
    let p = l.path_or_default();
    assert_eq!(p.up, Vec3::Y);
    let b = l.scene.bounds();
    for (_, cam) in p.frames(64, 48, 2.0).unwrap() {
        let e = cam.eye();
        assert!(e.y > b.max.y + 1.0, "eye {e} must be above the Y-up scene");
        let c = cam.project(b.center()).unwrap();
        assert!(c.x > 0.0 && c.x < 64.0 && c.y > 0.0 && c.y < 48.0 && c.z < 1.0);
    }
}

/// 4x4 RGBA test texture: texel (i, j) has sRGB bytes (60 i, 60 j, 200, 255).
fn test_png() -> Vec<u8> {
    let mut px = Vec::new();
    for j in 0..4u8 {
        for i in 0..4u8 {
            px.extend_from_slice(&[60 * i, 60 * j, 200, 255]);
        }
    }
    let img = image::RgbaImage::from_raw(4, 4, px).unwrap();
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}

/// The linear value the loaders must give an sRGB byte.
fn lin(b: u8) -> f32 {
    zwarp_core::srgb_to_linear(b as f32 / 255.0)
}

/// A glTF quad (x, y in [0, 1], z = 0, normal +z) with UVs (glTF: v = 0 at the top, i.e. at
/// y = 1), a base-colour factor and the base-colour texture `image` (a JSON image object).
fn textured_quad_gltf(image: serde_json::Value, uv_count: usize) -> String {
    let mut b: Vec<u8> = Vec::new();
    for p in [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]] {
        p.iter().for_each(|v| b.extend_from_slice(&v.to_le_bytes()));
    }
    for _ in 0..4 {
        [0.0f32, 0.0, 1.0].iter().for_each(|v| b.extend_from_slice(&v.to_le_bytes()));
    }
    for uv in [[0.0f32, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]] {
        uv.iter().for_each(|v| b.extend_from_slice(&v.to_le_bytes()));
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        b.extend_from_slice(&i.to_le_bytes());
    }
    b.extend_from_slice(&[0, 0]);
    let json = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": "panel"}],
        "meshes": [{"primitives": [{
            "attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2},
            "indices": 3,
            "material": 0
        }]}],
        "materials": [{"pbrMetallicRoughness": {
            "baseColorFactor": [1.0, 0.5, 1.0, 1.0],
            "baseColorTexture": {"index": 0}
        }}],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"wrapS": 33071, "wrapT": 10497}],
        "images": [image],
        "buffers": [{"byteLength": b.len(), "uri": format!("data:application/octet-stream;base64,{}", encode_b64(&b))}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 48},
            {"buffer": 0, "byteOffset": 96, "byteLength": 32},
            {"buffer": 0, "byteOffset": 128, "byteLength": 12}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0]},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5126, "count": uv_count, "type": "VEC2"},
            {"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"}
        ]
    });
    serde_json::to_string(&json).unwrap()
}

#[test]
fn gltf_normals_uvs_and_embedded_png_texture() {
    let (_dir, d) = temp_dir("gltf-tex");
    let uri = format!("data:image/png;base64,{}", encode_b64(&test_png()));
    let f = d.join("panel.gltf");
    std::fs::write(&f, textured_quad_gltf(serde_json::json!({ "uri": uri }), 4)).unwrap();
    let s = load_scene(f.to_str().unwrap(), &SceneOptions::default()).unwrap().scene;
    assert_eq!(s.instances.len(), 1);
    assert_eq!(s.instances[0].albedo, Vec3::ONE, "the file's material carries the colour");
    let m = &s.meshes[0];
    assert_eq!(m.normals.as_deref(), Some(&[Vec3::Z; 4][..]));
    let uvs = m.uvs.as_ref().unwrap();
    assert_eq!(uvs[3], glam::Vec2::new(0.0, 0.0), "top-left corner (y = 1) has uv (0, 0)");
    let mat = m.material_of(1);
    assert_eq!(mat.base_color, Vec3::new(1.0, 0.5, 1.0));
    let tex = mat.texture().expect("textured");
    assert_eq!(tex.image().size(), (4, 4));
    assert_eq!(tex.wrap(), [zwarp_core::Wrap::Clamp, zwarp_core::Wrap::Repeat]);
    // Texel (2, 1) = bytes (120, 60, 200), decoded from sRGB.
    let t = *tex.image().get(2, 1);
    for (got, want) in t.iter().zip([lin(120), lin(60), lin(200), 1.0]) {
        assert!((got - want).abs() < 1e-6, "{t:?}");
    }
    // A missing external image is a one-line error naming the file.
    let f = d.join("missing.gltf");
    std::fs::write(&f, textured_quad_gltf(serde_json::json!({ "uri": "nowhere.png" }), 4)).unwrap();
    let msg = err_of(f.to_str().unwrap());
    assert!(msg.contains("missing.gltf") && msg.contains("glTF image 0"), "{msg}");
    // TEXCOORD_0 with fewer elements than POSITION.
    let f = d.join("short_uv.gltf");
    std::fs::write(&f, textured_quad_gltf(serde_json::json!({ "uri": uri }), 3)).unwrap();
    let msg = err_of(f.to_str().unwrap());
    assert!(msg.contains("short_uv.gltf") && msg.contains("TEXCOORD"), "{msg}");
}

#[test]
fn gltf_blend_materials_are_translucent() {
    let (_dir, d) = temp_dir("gltf-blend");
    let uri = format!("data:image/png;base64,{}", encode_b64(&test_png()));
    let mut json: serde_json::Value =
        serde_json::from_str(&textured_quad_gltf(serde_json::json!({ "uri": uri }), 4)).unwrap();
    let load = |json: &serde_json::Value, name: &str| {
        let f = d.join(name);
        std::fs::write(&f, serde_json::to_string(json).unwrap()).unwrap();
        load_scene(f.to_str().unwrap(), &SceneOptions::default()).unwrap().scene
    };
    // Without alphaMode (OPAQUE) the factor's alpha is ignored.
    json["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"] = serde_json::json!([1.0, 0.5, 1.0, 0.4]);
    let s = load(&json, "opaque.gltf");
    assert_eq!(s.meshes[0].material_of(0).opacity, 1.0);
    assert_eq!(s.meshes[0].translucent_color(), None);
    json["materials"][0]["alphaMode"] = serde_json::json!("BLEND");
    let s = load(&json, "blend.gltf");
    let m = s.meshes[0].material_of(0);
    assert!(m.is_translucent() && (m.opacity - 0.4).abs() < 1e-6, "{}", m.opacity);
    let c = s.meshes[0].translucent_color().expect("every triangle is translucent");
    for (got, want) in c.iter().zip([0.4, 0.2, 0.4, 0.4]) {
        assert!((got - want).abs() < 1e-6, "{c:?}");
    }
    json["materials"][0]["alphaMode"] = serde_json::json!("MASK");
    assert_eq!(load(&json, "mask.gltf").meshes[0].material_of(0).opacity, 1.0);
}

#[test]
fn obj_with_mtl_map_kd_relative_to_the_mtl() {
    let (_dir, d) = temp_dir("obj-tex");
    std::fs::create_dir_all(d.join("mat/tex")).unwrap();
    std::fs::write(d.join("mat/tex/checker.png"), test_png()).unwrap();
    std::fs::write(d.join("mat/looks.mtl"), "newmtl painted\nKd 1 1 0.5\nmap_Kd tex/checker.png\n").unwrap();
    let obj = "mtllib mat/looks.mtl\no panel\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
               vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nusemtl painted\nf 1/1/1 2/2/1 3/3/1 4/4/1\n";
    let f = d.join("panel.obj");
    std::fs::write(&f, obj).unwrap();
    let s = load_scene(f.to_str().unwrap(), &SceneOptions::default()).unwrap().scene;
    assert_eq!(s.instances.len(), 1);
    let m = &s.meshes[0];
    assert_eq!(m.triangle_count(), 2);
    assert!(m.normals.as_ref().unwrap().iter().all(|n| *n == Vec3::Z));
    // OBJ's v = 0 is the bottom of the image: flipped to zwarp's (glTF's) top-left origin.
    let uvs = m.uvs.as_ref().unwrap();
    for (p, uv) in m.positions.iter().zip(uvs) {
        assert_eq!((uv.x, uv.y), (p.x, 1.0 - p.y), "{p} {uv}");
    }
    let mat = m.material_of(0);
    assert_eq!(mat.base_color, Vec3::new(1.0, 1.0, 0.5));
    let t = *mat.texture().expect("map_Kd").image().get(3, 0);
    assert!((t[0] - lin(180)).abs() < 1e-6 && t[1] == 0.0 && (t[2] - lin(200)).abs() < 1e-6, "{t:?}");
    // A map_Kd that is not there: one line naming the .mtl and the texture.
    std::fs::remove_file(d.join("mat/tex/checker.png")).unwrap();
    let msg = err_of(f.to_str().unwrap());
    assert!(msg.contains("looks.mtl") && msg.contains("checker.png") && msg.contains("not found"), "{msg}");
}

#[test]
fn ply_vertex_normals_are_read() {
    let (_dir, d) = temp_dir("ply-normals");
    let header = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
                  property float nx\nproperty float ny\nproperty float nz\nelement face 1\n\
                  property list uchar int vertex_indices\nend_header\n";
    let f = d.join("tri.ply");
    std::fs::write(&f, format!("{header}0 0 0 0 0 1\n1 0 0 0 0.6 0.8\n0 1 0 1 0 0\n3 0 1 2\n")).unwrap();
    let s = load_scene(f.to_str().unwrap(), &opts(SplitMode::None)).unwrap().scene;
    let n = s.meshes[0].normals.as_ref().expect("normals");
    let p = &s.meshes[0].positions;
    for (pos, want) in [(Vec3::ZERO, Vec3::Z), (Vec3::X, Vec3::new(0.0, 0.6, 0.8)), (Vec3::Y, Vec3::X)] {
        let i = p.iter().position(|q| *q == pos).unwrap();
        assert_eq!(n[i], want);
    }
    // A folder of PLY files keeps them too (one object per file).
    let s = load_scene(d.to_str().unwrap(), &SceneOptions::default()).unwrap().scene;
    assert!(s.meshes[0].normals.is_some());
    // Without nx/ny/nz: no normals.
    let s = load_scene(&fixture("quad_ascii.ply"), &SceneOptions::default()).unwrap().scene;
    assert!(s.meshes.iter().all(|m| m.normals.is_none()));
    // A NaN normal is a one-line error.
    let f = d.join("nan.ply");
    std::fs::write(&f, format!("{header}0 0 0 0 0 nan\n1 0 0 0 0 1\n0 1 0 0 0 1\n3 0 1 2\n")).unwrap();
    let msg = err_of(f.to_str().unwrap());
    assert!(msg.contains("nan.ply") && msg.contains("normal of vertex 0 is not finite"), "{msg}");
}

#[test]
fn files_without_materials_get_the_pattern_and_id_colours() {
    let s = load_scene(&fixture("quad_ascii.ply"), &opts(SplitMode::None)).unwrap().scene;
    assert!(s.meshes.iter().all(|m| m.parts.is_empty() && m.uvs.is_none()));
    assert_eq!(s.meshes[0].material_of(0).map, zwarp_core::ColorMap::Pattern);
    assert_ne!(s.instances[0].albedo, Vec3::ONE);
}

/// Two unit quads far apart, each with a UV seam (its two triangles use separate vertices at
/// the same positions), as one OBJ object or as two.
fn two_quads_obj(groups: bool) -> String {
    let mut s = String::new();
    for (k, x) in [0.0f32, 10.0].iter().enumerate() {
        if groups {
            s += &format!("o quad{k}\n");
        }
        for (px, py) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
            s += &format!("v {} {py} 0\n", x + px);
        }
        for (u, v) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.5, 0.5), (0.9, 0.9), (0.5, 0.9)] {
            s += &format!("vt {u} {v}\n");
        }
        let b = 6 * k + 1;
        s += &format!("f {}/{} {}/{} {}/{}\n", b, b, b + 1, b + 1, b + 2, b + 2);
        s += &format!("f {}/{} {}/{} {}/{}\n", b + 3, b + 3, b + 4, b + 4, b + 5, b + 5);
    }
    s
}

#[test]
fn a_one_object_file_is_split_into_connected_objects_for_culling() {
    let (_g, d) = temp_dir("split");
    let one = d.join("one.obj");
    std::fs::write(&one, two_quads_obj(false)).unwrap();
    let s = load_scene(one.to_str().unwrap(), &SceneOptions::default()).unwrap().scene;
    // Split by connectivity through positions: the UV seams do not cut a quad.
    assert_eq!(s.instances.len(), 2);
    let mut boxes: Vec<_> = s.instances.iter().map(|i| (i.world_aabb.min.x, i.world_aabb.max.x)).collect();
    boxes.sort_by(|a, b| a.0.total_cmp(&b.0));
    assert_eq!(boxes, vec![(0.0, 1.0), (10.0, 11.0)]);
    // One object's pieces keep its tint and its attributes.
    assert_eq!(s.instances[0].albedo, s.instances[1].albedo);
    assert!(s.meshes.iter().all(|m| m.triangle_count() == 2 && m.uvs.as_ref().is_some_and(|u| u.len() == 6)));
    assert_eq!(s.triangle_count(), 4);
    // Without splitting, and for a file of two objects, the file's structure stays.
    let none = load_scene(one.to_str().unwrap(), &opts(SplitMode::None)).unwrap().scene;
    assert_eq!(none.instances.len(), 1);
    let two = d.join("two.obj");
    std::fs::write(&two, two_quads_obj(true)).unwrap();
    let s2 = load_scene(two.to_str().unwrap(), &SceneOptions::default()).unwrap().scene;
    assert_eq!(s2.instances.len(), 2);
    assert_ne!(s2.instances[0].albedo, s2.instances[1].albedo);
}

#[test]
fn a_file_far_from_its_origin_is_recentred_and_its_paths_follow() {
    use glam::DVec3;
    use zwarp_core::Aabb;
    use zwarp_scene::{recentring_offset, FAR_FROM_ORIGIN};
    // Near the origin (every shipped scene) nothing moves; each far axis moves by its rounded
    // centre, the others stay (the up axis of a geo-referenced model keeps its heights).
    let b = |lo: [f32; 3], hi: [f32; 3]| Aabb { min: Vec3::from_array(lo), max: Vec3::from_array(hi) };
    assert_eq!(recentring_offset(&b([-806.0, -689.0, 0.0], [670.0, 517.0, 99.0])), None);
    assert_eq!(recentring_offset(&Aabb::EMPTY), None);
    let f = FAR_FROM_ORIGIN;
    assert_eq!(
        recentring_offset(&b([f, 0.0, -10.0], [f + 100.0, 40.0, 10.0])),
        Some(DVec3::new(f as f64 + 50.0, 0.0, 0.0))
    );
    assert_eq!(
        recentring_offset(&b([689_990.5, 5_334_000.0, 510.0], [690_400.0, 5_334_999.0, 600.0])),
        Some(DVec3::new(690_195.0, 5_334_500.0, 0.0)) // 690195.25 and 5334499.5 rounded
    );

    // A geo-referenced OBJ (UTM-like metres, Y up): loaded next to the origin, its path read in
    // the file's coordinates lands on the same local eye, written back it is the file's again.
    let (_dir, d) = temp_dir("far");
    let obj = d.join("far.obj");
    let (ox, oz) = (690_000.0f64, 5_334_000.0f64);
    let mut text = String::from("o block\n");
    for (x, y, z) in [(-4.0, 0.0, -2.0), (4.0, 0.0, -2.0), (4.0, 6.0, 2.0), (-4.0, 6.0, 2.0), (0.13, 3.0, 1.37)] {
        text += &format!("v {} {y} {}\n", ox + x, oz + z);
    }
    text += "f 1 2 3\nf 1 3 4\nf 1 2 5\n";
    std::fs::write(&obj, text).unwrap();
    let s = load_scene(obj.to_str().unwrap(), &SceneOptions::default()).unwrap().scene;
    assert_eq!(s.origin, DVec3::new(ox, 0.0, oz));
    assert_eq!(s.bounds(), b([-4.0, 0.0, -2.0], [4.0, 6.0, 2.0]));
    // Read in f64: the centimetres survive (in f32, 5,334,001.37 is 5,334,001.5).
    let p = s.meshes.iter().flat_map(|m| &m.positions).find(|p| p.y == 3.0).unwrap();
    assert_eq!((p.x, p.z), (0.13, 1.37));
    let json = format!(
        r#"{{"fov_y_deg": 60, "near": 0.1, "far": 100, "up": [0, 1, 0], "fps": 30,
            "keys": [{{"t": 0, "eye": [{}, 1.7, {}], "target": [{ox}, 1.5, {oz}]}},
                     {{"t": 1, "eye": [{}, 1.7, {}], "target": [{ox}, 1.5, {oz}]}}]}}"#,
        ox - 10.37,
        oz - 20.5,
        ox - 9.62,
        oz - 20.5
    );
    let p = CameraPath::from_json_str_at(&json, s.origin).unwrap();
    // f64 before f32: the local eye is what "-10.37" parses to, not the f32 step at 690 km.
    assert_eq!(p.keys[0].eye, Vec3::new(-10.37, 1.7, -20.5));
    assert_eq!(p.keys[1].eye.x, -9.62);
    let back: serde_json::Value = serde_json::from_str(&p.to_json_at(s.origin)).unwrap();
    assert_eq!(back["keys"][0]["eye"][0].as_f64(), Some(ox - 10.37));
    assert_eq!(CameraPath::from_json_str_at(&p.to_json_at(s.origin), s.origin).unwrap(), p);
    // A folder of such files (tiles 2 km apart): one origin, the tiles keep their spacing.
    let tiles = d.join("tiles");
    std::fs::create_dir(&tiles).unwrap();
    for (k, dx) in [0.0f64, 2000.0].iter().enumerate() {
        let v = |x: f64, y: f64, z: f64| format!("v {} {y} {}\n", ox + dx + x, oz + z);
        let text = format!("o tile\n{}{}{}f 1 2 3\n", v(0.25, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.25, 2.0, 0.5));
        std::fs::write(tiles.join(format!("t{k}.obj")), text).unwrap();
    }
    let s = load_scene(tiles.to_str().unwrap(), &SceneOptions::default()).unwrap().scene;
    assert_eq!(s.origin, DVec3::new(ox + 1001.0, 0.0, oz), "centre 1000.625 rounded");
    let firsts: Vec<Vec3> = s.instances.iter().map(|i| s.meshes[i.mesh as usize].positions[0]).collect();
    assert_eq!(firsts, vec![Vec3::new(-1000.75, 0.0, 0.0), Vec3::new(999.25, 0.0, 0.0)]);
    // A PLY with double vertices (Z up): anchored at its first vertex's whole metres.
    let ply = d.join("far.ply");
    let v = |x: f64, y: f64, z: f64| format!("{} {} {z}\n", ox + x, oz + y);
    let header = "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty double y\nproperty double z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
    std::fs::write(&ply, format!("{header}{}{}{}3 0 1 2\n", v(0.25, 0.0, 0.0), v(3.13, 0.0, 0.0), v(0.5, 1.37, 9.0)))
        .unwrap();
    let s = load_scene(ply.to_str().unwrap(), &SceneOptions::default()).unwrap().scene;
    assert_eq!(s.origin, DVec3::new(ox, oz, 0.0));
    let m = &s.meshes[s.instances[0].mesh as usize];
    assert_eq!(m.positions, vec![Vec3::new(0.25, 0.0, 0.0), Vec3::new(3.13, 0.0, 0.0), Vec3::new(0.5, 1.37, 9.0)]);
    // Read as if local (origin zero), the same file is 690 km away.
    assert!(CameraPath::from_json_str(&json).unwrap().keys[0].eye.x > 689_000.0);
}

#[test]
fn a_gltf_placing_its_objects_far_away_keeps_their_placement_to_the_centimetre() {
    use glam::DVec3;
    // One triangle mesh, placed by three nodes at UTM-like translations (a `matrix` node, a
    // decomposed one with a rotation, and a child of a far parent), the way geo-referenced glTF
    // exports place buildings: gltf's f32 would put them on a 0.5 m grid.
    let mut b: Vec<u8> = Vec::new();
    for p in [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
        p.iter().for_each(|v| b.extend_from_slice(&v.to_le_bytes()));
    }
    for i in [0u16, 1, 2, 0] {
        b.extend_from_slice(&i.to_le_bytes());
    }
    let (ox, oz) = (690_000.0f64, 5_334_000.0f64);
    let json = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 1, 2]}],
        "nodes": [
            {"mesh": 0, "translation": [ox + 0.13, 2.0, oz + 1.37]},
            {"mesh": 0, "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, ox + 10.5, 0, oz + 1.37, 1]},
            {"translation": [ox + 20.0, 0.0, oz], "rotation": [0, std::f64::consts::FRAC_1_SQRT_2, 0, std::f64::consts::FRAC_1_SQRT_2], "children": [3]},
            {"mesh": 0, "translation": [0.25, 0.0, 0.0]}
        ],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "buffers": [{"byteLength": b.len(), "uri": format!("data:application/octet-stream;base64,{}", encode_b64(&b))}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 6}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
            {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}
        ]
    });
    let (_dir, d) = temp_dir("gltf-far");
    let f = d.join("far.gltf");
    std::fs::write(&f, serde_json::to_string(&json).unwrap()).unwrap();
    let s = load_scene(f.to_str().unwrap(), &SceneOptions::default()).unwrap().scene;
    // Translations x 0.13 .. 20, z 0 .. 1.37 (Y up): the anchor is their rounded centre.
    assert_eq!(s.origin, DVec3::new(ox + 10.0, 0.0, oz + 1.0));
    let t: Vec<Vec3> = s.instances.iter().map(|i| i.transform.w_axis.truncate()).collect();
    assert!(t.contains(&Vec3::new(-9.87, 2.0, 0.37)), "{t:?}");
    assert!(t.contains(&Vec3::new(0.5, 0.0, 0.37)), "{t:?}");
    // The child: the parent's quarter turn about y takes its +x offset to -z.
    let child = t.iter().find(|p| p.x > 9.0).unwrap();
    assert!((*child - Vec3::new(10.0, 0.0, -1.25)).abs().max_element() < 1e-6, "{child:?}");
}
