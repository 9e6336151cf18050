//! Times the colour warps on a synthetic 1280x720 frame (smooth motion with discontinuous
//! blocks) next to the streaming floor: `cargo run --release -p zwarp-tools --bin speed`.

use glam::Vec2;
use zwarp_color::*;
use zwarp_core::{Image, Motion};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let (w, h) = (1280u32, 720u32);
    let depth = Image::from_fn(w, h, |x, y| if (x / 97 + y / 61) % 4 == 0 { 0.3 } else { 0.9 });
    let m = Image::from_fn(w, h, |x, y| {
        let near = *depth.get(x, y) < 0.5;
        Motion { v: if near { Vec2::new(6.3, -1.2) } else { Vec2::new(-2.1 + 0.001 * x as f32, 0.4) }, depth: 0.5 }
    });
    let color = Image::from_fn(w, h, |x, y| [(x % 17) as f32 / 17.0, (y % 13) as f32 / 13.0, 0.5]);
    let b = WarpBasis::temporal(&depth, &m).unwrap();
    let f = b.field(FieldParams::temporal(0.5)).unwrap();
    let reps = 30;
    let time = |name: &str, run: &mut dyn FnMut()| {
        run();
        let t: Vec<f64> = (0..reps)
            .map(|_| {
                let t0 = std::time::Instant::now();
                run();
                t0.elapsed().as_secs_f64() * 1e3
            })
            .collect();
        let m = median(t);
        println!("{name:<24} {m:8.3} ms");
        m
    };
    let mut out = ColorWarpOutput::empty();
    let mut fo = Image::new(0, 0, [0.0f32; 3]);
    let floor = time("floor", &mut || floor::floor_pass(&f, &color, &mut fo).unwrap());
    let hp = HeuristicParams::default();
    let hs = time("heuristic (lanes)", &mut || heuristic_warp_into(&f, &color, &hp, &mut out).unwrap());
    set_simd(false);
    time("heuristic (portable)", &mut || heuristic_warp_into(&f, &color, &hp, &mut out).unwrap());
    set_simd(true);
    let rp = RobustParams::default();
    let rs = time("robust", &mut || {
        robust_warp_with(&Subdivision::of_field(&f, 16).unwrap(), &f, &color, &rp, &mut out).unwrap();
    });
    time("rho cells", &mut || {
        std::hint::black_box(rho_cells(&f));
    });
    let sub = Subdivision::of_field(&f, 16).unwrap();
    println!("quads {}", sub.leaves().len());
    time("subdivision", &mut || {
        std::hint::black_box(Subdivision::of_field(&f, 16).unwrap());
    });
    time("robust raster only", &mut || {
        robust_warp_with(&sub, &f, &color, &rp, &mut out).unwrap();
    });
    println!("heuristic / floor {:.1}, robust / heuristic {:.1}", hs / floor, rs / hs);
}
