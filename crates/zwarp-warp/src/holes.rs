//! Hole policies for pixels where no fixed-point search converged (seed 000 Sec. 3.4 "Handling
//! Degenerate Cases", Fig. 8; Sec. 5.3 AWOC).

use glam::Vec2;
use rayon::prelude::*;
use zwarp_core::{Image, EMPTY_DEPTH};

use crate::PixelState;

/// What the warp writes where no search converged. Selectable per call.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum HolePolicy {
    /// Conservative: the far depth `1.0` ([`PixelState::Hole`]). Never nearer than any surface,
    /// so occlusion culling against the warped buffer stays safe (Sec. 5: "depth holes are
    /// conservatively kept at the far-clipping depth").
    #[default]
    FarDepth,
    /// Fig. 8: a hole surrounded by converged pixels (a converged pixel within `radius` on both
    /// sides along all four directions: horizontal, vertical, both diagonals) takes the depth of
    /// its nearest converged neighbour ([`PixelState::Filled`]); ties between equally near
    /// neighbours take the farther depth. Other holes stay far.
    Dilate {
        /// Search radius in pixels (1..=64).
        radius: u32,
    },
    /// AWOC (Sec. 5.3): fill with the nearest target depth among the samples at the extrema of
    /// the local search bound (the four corners of the tight search region, all layers). These
    /// samples did not converge; it is an approximation that keeps culling effective under
    /// rapid motion ([`PixelState::Filled`]).
    Awoc,
    /// Sec. 4 protocol for single-layer quality ("the single-layer solution keeps holes (filled
    /// with the background depth)"): a hole bracketed by converged pixels within `radius` on both
    /// sides of at least one of the four directions takes the *farthest* of the nearest converged
    /// pixels found along the eight probes ([`PixelState::Filled`]). A disocclusion sliver lies
    /// between the occluder and the surface it uncovers; the uncovered surface is the farther
    /// side. Holes wider than `2 radius` (and sky) stay far. Not conservative: for quality, never
    /// for culling.
    Background {
        /// Search radius in pixels (1..=64).
        radius: u32,
    },
}

/// Which converged neighbour fills a hole in [`fill_holes`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FillRule {
    /// [`HolePolicy::Dilate`]: surrounded in all four directions, nearest neighbour wins.
    Nearest,
    /// [`HolePolicy::Background`]: bracketed in one direction, farthest neighbour wins.
    Background,
}

/// Dilation of Fig. 8 over a warped buffer: fills [`PixelState::Hole`] pixels surrounded by
/// [`PixelState::Converged`] ones (see [`HolePolicy::Dilate`]). Only converged pixels are read,
/// so the result does not depend on the processing order.
pub fn dilate_holes(depth: &mut Image<f32>, state: &mut Image<PixelState>, radius: u32) {
    fill_holes(depth, state, radius, FillRule::Nearest)
}

/// Fills [`PixelState::Hole`] pixels from the nearest [`PixelState::Converged`] pixel along each
/// of the eight directions within `radius` ([`FillRule`] says which holes and which neighbour).
/// Only converged pixels are read, so the result does not depend on the processing order.
pub fn fill_holes(depth: &mut Image<f32>, state: &mut Image<PixelState>, radius: u32, rule: FillRule) {
    let (w, h) = depth.size();
    if w == 0 || h == 0 {
        return;
    }
    let src_depth = depth.data().to_vec();
    let src_state = state.data().to_vec();
    let r = radius as i64;
    depth.data_mut().par_chunks_mut(w as usize).zip(state.data_mut().par_chunks_mut(w as usize)).enumerate().for_each(
        |(y, (drow, srow))| {
            for x in 0..w as usize {
                if srow[x] != PixelState::Hole {
                    continue;
                }
                // Nearest converged pixel along +d and -d within the radius.
                let probe = |dx: i64, dy: i64| -> Option<(i64, f32)> {
                    for k in 1..=r {
                        let (xx, yy) = (x as i64 + dx * k, y as i64 + dy * k);
                        if xx < 0 || yy < 0 || xx >= w as i64 || yy >= h as i64 {
                            return None;
                        }
                        let i = yy as usize * w as usize + xx as usize;
                        if src_state[i] == PixelState::Converged {
                            return Some((k, src_depth[i]));
                        }
                    }
                    None
                };
                let fill = hole_fill(rule, probe);
                if let Some(z) = fill {
                    drow[x] = z;
                    srow[x] = PixelState::Filled;
                }
            }
        },
    );
}

/// The four probe directions of [`fill_holes`] (each probed both ways): horizontal, vertical and
/// both diagonals.
pub const FILL_DIRECTIONS: [(i64, i64); 4] = [(1, 0), (0, 1), (1, 1), (1, -1)];

/// The [`FillRule`] decision for one hole: `probe(dx, dy)` returns the nearest converged pixel
/// along `(dx, dy)` within the radius as `(steps, depth)`. Shared by [`fill_holes`] and sparse
/// callers (soft shadows fill only the texels they look up), so both apply the same rule.
pub fn hole_fill(rule: FillRule, probe: impl Fn(i64, i64) -> Option<(i64, f32)>) -> Option<f32> {
    match rule {
        FillRule::Nearest => {
            let mut best: Option<(f32, f32)> = None; // (distance, depth)
            for (dx, dy) in FILL_DIRECTIONS {
                let step = if dx != 0 && dy != 0 { std::f32::consts::SQRT_2 } else { 1.0 };
                let (Some(a), Some(b)) = (probe(dx, dy), probe(-dx, -dy)) else {
                    return None; // not surrounded
                };
                for (k, z) in [a, b] {
                    let d = k as f32 * step;
                    best = match best {
                        Some((bd, bz)) if bd < d || (bd == d && bz >= z) => Some((bd, bz)),
                        _ => Some((d, z)),
                    };
                }
            }
            best.map(|(_, z)| z)
        }
        FillRule::Background => {
            let mut farthest: Option<f32> = None;
            let mut bracketed = false;
            for (dx, dy) in FILL_DIRECTIONS {
                let (a, b) = (probe(dx, dy), probe(-dx, -dy));
                bracketed |= a.is_some() && b.is_some();
                for (_, z) in a.into_iter().chain(b) {
                    farthest = Some(farthest.map_or(z, |f: f32| f.max(z)));
                }
            }
            farthest.filter(|_| bracketed)
        }
    }
}

