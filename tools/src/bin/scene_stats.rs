//! Prints object / triangle / mesh counts and load (generation) times of scenes.
//!
//! `cargo run --release -p zwarp-tools --bin scene_stats -- yr mo bl cb /path/to/sponza /path/to/munich`
//! Optional `--scale S`, `--seed N`, `--write-paths DIR` (writes `<name>.path.json`),
//! `--street` (files: street-level walk instead of the default flight), `--path FILE.json`,
//! `--split none|components|K` (triangle soups).

use std::time::Instant;

use zwarp_scene::{load_scene, motion_profile, street_level_path, CameraPath, SceneOptions, SplitMode};

fn main() {
    let mut opts = SceneOptions::default();
    let mut specs = Vec::new();
    let mut write_paths = None;
    let mut street = false;
    let mut path_file = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--scale" => opts.scale = args.next().and_then(|v| v.parse().ok()).expect("--scale needs a number"),
            "--seed" => opts.seed = args.next().and_then(|v| v.parse().ok()).expect("--seed needs an integer"),
            "--write-paths" => write_paths = args.next(),
            "--street" => street = true,
            "--split" => {
                opts.split = match args.next().as_deref() {
                    Some("none") => SplitMode::None,
                    Some("components") => SplitMode::Components,
                    Some(k) => SplitMode::Clusters(k.parse().expect("--split none|components|<clusters>")),
                    None => panic!("--split needs a value"),
                }
            }
            "--path" => path_file = args.next(),
            _ => specs.push(a),
        }
    }
    if specs.is_empty() {
        specs = ["yr", "mo", "bl", "cb"].map(String::from).to_vec();
    }
    println!(
        "| scene | objects | animated | ground | meshes | triangles | load ms (median of 3, min-max) | path s | motion px/frame 1080p mean-max / peak |"
    );
    println!("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |");
    for spec in &specs {
        let mut times = Vec::new();
        let mut last = None;
        for _ in 0..3 {
            let t0 = Instant::now();
            match load_scene(spec, &opts) {
                Ok(s) => last = Some(s),
                Err(e) => {
                    eprintln!("error: {e}");
                    std::process::exit(1);
                }
            }
            times.push(t0.elapsed().as_secs_f64() * 1e3);
        }
        times.sort_by(f64::total_cmp);
        let s = last.unwrap();
        let sc = &s.scene;
        let path = match (&path_file, &s.path) {
            (Some(f), _) => CameraPath::from_json_file_at(f, sc.origin).unwrap_or_else(|e| {
                eprintln!("error: {e}");
                std::process::exit(1)
            }),
            (None, Some(p)) => p.clone(),
            (None, None) if street => street_level_path(sc, 1.8, 1.4, 10.0, 1.0).unwrap_or_else(|e| {
                eprintln!("error: {e}");
                std::process::exit(1)
            }),
            (None, None) => CameraPath::default_for(sc),
        };
        let motion = motion_profile(sc, &path, 1920, 1080, 1.0).expect("motion profile");
        println!(
            "| {} | {} | {} | {} | {} | {} | {:.0} ({:.0}-{:.0}) | {:.1}{} | {:.1} / {:.1} |",
            sc.name,
            sc.instances.len(),
            sc.instances.iter().filter(|i| i.animation.is_animated()).count(),
            sc.instances.iter().filter(|i| i.is_ground).count(),
            sc.meshes.len(),
            sc.triangle_count(),
            times[1],
            times[0],
            times[2],
            path.duration(),
            if s.path.is_some() || path_file.is_some() {
                ""
            } else if street {
                " (street)"
            } else {
                " (default)"
            },
            motion.mean_max(),
            motion.peak(),
        );
        if let Some(dir) = &write_paths {
            let f = std::path::Path::new(dir).join(format!("{}.path.json", sc.name));
            path.write_json_file_at(&f, sc.origin).expect("write path");
        }
    }
}
