//! WOC pipeline tests (seed 000 Sec. 5, thesis seed 002 Sec. III-V) on small hand-built scenes
//! rendered with zwarp-raster at non-power-of-two sizes.

use glam::{Mat4, Vec3};
use zwarp_core::{motion_field, Aabb, Animation, Camera, Image, Mesh, Scene};
use zwarp_cull::{
    aabb_triangles, accuracy, coarse_camera, cull_against_depth, culled_visible, downsample_max, hybrid_cull,
    ideal_screen_space, lastframe, nocull, open_rims_in_target, opening_rim_dirs, opening_rims, reference,
    run_sequence, run_sequence_repeated, screen_rect, screen_speed, summarize, twophase, vfc_cull, visible_from_items,
    woc, woc_motion_field, woc_objects, BoxObject, MaxDepthKind, Method, PrevFrame, RimMode, ScreenRect, WocParams,
};
use zwarp_raster::{any_fragment_visible, render_frame, FrameOptions};
use zwarp_warp::{warp_depth, WarpLayer, WarpParams};

const W: u32 = 96;
const H: u32 = 61;
const DT: f32 = 1.0 / 30.0;

/// A scene whose objects are axis-aligned boxes (mesh 0 = unit cube scaled per instance).
fn scene_of(boxes: &[(Aabb, Animation)]) -> Scene {
    let unit = Aabb::new(Vec3::ZERO, Vec3::ONE);
    let positions = unit.corners().to_vec();
    let indices: Vec<[u32; 3]> = aabb_triangles(&unit)
        .iter()
        .map(|t| t.map(|p| positions.iter().position(|q| *q == p).unwrap() as u32))
        .collect();
    let mut s = Scene { name: "boxes".into(), up: Vec3::Y, ..Scene::default() };
    let m = s.add_mesh(Mesh::new(positions, indices).unwrap());
    for (b, anim) in boxes {
        let tr = Mat4::from_translation(b.min) * Mat4::from_scale(b.extent());
        s.add_instance(m, tr, Vec3::ONE, *anim, false);
    }
    s
}

fn bx(min: [f32; 3], max: [f32; 3]) -> (Aabb, Animation) {
    (Aabb::new(Vec3::from(min), Vec3::from(max)), Animation::Static)
}

fn cam_at(eye: Vec3, target: Vec3) -> Camera {
    Camera::perspective(eye, target, Vec3::Y, 1.0, 0.1, 100.0, W, H).unwrap()
}

/// Renders the previous frame and runs WOC for the current one; returns (WOC, REF) visible sets.
fn run(
    scene: &Scene,
    prev_cam: &Camera,
    t_prev: f32,
    cam: &Camera,
    t: f32,
    params: &WocParams,
) -> (Vec<u32>, Vec<u32>) {
    let prev = render_frame(scene, prev_cam, t_prev, &FrameOptions::default()).unwrap();
    let pf = PrevFrame { depth: &prev.depth, items: &prev.items, cam: prev_cam, t: t_prev };
    let r = woc(scene, &pf, cam, t, params).unwrap();
    let reference = reference(scene, cam, t).unwrap();
    (r.visible, reference.visible)
}

/// The wall (id 0), an object fully behind it (id 1), an object beside it (id 2).
fn wall_scene() -> Scene {
    scene_of(&[
        bx([-6.0, -4.0, -0.2], [6.0, 4.0, 0.2]),
        bx([-1.0, -1.0, -5.0], [1.0, 1.0, -3.0]),
        bx([9.0, -1.0, -4.0], [10.0, 1.0, -3.0]),
    ])
}

#[test]
fn object_fully_behind_a_wall_is_culled() {
    let s = wall_scene();
    let prev = cam_at(Vec3::new(0.3, 0.1, 10.0), Vec3::new(0.3, 0.1, 0.0));
    let cur = cam_at(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO);
    let (v, r) = run(&s, &prev, 0.0, &cur, DT, &WocParams::default());
    assert_eq!(r, vec![0, 2]);
    assert_eq!(v, vec![0, 2], "the hidden box is culled, the wall and the side box are kept");
}

#[test]
fn sliver_visible_through_a_gap_is_kept() {
    // Two wall halves with a 0.3-unit gap (about 2 pixels on screen) and a box behind it.
    let s = scene_of(&[
        bx([-6.0, -4.0, -0.2], [-0.15, 4.0, 0.2]),
        bx([0.15, -4.0, -0.2], [6.0, 4.0, 0.2]),
        bx([-1.0, -1.0, -5.0], [1.0, 1.0, -3.0]),
    ]);
    let prev = cam_at(Vec3::new(0.1, 0.0, 10.0), Vec3::new(0.1, 0.0, 0.0));
    let cur = cam_at(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO);
    for erosion in [true, false] {
        let params = WocParams { erosion, ..WocParams::default() };
        let (v, r) = run(&s, &prev, 0.0, &cur, DT, &params);
        assert_eq!(r, vec![0, 1, 2], "REF sees the box through the gap");
        assert_eq!(v, vec![0, 1, 2], "erosion {erosion}");
    }
}

#[test]
fn object_crossing_the_near_plane_is_kept() {
    // A box reaching behind the eye at the side, and the wall; the rapid-motion path is off so
    // the near-plane rule alone must keep it.
    let s = scene_of(&[bx([-6.0, -4.0, -0.2], [6.0, 4.0, 0.2]), bx([0.5, -0.3, 8.0], [1.0, 0.3, 10.5])]);
    let prev = cam_at(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO);
    let params = WocParams { rapid_motion: None, ..WocParams::default() };
    let pf_frame = render_frame(&s, &prev, 0.0, &FrameOptions::default()).unwrap();
    let pf = PrevFrame { depth: &pf_frame.depth, items: &pf_frame.items, cam: &prev, t: 0.0 };
    let r = woc(&s, &pf, &prev, DT, &params).unwrap();
    assert_eq!(r.visible, vec![0, 1]);
    assert_eq!(r.stats.crosses_near, 1);
}

#[test]
fn dynamic_object_moving_out_from_behind_an_occluder_is_kept() {
    // Id 1 sits behind the wall at t = 0 and moves 11 units to the right within one frame.
    let v = Vec3::new(11.0 / DT, 0.0, 0.0);
    let s = scene_of(&[
        bx([-6.0, -4.0, -0.2], [6.0, 4.0, 0.2]),
        (Aabb::new(Vec3::new(-1.0, -1.0, -4.0), Vec3::new(0.0, 1.0, -3.0)), Animation::Linear { velocity: v }),
    ]);
    let cam = cam_at(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO);
    let prev = render_frame(&s, &cam, 0.0, &FrameOptions::default()).unwrap();
    assert_eq!(visible_from_items(&prev.items, 2), vec![0], "hidden in the previous frame");
    assert!(screen_speed(&s, 1, &cam, 0.0, &cam, DT) > 19.2);
    for rapid in [Some(19.2), None] {
        let params = WocParams { rapid_motion: rapid, ..WocParams::default() };
        let (vis, r) = run(&s, &cam, 0.0, &cam, DT, &params);
        assert_eq!(r, vec![0, 1]);
        assert_eq!(vis, vec![0, 1], "rapid path {rapid:?}");
    }
}

