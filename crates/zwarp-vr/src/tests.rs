//! Analytic tests of the quadtree, the grid warp and its baselines, and the hole filling.

use glam::{Mat4, Vec3};
use zwarp_core::{Camera, Image};

use crate::grid::{
    corner_depth, didyk_cells, grid_cells, raster_where, warp, ColorFilter, Method, Source, WarpMatrix, WarpOutput,
    WarpParams,
};
use crate::holes::{epipolar_dir, epipole, fill_holes, lowpass_pyramid, HoleMethod};
use crate::quadtree::*;

/// A camera at `eye` looking down -Y... (Z up), `w x h`.
fn camera(eye: Vec3, w: u32, h: u32) -> Camera {
    Camera::perspective(eye, eye + Vec3::new(0.0, 1.0, 0.0), Vec3::Z, 60f32.to_radians(), 0.1, 100.0, w, h).unwrap()
}

/// `cam` moved by `u` along its right axis (a stereo eye).
fn shifted(cam: &Camera, u: f32) -> Camera {
    Camera { view: Mat4::from_translation(Vec3::new(-u, 0.0, 0.0)) * cam.view, ..*cam }
}

/// A plane `dot(n, x) = k` limited to `|x.x| <= half_x` (infinite if `None`), with a colour.
#[derive(Clone, Copy)]
struct Plane {
    n: Vec3,
    k: f32,
    half_x: Option<f32>,
    color: fn(Vec3) -> [f32; 3],
}

/// Ray-traced depth and colour of the planes seen by `cam` (nearest hit per pixel centre; sky:
/// depth 1, colour grey).
fn trace(cam: &Camera, planes: &[Plane]) -> (Image<f32>, Image<[f32; 3]>) {
    let (w, h) = (cam.width, cam.height);
    let mut depth = Image::new(w, h, 1.0f32);
    let mut color = Image::new(w, h, [0.5f32; 3]);
    for y in 0..h {
        for x in 0..w {
            let (px, py) = (x as f32 + 0.5, y as f32 + 0.5);
            let (a, b) = (cam.unproject(px, py, 0.0), cam.unproject(px, py, 1.0));
            let dir = b - a;
            let mut best = f32::INFINITY;
            for p in planes {
                let den = p.n.dot(dir);
                if den.abs() < 1e-12 {
                    continue;
                }
                let t = (p.k - p.n.dot(a)) / den;
                let hit = a + dir * t;
                if !(0.0..=1.0).contains(&t) || p.half_x.is_some_and(|hx| hit.x.abs() > hx) {
                    continue;
                }
                let d = cam.project(hit).unwrap().z;
                if d < best {
                    best = d;
                    *depth.get_mut(x, y) = d;
                    *color.get_mut(x, y) = (p.color)(hit);
                }
            }
        }
    }
    (depth, color)
}

fn smooth(p: Vec3) -> [f32; 3] {
    [0.5 + 0.4 * (p.x * 1.3).sin(), 0.5 + 0.4 * (p.z * 1.7).cos(), 0.5 + 0.2 * (p.x * 0.7 + p.z).sin()]
}

fn red(_: Vec3) -> [f32; 3] {
    [1.0, 0.0, 0.0]
}

fn blue(_: Vec3) -> [f32; 3] {
    [0.0, 0.0, 1.0]
}

fn mse(a: &Image<[f32; 3]>, b: &Image<[f32; 3]>, mask: impl Fn(usize) -> bool) -> (f64, usize) {
    let mut s = 0.0;
    let mut n = 0;
    for (i, (p, q)) in a.data().iter().zip(b.data()).enumerate() {
        if mask(i) {
            s += (0..3).map(|c| ((p[c] - q[c]) as f64).powi(2)).sum::<f64>() / 3.0;
            n += 1;
        }
    }
    (s / n.max(1) as f64, n)
}

// --- quadtree ---------------------------------------------------------------------------

#[test]
fn collinearity_is_eq_1_with_a_relative_tolerance() {
    let c = Collinearity::default();
    assert_eq!(Collinearity::deviation(0.1, 0.2, 0.3), 0.0f32.max(((0.1f32 - 0.2) - (0.2 - 0.3)).abs()));
    assert!(c.test(0.1, 0.2, 0.3), "a line");
    assert!(c.test(0.5, 0.5, 0.5), "constant");
    assert!(!c.test(0.5, 0.5, 0.6), "a step next to a plane");
    assert!(!c.test(0.50, 0.51, 0.60), "a step between two slanted planes");
    assert!(c.test(0.50, 0.51, 0.5201), "gentle curvature");
    assert!(Collinearity { epsilon: 1.0, floor: 0.0 }.check().is_err());
    assert!(Collinearity { epsilon: 0.1, floor: f32::NAN }.check().is_err());
}

fn affine(w: u32, h: u32) -> Image<f32> {
    Image::from_fn(w, h, |x, y| 0.5 + 0.001 * x as f32 + 0.0005 * y as f32)
}

#[test]
fn a_plane_is_one_cell_per_tile_for_every_reduction() {
    let d = affine(64, 64);
    for r in [Reduction::Cross, Reduction::PartialCross, Reduction::Irregular] {
        let t = QuadTree::build(&d, r, &Collinearity::default()).unwrap();
        let cells = t.cells(|_, _| false);
        assert_eq!(cells.len(), 4, "{r:?}");
        assert!(cells.iter().all(|c| c.area() == 32 * 32), "{r:?}");
        assert!(t.levels[0].nodes.iter().all(|n| n.links == ALL));
        // A partial tile at the border is still one cell.
        let t = QuadTree::build(&affine(40, 20), r, &Collinearity::default()).unwrap();
        let cells = t.cells(|_, _| false);
        assert_eq!(cells, vec![Cell { x0: 0, y0: 0, x1: 32, y1: 20 }, Cell { x0: 32, y0: 0, x1: 40, y1: 20 }], "{r:?}");
    }
}

