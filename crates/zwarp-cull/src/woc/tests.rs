//! Tests of the WOC pipeline and its parts.

use super::*;
use zwarp_raster::draw_into;

#[test]
fn exact_draw_at_a_coarse_resolution_is_the_max_reduction_of_the_fine_draw() {
    // A sloped quad and a small copy in front of it over a far prediction, at 1/3 of an odd size
    // (97x61: the footprints straddle fine pixels): every coarse value must be the max of
    // the full-resolution drawing over its footprint (far where any fine pixel is
    // uncovered), min with what was predicted there.
    use zwarp_core::{Animation, Mesh};
    let mut s = Scene { name: "exact".into(), ..Default::default() };
    let quad = Mesh::new(
        vec![
            Vec3::new(-2.0, -1.0, -1.0),
            Vec3::new(2.0, -1.0, 1.0),
            Vec3::new(2.0, 1.0, 1.0),
            Vec3::new(-2.0, 1.0, -1.0),
        ],
        vec![[0, 1, 2], [0, 2, 3]],
    )
    .unwrap();
    let q = s.add_mesh(quad);
    s.add_instance(q, glam::Mat4::IDENTITY, Vec3::ONE, Animation::Static, false);
    s.add_instance(
        q,
        glam::Mat4::from_scale_rotation_translation(Vec3::splat(0.2), glam::Quat::IDENTITY, Vec3::new(0.5, 0.3, 1.5)),
        Vec3::ONE,
        Animation::Static,
        false,
    );
    let cam = Camera::perspective(Vec3::new(0.3, 0.2, 6.0), Vec3::ZERO, Vec3::Y, 0.9, 0.5, 50.0, 97, 61).unwrap();
    let coarse = coarse_camera(&cam, 3);
    let mut predicted = Image::new(coarse.width, coarse.height, 0.999f32);
    *predicted.get_mut(16, 10) = 0.5; // a near prediction the draw must not raise
    let before = predicted.clone();
    draw_exact(&mut predicted, &s, &cam, 0.0, &[0, 1]).unwrap();
    let mut fine = Image::new(cam.width, cam.height, EMPTY_DEPTH);
    draw_into(&mut fine, None, &s, &cam, 0.0, &[0, 1]).unwrap();
    let items = Image::new(cam.width, cam.height, 0u32);
    let (reduced, _) = downsample_max(&fine, &items, coarse.width, coarse.height).unwrap();
    let mut lowered = 0;
    for i in 0..predicted.len() {
        assert_eq!(predicted.data()[i], before.data()[i].min(reduced.data()[i]), "texel {i}");
        lowered += usize::from(predicted.data()[i] < before.data()[i]);
    }
    assert!(lowered > 50, "the quad covers ~15 % of the view: {lowered} texels lowered");
    // At full resolution it is the plain depth-tested draw.
    let mut full = Image::new(cam.width, cam.height, 0.999f32);
    draw_exact(&mut full, &s, &cam, 0.0, &[0, 1]).unwrap();
    let mut direct = Image::new(cam.width, cam.height, 0.999f32);
    draw_into(&mut direct, None, &s, &cam, 0.0, &[0, 1]).unwrap();
    assert_eq!(full, direct);
}

#[test]
fn hull_slack_shrinks_to_fine_centres_only_at_exact_divisors() {
    let cam = Camera::perspective(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 1.0, 0.1, 50.0, 960, 540).unwrap();
    assert_eq!(hull_slack(&cam, &cam), 0.01 - 0.5);
    assert_eq!(hull_slack(&coarse_camera(&cam, 4), &cam), 0.01 - 0.125);
    assert_eq!(hull_slack(&coarse_camera(&cam, 6), &cam), 0.01 - 0.5 / 6.0);
    // 540 / 8 = 67.5: the coarse rows straddle fine rows, the whole square counts.
    assert_eq!(hull_slack(&coarse_camera(&cam, 8), &cam), 0.01);
    let odd = cam.with_size(97, 61).unwrap();
    assert_eq!(hull_slack(&coarse_camera(&odd, 2), &odd), 0.01);
}