#[test]
fn visible_moving_occluder_uncovers_a_static_object() {
    // A small occluder (id 0) hides id 1 at t = 0 and moves away slowly (object deltas in the
    // motion field, below the rapid threshold): the warped occluder must not hide id 1.
    let v = Vec3::new(-2.0 / DT, 0.0, 0.0);
    let s = scene_of(&[
        (Aabb::new(Vec3::new(-1.5, -1.5, 1.0), Vec3::new(1.5, 1.5, 1.5)), Animation::Linear { velocity: v }),
        bx([-0.5, -0.5, -3.0], [0.5, 0.5, -2.0]),
        bx([-20.0, -20.0, -10.0], [20.0, 20.0, -9.5]),
    ]);
    let cam = cam_at(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO);
    let prev = render_frame(&s, &cam, 0.0, &FrameOptions::default()).unwrap();
    assert_eq!(visible_from_items(&prev.items, 3), vec![0, 2]);
    let params = WocParams { rapid_motion: None, ..WocParams::default() };
    let (vis, r) = run(&s, &cam, 0.0, &cam, DT, &params);
    assert_eq!(r, vec![0, 1, 2]);
    assert_eq!(vis, vec![0, 1, 2]);
}

/// Deterministic pseudo-random scene: a ground slab, 40 boxes of various sizes.
fn random_scene(seed: u64) -> Scene {
    let mut st = seed;
    let mut rnd = || {
        st = st.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((st >> 33) as f32) / (1u64 << 31) as f32
    };
    let mut boxes = vec![bx([-30.0, -1.0, -30.0], [30.0, 0.0, 30.0])];
    for _ in 0..40 {
        let c = Vec3::new(rnd() * 24.0 - 12.0, 0.0, rnd() * 24.0 - 12.0);
        let e = Vec3::new(0.6 + rnd() * 2.5, 0.6 + rnd() * 4.0, 0.6 + rnd() * 2.5);
        let anim = if rnd() < 0.3 {
            Animation::Linear { velocity: Vec3::new(rnd() * 6.0 - 3.0, 0.0, rnd() * 6.0 - 3.0) }
        } else {
            Animation::Static
        };
        boxes.push((Aabb::new(c - Vec3::new(e.x, 0.0, e.z) * 0.5, c + Vec3::new(e.x * 0.5, e.y, e.z * 0.5)), anim));
    }
    scene_of(&boxes)
}

#[test]
fn woc_is_conservative_along_a_camera_path_at_odd_sizes() {
    for (seed, (w, h)) in [(1u64, (97u32, 61u32)), (2, (64, 37)), (3, (53, 53))] {
        let s = random_scene(seed);
        let cams: Vec<Camera> = (0..6)
            .map(|k| {
                let a = 0.4 + k as f32 * 0.06;
                let eye = Vec3::new(18.0 * a.cos(), 2.5, 18.0 * a.sin());
                Camera::perspective(eye, Vec3::new(0.0, 1.0, 0.0), Vec3::Y, 1.0, 0.1, 100.0, w, h).unwrap()
            })
            .collect();
        let mut culled_any = false;
        for k in 1..cams.len() {
            let (tp, t) = ((k - 1) as f32 * DT, k as f32 * DT);
            let variants = [
                (MaxDepthKind::Mipmap, 1),
                (MaxDepthKind::NBuffer, 1),
                (MaxDepthKind::YMap { switch: 2 }, 1),
                (MaxDepthKind::YMap { switch: 2 }, 2),
                (MaxDepthKind::NBuffer, 3),
            ];
            for (kind, downsample) in variants {
                let params = WocParams { max_depth: kind, hybrid_min_triangles: 0, downsample, ..WocParams::default() };
                let (v, r) = run(&s, &cams[k - 1], tp, &cams[k], t, &params);
                let acc = accuracy(&v, &r, s.instances.len());
                assert_eq!(acc.false_negatives, 0, "seed {seed} frame {k} {kind:?} /{downsample}: {v:?} vs REF {r:?}");
                culled_any |= v.len() < vfc_cull(&s, &cams[k], t).unwrap().visible.len();
            }
            // The ideal screen-space test and two-phase culling are conservative too.
            let truth = reference(&s, &cams[k], t).unwrap();
            let ideal = ideal_screen_space(&s, truth.occlusion_map.as_ref().unwrap(), &cams[k], t).unwrap();
            assert_eq!(accuracy(&ideal.visible, &truth.visible, s.instances.len()).false_negatives, 0);
            let prev_ref = reference(&s, &cams[k - 1], tp).unwrap();
            let tp2 = twophase(&s, &prev_ref.visible, &cams[k], t, MaxDepthKind::NBuffer).unwrap();
            assert_eq!(accuracy(&tp2.visible, &truth.visible, s.instances.len()).false_negatives, 0);
            assert_eq!(&tp2.depth, truth.occlusion_map.as_ref().unwrap(), "two passes draw the whole visible set");
        }
        assert!(culled_any, "seed {seed}: occlusion culling removed nothing beyond VFC");
    }
}

/// An engine's plain boxes (`woc_objects` over [`BoxObject`]s: object-space box, previous and
/// current transform, ids = the item buffer's) cull exactly as the scene they bound wherever
/// the scene pipeline takes no step that needs triangles, and stay conservative with the
/// rapid-motion test on (rapid objects kept visible without being drawn).
#[test]
fn plain_boxes_cull_like_the_scene_they_bound() {
    for seed in [1u64, 2, 3] {
        let s = random_scene(seed);
        let cams: Vec<Camera> = (0..4)
            .map(|k| {
                let a = 0.4 + k as f32 * 0.06;
                let eye = Vec3::new(18.0 * a.cos(), 2.5, 18.0 * a.sin());
                Camera::perspective(eye, Vec3::new(0.0, 1.0, 0.0), Vec3::Y, 1.0, 0.1, 100.0, 97, 61).unwrap()
            })
            .collect();
        for k in 1..cams.len() {
            let (tp, t) = ((k - 1) as f32 * DT, k as f32 * DT);
            let boxes: Vec<BoxObject> = s
                .instances
                .iter()
                .map(|i| BoxObject {
                    bounds: s.meshes[i.mesh as usize].bounds,
                    prev_transform: i.transform_at(tp),
                    transform: i.transform_at(t),
                })
                .collect();
            let prev = render_frame(&s, &cams[k - 1], tp, &FrameOptions::default()).unwrap();
            let pf = PrevFrame { depth: &prev.depth, items: &prev.items, cam: &cams[k - 1], t: tp };
            let truth = reference(&s, &cams[k], t).unwrap();
            for downsample in [1, 2] {
                let params = WocParams { rapid_motion: None, hybrid_objects: 0, downsample, ..WocParams::default() };
                let by_scene = woc(&s, &pf, &cams[k], t, &params).unwrap();
                let by_boxes = woc_objects(boxes.as_slice(), &pf, &cams[k], &params).unwrap();
                assert_eq!(by_boxes.visible, by_scene.visible, "seed {seed} frame {k} /{downsample}");
                assert_eq!(by_boxes.occlusion_map, by_scene.occlusion_map);
                assert_eq!(by_boxes.stats, by_scene.stats);
            }
            // Every moving object in view is rapid at this threshold.
            let rapid = WocParams { rapid_motion: Some(1e-6), ..WocParams::default() };
            let r = woc_objects(boxes.as_slice(), &pf, &cams[k], &rapid).unwrap();
            assert_eq!(accuracy(&r.visible, &truth.visible, s.instances.len()).false_negatives, 0);
            assert!(r.stats.rapid > 0, "seed {seed} frame {k}: no rapid object");
            assert!(r.predrawn.iter().all(|id| r.visible.binary_search(id).is_ok()), "rapid objects are kept");
        }
    }
    // No objects: nothing to test, nothing visible.
    let cam = cam_at(Vec3::new(0.0, 2.0, 8.0), Vec3::ZERO);
    let depth = Image::new(W, H, 1.0f32);
    let items = Image::new(W, H, zwarp_core::NO_ITEM);
    let pf = PrevFrame { depth: &depth, items: &items, cam: &cam, t: 0.0 };
    let none: &[BoxObject] = &[];
    assert!(woc_objects(none, &pf, &cam, &WocParams::default()).unwrap().visible.is_empty());
    // Item ids the objects do not cover (a renderer's extra draws) move with the camera, at
    // full and coarse resolution, with or without rims.
    let depth = Image::from_fn(W, H, |x, _| if x < W / 2 + 1 { 0.5 } else { 0.9 });
    let items = Image::from_fn(W, H, |x, _| if x < W / 2 + 1 { 7 } else { 9 });
    let moved = cam_at(Vec3::new(0.3, 2.0, 8.0), Vec3::ZERO);
    let pf = PrevFrame { depth: &depth, items: &items, cam: &cam, t: 0.0 };
    let one = [BoxObject::fixed(Aabb::new(Vec3::splat(-0.5), Vec3::splat(0.5)))];
    for downsample in [1, 2, 4] {
        let p = WocParams { downsample, ..WocParams::default() };
        assert!(woc_objects(&one[..], &pf, &moved, &p).is_ok(), "/{downsample}");
    }
    let bad = WocParams { downsample: 0, ..WocParams::default() };
    assert!(woc_objects(none, &pf, &cam, &bad).is_err());
}

