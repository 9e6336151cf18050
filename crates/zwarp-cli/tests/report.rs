//! `zwarp report` end to end at its smoke level: every section runs and lands in
//! `results.json`, the page links only files that exist, an interrupted run's page names what
//! is missing, bad input gets one line, and the page renders in a real browser (headless
//! Chromium; skipped with a message when none is installed, a failure when
//! `ZWARP_REQUIRE_BROWSER=1`).

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

fn zwarp(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_zwarp")).args(args).output().expect("run zwarp");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// A path `name` that does not exist yet, in a fresh temp dir removed when the guard drops (also
/// when the test fails).
fn tmp(name: &str) -> (tempfile::TempDir, PathBuf) {
    let guard = tempfile::Builder::new().prefix("zwarp-report-test-").tempdir().unwrap();
    let d = guard.path().join(name);
    (guard, d)
}

/// One smoke report shared by the tests (it takes a few seconds), in cargo's scratch folder
/// for integration tests, replaced by the next run (a static is never dropped: a temp dir
/// would outlive every run).
fn smoke() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("zwarp-report-smoke");
        let _ = std::fs::remove_dir_all(&dir);
        let (ok, out, err) = zwarp(&["report", "--smoke", "--scenes", "cb", "--out", dir.to_str().unwrap()]);
        assert!(ok, "report failed:\n{out}\n{err}");
        dir
    })
}

fn results(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("results.json")).unwrap()).unwrap()
}

/// `src="..."` values of the page's `<img>` elements.
fn img_sources(html: &str) -> Vec<String> {
    html.split("<img src=\"").skip(1).map(|s| s.split('"').next().unwrap().to_string()).collect()
}

#[test]
fn every_section_runs_and_is_on_the_page() {
    let dir = smoke();
    let r = results(dir);
    assert!(r["finished"].is_string());
    assert_eq!(r["level"], "smoke");
    assert!(r["machine"]["threads"].as_u64().unwrap() >= 1);
    let jobs = r["jobs"].as_array().unwrap();
    for section in ["quality", "bounds_speed", "iterations", "culling", "shadows", "colour", "vr"] {
        let js: Vec<_> = jobs.iter().filter(|j| j["section"] == section).collect();
        assert!(!js.is_empty(), "no {section} job");
        for j in js {
            assert_eq!(j["status"], "ok", "{}: {}", j["id"], j["error"]);
            assert!(!j["result"]["rows"].as_array().unwrap().is_empty(), "{} has no rows", j["id"]);
        }
    }
    let html = std::fs::read_to_string(dir.join("index.html")).unwrap();
    for h in [
        "seed 000 Table 1",
        "seed 000 Tables 2-3",
        "seed 000 Fig. 11",
        "seed 000 Table 5",
        "seed 000 Table 8",
        "seed 001",
        "seed 003",
    ] {
        assert!(html.contains(h), "page lacks the section '{h}'");
    }
    // The paper's numbers sit beside ours (Table 1, CB, ours at L = 1: 0.994 / 31.3).
    assert!(html.contains("paper 0.994 / 31.3"));
    assert!(html.matches("<svg").count() >= 4, "plots are inlined");
    let imgs = img_sources(&html);
    assert!(imgs.len() >= 4, "figure strips are on the page: {imgs:?}");
    for src in &imgs {
        assert!(dir.join(src).is_file(), "page links a missing image {src}");
    }
    assert!(!html.contains("Incomplete sections"));
    let md = std::fs::read_to_string(dir.join("RESULTS.md")).unwrap();
    assert!(md.contains("| scene |") && md.contains("](plots/"), "markdown has tables and plot links");
}

