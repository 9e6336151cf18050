//! Diagnostic: compare warped sample maps with rasterized ones on the square-over-plane scene.
use glam::{Mat4, Vec3};
use zwarp_core::{Animation, AreaLight, LightShape, Mesh, Scene};
use zwarp_shadows::*;

fn quad(x0: f32, x1: f32, y0: f32, y1: f32, z: f32) -> Mesh {
    Mesh::new(
        vec![Vec3::new(x0, y0, z), Vec3::new(x1, y0, z), Vec3::new(x1, y1, z), Vec3::new(x0, y1, z)],
        vec![[0, 1, 2], [0, 2, 3]],
    )
    .unwrap()
}

fn main() {
    let mut s = Scene::default();
    let m = s.add_mesh(quad(-8.0, 8.0, -8.0, 8.0, 0.0));
    s.add_instance(m, Mat4::IDENTITY, Vec3::ONE, Animation::Static, true);
    let m = s.add_mesh(quad(-2.0, 2.0, -2.0, 2.0, 5.0));
    s.add_instance(m, Mat4::IDENTITY, Vec3::ONE, Animation::Static, false);
    let light = AreaLight {
        center: Vec3::new(0.0, 0.0, 10.0),
        target: Vec3::ZERO,
        up: Vec3::Y,
        shape: LightShape::Disc { radius: 1.0 },
        directional: false,
    };
    let p = ShadowParams { samples: 16, sm_size: 512, jitter: false, ..ShadowParams::default() };
    let rig = LightRig::new(&s, 0.0, &light, 16, 512, 1, false).unwrap();
    let mut zm = ZwarpMaps::new(&s, &rig, 0.0, &p).unwrap();
    for l in zm.layers() {
        println!("layer coverage {}", l.coverage());
    }
    let cam = zwarp_core::Camera::orthographic(Vec3::new(0.0, 0.0, 20.0), Vec3::ZERO, Vec3::Y, 0.4, 1.0, 40.0, 240, 16)
        .unwrap();
    for (thr, it) in [(0.5, 3), (0.25, 3), (0.1, 3), (0.1, 5), (0.05, 5)] {
        let p2 = ShadowParams {
            samples: 256,
            sm_size: 512,
            jitter: false,
            threshold: thr,
            iterations: it,
            ..ShadowParams::default()
        };
        let a = run_shadows(&s, &cam, 0.0, &light, Method::Zwarp, &p2).unwrap();
        let b = run_shadows(&s, &cam, 0.0, &light, Method::Reference, &p2).unwrap();
        let d: Vec<f32> = a.visibility.data().iter().zip(b.visibility.data()).map(|(x, y)| (x - y) * 256.0).collect();
        println!(
            "thr {thr} T {it}: max {} min {} mean {} holes {} ms {:.0} vs {:.0}",
            d.iter().cloned().fold(-1e9, f32::max),
            d.iter().cloned().fold(1e9, f32::min),
            d.iter().sum::<f32>() / d.len() as f32,
            a.warp_holes,
            a.ms,
            b.ms
        );
    }
    for i in [0usize, 5, 15] {
        let r = render_sample_map(&s, &rig, 0.0, i).unwrap();
        let z = zm.map(i).unwrap();
        let (c, f, h) = z.counts();
        let (mut nearer, mut farther) = (0, 0);
        let mut examples = vec![];
        for (k, (a, b)) in z.depth.data().iter().zip(r.data()).enumerate() {
            if (a - b).abs() > 1e-3 {
                if a < b {
                    nearer += 1
                } else {
                    farther += 1
                }
                if examples.len() < 6 {
                    examples.push((k % 512, k / 512, *a, *b));
                }
            }
        }
        println!("sample {i} off {:?} shift {:?}: conv {c} filled {f} holes {h}; warped nearer {nearer} farther {farther} {:?}", rig.offsets[i], rig.shifts[i], examples);
    }
}

#[allow(dead_code)]
fn unused() {}