#[test]
fn last_frame_depth_without_warping_culls_revealed_objects() {
    // Camera moves 3 units right: id 1 (hidden behind the wall's right edge) comes into view.
    let s = scene_of(&[bx([-6.0, -4.0, -0.2], [6.0, 4.0, 0.2]), bx([6.5, -1.0, -3.5], [7.5, 1.0, -3.0])]);
    let prev_cam = cam_at(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO);
    let cam = cam_at(Vec3::new(3.0, 0.0, 10.0), Vec3::new(3.0, 0.0, 0.0));
    let prev = render_frame(&s, &prev_cam, 0.0, &FrameOptions::default()).unwrap();
    assert_eq!(visible_from_items(&prev.items, 2), vec![0]);
    let r = reference(&s, &cam, DT).unwrap();
    assert_eq!(r.visible, vec![0, 1]);
    let lf = lastframe(&s, &prev.depth, &cam, DT, MaxDepthKind::NBuffer).unwrap();
    assert_eq!(lf.visible, vec![0], "the unsafe baseline culls the revealed object");
    let pf = PrevFrame { depth: &prev.depth, items: &prev.items, cam: &prev_cam, t: 0.0 };
    let params = WocParams { rapid_motion: None, ..WocParams::default() };
    assert_eq!(woc(&s, &pf, &cam, DT, &params).unwrap().visible, vec![0, 1], "WOC keeps it");

    // The diagnostic names the error: object 1, with exactly its REF pixels, not visible
    // before, revealed where the (static) wall was, culled by the screen-space test, its
    // pixels predicted nearer than the truth (the unwarped wall).
    let full = render_frame(&s, &cam, DT, &FrameOptions::default()).unwrap();
    let px = full.items.data().iter().filter(|&&i| i == 1).count();
    let cv = culled_visible(&s, &lf.visible, &full.items, &full.depth, Some(&prev.depth), &cam, DT, Some(&pf));
    assert_eq!(cv.len(), 1);
    let c = &cv[0];
    assert_eq!((c.id, c.pixels, c.prev_pixels, c.stage), (1, px, Some(0), "screen"));
    assert!(px > 0);
    assert_eq!(c.own_speed_px, 0.0, "static object");
    assert_eq!(c.prev_moving_occluder_pixels, 0, "the wall does not move");
    assert_eq!(c.wrong_pixels + c.prev_empty_pixels, px);
    assert!(c.map_max_over_rect < c.aabb_nearest && c.predicted_depth.1 <= c.map_max_over_rect);
    assert!(culled_visible(&s, &[0, 1], &full.items, &full.depth, None, &cam, DT, None).is_empty());
}

#[test]
fn hybrid_query_culls_an_object_the_rect_test_keeps() {
    // A deep box (id 1) up and right of the view axis behind a wall (id 0): its projection is a
    // hexagon, so the top-left corner pixel of its screen rect is not covered by the box. A
    // far-depth hole there (as an unconverged warp leaves) makes the rect test keep the box; the
    // object-space query sees that no box fragment is in front and culls it.
    let s = scene_of(&[bx([-6.0, -4.0, -0.2], [6.0, 4.0, 0.2]), bx([2.0, 1.0, -10.0], [4.0, 3.0, -3.0])]);
    let cam = cam_at(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO);
    let frame = render_frame(&s, &cam, 0.0, &FrameOptions::default()).unwrap();
    let b = s.instance_aabb_at(1, 0.0);
    let ScreenRect::Rect { rect, .. } = screen_rect(&b, &cam) else { panic!("box is on screen") };
    let corner = Image::from_fn(W, H, |x, y| if (x, y) == (rect.x0, rect.y0) { 1.0 } else { 0.0 });
    assert!(!any_fragment_visible(&corner, &cam, &aabb_triangles(&b)), "the corner pixel is outside the box");
    let mut depth = frame.depth.clone();
    *depth.get_mut(rect.x0, rect.y0) = 1.0;
    let rect_test = cull_against_depth(&s, &depth, &cam, 0.0, MaxDepthKind::NBuffer, None).unwrap();
    assert_eq!(rect_test.visible, vec![0, 1], "the hole lies in the box's rect");
    let (hidden, tested) = hybrid_cull(&s, &depth, &cam, 0.0, &rect_test.visible, 8, 0).unwrap();
    assert_eq!((hidden, tested), (vec![1], 2));
    // K = 1 tests only the heaviest (ties by id: the wall), min-triangle filter removes all.
    assert_eq!(hybrid_cull(&s, &depth, &cam, 0.0, &[0, 1], 1, 0).unwrap(), (vec![], 1));
    assert_eq!(hybrid_cull(&s, &depth, &cam, 0.0, &[0, 1], 8, 13).unwrap(), (vec![], 0));
    // On the true depth the wall's box is visible (against its own surface, within the
    // tolerance) and the hidden box is not.
    assert_eq!(hybrid_cull(&s, &frame.depth, &cam, 0.0, &[0, 1], 8, 0).unwrap(), (vec![1], 2));
}

#[test]
fn baselines_and_accuracy() {
    let s = wall_scene();
    let cam = cam_at(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO);
    assert_eq!(nocull(&s).visible, vec![0, 1, 2]);
    // Turn the camera away from id 2: VFC drops it.
    let left = cam_at(Vec3::new(0.0, 0.0, 10.0), Vec3::new(-3.0, 0.0, 0.0));
    assert_eq!(vfc_cull(&s, &left, 0.0).unwrap().visible, vec![0, 1]);
    let r = reference(&s, &cam, 0.0).unwrap();
    let a = accuracy(&[0, 1, 2], &r.visible, 3);
    assert_eq!((a.false_negatives, a.false_positives), (0, 1));
    assert_eq!(a.culling_ratio, 0.0);
    let a = accuracy(&r.visible, &r.visible, 3);
    assert_eq!(a.culling_ratio, 1.0);
    let a = accuracy(&[0], &r.visible, 3);
    assert_eq!(a.false_negatives, 1);
    assert!((a.object_error - 1.0 / 3.0).abs() < 1e-12);
    // Two-phase from an empty previous set: everything is found in phase 2.
    let tp = twophase(&s, &[], &cam, 0.0, MaxDepthKind::NBuffer).unwrap();
    assert!(tp.first.is_empty());
    assert_eq!(tp.visible, vec![0, 1, 2], "nothing drawn yet: no occlusion in phase 2");
    assert_eq!(tp.next_visible, vec![0, 2], "the re-test against the final depth drops the hidden box");
    // From REF's set: the hidden box stays culled.
    let tp = twophase(&s, &r.visible, &cam, 0.0, MaxDepthKind::NBuffer).unwrap();
    assert_eq!((tp.first.clone(), tp.second.clone()), (vec![0, 2], vec![]));
    assert_eq!(tp.triangles, (24, 0));
}