#[test]
fn connectivity_bits_of_a_single_raised_pixel() {
    let mut d = Image::new(8, 8, 0.5f32);
    *d.get_mut(4, 4) = 0.2;
    let t = QuadTree::build(&d, Reduction::PartialCross, &Collinearity::default()).unwrap();
    assert_eq!(t.pixel_links(4, 4), 0, "cut off on all 8 sides");
    assert_eq!(t.pixel_links(3, 4), ALL & !RIGHT);
    assert_eq!(t.pixel_links(5, 4), ALL & !LEFT);
    assert_eq!(t.pixel_links(4, 3), ALL & !DOWN);
    assert_eq!(t.pixel_links(4, 5), ALL & !UP);
    assert_eq!(t.pixel_links(3, 3), ALL & !DOWN_RIGHT);
    assert_eq!(t.pixel_links(5, 5), ALL & !UP_LEFT);
    assert_eq!(t.pixel_links(5, 3), ALL & !DOWN_LEFT);
    assert_eq!(t.pixel_links(3, 5), ALL & !UP_RIGHT);
    assert_eq!(t.pixel_links(2, 4), ALL, "two pixels away: collinear with its other side");
    assert!(!t.connected(3, 4, 1, 0) && !t.connected(4, 4, -1, 0));
    assert!(t.connected(2, 4, 1, 0));
    // Partial cross kernel: only the 2x2 node holding the pixel is no surface; the node left
    // of it touches the discontinuity, stays a surface and records it in its right bit.
    let l1 = &t.levels[1];
    assert!(!l1.get(2, 2).surface);
    assert!(l1.get(1, 2).surface && l1.get(1, 2).links & RIGHT == 0 && l1.get(0, 0).surface);
    assert_eq!((0..16).filter(|&i| !l1.nodes[i].surface).count(), 1);
    // The cross kernel also rejects the neighbours whose centred tests see the pixel.
    let c = QuadTree::build(&d, Reduction::Cross, &Collinearity::default()).unwrap();
    let c1 = &c.levels[1];
    assert!(!c1.get(2, 2).surface && !c1.get(1, 2).surface && !c1.get(2, 1).surface && c1.get(1, 1).surface);
}

#[test]
fn a_depth_step_splits_along_it_and_the_reductions_rank_as_in_fig_4() {
    // Left of column 20: near plane; right: a slanted far plane.
    let d = Image::from_fn(64, 64, |x, y| if x < 20 { 0.3 } else { 0.6 + 0.002 * x as f32 + 0.001 * y as f32 });
    let mut counts = Vec::new();
    for r in [Reduction::Cross, Reduction::PartialCross, Reduction::Irregular] {
        let t = QuadTree::build(&d, r, &Collinearity::default()).unwrap();
        let cells = t.cells(|_, _| false);
        let covered: u32 = cells.iter().map(|c| c.area()).sum();
        assert_eq!(covered, 64 * 64, "{r:?}: cells tile the image");
        for c in &cells {
            assert!(c.x1 <= 20 || c.x0 >= 20, "{r:?}: {c:?} straddles the step");
        }
        counts.push(cells.len());
    }
    // Cross over-tessellates next to the edge; rectangles remove more cells.
    assert!(counts[0] > counts[1] && counts[1] > counts[2], "{counts:?}");
}

#[test]
fn irregular_merge_types_of_a_horizontal_step() {
    let d = Image::from_fn(8, 8, |_, y| if y < 4 { 0.3 } else { 0.7 });
    let t = QuadTree::build(&d, Reduction::Irregular, &Collinearity::default()).unwrap();
    assert_eq!(t.levels[3].get(0, 0).merge, Merge::TopBottom);
    assert_eq!(t.cells(|_, _| false), vec![Cell { x0: 0, y0: 0, x1: 8, y1: 4 }, Cell { x0: 0, y0: 4, x1: 8, y1: 8 }]);
    let p = QuadTree::build(&d, Reduction::PartialCross, &Collinearity::default()).unwrap();
    assert_eq!(p.levels[3].get(0, 0).merge, Merge::None);
    assert_eq!(p.cells(|_, _| false).len(), 4);
    let d = Image::from_fn(8, 8, |x, _| if x < 4 { 0.3 } else { 0.7 });
    let t = QuadTree::build(&d, Reduction::Irregular, &Collinearity::default()).unwrap();
    assert_eq!(t.levels[3].get(0, 0).merge, Merge::LeftRight);
}

#[test]
fn the_estimation_error_splits_curved_cells() {
    // A parabola in x: second difference 2e-5 everywhere (below the tolerance: connected).
    let d = Image::from_fn(64, 32, |x, _| 0.5 + 0.001 * x as f32 + 1e-5 * (x * x) as f32);
    let t = QuadTree::build(&d, Reduction::Irregular, &Collinearity::default()).unwrap();
    let top = t.levels[LEVELS].get(0, 0);
    assert!(top.surface && (top.err - 2e-5).abs() < 2e-6, "{top:?}");
    assert_eq!(t.cells(|_, _| false).len(), 2);
    // Split whenever the sagitta exceeds 1e-3 stored depth: 32 px -> 2.6e-3 splits, 16 px ok.
    let cells = t.cells(|err, c| {
        let n = (c.x1 - c.x0).max(c.y1 - c.y0) as f32;
        err * n * n / 8.0 > 1e-3
    });
    assert!(cells.iter().all(|c| (c.x1 - c.x0).max(c.y1 - c.y0) <= 16) && cells.len() >= 8, "{cells:?}");
}

#[test]
fn bad_quadtree_input_is_an_error() {
    let mut d = Image::new(4, 4, 0.5f32);
    *d.get_mut(1, 1) = f32::NAN;
    assert!(QuadTree::build(&d, Reduction::Irregular, &Collinearity::default()).is_err());
    assert!(QuadTree::build(&Image::new(0, 0, 0.5f32), Reduction::Irregular, &Collinearity::default()).is_err());
}

// --- grid warp --------------------------------------------------------------------------

#[test]
fn corner_depths_share_connected_vertices_and_split_at_steps() {
    let d = Image::from_fn(8, 8, |x, y| if x < 4 { 0.3 + 0.01 * y as f32 } else { 0.7 });
    let t = QuadTree::build(&d, Reduction::Irregular, &Collinearity::default()).unwrap();
    // Corner (2, 3) inside the left plane: all four pixels, the plane's value there.
    let c = corner_depth(&d, Some(&t), 2, 3, 1, 2);
    assert!((c - (0.3 + 0.01 * 2.5)).abs() < 1e-6, "{c}");
    assert_eq!(c, corner_depth(&d, Some(&t), 2, 3, 2, 3), "shared by the cells on both sides");
    // Corner (4, 3) on the step: each side keeps its own depth.
    let left = corner_depth(&d, Some(&t), 4, 3, 3, 2);
    let right = corner_depth(&d, Some(&t), 4, 3, 4, 2);
    assert!((left - 0.325).abs() < 1e-6 && (right - 0.7).abs() < 1e-6, "{left} {right}");
    // A slanted side of a step extrapolates its plane to the corner (exact, so creases close).
    let s = Image::from_fn(8, 8, |x, _| if x < 4 { 0.3 + 0.01 * x as f32 } else { 0.9 });
    let st = QuadTree::build(&s, Reduction::Irregular, &Collinearity::default()).unwrap();
    let e = corner_depth(&s, Some(&st), 4, 3, 3, 2);
    assert!((e - 0.335).abs() < 1e-6, "{e}");
    assert!((corner_depth(&s, Some(&st), 4, 3, 4, 2) - 0.9).abs() < 1e-6);
    // Rubber sheets (no tree) average across the step.
    let rubber = corner_depth(&d, None, 4, 3, 3, 2);
    assert!((rubber - (0.32 + 0.33 + 1.4) / 4.0).abs() < 1e-6, "{rubber}");
}

