//! Times one method of the soft-shadow pipeline alone (for profilers: no reference runs) and
//! prints its stage times and the texels warped. Usage:
//! `cargo run --release -p zwarp-tools --bin shadow_profile -- SCENE SCALE S SM [METHOD] [REPS]`
//! (640x360 camera, frame 0, default light; METHOD = zwarp | zwarp-full | reference | pcss;
//! `ZW_SHARED=0` gives every sample its own motion mipmap; `ZW_GROUPING=auto|never|always`
//! chooses how the receivers are tested, [`Grouping`]).
use zwarp_shadows::*;

fn main() -> zwarp_core::Result<()> {
    let a: Vec<String> = std::env::args().collect();
    let arg = |i: usize, d: &str| a.get(i).cloned().unwrap_or_else(|| d.to_string());
    let spec = arg(1, "mo");
    let scale: f32 = arg(2, "0.25").parse().map_err(|_| zwarp_core::Error::invalid("bad scale"))?;
    let samples: u32 = arg(3, "64").parse().map_err(|_| zwarp_core::Error::invalid("bad S"))?;
    let sm: u32 = arg(4, "2048").parse().map_err(|_| zwarp_core::Error::invalid("bad sm"))?;
    let method: Method = arg(5, "zwarp").parse()?;
    let reps: usize = arg(6, "2").parse().map_err(|_| zwarp_core::Error::invalid("bad reps"))?;
    let loaded = zwarp_scene::load_scene(&spec, &zwarp_scene::SceneOptions { scale, ..Default::default() })?;
    let path = loaded.path_or_default();
    let t = path.time_of_frame(0, 1.0);
    let cam = path.camera_at(t, 640, 360)?;
    let light = default_light(&loaded.scene)?;
    // ZW_SHARED=0: per-sample motion buffers and (oriented) mipmaps instead of the shared one.
    let shared_mipmap = std::env::var("ZW_SHARED").map_or(true, |v| v != "0");
    let grouping = match std::env::var("ZW_GROUPING").as_deref() {
        Ok("never") => Grouping::Never,
        Ok("always") => Grouping::Always,
        _ => Grouping::Auto,
    };
    let p = ShadowParams { samples, sm_size: sm, shared_mipmap, grouping, ..ShadowParams::default() };
    for _ in 0..reps {
        let r = run_shadows(&loaded.scene, &cam, t, &light, method, &p)?;
        let tm = r.timings;
        println!(
            "{spec} {} S={samples} sm={sm}: {:.1} ms (camera {:.1}, render {:.1}, motion {:.1}, mipmap {:.1}, warp {:.1}, vis {:.1}); \
             {} texels warped ({:.3} of S sm^2), {} holes",
            method.name(),
            r.ms,
            tm.camera,
            tm.render,
            tm.motion,
            tm.mipmap,
            tm.warp,
            tm.visibility,
            r.warped_texels,
            r.warped_texels as f64 / (samples as f64 * sm as f64 * sm as f64),
            r.warp_holes
        );
    }
    Ok(())
}
