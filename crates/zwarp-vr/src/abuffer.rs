//! Transparency by A-buffer ray casting (seed 003 Sec. 4.2, 5.3, Fig. 7).
//!
//! The A-buffer holds, per source pixel, the transparent fragments in front of the opaque
//! surface (depth, premultiplied RGBA, object id), front to back, at most [`MAX_FRAGMENTS`]:
//! fragments beyond the bound are composited ("over") into the last kept one, which keeps its
//! depth — the colour is never lost, only the depth order behind the bound is flattened. A
//! min-max quadtree over the fragments' extruded depth ranges (32x32 roots) lets a ray skip
//! empty space. For each target pixel the ray from the target eye to the warped opaque surface
//! is mapped into the source image (a straight line in source pixel/depth space) and traversed
//! stacklessly (Tevs et al.: descend where the ray's depth range meets a node's, advance past
//! nodes it misses, ascend one level whenever the next node has no sibling in the ray
//! direction). Leaf fragments are boxes extruded in depth, so neighbouring fragments form a
//! closed surface; one surface is not hit twice where the boxes of neighbouring pixels overlap.
//! Hits are composited front to back until an opacity threshold or the opaque depth. On the
//! edges of transparent surfaces four rays through the source texel centres around the pixel's
//! ray are blended bilinearly ([`RayCastParams::edge_rays`]).

use rayon::prelude::*;
use zwarp_core::{Camera, Error, Image, Result, NO_ITEM};

use crate::grid::WarpMatrix;
use crate::quadtree::LEVELS;

/// Largest number of fragments stored per pixel (the documented bound; see [`ABuffer`]).
pub const MAX_FRAGMENTS: usize = 8;

/// One transparent fragment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fragment {
    /// Source depth (`[0, 1]`).
    pub depth: f32,
    /// Half the extrusion in depth (Sec. 5.3): the box `depth +- half` stands for the pixel's
    /// piece of surface.
    pub half: f32,
    /// Premultiplied linear RGBA.
    pub rgba: [f32; 4],
    /// Object id (one surface is not hit twice within its thickness).
    pub item: u32,
}

/// `acc` over `f`, both premultiplied.
#[inline]
fn over(acc: &mut [f32; 4], f: &[f32; 4]) {
    let k = 1.0 - acc[3];
    for i in 0..4 {
        acc[i] += k * f[i];
    }
}

/// Per-pixel lists of transparent fragments, front to back (seed 003 Sec. 4.2).
#[derive(Clone, Debug, PartialEq)]
pub struct ABuffer {
    width: u32,
    height: u32,
    /// `start[i]..start[i + 1]` are pixel `i`'s fragments.
    start: Vec<u32>,
    frags: Vec<Fragment>,
    /// Fragments composited into a kept one because a pixel held more than [`MAX_FRAGMENTS`].
    pub merged: usize,
}

impl ABuffer {
    /// An empty A-buffer of `w x h` pixels.
    pub fn empty(w: u32, h: u32) -> Self {
        ABuffer { width: w, height: h, start: vec![0; (w * h + 1) as usize], frags: Vec::new(), merged: 0 }
    }

