//! `zwarp report`: runs the protocol of every table and figure zwarp reproduces (seed 000
//! Tables 1, 2, 3, 5, 8 and Fig. 11; seed 001's applications; seed 003's VR warps) and writes `DIR/index.html` (one
//! self-contained page: tables with the paper's numbers beside ours, inline SVG plots, figure
//! strips as PNG files next to it), `DIR/results.json` (every row of every command) and
//! `DIR/RESULTS.md` (the same tables for a repository).
//!
//! Each job is the `zwarp` command a user would type, run as a child process of this binary
//! with its output in `DIR/logs/<job>.log`; `results.json` and the page are rewritten after
//! every job, so an interrupted run keeps what finished and the page names what is missing.

mod page;
mod paper;
mod plot;
mod protocol;

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::Args;
use serde::{Deserialize, Serialize};

use protocol::{Job, SceneSpec};
pub use protocol::{Level, Section};

/// Arguments of `zwarp report`.
#[derive(Args, Clone, Debug)]
pub struct ReportArgs {
    /// Every section at reduced sizes and fewer frames (under 10 minutes on 2 cores; the
    /// default).
    #[arg(long, conflicts_with_all = ["full", "smoke"])]
    pub quick: bool,
    /// The papers' protocol (1920x1080, the paper's scene sizes, N, L, T, S and map sizes).
    #[arg(long, conflicts_with = "smoke")]
    pub full: bool,
    /// Tiny sizes on one reduced scene (seconds; for tests of the report itself).
    #[arg(long, hide = true)]
    pub smoke: bool,
    /// Output folder (created): index.html, results.json, RESULTS.md, images/, plots/, raw/, logs/.
    #[arg(long)]
    pub out: PathBuf,
    /// Scenes (comma list): the procedural `yr,mo,bl,cb` and any scene files or folders
    /// (glTF, OBJ, PLY, raw Sponza folders), which join every section that applies to them;
    /// `SCENE@PATH.json` gives a scene its camera path.
    #[arg(long, default_value = "yr,mo,bl,cb")]
    pub scenes: String,
    /// Only these sections (comma list of quality, bounds_speed, iterations, culling, shadows,
    /// colour, vr); default all. An earlier report of the same level in DIR keeps its other
    /// sections.
    #[arg(long)]
    pub sections: Option<String>,
    /// Rebuild index.html and RESULTS.md from DIR/results.json without running anything.
    #[arg(long)]
    pub page_only: bool,
    /// Write the markdown summary here instead of DIR/RESULTS.md (image links are made relative
    /// to it).
    #[arg(long)]
    pub markdown: Option<PathBuf>,
}

/// The machine a report ran on (stated on the page: timings depend on it).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Machine {
    /// CPU model name.
    pub cpu: String,
    /// Worker threads of the CPU backend (rayon).
    pub threads: usize,
    /// GPU adapters found (lavapipe is Mesa's Vulkan on the CPU), or none.
    pub adapters: Vec<String>,
    /// 1-, 5- and 15-minute load averages when the run started.
    pub load_average: String,
    /// The same when it finished (other work on the machine inflates and scatters timings).
    #[serde(default)]
    pub load_average_end: Option<String>,
    /// Operating system and architecture.
    pub os: String,
}

/// The state of one job in `results.json`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    /// Not run (yet): the run was interrupted or is still going.
    Pending,
    /// Ran and wrote its JSON.
    Ok,
    /// Exited with an error (see `error` and the log).
    Failed,
}

/// One job's record in `results.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct JobRecord {
    /// Job id (`quality_cb`).
    pub id: String,
    /// Section id (`quality`, ...).
    pub section: String,
    /// Scene label.
    pub scene: String,
    /// The command line (`zwarp` arguments, including `--json` / `--images`).
    pub command: Vec<String>,
    /// Pending, ok or failed.
    pub status: Status,
    /// Wall-clock seconds of the job.
    pub seconds: f64,
    /// The command's error line when it failed.
    pub error: Option<String>,
    /// Folder of the job's images, relative to the report folder.
    pub images: Option<String>,
    /// The JSON the command wrote (`{"command", "rows", ...}`).
    pub result: Option<serde_json::Value>,
}

