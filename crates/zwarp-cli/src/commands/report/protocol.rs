//! The protocol of every table and figure the report reproduces: which `zwarp` commands run,
//! with which arguments, at each level. `Full` is the papers' protocol (seed 000 Sec. 4-6:
//! 1920x1080, the paper's scene sizes, its N, L, T, S and map sizes); `Quick` keeps every
//! section at smaller sizes and fewer frames; `Smoke` is the tiny level the tests run.

use serde::Serialize;

/// How much of the papers' protocol to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Level {
    /// Tiny sizes, one reduced scene: exercises every section in seconds (tests).
    Smoke,
    /// Every section at reduced sizes (under 10 minutes on 2 cores).
    Quick,
    /// The papers' protocol.
    Full,
}

/// A part of the report: one paper table or figure (or one application).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Section {
    /// Seed 000 Table 1: quality of ours, VFW and AFW at L = 1 and 4, N = 16.
    Quality,
    /// Seed 000 Table 2 (tight vs global bound) and Table 3 (speed vs N, L and the render).
    BoundsSpeed,
    /// Seed 000 Fig. 11: iterations T against motion speed.
    Iterations,
    /// Seed 000 Table 5: occlusion culling frame times, and the culling ratio over frames.
    Culling,
    /// Seed 000 Table 8: soft-shadow speed-up against S and the shadow-map size.
    Shadows,
    /// Seed 001: frame-rate upsampling, stereo and blur by colour warping.
    Colour,
    /// Seed 003: hybrid image warping of both eyes (adaptive grid, hole filling, A-buffer).
    Vr,
}

impl Section {
    /// Every section, in page order.
    pub const ALL: [Section; 7] = [
        Section::Quality,
        Section::BoundsSpeed,
        Section::Iterations,
        Section::Culling,
        Section::Shadows,
        Section::Colour,
        Section::Vr,
    ];

    /// The section's heading on the page.
    pub fn title(self) -> &'static str {
        match self {
            Section::Quality => "Depth-warp quality against forward warping (seed 000 Table 1)",
            Section::BoundsSpeed => "Tight vs global bound and speed against the render (seed 000 Tables 2-3)",
            Section::Iterations => "Iterations against motion speed (seed 000 Fig. 11)",
            Section::Culling => "Occlusion culling (seed 000 Table 5)",
            Section::Shadows => "Soft shadows (seed 000 Table 8)",
            Section::Colour => "Colour warping: upsampling, stereo, blur (seed 001)",
            Section::Vr => "Stereo and VR: hybrid image warping of both eyes (seed 003)",
        }
    }

    /// Short id used in file names and `results.json`.
    pub fn id(self) -> &'static str {
        match self {
            Section::Quality => "quality",
            Section::BoundsSpeed => "bounds_speed",
            Section::Iterations => "iterations",
            Section::Culling => "culling",
            Section::Shadows => "shadows",
            Section::Colour => "colour",
            Section::Vr => "vr",
        }
    }
}

/// One command of the protocol.
#[derive(Clone, Debug, Serialize)]
pub struct Job {
    /// Unique id (`quality_cb`): names its JSON (`raw/<id>.json`), images and log.
    pub id: String,
    /// The section it feeds.
    pub section: Section,
    /// The scene label shown on the page (`cb`, or a file scene's name).
    pub scene: String,
    /// `zwarp` arguments without `--json` / `--images` (the runner adds them).
    pub args: Vec<String>,
    /// Whether the command takes `--images`.
    pub images: bool,
}

/// A scene of the report: a label, the `--scene` spec and optionally its camera path.
#[derive(Clone, Debug)]
pub struct SceneSpec {
    /// Label on the page.
    pub label: String,
    /// `--scene` argument.
    pub spec: String,
    /// `--path` argument (a camera path JSON), if given as `SCENE@PATH`.
    pub path: Option<String>,
    /// Procedural (paper 000's yr/mo/bl/cb, which the paper's tables name) or a file scene.
    pub procedural: bool,
}

impl SceneSpec {
    /// A scene from a `--scenes` entry, `SCENE` or `SCENE@PATH.json`: procedural names as they
    /// are, files by their stem.
    pub fn new(entry: &str) -> SceneSpec {
        let (spec, path) = match entry.rsplit_once('@') {
            Some((s, p)) if p.ends_with(".json") => (s, Some(p.to_string())),
            _ => (entry, None),
        };
        let procedural = matches!(spec, "yr" | "mo" | "bl" | "cb");
        let label = if procedural {
            spec.to_string()
        } else {
            let p = std::path::Path::new(spec.trim_end_matches('/'));
            p.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| spec.to_string())
        };
        SceneSpec { label, spec: spec.to_string(), path, procedural }
    }
}

