//! Predict a view's depth buffer from the previous view's peeled layers with the `zwarp` facade,
//! and compare it with rendering that view directly.
//!
//! `cargo run --release -p zwarp --example predict_depth [OUT_DIR]` writes `source.png`,
//! `predicted.png`, `reference.png` and `error.png` (colour-mapped linear depth; the error map: red = predicted nearer, blue = farther, full at 5 % of the depth range) to
//! OUT_DIR (default `out/predict_depth`) and prints PSNR / SSIM on normalised linear depth.
//!
//! The scene is zwarp's analytic test city (ray cast, three peeled layers, the last one ground
//! only) with one box moving; an engine hands its own depth layers and cameras instead.

use std::path::{Path, PathBuf};

use zwarp::warp::synth::SynthScene;
use zwarp::{Backend, Prediction, Warper};

/// Quality of one prediction against the direct render.
pub struct Report {
    /// PSNR (dB) and SSIM on linear depth normalised by the reference's surface range.
    pub psnr: f64,
    /// SSIM on the same normalised depth.
    pub ssim: f64,
    /// Fraction of pixels that converged.
    pub converged: f64,
}

/// Renders the source view, predicts the target view with `backend`, writes the images to
/// `out` and returns the quality.
pub fn run(backend: Backend, w: u32, h: u32, out: &Path) -> zwarp::Result<Report> {
    let scene = SynthScene::moving_city();
    let (cam_a, cam_b) = SynthScene::city_views(w, h)?;
    let (t_a, t_b) = (0.0, 0.25);

    // The frame the renderer already drew: depth layers and item ids (for object motion).
    let source = scene.render(&cam_a, t_a, 3, true);
    let mut warper = Warper::new(backend, Warper::default_params())?;
    warper.prepare(&cam_a, &source.depth, Some(&source.items))?;
    let prediction: &Prediction = warper.warp_to(&cam_b, &scene.object_deltas(t_a, t_b))?;

    // What rendering the target view gives.
    let reference = scene.render(&cam_b, t_b, 1, false).depth.remove(0);
    let range = zwarp_viz::depth_range(&reference, Some(&cam_b)).unwrap_or((0.0, 1.0));
    let norm = |d| zwarp_metrics::normalized_linear_depth(d, &cam_b, range);
    let (p, r) = (norm(&prediction.depth), norm(&reference));
    let report = Report {
        psnr: zwarp_metrics::psnr(&p, &r, 1.0)?,
        ssim: zwarp_metrics::ssim(&p, &r, 1.0)?,
        converged: prediction.converged_fraction(),
    };
    std::fs::create_dir_all(out).map_err(|e| zwarp::Error::io(out, e))?;
    let rgb = |d, cam| zwarp_viz::depth_to_rgb8_in_range(d, Some(cam), range);
    zwarp_viz::write_png(out.join("source.png"), &rgb(&source.depth[0], &cam_a))?;
    zwarp_viz::write_png(out.join("predicted.png"), &rgb(&prediction.depth, &cam_b))?;
    zwarp_viz::write_png(out.join("reference.png"), &rgb(&reference, &cam_b))?;
    zwarp_viz::write_png(out.join("error.png"), &zwarp_viz::diff_heatmap(&p, &r, 0.05)?)?;
    Ok(report)
}

#[allow(dead_code)]
fn main() -> zwarp::Result<()> {
    let out = std::env::args().nth(1).map_or_else(|| PathBuf::from("out/predict_depth"), PathBuf::from);
    let r = run(Backend::Cpu, 640, 360, &out)?;
    println!(
        "predicted 640x360 from 3 layers: PSNR {:.2} dB, SSIM {:.4}, converged {:.3}; images in {}",
        r.psnr,
        r.ssim,
        r.converged,
        out.display()
    );
    Ok(())
}
