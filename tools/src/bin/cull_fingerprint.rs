//! Prints, per frame, a fingerprint (count and FNV-1a hash) of the object set WOC keeps along a
//! scene's path, one line per culling resolution: a speed-up of the pipeline that must not
//! change any decision is checked by diffing this output before and after.
//!
//! `cargo run --release -p zwarp-tools --bin cull_fingerprint -- [scene[@path.json]] [scale] [width] [height] [frames] [downsample list]`

use zwarp_cull::{run_sequence, Method, WocParams};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let a = zwarp_tools::common::CullArgs::from_env("cb", "8")?;
    let arg = |i: usize, d: &str| a.arg(i, d);
    let (scene_name, scale, w, h, n_frames) = (a.scene.clone(), a.scale, a.width, a.height, a.frames);
    let downs: Vec<u32> = arg(5, "1,2,4").split(',').map(|s| s.parse()).collect::<Result<_, _>>()?;
    let (loaded, path) = a.load()?;
    let mut frames = path.frames(w, h, 1.0)?;
    frames.truncate(n_frames);
    for f in downs {
        let p = WocParams { downsample: f, ..WocParams::default() };
        let reps = run_sequence(&loaded.scene, &frames, Method::Woc, &p)?;
        let prints: Vec<String> = reps
            .iter()
            .map(|r| {
                let hash = r
                    .visible_ids
                    .iter()
                    .fold(0xcbf2_9ce4_8422_2325u64, |h, &id| (h ^ id as u64).wrapping_mul(0x0100_0000_01b3));
                format!("{}:{:016x}", r.visible, hash)
            })
            .collect();
        println!("{scene_name} {scale} {w}x{h} /{f}: {}", prints.join(" "));
    }
    Ok(())
}
