//! Both eyes of a stereo frame from one rendered view with seed 003's hybrid warp: the
//! surface-estimation quadtree, the adaptive grid warped to each eye, depth-aware low-pass hole
//! filling; compared with rendering each eye.
//!
//! `cargo run --release -p zwarp-vr --example stereo_warp [OUT_DIR]` writes `centre.png` (the one
//! rendered view), `left.png` / `right.png` (the warped eyes), `anaglyph.png`, `reference_left.png`
//! / `reference_right.png` (rendered eyes) and `grid.png` (the cells over the centre view) to
//! OUT_DIR (default `out/stereo_warp`) and prints PSNR per eye and the cells drawn.
//!
//! The scene is zwarp's procedural MO at a small scale, rendered with zwarp-raster, and the eyes
//! are 0.3 world units apart (a wide baseline for this small world, so the grid refines along
//! its silhouettes: with a 64 mm IPD every 32x32 tile moves rigidly and is one cell); an engine
//! hands its own depth, colour and cameras instead.

use std::path::{Path, PathBuf};

use glam::{Mat4, Vec3};
use zwarp_core::{Camera, Image, Result};
use zwarp_vr::grid::{draw_cells, Source, WarpParams};
use zwarp_vr::{fill_holes, HoleMethod, Method, Reduction};

/// What the example measured.
pub struct Report {
    /// PSNR (dB, linear RGB) of the warped left and right eyes against their renders.
    pub psnr: [f64; 2],
    /// Grid cells drawn per eye (the source has `pixels` pixels).
    pub cells: usize,
    /// Source pixels.
    pub pixels: usize,
}

/// `cam` shifted by `u` world units along its right axis.
fn eye(cam: &Camera, u: f32) -> Camera {
    Camera { view: Mat4::from_translation(Vec3::new(-u, 0.0, 0.0)) * cam.view, ..*cam }
}

/// Renders the centre view and both eyes (`ipd` apart) at `w x h`, warps the centre view to each
/// eye, writes the images to `out` and returns the quality.
pub fn run(w: u32, h: u32, ipd: f32, out: &Path) -> Result<Report> {
    let opts = zwarp_scene::SceneOptions { scale: 0.03, ..Default::default() };
    let loaded = zwarp_scene::load_scene("mo", &opts)?;
    let path = loaded.path_or_default();
    let t = path.time_of_frame(10, 1.0);
    let centre = path.camera_at(t, w, h)?;
    let render = |cam: &Camera| -> Result<(Image<f32>, Image<[f32; 3]>)> {
        let f = zwarp_raster::render_frame(
            &loaded.scene,
            cam,
            t,
            &zwarp_raster::FrameOptions { color: true, objects: None },
        )?;
        Ok((f.depth, f.color.expect("colour is requested")))
    };
    // The one view the renderer draws.
    let (depth, color) = render(&centre)?;
    let src = Source { cam: &centre, depth: &depth, color: &color };
    std::fs::create_dir_all(out).map_err(|e| zwarp_core::Error::io(out, e))?;
    let png = |name: &str, img: &Image<[f32; 3]>| zwarp_viz::write_png(out.join(name), &zwarp_viz::color_to_rgb8(img));
    png("centre.png", &color)?;
    let mut eyes = Vec::new();
    let mut psnr = [0.0; 2];
    let mut cells = 0;
    for (i, (side, name)) in [(-0.5f32, "left"), (0.5, "right")].into_iter().enumerate() {
        let cam = eye(&centre, side * ipd);
        // The warp: quadtree, adaptive grid, rasterised with a depth test; then the holes.
        let warped = zwarp_vr::warp(&src, &cam, Method::Grid(Reduction::Irregular), &WarpParams::default())?;
        let predicted = fill_holes(&warped, &src, &cam, HoleMethod::LowPass)?;
        let (_, reference) = render(&cam)?;
        psnr[i] = zwarp_metrics::psnr_rgb(&reference, &predicted, 1.0)?;
        cells = warped.primitives;
        png(&format!("{name}.png"), &predicted)?;
        png(&format!("reference_{name}.png"), &reference)?;
        if i == 0 {
            png("grid.png", &draw_cells(&color, &warped.cells, [1.0, 0.1, 0.1]))?;
        }
        eyes.push(zwarp_viz::color_to_rgb8(&predicted));
    }
    // Red from the left eye, green and blue from the right.
    let ana = Image::from_fn(w, h, |x, y| [eyes[0].get(x, y)[0], eyes[1].get(x, y)[1], eyes[1].get(x, y)[2]]);
    zwarp_viz::write_png(out.join("anaglyph.png"), &ana)?;
    Ok(Report { psnr, cells, pixels: (w * h) as usize })
}

#[allow(dead_code)]
fn main() -> Result<()> {
    let out = std::env::args().nth(1).map_or_else(|| PathBuf::from("out/stereo_warp"), PathBuf::from);
    let r = run(640, 360, 0.3, &out)?;
    println!(
        "both eyes of 640x360 (0.3 apart) warped from one view: PSNR left {:.2} dB, right {:.2} dB; {} grid cells for {} pixels; images in {}",
        r.psnr[0],
        r.psnr[1],
        r.cells,
        r.pixels,
        out.display()
    );
    Ok(())
}