    /// Builds the A-buffer from depth-peeled layers of the transparent objects (front to back:
    /// layer `k + 1` lies behind layer `k`; depth 1 / [`NO_ITEM`] = no fragment), keeping the
    /// fragments in front of `opaque_depth`. `rgba(item)` gives an object's premultiplied
    /// colour. The extrusion of a fragment is 0.75 of its largest depth step to the nearest
    /// fragment of the same object in a 4-neighbour (so neighbouring boxes overlap), at least
    /// `1e-6`.
    pub fn from_layers(
        layers: &[(Image<f32>, Image<u32>)],
        opaque_depth: &Image<f32>,
        rgba: impl Fn(u32) -> [f32; 4] + Sync,
    ) -> Result<Self> {
        let (w, h) = opaque_depth.size();
        for (d, it) in layers {
            d.check_same_size(opaque_depth, "A-buffer layer vs opaque depth")?;
            d.check_same_size(it, "A-buffer layer depth vs items")?;
        }
        let per_pixel: Vec<(Vec<Fragment>, usize)> = (0..w * h)
            .into_par_iter()
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let od = *opaque_depth.get(x, y);
                let mut v: Vec<Fragment> = Vec::new();
                let mut merged = 0;
                for (d, it) in layers {
                    let (fd, item) = (*d.get(x, y), *it.get(x, y));
                    if item == NO_ITEM || fd >= 1.0 || fd >= od {
                        continue;
                    }
                    // The same surface continues in a neighbour in any layer (peeling order
                    // changes where other fragments lie in front): its nearest fragment of
                    // the same object.
                    let mut half = 1e-6f32;
                    for (dx, dy) in [(1i32, 0i32), (-1, 0), (0, 1), (0, -1)] {
                        let (nx, ny) = (x as i32 + dx, y as i32 + dy);
                        if nx < 0 || ny < 0 || nx >= w as i32 || ny >= h as i32 {
                            continue;
                        }
                        let step = layers
                            .iter()
                            .filter(|(_, li)| *li.get(nx as u32, ny as u32) == item)
                            .map(|(ld, _)| (*ld.get(nx as u32, ny as u32) - fd).abs())
                            .fold(f32::INFINITY, f32::min);
                        if step.is_finite() {
                            half = half.max(0.75 * step);
                        }
                    }
                    let f = Fragment { depth: fd, half, rgba: rgba(item), item };
                    if v.len() < MAX_FRAGMENTS {
                        v.push(f);
                    } else {
                        let last = v.last_mut().expect("full");
                        over(&mut last.rgba, &f.rgba);
                        merged += 1;
                    }
                }
                (v, merged)
            })
            .collect();
        let mut start = Vec::with_capacity((w * h + 1) as usize);
        let mut frags = Vec::new();
        let mut merged = 0;
        start.push(0);
        for (v, m) in per_pixel {
            frags.extend(v);
            merged += m;
            start.push(frags.len() as u32);
        }
        Ok(ABuffer { width: w, height: h, start, frags, merged })
    }

    /// Size in pixels.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Pixel `(x, y)`'s fragments, front to back.
    #[inline]
    pub fn fragments(&self, x: u32, y: u32) -> &[Fragment] {
        let i = (y * self.width + x) as usize;
        &self.frags[self.start[i] as usize..self.start[i + 1] as usize]
    }

    /// Fragments stored.
    pub fn len(&self) -> usize {
        self.frags.len()
    }

    /// No fragment at all.
    pub fn is_empty(&self) -> bool {
        self.frags.is_empty()
    }

    /// The view itself: each pixel's fragments composited front to back over `opaque` (what
    /// rendering with transparency shows, the reference).
    pub fn composite(&self, opaque: &Image<[f32; 3]>) -> Result<Image<[f32; 3]>> {
        if opaque.size() != self.size() {
            return Err(Error::invalid("A-buffer composite: the opaque image has another size"));
        }
        let w = self.width;
        let data = (0..self.width * self.height)
            .into_par_iter()
            .map(|i| {
                let mut acc = [0.0f32; 4];
                for f in self.fragments(i % w, i / w) {
                    over(&mut acc, &f.rgba);
                }
                let o = opaque.data()[i as usize];
                [acc[0] + (1.0 - acc[3]) * o[0], acc[1] + (1.0 - acc[3]) * o[1], acc[2] + (1.0 - acc[3]) * o[2]]
            })
            .collect();
        Image::from_vec(self.width, self.height, data)
    }
}