#[test]
fn bad_inputs_are_errors() {
    let s = wall_scene();
    let cam = cam_at(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO);
    let depth = Image::new(W, H, 1.0f32);
    let items = Image::new(W, H, u32::MAX);
    let pf = PrevFrame { depth: &depth, items: &items, cam: &cam, t: 0.0 };
    let other = cam.with_size(W + 1, H).unwrap();
    let e = woc(&s, &pf, &other, DT, &WocParams::default()).unwrap_err().to_string();
    assert!(e.contains("previous camera renders"), "{e}");
    let e = woc(&s, &pf, &cam, f32::NAN, &WocParams::default()).unwrap_err().to_string();
    assert!(e.contains("finite"), "{e}");
    let small = Image::new(3, 3, 1.0f32);
    let pf2 = PrevFrame { depth: &small, items: &items, cam: &cam, t: 0.0 };
    assert!(woc(&s, &pf2, &cam, DT, &WocParams::default()).is_err());
    let mut p = WocParams::default();
    p.warp.n_seeds = 0;
    assert!(woc(&s, &pf, &cam, DT, &p).is_err());
    let p = WocParams { rapid_motion: Some(f32::NAN), ..WocParams::default() };
    assert!(woc(&s, &pf, &cam, DT, &p).unwrap_err().to_string().contains("rapid-motion"));
    let e = twophase(&s, &[7], &cam, 0.0, MaxDepthKind::NBuffer).unwrap_err().to_string();
    assert!(e.contains("object 7"), "{e}");
    let mut nan = depth.clone();
    *nan.get_mut(1, 1) = f32::NAN;
    assert!(lastframe(&s, &nan, &cam, 0.0, MaxDepthKind::Mipmap).is_err());
}

/// `n` 80x45 frames DT apart on a circle of radius 18 around `random_scene`, starting at angle
/// `a0` and turning by `da` per frame.
fn orbit_frames(n: usize, a0: f32, da: f32) -> Vec<(f32, Camera)> {
    (0..n)
        .map(|k| {
            let a = a0 + k as f32 * da;
            let eye = Vec3::new(18.0 * a.cos(), 2.5, 18.0 * a.sin());
            (
                k as f32 * DT,
                Camera::perspective(eye, Vec3::new(0.0, 1.0, 0.0), Vec3::Y, 1.0, 0.1, 100.0, 80, 45).unwrap(),
            )
        })
        .collect()
}

#[test]
fn sequence_driver_measures_every_method_side_by_side() {
    let s = random_scene(7);
    let frames = orbit_frames(5, 0.9, 0.05);
    let params = WocParams::default();
    let mut ratio = std::collections::HashMap::new();
    for m in Method::ALL {
        let reps = run_sequence(&s, &frames, m, &params).unwrap();
        assert_eq!(reps.len(), 5);
        let history = matches!(m, Method::Woc | Method::Awoc | Method::LastFrame | Method::TwoPhase);
        assert_eq!(reps[0].bootstrap, history);
        assert!(reps.iter().all(|r| r.full_draw_ms > 0.0 && r.full_triangles == s.triangle_count()));
        let sum = summarize(&reps);
        assert_eq!(sum.frames, if history { 4 } else { 5 });
        if matches!(m, Method::NoCull | Method::Vfc | Method::Woc | Method::TwoPhase | Method::Ideal) {
            // Safe methods: every visible object drawn, so the image is exact.
            assert_eq!(sum.false_negatives, 0, "{m:?}");
            assert!(reps.iter().all(|r| r.pixel_error == 0), "{m:?}");
        }
        ratio.insert(m.name(), sum.culling_ratio);
    }
    assert_eq!(ratio["nocull"], 0.0);
    assert!(ratio["vfc"] <= ratio["woc"] && ratio["woc"] <= ratio["ideal"] + 1e-9, "{ratio:?}");
    assert!(run_sequence(&s, &[], Method::Woc, &params).is_err());
    let mixed = vec![frames[0], (DT, frames[1].1.with_size(81, 45).unwrap())];
    assert!(run_sequence(&s, &mixed, Method::Vfc, &params).unwrap_err().to_string().contains("frame 1 renders"));
}

#[test]
fn sequence_woc_is_the_engine_loop() {
    // `run_sequence` times its own loop first and evaluates afterwards (with a discarded
    // warm-up): its kept sets must be exactly those of culling frame by frame by hand, each
    // frame's previous frame being the drawing of the previous kept set.
    let s = random_scene(11);
    let frames = orbit_frames(4, 0.7, 0.06);
    let params = WocParams::default();
    let reps = run_sequence(&s, &frames, Method::Woc, &params).unwrap();
    let mut visible = vfc_cull(&s, &frames[0].1, frames[0].0).unwrap().visible;
    assert_eq!(reps[0].visible_ids, visible);
    for k in 1..frames.len() {
        let (t0, c0) = &frames[k - 1];
        let prev = render_frame(&s, c0, *t0, &FrameOptions { color: false, objects: Some(&visible) }).unwrap();
        let pf = PrevFrame { depth: &prev.depth, items: &prev.items, cam: c0, t: *t0 };
        visible = woc(&s, &pf, &frames[k].1, frames[k].0, &params).unwrap().visible;
        assert_eq!(reps[k].visible_ids, visible, "frame {k}");
    }
    // Repeating each frame's cull keeps every decision (and report) but the timings.
    for m in [Method::Woc, Method::TwoPhase, Method::Vfc] {
        let once = run_sequence(&s, &frames, m, &params).unwrap();
        let thrice = run_sequence_repeated(&s, &frames, m, &params, 3).unwrap();
        for (a, b) in once.iter().zip(&thrice) {
            assert_eq!(
                (&a.visible_ids, a.accuracy, a.pixel_error, a.stats),
                (&b.visible_ids, b.accuracy, b.pixel_error, b.stats),
                "{m:?}"
            );
        }
    }
}

#[test]
fn rapid_motion_counts_object_motion_not_camera_motion() {
    // Static wall scene, camera turning fast: nothing is rapid by default; counting camera
    // motion makes the on-screen objects rapid (and drawn directly).
    let s = wall_scene();
    let a = cam_at(Vec3::new(0.0, 0.0, 10.0), Vec3::new(-3.0, 0.0, 0.0));
    let b = cam_at(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO);
    assert_eq!(screen_speed(&s, 0, &b, 0.0, &b, DT), 0.0);
    let turn = screen_speed(&s, 0, &a, 0.0, &b, DT);
    assert!(turn > WocParams::default().rapid_threshold_px(W).unwrap(), "{turn}");
    let prev = render_frame(&s, &a, 0.0, &FrameOptions::default()).unwrap();
    let pf = PrevFrame { depth: &prev.depth, items: &prev.items, cam: &a, t: 0.0 };
    let r = woc(&s, &pf, &b, DT, &WocParams::default()).unwrap();
    assert_eq!((r.stats.rapid, r.predrawn.clone()), (0, vec![]));
    // 0.4 of the view (19.2 px at this width): the turn moves the on-screen objects farther,
    // the hidden box (projected near the centre) less.
    let with_cam = WocParams { rapid_includes_camera: true, rapid_motion: Some(0.4), ..WocParams::default() };
    let r = woc(&s, &pf, &b, DT, &with_cam).unwrap();
    assert_eq!(r.predrawn, vec![0, 2], "the on-screen objects that move faster than 0.4 of the view");
    assert_eq!(r.visible, vec![0, 2], "drawn exactly, the hidden box is still culled");
}

