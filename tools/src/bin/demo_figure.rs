//! Writes a demo figure of every colour map to look at:
//! `cargo run -p zwarp-tools --bin demo_figure -- /tmp/zwarp-viz-demo.png`.
//!
//! Panels: depth (turbo, linear), item ids, motion (Middlebury wheel) for a camera moving right
//! and forward, colour (sRGB), signed depth difference of a one-pixel-shifted prediction with a
//! far-plane hole (red = nearer = unsafe, blue = farther = safe).

use glam::Vec3;
use zwarp_core::{motion_field, Camera, Image, NO_ITEM};
use zwarp_viz::{
    color_to_rgb8, depth_to_rgb8, diff_heatmap, items_to_rgb8, motion_to_rgb8, side_by_side, write_exr_f32, write_png,
};

/// Ray-casts a sphere (id 0) in front of a ground plane y = -1 (id 1) and a back wall z = -6 (id 2).
fn render(cam: &Camera) -> (Image<f32>, Image<u32>, Image<[f32; 3]>) {
    let (w, h) = (cam.width, cam.height);
    let eye = cam.eye();
    let inv = cam.view_proj().inverse();
    let mut depth = Image::new(w, h, 1.0f32);
    let mut items = Image::new(w, h, NO_ITEM);
    let mut color = Image::new(w, h, [0.02f32, 0.02, 0.05]);
    let centre = Vec3::new(0.0, 0.0, 0.0);
    for y in 0..h {
        for x in 0..w {
            let far = zwarp_core::camera::unproject_with(&inv, w, h, x as f32 + 0.5, y as f32 + 0.5, 1.0);
            let dir = (far - eye).normalize();
            let mut best = (f32::INFINITY, NO_ITEM, Vec3::ZERO);
            // Sphere radius 1.
            let oc = eye - centre;
            let b = oc.dot(dir);
            let disc = b * b - (oc.length_squared() - 1.0);
            if disc > 0.0 {
                let t = -b - disc.sqrt();
                if t > 0.0 && t < best.0 {
                    best = (t, 0, (eye + dir * t - centre).normalize());
                }
            }
            if dir.y < 0.0 {
                let t = (-1.0 - eye.y) / dir.y;
                let p = eye + dir * t;
                if t < best.0 && p.z > -6.0 {
                    best = (t, 1, Vec3::Y);
                }
            }
            if dir.z < 0.0 {
                let t = (-6.0 - eye.z) / dir.z;
                if t < best.0 && (eye + dir * t).y > -1.0 {
                    best = (t, 2, Vec3::Z);
                }
            }
            if best.1 != NO_ITEM {
                let p = eye + dir * best.0;
                if let Some(s) = cam.project(p) {
                    *depth.get_mut(x, y) = s.z.clamp(0.0, 1.0);
                    *items.get_mut(x, y) = best.1;
                    let albedo = [Vec3::new(0.8, 0.2, 0.1), Vec3::new(0.3, 0.6, 0.3), Vec3::new(0.4, 0.4, 0.7)];
                    let shade = 0.15 + 0.85 * best.2.dot(Vec3::new(0.4, 0.8, 0.45).normalize()).max(0.0);
                    let c = albedo[best.1 as usize] * shade;
                    *color.get_mut(x, y) = [c.x, c.y, c.z];
                }
            }
        }
    }
    (depth, items, color)
}

fn main() -> zwarp_core::Result<()> {
    let out = std::env::args().nth(1).unwrap_or_else(|| "/tmp/zwarp-viz-demo.png".into());
    let (w, h) = (160, 120);
    let a = Camera::perspective(Vec3::new(0.0, 0.5, 4.0), Vec3::ZERO, Vec3::Y, 1.0, 0.1, 100.0, w, h)?;
    let b = Camera::perspective(Vec3::new(0.6, 0.5, 3.4), Vec3::new(0.3, 0.0, 0.0), Vec3::Y, 1.0, 0.1, 100.0, w, h)?;
    let (depth, items, color) = render(&a);
    let motion = motion_field(&depth, Some(&items), &a, &b, &[])?;
    // A "prediction": shifted one pixel right with a far hole.
    let mut pred = Image::from_fn(w, h, |x, y| *depth.get_clamped(x as i64 - 1, y as i64));
    for y in 50..60 {
        for x in 70..85 {
            *pred.get_mut(x, y) = 1.0;
        }
    }
    let panels = [
        depth_to_rgb8(&depth, Some(&a)),
        items_to_rgb8(&items),
        motion_to_rgb8(&motion, None),
        color_to_rgb8(&color),
        diff_heatmap(&pred, &depth, 0.02)?,
    ];
    let refs: Vec<&Image<[u8; 3]>> = panels.iter().collect();
    write_png(&out, &side_by_side(&refs)?)?;
    write_exr_f32(format!("{out}.depth.exr"), &depth, "Z")?;
    println!("wrote {out} and {out}.depth.exr");
    Ok(())
}