/// The min-max quadtree over the A-buffer (seed 003 Sec. 4.2): per node the smallest and
/// largest extruded fragment depth below it (`[+inf, -inf]` where empty), levels 0 (pixels) to
/// [`LEVELS`] (32x32 roots).
#[derive(Clone, Debug)]
pub struct MinMaxTree {
    levels: Vec<(u32, u32, Vec<[f32; 2]>)>,
    /// `[min, max]` over the roots, kept once: every ray piece reads it ([`Self::range`]).
    range: (f32, f32),
}

const EMPTY: [f32; 2] = [f32::INFINITY, f32::NEG_INFINITY];

impl MinMaxTree {
    /// Builds the pyramid by parallel reductions.
    pub fn build(ab: &ABuffer) -> Self {
        let (w, h) = ab.size();
        let base: Vec<[f32; 2]> = (0..w * h)
            .into_par_iter()
            .map(|i| {
                ab.fragments(i % w, i / w)
                    .iter()
                    .fold(EMPTY, |r, f| [r[0].min(f.depth - f.half), r[1].max(f.depth + f.half)])
            })
            .collect();
        let mut levels = vec![(w, h, base)];
        for _ in 0..LEVELS {
            let (pw, ph, prev) = levels.last().expect("level 0");
            let (nw, nh) = (pw.div_ceil(2), ph.div_ceil(2));
            let next = (0..nw * nh)
                .into_par_iter()
                .map(|i| {
                    let (x, y) = (i % nw, i / nw);
                    let mut r = EMPTY;
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        let (cx, cy) = (2 * x + dx, 2 * y + dy);
                        if cx < *pw && cy < *ph {
                            let c = prev[(cy * pw + cx) as usize];
                            r = [r[0].min(c[0]), r[1].max(c[1])];
                        }
                    }
                    r
                })
                .collect();
            levels.push((nw, nh, next));
        }
        let range = levels[LEVELS].2.iter().fold((EMPTY[0], EMPTY[1]), |r, n| (r.0.min(n[0]), r.1.max(n[1])));
        MinMaxTree { levels, range }
    }

    /// `[min, max]` extruded depth over the whole A-buffer (`[+inf, -inf]` if empty).
    pub fn range(&self) -> (f32, f32) {
        self.range
    }

    /// Node `(x, y)` of `level`: `[min, max]` extruded depth.
    #[inline]
    pub fn node(&self, level: usize, x: u32, y: u32) -> [f32; 2] {
        let (w, h, v) = &self.levels[level];
        if x < *w && y < *h {
            v[(y * w + x) as usize]
        } else {
            EMPTY
        }
    }
}

/// Parameters of [`ray_cast`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayCastParams {
    /// Compositing stops once the accumulated opacity reaches this (Sec. 5.3).
    pub opacity: f32,
    /// Traversal steps per ray at most (a guard; a ray across a `w x h` image needs far fewer).
    pub max_steps: u32,
    /// Pixels on the edge of a transparent surface (their opacity differs from one of their 8
    /// neighbours' by more than [`EDGE_OPACITY`]) take the bilinear blend of four rays instead of
    /// the one through their centre: the rays through the centres of the four source texels
    /// around the point where the centre ray meets that surface, weighted by the bilinear
    /// weights of that point. The source holds the surface as point samples (one fragment per
    /// texel it covers), so its edge lies somewhere between a covered and an uncovered texel
    /// centre; the blend is the expected colour of the point-sampled target pixel under that
    /// uncertainty (the bilinear filter the opaque warp applies to colour), where one ray puts
    /// the edge on whole pixels. Each of the four rays ends at the warped opaque depth where it
    /// lands. The surface is the nearest one the centre ray hits or, where that one also covers
    /// all eight neighbours, the farthest one the nine rays hit (the edge is a surface seen
    /// through it); a centre ray that hits none takes the nearest surface its neighbours' rays
    /// hit.
    pub edge_rays: bool,
}

/// Opacity difference to a neighbour that makes a pixel an edge pixel ([`RayCastParams::edge_rays`]).
pub const EDGE_OPACITY: f32 = 0.02;