#[test]
fn an_interrupted_run_keeps_its_rows_and_the_page_says_what_is_missing() {
    let (_dir, dir) = tmp("partial");
    std::fs::create_dir_all(&dir).unwrap();
    let mut r = results(smoke());
    // As the report leaves it when stopped after its first job.
    r["finished"] = serde_json::Value::Null;
    for j in r["jobs"].as_array_mut().unwrap().iter_mut().skip(1) {
        j["status"] = "pending".into();
        j["result"] = serde_json::Value::Null;
    }
    std::fs::write(dir.join("results.json"), serde_json::to_string(&r).unwrap()).unwrap();
    let (ok, _, err) = zwarp(&["report", "--page-only", "--out", dir.to_str().unwrap()]);
    assert!(ok, "{err}");
    let html = std::fs::read_to_string(dir.join("index.html")).unwrap();
    assert!(html.contains("Incomplete sections"));
    assert!(html.contains("culling_cb did not run"));
    assert!(html.contains("not finished"));
}

#[test]
fn one_section_runs_again_into_an_earlier_report() {
    let (_dir, dir) = tmp("rerun");
    std::fs::create_dir_all(&dir).unwrap();
    let before = results(smoke());
    std::fs::write(dir.join("results.json"), serde_json::to_string(&before).unwrap()).unwrap();
    let (ok, _, err) =
        zwarp(&["report", "--smoke", "--scenes", "cb", "--sections", "iterations", "--out", dir.to_str().unwrap()]);
    assert!(ok, "{err}");
    let after = results(&dir);
    let ids = |r: &serde_json::Value| -> Vec<String> {
        r["jobs"].as_array().unwrap().iter().map(|j| j["id"].as_str().unwrap().to_string()).collect()
    };
    // The same jobs in the same order, the other sections' rows untouched, the rerun stated.
    assert_eq!(ids(&before), ids(&after));
    let quality =
        |r: &serde_json::Value| r["jobs"].as_array().unwrap().iter().find(|j| j["section"] == "quality").cloned();
    assert_eq!(quality(&before), quality(&after));
    assert_eq!(after["reruns"].as_array().unwrap().len(), 1);
    assert!(std::fs::read_to_string(dir.join("index.html")).unwrap().contains("Run again separately: iterations"));
}

#[test]
fn bad_input_gets_one_line() {
    let (_dir, file) = tmp("file");
    let (_out, out) = tmp("out");
    std::fs::write(&file, "not a folder").unwrap();
    let under_file = file.join("out");
    for (args, expect) in [
        (vec!["report", "--smoke", "--out", under_file.to_str().unwrap()], "cannot create the folder"),
        (
            vec!["report", "--smoke", "--sections", "bogus", "--out", out.join("bad-section").to_str().unwrap()],
            "unknown section 'bogus'",
        ),
        (vec!["report", "--page-only", "--out", out.join("empty").to_str().unwrap()], "run the report first"),
        (
            vec![
                "report",
                "--smoke",
                "--scenes",
                "nosuch.obj",
                "--sections",
                "shadows",
                "--out",
                out.join("none").to_str().unwrap(),
            ],
            "no job to run",
        ),
    ] {
        let (ok, _, err) = zwarp(&args);
        assert!(!ok, "{args:?} should fail");
        assert!(err.contains(expect), "{args:?}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "one line: {err}");
    }
    // A failing job is reported by name, the others still run, and the exit is non-zero.
    let (_dir, dir) = tmp("failing");
    let (ok, _, err) = zwarp(&[
        "report",
        "--smoke",
        "--scenes",
        "nosuch.obj",
        "--sections",
        "quality",
        "--out",
        dir.to_str().unwrap(),
    ]);
    assert!(!ok);
    assert!(err.contains("1 of 1 jobs failed"), "{err}");
    let r = results(&dir);
    assert_eq!(r["jobs"][0]["status"], "failed");
    assert!(r["jobs"][0]["error"].as_str().unwrap().contains("nosuch.obj"));
    assert!(std::fs::read_to_string(dir.join("index.html")).unwrap().contains("quality_nosuch failed"));
}

fn chromium() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("ZWARP_CHROMIUM") {
        return Some(PathBuf::from(p));
    }
    ["/usr/bin/chromium", "/usr/bin/chromium-browser", "/usr/bin/google-chrome"]
        .iter()
        .map(PathBuf::from)
        .find(|p| p.is_file())
}

/// Headless Chromium with the flags a closed network and a root container need.
fn headless(browser: &Path, profile: &Path) -> Command {
    let mut c = Command::new(browser);
    c.args([
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--hide-scrollbars",
    ])
    .arg(format!("--user-data-dir={}", profile.display()));
    c
}