#[test]
fn awoc_fills_holes_that_woc_keeps_far() {
    // A fast sideways camera move over the random scene leaves disocclusion holes; AWOC fills
    // some of them (fewer far pixels in the predicted depth) and never culls less than WOC.
    let s = random_scene(11);
    let a = Camera::perspective(Vec3::new(0.0, 2.5, 18.0), Vec3::new(0.0, 1.0, 0.0), Vec3::Y, 1.0, 0.1, 100.0, 90, 50)
        .unwrap();
    let b = Camera::perspective(Vec3::new(2.0, 2.5, 18.0), Vec3::new(2.0, 1.0, 0.0), Vec3::Y, 1.0, 0.1, 100.0, 90, 50)
        .unwrap();
    let prev = render_frame(&s, &a, 0.0, &FrameOptions::default()).unwrap();
    let pf = PrevFrame { depth: &prev.depth, items: &prev.items, cam: &a, t: 0.0 };
    let w = woc(&s, &pf, &b, DT, &WocParams { erosion: false, ..WocParams::default() }).unwrap();
    let aw = woc(&s, &pf, &b, DT, &WocParams { erosion: false, awoc: true, ..WocParams::default() }).unwrap();
    let far =
        |r: &zwarp_cull::CullResult| r.occlusion_map.as_ref().unwrap().data().iter().filter(|&&d| d >= 1.0).count();
    assert!(far(&aw) < far(&w), "AWOC {} far pixels vs WOC {}", far(&aw), far(&w));
    assert!(aw.visible.len() <= w.visible.len());
    assert!(
        aw.visible.iter().all(|id| w.visible.contains(id)),
        "AWOC's depth is never farther, so it culls a superset"
    );
}

#[test]
fn coarse_reduction_is_a_conservative_max() {
    // 7x5 -> coarse 4x3 (factor 2, rounded up): every fine pixel lies in the footprint of the
    // coarse pixel covering its centre, and the coarse value is the max of its footprint.
    let cam = cam_at(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO).with_size(7, 5).unwrap();
    let c = coarse_camera(&cam, 2);
    assert_eq!((c.width, c.height), (4, 3));
    assert_eq!(c.view_proj(), cam.view_proj(), "same view volume");
    let depth = Image::from_fn(7, 5, |x, y| 0.5 + 0.01 * (x * 5 + y) as f32);
    let items = Image::from_fn(7, 5, |x, y| x * 10 + y);
    let (d, it) = downsample_max(&depth, &items, 4, 3).unwrap();
    for y in 0..5u32 {
        for x in 0..7u32 {
            // Coarse pixel under the fine pixel centre.
            let cx = ((x as f32 + 0.5) * 4.0 / 7.0) as u32;
            let cy = ((y as f32 + 0.5) * 3.0 / 5.0) as u32;
            assert!(*d.get(cx, cy) >= *depth.get(x, y), "({x},{y}) -> ({cx},{cy})");
        }
    }
    // Coarse (3, 2) covers fine x in [5.25, 7) and y in [3.33, 5): pixels 5..7 x 3..5, max at (6, 4).
    assert_eq!(*d.get(3, 2), *depth.get(6, 4));
    assert_eq!(*it.get(3, 2), 64);
    assert!(downsample_max(&depth, &items, 8, 3).is_err());
    assert!(downsample_max(&depth, &Image::new(3, 3, 0u32), 4, 3).is_err());
    let s = wall_scene();
    let pf = PrevFrame { depth: &depth, items: &items, cam: &cam, t: 0.0 };
    for bad in [0, 9] {
        let e = woc(&s, &pf, &cam, DT, &WocParams { downsample: bad, ..WocParams::default() }).unwrap_err();
        assert!(e.to_string().contains("downsample"), "{e}");
    }
}

#[test]
fn coarse_woc_culls_the_hidden_box_and_keeps_the_gap_sliver() {
    let s = scene_of(&[
        bx([-6.0, -4.0, -0.2], [-0.15, 4.0, 0.2]),
        bx([0.15, -4.0, -0.2], [6.0, 4.0, 0.2]),
        bx([-1.0, -1.0, -5.0], [1.0, 1.0, -3.0]),
        bx([-5.0, 1.5, -5.0], [-3.0, 3.0, -3.0]),
    ]);
    let prev = cam_at(Vec3::new(0.1, 0.0, 10.0), Vec3::new(0.1, 0.0, 0.0));
    let cur = cam_at(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO);
    for f in [2, 4] {
        let (v, r) = run(&s, &prev, 0.0, &cur, DT, &WocParams { downsample: f, ..WocParams::default() });
        assert_eq!(r, vec![0, 1, 2]);
        assert_eq!(v, vec![0, 1, 2], "factor {f}: id 3 is hidden, id 2 seen through the gap");
    }
}

/// Regression (BL scale 0.25, 960x540: 24 visible 1-2 pixel balloons culled in 23 frames): a
/// near object sliding away from a farther neighbour by half a pixel opens a sub-pixel
/// disocclusion that the warp's 1x1 texel footprints close; the near side's rim must become a
/// hole. Closing boundaries, boundaries with empty pixels and inside one object stay.
#[test]
fn opening_rims_drop_the_near_side_of_separating_boundaries_only() {
    use zwarp_core::{Motion, NO_ITEM};
    let (w, h) = (9u32, 3u32);
    // Columns 0-3: object 7 (near, 0.3); 4-6: object 9 (far, 0.6); 7-8 empty.
    let depth = Image::from_fn(w, h, |x, _| {
        if x < 4 {
            0.3
        } else if x < 7 {
            0.6
        } else {
            1.0
        }
    });
    let items = Image::from_fn(w, h, |x, _| {
        if x < 4 {
            7
        } else if x < 7 {
            9
        } else {
            NO_ITEM
        }
    });
    let mot = |va: f32, vb: f32| {
        Image::from_fn(w, h, |x, _| Motion {
            v: glam::Vec2::new(if x < 4 { va } else { vb }, 0.0),
            depth: if x < 4 { 0.3 } else { 0.6 },
        })
    };
    // Object 7 moves left 1.5 px, object 9 1.0 px: they separate by 0.5 px.
    let out = opening_rims(&depth, &items, &mot(-1.5, -1.0), 0.0).unwrap();
    for y in 0..h {
        for x in 0..w {
            let want = if x == 3 { 1.0 } else { *depth.get(x, y) };
            assert_eq!(*out.get(x, y), want, "({x}, {y})");
        }
    }
    // Below the threshold nothing changes; closing (7 moving onto 9) changes nothing.
    assert_eq!(opening_rims(&depth, &items, &mot(-1.5, -1.0), 0.6).unwrap(), depth);
    assert_eq!(opening_rims(&depth, &items, &mot(-0.5, -1.0), 0.0).unwrap(), depth);
    // Equal motion (no opening) changes nothing; the far object moving away from the near one
    // opens the same gap, and again only the near side's rim is dropped.
    assert_eq!(opening_rims(&depth, &items, &mot(-1.0, -1.0), 0.0).unwrap(), depth);
    let away = opening_rims(&depth, &items, &mot(0.0, 1.0), 0.0).unwrap();
    assert_eq!(away, out);
    // Bad threshold and sizes are errors.
    assert!(opening_rims(&depth, &items, &mot(0.0, 0.0), f32::NAN).unwrap_err().to_string().contains(">= 0"));
    let small = Image::new(2, 2, 7u32);
    assert!(opening_rims(&depth, &small, &mot(0.0, 0.0), 0.0).is_err());
    let bad = WocParams { open_rims: Some(-1.0), ..WocParams::default() };
    assert!(bad.validate().is_err());
}

/// Orthographic camera looking down -z with exactly 0.1 world units per pixel: pixel column
/// `i` spans world x `[0.1 i - 4.8, 0.1 (i + 1) - 4.8)`.
fn ortho_cam() -> Camera {
    Camera::orthographic(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, Vec3::Y, 0.05 * H as f32, 0.1, 100.0, W, H).unwrap()
}

