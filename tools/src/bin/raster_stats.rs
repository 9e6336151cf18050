//! Pipeline statistics of one scene (set-up vs raster split), for profiling. Reports process CPU
//! time (all threads, Linux schedstat) per call, which stays meaningful on a loaded machine.
//!
//! `cargo run --release -p zwarp-tools --bin raster_stats -- [SPEC]` with SPEC anything
//! `zwarp_scene::load_scene` accepts (default `/work/shared/scenes/sponza`). The camera is the
//! frame at 1/3 of the scene's path: the recorded one of the procedural scenes, the committed
//! `sponza_court.json` for a folder named `sponza`, else `CameraPath::default_for`.

use zwarp_scene::{load_scene, CameraPath, SceneOptions};

const SPONZA_COURT: &str = include_str!("../../../crates/zwarp-scene/paths/sponza_court.json");

fn cpu_ms() -> f64 {
    let mut total = 0u64;
    for t in std::fs::read_dir("/proc/self/task").unwrap() {
        let s = std::fs::read_to_string(t.unwrap().path().join("schedstat")).unwrap();
        total += s.split_whitespace().next().unwrap().parse::<u64>().unwrap();
    }
    total as f64 / 1e6
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

fn main() -> zwarp_core::Result<()> {
    let spec = std::env::args().nth(1).unwrap_or_else(|| "/work/shared/scenes/sponza".into());
    let loaded = load_scene(&spec, &SceneOptions::default())?;
    let is_sponza = std::path::Path::new(&spec)
        .canonicalize()
        .ok()
        .and_then(|c| c.file_name().map(|n| n.eq_ignore_ascii_case("sponza")))
        .unwrap_or(false);
    let path = match &loaded.path {
        Some(p) => p.clone(),
        None if is_sponza => CameraPath::from_json_str(SPONZA_COURT)?,
        None => CameraPath::default_for(&loaded.scene),
    };
    let t = path.start() + path.duration() / 3.0;
    let cam = path.camera_at(t, 1920, 1080)?;
    let s = &loaded.scene;
    let (a, b, c, _, _) = zwarp_raster::pipeline_stats(s, &cam, t)?;
    println!("source tris {a}, set-up tris {b}, bin entries {c}");
    let (mut full, mut setup) = (Vec::new(), Vec::new());
    for _ in 0..15 {
        let t0 = cpu_ms();
        std::hint::black_box(zwarp_raster::render_depth(s, &cam, t)?);
        let t1 = cpu_ms();
        std::hint::black_box(zwarp_raster::setup_only(s, &cam, t)?);
        let t2 = cpu_ms();
        full.push(t1 - t0);
        setup.push(t2 - t1);
    }
    let (f, st) = (median(full), median(setup));
    println!("CPU ms per depth render: {f:.2} (set-up {st:.2}, raster {:.2})", f - st);
    Ok(())
}
