//! Where L = b layers lose to L = a on one frame pair of a path (issue: more layers must never
//! hurt): per-pixel depth error of both predictions against the render, a histogram of
//! (state, chosen layer) for the pixels where b is worse by more than 5 % of the depth, and a
//! sample of them. Frames as `zwarp eval --frames 4` picks them (`which` in 0..=3), the paper's
//! hole protocol, umbra peeling, ground layer last when the scene has ground (and
//! `WarpParams::ground_layer` on for L >= 2, as `zwarp eval` runs it).
//!
//! `layer_diag SCENE PATH.json W H N a b which` (`ROW=y` also prints columns 178..216 of row y,
//! `COLS=a..b` others;
//! `SPEED=s` takes the frames at `zwarp eval --speed s`, `FRAMES=f` as `zwarp eval --frames f`, `NOSIMD=1` runs the portable kernels,
//! `SQERR=cap` sums the change of the squared depth error per (state, layer) transition over all
//! pixels, errors capped at `cap` metres, `LISTC0F=1` with it lists the pixels layer 0 solved in
//! run a that run b filled).
use zwarp_core::{motion_field, Image};
use zwarp_raster::{render_frame, render_source_layers, FrameOptions, UmbraPeeling, ViewRegion};
use zwarp_scene::{load_scene, CameraPath, SceneOptions};
use zwarp_warp::{predict_into, WarpLayer, WarpOutput, WarpParams};

