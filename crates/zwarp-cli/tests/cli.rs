//! End-to-end tests of the `zwarp` binary: bad input gives one clear line and a non-zero exit;
//! small real runs write the documented JSON fields.

use std::path::PathBuf;
use std::process::Command;

fn zwarp(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_zwarp")).args(args).output().expect("run zwarp");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// `zwarp` with extra environment variables.
fn zwarp_env(args: &[&str], env: &[(&str, &str)]) -> (bool, String, String) {
    let out =
        Command::new(env!("CARGO_BIN_EXE_zwarp")).args(args).envs(env.iter().copied()).output().expect("run zwarp");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The small `eval` run the tests share (MO at scale 0.02, 96x64, one frame pair, N = 4,
/// L = 1, 2, one repetition) with `extra` arguments, writing `json`.
fn eval_small(extra: &[&str], json: &std::path::Path) -> (bool, String, String) {
    let mut args = vec![
        "eval", "--scene", "mo", "--scale", "0.02", "--width", "96", "--height", "64", "--frames", "1", "--n", "4",
        "--l", "1,2", "--reps", "1",
    ];
    args.extend_from_slice(extra);
    args.extend_from_slice(&["--json", json.to_str().unwrap()]);
    zwarp(&args)
}

/// `zwarp vr` on a tiny scene (cb at scale 0.01, 64x48, one frame, one timed run) with
/// `extra` flags, JSON to `json`: (success, stdout, stderr).
fn vr_small(extra: &[&str], json: &std::path::Path) -> (bool, String, String) {
    let mut args = vec![
        "vr", "--scene", "cb", "--scale", "0.01", "--width", "64", "--height", "48", "--frames", "1", "--reps", "1",
    ];
    args.extend_from_slice(extra);
    args.extend_from_slice(&["--json", json.to_str().unwrap()]);
    zwarp(&args)
}

/// The `rows` of a JSON report.
fn json_rows(path: &std::path::Path) -> Vec<serde_json::Value> {
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    v["rows"].as_array().unwrap().clone()
}

/// Whether `zwarp info` finds a GPU adapter; with `ZWARP_REQUIRE_GPU` set (CI, lavapipe) a
/// missing adapter fails the test instead of skipping it.
fn gpu_available() -> bool {
    let require = std::env::var("ZWARP_REQUIRE_GPU").map(|v| v != "0" && !v.is_empty()).unwrap_or(false);
    let (ok, out, _) = zwarp(&["info"]);
    assert!(ok);
    if !out.contains("GPU adapter:") {
        assert!(!require, "ZWARP_REQUIRE_GPU is set but no GPU adapter was found:\n{out}");
        eprintln!("skipped: no GPU adapter");
        return false;
    }
    true
}

/// A fresh temp dir per test, removed when the guard drops (also when the test fails).
fn tmp(name: &str) -> (tempfile::TempDir, PathBuf) {
    let guard = tempfile::Builder::new().prefix(&format!("zwarp-cli-test-{name}-")).tempdir().unwrap();
    let d = guard.path().to_path_buf();
    (guard, d)
}

/// The error is the last stderr line (lavapipe may print noise before it), starts with
/// `error:` and is a single line.
fn error_line(stderr: &str) -> String {
    let line = stderr.lines().rfind(|l| l.starts_with("error")).unwrap_or("").to_string();
    assert!(line.starts_with("error: "), "no error line in: {stderr}");
    line
}

#[test]
fn missing_scene_file_is_a_clear_error() {
    let (_dir, d) = tmp("missing");
    let (ok, _, err) = zwarp(&["render", "--scene", "/nonexistent/model.obj", "--out", d.to_str().unwrap()]);
    assert!(!ok);
    assert!(error_line(&err).contains("/nonexistent/model.obj"), "{err}");
}

#[test]
fn unknown_format_is_a_clear_error() {
    let (_dir, d) = tmp("unknown");
    let f = d.join("scene.xyz");
    std::fs::write(&f, "not a mesh").unwrap();
    let (ok, _, err) = zwarp(&["render", "--scene", f.to_str().unwrap(), "--out", d.to_str().unwrap()]);
    assert!(!ok);
    assert!(error_line(&err).contains("scene.xyz"), "{err}");
}

#[test]
fn zero_size_image_is_rejected() {
    let (_dir, d) = tmp("zero");
    let (ok, _, err) =
        zwarp(&["render", "--scene", "mo", "--scale", "0.01", "--width", "0", "--out", d.to_str().unwrap()]);
    assert!(!ok);
    assert!(error_line(&err).contains("0x1080"), "{err}");
}

/// `zwarp ... | head`: a closed stdout ends the process without a panic message.
#[cfg(unix)]
#[test]
fn closed_stdout_is_not_a_panic() {
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_zwarp"))
        .args(["info"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn bad_camera_paths_are_rejected() {
    let (_dir, d) = tmp("paths");
    let one_key = d.join("one.json");
    std::fs::write(&one_key, r#"{"fov_y_deg":60,"near":0.1,"far":100,"up":[0,0,1],"fps":30,"keys":[{"t":0,"eye":[0,0,1],"target":[1,0,1]}]}"#).unwrap();
    let near_far = d.join("nf.json");
    std::fs::write(&near_far, r#"{"fov_y_deg":60,"near":5,"far":5,"up":[0,0,1],"fps":30,"keys":[{"t":0,"eye":[0,0,1],"target":[1,0,1]},{"t":1,"eye":[1,0,1],"target":[2,0,1]}]}"#).unwrap();
    for (f, what) in [(&one_key, "key"), (&near_far, "near")] {
        let (ok, _, err) = zwarp(&[
            "render",
            "--scene",
            "mo",
            "--scale",
            "0.01",
            "--path",
            f.to_str().unwrap(),
            "--out",
            d.to_str().unwrap(),
        ]);
        assert!(!ok, "{f:?} accepted");
        let line = error_line(&err);
        assert!(line.contains(f.file_name().unwrap().to_str().unwrap()) && line.contains(what), "{line}");
    }
}

#[test]
fn bad_eval_parameters_are_rejected() {
    let (_dir, d) = tmp("evalbad");
    let j = d.join("e.json");
    for (flag, value) in [
        ("--n", "0"),
        ("--l", "0"),
        ("--bound", "loose"),
        ("--speed", "-1"),
        ("--holes", "magic"),
        ("--multisample", "0"),
        ("--multisample", "9"),
    ] {
        let (ok, _, err) =
            zwarp(&["eval", "--scene", "mo", "--scale", "0.01", flag, value, "--json", j.to_str().unwrap()]);
        assert!(!ok, "{flag} {value} accepted");
        let line = error_line(&err);
        // A negative number reaches the command's own check, not the parser's.
        if value.starts_with('-') {
            assert!(line.contains(flag), "{flag} {value}: {line}");
        }
    }
    assert!(!j.exists(), "no JSON is written on bad input");
}

/// Without `XDG_RUNTIME_DIR` the GPU loader stays quiet: zwarp gives it a private runtime dir.
#[test]
fn missing_runtime_dir_prints_no_loader_errors() {
    let out = Command::new(env!("CARGO_BIN_EXE_zwarp"))
        .arg("info")
        .env_remove("XDG_RUNTIME_DIR")
        .output()
        .expect("run zwarp");
    assert!(out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.lines().any(|l| l.starts_with("error")), "{err}");
}

#[test]
fn cull_needs_two_frames() {
    let (_dir, d) = tmp("cullbad");
    let j = d.join("c.json");
    for frames in ["0", "1"] {
        let (ok, _, err) =
            zwarp(&["cull", "--scene", "cb", "--scale", "0.01", "--frames", frames, "--json", j.to_str().unwrap()]);
        assert!(!ok, "--frames {frames} accepted");
        error_line(&err);
        assert!(err.contains("--frames"), "{err}");
    }
    assert!(!j.exists(), "no JSON is written on bad input");
}

/// `--multisample 1,2`: our warp from a 2x2-sampled source next to the one-sample rows (the
/// forward baselines only at m = 1), same scene, frames and reference; `multisample` in JSON.
#[test]
fn eval_multisample_rows_are_ours_only() {
    let (_dir, d) = tmp("evalms");
    let j = d.join("e.json");
    let (ok, out, err) = eval_small(&["--multisample", "1,2"], &j);
    assert!(ok, "{err}");
    let rows = json_rows(&j);
    let key = |r: &serde_json::Value| (r["method"].as_str().unwrap().to_string(), r["multisample"].as_u64().unwrap());
    let mut keys: Vec<_> = rows.iter().map(key).collect();
    keys.sort();
    keys.dedup_by(|a, b| a == b);
    let want: Vec<(String, u64)> = vec![("afw".into(), 1), ("ours".into(), 1), ("ours".into(), 2), ("vfw".into(), 1)];
    assert_eq!(keys, want);
    // ours at L = 1, 2 for each m, the baselines at L = 1, 2.
    assert_eq!(rows.len(), 8);
    let r1 = rows.iter().find(|r| key(r) == ("ours".into(), 1)).unwrap();
    let r2 = rows.iter().find(|r| key(r) == ("ours".into(), 2)).unwrap();
    assert_eq!(r1["ref_ms"], r2["ref_ms"], "one reference per run");
    assert!(r2["ssim"].as_f64().unwrap() > 0.9, "{r2}");
    assert!(out.contains("| m "), "the table shows m");
}

#[test]
fn render_writes_every_buffer() {
    let (_dir, d) = tmp("render");
    let (ok, out, err) = zwarp(&[
        "render",
        "--scene",
        "mo",
        "--scale",
        "0.02",
        "--width",
        "64",
        "--height",
        "48",
        "--layers",
        "2",
        "--out",
        d.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    assert!(out.contains("wrote"), "{out}");
    for f in [
        "depth.png",
        "depth.exr",
        "items.png",
        "color.png",
        "motion.png",
        "motion.exr",
        "layer0.png",
        "layer1.png",
        "layer_ground.png",
    ] {
        assert!(d.join(f).exists(), "{f} missing");
    }
}

#[test]
fn eval_writes_the_documented_fields() {
    let (_dir, d) = tmp("eval");
    let j = d.join("e.json");
    let (ok, _, err) = eval_small(&[], &j);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&j).unwrap()).unwrap();
    let rows = v["rows"].as_array().unwrap();
    // ours, vfw, afw at L = 1 and 2.
    assert_eq!(rows.len(), 6);
    for r in rows {
        for k in [
            "method",
            "scene",
            "n",
            "l",
            "t",
            "bound",
            "speed",
            "psnr",
            "ssim",
            "converged",
            "converged_seen",
            "warp_ms",
            "ref_ms",
            "speedup",
            "floor_ms",
            "floor_ratio",
            "floor_gbps",
            "frames_detail",
        ] {
            assert!(!r[k].is_null(), "field {k} missing in {r}");
        }
        // The floor's bandwidth: L layers of f32 depth + 12-byte motion read, one f32 per pixel
        // written, over floor_ms.
        let (w, h, l) = (r["width"].as_f64().unwrap(), r["height"].as_f64().unwrap(), r["l"].as_f64().unwrap());
        let bytes = l * w * h * 16.0 + w * h * 4.0;
        let gbps = bytes / (r["floor_ms"].as_f64().unwrap() * 1e6);
        assert!((r["floor_gbps"].as_f64().unwrap() - gbps).abs() < 1e-6 * gbps, "{r}");
        // The floor ratio is the warp's time over the floor's; one detail per frame pair, whose
        // mean is the row's PSNR.
        let fr = r["warp_ms"].as_f64().unwrap() / r["floor_ms"].as_f64().unwrap();
        assert!((r["floor_ratio"].as_f64().unwrap() - fr).abs() < 1e-6 * fr.max(1.0), "{r}");
        let detail = r["frames_detail"].as_array().unwrap();
        assert_eq!(detail.len() as u64, r["frames"].as_u64().unwrap(), "{r}");
        let mean = detail.iter().map(|f| f["psnr"].as_f64().unwrap()).sum::<f64>() / detail.len() as f64;
        assert!((mean - r["psnr"].as_f64().unwrap()).abs() < 1e-9, "{r}");
        assert!(detail.iter().all(|f| f["ssim"].as_f64().unwrap() <= 1.0 && f["converged"].as_f64().unwrap() <= 1.0));
        assert!(detail.iter().all(|f| (0.0..=1.0).contains(&f["converged_seen"].as_f64().unwrap())), "{r}");
        let s = r["ssim"].as_f64().unwrap();
        assert!(s > 0.5 && s <= 1.0, "{r}");
        let sp = r["speedup"].as_f64().unwrap();
        let ratio = r["ref_ms"].as_f64().unwrap() / r["warp_ms"].as_f64().unwrap();
        assert!((sp - ratio).abs() < 1e-6 * ratio.max(1.0), "{r}");
    }
}

/// `zwarp cull` on a tiny scene (scale 0.01, 96x64, 4 frames) with `extra` flags, JSON to
/// `json`: (success, stderr).
fn cull_small(scene: &str, extra: &[&str], json: &std::path::Path) -> (bool, String) {
    let mut args =
        vec!["cull", "--scene", scene, "--scale", "0.01", "--width", "96", "--height", "64", "--frames", "4"];
    args.extend_from_slice(extra);
    args.extend_from_slice(&["--json", json.to_str().unwrap()]);
    let (ok, _, err) = zwarp(&args);
    (ok, err)
}

#[test]
fn cull_reference_and_nocull_are_exact() {
    let (_dir, d) = tmp("cull");
    let j = d.join("c.json");
    let (ok, err) = cull_small("cb", &["--method", "nocull,vfc,woc,ref"], &j);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&j).unwrap()).unwrap();
    let rows = v["rows"].as_array().unwrap();
    let get = |m: &str| rows.iter().find(|r| r["method"] == m).unwrap_or_else(|| panic!("no {m} row")).clone();
    let (nocull, vfc, woc, reference) = (get("nocull"), get("vfc"), get("woc"), get("ref"));
    assert_eq!(nocull["culling_ratio"].as_f64().unwrap(), 0.0);
    assert_eq!(nocull["object_error"].as_f64().unwrap(), 0.0);
    assert_eq!(reference["object_error"].as_f64().unwrap(), 0.0);
    assert_eq!(reference["psnr_worst"], "inf");
    // Occlusion-map accuracy: WOC has a map (fractions in [0, 1]), VFC none ("nan").
    let frac = |r: &serde_json::Value, k: &str| r[k].as_f64().unwrap_or_else(|| panic!("{k}: {r}"));
    assert!((0.0..=1.0).contains(&frac(&woc, "map_error_fraction")), "{woc}");
    assert!(frac(&woc, "map_error_fraction_max") >= frac(&woc, "map_error_fraction"), "{woc}");
    assert!((0.0..=1.0).contains(&frac(&woc, "map_overestimation_fraction")), "{woc}");
    assert_eq!(vfc["map_error_fraction"], "nan");
    // REF culls at least as much as any safe method; WOC at least as much as VFC.
    let cr = |r: &serde_json::Value| r["culling_ratio"].as_f64().unwrap();
    assert!(cr(&reference) >= cr(&woc) - 1e-12 && cr(&woc) >= cr(&vfc) - 1e-12, "{rows:?}");
}

/// `--repeat 3` culls every frame three times and keeps the median-cost repetition: the same
/// decisions as one run (the cull is deterministic), `repeat` recorded in the JSON; 0 and the
/// GPU backend are rejected with one line.
#[test]
fn cull_repeat_keeps_the_decisions() {
    let (_dir, d) = tmp("cullrepeat");
    let run = |repeat: &str, name: &str| {
        let j = d.join(name);
        let (ok, err) = cull_small("bl", &["--method", "vfc,twophase,woc", "--no-psnr", "--repeat", repeat], &j);
        (ok, err, j)
    };
    let read = |j: &std::path::Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(j).unwrap()).unwrap()
    };
    let (ok1, err1, j1) = run("1", "r1.json");
    let (ok3, err3, j3) = run("3", "r3.json");
    assert!(ok1 && ok3, "{err1}{err3}");
    let (v1, v3) = (read(&j1), read(&j3));
    assert_eq!(v3["repeat"], 3, "{v3}");
    for (a, b) in v1["rows"].as_array().unwrap().iter().zip(v3["rows"].as_array().unwrap()) {
        for k in ["method", "culling_ratio", "culled_visible", "pixel_error", "triangle_fraction"] {
            assert_eq!(a[k], b[k], "{k}: {a} vs {b}");
        }
    }
    let (ok, err, _) = run("0", "r0.json");
    assert!(!ok);
    assert!(error_line(&err).contains("--repeat"), "{err}");
}

/// `--rim-separation`: recorded in the JSON; a lower threshold opens more rims, so WOC never
/// culls more than with the default; a negative or NaN one is one `error:` line.
#[test]
fn cull_rim_separation_is_a_threshold() {
    let (_dir, d) = tmp("cullrims");
    let read = |j: &std::path::Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(j).unwrap()).unwrap()
    };
    let cr = |v: &serde_json::Value| v["rows"][0]["culling_ratio"].as_f64().unwrap();
    let (jd, js) = (d.join("default.json"), d.join("strict.json"));
    let (ok, err) = cull_small("bl", &["--method", "woc", "--no-psnr", "--downsample", "1"], &jd);
    assert!(ok, "{err}");
    let (ok, err) =
        cull_small("bl", &["--method", "woc", "--no-psnr", "--downsample", "1", "--rim-separation", "0.01"], &js);
    assert!(ok, "{err}");
    let (vd, vs) = (read(&jd), read(&js));
    assert_eq!(vd["rim_separation"].as_f64().unwrap() as f32, 0.1, "{vd}");
    assert_eq!(vs["rim_separation"].as_f64().unwrap() as f32, 0.01, "{vs}");
    assert!(cr(&vs) <= cr(&vd), "{} vs {}", cr(&vs), cr(&vd));
    for bad in ["-1", "NaN"] {
        let (ok, err) =
            cull_small("bl", &["--method", "woc", "--no-psnr", "--rim-separation", bad], &d.join("bad.json"));
        assert!(!ok);
        assert!(error_line(&err).contains("rim separation"), "{err}");
    }
}

#[test]
fn shadows_writes_the_documented_fields() {
    let (_dir, d) = tmp("shadows");
    let j = d.join("s.json");
    let (ok, _, err) = zwarp(&[
        "shadows",
        "--scene",
        "mo",
        "--scale",
        "0.02",
        "--width",
        "64",
        "--height",
        "48",
        "--samples",
        "1,4",
        "--sm",
        "64",
        "--reps",
        "1",
        "--json",
        j.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&j).unwrap()).unwrap();
    let rows = v["rows"].as_array().unwrap();
    // reference, zwarp and pcss at S = 1 and 4.
    assert_eq!(rows.len(), 6, "{rows:?}");
    for r in rows {
        for k in ["method", "scene", "samples", "sm", "ms", "psnr", "ssim", "speedup"] {
            assert!(!r[k].is_null(), "field {k} missing in {r}");
        }
    }
    // The reference against itself is exact.
    let reference = rows.iter().find(|r| r["method"] == "reference").unwrap();
    assert_eq!(reference["ssim"].as_f64().unwrap(), 1.0);
}

/// `--backend gpu` runs the WGSL twin of the warp: same quality as the CPU on the same frames,
/// with one source sample per pixel and with a 2x2-sampled source (`--multisample 2`, holes
/// filled by `--holes background` on the device). Runs where an adapter exists (lavapipe in CI,
/// which sets `ZWARP_REQUIRE_GPU=1` so that a missing adapter fails here instead of skipping).
#[test]
fn eval_gpu_backend_matches_cpu() {
    if !gpu_available() {
        return;
    }
    let (_dir, d) = tmp("evalgpu");
    for (m, extra) in [("1", &[][..]), ("2", &["--multisample", "2", "--holes", "background"][..])] {
        let mut ssim = Vec::new();
        for backend in ["cpu", "gpu"] {
            let j = d.join(format!("{backend}_m{m}.json"));
            let mut args = vec!["--methods", "ours", "--backend", backend];
            args.extend_from_slice(extra);
            let (ok, _, err) = eval_small(&args, &j);
            assert!(ok, "{backend} m = {m}: {err}");
            let rows = json_rows(&j);
            assert!(rows.iter().all(|r| r["multisample"].as_u64() == m.parse().ok()), "{backend} m = {m}");
            ssim.push(rows.iter().map(|r| r["ssim"].as_f64().unwrap()).collect::<Vec<_>>());
        }
        assert_eq!(ssim[0].len(), 2);
        for (c, g) in ssim[0].iter().zip(&ssim[1]) {
            assert!((c - g).abs() < 2e-3, "m = {m}: cpu {c} vs gpu {g}");
        }
    }
}

/// `render --backend gpu` writes the same files and JSON fields as the CPU, with the same
/// coverage (GPU and CPU rasterizers agree on >= 99.9% of pixels).
#[test]
fn render_gpu_backend_matches_cpu() {
    if !gpu_available() {
        return;
    }
    let (_dir, d) = tmp("rendergpu");
    let mut rows = Vec::new();
    for backend in ["cpu", "gpu"] {
        let out = d.join(backend);
        let j = d.join(format!("{backend}.json"));
        let (ok, text, err) = zwarp(&[
            "render",
            "--scene",
            "mo",
            "--scale",
            "0.02",
            "--width",
            "64",
            "--height",
            "48",
            "--layers",
            "2",
            "--backend",
            backend,
            "--out",
            out.to_str().unwrap(),
            "--json",
            j.to_str().unwrap(),
        ]);
        assert!(ok, "{backend}: {err}");
        assert!(text.contains(if backend == "gpu" { "on GPU" } else { "on CPU" }), "{text}");
        rows.push(json_rows(&j).remove(0));
    }
    let (c, g) = (&rows[0], &rows[1]);
    for k in ["objects", "triangles", "width", "height"] {
        assert_eq!(c[k], g[k], "{k}");
    }
    let names = |r: &serde_json::Value| -> Vec<String> {
        r["files"]
            .as_array()
            .unwrap()
            .iter()
            .map(|f| f.as_str().unwrap().rsplit('/').next().unwrap().to_string())
            .collect()
    };
    assert_eq!(names(c), names(g));
    let cov = |r: &serde_json::Value| r["covered_fraction"].as_f64().unwrap();
    assert!((cov(c) - cov(g)).abs() <= 1e-3, "coverage cpu {} gpu {}", cov(c), cov(g));
    let lc: Vec<Vec<f64>> = rows
        .iter()
        .map(|r| r["layer_coverage"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect())
        .collect();
    assert_eq!(lc[0].len(), lc[1].len());
    for (a, b) in lc[0].iter().zip(&lc[1]) {
        assert!((a - b).abs() <= 0.01 * (64.0 * 48.0), "layer coverage cpu {a} gpu {b}");
    }
}

/// `cull --backend gpu`: the same JSON fields, and the same decisions as the CPU for the
/// methods whose CPU and GPU versions compute the same function (the kernels are twins;
/// differences only at the conservative depth margin: at most one object per frame), and a
/// safe WOC. CPU-only methods are skipped with a note.
#[test]
fn cull_gpu_backend_matches_cpu() {
    if !gpu_available() {
        return;
    }
    let (_dir, d) = tmp("cullgpu");
    let mut all = Vec::new();
    for backend in ["cpu", "gpu"] {
        let j = d.join(format!("{backend}.json"));
        let (ok, _, err) = zwarp(&[
            "cull",
            "--scene",
            "cb",
            "--scale",
            "0.01",
            "--width",
            "96",
            "--height",
            "64",
            "--frames",
            "4",
            "--method",
            "nocull,vfc,lastframe,woc,awoc,ideal,ref,twophase",
            "--no-psnr",
            "--backend",
            backend,
            "--json",
            j.to_str().unwrap(),
        ]);
        assert!(ok, "{backend}: {err}");
        if backend == "gpu" {
            assert!(err.contains("twophase CPU-only, skipped"), "{err}");
        }
        all.push(json_rows(&j));
    }
    let (cpu, gpu) = (&all[0], &all[1]);
    assert_eq!(gpu.len(), 7, "every GPU method but twophase");
    let get = |rows: &[serde_json::Value], m: &str| rows.iter().find(|r| r["method"] == m).unwrap().clone();
    for g in gpu {
        let c = get(cpu, g["method"].as_str().unwrap());
        let keys = |r: &serde_json::Value| r.as_object().unwrap().keys().cloned().collect::<Vec<_>>();
        assert_eq!(keys(&c), keys(g), "same JSON fields");
    }
    let objects = get(gpu, "vfc")["objects"].as_f64().unwrap();
    let cr = |r: &serde_json::Value| r["culling_ratio"].as_f64().unwrap();
    for m in ["nocull", "vfc", "lastframe", "ideal", "ref"] {
        let (c, g) = (get(cpu, m), get(gpu, m));
        assert!((cr(&c) - cr(&g)).abs() * objects <= 1.0, "{m}: cpu {} gpu {}", cr(&c), cr(&g));
    }
    let woc = get(gpu, "woc");
    assert_eq!(woc["object_error"].as_f64().unwrap(), 0.0, "{woc}");
    assert!(cr(&woc) >= cr(&get(gpu, "vfc")) - 1e-12, "{woc}");
}

/// Without an adapter `--backend gpu` fails with one line (no adapter is forced by pointing
/// wgpu at a backend this build lacks).
#[test]
fn gpu_backend_without_adapter_is_one_clear_line() {
    let (_dir, d) = tmp("noadapter");
    let j = d.join("c.json");
    let args = [
        "cull",
        "--scene",
        "cb",
        "--scale",
        "0.01",
        "--width",
        "64",
        "--height",
        "48",
        "--frames",
        "2",
        "--backend",
        "gpu",
        "--json",
        j.to_str().unwrap(),
    ];
    let (ok, _, err) = zwarp_env(&args, &[("WGPU_BACKEND", "metal")]);
    assert!(!ok);
    assert!(error_line(&err).contains("no GPU adapter found"), "{err}");
    assert!(!j.exists());
}

/// `shadows --backend gpu` (zwarp_shadows::gpu::GpuShadows): the same JSON fields, and reference and
/// zwarp images close to the CPU's on a small scene (SSIM >= 0.99 per row, same S and map size).
#[test]
fn shadows_gpu_backend_matches_cpu() {
    if !gpu_available() {
        return;
    }
    let (_dir, d) = tmp("shadowsgpu");
    let mut runs = Vec::new();
    for backend in ["cpu", "gpu"] {
        let j = d.join(format!("{backend}.json"));
        let imgs = d.join(backend);
        let (ok, _, err) = zwarp(&[
            "shadows",
            "--scene",
            "mo",
            "--scale",
            "0.02",
            "--width",
            "64",
            "--height",
            "48",
            "--samples",
            "4",
            "--sm",
            "128",
            "--methods",
            "zwarp",
            "--reps",
            "1",
            "--warmup",
            "0",
            "--images",
            imgs.to_str().unwrap(),
            "--backend",
            backend,
            "--json",
            j.to_str().unwrap(),
        ]);
        assert!(ok, "{backend}: {err}");
        let rows = json_rows(&j);
        assert_eq!(rows.len(), 2, "{backend}: {rows:?}");
        for r in &rows {
            for k in ["method", "scene", "samples", "sm", "ms", "psnr", "ssim", "speedup"] {
                assert!(!r[k].is_null(), "{backend}: field {k} missing in {r}");
            }
        }
        runs.push(imgs);
    }
    for m in ["reference", "zwarp"] {
        // The shaded images as written (8-bit PNG), compared as [0, 1] RGB.
        let load = |dir: &PathBuf| {
            let p = dir.join(format!("mo_{m}_s4_sm128.png"));
            let img = zwarp_viz::read_png(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
            img.map(|c| (*c).map(|v| v as f32 / 255.0))
        };
        let (c, g) = (load(&runs[0]), load(&runs[1]));
        let ssim = zwarp_metrics::ssim_rgb(&g, &c, 1.0).unwrap();
        assert!(ssim >= 0.99, "{m}: gpu vs cpu SSIM {ssim}");
    }
}

/// The JSON fields every colour-warp row (`upsample`, `stereo`, `blur`) carries.
const COLOR_FIELDS: [&str; 12] =
    ["method", "scene", "width", "height", "psnr", "psnr_y", "psnr_rgb", "ssim", "ssim_y", "flip", "cie94", "floor_ms"];

/// Checks the shared colour-row fields and the method names; returns the rows.
fn color_rows(json: &std::path::Path, methods: usize) -> Vec<serde_json::Value> {
    let rows = json_rows(json);
    let names: std::collections::BTreeSet<String> =
        rows.iter().map(|r| r["method"].as_str().unwrap().to_string()).collect();
    assert_eq!(names.len(), methods, "{names:?}");
    for n in &names {
        assert!(["heuristic", "robust", "repeat", "mesh", "reproject", "scatter"].contains(&n.as_str()), "{n}");
    }
    for r in &rows {
        for k in COLOR_FIELDS {
            assert!(!r[k].is_null(), "field {k} missing in {r}");
        }
        let s = r["ssim"].as_f64().unwrap();
        assert!(s > 0.3 && s <= 1.0, "{r}");
        let f = r["flip"].as_f64().unwrap();
        assert!((0.0..=1.0).contains(&f), "{r}");
    }
    rows
}

#[test]
fn upsample_writes_the_documented_fields() {
    let (_dir, d) = tmp("upsample");
    let j = d.join("u.json");
    let img = d.join("img");
    let (ok, out, err) = zwarp(&[
        "upsample",
        "--scene",
        "mo",
        "--scale",
        "0.02",
        "--width",
        "96",
        "--height",
        "64",
        "--frames",
        "1",
        "--factor",
        "2",
        "--interpolate",
        "--reps",
        "1",
        "--images",
        img.to_str().unwrap(),
        "--json",
        j.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    assert!(out.contains("heuristic") && out.contains("speedup"), "{out}");
    let rows = color_rows(&j, 6);
    // Six methods, extrapolated and interpolated.
    assert_eq!(rows.len(), 12);
    for r in &rows {
        for k in [
            "mode",
            "motion",
            "factor",
            "warp_ms",
            "render_ms",
            "speedup",
            "floor_ratio",
            "converged",
            "disocc_fraction",
        ] {
            assert!(!r[k].is_null(), "field {k} missing in {r}");
        }
        let sp = r["render_ms"].as_f64().unwrap() / r["warp_ms"].as_f64().unwrap();
        assert!((r["speedup"].as_f64().unwrap() - sp).abs() < 1e-6 * sp.max(1.0), "{r}");
    }
    assert!(rows.iter().any(|r| r["mode"] == "interpolate") && rows.iter().any(|r| r["mode"] == "extrapolate"));
    assert!(img.join("mo_f2_reference.png").exists() && img.join("mo_f2_extrap_robust.png").exists());
    assert!(img.join("mo_f2_extrap_strip.png").exists());
}

#[test]
fn stereo_and_blur_write_the_documented_fields() {
    let (_dir, d) = tmp("stereo");
    let j = d.join("s.json");
    let img = d.join("img");
    let (ok, _, err) = zwarp(&[
        "stereo",
        "--scene",
        "cb",
        "--scale",
        "0.01",
        "--width",
        "96",
        "--height",
        "64",
        "--frames",
        "1",
        "--reps",
        "1",
        "--methods",
        "heuristic,robust,repeat",
        "--images",
        img.to_str().unwrap(),
        "--json",
        j.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let rows = color_rows(&j, 3);
    // Three methods x two strategies x two eyes.
    assert_eq!(rows.len(), 12);
    for r in &rows {
        assert!(["left", "right"].contains(&r["eye"].as_str().unwrap()), "{r}");
        assert!(["cyclops", "alternate"].contains(&r["strategy"].as_str().unwrap()), "{r}");
        assert!(!r["seed_offset_px"].is_null() && !r["warp_ms"].is_null());
    }
    assert!(img.join("cb_reference_anaglyph.png").exists() && img.join("cb_cyclops_robust_sbs.png").exists());
    let j = d.join("b.json");
    let (ok, _, err) = zwarp(&[
        "blur",
        "--scene",
        "cb",
        "--scale",
        "0.01",
        "--width",
        "96",
        "--height",
        "64",
        "--motion",
        "--defocus",
        "--samples",
        "4",
        "--methods",
        "heuristic,robust,repeat",
        "--json",
        j.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let rows = color_rows(&j, 3);
    for r in &rows {
        for k in ["samples", "ms", "render_ms", "speedup", "floor_ratio"] {
            assert!(!r[k].is_null(), "field {k} missing in {r}");
        }
        let k = if r["method"] == "repeat" { 1 } else { 4 };
        assert_eq!(r["samples"].as_u64().unwrap(), k, "{r}");
    }
}

#[test]
fn colour_commands_reject_bad_input_in_one_line() {
    let (_dir, d) = tmp("colorbad");
    let j = d.join("x.json");
    let js = j.to_str().unwrap();
    let sky = d.join("sky.json");
    std::fs::write(&sky, r#"{"fov_y_deg":60,"near":0.1,"far":100,"up":[0,0,1],"fps":30,"keys":[{"t":0,"eye":[0,0,500],"target":[100,0,600]},{"t":1,"eye":[1,0,500],"target":[101,0,600]}]}"#).unwrap();
    let small = ["--scale", "0.01", "--width", "64", "--height", "48"];
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["upsample", "--scene", "mo", "--factor", "0"], "--factor"),
        (vec!["upsample", "--scene", "mo", "--motion", "cubic"], "--motion"),
        (vec!["upsample", "--scene", "mo", "--methods", "magic"], "magic"),
        (vec!["stereo", "--scene", "mo", "--eye-sep", "NaN"], "--eye-sep"),
        (vec!["stereo", "--scene", "mo", "--eye-sep", "-1"], "--eye-sep"),
        (vec!["blur", "--scene", "mo", "--motion", "--samples", "0"], "--samples"),
        (vec!["blur", "--scene", "mo", "--motion", "--shutter", "-1"], "--shutter"),
        (vec!["blur", "--scene", "mo", "--defocus", "--aperture", "-0.1"], "--aperture"),
        (vec!["blur", "--scene", "mo", "--samples", "4"], "nothing to blur"),
        (vec!["upsample", "--scene", "mo", "--path", sky.to_str().unwrap()], "no surface"),
    ];
    for (mut args, what) in cases {
        args.extend_from_slice(&small);
        args.extend_from_slice(&["--reps", "1", "--json", js]);
        let (ok, _, err) = zwarp(&args);
        assert!(!ok, "{args:?} accepted");
        let line = error_line(&err);
        assert!(line.contains(what), "{args:?}: {line}");
        assert_eq!(err.lines().filter(|l| l.starts_with("error")).count(), 1, "{err}");
    }
}

#[test]
fn colour_commands_gpu_backend_matches_cpu() {
    if !gpu_available() {
        return;
    }
    let (_dir, d) = tmp("colorgpu");
    let run = |backend: &str| {
        let j = d.join(format!("{backend}.json"));
        let (ok, _, err) = zwarp_env(
            &[
                "upsample",
                "--scene",
                "mo",
                "--scale",
                "0.02",
                "--width",
                "96",
                "--height",
                "64",
                "--frames",
                "1",
                "--reps",
                "1",
                "--methods",
                "heuristic,robust",
                "--backend",
                backend,
                "--json",
                j.to_str().unwrap(),
            ],
            &[("XDG_RUNTIME_DIR", "/tmp")],
        );
        assert!(ok, "{err}");
        json_rows(&j)
    };
    let (cpu, gpu) = (run("cpu"), run("gpu"));
    assert_eq!(cpu.len(), gpu.len());
    for (c, g) in cpu.iter().zip(&gpu) {
        assert_eq!(c["method"], g["method"]);
        // Both render the same frames (GPU renderer vs CPU rasterizer) and warp them.
        let (pc, pg) = (c["psnr"].as_f64().unwrap(), g["psnr"].as_f64().unwrap());
        assert!((pc - pg).abs() < 1.0, "{c} vs {g}");
    }
}

/// The JSON fields of every `zwarp vr` row.
const VR_FIELDS: [&str; 24] = [
    "method",
    "strategy",
    "holes",
    "filter",
    "abuffer",
    "eye",
    "psnr",
    "psnr_holes",
    "ssim",
    "flip",
    "primitives",
    "ms_quadtree",
    "ms_grid",
    "ms_warp",
    "ms_holes",
    "ms_abuffer",
    "warp_ms",
    "render_ms",
    "speedup",
    "scene",
    "width",
    "height",
    "frames",
    "ipd",
];

#[test]
fn vr_writes_the_documented_fields() {
    let (_dir, d) = tmp("vr");
    let j = d.join("vr.json");
    let img = d.join("img");
    let (ok, out, err) = vr_small(
        &[
            "--method",
            "grid,points,didyk,fpi",
            "--filter",
            "bilinear,adaptive",
            "--holes",
            "lowpass,pushpull",
            "--images",
            img.to_str().unwrap(),
        ],
        &j,
    );
    assert!(ok, "{err}");
    assert!(out.contains("| grid") && out.contains("speedup"), "{out}");
    let rows = json_rows(&j);
    // (4 method/filter pairs x 2 holes + fpi) x 2 strategies x 2 eyes, no transparency:
    // abuffer off only.
    assert_eq!(rows.len(), 36, "{rows:?}");
    let filters: Vec<(&str, &str)> =
        rows.iter().map(|r| (r["method"].as_str().unwrap(), r["filter"].as_str().unwrap())).collect();
    for pair in
        [("grid", "bilinear"), ("grid", "adaptive"), ("didyk", "bilinear"), ("points", "nearest"), ("fpi", "builtin")]
    {
        assert!(filters.contains(&pair), "{pair:?} in {filters:?}");
    }
    assert!(!filters.contains(&("didyk", "adaptive")), "only the grid methods take --filter");
    for r in &rows {
        for k in VR_FIELDS {
            assert!(!r[k].is_null(), "field {k} missing in {r}");
        }
        assert_eq!(r["abuffer"], false);
        assert!(["left", "right"].contains(&r["eye"].as_str().unwrap()), "{r}");
        assert!(["cyclops", "alternate"].contains(&r["strategy"].as_str().unwrap()), "{r}");
        let holes = r["holes"].as_str().unwrap();
        if r["method"] == "fpi" {
            assert_eq!(holes, "builtin");
        } else {
            assert!(["lowpass", "pushpull"].contains(&holes), "{r}");
            assert!(r["primitives"].as_f64().unwrap() >= 1.0, "{r}");
        }
        let stages: f64 = ["ms_quadtree", "ms_grid", "ms_warp", "ms_holes", "ms_abuffer"]
            .iter()
            .map(|k| r[k].as_f64().unwrap())
            .sum();
        assert!((stages - r["warp_ms"].as_f64().unwrap()).abs() < 1e-9, "{r}");
        let sp = r["render_ms"].as_f64().unwrap() / r["warp_ms"].as_f64().unwrap();
        assert!((r["speedup"].as_f64().unwrap() - sp).abs() < 1e-6 * sp.max(1.0), "{r}");
        let s = r["ssim"].as_f64().unwrap();
        assert!(s > 0.3 && s <= 1.0, "{r}");
        assert!(r["ipd"].as_f64().unwrap() == 0.064f32 as f64);
        if r["method"] == "grid" {
            assert!(r["ms_quadtree"].as_f64().unwrap() > 0.0, "{r}");
        }
    }
    // Points draw one splat per pixel.
    assert!(rows.iter().filter(|r| r["method"] == "points").all(|r| r["primitives"].as_f64().unwrap() == 64.0 * 48.0));
    for f in [
        "cb_reference_anaglyph.png",
        "cb_cyclops_grid-bilinear_lowpass_anaglyph.png",
        "cb_cyclops_grid-adaptive_grid.png",
        "cb_alternate_grid-adaptive_lowpass_left_flip.png",
        "cb_cyclops_didyk_lowpass_anaglyph.png",
    ] {
        assert!(img.join(f).exists(), "{f}");
    }
}

/// `vr --backend gpu` (zwarp_vr::gpu::GridWarpKernel, fpi on the GPU colour warp): the same rows,
/// primitives and quality as the CPU up to the rasterisers' edge rules.
#[test]
fn vr_on_the_gpu_matches_the_cpu_rows() {
    if !gpu_available() {
        return;
    }
    let (_dir, d) = tmp("vrgpu");
    let mut rows = Vec::new();
    for backend in ["cpu", "gpu"] {
        let j = d.join(format!("{backend}.json"));
        let extra = [
            "--method",
            "grid,quads,points,didyk,fpi",
            "--holes",
            "lowpass",
            "--strategy",
            "cyclops",
            "--backend",
            backend,
        ];
        let (ok, out, err) = vr_small(&extra, &j);
        assert!(ok, "{backend}: {err}");
        assert!(out.contains(if backend == "gpu" { "GPU" } else { "CPU" }), "{out}");
        let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&j).unwrap()).unwrap();
        assert_eq!(v["backend"], backend, "{v}");
        rows.push(json_rows(&j));
    }
    assert_eq!(rows[0].len(), 10);
    assert_eq!(rows[0].len(), rows[1].len());
    for (c, g) in rows[0].iter().zip(&rows[1]) {
        for k in ["method", "eye", "holes", "primitives"] {
            assert_eq!(c[k], g[k], "{k}: {c} vs {g}");
        }
        let (pc, pg) = (c["psnr"].as_f64().unwrap(), g["psnr"].as_f64().unwrap());
        assert!((pc - pg).abs() < 0.3, "{}: CPU {pc} dB, GPU {pg} dB", c["method"]);
        assert!(g["ms_warp"].as_f64().unwrap() > 0.0 && g["render_ms"].as_f64().unwrap() > 0.0, "{g}");
    }
}

#[test]
fn vr_rejects_bad_input_in_one_line() {
    let (_dir, d) = tmp("vrbad");
    let j = d.join("x.json");
    let js = j.to_str().unwrap();
    let small = ["--scale", "0.01", "--width", "64", "--height", "48", "--frames", "1", "--reps", "1"];
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["--ipd", "-0.01"], "--ipd"),
        (vec!["--ipd", "NaN"], "--ipd"),
        (vec!["--ipd", "inf"], "--ipd"),
        (vec!["--transparent", "1.5"], "--transparent"),
        (vec!["--transparent", "-0.1"], "--transparent"),
        (vec!["--transparent", "NaN"], "--transparent"),
        // Every object glass: no opaque surface to warp, and the error says why.
        (vec!["--transparent", "1"], "only transparent surfaces"),
        (vec!["--method", "splat"], "splat"),
        (vec!["--holes", "inpaint"], "inpaint"),
        (vec!["--strategy", "mono"], "mono"),
        (vec!["--abuffer", "maybe"], "maybe"),
        (vec!["--filter", "trilinear"], "trilinear"),
    ];
    for (extra, what) in cases {
        let mut args = vec!["vr", "--scene", "cb", "--json", js];
        args.extend(small);
        args.extend(extra.iter().copied());
        let (ok, _, err) = zwarp(&args);
        assert!(!ok, "{extra:?} accepted");
        let line = error_line(&err);
        assert!(line.contains(what), "{extra:?}: {line}");
        assert!(!err.contains("panicked"), "{err}");
    }
    assert!(!j.exists(), "no JSON is written on bad input");
}

/// Writes a glTF scene to `dir`: an opaque wall (z = 0, 4 x 4) behind a glass pane (z = 1,
/// 2 x 2, `alphaMode: BLEND`, alpha 0.5), and a camera path looking at them from z = 6.
fn glass_pane_scene(dir: &std::path::Path) -> (std::path::PathBuf, std::path::PathBuf) {
    let mut bin: Vec<u8> = Vec::new();
    for (s, z) in [(2.0f32, 0.0f32), (1.0, 1.0)] {
        for p in [[-s, -s, z], [s, -s, z], [s, s, z], [-s, s, z]] {
            p.iter().for_each(|v| bin.extend_from_slice(&v.to_le_bytes()));
        }
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    std::fs::write(dir.join("panes.bin"), &bin).unwrap();
    let json = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"mesh": 0, "name": "wall"}, {"mesh": 1, "name": "pane"}],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": 0}, "indices": 2, "material": 0}]},
            {"primitives": [{"attributes": {"POSITION": 1}, "indices": 2, "material": 1}]}
        ],
        "materials": [
            {"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1.0]}},
            {"alphaMode": "BLEND", "pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.6, 1.0, 0.5]}}
        ],
        "buffers": [{"byteLength": bin.len(), "uri": "panes.bin"}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 48},
            {"buffer": 0, "byteOffset": 96, "byteLength": 12}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-2.0, -2.0, 0.0], "max": [2.0, 2.0, 0.0]},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-1.0, -1.0, 1.0], "max": [1.0, 1.0, 1.0]},
            {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}
        ]
    });
    let scene = dir.join("panes.gltf");
    std::fs::write(&scene, serde_json::to_string(&json).unwrap()).unwrap();
    let path = dir.join("panes.path.json");
    let keys = serde_json::json!({
        "fov_y_deg": 50.0, "near": 0.1, "far": 50.0, "up": [0.0, 1.0, 0.0], "fps": 30.0,
        "keys": [{"t": 0.0, "eye": [0.0, 0.0, 6.0], "target": [0.0, 0.0, 0.0]},
                 {"t": 1.0, "eye": [0.6, 0.0, 6.0], "target": [0.0, 0.0, 0.0]}]
    });
    std::fs::write(&path, serde_json::to_string(&keys).unwrap()).unwrap();
    (scene, path)
}