/// A fronto-parallel textured wall in front of the camera at distance 10.
fn wall(w: u32, h: u32) -> (Camera, Image<f32>, Image<[f32; 3]>) {
    let cam = camera(Vec3::ZERO, w, h);
    let planes = [Plane { n: Vec3::Y, k: 10.0, half_x: None, color: smooth }];
    let (d, _) = trace(&cam, &planes);
    // Texels with sharp detail: the exact shift must survive any filtering.
    let c = Image::from_fn(w, h, |x, y| [((x * 7 + y * 3) % 11) as f32 / 10.0, (x % 2) as f32, (y % 3) as f32 / 2.0]);
    (cam, d, c)
}

#[test]
fn a_wall_under_a_pure_translation_is_the_shifted_image() {
    let (w, h) = (64, 48);
    let (cam, depth, color) = wall(w, h);
    // The eye offset that moves the wall by exactly 3 pixels.
    let f_px = h as f32 / (2.0 * (30f32.to_radians()).tan());
    let k = 3u32;
    let dst = shifted(&cam, k as f32 * 10.0 / f_px);
    let src = Source { cam: &cam, depth: &depth, color: &color };
    for m in [
        Method::Grid(Reduction::Irregular),
        Method::Grid(Reduction::Cross),
        Method::Quads,
        Method::Points,
        Method::Didyk,
    ] {
        let out = warp(&src, &dst, m, &WarpParams::default()).unwrap();
        for y in 0..h {
            for x in 0..w {
                let hole = *out.hole.get(x, y);
                if x + k < w {
                    assert!(!hole, "{m:?}: hole at ({x}, {y})");
                    let (a, b) = (out.color.get(x, y), color.get(x + k, y));
                    assert!((0..3).all(|i| (a[i] - b[i]).abs() < 1e-3), "{m:?} ({x}, {y}): {a:?} vs {b:?}");
                } else {
                    assert!(hole, "{m:?}: the uncovered border strip at ({x}, {y}) is a hole");
                }
            }
        }
        match m {
            Method::Grid(_) => assert_eq!(out.primitives, 4, "one cell per 32x32 tile (2 x 2 tiles)"),
            Method::Points | Method::Quads => assert_eq!(out.primitives, (w * h) as usize),
            _ => {}
        }
    }
}

/// A slanted ground plane (z = -2) and a wall: smooth surfaces only.
fn slanted(w: u32, h: u32) -> (Camera, Vec<Plane>) {
    let cam = Camera::perspective(
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(0.0, 10.0, -2.0),
        Vec3::Z,
        60f32.to_radians(),
        0.1,
        100.0,
        w,
        h,
    )
    .unwrap();
    let planes = vec![
        Plane { n: Vec3::Z, k: -2.0, half_x: None, color: smooth },
        Plane { n: Vec3::Y, k: 30.0, half_x: None, color: smooth },
    ];
    (cam, planes)
}

#[test]
fn grid_points_and_quads_agree_with_the_truth_on_a_smooth_surface() {
    let (w, h) = (96, 64);
    let (cam, planes) = slanted(w, h);
    let (d, c) = trace(&cam, &planes);
    let dst = shifted(&cam, 0.2);
    let (_, truth) = trace(&dst, &planes);
    let src = Source { cam: &cam, depth: &d, color: &c };
    let mut outs = Vec::new();
    for m in [Method::Grid(Reduction::Irregular), Method::Quads, Method::Points, Method::Didyk] {
        let o = warp(&src, &dst, m, &WarpParams::default()).unwrap();
        let (e, n) = mse(&o.color, &truth, |i| !o.hole.data()[i]);
        let psnr = 10.0 * (1.0 / e).log10();
        // Splats fetch the nearest texel at a rounded position: coarser.
        let floor = if m == Method::Points { 28.0 } else { 33.0 };
        assert!(psnr > floor, "{m:?}: {psnr} dB over {n} pixels");
        println!("{m:?}: {psnr:.2} dB, {} primitives", o.primitives);
        outs.push(o);
    }
    let (grid, didyk) = (&outs[0], &outs[3]);
    // The grid covers what the connected quads cover (no micro holes on a smooth surface).
    let gh = grid.hole.data().iter().filter(|&&x| x).count();
    let qh = outs[1].hole.data().iter().filter(|&&x| x).count();
    assert!(gh <= qh + w as usize / 8, "grid holes {gh} vs quads {qh}");
    // Fewer primitives than Didyk et al. on slanted surfaces (seed 003 Fig. 4, Table 1).
    assert!(grid.primitives * 2 < didyk.primitives, "{} vs {}", grid.primitives, didyk.primitives);
}

#[test]
fn didyk_splits_by_disparity_range() {
    let (w, h) = (64, 64);
    let (cam, planes) = slanted(w, h);
    let (d, c) = trace(&cam, &planes);
    let src = Source { cam: &cam, depth: &d, color: &c };
    let m = WarpMatrix::new(&cam, &shifted(&cam, 0.064)).unwrap();
    let fine = didyk_cells(&src, &m, 0.1).unwrap();
    let coarse = didyk_cells(&src, &m, 4.0).unwrap();
    assert!(fine.len() > coarse.len(), "{} vs {}", fine.len(), coarse.len());
    let same = didyk_cells(&src, &WarpMatrix::new(&cam, &cam).unwrap(), 0.1).unwrap();
    assert_eq!(same.len(), 4, "no disparity: one cell per tile");
    assert!(didyk_cells(&src, &m, f32::NAN).is_err());
}

#[test]
fn the_warp_matrix_maps_pixels_to_their_reprojection() {
    let (cam, planes) = slanted(64, 48);
    let (d, _) = trace(&cam, &planes);
    let dst = shifted(&cam, 0.3);
    let m = WarpMatrix::new(&cam, &dst).unwrap();
    for &(x, y) in &[(3u32, 40u32), (31, 30), (60, 47)] {
        let (px, py, dd) = (x as f32 + 0.5, y as f32 + 0.5, *d.get(x, y));
        let world = cam.unproject(px, py, dd);
        let want = dst.project(world).unwrap();
        let (tx, ty, tz) = m.project(px, py, dd).unwrap();
        assert!((tx - want.x).abs() < 1e-2 && (ty - want.y).abs() < 1e-2 && (tz - want.z).abs() < 1e-5);
    }
    let _ = grid_cells;
}