/// Sizes, counts and lists of one level.
struct Sizes {
    eval: (u32, u32),
    frames: usize,
    reps: usize,
    ns: &'static str,
    ls: &'static str,
    speeds: &'static str,
    ts: &'static str,
    cull: (u32, u32),
    cull_frames: usize,
    shadows: (u32, u32),
    samples: &'static str,
    sm: &'static str,
    /// Timed runs per shadow measurement (the reference at S = 256 renders 256 maps per run).
    shadow_reps: usize,
    /// Untimed warm-up runs per shadow measurement (none at full: a warm-up would double the
    /// reference's hour-long part).
    shadow_warmup: usize,
    colour: (u32, u32),
    blur_samples: usize,
    /// `--scale` of the procedural scenes (1 = the paper's scene sizes).
    scale: f32,
}

fn sizes(level: Level) -> Sizes {
    match level {
        Level::Full => Sizes {
            eval: (1920, 1080),
            frames: 2,
            reps: 3,
            ns: "1,2,4,8,16,32",
            ls: "1,2,3,4",
            speeds: "1,2,4,8",
            ts: "1,2,3,4,6,8",
            cull: (1920, 1080),
            cull_frames: 24,
            shadows: (640, 360),
            samples: "4,16,64,256",
            sm: "512,1024,2048",
            shadow_reps: 1,
            shadow_warmup: 0,
            colour: (1280, 720),
            blur_samples: 64,
            scale: 1.0,
        },
        Level::Quick => Sizes {
            eval: (960, 540),
            frames: 1,
            reps: 1,
            ns: "1,4,16",
            ls: "1,3",
            speeds: "1,4",
            ts: "1,2,3,4",
            cull: (480, 270),
            cull_frames: 8,
            shadows: (320, 180),
            samples: "4,16",
            sm: "512",
            shadow_reps: 1,
            shadow_warmup: 1,
            colour: (480, 270),
            blur_samples: 8,
            scale: 1.0,
        },
        Level::Smoke => Sizes {
            eval: (64, 48),
            frames: 1,
            reps: 1,
            ns: "1,4",
            ls: "1,2",
            speeds: "1,2",
            ts: "1,3",
            cull: (64, 48),
            cull_frames: 3,
            shadows: (64, 48),
            samples: "4",
            sm: "64",
            shadow_reps: 1,
            shadow_warmup: 1,
            colour: (64, 48),
            blur_samples: 2,
            scale: 0.02,
        },
    }
}

/// A human-readable summary of the level's sizes, stated on the page.
pub fn describe(level: Level) -> String {
    let s = sizes(level);
    format!(
        "depth warping {}x{}, {} frame pair(s), median of {} timed run(s), N in {{{}}}, L in {{{}}}; \
         culling {}x{}, {} frames; shadows {}x{}, S in {{{}}}, maps {{{}}}, {} timed run(s) after {} warm-up(s); colour {}x{}; \
         procedural scenes at scale {} ({})",
        s.eval.0,
        s.eval.1,
        s.frames,
        s.reps,
        s.ns,
        s.ls,
        s.cull.0,
        s.cull.1,
        s.cull_frames,
        s.shadows.0,
        s.shadows.1,
        s.samples,
        s.sm,
        s.shadow_reps,
        s.shadow_warmup,
        s.colour.0,
        s.colour.1,
        s.scale,
        if s.scale == 1.0 { "the paper's sizes" } else { "reduced" },
    )
}