/// AWOC fill (Sec. 5.3) for one pixel: the nearest valid target depth among `fetch(q)` at the
/// four corners `corners` of the local search region (image coordinates, clamped to the image
/// by the caller). Returns `None` if none of them is a surface.
#[inline]
pub fn awoc_depth(corners: &[Vec2; 4], mut fetch: impl FnMut(Vec2) -> Option<f32>) -> Option<f32> {
    let mut best = EMPTY_DEPTH;
    for &q in corners {
        if let Some(z) = fetch(q) {
            best = best.min(z);
        }
    }
    (best < EMPTY_DEPTH).then_some(best)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(rows: &[&str]) -> (Image<f32>, Image<PixelState>) {
        let (w, h) = (rows[0].len() as u32, rows.len() as u32);
        let d = Image::from_fn(w, h, |x, y| {
            let c = rows[y as usize].as_bytes()[x as usize];
            if c == b'.' {
                1.0
            } else {
                (c - b'0') as f32 / 10.0
            }
        });
        let s = Image::from_fn(w, h, |x, y| {
            if rows[y as usize].as_bytes()[x as usize] == b'.' {
                PixelState::Hole
            } else {
                PixelState::Converged
            }
        });
        (d, s)
    }

    #[test]
    fn dilation_fills_enclosed_holes_with_nearest_neighbour_only() {
        let (mut d, mut s) = grid(&["55555", "55.55", "55555", "5....", "55555"]);
        dilate_holes(&mut d, &mut s, 1);
        // The enclosed hole at (2, 1) is filled with its neighbours' depth.
        assert_eq!(*s.get(2, 1), PixelState::Filled);
        assert_eq!(*d.get(2, 1), 0.5);
        // The open band on row 3 reaching the border stays a hole where not surrounded.
        assert_eq!(*s.get(4, 3), PixelState::Hole);
        assert_eq!(*d.get(4, 3), 1.0);
    }

    #[test]
    fn dilation_prefers_the_nearest_and_then_the_farther_depth() {
        // Hole at (2,2): left neighbour 0.3 at distance 1, right 0.7 at distance 1: tie -> 0.7.
        let (mut d, mut s) = grid(&["77777", "77777", "73.77", "77777", "77777"]);
        dilate_holes(&mut d, &mut s, 2);
        assert_eq!(*d.get(2, 2), 0.7);
        // 2-wide hole with radius 1 is not surrounded; radius 2 is.
        let (mut d, mut s) = grid(&["666666", "666666", "66..66", "666666", "666666"]);
        dilate_holes(&mut d.clone(), &mut s.clone(), 1);
        let (mut d1, mut s1) = (d.clone(), s.clone());
        dilate_holes(&mut d1, &mut s1, 1);
        assert_eq!(*s1.get(2, 2), PixelState::Hole);
        dilate_holes(&mut d, &mut s, 2);
        assert_eq!((*s.get(2, 2), *d.get(2, 2)), (PixelState::Filled, 0.6));
    }

    #[test]
    fn background_fill_takes_the_farther_side_of_a_sliver_and_leaves_open_holes() {
        // A 2-px disocclusion sliver between a near occluder (0.2) and the uncovered far surface
        // (0.8): bracketed horizontally, filled with 0.8 even though 0.2 is as near.
        let (mut d, mut s) = grid(&["22..88", "22..88", "22..88"]);
        fill_holes(&mut d, &mut s, 2, FillRule::Background);
        for y in 0..3 {
            assert_eq!((*s.get(2, y), *d.get(2, y), *d.get(3, y)), (PixelState::Filled, 0.8, 0.8));
        }
        // Radius 1 does not bracket a 2-px sliver; the Fig. 8 rule (all four directions) would
        // not fill it either.
        let (mut d1, mut s1) = grid(&["22..88", "22..88", "22..88"]);
        fill_holes(&mut d1, &mut s1, 1, FillRule::Background);
        assert_eq!((*s1.get(2, 1), *d1.get(2, 1)), (PixelState::Hole, 1.0));
        let (mut d2, mut s2) = grid(&["22..88", "22..88", "22..88"]);
        dilate_holes(&mut d2, &mut s2, 2);
        assert_eq!(*s2.get(2, 1), PixelState::Hole);
        // A hole open to the border (sky beside a surface) is never bracketed: stays far.
        let (mut d3, mut s3) = grid(&["55...", "55...", "55..."]);
        fill_holes(&mut d3, &mut s3, 4, FillRule::Background);
        assert!(s3.data().iter().filter(|&&st| st == PixelState::Filled).count() == 0);
    }

    #[test]
    fn awoc_takes_the_nearest_valid_corner() {
        let c = [Vec2::ZERO, Vec2::X, Vec2::Y, Vec2::ONE];
        let z = awoc_depth(&c, |q| if q == Vec2::ZERO { None } else { Some(0.9 - q.x * 0.1 - q.y * 0.2) });
        assert!((z.unwrap() - 0.6).abs() < 1e-6);
        assert_eq!(awoc_depth(&c, |_| None), None);
    }
}