#[test]
fn bad_warp_input_is_an_error() {
    let (cam, depth, color) = wall(16, 16);
    let small = Image::new(8, 8, [0.0f32; 3]);
    assert!(
        warp(&Source { cam: &cam, depth: &depth, color: &small }, &cam, Method::Quads, &WarpParams::default()).is_err()
    );
    let mut nan = depth.clone();
    *nan.get_mut(2, 2) = f32::NAN;
    assert!(
        warp(&Source { cam: &cam, depth: &nan, color: &color }, &cam, Method::Points, &WarpParams::default()).is_err()
    );
    assert!(Method::parse("splat").is_err() && HoleMethod::parse("inpaint").is_err());
    assert_eq!(Method::parse("grid").unwrap().name(), "grid");
    let p = WarpParams { max_error_px: -1.0, ..WarpParams::default() };
    let src = Source { cam: &cam, depth: &depth, color: &color };
    assert!(warp(&src, &cam, Method::Grid(Reduction::Irregular), &p).is_err());
}

// --- holes ------------------------------------------------------------------------------

/// A red near slab (|x| <= 1.5 at y = 5) in front of a blue-ish far wall, warped to the right
/// eye: a disocclusion beside the slab. The source camera, the target camera and the source's
/// depth and colour.
fn occluder(w: u32, h: u32) -> (Camera, Camera, Image<f32>, Image<[f32; 3]>) {
    let cam = camera(Vec3::ZERO, w, h);
    let planes = [
        Plane { n: Vec3::Y, k: 5.0, half_x: Some(1.5), color: red },
        Plane { n: Vec3::Y, k: 40.0, half_x: None, color: blue },
    ];
    let (d, c) = trace(&cam, &planes);
    (cam, shifted(&cam, 0.5), d, c)
}

#[test]
fn holes_are_filled_from_the_background_side_only() {
    let (w, h) = (64, 32);
    let (cam, dst, d, c) = occluder(w, h);
    let src = Source { cam: &cam, depth: &d, color: &c };
    let out = warp(&src, &dst, Method::Grid(Reduction::Irregular), &WarpParams::default()).unwrap();
    let holes: Vec<usize> = (0..out.hole.len()).filter(|&i| out.hole.data()[i]).collect();
    assert!(holes.len() >= h as usize * 2, "a disocclusion opened: {} holes", holes.len());
    // Low-pass: the background, plus the red's expected share (at most 1/2) in the hole pixel
    // beside the red slab's warped silhouette; pure background a pixel farther.
    let red_at =
        |x: i64, y: u32| x >= 0 && x < w as i64 && !out.hole.get(x as u32, y) && out.color.get(x as u32, y)[0] > 0.5;
    let f = fill_holes(&out, &src, &dst, HoleMethod::LowPass).unwrap();
    let mut mixed = 0;
    for &i in &holes {
        let p = f.data()[i];
        let (x, y) = ((i as u32 % w) as i64, i as u32 / w);
        assert!((p[0] + p[2] - 1.0).abs() < 1e-5 && p[1] == 0.0 && p[0] <= 0.5 + 1e-6, "hole pixel {i} got {p:?}");
        if red_at(x - 1, y) || red_at(x + 1, y) {
            mixed += usize::from(p[0] > 0.0);
        } else {
            assert_eq!(p, [0.0, 0.0, 1.0], "hole pixel {i} away from the red");
        }
    }
    assert!(mixed >= h as usize, "the silhouette's hole pixels take the red's share: {mixed}");
    for m in [HoleMethod::LowPass, HoleMethod::Stretch] {
        let f = fill_holes(&out, &src, &dst, m).unwrap();
        if m == HoleMethod::Stretch {
            for &i in &holes {
                let p = f.data()[i];
                assert!(p[0] < 1e-3 && p[2] > 0.999, "{m:?}: hole pixel {i} got {p:?}");
            }
        }
        for i in 0..f.len() {
            if !out.hole.data()[i] {
                assert_eq!(f.data()[i], out.color.data()[i], "{m:?}: non-hole pixels are kept");
            }
        }
    }
    // The depth-unaware push-pull and the rubber sheets bring the foreground's red in.
    for m in [HoleMethod::PushPull, HoleMethod::Rubber] {
        let f = fill_holes(&out, &src, &dst, m).unwrap();
        let worst = holes.iter().map(|&i| f.data()[i][0]).fold(0.0f32, f32::max);
        assert!(worst > 0.1, "{m:?}: {worst}");
        assert!(f.data().iter().all(|p| p.iter().all(|v| v.is_finite())));
    }
}

#[test]
fn the_foreground_share_falls_from_a_half_to_zero_a_pixel_past_the_texel_boundary() {
    // Source = target: the boundary of foreground texel (10, 5) towards +x is x = 11.
    let cam = camera(Vec3::ZERO, 32, 16);
    let edge = crate::holes::ForegroundEdge::new(&cam, &cam).unwrap();
    let d = 0.9;
    let share = |px: f32| edge.share(glam::Vec2::new(px, 5.5), (10, 5), d, -glam::Vec2::X);
    // u = distance past the boundary; share = (1 - u) / 2.
    for (px, want) in [(11.0, 0.5), (11.25, 0.375), (11.5, 0.25), (12.0, 0.0), (12.5, 0.0)] {
        assert!((share(px) - want).abs() < 1e-4, "p.x {px}: {} vs {want}", share(px));
    }
    // A pixel that warps back into the foreground texel itself sits on the boundary.
    assert!((share(10.8) - 0.5).abs() < 1e-6);
}

#[test]
fn drawing_only_where_asked_is_exact_there() {
    // Per-pixel quads over an occluder and its background, drawn everywhere and only where a
    // scattered mask (plus the disocclusion) is set: equal depth, colour and holes there.
    let (w, h) = (64, 40);
    let (cam, dst, d, c) = occluder(w, h);
    let src = Source { cam: &cam, depth: &d, color: &c };
    let mesh = crate::grid::Mesh::build(&src, &dst, Method::Quads, &WarpParams::default()).unwrap();
    let all = crate::grid::raster(&src, &dst, &mesh).unwrap();
    let only = Image::from_fn(w, h, |x, y| all.hole.get(x, y) | ((x * 7 + y * 13) % 11 == 0));
    let part = raster_where(&src, &dst, &mesh, &only).unwrap();
    let set: Vec<usize> = (0..only.len()).filter(|&i| only.data()[i]).collect();
    assert!(set.len() > 200 && set.len() < only.len() / 2, "{} pixels asked", set.len());
    for &i in &set {
        assert_eq!(part.hole.data()[i], all.hole.data()[i], "hole at {i}");
        assert_eq!(part.depth.data()[i].to_bits(), all.depth.data()[i].to_bits(), "depth at {i}");
        assert_eq!(part.color.data()[i], all.color.data()[i], "colour at {i}");
    }
    // Fewer pixels drawn: most of the rest are left as holes.
    let skipped = (0..only.len()).filter(|&i| !only.data()[i] && part.hole.data()[i]).count();
    assert!(skipped > only.len() / 2, "{skipped} pixels skipped");
    let wrong = Image::new(w + 1, h, false);
    assert!(raster_where(&src, &dst, &mesh, &wrong).unwrap_err().to_string().contains("mask"));
}

