//! The report's page (`index.html`) and markdown summary (`RESULTS.md`) from a [`Report`]:
//! each section's tables (ours beside the paper's numbers), plots and figure strips, built once
//! as [`Block`]s and rendered to both formats.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde_json::Value;

use super::paper;
use super::plot::{self, Chart, Series};
use super::protocol::Section;
use super::{write_atomic, JobRecord, Report, Status};

/// A table: caption, header and rows of cells (a cell may hold several lines).
pub struct Tab {
    /// One line above the table saying what to look at.
    pub caption: String,
    /// Column names.
    pub header: Vec<String>,
    /// Rows of cells.
    pub rows: Vec<Vec<String>>,
}

/// A piece of a section.
pub enum Block {
    /// The command lines that produced the section.
    Commands(Vec<String>),
    /// A table.
    Table(Tab),
    /// A chart with its caption; `name` is its file name under `plots/`.
    Plot { name: String, chart: Chart, caption: String },
    /// A PNG under the report folder with its caption.
    Image { path: String, caption: String },
    /// A job that did not finish: what is missing and why.
    Missing(String),
}

// ---- reading rows ----------------------------------------------------------------------------

fn rows(j: &JobRecord) -> Vec<&Value> {
    j.result
        .as_ref()
        .and_then(|r| r.get("rows"))
        .and_then(Value::as_array)
        .map(|a| a.iter().collect())
        .unwrap_or_default()
}

/// A numeric field; the strings `inf` / `-inf` / `nan` of non-finite values; NaN if absent.
fn num(r: &Value, k: &str) -> f64 {
    match r.get(k) {
        Some(Value::Number(n)) => n.as_f64().unwrap_or(f64::NAN),
        Some(Value::String(s)) => match s.as_str() {
            "inf" => f64::INFINITY,
            "-inf" => f64::NEG_INFINITY,
            _ => f64::NAN,
        },
        Some(Value::Bool(b)) => *b as u8 as f64,
        _ => f64::NAN,
    }
}

fn text<'a>(r: &'a Value, k: &str) -> &'a str {
    r.get(k).and_then(Value::as_str).unwrap_or("")
}

fn ok_jobs(report: &Report, s: Section) -> impl Iterator<Item = &JobRecord> {
    report.section(s).filter(|j| j.status == Status::Ok)
}

fn f(x: f64, d: usize) -> String {
    if x.is_nan() {
        "-".into()
    } else if x.is_infinite() {
        "inf".into()
    } else {
        format!("{x:.d$}")
    }
}

fn pair(ssim: f64, psnr: f64) -> String {
    format!("{} / {}", f(ssim, 4), f(psnr, 2))
}

/// Ours (L = 1 or 4, N = 16, one sample per pixel, speed 1, T = 3) or a baseline at that L.
fn quality_row<'a>(rs: &[&'a Value], method: &str, l: usize) -> Option<&'a Value> {
    quality_row_m(rs, method, l, 1)
}

/// [`quality_row`] from an `m x m` multisampled source.
fn quality_row_m<'a>(rs: &[&'a Value], method: &str, l: usize, m: u32) -> Option<&'a Value> {
    rs.iter().copied().find(|r| {
        text(r, "method") == method
            && num(r, "l") == l as f64
            && num(r, "multisample") == m as f64
            && num(r, "speed") == 1.0
            && (method != "ours" || (num(r, "n") == 16.0 && num(r, "t") == 3.0))
    })
}

fn eval_row<'a>(rs: &[&'a Value], bound: &str, l: usize, n: u32) -> Option<&'a Value> {
    rs.iter().copied().find(|r| {
        text(r, "method") == "ours"
            && text(r, "bound") == bound
            && num(r, "l") == l as f64
            && num(r, "n") == n as f64
            && num(r, "t") == 3.0
            && num(r, "speed") == 1.0
    })
}

fn distinct(values: impl Iterator<Item = f64>) -> Vec<f64> {
    let mut v: Vec<f64> = values.filter(|x| x.is_finite()).collect();
    v.sort_by(|a, b| a.total_cmp(b));
    v.dedup();
    v
}