/// The analytic sub-pixel opening of the rim tests on [`ortho_cam`]: a near box A (id 0) whose
/// right edge abuts a farther box B (id 1) at pixel x = `edge` and slides left `slide` pixels per
/// frame, and a narrow box C (id 2) far behind the seam (columns 48.0-49.2). Returns the scene
/// and the previous frame (t = 0) after checking that C is hidden there and shows at column 48
/// of the current frame (t = DT).
fn opening(edge: f32, slide: f32) -> (Scene, zwarp_raster::Frame) {
    let v = Vec3::new(-0.1 * slide / DT, 0.0, 0.0);
    let x = |px: f32| 0.1 * px - 4.8;
    let s = scene_of(&[
        (Aabb::new(Vec3::new(x(10.0), -2.0, 1.0), Vec3::new(x(edge), 2.0, 1.5)), Animation::Linear { velocity: v }),
        bx([x(edge), -2.0, -1.0], [x(85.0), 2.0, -0.5]),
        bx([x(48.0), -1.0, -5.0], [x(49.2), 1.0, -4.0]),
    ]);
    let cam = ortho_cam();
    let prev = render_frame(&s, &cam, 0.0, &FrameOptions::default()).unwrap();
    assert_eq!(visible_from_items(&prev.items, 3), vec![0, 1], "C is hidden in the previous frame");
    let cur = render_frame(&s, &cam, DT, &FrameOptions::default()).unwrap();
    assert_eq!(*cur.items.get(48, 30), 2, "C shows through the strip");
    assert_eq!(visible_from_items(&cur.items, 3), vec![0, 1, 2]);
    (s, prev)
}

/// Analytic sub-pixel opening: a near box A (id 0) and a farther box B (id 1) abut on screen at
/// pixel x = 48.7; a narrow box C (id 2) far behind the seam is hidden. A slides left 0.4 px in
/// one frame, opening the strip [48.3, 48.7) that holds the centre of pixel column 48: REF sees
/// C there. The warp fills the strip from A's rim texel (column 48, preimage 48.9 within half a
/// pixel) and the erosion only raises it to B's depth, so without rims C is culled; both rim
/// modes keep it, and the target mode opens exactly column 48.
#[test]
fn separating_objects_keep_what_the_opening_shows() {
    let (s, prev) = opening(48.7, 0.4);
    let cam = ortho_cam();
    let pf = PrevFrame { depth: &prev.depth, items: &prev.items, cam: &cam, t: 0.0 };
    let norims = woc(&s, &pf, &cam, DT, &WocParams { open_rims: None, ..WocParams::default() }).unwrap();
    assert_eq!(norims.visible, vec![0, 1], "without rims the strip is closed and C is culled");
    for mode in [RimMode::Target, RimMode::Source] {
        let r = woc(&s, &pf, &cam, DT, &WocParams { rim_mode: mode, ..WocParams::default() }).unwrap();
        assert_eq!(r.visible, vec![0, 1, 2], "{mode:?}");
    }
    // Coarse culling (1/4): the seam lies inside coarse texel 12 (fine columns 48-51), which
    // keeps B's depth and motion; without the internal-opening rule C is culled.
    let coarse = WocParams { downsample: 4, ..WocParams::default() };
    let r = woc(&s, &pf, &cam, DT, &coarse).unwrap();
    assert_eq!(r.visible, vec![0, 1, 2], "coarse");
    let r = woc(&s, &pf, &cam, DT, &WocParams { open_rims: None, ..coarse }).unwrap();
    assert_eq!(r.visible, vec![0, 1], "coarse without rims");
    // The target rule opens column 48 (the strip) on the rows A and B share, nothing else.
    let deltas = s.object_deltas(0.0, DT);
    let motion = motion_field(&prev.depth, Some(&prev.items), &cam, &cam, &deltas).unwrap();
    let dirs = opening_rim_dirs(&prev.depth, &prev.items, &motion, 0.1).unwrap();
    let rim_texels: Vec<(u32, u32)> =
        (0..H).flat_map(|y| (0..W).map(move |x| (x, y))).filter(|&(x, y)| *dirs.get(x, y) != 0).collect();
    assert!(!rim_texels.is_empty() && rim_texels.iter().all(|&(x, _)| x == 48), "{rim_texels:?}");
    // Column 48's opening neighbours are to the right (bits of (1,-1), (1,0), (1,1)).
    assert!(rim_texels.iter().all(|&(x, y)| *dirs.get(x, y) & !0b1001_0100 == 0));
    let wp = WarpParams { record_source: true, ..WocParams::default().warp };
    let warped = warp_depth(&[WarpLayer { depth: &prev.depth, motion: &motion }], &wp).unwrap();
    let mut predicted = warped.depth.clone();
    let src = warped.source.as_ref().unwrap();
    let n = open_rims_in_target(&mut predicted, src, &warped.state, &motion, &dirs).unwrap();
    let opened: Vec<(u32, u32)> = (0..H)
        .flat_map(|y| (0..W).map(move |x| (x, y)))
        .filter(|&(x, y)| *predicted.get(x, y) != *warped.depth.get(x, y))
        .collect();
    assert_eq!(n, opened.len());
    assert!(opened.iter().all(|&(x, _)| x == 48) && opened.len() == rim_texels.len(), "{opened:?}");
    // Errors: mismatched sizes.
    let small = Image::new(3, 3, 0u8);
    assert!(open_rims_in_target(&mut predicted, src, &warped.state, &motion, &small).is_err());
    assert!(opening_rim_dirs(&prev.depth, &prev.items, &motion, -0.5).is_err());
}

/// Any opening can expose a pixel centre, however slow, and `open_rims` decides which are
/// trusted: A abuts B at pixel x = 48.52 and slides left 0.05 px in one frame, opening the strip
/// [48.47, 48.52) that holds the centre of column 48, where REF sees the hidden box C. A
/// threshold below the separation keeps C at full and coarse resolution; the default (0.1 px)
/// trusts the opening and culls it (as on CB at 960x540, through a rim separating by 0.077 px).
#[test]
fn openings_slower_than_the_threshold_are_trusted() {
    let (s, prev) = opening(48.52, 0.05);
    let cam = ortho_cam();
    let pf = PrevFrame { depth: &prev.depth, items: &prev.items, cam: &cam, t: 0.0 };
    for downsample in [1, 4] {
        let trusting = WocParams { downsample, ..WocParams::default() };
        assert_eq!(woc(&s, &pf, &cam, DT, &trusting).unwrap().visible, vec![0, 1], "1/{downsample}, 0.1 px");
        let strict = WocParams { open_rims: Some(0.01), ..trusting };
        assert_eq!(woc(&s, &pf, &cam, DT, &strict).unwrap().visible, vec![0, 1, 2], "1/{downsample}, 0.01 px");
    }
}

/// Where the warp is exact (no camera or object motion), WOC without erosion (and without the
/// silhouette test) culls exactly what the ideal screen-space test culls, and with the default
/// erosion keeps a superset; the silhouette test culls more than the ideal rectangle test,
/// never an object REF shows.
#[test]
fn static_view_culls_what_the_ideal_test_culls() {
    let s = random_scene(5);
    let cam = cam_at(Vec3::new(1.0, 3.0, 17.0), Vec3::new(0.0, 1.0, 0.0));
    let prev = render_frame(&s, &cam, 0.0, &FrameOptions::default()).unwrap();
    let pf = PrevFrame { depth: &prev.depth, items: &prev.items, cam: &cam, t: 0.0 };
    let ideal = ideal_screen_space(&s, &prev.depth, &cam, 0.0).unwrap();
    assert!(ideal.stats.occlusion_culled > 3, "the scene must have occluded objects");
    let exact =
        WocParams { erosion: false, max_depth: MaxDepthKind::NBuffer, hull_test: false, ..WocParams::default() };
    let r = woc(&s, &pf, &cam, 0.0, &exact).unwrap();
    assert_eq!(r.visible, ideal.visible);
    let map = r.occlusion_map.as_ref().unwrap();
    let err = map.data().iter().zip(prev.depth.data()).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
    assert!(err < 1e-6, "the warp reproduces the frame (max error {err})");
    let d = woc(&s, &pf, &cam, 0.0, &WocParams { hull_test: false, ..WocParams::default() }).unwrap();
    assert!(ideal.visible.iter().all(|id| d.visible.contains(id)));
    // The silhouette test goes beyond the ideal *rectangle* test, never beyond REF.
    let h = WocParams { hull_test: true, ..exact };
    let h = woc(&s, &pf, &cam, 0.0, &h).unwrap();
    let reference = visible_from_items(&prev.items, s.instances.len());
    assert!(h.visible.iter().all(|id| ideal.visible.contains(id)) && h.visible.len() < ideal.visible.len());
    assert!(reference.iter().all(|id| h.visible.contains(id)));
}