#[test]
fn lowpass_beats_the_baselines_in_the_holes_on_a_textured_background() {
    let (w, h) = (96, 48);
    let cam = camera(Vec3::ZERO, w, h);
    let planes = [
        Plane { n: Vec3::Y, k: 5.0, half_x: Some(1.0), color: red },
        Plane { n: Vec3::Y, k: 40.0, half_x: None, color: smooth },
    ];
    let dst = shifted(&cam, 0.6);
    let (d, c) = trace(&cam, &planes);
    let (_, truth) = trace(&dst, &planes);
    let src = Source { cam: &cam, depth: &d, color: &c };
    let out = warp(&src, &dst, Method::Grid(Reduction::Irregular), &WarpParams::default()).unwrap();
    let err = |m| {
        let f = fill_holes(&out, &src, &dst, m).unwrap();
        mse(&f, &truth, |i| out.hole.data()[i]).0
    };
    let (lp, pp, rb) = (err(HoleMethod::LowPass), err(HoleMethod::PushPull), err(HoleMethod::Rubber));
    assert!(lp < pp && lp < rb, "lowpass {lp} pushpull {pp} rubber {rb}");
}

#[test]
fn the_pyramid_dissolves_the_foreground() {
    let color = Image::from_fn(8, 8, |x, _| if x < 4 { [1.0, 0.0, 0.0] } else { [0.0, 0.0, 1.0] });
    let depth = Image::from_fn(8, 8, |x, _| if x < 4 { 0.2 } else { 0.8 });
    let hole = Image::new(8, 8, false);
    let p = lowpass_pyramid(&color, &depth, &hole).unwrap();
    assert_eq!(p.len(), 4);
    // Level 2 (2x2 texels) still separates; level 3 (one texel) keeps only the background.
    assert_eq!(p[3].texels[0], glam::Vec4::new(0.0, 0.0, 1.0, 0.8));
    assert!(p[2].valid.iter().all(|&v| v));
}

#[test]
fn epipolar_directions_follow_the_eye_offset() {
    let cam = camera(Vec3::ZERO, 32, 32);
    let e = epipole(&cam, &shifted(&cam, 0.1));
    // Parallel eyes: the epipole is at infinity along x.
    let d = epipolar_dir(e, glam::Vec2::new(5.5, 20.5));
    assert!(d.x.abs() > 0.999 && d.y.abs() < 1e-3, "{d:?}");
    let _: Option<WarpOutput> = None;
}

// --- A-buffer ---------------------------------------------------------------------------

use crate::abuffer::{ray_cast, ABuffer, MinMaxTree, RayCastParams, MAX_FRAGMENTS};

fn glass(item: u32) -> [f32; 4] {
    match item {
        1 => [0.5, 0.0, 0.0, 0.5],
        2 => [0.0, 0.24, 0.0, 0.4],
        _ => [0.0, 0.0, 0.09 * item as f32, 0.3],
    }
}

#[test]
fn a_buffer_keeps_the_bound_and_merges_the_rest_without_loss() {
    // Pixel (0, 0) holds 11 fragments (items 3..14 at increasing depth); the opaque surface
    // hides everything behind 0.85.
    let n = MAX_FRAGMENTS + 3;
    let layers: Vec<(Image<f32>, Image<u32>)> = (0..n + 1)
        .map(|k| {
            let d = 0.1 + 0.07 * k as f32;
            (
                Image::from_fn(2, 1, |x, _| if x == 0 { d } else { 1.0 }),
                Image::from_fn(2, 1, |x, _| if x == 0 { 3 + k as u32 } else { NO }),
            )
        })
        .collect();
    const NO: u32 = zwarp_core::NO_ITEM;
    let opaque_depth = Image::new(2, 1, 0.85f32);
    let ab = ABuffer::from_layers(&layers, &opaque_depth, glass).unwrap();
    // Layer 12 lies at 0.87, behind the opaque surface: dropped; 11 in front, 8 kept.
    assert_eq!(ab.fragments(0, 0).len(), MAX_FRAGMENTS);
    assert_eq!(ab.merged, n - MAX_FRAGMENTS);
    assert!(ab.fragments(1, 0).is_empty());
    let opaque = Image::new(2, 1, [0.2f32, 0.6, 0.4]);
    let c = ab.composite(&opaque).unwrap();
    // Every fragment in front of the opaque surface, composited in order.
    let mut acc = [0.0f32; 4];
    for k in 0..n {
        let f = glass(3 + k as u32);
        let r = 1.0 - acc[3];
        for i in 0..4 {
            acc[i] += r * f[i];
        }
    }
    let want: Vec<f32> = (0..3).map(|i| acc[i] + (1.0 - acc[3]) * opaque.data()[0][i]).collect();
    for i in 0..3 {
        assert!((c.data()[0][i] - want[i]).abs() < 1e-6, "{:?} vs {want:?}", c.data()[0]);
    }
    assert_eq!(c.data()[1], opaque.data()[1]);
    assert!(ABuffer::from_layers(&layers, &Image::new(3, 1, 0.9f32), glass).is_err());
}

#[test]
fn ray_casting_the_source_view_itself_is_the_composite() {
    let (w, h) = (40, 24);
    let (cam, depth, color) = wall(w, h);
    let l0 = (
        Image::from_fn(w, h, |x, _| if x < 30 { 0.3 } else { 1.0 }),
        Image::from_fn(w, h, |x, _| if x < 30 { 1 } else { zwarp_core::NO_ITEM }),
    );
    let l1 = (
        Image::from_fn(w, h, |_, y| if y > 8 { 0.5 } else { 1.0 }),
        Image::from_fn(w, h, |_, y| if y > 8 { 2 } else { zwarp_core::NO_ITEM }),
    );
    let od = Image::new(w, h, 0.999f32);
    let ab = ABuffer::from_layers(&[l0, l1], &od, glass).unwrap();
    let tree = MinMaxTree::build(&ab);
    let root = tree.node(LEVELS, 0, 0);
    assert!(root[0] < 0.3 && root[1] > 0.5, "{root:?}");
    // The range over the whole tree: the union of its two 32 x 32 roots (40 x 24 pixels).
    let roots = [tree.node(LEVELS, 0, 0), tree.node(LEVELS, 1, 0)];
    assert_eq!(tree.range(), (roots[0][0].min(roots[1][0]), roots[0][1].max(roots[1][1])));
    let r = ray_cast(&ab, &tree, &cam, &cam, &color, &od, &RayCastParams::default()).unwrap();
    let want = ab.composite(&color).unwrap();
    for (a, b) in r.color.data().iter().zip(want.data()) {
        assert!((0..3).all(|i| (a[i] - b[i]).abs() < 1e-5), "{a:?} vs {b:?}");
    }
    let _ = depth;
    // A ray through empty space skips it in a few steps.
    let empty = ABuffer::from_layers(&[], &od, glass).unwrap();
    assert!(empty.is_empty());
    assert_eq!(MinMaxTree::build(&empty).range(), (f32::INFINITY, f32::NEG_INFINITY));
}