impl Default for RayCastParams {
    fn default() -> Self {
        RayCastParams { opacity: 0.99, max_steps: 1 << 16, edge_rays: true }
    }
}

/// The result of [`ray_cast`].
#[derive(Clone, Debug)]
pub struct RayCast {
    /// `base` with the transparent fragments composited over it.
    pub color: Image<[f32; 3]>,
    /// Quadtree nodes visited per pixel (Fig. 7b).
    pub steps: Image<u32>,
}

/// Ray casts the A-buffer `ab` of the source view `src` for every pixel of `dst` (seed 003 Sec.
/// 5.3) and composites the hits over `base`, the warped opaque image, front to back; each ray
/// ends at the warped opaque depth `depth` (target depth, 1 = nothing).
pub fn ray_cast(
    ab: &ABuffer,
    tree: &MinMaxTree,
    src: &Camera,
    dst: &Camera,
    base: &Image<[f32; 3]>,
    depth: &Image<f32>,
    p: &RayCastParams,
) -> Result<RayCast> {
    if ab.size() != (src.width, src.height) {
        return Err(Error::invalid("ray cast: the A-buffer does not have the source camera's size"));
    }
    base.check_same_size(depth, "ray cast base vs depth")?;
    if base.size() != (dst.width, dst.height) {
        return Err(Error::invalid("ray cast: the warped image does not have the target camera's size"));
    }
    if !(p.opacity > 0.0 && p.opacity <= 1.0) {
        return Err(Error::invalid(format!("ray cast: opacity threshold must be in (0, 1], got {}", p.opacity)));
    }
    // Target pixel + depth -> source pixel + depth: the inverse of the forward warp.
    let inv = WarpMatrix::new(dst, src)?;
    let (tw, th) = base.size();
    let caster = Caster { ab, tree, sw: src.width as f32, sh: src.height as f32, p };
    // The ray through target position (px, py), ending at the warped opaque depth of pixel
    // (x, y).
    // Its ends in source pixel / depth space (`None` behind the source eye).
    let ends = |x: u32, y: u32, px: f32, py: f32| {
        let end = depth.get(x, y).clamp(0.0, 1.0);
        let (a, e) = (inv.project(px, py, 0.0)?, inv.project(px, py, end)?);
        Some(([a.0, a.1, a.2], [e.0, e.1, e.2]))
    };
    let cast = |x: u32, y: u32, px: f32, py: f32| -> Ray {
        ends(x, y, px, py).map_or(Ray::MISS, |(a, e)| caster.cast_one(a, e))
    };
    let mut rays: Vec<Ray> = if ab.is_empty() {
        vec![Ray::MISS; (tw * th) as usize]
    } else {
        (0..tw * th)
            .into_par_iter()
            .map(|i| cast(i % tw, i / tw, (i % tw) as f32 + 0.5, (i / tw) as f32 + 0.5))
            .collect()
    };
    if p.edge_rays && !ab.is_empty() {
        let fwd = WarpMatrix::new(src, dst)?;
        let neighbours = |x: u32, y: u32| {
            (0..9u32).filter(|&k| k != 4).filter_map(move |k| {
                let (u, v) = ((x + k % 3).wrapping_sub(1), (y + k / 3).wrapping_sub(1));
                (u < tw && v < th).then(|| (v * tw + u) as usize)
            })
        };
        let edge = |x: u32, y: u32| {
            let a = rays[(y * tw + x) as usize].rgba[3];
            neighbours(x, y).any(|j| (rays[j].rgba[3] - a).abs() > EDGE_OPACITY)
        };
        // The source depth of the surface whose edge pixel (x, y) lies on.
        let surface = |x: u32, y: u32| -> Option<f32> {
            let own = &rays[(y * tw + x) as usize];
            if own.first.is_finite() {
                let covered = neighbours(x, y).all(|j| {
                    let n = &rays[j];
                    n.first.is_finite() && (n.first - own.first).abs() <= n.first_half + own.first_half
                });
                if !covered {
                    return Some(own.first);
                }
                // Seen through it: the farthest surface the nine rays hit.
                Some(neighbours(x, y).map(|j| rays[j].last).filter(|d| d.is_finite()).fold(own.last, f32::max))
            } else {
                let d = neighbours(x, y).map(|j| rays[j].first).fold(f32::INFINITY, f32::min);
                d.is_finite().then_some(d)
            }
        };
        // The four rays through the texel centres around where the centre ray of (x, y) meets
        // the surface at source depth `z`, blended with that point's bilinear weights.
        let blend = |x: u32, y: u32, z: f32| -> Option<Ray> {
            let (a, e) = ends(x, y, x as f32 + 0.5, y as f32 + 0.5)?;
            let dz = e[2] - a[2];
            let t = if dz.abs() > 1e-12 { ((z - a[2]) / dz).clamp(0.0, 1.0) } else { 0.0 };
            let (gx, gy) = (a[0] + (e[0] - a[0]) * t - 0.5, a[1] + (e[1] - a[1]) * t - 0.5);
            let (fx, fy) = (zwarp_core::round::floor(gx), zwarp_core::round::floor(gy));
            let (ax, ay) = (gx - fx, gy - fy);
            // The pixel a target position lies in (clamped into the image).
            let pixel = |v: f32, n: u32| (v.max(0.0) as u32).min(n - 1);
            let mut out = Ray { rgba: [0.0; 4], ..rays[(y * tw + x) as usize] };
            for k in 0..4u32 {
                let (ox, oy) = ((k % 2) as f32, (k / 2) as f32);
                let wgt = (ox * ax + (1.0 - ox) * (1.0 - ax)) * (oy * ay + (1.0 - oy) * (1.0 - ay));
                let q = fwd.project(fx + 0.5 + ox, fy + 0.5 + oy, z)?;
                let r = cast(pixel(q.0, tw), pixel(q.1, th), q.0, q.1);
                for (o, c) in out.rgba.iter_mut().zip(r.rgba) {
                    *o += wgt * c;
                }
                out.steps += r.steps;
            }
            Some(out)
        };
        let edges: Vec<(usize, Ray)> = (0..tw * th)
            .into_par_iter()
            .filter_map(|i| {
                let (x, y) = (i % tw, i / tw);
                if !edge(x, y) {
                    return None;
                }
                Some((i as usize, blend(x, y, surface(x, y)?)?))
            })
            .collect();
        for (i, r) in edges {
            rays[i] = r;
        }
    }
    let color = rays
        .par_iter()
        .zip(base.data())
        .map(|(Ray { rgba: acc, .. }, b)| {
            [acc[0] + (1.0 - acc[3]) * b[0], acc[1] + (1.0 - acc[3]) * b[1], acc[2] + (1.0 - acc[3]) * b[2]]
        })
        .collect();
    Ok(RayCast {
        color: Image::from_vec(tw, th, color)?,
        steps: Image::from_vec(tw, th, rays.iter().map(|r| r.steps).collect())?,
    })
}

