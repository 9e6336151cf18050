//! Debug probe: neighbourhoods of one culling error (prev / warped / true buffers).
//!
//! `cargo run --release -p zwarp-tools --bin cull_probe -- FRAME ID`: BL at scale 0.25, 960x540,
//! the 7x7 pixels around the first pixel of object ID in frame FRAME's full render (an object
//! `cull_diag` reports), the previous frame drawn with VFC's visible set.
use zwarp_core::{motion_field, Image};
use zwarp_cull::{vfc_cull, WocParams};
use zwarp_raster::{render_frame, FrameOptions};
use zwarp_scene::{load_scene, SceneOptions};
use zwarp_warp::{warp_depth, WarpLayer};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let a: Vec<String> = std::env::args().skip(1).collect();
    let (frame, id): (usize, u32) = (a[0].parse()?, a[1].parse()?);
    let loaded = load_scene("bl", &SceneOptions { scale: 0.25, ..SceneOptions::default() })?;
    let scene = &loaded.scene;
    let frames = loaded.path_or_default().frames(960, 540, 1.0)?;
    let (tp, pc) = &frames[frame - 1];
    let (t, c) = &frames[frame];
    let vis = vfc_cull(scene, pc, *tp)?.visible;
    let prev = render_frame(scene, pc, *tp, &FrameOptions { color: false, objects: Some(&vis) })?;
    let full = render_frame(scene, c, *t, &FrameOptions::default())?;
    let deltas = scene.object_deltas(*tp, *t);
    let motion = motion_field(&prev.depth, Some(&prev.items), pc, c, &deltas)?;
    let mut wp = WocParams::default().warp;
    wp.record_source = true;
    let w = warp_depth(&[WarpLayer { depth: &prev.depth, motion: &motion }], &wp)?;
    let i = full.items.data().iter().position(|&v| v == id).unwrap();
    let (x, y) = ((i % 960) as i32, (i / 960) as i32);
    println!("q = ({x}, {y})");
    let show = |name: &str, f: &dyn Fn(u32, u32) -> String| {
        println!("{name}:");
        for yy in y - 3..=y + 3 {
            let row: Vec<String> = (x - 3..=x + 3).map(|xx| f(xx as u32, yy as u32)).collect();
            println!("  {}", row.join(" "));
        }
    };
    let d = |img: &Image<f32>, xx, yy| format!("{:.5}", img.get(xx, yy));
    show("prev items", &|xx, yy| format!("{:>5}", *prev.items.get(xx, yy) as i32));
    show("prev depth", &|xx, yy| d(&prev.depth, xx, yy));
    show("prev motion", &|xx, yy| {
        let m = motion.get(xx, yy);
        format!("{:+.2},{:+.2}", m.v.x, m.v.y)
    });
    show("warped", &|xx, yy| d(&w.depth, xx, yy));
    show("source", &|xx, yy| {
        w.source.as_ref().map_or("-".into(), |s| {
            let s = s.get(xx, yy);
            format!("{:.1},{:.1}", s.q.x, s.q.y)
        })
    });
    show("true items", &|xx, yy| format!("{:>5}", *full.items.get(xx, yy) as i32));
    show("true depth", &|xx, yy| d(&full.depth, xx, yy));
    Ok(())
}
