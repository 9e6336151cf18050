//! Pipeline statistics of one scene (set-up vs raster split), for profiling.
fn main() -> zwarp_core::Result<()> {
    let dir = std::env::args().nth(1).unwrap_or_else(|| "/work/shared/scenes/sponza".into());
    let s = zwarp_raster::scenes::load_raw_sponza(std::path::Path::new(&dir))?;
    let cam = zwarp_raster::scenes::sponza_camera(1920, 1080)?;
    for _ in 0..8 {
        let (a, b, c, ts, tr) = zwarp_raster::pipeline_stats(&s, &cam, 0.0)?;
        println!("tris {a} setup {b} bin entries {c} setup {ts:.2} ms raster {tr:.2} ms");
    }
    Ok(())
}