/// Thesis Sec. IV.1: the rapid-motion threshold is a fraction of the view (0.02 of the
/// canonical view volume), so the same objects are rapid at any resolution and downsampling.
#[test]
fn rapid_motion_decision_is_resolution_independent() {
    // A static wall (id 0) and three boxes in front of it moving 0.05, 0.15 and 0.5 units per
    // frame: 0.0104, 0.031 and 0.104 of the view volume (its width [-1, 1] is 9.6 units).
    let s = scene_of(&[
        bx([-4.0, -2.5, -1.0], [4.0, 2.5, -0.5]),
        (
            Aabb::new(Vec3::new(-3.0, -1.0, 1.0), Vec3::new(-2.0, 0.0, 2.0)),
            Animation::Linear { velocity: Vec3::new(0.05 / DT, 0.0, 0.0) },
        ),
        (
            Aabb::new(Vec3::new(-1.0, -1.0, 1.0), Vec3::new(0.0, 0.0, 2.0)),
            Animation::Linear { velocity: Vec3::new(0.15 / DT, 0.0, 0.0) },
        ),
        (
            Aabb::new(Vec3::new(1.0, 0.5, 1.0), Vec3::new(2.0, 1.5, 2.0)),
            Animation::Linear { velocity: Vec3::new(0.0, -0.5 / DT, 0.0) },
        ),
    ]);
    let p = WocParams::default();
    assert!((p.rapid_threshold_px(1920).unwrap() - 19.2).abs() < 1e-4, "the thesis' 1152 px/s at 60 Hz on full HD");
    for (w, h) in [(W, H), (2 * W, 2 * H), (5 * W, 5 * H)].into_iter() {
        let cam =
            Camera::orthographic(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, Vec3::Y, 0.05 * H as f32, 0.1, 100.0, w, h)
                .unwrap();
        let prev = render_frame(&s, &cam, 0.0, &FrameOptions::default()).unwrap();
        let pf = PrevFrame { depth: &prev.depth, items: &prev.items, cam: &cam, t: 0.0 };
        for downsample in [1, 4] {
            let r = woc(&s, &pf, &cam, DT, &WocParams { downsample, ..p }).unwrap();
            assert_eq!(r.predrawn, vec![2, 3], "{w}x{h} /{downsample}");
        }
        let thr = p.rapid_threshold_px(w).unwrap();
        assert!((thr - 0.01 * w as f32).abs() < 1e-4, "{w}: {thr} px");
    }
}

/// The WOC motion buffer computes object matrices only for the animated objects on screen; it
/// must equal the core motion field with every object's delta, bit for bit.
#[test]
fn woc_motion_field_equals_the_core_motion_field() {
    let s = random_scene(3);
    let a = cam_at(Vec3::new(0.5, 3.0, 18.0), Vec3::new(0.0, 1.0, 0.0));
    let b = cam_at(Vec3::new(0.9, 3.1, 17.6), Vec3::new(0.2, 1.0, 0.0));
    let prev = render_frame(&s, &a, 0.0, &FrameOptions::default()).unwrap();
    assert!(visible_from_items(&prev.items, s.instances.len())
        .iter()
        .any(|&id| s.instances[id as usize].animation.is_animated()));
    let want = motion_field(&prev.depth, Some(&prev.items), &a, &b, &s.object_deltas(0.0, DT)).unwrap();
    let got = woc_motion_field(&s, &prev.depth, &prev.items, &a, &b, 0.0, DT).unwrap();
    assert_eq!(got, want);
    let small = Image::new(3, 3, 0u32);
    assert!(woc_motion_field(&s, &prev.depth, &small, &a, &b, 0.0, DT).is_err());
}

/// The static-ray hole bound is an upper bound of the true depth wherever it answers: over
/// every pixel of a moving camera on the random scene (static and moving boxes), and it does
/// answer for a good share of the pixels (small boxes at 96x61: many 3x3 neighbourhoods straddle
/// an edge and are not trusted).
#[test]
fn static_ray_bounds_are_never_nearer_than_the_truth() {
    use zwarp_cull::StaticRays;
    for (seed, shift) in [(2u64, Vec3::new(0.6, 0.1, -0.4)), (9, Vec3::new(-0.8, 0.3, 0.5))] {
        let s = random_scene(seed);
        let a = cam_at(Vec3::new(0.5, 4.0, 18.0), Vec3::new(0.0, 1.0, 0.0));
        let b = cam_at(Vec3::new(0.5, 4.0, 18.0) + shift, Vec3::new(0.2, 1.0, 0.0));
        let prev = render_frame(&s, &a, 0.0, &FrameOptions::default()).unwrap();
        let cur = render_frame(&s, &b, DT, &FrameOptions::default()).unwrap();
        let rays = StaticRays::new(&s, &prev.depth, &prev.items, &a, &b).unwrap();
        let (mut answered, mut surfaces) = (0, 0);
        for y in 0..H {
            for x in 0..W {
                let truth = *cur.depth.get(x, y);
                surfaces += (truth < 1.0) as usize;
                if let Some(bd) = rays.bound(x as f32 + 0.5, y as f32 + 0.5) {
                    answered += 1;
                    assert!(bd >= truth - 1e-6, "seed {seed} ({x}, {y}): bound {bd} < true {truth}");
                }
            }
        }
        assert!(answered * 8 > surfaces, "seed {seed}: {answered} bounds for {surfaces} surface pixels");
    }
    let s = random_scene(2);
    let a = cam_at(Vec3::new(0.5, 4.0, 18.0), Vec3::ZERO);
    let prev = render_frame(&s, &a, 0.0, &FrameOptions::default()).unwrap();
    let small = Image::new(3, 3, 0u32);
    assert!(StaticRays::new(&s, &prev.depth, &small, &a, &a).is_err());
}