#[test]
fn ray_casting_beats_warping_the_composite_as_if_opaque() {
    let (w, h) = (96, 48);
    let cam = camera(Vec3::ZERO, w, h);
    let dst = shifted(&cam, 0.6);
    // A wall whose colour varies slowly (resampling error stays out of the comparison).
    fn gentle(p: Vec3) -> [f32; 3] {
        [0.4 + 0.2 * (p.x * 0.05).sin(), 0.5 + 0.2 * (p.z * 0.07).cos(), 0.6]
    }
    let wall = [Plane { n: Vec3::Y, k: 40.0, half_x: None, color: gentle }];
    let pane = [Plane { n: Vec3::Y, k: 6.0, half_x: Some(1.0), color: red }];
    let layers_of = |c: &Camera| {
        let (gd, _) = trace(c, &pane);
        let items = gd.map(|&d| if d < 1.0 { 1 } else { zwarp_core::NO_ITEM });
        (gd, items)
    };
    let (sd, sc) = trace(&cam, &wall);
    let ab = ABuffer::from_layers(&[layers_of(&cam)], &sd, glass).unwrap();
    let (td, tc) = trace(&dst, &wall);
    let truth = ABuffer::from_layers(&[layers_of(&dst)], &td, glass).unwrap().composite(&tc).unwrap();
    // Opaque part: the wall warped by the grid (no disocclusion behind glass).
    let src = Source { cam: &cam, depth: &sd, color: &sc };
    let warped = warp(&src, &dst, Method::Grid(Reduction::Irregular), &WarpParams::default()).unwrap();
    let base = fill_holes(&warped, &src, &dst, HoleMethod::LowPass).unwrap();
    let tree = MinMaxTree::build(&ab);
    let rc = ray_cast(&ab, &tree, &cam, &dst, &base, &warped.depth, &RayCastParams::default()).unwrap();
    // Without the A-buffer: the composited source warped with the wall's depth.
    let comp = ab.composite(&sc).unwrap();
    let flat = warp(
        &Source { cam: &cam, depth: &sd, color: &comp },
        &dst,
        Method::Grid(Reduction::Irregular),
        &WarpParams::default(),
    )
    .unwrap();
    let flat = fill_holes(&flat, &src, &dst, HoleMethod::LowPass).unwrap();
    // Away from the border strip the source did not see.
    let seen = |i: usize| !warped.hole.data()[i];
    let (e_rc, _) = mse(&rc.color, &truth, seen);
    let (e_flat, _) = mse(&flat, &truth, seen);
    assert!(e_rc * 10.0 < e_flat, "ray cast {e_rc} vs opaque warp {e_flat}");
    assert!(10.0 * (1.0 / e_rc).log10() > 30.0, "{e_rc}");
    assert!(ray_cast(
        &ab,
        &tree,
        &cam,
        &dst,
        &base,
        &warped.depth,
        &RayCastParams { opacity: 0.0, ..RayCastParams::default() }
    )
    .is_err());
}

#[test]
fn the_interior_fast_path_matches_the_general_tests() {
    // A plane with a step and scattered bumps, at sizes whose interior rows end inside and
    // past a vector of lanes: every pixel's node equals the general path's.
    for (w, h) in [(24, 20), (70, 9), (5, 9), (37, 6)] {
        let d = Image::from_fn(w, h, |x, y| {
            let v = 0.4 + 0.003 * x as f32 + 0.002 * y as f32 + if (x * 7 + y * 3) % 11 == 0 { 0.2 } else { 0.0 };
            if x > 12 {
                v + 0.1
            } else {
                v
            }
        });
        for r in [Reduction::Cross, Reduction::PartialCross, Reduction::Irregular] {
            let t = QuadTree::build(&d, r, &Collinearity::default()).unwrap();
            for y in 0..h {
                for x in 0..w {
                    assert_eq!(
                        t.levels[0].get(x, y),
                        crate::quadtree::pixel_node_general(&d, x, y, &Collinearity::default(), r),
                        "{w}x{h} {r:?} ({x}, {y})"
                    );
                }
            }
        }
    }
}

#[test]
fn edge_rays_blend_a_pane_edge_and_leave_the_rest_alone() {
    // A glass slab (|x| <= 1 at y = 6) over a wall, the eye moved by a fraction of a pixel's
    // parallax: the edge rays on the pixels where the opacity changes give colours between the hard
    // ones around them; every other pixel is the one-ray result, bit for bit.
    let (w, h) = (96, 48);
    let pane = Plane { n: Vec3::Y, k: 6.0, half_x: Some(1.0), color: red };
    let cast = |edge_rays| {
        let p = RayCastParams { edge_rays, ..RayCastParams::default() };
        ray_cast_glass(w, h, 0.1, 0.37, pane, &p).0.color
    };
    let (soft, hard) = (cast(true), cast(false));
    let mut blended = 0;
    for y in 0..h {
        for x in 0..w {
            let (a, b) = (soft.get(x, y), hard.get(x, y));
            if a == b {
                continue;
            }
            // Only where the hard image changes to a neighbour, and between the colours there.
            let around: Vec<[f32; 3]> = (0..9u32)
                .map(|k| ((x + k % 3).wrapping_sub(1), (y + k / 3).wrapping_sub(1)))
                .filter(|&(u, v)| u < w && v < h)
                .map(|(u, v)| *hard.get(u, v))
                .chain([*b])
                .collect();
            assert!(around.iter().any(|c| c != b), "({x}, {y}) changed off an edge");
            for k in 0..3 {
                let lo = around.iter().map(|c| c[k]).fold(f32::INFINITY, f32::min);
                let hi = around.iter().map(|c| c[k]).fold(f32::NEG_INFINITY, f32::max);
                assert!(a[k] >= lo - 0.02 && a[k] <= hi + 0.02, "({x}, {y}) channel {k}: {} not in [{lo}, {hi}]", a[k]);
            }
            blended += 1;
        }
    }
    // Both vertical edges of the pane, a pixel or two each per row.
    assert!(blended >= h as usize && blended <= 4 * h as usize, "{blended} edge pixels blended");
}

