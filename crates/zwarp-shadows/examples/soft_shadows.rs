//! Soft shadows from warped shadow maps (seed 000 Sec. 6): a procedural city lit by an area
//! light, shaded with S sample shadow maps rendered one by one (the reference) and with the
//! same S maps synthesized by zwarp from one peeled centre map, side by side with PCSS and the
//! visibility difference, in one labelled PNG.
//!
//! `cargo run --release -p zwarp-shadows --example soft_shadows [OUT_DIR]` writes
//! `soft_shadows.png` to OUT_DIR (default `out/soft_shadows`) and prints SSIM and the speed-up.

use std::path::{Path, PathBuf};

use zwarp_core::Result;
use zwarp_shadows::{default_light, run_shadows, Method, ShadowParams};

/// What the example measured.
pub struct Figures {
    /// SSIM of zwarp's shading against the reference's (linear RGB).
    pub ssim_zwarp: f64,
    /// SSIM of PCSS against the reference.
    pub ssim_pcss: f64,
    /// Reference time over zwarp's time (same run, one cold run each: indicative only).
    pub speedup: f64,
}

/// Renders `scene` ("mo" at `scale`) soft-shadowed at `w` x `h` with `samples` light samples and
/// `sm`^2 maps by the three methods and writes the strip to `out/soft_shadows.png`.
pub fn run(scale: f32, w: u32, h: u32, samples: u32, sm: u32, out: &Path) -> Result<Figures> {
    let opts = zwarp_scene::SceneOptions { scale, ..Default::default() };
    let loaded = zwarp_scene::load_scene("mo", &opts)?;
    let scene = loaded.scene;
    let path = loaded.path.unwrap_or_else(|| zwarp_scene::CameraPath::default_for(&scene));
    let cam = path.camera_at(0.0, w, h)?;
    let light = default_light(&scene)?;
    let params = ShadowParams { samples, sm_size: sm, ..ShadowParams::default() };
    let reference = run_shadows(&scene, &cam, 0.0, &light, Method::Reference, &params)?;
    let zwarp = run_shadows(&scene, &cam, 0.0, &light, Method::Zwarp, &params)?;
    let pcss = run_shadows(&scene, &cam, 0.0, &light, Method::Pcss, &params)?;

    let panel = |label: &str, r: &zwarp_shadows::ShadowResult| {
        zwarp_viz::labelled(&zwarp_viz::color_to_rgb8(&r.image), label, 1)
    };
    // Visibility difference: red = zwarp darker than the reference, blue = lighter.
    let diff = zwarp_viz::labelled(
        &zwarp_viz::diff_heatmap(&zwarp.visibility, &reference.visibility, 0.5)?,
        "visibility zwarp - reference",
        1,
    )?;
    let strip = zwarp_viz::strip(&[
        panel(&format!("reference, S = {samples}"), &reference)?,
        panel(&format!("zwarp, S = {samples}"), &zwarp)?,
        panel("PCSS", &pcss)?,
        diff,
    ])?;
    std::fs::create_dir_all(out).map_err(|e| zwarp_core::Error::io(out, e))?;
    zwarp_viz::write_png(out.join("soft_shadows.png"), &strip)?;
    Ok(Figures {
        ssim_zwarp: zwarp_metrics::ssim_rgb(&zwarp.image, &reference.image, 1.0)?,
        ssim_pcss: zwarp_metrics::ssim_rgb(&pcss.image, &reference.image, 1.0)?,
        speedup: reference.ms / zwarp.ms.max(1e-9),
    })
}

#[allow(dead_code)] // `run` is also called by the example test
fn main() -> Result<()> {
    let out = std::env::args().nth(1).map(PathBuf::from).unwrap_or_else(|| PathBuf::from("out/soft_shadows"));
    let f = run(0.25, 640, 360, 64, 1024, &out)?;
    println!(
        "SSIM against the reference: zwarp {:.4}, PCSS {:.4}; zwarp {:.1}x faster than rendering the 64 maps; {}",
        f.ssim_zwarp,
        f.ssim_pcss,
        f.speedup,
        out.join("soft_shadows.png").display()
    );
    Ok(())
}
