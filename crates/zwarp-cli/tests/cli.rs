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

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("zwarp-cli-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The error is the last stderr line (lavapipe may print noise before it), starts with
/// `error:` and is a single line.
fn error_line(stderr: &str) -> String {
    let line = stderr.lines().filter(|l| l.starts_with("error")).last().unwrap_or("").to_string();
    assert!(line.starts_with("error: "), "no error line in: {stderr}");
    line
}

#[test]
fn missing_scene_file_is_a_clear_error() {
    let d = tmp("missing");
    let (ok, _, err) = zwarp(&["render", "--scene", "/nonexistent/model.obj", "--out", d.to_str().unwrap()]);
    assert!(!ok);
    assert!(error_line(&err).contains("/nonexistent/model.obj"), "{err}");
}

#[test]
fn unknown_format_is_a_clear_error() {
    let d = tmp("unknown");
    let f = d.join("scene.xyz");
    std::fs::write(&f, "not a mesh").unwrap();
    let (ok, _, err) = zwarp(&["render", "--scene", f.to_str().unwrap(), "--out", d.to_str().unwrap()]);
    assert!(!ok);
    assert!(error_line(&err).contains("scene.xyz"), "{err}");
}

#[test]
fn zero_size_image_is_rejected() {
    let d = tmp("zero");
    let (ok, _, err) =
        zwarp(&["render", "--scene", "mo", "--scale", "0.01", "--width", "0", "--out", d.to_str().unwrap()]);
    assert!(!ok);
    assert!(error_line(&err).contains("0x1080"), "{err}");
}

#[test]
fn bad_camera_paths_are_rejected() {
    let d = tmp("paths");
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
    let d = tmp("evalbad");
    let j = d.join("e.json");
    for (flag, value) in [("--n", "0"), ("--l", "0"), ("--bound", "loose"), ("--speed", "-1"), ("--holes", "magic")] {
        let (ok, _, err) =
            zwarp(&["eval", "--scene", "mo", "--scale", "0.01", flag, value, "--json", j.to_str().unwrap()]);
        assert!(!ok, "{flag} {value} accepted");
        error_line(&err);
    }
    assert!(!j.exists(), "no JSON is written on bad input");
}

#[test]
fn render_writes_every_buffer() {
    let d = tmp("render");
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
    let d = tmp("eval");
    let j = d.join("e.json");
    let (ok, _, err) = zwarp(&[
        "eval",
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
        "--n",
        "4",
        "--l",
        "1,2",
        "--reps",
        "1",
        "--json",
        j.to_str().unwrap(),
    ]);
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
            "warp_ms",
            "ref_ms",
            "speedup",
        ] {
            assert!(!r[k].is_null(), "field {k} missing in {r}");
        }
        let s = r["ssim"].as_f64().unwrap();
        assert!(s > 0.5 && s <= 1.0, "{r}");
        let sp = r["speedup"].as_f64().unwrap();
        let ratio = r["ref_ms"].as_f64().unwrap() / r["warp_ms"].as_f64().unwrap();
        assert!((sp - ratio).abs() < 1e-6 * ratio.max(1.0), "{r}");
    }
}

#[test]
fn cull_reference_and_nocull_are_exact() {
    let d = tmp("cull");
    let j = d.join("c.json");
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
        "nocull,vfc,woc,ref",
        "--json",
        j.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&j).unwrap()).unwrap();
    let rows = v["rows"].as_array().unwrap();
    let get = |m: &str| rows.iter().find(|r| r["method"] == m).unwrap_or_else(|| panic!("no {m} row")).clone();
    let (nocull, vfc, woc, reference) = (get("nocull"), get("vfc"), get("woc"), get("ref"));
    assert_eq!(nocull["culling_ratio"].as_f64().unwrap(), 0.0);
    assert_eq!(nocull["object_error"].as_f64().unwrap(), 0.0);
    assert_eq!(reference["object_error"].as_f64().unwrap(), 0.0);
    assert_eq!(reference["psnr_worst"], "inf");
    // REF culls at least as much as any safe method; WOC at least as much as VFC.
    let cr = |r: &serde_json::Value| r["culling_ratio"].as_f64().unwrap();
    assert!(cr(&reference) >= cr(&woc) - 1e-12 && cr(&woc) >= cr(&vfc) - 1e-12, "{rows:?}");
}

#[test]
fn shadows_writes_the_documented_fields() {
    let d = tmp("shadows");
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

/// `--backend gpu` runs the WGSL twin of the warp: same quality as the CPU on the same frames.
/// Runs where an adapter exists (lavapipe in CI, which sets `ZWARP_REQUIRE_GPU=1` so that a
/// missing adapter fails here instead of skipping).
#[test]
fn eval_gpu_backend_matches_cpu() {
    let require = std::env::var("ZWARP_REQUIRE_GPU").map(|v| v != "0" && !v.is_empty()).unwrap_or(false);
    let (ok, out, _) = zwarp(&["info"]);
    assert!(ok);
    if !out.contains("GPU adapter:") {
        assert!(!require, "ZWARP_REQUIRE_GPU is set but no GPU adapter was found:\n{out}");
        eprintln!("skipped: no GPU adapter");
        return;
    }
    let d = tmp("evalgpu");
    let mut ssim = Vec::new();
    for backend in ["cpu", "gpu"] {
        let j = d.join(format!("{backend}.json"));
        let (ok, _, err) = zwarp(&[
            "eval",
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
            "--n",
            "4",
            "--l",
            "1,2",
            "--methods",
            "ours",
            "--reps",
            "1",
            "--backend",
            backend,
            "--json",
            j.to_str().unwrap(),
        ]);
        assert!(ok, "{backend}: {err}");
        let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&j).unwrap()).unwrap();
        ssim.push(v["rows"].as_array().unwrap().iter().map(|r| r["ssim"].as_f64().unwrap()).collect::<Vec<_>>());
    }
    assert_eq!(ssim[0].len(), 2);
    for (c, g) in ssim[0].iter().zip(&ssim[1]) {
        assert!((c - g).abs() < 2e-3, "cpu {c} vs gpu {g}");
    }
}