/// The source's coverage of the slab `|x| <= 1` on the plane `y = k` (one sample per texel
/// centre) interpolated bilinearly at the point where target pixel `(x, y)`'s ray meets that
/// plane: what the edge rays of [`ray_cast`] must give for that surface.
fn slab_coverage(cam: &Camera, dst: &Camera, k: f32, x: u32, y: u32) -> f32 {
    // Where a camera's ray through pixel position (px, py) meets the plane.
    let on_plane = |c: &Camera, px: f32, py: f32| {
        let (a, b) = (c.unproject(px, py, 0.0), c.unproject(px, py, 1.0));
        a + (b - a) * ((k - a.y) / (b.y - a.y))
    };
    let covered = |sx: f32, sy: f32| (on_plane(cam, sx, sy).x.abs() <= 1.0) as u8 as f32;
    let s = cam.project(on_plane(dst, x as f32 + 0.5, y as f32 + 0.5)).unwrap();
    let (gx, gy) = (s.x - 0.5, s.y - 0.5);
    let (fx, fy) = (gx.floor(), gy.floor());
    let (ax, ay) = (gx - fx, gy - fy);
    (1.0 - ay) * ((1.0 - ax) * covered(fx + 0.5, fy + 0.5) + ax * covered(fx + 1.5, fy + 0.5))
        + ay * ((1.0 - ax) * covered(fx + 0.5, fy + 1.5) + ax * covered(fx + 1.5, fy + 1.5))
}

/// Every pixel of `got` is `want(c, base channel, channel)` for the slab's coverage `c`
/// ([`slab_coverage`] on the plane y = 6) to 2e-3, and both of the slab's edges fall between
/// texel centres in every row (a fraction of coverage on two pixels per row at least).
fn assert_slab_edges_filtered(
    got: &Image<[f32; 3]>,
    base: &Image<[f32; 3]>,
    cam: &Camera,
    dst: &Camera,
    want: impl Fn(f32, f32, usize) -> f32,
) {
    let (w, h) = got.size();
    let mut partial = 0;
    for y in 0..h {
        for x in 0..w {
            let c = slab_coverage(cam, dst, 6.0, x, y);
            let (g, b) = (got.get(x, y), base.get(x, y));
            for k in 0..3 {
                let want = want(c, b[k], k);
                assert!((g[k] - want).abs() < 2e-3, "({x}, {y}) channel {k}: {} vs {want} (coverage {c})", g[k]);
            }
            partial += (c > 0.01 && c < 0.99) as usize;
        }
    }
    assert!(partial >= 2 * h as usize, "{partial} partially covered pixels");
}

#[test]
fn edge_rays_are_the_bilinear_filter_of_the_panes_point_samples() {
    // The slab |x| <= 1 at y = 6 seen by the source (one fragment per pixel whose centre it
    // covers) and ray cast to an eye 0.37 to the right: every pixel's colour is the pane's
    // coverage c over the opaque base, c g + (1 - c a) base, where c is the bilinear
    // interpolation of the source's covered / uncovered texel centres at the point where the
    // pixel's ray meets the pane — 0 or 1 inside and outside, a fraction on the edge pixels.
    let (w, h, u) = (96u32, 48u32, 0.37);
    let pane = Plane { n: Vec3::Y, k: 6.0, half_x: Some(1.0), color: red };
    let (rc, base) = ray_cast_glass(w, h, 0.1, u, pane, &RayCastParams::default());
    let cam = Camera::perspective(Vec3::ZERO, Vec3::Y, Vec3::Z, 60f32.to_radians(), 0.1, 100.0, w, h).unwrap();
    let dst = shifted(&cam, u);
    let g = glass(1);
    assert_slab_edges_filtered(&rc.color, &base, &cam, &dst, |c, b, k| c * g[k] + (1.0 - c * g[3]) * b);
}

#[test]
fn an_edge_seen_through_a_pane_is_filtered_at_its_own_depth() {
    // A green pane covering the whole view at y = 4 in front of the red slab |x| <= 1 at y = 6:
    // the slab's edges are seen through the pane, whose own texels cover every neighbour, so the
    // edge rays align with the slab's texels (1.3 px more disparity than the pane's here). Every
    // pixel is the pane over the slab's tent-interpolated coverage c over the base.
    let (w, h, u) = (96u32, 48u32, 0.37);
    let cam = Camera::perspective(Vec3::ZERO, Vec3::Y, Vec3::Z, 60f32.to_radians(), 0.1, 100.0, w, h).unwrap();
    let dst = shifted(&cam, u);
    let wall = [Plane { n: Vec3::Y, k: 40.0, half_x: None, color: smooth }];
    let front = [Plane { n: Vec3::Y, k: 4.0, half_x: None, color: red }];
    let slab = [Plane { n: Vec3::Y, k: 6.0, half_x: Some(1.0), color: red }];
    let (sd, sc) = trace(&cam, &wall);
    let layer = |planes: &[Plane], item: u32| {
        let (d, _) = trace(&cam, planes);
        let items = d.map(|&z| if z < 1.0 { item } else { zwarp_core::NO_ITEM });
        (d, items)
    };
    let ab = ABuffer::from_layers(&[layer(&front, 2), layer(&slab, 1)], &sd, glass).unwrap();
    let src = Source { cam: &cam, depth: &sd, color: &sc };
    let warped = warp(&src, &dst, Method::Grid(Reduction::Irregular), &WarpParams::default()).unwrap();
    let base = fill_holes(&warped, &src, &dst, HoleMethod::LowPass).unwrap();
    let tree = MinMaxTree::build(&ab);
    let rc = ray_cast(&ab, &tree, &cam, &dst, &base, &warped.depth, &RayCastParams::default()).unwrap();
    let (g1, g2) = (glass(1), glass(2));
    assert_slab_edges_filtered(&rc.color, &base, &cam, &dst, |c, b, k| {
        g2[k] + (1.0 - g2[3]) * (c * g1[k] + (1.0 - c * g1[3]) * b)
    });
}

/// A glass pane (normal `pane_n`, `dot(pane_n, x) = 6`, covering the whole view) in front of a
/// wall, seen by a `w x h` camera with near plane `near`, ray cast to the eye `u` to its right
/// over the warped, hole-filled wall: the ray cast and that opaque base.
fn ray_cast_pane(w: u32, h: u32, near: f32, u: f32, pane_n: Vec3) -> (crate::abuffer::RayCast, Image<[f32; 3]>) {
    let pane = Plane { n: pane_n, k: 6.0, half_x: None, color: red };
    ray_cast_glass(w, h, near, u, pane, &RayCastParams::default())
}

