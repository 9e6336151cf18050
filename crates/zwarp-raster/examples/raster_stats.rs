//! Pipeline statistics of Sponza (set-up vs raster split), for profiling. Reports process CPU
//! time (all threads, Linux schedstat) per call, which stays meaningful on a loaded machine.
fn cpu_ms() -> f64 {
    let mut total = 0u64;
    for t in std::fs::read_dir("/proc/self/task").unwrap() {
        let s = std::fs::read_to_string(t.unwrap().path().join("schedstat")).unwrap();
        total += s.split_whitespace().next().unwrap().parse::<u64>().unwrap();
    }
    total as f64 / 1e6
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

fn main() -> zwarp_core::Result<()> {
    let dir = std::env::args().nth(1).unwrap_or_else(|| "/work/shared/scenes/sponza".into());
    let s = zwarp_raster::scenes::load_raw_sponza(std::path::Path::new(&dir))?;
    let cam = zwarp_raster::scenes::sponza_camera(1920, 1080)?;
    let (a, b, c, _, _) = zwarp_raster::pipeline_stats(&s, &cam, 0.0)?;
    println!("source tris {a}, set-up tris {b}, bin entries {c}");
    let (mut full, mut setup) = (Vec::new(), Vec::new());
    for _ in 0..15 {
        let t0 = cpu_ms();
        std::hint::black_box(zwarp_raster::render_depth(&s, &cam, 0.0)?);
        let t1 = cpu_ms();
        std::hint::black_box(zwarp_raster::setup_only(&s, &cam, 0.0)?);
        let t2 = cpu_ms();
        full.push(t1 - t0);
        setup.push(t2 - t1);
    }
    let (f, st) = (median(full), median(setup));
    println!("CPU ms per depth render: {f:.2} (set-up {st:.2}, raster {:.2})", f - st);
    Ok(())
}