fn strings(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

/// Every hole fill of `zwarp vr` (seed 003 Table 2).
const HOLES: &str = "lowpass,rubber,stretch,pushpull";

/// The jobs of `level` on `scenes` (the smoke level keeps only the first scene).
pub fn jobs(level: Level, scenes: &[SceneSpec]) -> Vec<Job> {
    let s = sizes(level);
    let scenes: Vec<&SceneSpec> =
        if level == Level::Smoke { scenes.iter().take(1).collect() } else { scenes.iter().collect() };
    let size = |(w, h): (u32, u32)| strings(&["--width", &w.to_string(), "--height", &h.to_string()]);
    let scene_args = |sc: &SceneSpec| {
        let mut a = strings(&["--scene", &sc.spec]);
        if let Some(p) = &sc.path {
            a.extend(strings(&["--path", p]));
        }
        if sc.procedural {
            a.extend(strings(&["--scale", &s.scale.to_string()]));
        }
        a
    };
    let job = |id: String, section: Section, sc: &SceneSpec, cmd: &str, mut rest: Vec<String>, images: bool| {
        let mut args = vec![cmd.to_string()];
        args.extend(scene_args(sc));
        args.append(&mut rest);
        Job { id, section, scene: sc.label.clone(), args, images }
    };
    let frames = s.frames.to_string();
    let reps = s.reps.to_string();
    let mut out = Vec::new();
    for sc in &scenes {
        let mut a = size(s.eval);
        a.extend(strings(&[
            "--frames",
            &frames,
            "--reps",
            &reps,
            "--n",
            "16",
            "--l",
            "1,4",
            "--methods",
            "ours,vfw,afw",
        ]));
        // Real scenes: also from a 2 x 2 multisampled source, where the residual is silhouette
        // aliasing (seed 000 Sec. 7).
        if !sc.procedural {
            a.extend(strings(&["--multisample", "1,2"]));
        }
        out.push(job(format!("quality_{}", sc.label), Section::Quality, sc, "eval", a, true));
    }
    for sc in &scenes {
        let mut a = size(s.eval);
        a.extend(strings(&[
            "--frames",
            &frames,
            "--reps",
            &reps,
            "--n",
            s.ns,
            "--l",
            s.ls,
            "--bound",
            "global,oriented",
            "--methods",
            "ours",
        ]));
        out.push(job(format!("bounds_speed_{}", sc.label), Section::BoundsSpeed, sc, "eval", a, false));
    }
    // Fig. 11 is on CB in the paper; the first procedural scene given stands in otherwise.
    if let Some(sc) = scenes.iter().find(|sc| sc.label == "cb").or_else(|| scenes.iter().find(|sc| sc.procedural)) {
        let mut a = size(s.eval);
        a.extend(strings(&[
            "--frames",
            &frames,
            "--reps",
            "1",
            "--n",
            "8",
            "--l",
            "3",
            "--speed",
            s.speeds,
            "--t",
            s.ts,
            "--methods",
            "ours",
        ]));
        out.push(job(format!("iterations_{}", sc.label), Section::Iterations, sc, "eval", a, false));
    }
    for sc in &scenes {
        let mut a = size(s.cull);
        a.extend(strings(&[
            "--frames",
            &s.cull_frames.to_string(),
            "--method",
            "nocull,vfc,twophase,woc,awoc,ideal,ref",
            "--no-psnr",
        ]));
        out.push(job(format!("culling_{}", sc.label), Section::Culling, sc, "cull", a, false));
    }
    for sc in scenes.iter().filter(|sc| sc.procedural) {
        let mut a = size(s.shadows);
        a.extend(strings(&[
            "--samples",
            s.samples,
            "--sm",
            s.sm,
            "--reps",
            &s.shadow_reps.to_string(),
            "--warmup",
            &s.shadow_warmup.to_string(),
        ]));
        out.push(job(format!("shadows_{}", sc.label), Section::Shadows, sc, "shadows", a, true));
    }
    // Colour: on the first scene with colour detail everywhere (every scene has the triplanar
    // pattern) — the first file scene if one is given, else cb.
    // `zwarp vr` at the colour size on one frame, both strategies, with `methods` and `extra`.
    let vr_args = |methods: &str, extra: &[&str]| {
        let mut a = size(s.colour);
        a.extend(strings(&["--frames", "1", "--reps", &reps, "--method", methods, "--strategy", "cyclops,alternate"]));
        a.extend(strings(extra));
        a
    };
    let colour_scene = scenes
        .iter()
        .find(|sc| !sc.procedural)
        .or_else(|| scenes.iter().find(|sc| sc.label == "cb"))
        .or(scenes.first());
    if let Some(sc) = colour_scene {
        let cf = (s.frames + 1).to_string();
        let mut a = size(s.colour);
        a.extend(strings(&["--frames", &cf, "--reps", &reps, "--factor", "2"]));
        out.push(job(format!("upsample_{}", sc.label), Section::Colour, sc, "upsample", a, true));
        let mut a = size(s.colour);
        a.extend(strings(&["--frames", &cf, "--reps", &reps]));
        out.push(job(format!("stereo_{}", sc.label), Section::Colour, sc, "stereo", a, true));
        let mut a = size(s.colour);
        a.extend(strings(&[
            "--frames",
            "1",
            "--reps",
            "1",
            "--motion",
            "--defocus",
            "--samples",
            &s.blur_samples.to_string(),
        ]));
        out.push(job(format!("blur_{}", sc.label), Section::Colour, sc, "blur", a, true));
        // Seed 003 Tables 1-2 on the opaque scene, Fig. 7 with a fifth of the objects glass.
        let a = vr_args("grid,quads,points,didyk,fpi", &["--filter", "bilinear,adaptive", "--holes", HOLES]);
        out.push(job(format!("vr_{}", sc.label), Section::Vr, sc, "vr", a, true));
    }
    // On every other scene: frame-rate upsampling (seed 001's quality target holds per scene)
    // and Table 1 (the grid against Didyk et al.: primitives and PSNR).
    for sc in scenes.iter().copied().filter(|sc| colour_scene.is_none_or(|c| c.label != sc.label)) {
        let mut a = size(s.colour);
        a.extend(strings(&["--frames", &(s.frames + 1).to_string(), "--reps", &reps, "--factor", "2"]));
        out.push(job(format!("upsample_{}", sc.label), Section::Colour, sc, "upsample", a, false));
        let a = vr_args("grid,didyk", &["--filter", "bilinear,adaptive", "--holes", "lowpass"]);
        out.push(job(format!("vr_grid_{}", sc.label), Section::Vr, sc, "vr", a, false));
    }
    // Fig. 7 (A-buffer ray casting against warping the composited image) on every scene.
    for sc in scenes.iter().copied() {
        let a = vr_args("grid", &["--holes", "lowpass", "--transparent", "0.2", "--abuffer", "on,off"]);
        out.push(job(format!("vr_glass_{}", sc.label), Section::Vr, sc, "vr", a, false));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Fig. 7's glass rows run on every scene (the colour and VR tables on the first file scene,
    /// the grid-vs-Didyk rows on every other scene).
    #[test]
    fn glass_rows_run_on_every_scene() {
        let scenes: Vec<SceneSpec> =
            ["cb", "/data/sponza@p.json", "/data/city"].iter().map(|s| SceneSpec::new(s)).collect();
        let ids: Vec<String> = jobs(Level::Quick, &scenes).into_iter().map(|j| j.id).collect();
        let has = |id: &str| ids.iter().any(|i| i == id);
        assert!(has("vr_glass_sponza") && has("vr_glass_city") && has("vr_glass_cb"), "{ids:?}");
        assert!(has("vr_sponza") && !has("vr_city"), "{ids:?}");
        // The grid against Didyk et al. on every other scene.
        assert!(has("vr_grid_cb") && has("vr_grid_city") && !has("vr_grid_sponza"), "{ids:?}");
        // Upsampling on every scene: with images on the colour scene, rows only on the others.
        assert!(has("upsample_sponza") && has("upsample_cb") && has("upsample_city"), "{ids:?}");
        let procedural: Vec<SceneSpec> = ["yr", "cb"].iter().map(|s| SceneSpec::new(s)).collect();
        let ids: Vec<String> = jobs(Level::Quick, &procedural).into_iter().map(|j| j.id).collect();
        assert_eq!(
            ids.iter().filter(|i| i.starts_with("vr_glass_")).collect::<Vec<_>>(),
            ["vr_glass_yr", "vr_glass_cb"]
        );
    }

    #[test]
    fn every_section_has_jobs_at_every_level() {
        let scenes: Vec<SceneSpec> = ["yr", "mo", "bl", "cb"].iter().map(|s| SceneSpec::new(s)).collect();
        for level in [Level::Smoke, Level::Quick, Level::Full] {
            let jobs = jobs(level, &scenes);
            for section in Section::ALL {
                assert!(jobs.iter().any(|j| j.section == section), "{level:?} has no {section:?} job");
            }
            let mut ids: Vec<&str> = jobs.iter().map(|j| j.id.as_str()).collect();
            ids.sort();
            ids.dedup();
            assert_eq!(ids.len(), jobs.len(), "job ids are unique");
        }
        let full = jobs(Level::Full, &scenes);
        let q = full.iter().find(|j| j.id == "quality_cb").unwrap();
        assert!(q.args.windows(2).any(|w| w == ["--width", "1920"]));
        assert!(q.args.windows(2).any(|w| w == ["--scale", "1"]));
        assert_eq!(SceneSpec::new("/data/scenes/sponza/").label, "sponza");
        assert_eq!(SceneSpec::new("/data/temple.obj").label, "temple");
        let with_path = SceneSpec::new("/data/sponza@paths/court.json");
        assert_eq!((with_path.spec.as_str(), with_path.path.as_deref()), ("/data/sponza", Some("paths/court.json")));
        let q = jobs(Level::Quick, &[with_path]);
        assert!(q[0].args.windows(2).any(|w| w == ["--path", "paths/court.json"]));
    }
}