/// `results.json`: the run's description and every job's rows.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Report {
    /// zwarp version.
    pub zwarp: String,
    /// `smoke`, `quick` or `full`.
    pub level: String,
    /// The level's sizes in words.
    pub protocol: String,
    /// The machine.
    pub machine: Machine,
    /// Start time (UTC, RFC 3339).
    pub started: String,
    /// End time, `None` while running or when interrupted.
    pub finished: Option<String>,
    /// Every planned job, in order.
    pub jobs: Vec<JobRecord>,
    /// Sections run again into this report by later `--sections` runs, with when and the load
    /// average then: the latest run of each section ("ids at time on cpu, load ...").
    #[serde(default)]
    pub reruns: Vec<String>,
}

impl Report {
    /// The records of `section`'s jobs.
    pub fn section(&self, section: Section) -> impl Iterator<Item = &JobRecord> {
        self.jobs.iter().filter(move |j| j.section == section.id())
    }
}

fn first_line_of(path: &str, key: &str) -> Option<String> {
    let text = std::fs::read_to_string(path).ok()?;
    text.lines().find(|l| l.starts_with(key)).and_then(|l| l.split(':').nth(1)).map(|s| s.trim().to_string())
}

/// What the machine is, read off the system (missing parts say "unknown").
pub fn machine() -> Machine {
    Machine {
        cpu: first_line_of("/proc/cpuinfo", "model name").unwrap_or_else(|| "unknown".into()),
        threads: rayon::current_num_threads(),
        adapters: zwarp_gpu::list_adapters()
            .into_iter()
            .map(|a| format!("{} ({}, {})", a.name, a.backend, a.device_type))
            .collect(),
        load_average: load_average(),
        load_average_end: None,
        os: format!("{} {}", std::env::consts::OS, std::env::consts::ARCH),
    }
}

fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|_| "unknown".into())
}

fn now() -> String {
    humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string()
}