#[test]
fn vr_puts_the_files_blend_materials_in_the_a_buffer() {
    let (_dir, d) = tmp("vrblend");
    let (scene, path) = glass_pane_scene(&d);
    let j = d.join("vr.json");
    let (ok, out, err) = zwarp(&[
        "vr",
        "--scene",
        scene.to_str().unwrap(),
        "--path",
        path.to_str().unwrap(),
        "--width",
        "64",
        "--height",
        "48",
        "--frames",
        "1",
        "--reps",
        "1",
        "--method",
        "grid",
        "--holes",
        "lowpass",
        "--strategy",
        "cyclops",
        "--json",
        j.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    assert!(out.contains("0 transparent (1 objects)"), "{out}");
    let rows = json_rows(&j);
    assert_eq!(rows.iter().filter(|r| r["abuffer"] == true).count(), 2, "{rows:?}");
    assert_eq!(rows.iter().filter(|r| r["abuffer"] == false).count(), 2, "{rows:?}");
    for r in rows.iter().filter(|r| r["abuffer"] == true) {
        assert!(r["ms_abuffer"].as_f64().unwrap() > 0.0, "{r}");
    }
}

#[test]
fn vr_with_transparency_gives_rows_with_and_without_the_a_buffer() {
    let (_dir, d) = tmp("vrglass");
    let j = d.join("vr.json");
    let (ok, out, err) =
        vr_small(&["--method", "grid", "--holes", "lowpass", "--strategy", "cyclops", "--transparent", "0.5"], &j);
    assert!(ok, "{err}");
    assert!(out.contains("transparent"), "{out}");
    let rows = json_rows(&j);
    assert_eq!(rows.len(), 4, "{rows:?}");
    for r in &rows {
        let on = r["abuffer"].as_bool().unwrap();
        let ms = r["ms_abuffer"].as_f64().unwrap();
        assert!(if on { ms > 0.0 } else { ms == 0.0 }, "{r}");
        assert_eq!(r["transparent"].as_f64().unwrap(), 0.5);
    }
    assert_eq!(rows.iter().filter(|r| r["abuffer"] == true).count(), 2);
    // Only the A-buffer rows: --abuffer on.
    let (ok, _, err) = vr_small(
        &[
            "--method",
            "points",
            "--holes",
            "stretch",
            "--strategy",
            "alternate",
            "--transparent",
            "0.5",
            "--abuffer",
            "on",
        ],
        &j,
    );
    assert!(ok, "{err}");
    assert!(json_rows(&j).iter().all(|r| r["abuffer"] == true));
}

/// An OBJ of a ground quad and three boxes (one object each), every coordinate a multiple of
/// 0.25 so that it stays exact in `f32` when moved by `offset` (x, z) up to 2^22, with its
/// bounds centred on the origin; and a two-key camera path walking past them, moved likewise.
fn offset_scene(dir: &std::path::Path, name: &str, offset: (f64, f64)) -> (String, String) {
    let mut obj = String::new();
    let mut base = 1;
    let mut cuboid = |obj: &mut String, name: &str, lo: [f64; 3], hi: [f64; 3]| {
        obj.push_str(&format!("o {name}\n"));
        for k in 0..8 {
            let c = |i: usize| if k >> i & 1 == 0 { lo[i] } else { hi[i] };
            obj.push_str(&format!("v {} {} {}\n", c(0) + offset.0, c(1), c(2) + offset.1));
        }
        for f in [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]] {
            obj.push_str(&format!("f {} {} {} {}\n", base + f[0], base + f[1], base + f[2], base + f[3]));
        }
        base += 8;
    };
    cuboid(&mut obj, "ground", [-20.0, -0.5, -20.0], [20.0, 0.0, 20.0]);
    cuboid(&mut obj, "a", [-3.25, 0.0, -2.0], [-1.0, 4.5, 0.75]);
    cuboid(&mut obj, "b", [1.5, 0.0, 2.25], [3.75, 2.5, 4.0]);
    cuboid(&mut obj, "c", [-6.0, 0.0, 5.5], [-4.75, 7.25, 6.5]);
    let key = |t: f64, eye: [f64; 3], target: [f64; 3]| {
        format!(
            r#"{{"t": {t}, "eye": [{}, {}, {}], "target": [{}, {}, {}]}}"#,
            eye[0] + offset.0,
            eye[1],
            eye[2] + offset.1,
            target[0] + offset.0,
            target[1],
            target[2] + offset.1
        )
    };
    let path = format!(
        r#"{{"fov_y_deg": 60, "near": 0.1, "far": 200, "up": [0, 1, 0], "fps": 30, "keys": [{}, {}]}}"#,
        key(0.0, [-12.5, 2.0, -14.25], [0.5, 1.5, 0.0]),
        key(1.0, [-8.5, 2.0, -15.0], [1.0, 1.5, 0.5])
    );
    let (o, p) = (dir.join(format!("{name}.obj")), dir.join(format!("{name}.path.json")));
    std::fs::write(&o, obj).unwrap();
    std::fs::write(&p, path).unwrap();
    (o.to_str().unwrap().to_string(), p.to_str().unwrap().to_string())
}

#[test]
fn a_scene_far_from_its_files_origin_renders_as_at_the_origin() {
    // Geo-referenced coordinates (4,000 km east, 2,500 km north): without recentring, f32 depth
    // pushed every pixel beyond the far plane (0 % covered).
    let (_dir, d) = tmp("offset");
    let mut outs = Vec::new();
    for (name, offset) in [("here", (0.0, 0.0)), ("there", (4.0e6, 2.5e6))] {
        let (obj, path) = offset_scene(&d, name, offset);
        let out_dir = d.join(format!("out_{name}"));
        let (ok, out, err) = zwarp(&[
            "render",
            "--scene",
            &obj,
            "--path",
            &path,
            "--frame",
            "1",
            "--width",
            "64",
            "--height",
            "48",
            "--out",
            out_dir.to_str().unwrap(),
        ]);
        assert!(ok, "{err}");
        let covered: f32 = out.split("% covered").next().and_then(|s| s.rsplit(' ').next()).unwrap().parse().unwrap();
        assert!(covered > 50.0, "{name}: {out}");
        outs.push(out_dir);
    }
    for f in ["depth.exr", "items.png", "motion.exr", "color.exr"] {
        let (a, b) = (std::fs::read(outs[0].join(f)).unwrap(), std::fs::read(outs[1].join(f)).unwrap());
        assert!(a == b, "{f} differs between the scene at its origin and the one 4000 km away");
    }
}
