//! Frame-rate upsampling with seed 001's colour warp: the frame half-way between two rendered
//! frames, predicted from the first one and its motion vectors towards the second (30 -> 60 Hz
//! by extrapolation), with the heuristic and the robust warp, beside the rendered in-between
//! frame and repeating the last frame.
//!
//! `cargo run --release -p zwarp-color --example frame_upsample [OUT_DIR]` writes `source.png`
//! (the rendered frame), `heuristic.png` and `robust.png` (the predicted in-between frame),
//! `reference.png` (the in-between frame rendered) and `confidence.png` (the robust warp's
//! per-pixel residual: white = converged) to OUT_DIR (default `out/frame_upsample`) and prints
//! the PSNR of each against the reference.
//!
//! The scene is zwarp's procedural MO (moving objects) at a small scale, rendered with
//! zwarp-raster; an engine hands its own colour, depth and motion vectors instead. The motion
//! to the in-between frame is taken as half the motion to the next frame (`t = 0.5`, eq. 2).

use std::path::{Path, PathBuf};

use zwarp_color::{heuristic_warp, robust_warp, FieldParams, HeuristicParams, RobustParams, WarpBasis};
use zwarp_core::{motion_field, Camera, Image, Result};

/// What the example measured: PSNR (dB, linear RGB) against the rendered in-between frame.
pub struct Report {
    /// Repeating the source frame.
    pub repeat: f64,
    /// The heuristic warp (Sec. 3.3).
    pub heuristic: f64,
    /// The robust warp (Sec. 3.4).
    pub robust: f64,
}

/// Renders frames k and k + 1 and the in-between time at `w x h`, predicts the in-between
/// frame from frame k, writes the images to `out` and returns the quality.
pub fn run(w: u32, h: u32, out: &Path) -> Result<Report> {
    let opts = zwarp_scene::SceneOptions { scale: 0.03, ..Default::default() };
    let loaded = zwarp_scene::load_scene("mo", &opts)?;
    let path = loaded.path_or_default();
    // Frame k and k + 1 at the path's rate, a few frames in so that objects are under way.
    let (t0, t1) = (path.time_of_frame(10, 1.0), path.time_of_frame(11, 1.0));
    let render = |t: f32| -> Result<(Camera, zwarp_raster::Frame)> {
        let cam = path.camera_at(t, w, h)?;
        let f = zwarp_raster::render_frame(
            &loaded.scene,
            &cam,
            t,
            &zwarp_raster::FrameOptions { color: true, objects: None },
        )?;
        Ok((cam, f))
    };
    let (cam0, frame0) = render(t0)?;
    let (cam1, _) = render(t1)?;
    let (_, between) = render(0.5 * (t0 + t1))?;
    let color = frame0.color.as_ref().expect("colour is requested");
    let reference = between.color.as_ref().expect("colour is requested");
    // The engine's motion vectors of frame k towards frame k + 1 (camera and objects).
    let motion = motion_field(&frame0.depth, Some(&frame0.items), &cam0, &cam1, &loaded.scene.object_deltas(t0, t1))?;
    let basis = WarpBasis::temporal(&frame0.depth, &motion)?;
    let field = basis.field(FieldParams::temporal(0.5))?;
    let heuristic = heuristic_warp(&field, color, &HeuristicParams::default())?;
    let (robust, _) = robust_warp(&field, color, &RobustParams::default())?;

    std::fs::create_dir_all(out).map_err(|e| zwarp_core::Error::io(out, e))?;
    let png = |name: &str, img: &Image<[f32; 3]>| zwarp_viz::write_png(out.join(name), &zwarp_viz::color_to_rgb8(img));
    png("source.png", color)?;
    png("heuristic.png", &heuristic.color)?;
    png("robust.png", &robust.color)?;
    png("reference.png", reference)?;
    // Confidence: 1 where the search converged (residual below half a pixel), fading to 0 at 2 px.
    let confidence = robust.residual.map(|&r| {
        let c = (1.0 - (r - 0.5) / 1.5).clamp(0.0, 1.0);
        [c, c, c]
    });
    png("confidence.png", &confidence)?;
    let psnr = |img: &Image<[f32; 3]>| zwarp_metrics::psnr_rgb(reference, img, 1.0);
    Ok(Report { repeat: psnr(color)?, heuristic: psnr(&heuristic.color)?, robust: psnr(&robust.color)? })
}

#[allow(dead_code)]
fn main() -> Result<()> {
    let out = std::env::args().nth(1).map_or_else(|| PathBuf::from("out/frame_upsample"), PathBuf::from);
    let r = run(640, 360, &out)?;
    println!(
        "in-between frame of 640x360 predicted from the previous one: PSNR repeat {:.2} dB, heuristic {:.2} dB, robust {:.2} dB; images in {}",
        r.repeat,
        r.heuristic,
        r.robust,
        out.display()
    );
    Ok(())
}