/// [`ray_cast_pane`] for any glass plane `pane` and ray-cast parameters `p`.
fn ray_cast_glass(
    w: u32,
    h: u32,
    near: f32,
    u: f32,
    pane: Plane,
    p: &RayCastParams,
) -> (crate::abuffer::RayCast, Image<[f32; 3]>) {
    let cam = Camera::perspective(Vec3::ZERO, Vec3::Y, Vec3::Z, 60f32.to_radians(), near, 100.0, w, h).unwrap();
    let dst = shifted(&cam, u);
    let wall = [Plane { n: Vec3::Y, k: 40.0, half_x: None, color: smooth }];
    let pane = [pane];
    let (sd, sc) = trace(&cam, &wall);
    let (gd, _) = trace(&cam, &pane);
    let items = gd.map(|&d| if d < 1.0 { 1 } else { zwarp_core::NO_ITEM });
    let ab = ABuffer::from_layers(&[(gd, items)], &sd, glass).unwrap();
    let src = Source { cam: &cam, depth: &sd, color: &sc };
    let warped = warp(&src, &dst, Method::Grid(Reduction::Irregular), &WarpParams::default()).unwrap();
    let base = fill_holes(&warped, &src, &dst, HoleMethod::LowPass).unwrap();
    let tree = MinMaxTree::build(&ab);
    let rc = ray_cast(&ab, &tree, &cam, &dst, &base, &warped.depth, p).unwrap();
    (rc, base)
}

/// [`ray_cast_pane`] with a fronto-parallel pane and the eye 0.6 to the right: every ray
/// crosses the pane exactly once, so each pixel must be the pane's premultiplied colour over
/// the warped opaque image, `g + (1 - a) base`, exactly — also where the pane's piece of the ray
/// lies beyond the source's border, and on every cell boundary of the min-max tree.
fn assert_pane_composited_once(w: u32, h: u32, near: f32) {
    let (rc, base) = ray_cast_pane(w, h, near, 0.6, Vec3::Y);
    let g = glass(1);
    let mut wrong = Vec::new();
    for (i, (c, b)) in rc.color.data().iter().zip(base.data()).enumerate() {
        if (0..3).any(|k| (c[k] - (g[k] + (1.0 - g[3]) * b[k])).abs() > 1e-5) {
            wrong.push((i as u32 % w, i as u32 / w));
        }
    }
    assert!(
        wrong.is_empty(),
        "{w}x{h}: {} pixels not composited once, e.g. {:?}",
        wrong.len(),
        &wrong[..wrong.len().min(8)]
    );
}

#[test]
fn a_pane_reaching_the_border_covers_the_strip_the_source_did_not_see() {
    // The pane's piece of the rays in the right-hand columns lies beyond the source's border
    // (8 px of disparity at the pane, 1 px at the wall): it continues the border fragments.
    assert_pane_composited_once(96, 48, 0.1);
}

#[test]
fn a_ray_far_from_the_origin_visits_each_cell_once() {
    // Source coordinates beyond 1024 px, where a float step is 1.2e-4 px: the step into the
    // next cell must not round back into the cell just left (which composited it twice).
    assert_pane_composited_once(2048, 16, 0.1);
}

#[test]
fn long_rays_advance_through_every_cell() {
    // A slanted pane and a near plane at 1 mm: rays span thousands of source pixels, so the
    // step past a cell boundary is far below a float step of the ray parameter unless it is
    // sized in pixels (a stuck ray spends the whole step budget on one cell).
    let (rc, _) = ray_cast_pane(640, 360, 0.001, 1.0, Vec3::new(0.5, 1.0, 0.2));
    let most = *rc.steps.data().iter().max().unwrap();
    assert!(most < 200, "a ray took {most} steps");
}

/// The warp matrix keeps depth precise for a street scene (near 0.1 m, far 1908 m, the eye
/// 120 m from the world origin): points up to 200 m away, seen by two eyes 64 mm apart, keep
/// their linear depth to 0.1 % and their position to 0.05 px through it (the f32 inverse of the
/// view-projection moved a point 56 m away by metres, so A-buffer rays ended in front of the
/// panes before roofs).
#[test]
fn warp_matrix_keeps_far_depths_precise() {
    let o = Vec3::new(-73.98, -94.79, 0.0);
    let cam = Camera::perspective(
        o + Vec3::new(0.0, 0.0, 1.8),
        o + Vec3::new(0.0, 15.0, 1.3),
        Vec3::Z,
        60f32.to_radians(),
        0.1,
        1907.95,
        1280,
        720,
    )
    .unwrap();
    let dst = shifted(&cam, 0.064);
    let m = WarpMatrix::new(&cam, &dst).unwrap();
    for p in [Vec3::new(5.0, 56.0, 8.0), Vec3::new(-3.0, 30.0, 2.0), Vec3::new(10.0, 200.0, 20.0)] {
        let world = o + p;
        let (s, t) = (cam.project(world).unwrap(), dst.project(world).unwrap());
        let (x, y, d) = m.project(s.x, s.y, s.z).unwrap();
        let ratio = dst.linear_depth(d) / dst.linear_depth(t.z);
        assert!((ratio - 1.0).abs() < 1e-3, "{world}: linear depth ratio {ratio}");
        assert!((x - t.x).abs() < 0.05 && (y - t.y).abs() < 0.05, "{world}: ({x}, {y}) vs {t}");
    }
}

#[test]
fn the_adaptive_filter_keeps_silhouettes_hard_and_bilinear_blends_them() {
    let (w, h) = (64, 32);
    let (cam, dst, d, c) = occluder(w, h);
    let src = Source { cam: &cam, depth: &d, color: &c };
    let grid = Method::Grid(Reduction::Irregular);
    let hard = warp(&src, &dst, grid, &WarpParams { filter: ColorFilter::Adaptive, ..WarpParams::default() }).unwrap();
    let soft = warp(&src, &dst, grid, &WarpParams { filter: ColorFilter::Bilinear, ..WarpParams::default() }).unwrap();
    // The filter changes the colour fetch only: same cells, coverage and depth.
    assert_eq!((hard.primitives, &hard.hole, &hard.depth), (soft.primitives, &soft.hole, &soft.depth));
    // Red occluder over a blue wall: a covered pixel mixing both sits on a silhouette.
    let mixed = |o: &WarpOutput| {
        (0..o.color.len())
            .filter(|&i| !o.hole.data()[i] && o.color.data()[i][0] > 0.01 && o.color.data()[i][2] > 0.01)
            .count()
    };
    assert_eq!(mixed(&hard), 0, "nearest across the discontinuity");
    assert!(mixed(&soft) >= h as usize, "a blend along the occluder's edges: {}", mixed(&soft));
    // Off the silhouettes both fetch the same colour.
    let same = (0..hard.color.len()).filter(|&i| hard.color.data()[i] == soft.color.data()[i]).count();
    assert!(same >= hard.color.len() - 4 * h as usize, "{same}");
    assert!(ColorFilter::parse("nearest").unwrap_err().to_string().contains("adaptive, bilinear"));
}
