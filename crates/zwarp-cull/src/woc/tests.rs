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