/// One cast ray: premultiplied colour, quadtree nodes visited, and the source depths of the
/// first and last fragments it composited (`+inf` if none) with the first one's half extrusion.
#[derive(Clone, Copy, Debug)]
struct Ray {
    rgba: [f32; 4],
    steps: u32,
    first: f32,
    first_half: f32,
    last: f32,
}

impl Ray {
    /// A ray that hit nothing.
    const MISS: Ray = Ray { rgba: [0.0; 4], steps: 0, first: f32::INFINITY, first_half: 0.0, last: f32::INFINITY };
}

/// What a ray carries from one piece to the next: premultiplied colour, the last fragment hit
/// (with its pixel), the quadtree nodes visited and the first fragment hit.
struct RayState {
    acc: [f32; 4],
    /// The last fragment composited, its pixel and its index in that pixel's list.
    last: Option<(Fragment, (u32, u32), usize)>,
    steps: u32,
    first: Option<Fragment>,
}

/// What every ray of one [`ray_cast`] reads: the A-buffer, its quadtree, the source size and
/// the parameters.
#[derive(Clone, Copy)]
struct Caster<'a> {
    ab: &'a ABuffer,
    tree: &'a MinMaxTree,
    sw: f32,
    sh: f32,
    p: &'a RayCastParams,
}