fn pngs(out: &Path, j: &JobRecord) -> Vec<String> {
    let Some(dir) = &j.images else { return Vec::new() };
    let mut v: Vec<String> = std::fs::read_dir(out.join(dir))
        .map(|rd| {
            rd.filter_map(|e| e.ok())
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| n.ends_with(".png"))
                .map(|n| format!("{dir}/{n}"))
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

// ---- sections --------------------------------------------------------------------------------

fn headline(report: &Report) -> Vec<Block> {
    let speed: Vec<&JobRecord> = ok_jobs(report, Section::BoundsSpeed).collect();
    let mut t = Tab {
        caption: "Ours against forward warping (L = 1, N = 16, T = 3) and the cost of the complete CPU prediction \
                  (bounds, search, hole fill) next to a depth render of the same view in the same run; the paper's \
                  ratio is REF over its tight-bound warp on a GTX 1080."
            .into(),
        header: [
            "scene",
            "ours SSIM / PSNR",
            "VFW",
            "AFW",
            "render / prediction",
            "paper render / prediction",
            "prediction / memory floor",
        ]
        .map(String::from)
        .to_vec(),
        rows: Vec::new(),
    };
    for j in ok_jobs(report, Section::Quality) {
        let rs = rows(j);
        let q = |m| quality_row(&rs, m, 1).map_or("-".into(), |r| pair(num(r, "ssim"), num(r, "psnr")));
        // Speed from the bounds/speed job (more repetitions of the same configuration) when it ran.
        let sp = speed.iter().find(|s| s.scene == j.scene).map(|s| rows(s));
        let ours = sp.as_ref().and_then(|rs| eval_row(rs, "oriented", 1, 16)).or_else(|| quality_row(&rs, "ours", 1));
        let paper_ratio = paper::table3_ref_ms(&j.scene)
            .zip(paper::table3_tight_ms(&j.scene, 1, 16))
            .map_or("-".into(), |(r, w)| f(r / w, 1));
        t.rows.push(vec![
            j.scene.clone(),
            q("ours"),
            q("vfw"),
            q("afw"),
            ours.map_or("-".into(), |r| f(num(r, "speedup"), 2)),
            paper_ratio,
            ours.map_or("-".into(), |r| {
                // The floor's bandwidth in that run: the ratio is relative to it.
                let gbps = num(r, "floor_gbps");
                let at = if gbps.is_finite() { format!(" at {} GB/s", f(gbps, 0)) } else { String::new() };
                format!("{}x{at}", f(num(r, "floor_ratio"), 0))
            }),
        ]);
    }
    if t.rows.is_empty() {
        return Vec::new();
    }
    vec![Block::Table(t)]
}

fn quality(report: &Report, out: &Path) -> Vec<Block> {
    let mut t = Tab {
        caption: "SSIM / PSNR (dB) on linear depth normalised by the reference's surface range (stricter than on the \
                  stored buffer), N = 16; second line: the paper's Table 1. Look for ours above VFW and AFW in \
                  every column. Strips: source | ours | VFW | AFW | reference | error (red: predicted nearer, blue: \
                  farther, full colour at 1 % of the depth range), depth in metres on the colour bars. Real \
                  scenes also from a 2 x 2 multisampled source (m = 2), where the residual is silhouette aliasing."
            .into(),
        header: ["scene", "ours L=1", "VFW L=1", "AFW L=1", "ours L=4", "VFW L=4", "AFW L=4", "ours L=4 m=2"]
            .map(String::from)
            .to_vec(),
        rows: Vec::new(),
    };
    let mut images = Vec::new();
    for j in ok_jobs(report, Section::Quality) {
        let rs = rows(j);
        let mut row = vec![j.scene.clone()];
        for l in [1, 4] {
            for m in ["ours", "vfw", "afw"] {
                let ours = quality_row(&rs, m, l).map_or("-".into(), |r| pair(num(r, "ssim"), num(r, "psnr")));
                let p =
                    paper::table1(&j.scene, m, l).map_or(String::new(), |(s, p)| format!("\npaper {s:.3} / {p:.1}"));
                row.push(format!("{ours}{p}"));
            }
        }
        row.push(quality_row_m(&rs, "ours", 4, 2).map_or("-".into(), |r| pair(num(r, "ssim"), num(r, "psnr"))));
        t.rows.push(row);
        for p in pngs(out, j) {
            let l = p
                .rsplit('/')
                .next()
                .and_then(|n| n.split("_l").nth(1))
                .and_then(|t| t.split('_').next())
                .unwrap_or("?");
            let m = p.rsplit("_m").next().and_then(|t| t.strip_suffix(".png")).unwrap_or("1");
            let samples = if m == "1" { String::new() } else { format!(", source {m} x {m} samples per pixel") };
            images.push(Block::Image { caption: format!("{}, L = {l}, N = 16{samples}", j.scene), path: p });
        }
    }
    let mut v = vec![Block::Table(t)];
    v.extend(images);
    v
}

fn bounds_speed(report: &Report) -> Vec<Block> {
    let jobs: Vec<&JobRecord> = ok_jobs(report, Section::BoundsSpeed).collect();
    let mut blocks = Vec::new();
    // Table 2 on MO as in the paper (else the first scene).
    if let Some(j) = jobs.iter().find(|j| j.scene == "mo").or(jobs.first()) {
        let rs = rows(j);
        let ns = distinct(rs.iter().map(|r| num(r, "n")));
        let ls = distinct(rs.iter().map(|r| num(r, "l")));
        let mut t = Tab {
            caption: format!(
                "{}: SSIM / PSNR gained by the tight bound (ours: the PCA-oriented tight bound) over the global one; \
                 second line: the paper's Table 2 (MO). Look for gains at every cell, largest at small N.",
                j.scene
            ),
            header: std::iter::once("L".to_string()).chain(ns.iter().map(|n| format!("N={n}"))).collect(),
            rows: Vec::new(),
        };
        for &l in &ls {
            let mut row = vec![f(l, 0)];
            for &n in &ns {
                let cell = match (
                    eval_row(&rs, "oriented", l as usize, n as u32),
                    eval_row(&rs, "global", l as usize, n as u32),
                ) {
                    (Some(a), Some(b)) => pair(num(a, "ssim") - num(b, "ssim"), num(a, "psnr") - num(b, "psnr")),
                    _ => "-".into(),
                };
                let p = if j.scene == "mo" {
                    paper::table2(l as usize, n as u32)
                        .map_or(String::new(), |(s, p)| format!("\npaper {s:.2} / {p:.2}"))
                } else {
                    String::new()
                };
                row.push(format!("{cell}{p}"));
            }
            t.rows.push(row);
        }
        blocks.push(Block::Table(t));
    }
    let mut chart = Chart {
        title: "render / prediction against N (L = 1, tight bound)".into(),
        x_label: "search seeds N".into(),
        y_label: "render time / prediction time".into(),
        log_x: true,
        series: Vec::new(),
    };
    for (ci, j) in jobs.iter().enumerate() {
        let rs = rows(j);
        let ns = distinct(rs.iter().map(|r| num(r, "n")));
        let ls = distinct(rs.iter().map(|r| num(r, "l")));
        let mut t = Tab {
            caption: format!(
                "{}: complete prediction time (tight bound), its ratio to the depth render of the same run, its \
                 distance from the streaming memory floor of its inputs, and the paper's render/warp ratio (Table 3).",
                j.scene
            ),
            header: std::iter::once("L".to_string()).chain(ns.iter().map(|n| format!("N={n}"))).collect(),
            rows: Vec::new(),
        };
        for &l in &ls {
            let mut row = vec![f(l, 0)];
            for &n in &ns {
                let cell = eval_row(&rs, "oriented", l as usize, n as u32).map_or("-".into(), |r| {
                    let p = paper::table3_ref_ms(&j.scene)
                        .zip(paper::table3_tight_ms(&j.scene, l as usize, n as u32))
                        .map_or(String::new(), |(rf, w)| format!("\npaper x{}", f(rf / w, 1)));
                    format!(
                        "{} ms\nx{} render\n{}x floor{p}",
                        f(num(r, "warp_ms"), 1),
                        f(num(r, "speedup"), 2),
                        f(num(r, "floor_ratio"), 0)
                    )
                });
                row.push(cell);
            }
            t.rows.push(row);
        }
        blocks.push(Block::Table(t));
        let pts: Vec<(f64, f64)> =
            ns.iter().filter_map(|&n| eval_row(&rs, "oriented", 1, n as u32).map(|r| (n, num(r, "speedup")))).collect();
        chart.series.push(Series { name: format!("{} ours", j.scene), points: pts, dashed: false, color: ci });
        if let Some(rf) = paper::table3_ref_ms(&j.scene) {
            let pp: Vec<(f64, f64)> =
                ns.iter().filter_map(|&n| paper::table3_tight_ms(&j.scene, 1, n as u32).map(|w| (n, rf / w))).collect();
            if !pp.is_empty() {
                chart.series.push(Series { name: format!("{} paper", j.scene), points: pp, dashed: true, color: ci });
            }
        }
    }
    if !chart.series.is_empty() {
        blocks.push(Block::Plot {
            name: "render_over_prediction".into(),
            chart,
            caption: "Solid: zwarp on this CPU; dashed: the paper on a GTX 1080. Above 1 the prediction is cheaper \
                      than drawing the frame."
                .into(),
        });
    }
    blocks
}

fn iterations(report: &Report) -> Vec<Block> {
    let mut blocks = Vec::new();
    for j in ok_jobs(report, Section::Iterations) {
        let rs = rows(j);
        let speeds = distinct(rs.iter().map(|r| num(r, "speed")));
        let ts = distinct(rs.iter().map(|r| num(r, "t")));
        let at = |s: f64, t: f64| rs.iter().copied().find(|r| num(r, "speed") == s && num(r, "t") == t);
        let mut tab = Tab {
            caption: format!(
                "{}: PSNR (dB) and converged fraction against T and the motion speed (L = {}, N = {}). The paper: T = 2 \
                 suffices at 1-2x, 4x needs T = 4, 8x more than 8.",
                j.scene,
                rs.first().map_or("-".into(), |r| f(num(r, "l"), 0)),
                rs.first().map_or("-".into(), |r| f(num(r, "n"), 0)),
            ),
            header: std::iter::once("speed".to_string()).chain(ts.iter().map(|t| format!("T={t}"))).collect(),
            rows: Vec::new(),
        };
        let mut chart = Chart {
            title: format!("{}: PSNR against iterations T", j.scene),
            x_label: "iterations T".into(),
            y_label: "PSNR (dB)".into(),
            log_x: false,
            series: Vec::new(),
        };
        for (ci, &s) in speeds.iter().enumerate() {
            tab.rows.push(
                std::iter::once(format!("{s}x"))
                    .chain(ts.iter().map(|&t| {
                        at(s, t)
                            .map_or("-".into(), |r| format!("{}\n{}", f(num(r, "psnr"), 2), f(num(r, "converged"), 4)))
                    }))
                    .collect(),
            );
            chart.series.push(Series {
                name: format!("{s}x motion"),
                points: ts.iter().filter_map(|&t| at(s, t).map(|r| (t, num(r, "psnr")))).collect(),
                dashed: false,
                color: ci,
            });
        }
        blocks.push(Block::Table(tab));
        blocks.push(Block::Plot {
            name: format!("iterations_{}", j.scene),
            chart,
            caption: "Each line saturates once T is enough for that motion; faster motion needs more iterations."
                .into(),
        });
    }
    blocks
}

const CULL_METHODS: [&str; 7] = ["nocull", "vfc", "twophase", "woc", "awoc", "ideal", "ref"];

fn culling(report: &Report) -> Vec<Block> {
    let mut blocks = Vec::new();
    let mut t = Tab {
        caption: "Median frame time (ms: cull + draw of depth and ids of the kept objects) per method along the path; \
                  WOC culled % of the objects (of what REF culls), visible objects culled (errors), WOC over VFC; the \
                  paper's Table 5 (GTX 1080; CHC++ where we run two-phase HZB)."
            .into(),
        header: [
            "scene",
            "nocull",
            "vfc",
            "twophase",
            "woc",
            "awoc",
            "ideal",
            "ref",
            "WOC culled % (CR)",
            "culled visible",
            "VFC / WOC",
            "paper VFC / WOC",
            "paper ms nocull / vfc / chc++ / woc / ref",
        ]
        .map(String::from)
        .to_vec(),
        rows: Vec::new(),
    };
    let mut plots = Vec::new();
    for j in ok_jobs(report, Section::Culling) {
        let rs = rows(j);
        let by = |m: &str| rs.iter().copied().find(|r| text(r, "method") == m && num(r, "speed") == 1.0);
        let mut row = vec![j.scene.clone()];
        for m in CULL_METHODS {
            row.push(by(m).map_or("-".into(), |r| f(num(r, "frame_ms"), 1)));
        }
        let woc = by("woc");
        row.push(woc.map_or("-".into(), |r| {
            format!("{} ({})", f(100.0 * num(r, "culling_ratio"), 1), f(num(r, "culling_ratio_vs_ref"), 3))
        }));
        row.push(woc.map_or("-".into(), |r| f(num(r, "culled_visible"), 0)));
        row.push(woc.map_or("-".into(), |r| f(num(r, "speedup_vs_vfc"), 2)));
        row.push(
            paper::table5_ms(&j.scene, "vfc")
                .zip(paper::table5_ms(&j.scene, "woc"))
                .map_or("-".into(), |(v, w)| f(v / w, 2)),
        );
        row.push(
            ["nocull", "vfc", "chc++", "woc", "ref"]
                .iter()
                .map(|m| paper::table5_ms(&j.scene, m).map_or("-".into(), |v| f(v, 1)))
                .collect::<Vec<_>>()
                .join(" / "),
        );
        t.rows.push(row);
        let mut chart = Chart {
            title: format!("{}: culling ratio over frames", j.scene),
            x_label: "frame".into(),
            y_label: "objects culled (fraction)".into(),
            log_x: false,
            series: Vec::new(),
        };
        for (ci, m) in CULL_METHODS.iter().enumerate() {
            let Some(r) = by(m) else { continue };
            let pts: Vec<(f64, f64)> = r
                .get("frames_detail")
                .and_then(Value::as_array)
                .map(|a| a.iter().map(|d| (num(d, "frame"), num(d, "culling_ratio"))).collect())
                .unwrap_or_default();
            if !pts.is_empty() {
                chart.series.push(Series { name: m.to_string(), points: pts, dashed: false, color: ci });
            }
        }
        if !chart.series.is_empty() {
            plots.push(Block::Plot {
                name: format!("culling_{}", j.scene),
                chart,
                caption: "WOC and AWOC should sit near REF (the truth) and well above VFC on every frame.".into(),
            });
        }
    }
    blocks.push(Block::Table(t));
    blocks.extend(plots);
    blocks
}

fn shadows(report: &Report, out: &Path) -> Vec<Block> {
    let mut blocks = Vec::new();
    for j in ok_jobs(report, Section::Shadows) {
        let rs = rows(j);
        let z: Vec<&Value> = rs.iter().copied().filter(|r| text(r, "method") == "zwarp").collect();
        let ss = distinct(z.iter().map(|r| num(r, "samples")));
        let sms = distinct(z.iter().map(|r| num(r, "sm")));
        let at = |m: &str, s: f64, sm: f64| {
            rs.iter().copied().find(|r| text(r, "method") == m && num(r, "samples") == s && num(r, "sm") == sm)
        };
        let mut t = Tab {
            caption: format!(
                "{}: speed-up of zwarp's warped shadow maps over rendering S maps (same run), SSIM against the \
                 reference of the same S, PCSS's SSIM; second line: the paper's Table 8 speed-up.",
                j.scene
            ),
            header: std::iter::once("map".to_string()).chain(ss.iter().map(|s| format!("S={s}"))).collect(),
            rows: Vec::new(),
        };
        let mut chart = Chart {
            title: format!("{}: soft-shadow speed-up against S", j.scene),
            x_label: "light samples S".into(),
            y_label: "reference time / zwarp time".into(),
            log_x: true,
            series: Vec::new(),
        };
        for (ci, &sm) in sms.iter().enumerate() {
            let mut row = vec![format!("{sm}^2")];
            for &s in &ss {
                let cell = at("zwarp", s, sm).map_or("-".into(), |r| {
                    let p = paper::table8_speedup(&j.scene, sm as u32, s as u32)
                        .map_or(String::new(), |v| format!("\npaper x{v}"));
                    let pcss = at("pcss", s, sm).map_or("-".into(), |q| f(num(q, "ssim"), 4));
                    format!("x{}\nSSIM {}\nPCSS {pcss}{p}", f(num(r, "speedup"), 1), f(num(r, "ssim"), 4))
                });
                row.push(cell);
            }
            t.rows.push(row);
            chart.series.push(Series {
                name: format!("ours {sm}"),
                points: ss.iter().filter_map(|&s| at("zwarp", s, sm).map(|r| (s, num(r, "speedup")))).collect(),
                dashed: false,
                color: ci,
            });
            let pp: Vec<(f64, f64)> = ss
                .iter()
                .filter_map(|&s| paper::table8_speedup(&j.scene, sm as u32, s as u32).map(|v| (s, v)))
                .collect();
            if !pp.is_empty() {
                chart.series.push(Series { name: format!("paper {sm}"), points: pp, dashed: true, color: ci });
            }
        }
        blocks.push(Block::Table(t));
        blocks.push(Block::Plot {
            name: format!("shadows_{}", j.scene),
            chart,
            caption: "Solid: ours (CPU), dashed: the paper (GTX 1080). The gain grows with S: one warp serves many \
                      samples."
                .into(),
        });
        // The shaded image of the largest S (the paper's showcase), beside the reference of that S.
        let images = pngs(out, j);
        let samples_of = |p: &str| {
            p.rsplit('/')
                .next()
                .and_then(|n| n.split("_s").nth(1))
                .and_then(|t| t.split('_').next()?.parse::<u32>().ok())
        };
        let shaded = |m: &str| {
            images
                .iter()
                .filter(|p| p.contains(m) && !p.contains("diff") && !p.contains("vis"))
                .max_by_key(|p| samples_of(p))
        };
        for (m, what) in [("zwarp", "zwarp's warped shadow maps"), ("reference", "the reference (S rendered maps)")] {
            if let Some(p) = shaded(m) {
                blocks.push(Block::Image {
                    caption: format!("{}: shaded with {what}, {}", j.scene, file_stem(p)),
                    path: p.clone(),
                });
            }
        }
    }
    blocks
}

fn colour(report: &Report, out: &Path) -> Vec<Block> {
    let mut t = Tab {
        caption:
            "Colour warping against rendering the frame it replaces (same run): luminance PSNR / SSIM, FLIP (lower \
                  is better), warp and render ms, speed-up; the paper's speed-up is its forward render over each \
                  reprojection on Sponza at 720p (GTX 580)."
                .into(),
        header: [
            "command",
            "scene",
            "method",
            "variant",
            "PSNR",
            "SSIM",
            "FLIP",
            "warp ms",
            "render ms",
            "speed-up",
            "paper speed-up (seed 001 Table 1)",
        ]
        .map(String::from)
        .to_vec(),
        rows: Vec::new(),
    };
    let mut images = Vec::new();
    for j in ok_jobs(report, Section::Colour) {
        let cmd = j.result.as_ref().and_then(|r| r.get("command")).and_then(Value::as_str).unwrap_or("").to_string();
        for r in rows(j) {
            let variant = ["mode", "factor", "strategy", "eye", "motion"]
                .iter()
                .filter_map(|k| match r.get(*k) {
                    Some(Value::String(s)) => Some(s.clone()),
                    Some(Value::Number(n)) if *k == "factor" => Some(format!("x{n}")),
                    Some(Value::Bool(true)) if *k == "motion" => Some("motion+defocus".into()),
                    _ => None,
                })
                .collect::<Vec<_>>()
                .join(" ");
            let warp = if r.get("warp_ms").is_some() { num(r, "warp_ms") } else { num(r, "ms") };
            t.rows.push(vec![
                cmd.clone(),
                j.scene.clone(),
                text(r, "method").to_string(),
                variant,
                f(num(r, "psnr"), 2),
                f(num(r, "ssim"), 4),
                f(num(r, "flip"), 4),
                f(warp, 1),
                f(num(r, "render_ms"), 1),
                f(num(r, "speedup"), 2),
                if cmd == "upsample" || cmd == "stereo" {
                    paper::seed001_speedup(text(r, "method")).unwrap_or("-").to_string()
                } else {
                    "-".into()
                },
            ]);
        }
        // The images that compare methods at a glance: strips when the command writes them, else
        // the robust / heuristic warp and the reference.
        let all = pngs(out, j);
        let strips: Vec<&String> = all.iter().filter(|p| p.contains("strip")).collect();
        let chosen: Vec<&String> = if strips.is_empty() {
            all.iter()
                .filter(|p| {
                    let n = file_stem(p);
                    (n.ends_with("robust") || n.ends_with("heuristic") || n.ends_with("reference"))
                        && !n.contains("flip")
                })
                .collect()
        } else {
            strips
        };
        for p in chosen.into_iter().take(4) {
            images.push(Block::Image { caption: format!("{cmd} on {}: {}", j.scene, file_stem(p)), path: p.clone() });
        }
    }
    let mut v = vec![Block::Table(t)];
    v.extend(images);
    v
}

fn vr(report: &Report, out: &Path) -> Vec<Block> {
    let mut t = Tab {
        caption: "Both eyes warped from one view (cyclops) or from the previous frame's other eye (alternate) against \
                  rendering each eye (same run): PSNR, PSNR over the pixels the source did not see (holes), SSIM, \
                  FLIP (lower is better), primitives drawn, warp (all stages) and render ms. Filter: the grid's \
                  colour fetch, bilinear (default) or the paper's adaptive one (nearest across discontinuities). Paper (seed 003, Sponza): Table 1 PSNR Didyk \
                  35.63 vs grid 35.83; Table 2 hole filling PSNR rubber 35.45 / stretch 37.41 / low-pass 37.63; \
                  Fig. 7 SSIM opaque-only 0.885, A-buffer ray casting 0.975."
            .into(),
        header: [
            "scene",
            "method",
            "strategy",
            "holes",
            "filter",
            "A-buffer",
            "eye",
            "PSNR",
            "PSNR holes",
            "SSIM",
            "FLIP",
            "primitives",
            "warp ms",
            "render ms",
            "speed-up",
        ]
        .map(String::from)
        .to_vec(),
        rows: Vec::new(),
    };
    let mut images = Vec::new();
    for j in ok_jobs(report, Section::Vr) {
        for r in rows(j) {
            t.rows.push(vec![
                j.scene.clone(),
                text(r, "method").to_string(),
                text(r, "strategy").to_string(),
                text(r, "holes").to_string(),
                text(r, "filter").to_string(),
                if num(r, "abuffer") == 1.0 { "on".into() } else { "off".into() },
                text(r, "eye").to_string(),
                f(num(r, "psnr"), 2),
                f(num(r, "psnr_holes"), 2),
                f(num(r, "ssim"), 4),
                f(num(r, "flip"), 4),
                f(num(r, "primitives"), 0),
                f(num(r, "warp_ms"), 1),
                f(num(r, "render_ms"), 1),
                f(num(r, "speedup"), 2),
            ]);
        }
        // The grid method's cells drawn over the source (Fig. 12-13) and its eyes as anaglyphs.
        let grid_method = |p: &str| p.contains("_grid_") || p.contains("_grid-");
        let shown = |p: &str| p.ends_with("_grid.png") || p.ends_with("lowpass_anaglyph.png");
        for p in pngs(out, j).into_iter().filter(|p| grid_method(p) && shown(p)).take(4) {
            images.push(Block::Image { caption: format!("vr on {}: {}", j.scene, file_stem(&p)), path: p });
        }
    }
    let mut v = vec![Block::Table(t)];
    v.extend(images);
    v
}

fn file_stem(p: &str) -> String {
    Path::new(p).file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default()
}

fn missing(report: &Report, s: Section) -> Vec<Block> {
    report
        .section(s)
        .filter(|j| j.status != Status::Ok)
        .map(|j| match j.status {
            Status::Failed => Block::Missing(format!(
                "{} failed: {} (log: logs/{}.log)",
                j.id,
                j.error.as_deref().unwrap_or("error"),
                j.id
            )),
            _ => Block::Missing(format!("{} did not run (the report stopped before it)", j.id)),
        })
        .collect()
}

/// Every section with jobs in the report, with its blocks.
pub fn sections(report: &Report, out: &Path) -> Vec<(Section, Vec<Block>)> {
    Section::ALL
        .iter()
        .copied()
        .filter(|s| report.section(*s).next().is_some())
        .map(|s| {
            let mut b = missing(report, s);
            let commands: Vec<String> = ok_jobs(report, s).map(|j| format!("zwarp {}", j.command.join(" "))).collect();
            if !commands.is_empty() {
                b.push(Block::Commands(commands));
            }
            if ok_jobs(report, s).next().is_some() {
                b.extend(match s {
                    Section::Quality => quality(report, out),
                    Section::BoundsSpeed => bounds_speed(report),
                    Section::Iterations => iterations(report),
                    Section::Culling => culling(report),
                    Section::Shadows => shadows(report, out),
                    Section::Colour => colour(report, out),
                    Section::Vr => vr(report, out),
                });
            }
            (s, b)
        })
        .collect()
}

// ---- rendering -------------------------------------------------------------------------------

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

fn html_table(t: &Tab) -> String {
    let cell = |c: &str| esc(c).replace('\n', "<br>");
    let mut h = format!("<p class=\"cap\">{}</p>\n<table>\n<tr>", esc(&t.caption));
    for c in &t.header {
        h.push_str(&format!("<th>{}</th>", cell(c)));
    }
    h.push_str("</tr>\n");
    for r in &t.rows {
        h.push_str("<tr>");
        for c in r {
            h.push_str(&format!("<td>{}</td>", cell(c)));
        }
        h.push_str("</tr>\n");
    }
    h.push_str("</table>\n");
    h
}

fn md_table(t: &Tab) -> String {
    let cell = |c: &str| c.replace('|', "\\|").replace('\n', "<br>");
    let mut m = format!("{}\n\n| {} |\n|", t.caption, t.header.iter().map(|c| cell(c)).collect::<Vec<_>>().join(" | "));
    m.push_str(&" --- |".repeat(t.header.len()));
    m.push('\n');
    for r in &t.rows {
        m.push_str(&format!("| {} |\n", r.iter().map(|c| cell(c)).collect::<Vec<_>>().join(" | ")));
    }
    m
}

fn machine_lines(report: &Report) -> Vec<String> {
    let m = &report.machine;
    vec![
        format!("zwarp {}, level `{}`: {}", report.zwarp, report.level, report.protocol),
        format!(
            "Machine: {}, {} CPU threads, {}, GPU adapters: {}; load average (1, 5, 15 min) at start {}{}",
            m.cpu,
            m.threads,
            m.os,
            if m.adapters.is_empty() { "none".to_string() } else { m.adapters.join(", ") },
            m.load_average,
            m.load_average_end.as_ref().map_or(String::new(), |l| format!(", at the end {l}"))
        ),
        format!(
            "Started {}, {}. Every speed figure is a ratio to the alternative measured in the same run; GPU figures \
             (if any) are Mesa lavapipe, Vulkan on the CPU.",
            report.started,
            report
                .finished
                .as_ref()
                .map_or("not finished (sections below say what is missing)".to_string(), |f| format!("finished {f}"))
        ),
    ]
}

const CSS: &str = "body{font-family:system-ui,sans-serif;max-width:1400px;margin:2em auto;padding:0 1em;color:#222}\
table{border-collapse:collapse;margin:.5em 0 1.5em;font-size:13px}td,th{border:1px solid #ccc;padding:3px 6px;\
text-align:right;vertical-align:top}th{background:#f3f3f3}td:first-child{text-align:left}.cap{color:#444;max-width:1100px}\
.missing{color:#a00}figure{margin:1em 0}figcaption{color:#444;font-size:13px}img{max-width:100%;border:1px solid #ddd}\
code{background:#f3f3f3;padding:0 3px}";

/// Writes `index.html`, `plots/*.svg` and the markdown summary.
pub fn write(report: &Report, out: &Path, markdown: &Path) -> Result<()> {
    let secs = sections(report, out);
    let head = headline(report);
    std::fs::create_dir_all(out.join("plots"))
        .with_context(|| format!("{}: cannot create folder", out.join("plots").display()))?;
    let md_dir = markdown.parent().map(Path::to_path_buf).unwrap_or_else(|| PathBuf::from("."));
    std::fs::create_dir_all(&md_dir).with_context(|| format!("{}: cannot create folder", md_dir.display()))?;
    // Links from the markdown file to the report folder.
    let base = pathdiff::diff_paths(
        std::fs::canonicalize(out).unwrap_or_else(|_| out.to_path_buf()),
        std::fs::canonicalize(&md_dir).unwrap_or_else(|_| md_dir.clone()),
    )
    .unwrap_or_else(|| out.to_path_buf());
    let link = |rel: &str| {
        let p = base.join(rel);
        p.to_string_lossy().replace('\\', "/")
    };
    let mut html = format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>zwarp report</title><style>{CSS}</style></head><body>\n<h1>zwarp report</h1>\n"
    );
    let mut md = String::from(
        "# zwarp results\n\nGenerated by `zwarp report`; the page with plots is `index.html` in the report folder.\n\n",
    );
    let mut lines = machine_lines(report);
    lines.extend(report.reruns.iter().map(|r| format!("Run again separately: {r}.")));
    for l in lines {
        html.push_str(&format!("<p>{}</p>\n", esc(&l)));
        md.push_str(&format!("{l}\n\n"));
    }
    let missing: Vec<&str> =
        secs.iter().filter(|(_, b)| b.iter().any(|x| matches!(x, Block::Missing(_)))).map(|(s, _)| s.title()).collect();
    if !missing.is_empty() {
        let l = format!("Incomplete sections: {}.", missing.join("; "));
        html.push_str(&format!("<p class=\"missing\">{}</p>\n", esc(&l)));
        md.push_str(&format!("**{l}**\n\n"));
    }
    let mut all = vec![("Headline".to_string(), "headline".to_string(), head)];
    all.extend(secs.into_iter().map(|(s, b)| (s.title().to_string(), s.id().to_string(), b)));
    for (title, id, blocks) in all {
        if blocks.is_empty() {
            continue;
        }
        html.push_str(&format!("<h2 id=\"{id}\">{}</h2>\n", esc(&title)));
        md.push_str(&format!("## {title}\n\n"));
        for b in blocks {
            match b {
                Block::Commands(c) => {
                    html.push_str(&format!(
                        "<details><summary>commands</summary><pre>{}</pre></details>\n",
                        esc(&c.join("\n"))
                    ));
                    md.push_str(&format!("```sh\n{}\n```\n\n", c.join("\n")));
                }
                Block::Table(t) => {
                    html.push_str(&html_table(&t));
                    md.push_str(&md_table(&t));
                    md.push('\n');
                }
                Block::Plot { name, chart, caption } => {
                    let svg = plot::svg(&chart)?;
                    let file = format!("plots/{name}.svg");
                    write_atomic(&out.join(&file), &svg)?;
                    html.push_str(&format!(
                        "<figure class=\"plot\">{svg}<figcaption>{}</figcaption></figure>\n",
                        esc(&caption)
                    ));
                    md.push_str(&format!("![{}]({})\n\n{caption}\n\n", chart.title, link(&file)));
                }
                Block::Image { path, caption } => {
                    html.push_str(&format!(
                        "<figure><img src=\"{}\" alt=\"{}\"><figcaption>{}</figcaption></figure>\n",
                        esc(&path),
                        esc(&caption),
                        esc(&caption)
                    ));
                    md.push_str(&format!("![{caption}]({})\n\n", link(&path)));
                }
                Block::Missing(s) => {
                    html.push_str(&format!("<p class=\"missing\">{}</p>\n", esc(&s)));
                    md.push_str(&format!("*{s}*\n\n"));
                }
            }
        }
    }
    html.push_str("</body></html>\n");
    write_atomic(&out.join("index.html"), &html)?;
    write_atomic(markdown, &md)?;
    Ok(())
}
