//! Occlusion culling by depth warping (WOC, seed 000 Sec. 5): the previous frame's depth and
//! item buffers are warped to the new camera and every object's box is tested against that
//! prediction before anything of the new frame is drawn. The example culls one frame of a
//! procedural city with WOC and with view-frustum culling, draws only what WOC keeps, and writes
//! a labelled strip: the full render | the kept objects drawn | the warped occlusion map | the
//! pixels that differ (none when no visible object was culled).
//!
//! `cargo run --release -p zwarp-cull --example cull_with_warp [OUT_DIR]` writes
//! `cull_with_warp.png` to OUT_DIR (default `out/cull_with_warp`).

use std::path::{Path, PathBuf};

use zwarp_core::{Image, Result};
use zwarp_cull::{reference, vfc_cull, woc, PrevFrame, WocParams};
use zwarp_raster::{render_frame, FrameOptions};

/// What the example measured on its frame.
pub struct Figures {
    /// Objects in the scene.
    pub objects: usize,
    /// Objects WOC keeps, VFC keeps, and truly visible ones (REF).
    pub woc: usize,
    /// See [`Figures::woc`].
    pub vfc: usize,
    /// See [`Figures::woc`].
    pub visible: usize,
    /// Visible objects WOC culled (culling errors).
    pub culled_visible: usize,
    /// Pixels whose colour differs between the full render and the render of WOC's set.
    pub differing_pixels: usize,
}

/// Culls frame 1 of the `cb` city (at `scale`) from frame 0's buffers at `w` x `h`.
pub fn run(scale: f32, w: u32, h: u32, out: &Path) -> Result<Figures> {
    let opts = zwarp_scene::SceneOptions { scale, ..Default::default() };
    let loaded = zwarp_scene::load_scene("cb", &opts)?;
    let scene = loaded.scene;
    let path = loaded.path.unwrap_or_else(|| zwarp_scene::CameraPath::default_for(&scene));
    let frames = path.frames(w, h, 1.0)?;
    let ((t0, cam0), (t1, cam1)) = (frames[0], frames[1]);

    // The previous frame, as the engine drew it: depth and item ids.
    let prev = render_frame(&scene, &cam0, t0, &FrameOptions::default())?;
    let prev_frame = PrevFrame { depth: &prev.depth, items: &prev.items, cam: &cam0, t: t0 };
    let culled = woc(&scene, &prev_frame, &cam1, t1, &WocParams::default())?;
    let vfc = vfc_cull(&scene, &cam1, t1)?;
    let truth = reference(&scene, &cam1, t1)?;

    // Draw everything, and only what WOC keeps: the images must agree.
    let colour = FrameOptions { color: true, objects: None };
    let full = render_frame(&scene, &cam1, t1, &colour)?;
    let kept = render_frame(&scene, &cam1, t1, &FrameOptions { color: true, objects: Some(&culled.visible) })?;
    let (fc, kc) = (full.color.expect("colour requested"), kept.color.expect("colour requested"));
    let diff: Vec<bool> = fc.data().iter().zip(kc.data()).map(|(a, b)| a != b).collect();
    let differing_pixels = diff.iter().filter(|d| **d).count();
    let diff = Image::from_vec(w, h, diff)?;

    let map = culled.occlusion_map.as_ref().map_or_else(|| Image::new(w, h, 1.0), |m| m.clone());
    let strip = zwarp_viz::strip(&[
        zwarp_viz::labelled(
            &zwarp_viz::color_to_rgb8(&fc),
            &format!("full render, {} objects", scene.instances.len()),
            1,
        )?,
        zwarp_viz::labelled(&zwarp_viz::color_to_rgb8(&kc), &format!("WOC keeps {}", culled.visible.len()), 1)?,
        zwarp_viz::labelled(&zwarp_viz::depth_to_rgb8(&map, None), "warped occlusion map", 1)?,
        zwarp_viz::labelled(&zwarp_viz::mask_to_rgb8(&diff), &format!("{differing_pixels} pixels differ"), 1)?,
    ])?;
    std::fs::create_dir_all(out).map_err(|e| zwarp_core::Error::io(out, e))?;
    zwarp_viz::write_png(out.join("cull_with_warp.png"), &strip)?;

    let shown: std::collections::HashSet<u32> = culled.visible.iter().copied().collect();
    Ok(Figures {
        objects: scene.instances.len(),
        woc: culled.visible.len(),
        vfc: vfc.visible.len(),
        visible: truth.visible.len(),
        culled_visible: truth.visible.iter().filter(|id| !shown.contains(id)).count(),
        differing_pixels,
    })
}

#[allow(dead_code)] // `run` is also called by the example test
fn main() -> Result<()> {
    let out = std::env::args().nth(1).map(PathBuf::from).unwrap_or_else(|| PathBuf::from("out/cull_with_warp"));
    let f = run(0.25, 960, 540, &out)?;
    println!(
        "{} objects: VFC keeps {}, WOC keeps {}, {} are visible; {} visible culled, {} pixels differ; {}",
        f.objects,
        f.vfc,
        f.woc,
        f.visible,
        f.culled_visible,
        f.differing_pixels,
        out.join("cull_with_warp.png").display()
    );
    Ok(())
}