/// The box silhouette of the hull test: an axis-aligned view of a box gives its square; a
/// diamond (the silhouette of a box turned 45 degrees) excludes its bounding square's corners.
#[test]
fn box_silhouette_and_pixel_squares() {
    use glam::Vec2;
    use zwarp_cull::{screen_hull_with, square_meets_hull};
    let cam = ortho_cam(); // 0.1 world units per pixel, x = 0.1 px - 4.8
    let b = Aabb::new(Vec3::new(-1.0, -1.0, -1.0), Vec3::new(1.0, 1.0, 0.0));
    let (hull, n) = screen_hull_with(&b, &cam.view_proj(), W, H).unwrap();
    assert_eq!(n, 4, "{:?}", &hull[..n]);
    let (lo, hi) = hull[..n].iter().fold((Vec2::splat(1e9), Vec2::splat(-1e9)), |(l, h), p| (l.min(*p), h.max(*p)));
    assert!(
        (lo - Vec2::new(38.0, 20.5)).abs().max_element() < 1e-3
            && (hi - Vec2::new(58.0, 40.5)).abs().max_element() < 1e-3
    );
    assert!(square_meets_hull(38.0, 20.0, 0.0, &hull, n) && !square_meets_hull(58.5, 30.0, 0.0, &hull, n));
    // Diamond |x - 10| + |y - 10| <= 4 (counter-clockwise in pixel coordinates).
    let d = [Vec2::new(10.0, 6.0), Vec2::new(14.0, 10.0), Vec2::new(10.0, 14.0), Vec2::new(6.0, 10.0)];
    let mut hull = [Vec2::ZERO; 8];
    hull[..4].copy_from_slice(&d);
    assert!(square_meets_hull(9.0, 9.0, 0.0, &hull, 4), "centre");
    assert!(!square_meets_hull(6.0, 6.0, 0.0, &hull, 4), "bounding-square corner");
    assert!(!square_meets_hull(12.6, 12.6, 0.0, &hull, 4), "just outside an edge");
    assert!(square_meets_hull(11.9, 11.9, 0.0, &hull, 4), "touching an edge");
    // Behind the eye: no hull (the object crosses the near plane).
    assert!(screen_hull_with(
        &Aabb::new(Vec3::new(-1.0, -1.0, 9.0), Vec3::new(1.0, 1.0, 11.0)),
        &cam_at(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO).view_proj(),
        W,
        H
    )
    .is_none());
}

/// The hull test only removes objects the rectangle test kept, never a visible one: along a
/// moving camera on random scenes, WOC with it keeps a subset of WOC without it and a superset
/// of REF.
#[test]
fn hull_test_culls_more_and_stays_conservative() {
    let mut gained = 0;
    for seed in [4u64, 8] {
        let s = random_scene(seed);
        let frames: Vec<(f32, Camera)> = (0..6)
            .map(|k| {
                let e = Vec3::new(-3.0 + 0.35 * k as f32, 2.0 + 0.05 * k as f32, 16.0 - 0.3 * k as f32);
                (k as f32 * DT, cam_at(e, Vec3::new(0.5 * k as f32, 1.0, 0.0)))
            })
            .collect();
        let on = run_sequence(&s, &frames, Method::Woc, &WocParams::default()).unwrap();
        let off =
            run_sequence(&s, &frames, Method::Woc, &WocParams { hull_test: false, ..WocParams::default() }).unwrap();
        for (a, b) in on.iter().zip(&off) {
            assert_eq!(a.accuracy.false_negatives, 0, "seed {seed} frame {}", a.frame);
            assert!(a.visible_ids.iter().all(|id| b.visible_ids.contains(id)));
            gained += b.visible - a.visible;
        }
    }
    assert!(gained > 0, "the silhouette removes some rectangle-only survivors");
}

/// The boxes kept across frames ([`ObjectBounds`]) give every method exactly the answers of
/// the per-call path (static boxes stored once, animated ones recomputed at each time), and a
/// snapshot of another scene is an error, not a silent mismatch.
#[test]
fn kept_object_bounds_change_no_decision() {
    use zwarp_cull::{twophase_with, vfc_cull_with, woc_with, ObjectBounds};
    let s = random_scene(5);
    let bounds = ObjectBounds::new(&s);
    assert_eq!(bounds.len(), s.instances.len());
    let animated = (0..s.instances.len() as u32).filter(|&id| bounds.is_animated(id)).count();
    assert!(animated > 3 && animated < s.instances.len() - 3, "{animated}");
    for t in [0.0, 0.4, 1.7] {
        for id in 0..s.instances.len() as u32 {
            assert_eq!(bounds.at(&s, id, t), s.instance_aabb_at(id, t), "object {id} at {t}");
        }
    }
    let cams: Vec<Camera> = (0..3)
        .map(|k| {
            let a = 0.5 + k as f32 * 0.05;
            Camera::perspective(
                Vec3::new(18.0 * a.cos(), 2.5, 18.0 * a.sin()),
                Vec3::Y,
                Vec3::Y,
                1.0,
                0.1,
                100.0,
                71,
                43,
            )
            .unwrap()
        })
        .collect();
    for k in 1..cams.len() {
        let (tp, t) = ((k - 1) as f32 * DT * 9.0, k as f32 * DT * 9.0);
        let prev = render_frame(&s, &cams[k - 1], tp, &FrameOptions::default()).unwrap();
        let pf = PrevFrame { depth: &prev.depth, items: &prev.items, cam: &cams[k - 1], t: tp };
        for downsample in [1, 2, 3] {
            let p = WocParams { downsample, hybrid_min_triangles: 0, ..WocParams::default() };
            let a = woc(&s, &pf, &cams[k], t, &p).unwrap();
            let b = woc_with(&s, &bounds, &pf, &cams[k], t, &p).unwrap();
            assert_eq!((a.visible, a.stats, a.predrawn), (b.visible, b.stats, b.predrawn), "/{downsample}");
        }
        assert_eq!(
            vfc_cull(&s, &cams[k], t).unwrap().visible,
            vfc_cull_with(&s, &bounds, &cams[k], t).unwrap().visible
        );
        let prev_vis = visible_from_items(&prev.items, s.instances.len());
        let a = twophase(&s, &prev_vis, &cams[k], t, MaxDepthKind::Default).unwrap();
        let b = twophase_with(&s, &bounds, &prev_vis, &cams[k], t, MaxDepthKind::Default).unwrap();
        assert_eq!((a.visible, a.next_visible), (b.visible, b.next_visible));
    }
    let other = random_scene(6);
    let mut fewer = other.clone();
    fewer.instances.pop();
    let e = vfc_cull_with(&fewer, &bounds, &cams[0], 0.0).unwrap_err().to_string();
    assert!(e.contains("object bounds hold 41 objects but the scene has 40"), "{e}");
}

/// The coarse pipeline's single pass over the fine buffers checks them for NaN too.
#[test]
fn coarse_woc_rejects_a_nan_previous_depth() {
    let s = wall_scene();
    let cam = cam_at(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO);
    let mut depth = Image::new(W, H, 1.0f32);
    *depth.get_mut(W - 1, H - 1) = f32::NAN;
    let items = Image::new(W, H, u32::MAX);
    let pf = PrevFrame { depth: &depth, items: &items, cam: &cam, t: 0.0 };
    for downsample in [1, 2, 4] {
        let e = woc(&s, &pf, &cam, DT, &WocParams { downsample, ..WocParams::default() }).unwrap_err().to_string();
        assert!(e.contains("previous depth buffer holds NaN"), "/{downsample}: {e}");
    }
}

/// At a divisor that divides both image sides the coarse silhouette test counts only the part
/// of each coarse pixel that holds fine pixel centres (`0.5 / f` inside its border): still no
/// visible object culled along paths at 96x60 (exact at /2, /3, /4) and at odd sizes.
#[test]
fn coarse_silhouette_test_at_exact_divisors_stays_conservative() {
    for seed in [4u64, 9, 13] {
        let s = random_scene(seed);
        for (w, h) in [(96u32, 60u32), (97, 61)] {
            let frames: Vec<(f32, Camera)> = (0..5)
                .map(|k| {
                    let e = Vec3::new(-3.0 + 0.4 * k as f32, 2.0 + 0.05 * k as f32, 16.0 - 0.3 * k as f32);
                    let c = Camera::perspective(e, Vec3::new(0.5 * k as f32, 1.0, 0.0), Vec3::Y, 1.0, 0.1, 100.0, w, h);
                    (k as f32 * DT, c.unwrap())
                })
                .collect();
            for downsample in [2, 3, 4] {
                let p = WocParams { downsample, ..WocParams::default() };
                for r in run_sequence(&s, &frames, Method::Woc, &p).unwrap() {
                    assert_eq!(r.accuracy.false_negatives, 0, "seed {seed} {w}x{h} /{downsample} frame {}", r.frame);
                }
            }
        }
    }
}