fn main() {
    let a: Vec<String> = std::env::args().collect();
    if a.len() != 9 {
        eprintln!("usage: layer_diag SCENE PATH.json W H N a b which");
        std::process::exit(1);
    }
    let (spec, pathf, w, h, n, la, lb, which): (&str, &str, u32, u32, u32, usize, usize, usize) = (
        &a[1],
        &a[2],
        a[3].parse().unwrap(),
        a[4].parse().unwrap(),
        a[5].parse().unwrap(),
        a[6].parse().unwrap(),
        a[7].parse().unwrap(),
        a[8].parse().unwrap(),
    );
    if std::env::var_os("NOSIMD").is_some() {
        zwarp_warp::simd::set_simd(false);
    }
    let loaded = load_scene(spec, &SceneOptions::default()).unwrap();
    let scene = &loaded.scene;
    let path = if pathf == "-" {
        loaded.path_or_default()
    } else {
        CameraPath::from_json_file_at(pathf, scene.origin).unwrap()
    };
    let speed: f32 = std::env::var("SPEED").map_or(1.0, |s| s.parse().unwrap());
    let total = path.frame_count_at(speed);
    let last = total - 2;
    // `zwarp eval --frames F` (FRAMES=F, default 4) spreads the pairs evenly over the path.
    let frames: usize = std::env::var("FRAMES").map_or(4, |f| f.parse().unwrap());
    let k = which * last / (frames - 1).max(1);
    let (ta, tb) = (path.time_of_frame(k, speed), path.time_of_frame(k + 1, speed));
    let (ca, cb) = (path.camera_at(ta, w, h).unwrap(), path.camera_at(tb, w, h).unwrap());
    let deltas = scene.object_deltas(ta, tb);
    let frame = render_frame(scene, &ca, ta, &FrameOptions::default()).unwrap();
    let reference = render_frame(scene, &cb, tb, &FrameOptions::default()).unwrap().depth;
    let e = (cb.eye() - ca.eye()).length() * 1.5;
    let has_ground = scene.instances.iter().any(|i| i.is_ground);
    let maxl = la.max(lb);
    // zwarp eval's protocol: the ground alone as the last layer.
    let umbra = Some(UmbraPeeling { region: ViewRegion::Disc { e, c: 0.0 } });
    let layers = render_source_layers(scene, &ca, ta, maxl.max(2), umbra).unwrap();
    let lm: Vec<(Image<f32>, Image<zwarp_core::Motion>)> = layers
        .iter()
        .map(|l| (l.depth.clone(), motion_field(&l.depth, Some(&l.items), &ca, &cb, &deltas).unwrap()))
        .collect();
    let single = (frame.depth.clone(), motion_field(&frame.depth, Some(&frame.items), &ca, &cb, &deltas).unwrap());
    let prefix = |l: usize| -> Vec<WarpLayer<'_>> {
        if l == 1 {
            return vec![WarpLayer { depth: &single.0, motion: &single.1 }];
        }
        let mut v: Vec<WarpLayer<'_>> = if has_ground {
            lm[..l - 1]
                .iter()
                .chain(std::iter::once(lm.last().unwrap()))
                .map(|(d, m)| WarpLayer { depth: d, motion: m })
                .collect()
        } else {
            lm[..l].iter().map(|(d, m)| WarpLayer { depth: d, motion: m }).collect()
        };
        v.truncate(l);
        v
    };
    let run = |l: usize| {
        let params = WarpParams {
            n_seeds: n,
            record_source: true,
            holes: zwarp_warp::HolePolicy::PAPER,
            ground_layer: has_ground && l >= 2,
            ..WarpParams::default()
        };
        let mut o = WarpOutput::empty();
        predict_into(&prefix(l), &params, Vec::new(), &mut o).unwrap();
        o
    };
    let (oa, ob) = (run(la), run(lb));
    for l in [la, lb] {
        println!("L{l} limits {:?}", zwarp_warp::holes::BackgroundLimits::of(&prefix(l), w, h, 64).unwrap());
    }
    let lin = |d: f32| if d >= 1.0 { cb.far } else { cb.linear_depth(d) };
    let qa = zwarp_metrics::depth_quality(&oa.depth, &reference, &cb).unwrap();
    let qb = zwarp_metrics::depth_quality(&ob.depth, &reference, &cb).unwrap();
    println!(
        "frame k={k}: L{la} psnr {:.3} ssim {:.5} | L{lb} psnr {:.3} ssim {:.5}",
        qa.psnr, qa.ssim, qb.psnr, qb.ssim
    );
    // pixels where b is worse
    let mut worse = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let r = lin(*reference.get(x, y));
            let ea = (lin(*oa.depth.get(x, y)) - r).abs();
            let eb = (lin(*ob.depth.get(x, y)) - r).abs();
            if eb > ea + 0.05 * r {
                worse.push((x, y, ea, eb));
            }
        }
    }
    let better = (0..w * h)
        .filter(|&i| {
            let (x, y) = (i % w, i / w);
            let r = lin(*reference.get(x, y));
            (lin(*oa.depth.get(x, y)) - r).abs() > (lin(*ob.depth.get(x, y)) - r).abs() + 0.05 * r
        })
        .count();
    println!("worse pixels: {} better pixels: {}", worse.len(), better);
    let sa = oa.source.as_ref().unwrap();
    let sb = ob.source.as_ref().unwrap();
    let mut hist = std::collections::BTreeMap::new();
    for &(x, y, _, _) in &worse {
        let key = (
            format!("{:?}", oa.state.get(x, y)),
            sa.get(x, y).layer as i64,
            format!("{:?}", ob.state.get(x, y)),
            sb.get(x, y).layer as i64,
        );
        *hist.entry(key).or_insert(0) += 1;
    }
    for (k, v) in &hist {
        println!("  a {:?}/{} -> b {:?}/{}: {v}", k.0, k.1, k.2, k.3);
    }
    if std::env::var_os("SQERR").is_some() {
        // Per (state, layer) transition over all pixels: the change of the squared linear-depth
        // error, errors clamped at SQERR metres (the metric normalises by the surface range).
        let cap: f32 = std::env::var("SQERR").unwrap().parse().unwrap_or(100.0);
        let mut acc = std::collections::BTreeMap::new();
        for y in 0..h {
            for x in 0..w {
                let r = lin(*reference.get(x, y));
                let ea = (lin(*oa.depth.get(x, y)) - r).abs().min(cap);
                let eb = (lin(*ob.depth.get(x, y)) - r).abs().min(cap);
                if ea == eb {
                    continue;
                }
                let key = (
                    format!("{:?}", oa.state.get(x, y)),
                    sa.get(x, y).layer as i64,
                    format!("{:?}", ob.state.get(x, y)),
                    sb.get(x, y).layer as i64,
                );
                if std::env::var_os("LISTC0F").is_some() && key.0 == "Converged" && key.2 == "Filled" && key.1 == 0 {
                    println!(
                        "    C0F ({x},{y}) ref {r:.2} a {:.2} b {:.2} q {:?}",
                        lin(*oa.depth.get(x, y)),
                        lin(*ob.depth.get(x, y)),
                        sa.get(x, y).q
                    );
                }
                let e = acc.entry(key).or_insert((0usize, 0f64));
                e.0 += 1;
                e.1 += (eb * eb - ea * ea) as f64;
            }
        }
        for (k, (n, d)) in &acc {
            println!("  SQERR a {:?}/{} -> b {:?}/{}: {n} px, sum d(err^2) {d:.1}", k.0, k.1, k.2, k.3);
        }
    }
    if let Ok(row) = std::env::var("ROW") {
        let y: u32 = row.parse().unwrap();
        let cols = std::env::var("COLS").unwrap_or_else(|_| "178..216".into());
        let (c0, c1) = cols.split_once("..").expect("COLS=a..b");
        for x in c0.parse::<u32>().unwrap()..c1.parse::<u32>().unwrap() {
            let st = |o: &WarpOutput| format!("{:?}", o.state.get(x, y)).chars().next().unwrap();
            println!(
                "  x{x}: ref {:.2} | a {:.2} {} l{:>2} | b {:.2} {} l{:>2}",
                lin(*reference.get(x, y)),
                lin(*oa.depth.get(x, y)),
                st(&oa),
                sa.get(x, y).layer as i32,
                lin(*ob.depth.get(x, y)),
                st(&ob),
                sb.get(x, y).layer as i32
            );
        }
    }
    if let Ok(d) = std::env::var("DETAIL") {
        // Both layers' samples along the source column through `q` of pixel DETAIL=x,y.
        let (x, y) = d.split_once(',').expect("DETAIL=x,y");
        let (x, y): (u32, u32) = (x.parse().unwrap(), y.parse().unwrap());
        let q = sb.get(x, y).q;
        println!("DETAIL p ({x},{y}) q {q:?} layer {}", sb.get(x, y).layer);
        let qx = q.x as u32;
        let qy = std::env::var("DROW").ok().map(|r| r.parse::<u32>().unwrap());
        let cells: Vec<(u32, u32)> = match qy {
            Some(r) => {
                let c0 = std::env::var("DCOL").map_or(qx, |c| c.parse().unwrap());
                (c0..(c0 + 6).min(w)).flat_map(|c| (r..r + 4).map(move |rr| (c, rr))).collect()
            }
            None => (0..(q.y as u32 + 3).min(h)).map(|r| (qx, r)).collect(),
        };
        for (qx, sy) in cells {
            let row: Vec<String> = lm
                .iter()
                .take(2)
                .map(|(dd, m)| {
                    let z = *dd.get(qx, sy);
                    let mv = m.get(qx, sy);
                    format!(
                        "z {:6.2} v ({:7.2},{:7.2}) -> ({:7.2},{:7.2})",
                        if z >= 1.0 { -1.0 } else { ca.linear_depth(z) },
                        mv.v.x,
                        mv.v.y,
                        qx as f32 + 0.5 + mv.v.x,
                        sy as f32 + 0.5 + mv.v.y
                    )
                })
                .collect();
            println!("  ({qx},{sy}): {}", row.join(" | "));
        }
    }
    if let Ok(d) = std::env::var("PROBE") {
        // Where the reference surface of target pixel PROBE=x,y lies in the source view, and what
        // each source layer holds there.
        let (x, y) = d.split_once(',').expect("PROBE=x,y");
        let (x, y): (u32, u32) = (x.parse().unwrap(), y.parse().unwrap());
        let world = cb.unproject(x as f32 + 0.5, y as f32 + 0.5, *reference.get(x, y));
        let s = ca.project(world);
        println!("PROBE ({x},{y}) ref {:.3} world {world:?} in source {s:?}", lin(*reference.get(x, y)));
        if let Some(s) = s {
            if s.x >= 0.0 && s.y >= 0.0 && (s.x as u32) < w && (s.y as u32) < h {
                for (j, (dd, _)) in lm.iter().enumerate() {
                    let z = *dd.get(s.x as u32, s.y as u32);
                    println!(
                        "  layer {j}: {:.3} (surface at {:.3})",
                        if z >= 1.0 { -1.0 } else { ca.linear_depth(z) },
                        ca.linear_depth(s.z)
                    );
                }
            }
        }
    }
    if std::env::var_os("CMP0").is_some() {
        // Does the peeled layer 0 equal the plain frame (L = 1's input)?
        let (a0, b0) = (&single.0, &lm[0].0);
        let differ = a0.data().iter().zip(b0.data()).filter(|(x, y)| x != y).count();
        let mdiff = single.1.data().iter().zip(lm[0].1.data()).filter(|(x, y)| x != y).count();
        println!("CMP0 depth texels differing: {differ}, motion texels differing: {mdiff}");
    }
    if let Ok(d) = std::env::var("COVER") {
        // The b-run candidate at pixel COVER=x,y and what the front layers hold at its source
        // position and one fixed-point step from there (Kernel::covered_at_source).
        let (x, y) = d.split_once(',').expect("COVER=x,y");
        let (x, y): (u32, u32) = (x.parse().unwrap(), y.parse().unwrap());
        let p = glam::Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
        let c = sb.get(x, y);
        println!("COVER p {p:?} b layer {} q {:?} depth {:.3}", c.layer, c.q, lin(*ob.depth.get(x, y)));
        let layers = prefix(lb);
        for (j, l) in layers.iter().enumerate().take(c.layer as usize + 1) {
            let step = if c.layer as usize > j {
                let m = l.motion.get(c.q.x as u32, c.q.y as u32);
                Some(p - m.v)
            } else {
                None
            };
            for (what, q) in std::iter::once(("at q", c.q)).chain(step.map(|s| ("one step", s))) {
                let (qx, qy) = (q.x as u32, q.y as u32);
                for (ox, oy) in [(0i32, 0i32), (-1, 0), (1, 0), (0, -1), (0, 1)] {
                    let (tx, ty) = ((qx as i32 + ox) as u32, (qy as i32 + oy) as u32);
                    let m = l.motion.get(tx, ty);
                    let z = *l.depth.get(tx, ty);
                    let land = glam::Vec2::new(tx as f32 + 0.5, ty as f32 + 0.5) + m.v;
                    println!(
                        "  layer {j} {what} texel ({tx},{ty}): z {:.3} v {:?} lands {:?} (dist {:.2})",
                        if z >= 1.0 { -1.0 } else { ca.linear_depth(z) },
                        m.v,
                        land,
                        (land - p).length()
                    );
                }
            }
        }
    }
    if let Ok(d) = std::env::var("TRACE") {
        // Layer 0's (single-layer) search at pixel TRACE=x,y: global-frame tight bound, seeds, walks.
        use zwarp_warp::sampling::{LayerSampler, MotionSource, SamplePlanes, Sampling};
        let (x, y) = d.split_once(',').expect("TRACE=x,y");
        let (x, y): (u32, u32) = (x.parse().unwrap(), y.parse().unwrap());
        let p = glam::Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
        let planes = SamplePlanes::from_motion(single.1.data());
        let ls = LayerSampler::new(&planes, w, h, Sampling::Adaptive, 0);
        // The preparation's pyramid (identity frame, image clip), as the warp's.
        let prepared = zwarp_warp::PreparedLayer::new(
            &WarpLayer { depth: &single.0, motion: &single.1 },
            zwarp_warp::BoundKind::Tight,
        )
        .unwrap();
        let pyr = prepared.pyramid();
        let tb = pyr.tight_bound(p, 6, 0.5);
        println!("TRACE p {p:?} tight {:?}", tb.map(|t| (t.motion, t.region)));
        let extra: Vec<glam::Vec2> = std::env::var("SEEDS")
            .ok()
            .map(|s| {
                s.split(';')
                    .map(|t| {
                        let (a, b) = t.split_once(',').unwrap();
                        glam::Vec2::new(a.parse().unwrap(), b.parse().unwrap())
                    })
                    .collect()
            })
            .unwrap_or_default();
        let mut seeds = extra;
        if let Some(t) = tb {
            let mut buf = [glam::Vec2::ZERO; 64];
            let n = zwarp_warp::search::stratified_seeds(
                &pyr.frame(),
                &t.region,
                4,
                zwarp_warp::search::seed_key(x, y, 0),
                &mut buf,
            );
            seeds.extend_from_slice(&buf[..n]);
        }
        for s0 in seeds {
            let mut q = s0;
            print!("  seed {q:?}:");
            for _ in 0..6 {
                let Some(s) = ls.sample(q, &mut ()) else {
                    print!(" out/empty");
                    break;
                };
                let step = p - s.v - q;
                print!(
                    " [q ({:.2},{:.2}) z {:.3} smooth {} r {:.3}]",
                    q.x,
                    q.y,
                    ca.linear_depth(s.depth.min(0.999999)),
                    s.smooth,
                    step.length()
                );
                q = match zwarp_warp::search::newton_step(&s, step) {
                    Some(d) => q + d,
                    None => p - s.v,
                };
            }
            println!();
        }
    }
    if let Ok(f) = std::env::var("DUMP") {
        // Raw little-endian f32 planes: reference, a, b linear depths; a, b states; b layer.
        let mut out = Vec::new();
        let planes: [&dyn Fn(u32, u32) -> f32; 6] = [
            &|x, y| lin(*reference.get(x, y)),
            &|x, y| lin(*oa.depth.get(x, y)),
            &|x, y| lin(*ob.depth.get(x, y)),
            &|x, y| *oa.state.get(x, y) as u8 as f32,
            &|x, y| *ob.state.get(x, y) as u8 as f32,
            &|x, y| sb.get(x, y).layer as i32 as f32,
        ];
        for pl in planes {
            for y in 0..h {
                for x in 0..w {
                    out.extend_from_slice(&pl(x, y).to_le_bytes());
                }
            }
        }
        std::fs::write(f, out).unwrap();
    }
    for &(x, y, ea, eb) in worse.iter().step_by((worse.len() / 12).max(1)) {
        let r = lin(*reference.get(x, y));
        println!(
            "  ({x},{y}) ref {r:.3} a {:.3} ({:?} l{} q {:?}) b {:.3} ({:?} l{} q {:?}) err {ea:.3} -> {eb:.3}",
            lin(*oa.depth.get(x, y)),
            oa.state.get(x, y),
            sa.get(x, y).layer,
            sa.get(x, y).q,
            lin(*ob.depth.get(x, y)),
            ob.state.get(x, y),
            sb.get(x, y).layer,
            sb.get(x, y).q
        );
    }
}
