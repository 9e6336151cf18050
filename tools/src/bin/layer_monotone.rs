//! Issue check "more layers never hurt" over `zwarp eval` JSON files: for every file, bound
//! kind, N and frame pair, where L = k + 1 is worse than L = k by more than 0.1 dB PSNR or
//! 0.0005 SSIM (the rows' `frames_detail`), and a count per bound kind.
//!
//! `layer_monotone FILE.json...` — the files from runs such as (960x540, 8 pairs, 1-4 layers,
//! about two minutes for the twelve configurations below on two cores):
//!
//! ```sh
//! for spec in "yr" "mo" "bl" "cb" \
//!   "../shared/scenes/sponza --path crates/zwarp-scene/paths/sponza_court.json" \
//!   "../shared/scenes/sponza --path crates/zwarp-scene/paths/sponza_near_wall.json" \
//!   "../shared/scenes/sponza --path crates/zwarp-scene/paths/sponza_near_wall.json --speed 2" \
//!   "../shared/scenes/sponza --path ../shared/scenes/sponza_colonnade.path.json" \
//!   "../shared/scenes/sponza --path ../shared/scenes/sponza_colonnade.path.json --speed 4" \
//!   "../shared/scenes/munich --path crates/zwarp-scene/paths/munich_street.json" \
//!   "../shared/scenes/munich --path crates/zwarp-scene/paths/munich_near_wall.json" \
//!   "../shared/scenes/munich --path crates/zwarp-scene/paths/munich_near_wall.json --speed 2"; do
//!   zwarp eval --scene $spec --width 960 --height 540 --frames 8 --reps 1 --n 4,16 \
//!     --l 1,2,3,4 --methods ours --json out/mono_$((i++)).json
//! done
//! ```

use std::collections::BTreeMap;

/// Per-frame quality of one row: (pair, PSNR, SSIM).
type Frames = Vec<(u64, f64, f64)>;

fn main() {
    let files: Vec<String> = std::env::args().skip(1).collect();
    if files.is_empty() {
        eprintln!("usage: layer_monotone FILE.json...");
        std::process::exit(1);
    }
    let (mut checked, mut violations) = (BTreeMap::<String, usize>::new(), BTreeMap::<String, usize>::new());
    for file in &files {
        let text = std::fs::read_to_string(file).unwrap_or_else(|e| fail(&format!("{file}: {e}")));
        let json: serde_json::Value = serde_json::from_str(&text).unwrap_or_else(|e| fail(&format!("{file}: {e}")));
        let rows = json["rows"].as_array().unwrap_or_else(|| fail(&format!("{file}: no `rows`")));
        // (bound, N, L) -> frames, for the method "ours".
        let mut by: BTreeMap<(String, u64, u64), Frames> = BTreeMap::new();
        for r in rows.iter().filter(|r| r["method"] == "ours") {
            let frames = r["frames_detail"]
                .as_array()
                .unwrap_or_else(|| fail(&format!("{file}: a row without `frames_detail`")))
                .iter()
                .map(|f| (f["pair"].as_u64().unwrap_or(0), num(&f["psnr"]), num(&f["ssim"])))
                .collect();
            let key = (r["bound"].as_str().unwrap_or("-").to_string(), uint(&r["n"]), uint(&r["l"]));
            by.insert(key, frames);
        }
        for ((bound, n, l), frames) in &by {
            let Some(next) = by.get(&(bound.clone(), *n, l + 1)) else { continue };
            for (&(pair, p0, s0), &(_, p1, s1)) in frames.iter().zip(next) {
                *checked.entry(bound.clone()).or_default() += 1;
                if p1 < p0 - 0.1 || s1 < s0 - 0.0005 {
                    *violations.entry(bound.clone()).or_default() += 1;
                    println!(
                        "{file}: {bound} N={n} pair {pair}: L={l} {p0:.2} dB / {s0:.4} -> L={} {p1:.2} dB / {s1:.4}",
                        l + 1
                    );
                }
            }
        }
    }
    for (bound, n) in &checked {
        println!("{bound}: {} of {n} frame pairs lose with one more layer", violations.get(bound).unwrap_or(&0));
    }
}

fn num(v: &serde_json::Value) -> f64 {
    v.as_f64().unwrap_or(f64::NAN)
}

fn uint(v: &serde_json::Value) -> u64 {
    v.as_u64().unwrap_or(0)
}

fn fail(msg: &str) -> ! {
    eprintln!("error: {msg}");
    std::process::exit(1)
}
