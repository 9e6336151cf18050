//! Analytic tests of the colour warps: identity, integer shifts with their uncovered strips, a
//! magnification where plain iteration stalls, a disocclusion where the orbit picks the
//! background, the subdivision invariants and the baselines.

use glam::{Vec2, Vec3};
use zwarp_core::{Camera, Image, Motion};

use super::*;

/// A colour image that is an affine function of the position (bilinear sampling reproduces it
/// exactly between texel centres).
fn ramp(w: u32, h: u32) -> Image<[f32; 3]> {
    Image::from_fn(w, h, |x, y| [(x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32, 0.25])
}

/// Distinct colours per texel (a hash pattern).
fn noise(w: u32, h: u32) -> Image<[f32; 3]> {
    Image::from_fn(w, h, |x, y| {
        let k = zwarp_warp::search::hash_u32(x * 7919 + y * 104_729);
        [(k & 255) as f32 / 255.0, ((k >> 8) & 255) as f32 / 255.0, ((k >> 16) & 255) as f32 / 255.0]
    })
}

fn basis(depth: Image<f32>, v: impl Fn(u32, u32) -> Vec2) -> WarpBasis {
    let (w, h) = depth.size();
    let m = Image::from_fn(w, h, |x, y| Motion { v: v(x, y), depth: 0.5 });
    WarpBasis::temporal(&depth, &m).unwrap()
}

fn cam(w: u32, h: u32) -> Camera {
    Camera::perspective(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, Vec3::Y, 1.0, 0.1, 100.0, w, h).unwrap()
}

#[test]
fn zero_motion_is_the_identity() {
    let (w, h) = (37, 23);
    let color = noise(w, h);
    let depth = Image::from_fn(w, h, |x, y| 0.3 + 0.01 * ((x * y) % 7) as f32);
    let b = basis(depth.clone(), |_, _| Vec2::ZERO);
    for t in [0.0, 0.7] {
        let f = b.field(FieldParams::temporal(t)).unwrap();
        let hst = heuristic_warp(&f, &color, &HeuristicParams::default()).unwrap();
        assert_eq!(hst.color, color);
        assert_eq!(hst.depth, depth);
        assert_eq!(hst.converged_fraction(), 1.0);
        let (rob, stats) = robust_warp(&f, &color, &RobustParams::default()).unwrap();
        assert_eq!(rob.color, color);
        assert_eq!(rob.converged_fraction(), 1.0);
        assert_eq!(stats.holes, 0);
        // One quad per 16x16 tile: a constant field has rho = 0 everywhere.
        assert_eq!(stats.quads, 3 * 2);
        for out in [mesh_warp(&f, &color, &cam(w, h)).unwrap(), scatter_warp(&f, &color).unwrap()] {
            for (a, b) in out.color.data().iter().zip(color.data()) {
                assert!((0..3).all(|k| (a[k] - b[k]).abs() < 1e-5), "{a:?} vs {b:?}");
            }
            assert_eq!(out.converged_fraction(), 1.0);
        }
    }
}

#[test]
fn integer_shift_moves_the_image_and_reports_the_uncovered_strip() {
    let (w, h) = (40, 30);
    let color = noise(w, h);
    let shift = Vec2::new(3.0, -2.0);
    let b = basis(Image::new(w, h, 0.5), |_, _| shift);
    let f = b.field(FieldParams::temporal(1.0)).unwrap();
    let hst = heuristic_warp(&f, &color, &HeuristicParams::default()).unwrap();
    let (rob, _) = robust_warp(&f, &color, &RobustParams::default()).unwrap();
    for out in [&hst, &rob] {
        for y in 0..h {
            for x in 0..w {
                // Target (x, y) shows source (x - 3, y + 2) where that exists.
                let seen = x >= 3 && y + 2 < h;
                assert_eq!(out.converged(x, y), seen, "({x}, {y})");
                if seen {
                    assert_eq!(out.color.get(x, y), color.get(x - 3, y + 2), "({x}, {y})");
                }
            }
        }
    }
    // The uncovered strip is in-painted inwards, never left black.
    assert!(hst.color.data().iter().all(|c| c.iter().any(|&v| v > 0.0) || c == &[0.0; 3]));
    // The forward baselines agree on the seen part.
    for out in [mesh_warp(&f, &color, &cam(w, h)).unwrap(), scatter_warp(&f, &color).unwrap()] {
        for y in 0..h - 2 {
            for x in 3..w {
                let (a, b) = (out.color.get(x, y), color.get(x - 3, y + 2));
                assert!((0..3).all(|k| (a[k] - b[k]).abs() < 1e-5), "({x}, {y}): {a:?} vs {b:?}");
            }
        }
    }
}

/// A 1.9x magnification about the centre, `V(q) = 0.9 (q - c)`: `rho = 0.9 < 1`, so the
/// fixed-point theorem applies, but plain iteration from the pixel contracts only by 0.9 per
/// step (alternating) and misses the threshold within T = 3 almost everywhere; the robust
/// variant starts every pixel at the position interpolated in its quad and converges
/// everywhere, reading the exact colour of the affine ramp.
#[test]
fn magnification_stalls_plain_iteration_and_the_robust_warp_still_covers() {
    let (w, h) = (64, 64);
    let c = Vec2::splat(32.0);
    let color = ramp(w, h);
    let b = basis(Image::new(w, h, 0.5), |x, y| 0.9 * (Vec2::new(x as f32 + 0.5, y as f32 + 0.5) - c));
    let f = b.field(FieldParams::temporal(1.0)).unwrap();
    let rho = rho_cells(&f);
    let worst = rho.iter().map(|&r| (r - 0.9).abs()).fold(0.0f32, f32::max);
    assert!(worst < 1e-3, "{worst}");
    let plain = HeuristicParams { seed: Seed::Pixel, ..HeuristicParams::default() };
    let hst = heuristic_warp(&f, &color, &plain).unwrap();
    assert!(hst.converged_fraction() < 0.1, "{}", hst.converged_fraction());
    let (rob, stats) = robust_warp(&f, &color, &RobustParams::default()).unwrap();
    assert_eq!(stats.holes, 0);
    assert_eq!(rob.converged_fraction(), 1.0);
    assert_eq!(stats.quads, 16);
    for y in 0..h {
        for x in 0..w {
            let p = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            let q = c + (p - c) / 1.9;
            let got = rob.color.get(x, y);
            assert!(
                (got[0] - q.x / w as f32).abs() < 2e-3 && (got[1] - q.y / h as f32).abs() < 2e-3,
                "({x}, {y}) {got:?}"
            );
        }
    }
}

/// A quad's box margin holds the warped half-texel footprint of its corner texels: half a pixel
/// for a translation, more along a shear, the cap where the quad magnifies 2x or more or is one
/// texel wide (no difference to estimate the Jacobian from).
#[test]
fn quad_margin_follows_the_quads_jacobian() {
    let corners = |map: &dyn Fn(Vec2) -> Vec2| {
        [Vec2::new(0.5, 0.5), Vec2::new(8.5, 0.5), Vec2::new(0.5, 8.5), Vec2::new(8.5, 8.5)].map(map)
    };
    let ext = Vec2::splat(8.0);
    let m = |map: &dyn Fn(Vec2) -> Vec2, cap| robust::footprint_margin(corners(map), ext, cap);
    assert_eq!(m(&|q| q + Vec2::new(3.25, -7.5), 1.0), Vec2::splat(0.5));
    assert_eq!(m(&|q| q + Vec2::new(0.25 * q.y, 0.0), 1.0), Vec2::new(0.625, 0.5));
    assert_eq!(m(&|q| 0.5 * q, 1.0), Vec2::splat(0.75));
    assert_eq!(m(&|q| 2.0 * q, 8.0), Vec2::splat(1.0));
    assert_eq!(m(&|q| 3.0 * q, 1.0), Vec2::splat(1.0));
    let one_wide = [Vec2::ZERO; 4];
    assert_eq!(robust::footprint_margin(one_wide, Vec2::new(0.0, 8.0), 0.9), Vec2::splat(0.9));
}

/// A 0.6x minification about the centre, `V(q) = -0.4 (q - c)`: the quads' boxes shrink to their
/// Jacobian margin, and still every pixel whose preimage lies among the texel centres converges
/// in a quad on the exact colour of the affine ramp (the pixels left out of a box were not its
/// solutions).
#[test]
fn minification_loses_no_pixel_to_the_quad_margin() {
    let (w, h) = (64, 64);
    let c = Vec2::splat(32.0);
    let color = ramp(w, h);
    let b = basis(Image::new(w, h, 0.5), |x, y| -0.4 * (Vec2::new(x as f32 + 0.5, y as f32 + 0.5) - c));
    let f = b.field(FieldParams::temporal(1.0)).unwrap();
    // A fallback that cannot solve a minification (one plain step from the pixel): every
    // converged pixel is a quad's.
    let quads_only = RobustParams {
        fallback: HeuristicParams { seed: Seed::Pixel, iterations: 1, ..HeuristicParams::default() },
        ..RobustParams::default()
    };
    let (rob, _) = robust_warp(&f, &color, &quads_only).unwrap();
    let mut inside = 0;
    for y in 0..h {
        for x in 0..w {
            let p = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
            let q = c + (p - c) / 0.6;
            if q.min_element() < 0.75 || q.max_element() > w as f32 - 0.75 {
                continue;
            }
            inside += 1;
            assert!(rob.converged(x, y), "({x}, {y}) q {q}");
            let got = rob.color.get(x, y);
            assert!(
                (got[0] - q.x / w as f32).abs() < 2e-3 && (got[1] - q.y / h as f32).abs() < 2e-3,
                "({x}, {y}) {got:?}"
            );
        }
    }
    assert!(inside > 1400, "{inside}");
}

/// Background static at depth 0.8 with a red ramp, a green foreground strip `x in [20, 30)` at
/// depth 0.3 moving +6 px. In the target the strip covers `[26, 36)` and uncovers `[20, 26)`.
fn strip_scene() -> (WarpBasis, Image<[f32; 3]>) {
    let (w, h) = (64, 24);
    let fg = |x: u32| (20..30).contains(&x);
    let depth = Image::from_fn(w, h, |x, _| if fg(x) { 0.3 } else { 0.8 });
    let color = Image::from_fn(w, h, |x, _| if fg(x) { [0.0, 1.0, 0.0] } else { [x as f32 / 64.0, 0.0, 0.2] });
    (basis(depth, |x, _| if fg(x) { Vec2::new(6.0, 0.0) } else { Vec2::ZERO }), color)
}

#[test]
fn the_orbit_at_a_disocclusion_picks_the_background() {
    let (b, color) = strip_scene();
    let f = b.field(FieldParams::temporal(1.0)).unwrap();
    let params = HeuristicParams { seed: Seed::Offset(Vec2::new(-6.0, 0.0)), ..HeuristicParams::default() };
    let out = heuristic_warp(&f, &color, &params).unwrap();
    for y in 2..22 {
        for x in 20..26 {
            // Never seen by the source: not converged, the background cloned from x - 6.
            assert!(!out.converged(x, y), "({x}, {y})");
            assert_eq!(*out.depth.get(x, y), 0.8);
            assert_eq!(out.color.get(x, y), &[(x - 6) as f32 / 64.0, 0.0, 0.2], "({x}, {y})");
        }
        for x in 26..36 {
            assert!(out.converged(x, y) && out.color.get(x, y) == &[0.0, 1.0, 0.0], "({x}, {y})");
        }
        for x in (0..20).chain(36..64) {
            assert!(out.converged(x, y) && out.color.get(x, y)[0] == x as f32 / 64.0, "({x}, {y})");
        }
    }
    // From the pixel itself the overlap [30, 36) converges to the background (Fig. 2b); the
    // robust warp's depth test keeps the foreground there (Fig. 5).
    let pixel = heuristic_warp(&f, &color, &HeuristicParams { seed: Seed::Pixel, ..params }).unwrap();
    assert_eq!(pixel.color.get(32, 10)[1], 0.0);
    let (rob, stats) = robust_warp(&f, &color, &RobustParams::default()).unwrap();
    assert!(stats.holes > 0);
    for y in 0..24 {
        for x in 26..36 {
            assert!(rob.converged(x, y) && rob.color.get(x, y) == &[0.0, 1.0, 0.0], "({x}, {y})");
        }
        for x in 21..26 {
            assert!(!rob.converged(x, y) && *rob.depth.get(x, y) == 0.8, "({x}, {y})");
        }
    }
}

#[test]
fn subdivision_tiles_the_image_and_isolates_discontinuities() {
    let (b, _) = strip_scene();
    let f = b.field(FieldParams::temporal(1.0)).unwrap();
    let sub = Subdivision::of_field(&f, 16).unwrap();
    let (w, h) = sub.size();
    let mut cover = Image::new(w, h, 0u32);
    for l in sub.leaves() {
        for y in l.y0..l.y1 {
            for x in l.x0..l.x1 {
                *cover.get_mut(x, y) += 1;
            }
        }
        // No leaf larger than a texel touches a cell with rho >= 1.
        if l.x1 - l.x0 > 1 || l.y1 - l.y0 > 1 {
            for cy in l.y0.saturating_sub(1)..l.y1.min(h - 1) {
                for cx in l.x0.saturating_sub(1)..l.x1.min(w - 1) {
                    assert!(sub.rho()[(cy * (w - 1) + cx) as usize] < 1.0, "{l:?}");
                }
            }
        }
    }
    assert!(cover.data().iter().all(|&c| c == 1));
    // The motion jumps by 6 px at x = 19|20 and 29|30: rho = 6 in those cells.
    assert!((sub.rho()[19] - 6.0).abs() < 1e-5 && sub.rho()[10] == 0.0);
    assert!(Subdivision::new(4, 4, vec![0.0; 3], 16).is_err());
    assert!(Subdivision::new(4, 4, vec![0.0; 9], 3).is_err());
}

/// On an odd-sized image (levels with a one-texel-thick last row and column), `rho_cells` equals
/// the spectral radii taken directly from `Field::v` at each cell's corners, and every leaf is
/// the largest aligned block of its tile whose footprint's cells all have `rho < 1`: its own
/// cells do (or it is one texel), its parent's do not (or it is a whole tile).
#[test]
fn subdivision_leaves_are_the_largest_blocks_below_rho_one() {
    let (w, h) = (37u32, 23u32);
    let b = basis(Image::new(w, h, 0.5), |x, y| {
        let mut v = Vec2::new(0.01 * x as f32, -0.02 * y as f32);
        if x >= 12 {
            v.x += 3.0;
        }
        if y >= 9 {
            v.y += 2.0;
        }
        if (x, y) == (30, 17) {
            v += Vec2::splat(5.0);
        }
        v
    });
    let f = b.field(FieldParams::temporal(1.0)).unwrap();
    let rho = rho_cells(&f);
    let (cw, ch) = (w - 1, h - 1);
    for cy in 0..ch {
        for cx in 0..cw {
            let v = |x: u32, y: u32| f.v((y * w + x) as usize);
            let (va, vb, vc, vd) = (v(cx, cy), v(cx + 1, cy), v(cx, cy + 1), v(cx + 1, cy + 1));
            let (dxt, dxb, dyl, dyr) = (vb - va, vd - vc, vc - va, vd - vb);
            let want = spectral_radius(dxt, dyl)
                .max(spectral_radius(dxt, dyr))
                .max(spectral_radius(dxb, dyl))
                .max(spectral_radius(dxb, dyr));
            assert_eq!(rho[(cy * cw + cx) as usize], want, "cell ({cx}, {cy})");
        }
    }
    // The largest rho over the cells the footprint of the texels [x0, x1) x [y0, y1) touches.
    let block_max = |x0: u32, y0: u32, x1: u32, y1: u32| {
        let mut m = f32::NEG_INFINITY;
        for cy in y0.saturating_sub(1)..y1.min(ch) {
            for cx in x0.saturating_sub(1)..x1.min(cw) {
                m = m.max(rho[(cy * cw + cx) as usize]);
            }
        }
        m
    };
    for tile in [8, 16] {
        let sub = Subdivision::new(w, h, rho.clone(), tile).unwrap();
        let mut cover = Image::new(w, h, 0u32);
        for l in sub.leaves() {
            for y in l.y0..l.y1 {
                for x in l.x0..l.x1 {
                    *cover.get_mut(x, y) += 1;
                }
            }
            // The aligned block of side s holding the leaf, clipped to the image; at the image's
            // edge several sides clip to the leaf: the largest of them is the node.
            let block = |s: u32| (l.x0 / s * s, l.y0 / s * s, (l.x0 / s * s + s).min(w), (l.y0 / s * s + s).min(h));
            let mut size = (l.x1 - l.x0).max(l.y1 - l.y0).next_power_of_two();
            assert_eq!(block(size), (l.x0, l.y0, l.x1, l.y1), "tile {tile}: {l:?} is not an aligned block");
            while size < tile && block(2 * size) == block(size) {
                size *= 2;
            }
            assert!(size == 1 || block_max(l.x0, l.y0, l.x1, l.y1) < 1.0, "tile {tile}: {l:?}");
            if size < tile {
                let (px, py, px1, py1) = block(2 * size);
                assert!(block_max(px, py, px1, py1) >= 1.0, "tile {tile}: {l:?} merges");
            }
        }
        assert!(cover.data().iter().all(|&c| c == 1), "tile {tile}");
    }
}

#[test]
fn spectral_radius_of_known_matrices() {
    assert!((spectral_radius(Vec2::new(0.5, 0.0), Vec2::new(0.0, -0.8)) - 0.8).abs() < 1e-6);
    // A rotation by 90 degrees scaled by 0.7: eigenvalues +-0.7i.
    assert!((spectral_radius(Vec2::new(0.0, 0.7), Vec2::new(-0.7, 0.0)) - 0.7).abs() < 1e-6);
    // A shear has spectral radius 0 whatever its size.
    assert_eq!(spectral_radius(Vec2::ZERO, Vec2::new(5.0, 0.0)), 0.0);
}

#[test]
fn stereo_field_of_two_planes_resolves_the_occlusion_with_an_offset_seed() {
    // A near plane (left half of the rows 8..16) in front of a far wall: the right eye sees the
    // near plane shifted left by more; the heuristic with a fixed offset and the robust warp
    // both keep the near plane where it overlaps the wall.
    let (w, h) = (64, 24);
    let c = cam(w, h);
    let near = |x: u32, y: u32| (8..16).contains(&y) && (16..40).contains(&x);
    let depth = Image::from_fn(w, h, |x, y| c.stored_depth(if near(x, y) { 2.0 } else { 20.0 }));
    let color = Image::from_fn(w, h, |x, y| if near(x, y) { [1.0, 1.0, 1.0] } else { [0.1, (x as f32) / 64.0, 0.0] });
    let b = WarpBasis::new(&depth).unwrap().with_spatial(&c, None).unwrap();
    let f = b.field(FieldParams::spatial(0.2, 0.0)).unwrap();
    let shift_near = f.v(10 * w as usize + 20).x;
    assert!(shift_near < -2.0, "{shift_near}");
    let seed = Seed::Offset(Vec2::new(-shift_near, 0.0));
    let hst = heuristic_warp(&f, &color, &HeuristicParams { seed, ..HeuristicParams::default() }).unwrap();
    let (rob, _) = robust_warp(&f, &color, &RobustParams::default()).unwrap();
    let x_left = (16.0 + shift_near).round() as u32 + 1;
    for out in [&hst, &rob] {
        assert_eq!(out.color.get(x_left, 12), &[1.0, 1.0, 1.0]);
    }
}

#[test]
fn reprojection_and_visibility_of_a_static_view() {
    let (w, h) = (32, 20);
    let c = cam(w, h);
    let depth = Image::from_fn(w, h, |x, _| c.stored_depth(5.0 + x as f32 * 0.1));
    let color = noise(w, h);
    let m = zwarp_core::motion_field(&depth, None, &c, &c, &[]).unwrap();
    let vis = source_visibility(&depth, &m, &depth, &c).unwrap();
    assert!(vis.data().iter().all(|&v| v));
    let out = reproject(&depth, &m, &depth, &color, &c).unwrap();
    for (a, b) in out.color.data().iter().zip(color.data()) {
        assert!((0..3).all(|k| (a[k] - b[k]).abs() < 2e-3), "{a:?} vs {b:?}");
    }
}

#[test]
fn push_pull_fills_holes_from_their_surroundings() {
    let mut img = Image::from_fn(16, 16, |x, _| if x < 8 { [1.0, 0.0, 0.0] } else { [0.0, 0.0, 1.0] });
    let valid = Image::from_fn(16, 16, |x, y| !((6..10).contains(&x) && (6..10).contains(&y)));
    for y in 6..10 {
        for x in 6..10 {
            *img.get_mut(x, y) = [0.0, 9.0, 0.0];
        }
    }
    push_pull(&mut img, &valid).unwrap();
    assert!(img.data().iter().all(|c| c[1] == 0.0 && (c[0] + c[2] - 1.0).abs() < 1e-5));
    assert!(img.get(6, 8)[0] > img.get(9, 8)[0]);
    assert!(push_pull(&mut img, &Image::new(3, 3, true)).is_err());
}

#[test]
fn interpolation_takes_what_either_frame_saw() {
    let (b, color) = strip_scene();
    let fa = b.field(FieldParams::temporal(0.5)).unwrap();
    let a = heuristic_warp(&fa, &color, &HeuristicParams::default()).unwrap();
    let mut other = a.clone();
    // A second prediction converged everywhere with another colour.
    other.residual = Image::new(64, 24, 0.0);
    other.color = Image::new(64, 24, [0.5; 3]);
    let m = combine_interpolated(&a, &other, 0.5, &cam(64, 24)).unwrap();
    assert_eq!(m.converged_fraction(), 1.0);
    for x in 0..64 {
        if !a.converged(x, 5) {
            assert_eq!(m.color.get(x, 5), &[0.5; 3]);
        }
    }
    assert!(combine_interpolated(&a, &other, 1.5, &cam(64, 24)).is_err());
    let wts = confidence_weights(&a);
    assert!(wts.data().iter().all(|&v| (0.0..=1.0).contains(&v)));
}

#[test]
fn bad_input_is_a_one_line_error() {
    let (b, color) = strip_scene();
    let f = b.field(FieldParams::temporal(1.0)).unwrap();
    let small = Image::new(4, 4, [0.0f32; 3]);
    for e in [
        heuristic_warp(&f, &small, &HeuristicParams::default()).unwrap_err(),
        heuristic_warp(&f, &color, &HeuristicParams { iterations: 0, ..HeuristicParams::default() }).unwrap_err(),
        robust_warp(&f, &color, &RobustParams { tile: 12, ..RobustParams::default() }).unwrap_err(),
        require_color(None, "frame 3").unwrap_err(),
        WarpBasis::new(&Image::new(2, 2, f32::NAN)).unwrap_err(),
    ] {
        let s = e.to_string();
        assert!(!s.contains('\n') && !s.is_empty(), "{s}");
    }
    assert!(require_color(None, "frame 3").unwrap_err().to_string().contains("frame 3"));
}

/// A temporal basis refilled in place (a frame loop) equals a fresh one across sizes, with the
/// depth clamped to [0, 1], infinite motion sent far off and an earlier spatial term dropped;
/// bad input is refused with one line and leaves no term behind.
#[test]
fn a_recycled_temporal_basis_equals_a_fresh_one() {
    let frame = |w: u32, h: u32, s: f32| {
        let depth = Image::from_fn(w, h, |x, y| -0.2 + 0.011 * s * ((x * 7 + y * 3) % 131) as f32);
        let m = Image::from_fn(w, h, |x, y| Motion {
            v: if (x + y) % 13 == 0 { Vec2::splat(f32::INFINITY) } else { Vec2::new(s * x as f32, -0.5 * y as f32) },
            depth: 0.5,
        });
        (depth, m)
    };
    let (d0, m0) = frame(40, 30, 1.0);
    let mut b = WarpBasis::temporal(&d0, &m0).unwrap().with_spatial(&cam(40, 30), None).unwrap();
    assert!(b.field(FieldParams::spatial(0.1, 0.0)).is_ok());
    for (w, h, s) in [(17, 9, 0.7), (64, 33, 1.3), (40, 30, 1.0)] {
        let (d, m) = frame(w, h, s);
        b.set_temporal(&d, &m).unwrap();
        let fresh = WarpBasis::temporal(&d, &m).unwrap();
        assert_eq!(b, fresh);
        let f = b.field(FieldParams::temporal(1.0)).unwrap();
        assert_eq!(f.size(), (w, h));
        assert!(b.field(FieldParams::spatial(0.1, 0.0)).is_err(), "the spatial term is gone");
    }
    let (d, m) = frame(40, 30, 1.0);
    let mut nan = m.clone();
    nan.get_mut(3, 4).v.y = f32::NAN;
    let mut inf = d.clone();
    *inf.get_mut(39, 29) = f32::INFINITY;
    // A size mismatch is refused before the pass (the last good depth stays, without terms); bad
    // values are found by the pass, which leaves a 0x0 basis.
    let small = Image::new(3, 3, Motion::default());
    for (depth, motion, what, left) in
        [(&d, &small, "3x3", (40, 30)), (&d, &nan, "NaN", (0, 0)), (&inf, &m, "infinite", (0, 0))]
    {
        b.set_temporal(&d, &m).unwrap();
        let e = b.set_temporal(depth, motion).unwrap_err().to_string();
        assert!(e.contains(what) && !e.contains('\n'), "{e}");
        assert!(b.field(FieldParams::temporal(1.0)).is_err(), "no term after an error");
        assert_eq!(b.field(FieldParams::temporal(0.0)).unwrap().size(), left);
    }
}

#[test]
fn floor_pass_copies_the_colour() {
    let (b, color) = strip_scene();
    let f = b.field(FieldParams::temporal(1.0)).unwrap();
    let mut out = Image::new(0, 0, [0.0f32; 3]);
    floor::floor_pass(&f, &color, &mut out).unwrap();
    assert_eq!(out, color);
    assert!(floor::floor_ms(&f, &color, 2).unwrap().0 >= 0.0);
}

/// The AVX2 lanes of the heuristic warp give the portable path's output bit for bit, on
/// random smooth and discontinuous fields with one to three terms, every seed kind.
#[test]
fn heuristic_lanes_are_bit_identical_to_the_portable_path() {
    let (w, h) = (53, 29);
    let color = noise(w, h);
    let rnd =
        |x: u32, y: u32, s: u32| (zwarp_warp::search::hash_u32(x * 131 + y * 7919 + s) % 10_000) as f32 / 10_000.0;
    let depth = Image::from_fn(w, h, |x, y| if (x / 9 + y / 7) % 3 == 0 { 0.3 + 0.1 * rnd(x, y, 1) } else { 0.9 });
    let m1 = Image::from_fn(w, h, |x, y| {
        let near = *depth.get(x, y) < 0.5;
        let base = if near { Vec2::new(4.5, -1.25) } else { Vec2::new(-0.3, 0.2) };
        Motion {
            v: base + Vec2::new(0.05 * x as f32, 0.02 * y as f32) + 0.3 * Vec2::new(rnd(x, y, 2), rnd(x, y, 3)),
            depth: 0.5,
        }
    });
    let m2 =
        Image::from_fn(w, h, |x, y| Motion { v: Vec2::new(rnd(x, y, 4) * 8.0 - 4.0, rnd(x, y, 5) * 2.0), depth: 0.5 });
    let b =
        WarpBasis::second_order(&depth, (1.0, &m1), (-1.0, &m2)).unwrap().with_spatial(&cam(w, h), Some(5.0)).unwrap();
    let params = [
        FieldParams::temporal(0.5),
        FieldParams::temporal(-1.7),
        FieldParams { t: 0.3, u: 0.4, v: -0.2 },
        FieldParams { t: 0.0, u: 2.0, v: 0.0 },
    ];
    let mut compared = 0;
    for p in params {
        let f = b.field(p).unwrap();
        for seed in [Seed::Pixel, Seed::Upstream(1.0), Seed::Upstream(2.0), Seed::Offset(Vec2::new(5.0, -2.0))] {
            for t in [1, 3, 7] {
                let hp = HeuristicParams { seed, iterations: t, threshold: 0.5 };
                set_simd(false);
                let portable = heuristic_warp(&f, &color, &hp).unwrap();
                set_simd(true);
                let lanes = heuristic_warp(&f, &color, &hp).unwrap();
                let bits = |o: &ColorWarpOutput| {
                    let c: Vec<u32> = o.color.data().iter().flat_map(|c| c.map(f32::to_bits)).collect();
                    let d: Vec<u32> = o.depth.data().iter().map(|v| v.to_bits()).collect();
                    let r: Vec<u32> = o.residual.data().iter().map(|v| v.to_bits()).collect();
                    (c, d, r)
                };
                assert!(bits(&portable) == bits(&lanes), "{p:?} {seed:?} T={t}");
                // The AVX-512-enabled build (where the CPU has it) against the AVX2 one.
                crate::lanes::set_avx512(false);
                let narrow = heuristic_warp(&f, &color, &hp).unwrap();
                crate::lanes::set_avx512(true);
                assert!(bits(&narrow) == bits(&lanes), "AVX2 vs AVX-512 {p:?} {seed:?} T={t}");
                compared += 1;
            }
        }
    }
    assert_eq!(compared, 48);
    // The robust warp's quad lanes likewise (Newton on and off, two tile sizes), and rho.
    for p in params {
        let f = b.field(p).unwrap();
        set_simd(false);
        let rp = rho_cells(&f);
        set_simd(true);
        assert_eq!(rp, rho_cells(&f), "rho {p:?}");
        for (accelerate, tile) in [(true, 16), (false, 8), (true, 4)] {
            let rp = RobustParams { accelerate, tile, ..RobustParams::default() };
            set_simd(false);
            let (portable, sp) = robust_warp(&f, &color, &rp).unwrap();
            set_simd(true);
            let (lanes, sl) = robust_warp(&f, &color, &rp).unwrap();
            assert_eq!(sp, sl);
            crate::lanes::set_avx512(false);
            let (narrow, _) = robust_warp(&f, &color, &rp).unwrap();
            crate::lanes::set_avx512(true);
            let same_bits = |a: &ColorWarpOutput, b: &ColorWarpOutput| {
                a.color.data().iter().zip(b.color.data()).all(|(a, b)| a.map(f32::to_bits) == b.map(f32::to_bits))
                    && a.depth.data().iter().zip(b.depth.data()).all(|(a, b)| a.to_bits() == b.to_bits())
                    && a.residual.data().iter().zip(b.residual.data()).all(|(a, b)| a.to_bits() == b.to_bits())
            };
            assert!(same_bits(&narrow, &lanes), "robust AVX2 vs AVX-512 {p:?} accelerate {accelerate} tile {tile}");
            let same = same_bits(&portable, &lanes);
            assert!(same, "robust {p:?} accelerate {accelerate} tile {tile}");
        }
    }
}
