//! Prints every culling error of WOC (an object REF shows that WOC culled) with the
//! diagnostics of [`zwarp_cull::CulledVisible`], along the first frames of a scene's path
//! (the frames `zwarp cull` uses).
//!
//! `cargo run --release -p zwarp-tools --bin cull_diag -- [scene[@path.json]] [scale] [width] [height] [frames] [method] [default|norims|<rim px>] [downsample] [speed]`

use zwarp_cull::{run_sequence, summarize, Method, WocParams};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let a = zwarp_tools::common::CullArgs::from_env("bl", "24")?;
    let arg = |i: usize, d: &str| a.arg(i, d);
    let (w, h, n_frames) = (a.width, a.height, a.frames);
    let method = Method::parse(&arg(5, "woc"))?;
    let (loaded, path) = a.load()?;
    // Optional 9th argument: motion-speed factor (default 1).
    let speed: f32 = arg(8, "1").parse()?;
    let mut frames = path.frames(w, h, speed)?;
    frames.truncate(n_frames);
    // Optional 7th argument: `norims` (WOC without the opening-rim holes, the old behaviour) or
    // the rim separation threshold in pixels.
    let mut params = WocParams::default();
    match arg(6, "default").as_str() {
        "default" => {}
        "norims" => params.open_rims = None,
        px => params.open_rims = Some(px.parse()?),
    }
    // Optional 8th argument: culling resolution divisor.
    params.downsample = arg(7, "1").parse()?;
    let reps = run_sequence(&loaded.scene, &frames, method, &params)?;
    for r in &reps {
        for c in &r.culled_visible {
            println!("frame {:2} {}", r.frame, serde_json::to_string(c)?);
        }
    }
    let s = summarize(&reps);
    println!(
        "{} objects, {} frames: CR {:.4}, FN {}, object error {:.5}",
        loaded.scene.instances.len(),
        s.frames,
        s.culling_ratio,
        s.false_negatives,
        s.object_error
    );
    Ok(())
}