/// Records load errors of any element, script errors and console errors, and on load writes
/// what it found into `<pre id="zwarp-check">` for `--dump-dom` to show.
const CHECK_HEAD: &str = "<script>window.__errors=[];\
window.addEventListener('error',e=>window.__errors.push(String(e.message||(e.target&&(e.target.src||e.target.href))||'error')),true);\
const __ce=console.error;console.error=(...a)=>{window.__errors.push(a.join(' '));__ce(...a)};</script>";
const CHECK_TAIL: &str = "<script>window.addEventListener('load',()=>{const im=[...document.images];\
const p=document.createElement('pre');p.id='zwarp-check';p.textContent=JSON.stringify({images:im.length,\
broken:im.filter(i=>!(i.complete&&i.naturalWidth>0)).map(i=>i.src),svgs:document.querySelectorAll('svg').length,\
errors:window.__errors});document.body.appendChild(p);});</script>";

#[test]
fn the_page_renders_in_a_real_browser() {
    let Some(browser) = chromium() else {
        if std::env::var("ZWARP_REQUIRE_BROWSER").as_deref() == Ok("1") {
            panic!("ZWARP_REQUIRE_BROWSER=1 but no Chromium found (install Debian's chromium)");
        }
        eprintln!("skipped: no Chromium found (install Debian's `chromium` or set ZWARP_CHROMIUM)");
        return;
    };
    let dir = smoke();
    let html = std::fs::read_to_string(dir.join("index.html")).unwrap();
    let checked = html.replacen("<head>", &format!("<head>{CHECK_HEAD}"), 1).replacen(
        "</body>",
        &format!("{CHECK_TAIL}</body>"),
        1,
    );
    let check = dir.join("check.html");
    std::fs::write(&check, checked).unwrap();
    let url = format!("file://{}", check.canonicalize().unwrap().display());
    let (_profile_dir, profile) = tmp("chromium-profile");
    let out = headless(&browser, &profile)
        .args(["--virtual-time-budget=10000", "--dump-dom", &url])
        .output()
        .expect("run chromium");
    let dom = String::from_utf8_lossy(&out.stdout);
    let report =
        dom.split("<pre id=\"zwarp-check\">").nth(1).and_then(|s| s.split("</pre>").next()).unwrap_or_else(|| {
            panic!("the check script did not run; chromium said:\n{}", String::from_utf8_lossy(&out.stderr))
        });
    let report = report.replace("&lt;", "<").replace("&gt;", ">").replace("&quot;", "\"").replace("&amp;", "&");
    let v: serde_json::Value = serde_json::from_str(&report).unwrap();
    assert_eq!(v["images"].as_u64().unwrap() as usize, img_sources(&html).len());
    assert!(v["broken"].as_array().unwrap().is_empty(), "images that did not load: {}", v["broken"]);
    assert!(v["svgs"].as_u64().unwrap() >= 4, "plots rendered: {v}");
    assert!(v["errors"].as_array().unwrap().is_empty(), "console / load errors: {}", v["errors"]);
    // A screenshot of the page itself: not blank (text, tables, plots and images drawn).
    let shot = dir.join("screenshot.png");
    let page_url = format!("file://{}", dir.join("index.html").canonicalize().unwrap().display());
    let status = headless(&browser, &profile)
        .args(["--window-size=1280,2400", &format!("--screenshot={}", shot.display()), &page_url])
        .output()
        .expect("run chromium");
    assert!(shot.is_file(), "no screenshot: {}", String::from_utf8_lossy(&status.stderr));
    let img = zwarp_viz::read_png(&shot).unwrap();
    let non_white = img.data().iter().filter(|p| p.iter().any(|c| *c < 200)).count();
    let mut colours: Vec<[u8; 3]> = img.data().to_vec();
    colours.sort();
    colours.dedup();
    assert!(non_white as f64 > 0.02 * img.data().len() as f64, "screenshot is almost blank");
    assert!(colours.len() > 64, "screenshot has {} colours: images and plots did not draw", colours.len());
}