/// Writes `text` to `path` through a temporary file in the same folder, so a reader never sees
/// a half-written file.
pub fn write_atomic(path: &Path, text: &str) -> Result<()> {
    let tmp = path.with_extension("tmp");
    std::fs::write(&tmp, text).with_context(|| format!("{}: cannot write", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("{}: cannot write", path.display()))?;
    Ok(())
}

fn parse_sections(list: &Option<String>) -> Result<Vec<Section>> {
    let Some(list) = list else { return Ok(Section::ALL.to_vec()) };
    crate::args::parse_list::<String>(list, "--sections")?
        .iter()
        .map(|s| {
            Section::ALL.iter().copied().find(|x| x.id() == s).with_context(|| {
                let ids: Vec<&str> = Section::ALL.iter().map(|x| x.id()).collect();
                format!("--sections: unknown section '{s}' (one of {})", ids.join(", "))
            })
        })
        .collect()
}

fn write_outputs(report: &Report, out: &Path, markdown: &Path) -> Result<()> {
    write_atomic(&out.join("results.json"), &serde_json::to_string_pretty(report)?)?;
    page::write(report, out, markdown)
}

/// `zwarp report`.
pub fn run(args: ReportArgs) -> Result<()> {
    let out = args.out.clone();
    std::fs::create_dir_all(&out).with_context(|| format!("--out {}: cannot create the folder", out.display()))?;
    // Fail now, not after an hour of measurements, when the folder is not writable.
    write_atomic(&out.join(".zwarp-report-probe"), "")
        .with_context(|| format!("--out {}: folder is not writable", out.display()))?;
    let _ = std::fs::remove_file(out.join(".zwarp-report-probe"));
    let markdown = args.markdown.clone().unwrap_or_else(|| out.join("RESULTS.md"));
    if args.page_only {
        let path = out.join("results.json");
        let text = std::fs::read_to_string(&path)
            .with_context(|| format!("{}: cannot read (run the report first)", path.display()))?;
        let report: Report =
            serde_json::from_str(&text).with_context(|| format!("{}: not a zwarp report", path.display()))?;
        page::write(&report, &out, &markdown)?;
        println!("wrote {} and {}", out.join("index.html").display(), markdown.display());
        return Ok(());
    }
    let level = if args.smoke {
        Level::Smoke
    } else if args.full {
        Level::Full
    } else {
        Level::Quick
    };
    let sections = parse_sections(&args.sections)?;
    let scenes: Vec<SceneSpec> =
        crate::args::parse_list::<String>(&args.scenes, "--scenes")?.iter().map(|s| SceneSpec::new(s)).collect();
    let jobs: Vec<Job> = protocol::jobs(level, &scenes).into_iter().filter(|j| sections.contains(&j.section)).collect();
    if jobs.is_empty() {
        bail!("no job to run: the sections chosen need a procedural scene (yr, mo, bl or cb)");
    }
    let exe = std::env::current_exe().context("cannot find the zwarp executable")?;
    for sub in ["raw", "logs", "images", "plots"] {
        std::fs::create_dir_all(out.join(sub))
            .with_context(|| format!("{}: cannot create folder", out.join(sub).display()))?;
    }
    let planned: Vec<JobRecord> = jobs
        .iter()
        .map(|j| JobRecord {
            id: j.id.clone(),
            section: j.section.id().to_string(),
            scene: j.scene.clone(),
            command: j.args.clone(),
            status: Status::Pending,
            seconds: 0.0,
            error: None,
            images: None,
            result: None,
        })
        .collect();
    let level_name = serde_json::to_value(level)?.as_str().unwrap_or("quick").to_string();
    // With --sections, an earlier report of the same level in DIR keeps its other sections: one
    // section can be run again (or added) without repeating the rest.
    let earlier: Option<Report> = args
        .sections
        .as_ref()
        .and_then(|_| std::fs::read_to_string(out.join("results.json")).ok())
        .and_then(|t| serde_json::from_str::<Report>(&t).ok())
        .filter(|r| r.level == level_name);
    let mut report = if let Some(mut r) = earlier {
        let ids: Vec<&str> = sections.iter().map(|s| s.id()).collect();
        r.jobs.retain(|j| !ids.contains(&j.section.as_str()));
        r.jobs.extend(planned);
        let order = |j: &JobRecord| Section::ALL.iter().position(|s| s.id() == j.section).unwrap_or(usize::MAX);
        r.jobs.sort_by_key(order);
        let m = machine();
        drop_reruns_of(&mut r.reruns, &ids);
        r.reruns.push(format!(
            "{} at {} on {} ({} threads), load average {}",
            ids.join(", "),
            now(),
            m.cpu,
            m.threads,
            load_average()
        ));
        r.finished = None;
        r
    } else {
        Report {
            zwarp: env!("CARGO_PKG_VERSION").to_string(),
            level: level_name,
            protocol: protocol::describe(level),
            machine: machine(),
            started: now(),
            finished: None,
            jobs: planned,
            reruns: Vec::new(),
        }
    };
    write_outputs(&report, &out, &markdown)?;
    println!(
        "zwarp report ({}): {} jobs, {}; machine: {}, {} threads, load {}",
        report.level,
        jobs.len(),
        report.protocol,
        report.machine.cpu,
        report.machine.threads,
        report.machine.load_average
    );
    let bar = indicatif::ProgressBar::new(jobs.len() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("report [{bar:30}] {pos}/{len} {elapsed} {msg}")?.progress_chars("=> "),
    );
    let mut failed = 0usize;
    for job in &jobs {
        bar.set_message(job.id.clone());
        let json = out.join("raw").join(format!("{}.json", job.id));
        let log_path = out.join("logs").join(format!("{}.log", job.id));
        let images = out.join("images").join(&job.id);
        // A job's outputs are its own run's, never a previous run's.
        let _ = std::fs::remove_file(&json);
        let _ = std::fs::remove_dir_all(&images);
        let mut argv = job.args.clone();
        argv.extend(["--json".to_string(), json.display().to_string()]);
        if job.images {
            argv.extend(["--images".to_string(), images.display().to_string()]);
        }
        let log = std::fs::File::create(&log_path).with_context(|| format!("{}: cannot write", log_path.display()))?;
        let t0 = Instant::now();
        let status = std::process::Command::new(&exe)
            .args(&argv)
            .stdout(log.try_clone()?)
            .stderr(log)
            .status()
            .with_context(|| format!("cannot start {}", exe.display()))?;
        let rec = report.jobs.iter_mut().find(|r| r.id == job.id).expect("every job has a record");
        rec.command = argv;
        rec.seconds = t0.elapsed().as_secs_f64();
        if status.success() {
            let text =
                std::fs::read_to_string(&json).with_context(|| format!("{}: the job wrote no JSON", json.display()))?;
            rec.result = Some(serde_json::from_str(&text).with_context(|| format!("{}: not JSON", json.display()))?);
            rec.status = Status::Ok;
            if job.images && images.is_dir() {
                rec.images = Some(format!("images/{}", job.id));
            }
        } else {
            failed += 1;
            let text = std::fs::read_to_string(&log_path).unwrap_or_default();
            let line = text.lines().rev().find(|l| l.starts_with("error:")).unwrap_or("exited with an error");
            rec.error = Some(line.trim_start_matches("error:").trim().to_string());
            rec.status = Status::Failed;
            bar.println(format!("{}: {} (log: {})", job.id, rec.error.as_deref().unwrap_or(""), log_path.display()));
        }
        write_outputs(&report, &out, &markdown)?;
        bar.inc(1);
    }
    bar.finish_and_clear();
    report.finished = Some(now());
    // A rerun of some sections records its load in `reruns`; the machine line keeps the run's.
    if report.reruns.is_empty() {
        report.machine.load_average_end = Some(load_average());
    }
    write_outputs(&report, &out, &markdown)?;
    println!(
        "wrote {}, {} and {}",
        out.join("index.html").display(),
        out.join("results.json").display(),
        markdown.display()
    );
    if failed > 0 {
        bail!("{failed} of {} jobs failed (their logs are in {})", jobs.len(), out.join("logs").display());
    }
    Ok(())
}

/// Removes sections `ids` from the rerun records (`"a, b at ..."`), dropping records left with
/// none: a section run again replaces its earlier record, so the report states what is, not
/// its history.
fn drop_reruns_of(reruns: &mut Vec<String>, ids: &[&str]) {
    reruns.retain_mut(|r| {
        let Some((sections, rest)) = r.split_once(" at ") else { return true };
        let left: Vec<&str> = sections.split(", ").filter(|s| !ids.contains(s)).collect();
        if left.is_empty() {
            return false;
        }
        *r = format!("{} at {rest}", left.join(", "));
        true
    });
}

#[cfg(test)]
mod tests {
    use super::drop_reruns_of;

    #[test]
    fn a_section_run_again_replaces_its_earlier_record() {
        let mut reruns = vec![
            "culling at t1 on cpu (2 threads), load average 1".to_string(),
            "quality, bounds_speed, culling at t2 on cpu (2 threads), load average 2".to_string(),
            "colour at t3 on cpu (2 threads), load average 3".to_string(),
        ];
        drop_reruns_of(&mut reruns, &["culling", "colour"]);
        assert_eq!(reruns, vec!["quality, bounds_speed at t2 on cpu (2 threads), load average 2".to_string()]);
        drop_reruns_of(&mut reruns, &["iterations"]);
        assert_eq!(reruns.len(), 1);
    }
}