#[test]
fn opening_rim_dirs_skipping_whole_groups_equals_the_per_texel_test() {
    // Blocky items (objects a few texels wide, empty and NO_ITEM patches among them), random
    // depths and motions with separations around the threshold: the groups of eight texels
    // that `opening_rim_dirs` skips must be exactly those with no rim, at widths below, at and
    // past a group and at the image borders.
    use super::rims::rim_mask;
    use zwarp_core::{Motion, NO_ITEM};
    let mut r = zwarp_testkit::rng(11);
    for (w, h, bw, bh) in [
        (1u32, 1u32, 3u32, 2u32),
        (3, 2, 3, 2),
        (9, 5, 3, 2),
        (10, 3, 3, 2),
        (17, 9, 3, 2),
        (33, 21, 3, 2),
        (64, 40, 3, 2),
        (64, 40, 11, 7),
        (97, 61, 13, 9),
    ] {
        // Blocks of bw x bh texels, wide ones leaving groups whose only other item is a
        // single diagonal neighbour.
        let blocks = (w.div_ceil(bw), h.div_ceil(bh));
        let ids: Vec<u32> = (0..blocks.0 * blocks.1)
            .map(|_| match r() {
                v if v < 0.1 => NO_ITEM,
                v => (v * 6.0) as u32,
            })
            .collect();
        let items =
            Image::from_vec(w, h, (0..w * h).map(|i| ids[((i / w / bh) * blocks.0 + i % w / bw) as usize]).collect())
                .unwrap();
        let depth =
            Image::from_vec(w, h, (0..w * h).map(|_| if r() < 0.05 { EMPTY_DEPTH } else { r() }).collect()).unwrap();
        let motion = Image::from_vec(
            w,
            h,
            (0..w * h).map(|_| Motion { v: glam::Vec2::new(r() - 0.5, r() - 0.5), depth: r() }).collect(),
        )
        .unwrap();
        let dirs = opening_rim_dirs(&depth, &items, &motion, 0.1).unwrap();
        let per_texel: Vec<u8> = (0..h as usize)
            .flat_map(|y| (0..w as usize).map(move |x| (x, y)))
            .map(|p| rim_mask(depth.data(), items.data(), motion.data(), (w, h), p, 0.1))
            .collect();
        assert_eq!(dirs.data(), &per_texel[..], "{w}x{h}");
        if w * h > 100 {
            assert!(per_texel.iter().any(|&m| m != 0), "{w}x{h}: no rim to find");
        }
    }
    // One farther texel of another item, separating from a uniform surface, seen by the first
    // or the last texel of a group through each of the eight neighbour directions alone.
    let (w, h) = (19u32, 5u32);
    for &(dx, dy) in NEIGHBOURS.iter() {
        for lane in [1i32, 8, 9, 16] {
            let (sx, sy) = ((lane + dx) as u32, (2 + dy) as u32);
            let at = |i: u32| i == sy * w + sx;
            let items = Image::from_vec(w, h, (0..w * h).map(|i| if at(i) { 2 } else { 1 }).collect()).unwrap();
            let depth = Image::from_vec(w, h, (0..w * h).map(|i| if at(i) { 0.6 } else { 0.3 }).collect()).unwrap();
            let away = glam::Vec2::new(-dx as f32, -dy as f32);
            let motion = Image::from_vec(
                w,
                h,
                (0..w * h).map(|i| Motion { v: if at(i) { glam::Vec2::ZERO } else { away }, depth: 0.3 }).collect(),
            )
            .unwrap();
            let dirs = opening_rim_dirs(&depth, &items, &motion, 0.1).unwrap();
            let k = NEIGHBOURS.iter().position(|&n| n == (dx, dy)).unwrap();
            assert_eq!(*dirs.get(lane as u32, 2), 1 << k, "direction ({dx}, {dy}) from texel {lane}");
        }
    }
}