impl Caster<'_> {
    /// One ray from `a` to `b` (source pixel x, y, depth).
    ///
    /// Where the ray runs outside the source image (the border strip the source did not see) it
    /// continues the transparent surfaces at the image border, as the hole filling does for opaque
    /// ones: those pieces of the ray are clamped onto the border (x and y clamped, depth kept) and
    /// traversed in ray order with the inside piece, so a pane that reaches the border still covers
    /// the strip at its own depth.
    fn cast_one(&self, a: [f32; 3], b: [f32; 3]) -> Ray {
        let Caster { sw, sh, p, .. } = *self;
        let d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        // Where the ray crosses the image's border lines: the ends of the pieces.
        let mut cuts = [0.0f32, 1.0, 1.0, 1.0, 1.0, 1.0];
        let mut n = 1;
        for (o, v, hi) in [(a[0], d[0], sw), (a[1], d[1], sh)] {
            if v.abs() > 1e-12 {
                for edge in [0.0, hi] {
                    let t = (edge - o) / v;
                    if t > 0.0 && t < 1.0 {
                        cuts[n] = t;
                        n += 1;
                    }
                }
            }
        }
        cuts[n] = 1.0;
        cuts[..=n].sort_by(f32::total_cmp);
        let at = |t: f32| [a[0] + d[0] * t, a[1] + d[1] * t, a[2] + d[2] * t];
        let clamp = |q: [f32; 3]| [q[0].clamp(0.0, sw - 1e-3), q[1].clamp(0.0, sh - 1e-3), q[2]];
        let mut ray = RayState { acc: [0.0; 4], last: None, steps: 0, first: None };
        for w in cuts[..=n].windows(2) {
            if w[1] > w[0] && ray.acc[3] < p.opacity {
                self.cast_piece(clamp(at(w[0])), clamp(at(w[1])), &mut ray);
            }
        }
        let last = ray.last.map_or(f32::INFINITY, |(f, _, _)| f.depth);
        match ray.first {
            Some(f) => Ray { rgba: ray.acc, steps: ray.steps, first: f.depth, first_half: f.half, last },
            None => Ray { rgba: ray.acc, steps: ray.steps, ..Ray::MISS },
        }
    }

    /// The traversal of one straight piece of a ray from `a` to `b` (source pixel x, y, depth, inside
    /// the image), compositing into `ray`.
    fn cast_piece(&self, a: [f32; 3], b: [f32; 3], ray: &mut RayState) {
        let Caster { ab, tree, sw, sh, p } = *self;
        let d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        // Clip to the source image (slabs in x and y).
        let (mut t0, mut t1) = (0.0f32, 1.0f32);
        for (o, v, hi) in [(a[0], d[0], sw), (a[1], d[1], sh)] {
            if v.abs() < 1e-12 {
                if o < 0.0 || o >= hi {
                    return;
                }
            } else {
                let (mut ta, mut tb) = ((0.0 - o) / v, (hi - o) / v);
                if ta > tb {
                    std::mem::swap(&mut ta, &mut tb);
                }
                t0 = t0.max(ta);
                t1 = t1.min(tb);
            }
        }
        // Empty-space skipping in depth: start where the ray reaches the nearest fragment.
        let (zmin, zmax) = tree.range();
        if d[2].abs() > 1e-12 {
            let (ta, tb) = ((zmin - a[2]) / d[2], (zmax - a[2]) / d[2]);
            t0 = t0.max(ta.min(tb));
            t1 = t1.min(ta.max(tb) + 1e-6);
        } else if a[2] < zmin || a[2] > zmax {
            return;
        }
        if t0 >= t1 {
            return;
        }
        let at = |t: f32| [a[0] + d[0] * t, a[1] + d[1] * t, a[2] + d[2] * t];
        // Cell index of the ray just after `t` (so a boundary point belongs to the next cell): a
        // thousandth of a pixel, several float steps even at 8K coordinates (a smaller step can
        // round back into the cell just left, which would then be visited twice).
        let nudge = 1e-3 / (d[0].abs() + d[1].abs()).max(1e-3);
        let cell = |t: f32, level: usize| {
            let q = at((t + nudge).min(t1));
            let (x, y) = ((q[0].clamp(0.0, sw - 1e-3)) as u32, (q[1].clamp(0.0, sh - 1e-3)) as u32);
            (x >> level, y >> level)
        };
        let exit = |t: f32, level: usize, cx: u32, cy: u32| {
            let s = (1u32 << level) as f32;
            let mut te = t1;
            for (o, v, c) in [(a[0], d[0], cx), (a[1], d[1], cy)] {
                if v > 1e-12 {
                    te = te.min(((c + 1) as f32 * s - o) / v);
                } else if v < -1e-12 {
                    te = te.min((c as f32 * s - o) / v);
                }
            }
            te.max(t)
        };
        let RayState { acc, last, steps, first } = ray;
        let mut level = LEVELS;
        let mut t = t0;
        while t < t1 && acc[3] < p.opacity && *steps < p.max_steps {
            *steps += 1;
            let (cx, cy) = cell(t, level);
            let te = exit(t, level, cx, cy);
            let (za, zb) = (at(t)[2], at(te)[2]);
            let (lo, hi) = (za.min(zb), za.max(zb));
            let n = tree.node(level, cx, cy);
            let hit = lo <= n[1] && hi >= n[0];
            if hit && level > 0 {
                level -= 1;
                continue;
            }
            if hit {
                // A leaf: the fragments whose boxes the ray's depth span meets, in ray order.
                let fr = ab.fragments(cx, cy);
                let forward = zb >= za;
                let mut visit = |i: usize, f: &Fragment| {
                    if acc[3] >= p.opacity || !(lo <= f.depth + f.half && hi >= f.depth - f.half) {
                        return;
                    }
                    if let Some((l, px, li)) = *last {
                        if px == (cx, cy) {
                            // The pixel again (the border piece of a ray continues in the pixel
                            // where the inside piece ended): only the fragments after the last hit.
                            if (forward && i <= li) || (!forward && i >= li) {
                                return;
                            }
                        } else if l.item == f.item && (l.depth - f.depth).abs() <= l.half + f.half {
                            // The same surface again in a neighbouring pixel within its thickness
                            // (overlapping boxes). Fragments of one pixel are distinct surfaces.
                            return;
                        }
                    }
                    over(acc, &f.rgba);
                    first.get_or_insert(*f);
                    *last = Some((*f, (cx, cy), i));
                };
                if forward {
                    fr.iter().enumerate().for_each(|(i, f)| visit(i, f));
                } else {
                    fr.iter().enumerate().rev().for_each(|(i, f)| visit(i, f));
                }
            }
            // Advance past the node; ascend when the next node is no sibling (other parent).
            let next = te.max(t + nudge);
            if next >= t1 {
                break;
            }
            if level < LEVELS {
                let (nx, ny) = cell(next, level);
                if (nx >> 1, ny >> 1) != (cx >> 1, cy >> 1) {
                    level += 1;
                }
            }
            t = next;
        }
    }
}
