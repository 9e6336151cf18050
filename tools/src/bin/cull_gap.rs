//! Where does WOC lose culling ratio against the ideal screen-space test? Runs WOC variants on
//! the same frames (each frame's previous frame is the full render of the previous camera, which
//! is what a safe method draws) and prints, per variant, the culling ratio vs REF and the visible
//! objects culled, next to the ideal test and the ideal test against the *eroded* true depth.
//!
//! `cargo run --release -p zwarp-tools --bin cull_gap -- [scene[@path.json]] [scale] [width] [height] [frames] [speed]`

use zwarp_core::motion_field;
use zwarp_cull::{
    accuracy, cull_against_depth, erode_max, ideal_screen_space, visible_from_items, woc, MaxDepthKind, PrevFrame,
    RimMode, WocParams,
};
use zwarp_raster::{render_frame, FrameOptions};
use zwarp_warp::{warp_depth, WarpLayer};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let a = zwarp_tools::common::CullArgs::from_env("bl", "12")?;
    let arg = |i: usize, d: &str| a.arg(i, d);
    let (scene_name, scale, w, h, n_frames) = (a.scene.clone(), a.scale, a.width, a.height, a.frames);
    let speed: f32 = arg(5, "1").parse()?;
    let (loaded, path) = a.load()?;
    let scene = &loaded.scene;
    let n = scene.instances.len();
    let mut frames = path.frames(w, h, speed)?;
    frames.truncate(n_frames);
    let d = WocParams::default();
    let variants: Vec<(&str, WocParams)> = vec![
        ("default", d),
        ("hole-bound", WocParams { hole_bound: true, ..d }),
        ("source-rims", WocParams { rim_mode: RimMode::Source, ..d }),
        ("norims", WocParams { open_rims: None, ..d }),
        ("norims-noerode", WocParams { open_rims: None, erosion: false, ..d }),
        ("norims-noerode-nbuf", WocParams { open_rims: None, erosion: false, max_depth: MaxDepthKind::NBuffer, ..d }),
        ("norims-norapid", WocParams { open_rims: None, rapid_motion: None, ..d }),
        ("rims-noerode", WocParams { erosion: false, ..d }),
        ("down4", WocParams { downsample: 4, ..d }),
    ];
    let mut sums = vec![(0.0f64, 0usize); variants.len() + 2];
    let mut prev = render_frame(scene, &frames[0].1, frames[0].0, &FrameOptions { color: false, objects: None })?;
    for k in 1..frames.len() {
        let (t, cam) = &frames[k];
        let full = render_frame(scene, cam, *t, &FrameOptions { color: false, objects: None })?;
        let reference = visible_from_items(&full.items, n);
        let p = PrevFrame { depth: &prev.depth, items: &prev.items, cam: &frames[k - 1].1, t: frames[k - 1].0 };
        let mut line = format!("frame {k:2}:");
        for (i, (name, params)) in variants.iter().enumerate() {
            let r = woc(scene, &p, cam, *t, params)?;
            if *name == "default" || *name == "hole-bound" {
                let m = r.occlusion_map.as_ref().unwrap();
                let far_surf = m.data().iter().zip(full.depth.data()).filter(|(a, b)| **a >= 1.0 && **b < 1.0).count();
                line += &format!(" [{name} far-over-surface {far_surf}]");
            }
            let a = accuracy(&r.visible, &reference, n);
            sums[i].0 += a.culling_ratio;
            sums[i].1 += a.false_negatives;
            line += &format!(" {name} {:.1}/{}", 100.0 * a.culling_ratio, a.false_negatives);
        }
        let ideal = ideal_screen_space(scene, &full.depth, cam, *t)?;
        let a = accuracy(&ideal.visible, &reference, n);
        sums[variants.len()].0 += a.culling_ratio;
        let eroded = cull_against_depth(scene, &erode_max(&full.depth), cam, *t, MaxDepthKind::NBuffer, None)?;
        let b = accuracy(&eroded.visible, &reference, n);
        sums[variants.len() + 1].0 += b.culling_ratio;
        line += &format!(" ideal {:.1} ideal-eroded {:.1}", 100.0 * a.culling_ratio, 100.0 * b.culling_ratio);
        // Holes of the plain warp (no rims, no erosion) over true surfaces: genuine
        // disocclusions (the true point, moved back to the previous frame, is hidden there or
        // off screen) vs warp failures (it was visible there).
        let deltas = scene.object_deltas(p.t, *t);
        let motion = motion_field(p.depth, Some(p.items), p.cam, cam, &deltas)?;
        let warped = warp_depth(&[WarpLayer { depth: p.depth, motion: &motion }], &d.warp)?;
        let (mut offscreen, mut self_occ) = (0usize, 0usize);
        let (mut disocc, mut fail, mut oracle) = (0usize, 0usize, warped.depth.clone());
        let mut oracle_fail = warped.depth.clone();
        for y in 0..h {
            for x in 0..w {
                let (td, wd) = (*full.depth.get(x, y), *warped.depth.get(x, y));
                if td < 1.0 && wd >= 1.0 {
                    *oracle.get_mut(x, y) = td;
                    let id = *full.items.get(x, y);
                    let world = cam.unproject(x as f32 + 0.5, y as f32 + 0.5, td);
                    let back = deltas[id as usize].inverse().transform_point3(world);
                    let q = p.cam.project(back);
                    let on =
                        q.filter(|q| q.x >= 0.0 && q.y >= 0.0 && (q.x.floor() as u32) < w && (q.y.floor() as u32) < h);
                    match on {
                        None => offscreen += 1,
                        Some(q) => {
                            let (qx, qy) = (q.x.floor() as u32, q.y.floor() as u32);
                            if *p.depth.get(qx, qy) >= q.z - 1e-4 {
                                fail += 1;
                                *oracle_fail.get_mut(x, y) = td;
                            } else {
                                disocc += 1;
                                let pid = *p.items.get(qx, qy);
                                if pid == id {
                                    self_occ += 1;
                                }
                            }
                        }
                    }
                }
            }
        }
        let o = cull_against_depth(scene, &oracle, cam, *t, MaxDepthKind::NBuffer, None)?;
        let oa = accuracy(&o.visible, &reference, n);
        let of = cull_against_depth(scene, &oracle_fail, cam, *t, MaxDepthKind::NBuffer, None)?;
        let ofa = accuracy(&of.visible, &reference, n);
        line += &format!(" oracle-fail-only CR {:.1}/{}", 100.0 * ofa.culling_ratio, ofa.false_negatives);
        line += &format!(
            " | holes: offscreen {offscreen} disocc {disocc} (self {self_occ}) fail {fail} oracle-fill CR {:.1}/{}",
            100.0 * oa.culling_ratio,
            oa.false_negatives
        );
        println!("{line}");
        prev = full;
    }
    let m = (frames.len() - 1).max(1) as f64;
    println!("{scene_name} scale {scale} {w}x{h} speed {speed}, {n} objects, {} frames (CR vs REF / FN):", m);
    for (i, (name, _)) in variants.iter().enumerate() {
        println!("  {name:<22} {:6.2}% {}", 100.0 * sums[i].0 / m, sums[i].1);
    }
    println!("  {:<22} {:6.2}%", "ideal", 100.0 * sums[variants.len()].0 / m);
    println!("  {:<22} {:6.2}%", "ideal-eroded", 100.0 * sums[variants.len() + 1].0 / m);
    Ok(())
}
