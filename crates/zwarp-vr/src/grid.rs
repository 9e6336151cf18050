//! Adaptive grid warping (seed 003 Sec. 4.1.4, 5.1) and its baselines.
//!
//! The grid's cells come from the surface-estimation quadtree; each cell is one quad (two
//! triangles) whose corners sit on pixel corners. A corner's depth comes from the pixels
//! around it that are connected to the cell's corner pixel (a union of the 6 links between the
//! 4 pixels): where the surface continues, neighbouring cells share the vertex (no micro
//! holes); across a discontinuity each side extrapolates its own surface (no rubber sheets).
//! All vertices go through one combined warp matrix (source pixel + depth -> target clip, Sec.
//! 5.1), the quads are rasterised on the CPU with a depth test, and colour is fetched with
//! [`ColorFilter`]: bilinear (the default, measured better) or the paper's adaptive filtering,
//! bilinear over the texels connected to the nearest one (surfaces), nearest across
//! discontinuities.
//!
//! Baselines: `points` (one splat per pixel), `quads` (one quad per pixel, corners shared by
//! all four pixels: rubber sheets), `didyk` (Didyk et al. 2010: a quadtree split while the
//! disparity range of a node exceeds a threshold, connected corners), and `fpi`, zwarp's
//! fixed-point colour warp (seed 001's heuristic warp on a camera-only motion field).

use std::time::Instant;

use glam::{Mat4, Vec2, Vec4};
use rayon::prelude::*;
use zwarp_color::{HeuristicParams, Seed, WarpBasis};
use zwarp_core::{Camera, Error, Image, Result};

use crate::quadtree::{Cell, Collinearity, QuadTree, Reduction, LEVELS};

/// The combined warp matrix of seed 003 Sec. 5.1: source `(pixel x, pixel y, depth, 1)` ->
/// target `(X w, Y w, z, w)` with `(X, Y)` target pixel coordinates and `z / w` target depth.
/// It folds pixel -> NDC, the source's inverse view-projection, the target's view-projection
/// and NDC -> pixel into one matrix, so a vertex costs one multiply.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WarpMatrix(pub Mat4);

impl WarpMatrix {
    /// The warp from `src`'s image to `dst`'s image.
    pub fn new(src: &Camera, dst: &Camera) -> Result<Self> {
        let vp = src.view_proj();
        if vp.determinant().abs() < 1e-30 || !vp.is_finite() {
            return Err(Error::invalid("warp matrix: the source camera is not invertible"));
        }
        let (sw, sh) = (src.width as f32, src.height as f32);
        let (tw, th) = (dst.width as f32, dst.height as f32);
        let to_ndc = Mat4::from_cols(
            Vec4::new(2.0 / sw, 0.0, 0.0, 0.0),
            Vec4::new(0.0, -2.0 / sh, 0.0, 0.0),
            Vec4::Z,
            Vec4::new(-1.0, 1.0, 0.0, 1.0),
        );
        let to_pixel = Mat4::from_cols(
            Vec4::new(0.5 * tw, 0.0, 0.0, 0.0),
            Vec4::new(0.0, -0.5 * th, 0.0, 0.0),
            Vec4::Z,
            Vec4::new(0.5 * tw, 0.5 * th, 0.0, 1.0),
        );
        // In f64: in f32 the inverse of a view-projection with a far / near ratio of 10^4 and an
        // eye 100 m from the origin loses most of the precision of post-projection depths near 1
        // (a point 56 m away moved by metres between two eyes 64 mm apart).
        let m = to_pixel.as_dmat4() * dst.view_proj().as_dmat4() * vp.as_dmat4().inverse() * to_ndc.as_dmat4();
        Ok(WarpMatrix(m.as_mat4()))
    }

    /// The homogeneous target of a source point.
    #[inline]
    pub fn apply(&self, px: f32, py: f32, d: f32) -> Vec4 {
        self.0 * Vec4::new(px, py, d, 1.0)
    }

    /// Target pixel position and depth of a source point (`None` behind the target eye).
    #[inline]
    pub fn project(&self, px: f32, py: f32, d: f32) -> Option<(f32, f32, f32)> {
        let h = self.apply(px, py, d);
        (h.w > 1e-9).then(|| (h.x / h.w, h.y / h.w, h.z / h.w))
    }
}

/// A warp method (JSON `method`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Seed 003's adaptive grid from the quadtree built with this reduction.
    Grid(Reduction),
    /// One quad per pixel, corners shared by all neighbours (rubber sheets everywhere).
    Quads,
    /// One splat per pixel.
    Points,
    /// Didyk et al. 2010: disparity-range quadtree, connected corners.
    Didyk,
    /// zwarp's fixed-point colour warp (seed 001, heuristic variant with a fixed seed offset).
    Fpi,
}

impl Method {
    /// CLI / JSON name (`grid` is the irregular-grid reduction, the paper's best).
    pub fn name(self) -> String {
        match self {
            Method::Grid(Reduction::Irregular) => "grid".into(),
            Method::Grid(r) => format!("grid-{}", r.name()),
            Method::Quads => "quads".into(),
            Method::Points => "points".into(),
            Method::Didyk => "didyk".into(),
            Method::Fpi => "fpi".into(),
        }
    }

    /// Parses a name of [`Method::name`].
    pub fn parse(s: &str) -> Result<Self> {
        Ok(match s {
            "grid" => Method::Grid(Reduction::Irregular),
            "grid-partial" => Method::Grid(Reduction::PartialCross),
            "grid-cross" => Method::Grid(Reduction::Cross),
            "quads" => Method::Quads,
            "points" => Method::Points,
            "didyk" => Method::Didyk,
            "fpi" => Method::Fpi,
            o => {
                return Err(Error::invalid(format!(
                    "unknown warp method '{o}' (grid, grid-partial, grid-cross, quads, points, didyk, fpi)"
                )))
            }
        })
    }
}

/// The colour fetch of the grid methods (JSON `filter`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ColorFilter {
    /// Seed 003 Sec. 5.1's adaptive filtering: bilinear over the texels connected to the
    /// nearest one (quadtree connectivity), so nearest across discontinuities.
    Adaptive,
    /// Bilinear over all four texels, as the quads and Didyk et al.'s cells fetch. The
    /// default: against renders of the target eyes (one sample per pixel, 1280x720, Sponza,
    /// Munich and the procedural kinds, cyclops and alternate) it scores higher PSNR, SSIM and
    /// lower FLIP than [`ColorFilter::Adaptive`] on every scene measured. A silhouette the
    /// source sampled as a staircase of whole texels lands between the target's pixel centres;
    /// the hard edge of the nearest fetch puts the staircase's steps where the source had
    /// them, the one-texel blend puts a half-way colour there, which is closer to either
    /// colour the target's own sampling may pick.
    Bilinear,
}

impl ColorFilter {
    /// CLI / JSON name.
    pub fn name(self) -> &'static str {
        match self {
            ColorFilter::Adaptive => "adaptive",
            ColorFilter::Bilinear => "bilinear",
        }
    }

    /// Parses a name of [`ColorFilter::name`].
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "adaptive" => Ok(ColorFilter::Adaptive),
            "bilinear" => Ok(ColorFilter::Bilinear),
            o => Err(Error::invalid(format!("unknown colour filter '{o}' (adaptive, bilinear)"))),
        }
    }
}

/// Parameters of [`warp`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WarpParams {
    /// The collinearity tolerance of the quadtree (eq. 2).
    pub collinearity: Collinearity,
    /// A connected cell is split when its estimated deviation from a plane moves its content by
    /// more than this many target pixels (Sec. 4.1.4's estimation error threshold).
    pub max_error_px: f32,
    /// Didyk et al.'s split threshold: the largest disparity range (pixels) within one cell.
    pub didyk_px: f32,
    /// A view-dependent bound added to seed 003's grid: a quadtree node whose disparity range
    /// is at most this many pixels is one cell even across a discontinuity (it moves rigidly
    /// to within the threshold), so the grid never needs more cells than Didyk et al. at the
    /// same threshold. `None`: the paper's grid alone.
    pub rigid_px: Option<f32>,
    /// The colour fetch of the grid methods (the others: bilinear, points nearest).
    pub filter: ColorFilter,
}

impl Default for WarpParams {
    fn default() -> Self {
        WarpParams {
            collinearity: Collinearity::default(),
            max_error_px: 0.5,
            didyk_px: 0.5,
            rigid_px: Some(0.5),
            filter: ColorFilter::Bilinear,
        }
    }
}

/// The source view of a warp.
#[derive(Clone, Copy, Debug)]
pub struct Source<'a> {
    /// Camera of the source render.
    pub cam: &'a Camera,
    /// Its depth, `[0, 1]`, 1 = sky.
    pub depth: &'a Image<f32>,
    /// Its linear RGB colour.
    pub color: &'a Image<[f32; 3]>,
}

impl Source<'_> {
    /// Errors unless depth, colour and camera have one size and the depth is finite.
    pub fn check(&self) -> Result<()> {
        self.depth.check_nonempty("warp source depth")?;
        self.depth.check_same_size(self.color, "warp source depth vs colour")?;
        if self.depth.size() != (self.cam.width, self.cam.height) {
            return Err(Error::invalid(format!(
                "warp source is {}x{} but its camera renders {}x{}",
                self.depth.width(),
                self.depth.height(),
                self.cam.width,
                self.cam.height
            )));
        }
        if !self.depth.all_finite() {
            return Err(Error::invalid("warp source depth holds NaN or infinite values"));
        }
        Ok(())
    }
}

/// Time of each stage of one warp (ms).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StageMs {
    /// Building the surface-estimation quadtree (Sec. 4.1).
    pub quadtree: f64,
    /// Building the grid / mesh for this view (Sec. 4.1.4).
    pub grid: f64,
    /// Warping and rasterising, colour fetch included (Sec. 5.1).
    pub warp: f64,
}

/// The result of a warp.
#[derive(Clone, Debug)]
pub struct WarpOutput {
    /// Linear RGB; black where `hole`.
    pub color: Image<[f32; 3]>,
    /// Target depth of the surface shown (`[0, 1]`); 1 where `hole`.
    pub depth: Image<f32>,
    /// Pixels no primitive covered (disocclusions, image borders).
    pub hole: Image<bool>,
    /// Primitives drawn (grid cells, quads or splats).
    pub primitives: usize,
    /// The grid cells in source pixels (grid and Didyk methods; empty otherwise).
    pub cells: Vec<Cell>,
    /// Stage times.
    pub ms: StageMs,
}

fn ms_since(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// What a warp method draws for one view, built on the CPU: seed 003's grid cells with the
/// quadtree whose connectivity gives the corner depths and the colour filter, one quad per pixel,
/// Didyk et al.'s cells, or one splat per pixel. [`raster`] draws it on the CPU;
/// `gpu::GridWarpKernel` draws the same mesh with the GPU's rasteriser.
#[derive(Clone, Debug)]
pub struct Mesh {
    /// The method it is built for.
    pub method: Method,
    /// The primitives.
    pub primitives: Primitives,
    /// The surface-estimation quadtree (grid methods): connected corners share vertices (and
    /// with [`ColorFilter::Adaptive`] the colour fetch follows its connectivity). `None`: every
    /// corner is shared and the fetch is bilinear (quads, Didyk), or nearest (points).
    pub tree: Option<QuadTree>,
    /// The colour fetch of the cells (grid methods: [`WarpParams::filter`]; quads and Didyk:
    /// bilinear).
    pub filter: ColorFilter,
    /// The combined warp matrix from the source to the target view.
    pub matrix: WarpMatrix,
    /// Time of building the quadtree and the cells (ms; `warp` is 0 here).
    pub ms: StageMs,
}

/// The primitives of a [`Mesh`].
#[derive(Clone, Debug, PartialEq)]
pub enum Primitives {
    /// Quads over source pixel rectangles (two triangles each).
    Cells(Vec<Cell>),
    /// One splat per source pixel.
    Points,
}

impl Mesh {
    /// The mesh of `method` (any but [`Method::Fpi`], which draws nothing) for the warp from
    /// `src` to `dst`.
    pub fn build(src: &Source<'_>, dst: &Camera, method: Method, p: &WarpParams) -> Result<Self> {
        src.check()?;
        let matrix = WarpMatrix::new(src.cam, dst)?;
        let (w, h) = src.depth.size();
        let t = Instant::now();
        match method {
            Method::Grid(r) => {
                let tree = QuadTree::build(src.depth, r, &p.collinearity)?;
                let quadtree = ms_since(t);
                let mut mesh = Mesh::grid(src, dst, tree, p)?;
                mesh.ms.quadtree = quadtree;
                Ok(mesh)
            }
            Method::Quads => {
                let cells =
                    (0..h).flat_map(|y| (0..w).map(move |x| Cell { x0: x, y0: y, x1: x + 1, y1: y + 1 })).collect();
                Ok(Mesh::connected(method, Primitives::Cells(cells), matrix, ms_since(t)))
            }
            Method::Didyk => {
                let cells = didyk_cells(src, &matrix, p.didyk_px)?;
                Ok(Mesh::connected(method, Primitives::Cells(cells), matrix, ms_since(t)))
            }
            Method::Points => Ok(Mesh::connected(method, Primitives::Points, matrix, 0.0)),
            Method::Fpi => Err(Error::invalid("the fpi warp is a per-pixel search: it draws no mesh")),
        }
    }

    /// A mesh without a quadtree (quads, Didyk, points): every corner shared, bilinear fetch
    /// (points: nearest); `grid_ms` is the time of building its primitives.
    fn connected(method: Method, primitives: Primitives, matrix: WarpMatrix, grid_ms: f64) -> Self {
        let ms = StageMs { grid: grid_ms, ..StageMs::default() };
        Mesh { method, primitives, tree: None, filter: ColorFilter::Bilinear, matrix, ms }
    }

    /// The adaptive grid of a quadtree built by the caller (e.g. once for both eyes).
    pub fn grid(src: &Source<'_>, dst: &Camera, tree: QuadTree, p: &WarpParams) -> Result<Self> {
        src.check()?;
        if tree.size() != src.depth.size() {
            return Err(Error::invalid("grid warp: the quadtree was built for another image size"));
        }
        if !(p.max_error_px.is_finite() && p.max_error_px >= 0.0) {
            return Err(Error::invalid(format!("grid warp: max error must be >= 0 pixels, got {}", p.max_error_px)));
        }
        let matrix = WarpMatrix::new(src.cam, dst)?;
        let t = Instant::now();
        let cells = grid_cells(src, &matrix, &tree, p);
        let ms = StageMs { grid: ms_since(t), ..StageMs::default() };
        Ok(Mesh {
            method: Method::Grid(tree.reduction),
            primitives: Primitives::Cells(cells),
            tree: Some(tree),
            filter: p.filter,
            matrix,
            ms,
        })
    }

    /// Primitives drawn: cells (quads) or splats.
    pub fn count(&self, src: &Source<'_>) -> usize {
        match &self.primitives {
            Primitives::Cells(c) => c.len(),
            Primitives::Points => src.depth.len(),
        }
    }

    /// The cells [`WarpOutput::cells`] reports, for drawing the grid over the image: all of
    /// them, except for one quad per pixel (no picture) and points.
    pub fn outline(&self) -> Vec<Cell> {
        if self.method == Method::Quads {
            Vec::new()
        } else {
            self.cells().to_vec()
        }
    }

    /// The grid cells (empty for points).
    pub fn cells(&self) -> &[Cell] {
        match &self.primitives {
            Primitives::Cells(c) => c,
            Primitives::Points => &[],
        }
    }
}

/// Warps `src` to the view of `dst` with `method`: its [`Mesh`] drawn by [`raster`] (`fpi`: the
/// fixed-point colour warp).
pub fn warp(src: &Source<'_>, dst: &Camera, method: Method, p: &WarpParams) -> Result<WarpOutput> {
    src.check()?;
    if method == Method::Fpi {
        let t = Instant::now();
        let mut out = fpi(src, dst)?;
        out.ms = StageMs { quadtree: 0.0, grid: 0.0, warp: ms_since(t) };
        return Ok(out);
    }
    let mesh = Mesh::build(src, dst, method, p)?;
    raster(src, dst, &mesh)
}

/// Draws `mesh` on the CPU: warped quads rasterised with a depth test (or splats), then the
/// colour fetch (stage `warp`; the mesh's own stage times are kept).
pub fn raster(src: &Source<'_>, dst: &Camera, mesh: &Mesh) -> Result<WarpOutput> {
    raster_impl(src, dst, mesh, None)
}

/// [`raster`] restricted to the target pixels set in `only` (the target's size): quads whose
/// footprint touches none of them are not drawn. Exact on those pixels (every quad covering
/// one is drawn, so the depth test picks the same one); the other pixels are undefined. The
/// rubber-sheet hole fill draws the connected quads of the holes alone this way.
pub fn raster_where(src: &Source<'_>, dst: &Camera, mesh: &Mesh, only: &Image<bool>) -> Result<WarpOutput> {
    if only.size() != (dst.width, dst.height) {
        return Err(Error::invalid("raster_where: the pixel mask does not have the target camera's size"));
    }
    raster_impl(src, dst, mesh, Some(only))
}

fn raster_impl(src: &Source<'_>, dst: &Camera, mesh: &Mesh, only: Option<&Image<bool>>) -> Result<WarpOutput> {
    src.check()?;
    let t = Instant::now();
    let mut out = match &mesh.primitives {
        Primitives::Cells(cells) => raster_cells(src, dst, mesh, cells, only.map(MaskSums::new).as_ref())?,
        Primitives::Points => points(src, dst, &mesh.matrix)?,
    };
    out.ms = StageMs { warp: ms_since(t), ..mesh.ms };
    out.primitives = mesh.count(src);
    out.cells = mesh.outline();
    Ok(out)
}

/// The adaptive grid of `tree` for the warp `m`: a connected cell is split when its estimated
/// plane deviation (`err * n^2 / 8` stored depth over `n` pixels, the sagitta of a curve with
/// second difference `err`) moves it by more than `p.max_error_px` target pixels; with
/// `p.rigid_px`, nodes moving rigidly to within that many pixels are not split.
pub fn grid_cells(src: &Source<'_>, m: &WarpMatrix, tree: &QuadTree, p: &WarpParams) -> Vec<Cell> {
    let split = |err: f32, c: Cell| {
        if err <= 0.0 {
            return false;
        }
        let n = (c.x1 - c.x0).max(c.y1 - c.y0) as f32;
        let dev = err * n * n / 8.0;
        let (cx, cy) = ((c.x0 + c.x1) / 2, (c.y0 + c.y1) / 2);
        let d = *src.depth.get(cx.min(src.depth.width() - 1), cy.min(src.depth.height() - 1));
        let (px, py) = (cx as f32 + 0.5, cy as f32 + 0.5);
        match (m.project(px, py, d), m.project(px, py, (d + dev).min(1.0 + dev))) {
            (Some(a), Some(b)) => (a.0 - b.0).hypot(a.1 - b.1) > p.max_error_px,
            _ => true,
        }
    };
    match p.rigid_px {
        None => tree.cells(split),
        Some(tau) => {
            let lv = disparity_pyramid(src, m);
            tree.cells_with(split, |level, x, y| {
                let (lw, _, v) = &lv[level];
                let r = v[(y * lw + x) as usize];
                r[1] - r[0] <= tau && r[3] - r[2] <= tau
            })
        }
    }
}

/// Depth of the vertex at pixel corner `(cx, cy)` for the cell pixel `(px, py)` (one of the
/// four pixels around the corner): the pixels connected to it among the four, by union over
/// the 6 links; one pixel -> its depth, two -> their mean (exact for a plane at the midpoint
/// of diagonal pixels), three -> the mean of its diagonal pair (whose midpoint is the corner),
/// four -> the mean of all. A single pixel, or an adjacent pair, is extrapolated half a pixel
/// along the axes it does not span with the slope of its surface (exact on planes: both sides
/// of a crease meet, separate surfaces keep their own depth). `tree = None` connects all four
/// without extrapolation (rubber sheets).
pub fn corner_depth(depth: &Image<f32>, tree: Option<&QuadTree>, cx: u32, cy: u32, px: u32, py: u32) -> f32 {
    let (w, h) = depth.size();
    // Pixels a (top-left), b (top-right), c (bottom-left), d (bottom-right) of the corner.
    let pos = [
        (cx as i32 - 1, cy as i32 - 1),
        (cx as i32, cy as i32 - 1),
        (cx as i32 - 1, cy as i32),
        (cx as i32, cy as i32),
    ];
    let inside = |i: usize| pos[i].0 >= 0 && pos[i].1 >= 0 && pos[i].0 < w as i32 && pos[i].1 < h as i32;
    if tree.is_none() {
        // Rubber sheets: every pixel of the corner inside the image is connected to the cell
        // pixel, no extrapolation: their mean, summed in index order as below (the per-pixel
        // quads ask this a million times).
        let (mut s, mut n) = (0.0, 0u32);
        for (i, &(x, y)) in pos.iter().enumerate() {
            if inside(i) {
                s += *depth.get(x as u32, y as u32);
                n += 1;
            }
        }
        return s / n as f32;
    }
    let me = pos.iter().position(|&q| q == (px as i32, py as i32)).expect("the cell pixel touches its corner");
    let mut parent = [0usize, 1, 2, 3];
    fn find(p: &mut [usize; 4], i: usize) -> usize {
        let mut i = i;
        while p[i] != i {
            i = p[i];
        }
        i
    }
    let links = [(0, 1), (2, 3), (0, 2), (1, 3), (0, 3), (1, 2)];
    for &(i, j) in &links {
        if !(inside(i) && inside(j)) {
            continue;
        }
        let ok = match tree {
            None => true,
            Some(t) => t.connected(pos[i].0, pos[i].1, pos[j].0 - pos[i].0, pos[j].1 - pos[i].1),
        };
        if ok {
            let (a, b) = (find(&mut parent, i), find(&mut parent, j));
            parent[a] = b;
        }
    }
    let root = find(&mut parent, me);
    // The members of `me`'s component in index order (no allocation: this runs per cell corner).
    let mut members = [0usize; 4];
    let mut count = 0;
    for i in 0..4 {
        if inside(i) && find(&mut parent, i) == root {
            members[count] = i;
            count += 1;
        }
    }
    let comp = &members[..count];
    let d = |i: usize| *depth.get(pos[i].0 as u32, pos[i].1 as u32);
    let cols = comp.iter().any(|&i| i % 2 == 0) && comp.iter().any(|&i| i % 2 == 1);
    let rows = comp.iter().any(|&i| i < 2) && comp.iter().any(|&i| i >= 2);
    // Half a pixel outwards along the surface of member `i` on axis (ax, ay): the slope from
    // its inward neighbour when that one is connected (exact on a plane, so both sides of a
    // crease meet), else none.
    let extrapolate = |i: usize, ax: i32, ay: i32| -> f32 {
        let Some(t) = tree else { return 0.0 };
        let (mx, my) = pos[i];
        // Outward points from the pixel centre to the corner.
        let (ox, oy) = (
            if ax != 0 {
                if mx < cx as i32 {
                    1
                } else {
                    -1
                }
            } else {
                0
            },
            if ay != 0 {
                if my < cy as i32 {
                    1
                } else {
                    -1
                }
            } else {
                0
            },
        );
        if t.connected(mx, my, -ox, -oy) {
            0.5 * (d(i) - *depth.get((mx - ox) as u32, (my - oy) as u32))
        } else {
            0.0
        }
    };
    match comp.len() {
        3 => {
            // The diagonal pair of the three: (0, 3) or (1, 2); its midpoint is the corner.
            if comp.contains(&0) && comp.contains(&3) {
                0.5 * (d(0) + d(3))
            } else {
                0.5 * (d(1) + d(2))
            }
        }
        n => {
            let mut s = 0.0;
            for &i in comp {
                let mut v = d(i);
                if !cols {
                    v += extrapolate(i, 1, 0);
                }
                if !rows {
                    v += extrapolate(i, 0, 1);
                }
                s += v;
            }
            s / n as f32
        }
    }
}

/// The depths of the four corners of cell `c` in the order of [`Cell::corner`], each by
/// [`corner_depth`] from the cell pixel at that corner.
pub fn corner_depths(depth: &Image<f32>, tree: Option<&QuadTree>, c: &Cell) -> [f32; 4] {
    let px = [(c.x0, c.y0), (c.x1 - 1, c.y0), (c.x0, c.y1 - 1), (c.x1 - 1, c.y1 - 1)];
    std::array::from_fn(|i| {
        let (cx, cy) = c.corner(i);
        corner_depth(depth, tree, cx, cy, px[i].0, px[i].1)
    })
}

/// The two triangles of a cell as corner indices of [`Cell::corner`] (shared with the GPU twin).
pub const CELL_TRIANGLES: [[usize; 3]; 2] = [[0, 1, 3], [0, 3, 2]];

/// One warped triangle ready for rasterisation.
#[derive(Clone, Copy, Debug)]
struct Tri {
    /// Screen positions.
    p: [Vec2; 3],
    /// Target depth `z / w`.
    z: [f32; 3],
    /// `1 / w`, `u / w`, `v / w` (perspective-correct texture coordinates).
    iw: [f32; 3],
    uw: [f32; 3],
    vw: [f32; 3],
    /// The cell's source rectangle (texture coordinates stay inside it).
    clamp: [f32; 4],
    /// Coverage tolerance per edge (edge-function units, ~0.02 px).
    tol: [f32; 3],
    /// Pixel bounding box.
    bb: [i32; 4],
    area: f32,
}

/// Covers a pixel centre whose distance outside an edge is below this (pixels): closes the
/// sub-pixel slivers that T-junctions on nearly flat surfaces leave; overlaps are resolved by
/// the depth test.
const EDGE_TOL_PX: f32 = 0.02;

fn make_tri(v: [(Vec4, Vec2); 3], clamp: [f32; 4], tw: u32, th: u32) -> Option<Tri> {
    if v.iter().any(|(h, _)| h.w <= 1e-9 || !h.is_finite()) {
        return None;
    }
    let p = v.map(|(h, _)| Vec2::new(h.x / h.w, h.y / h.w));
    let area = (p[1] - p[0]).perp_dot(p[2] - p[0]);
    // NaN areas fail too.
    if area.abs().partial_cmp(&1e-12) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    let lo = p[0].min(p[1]).min(p[2]) - Vec2::splat(EDGE_TOL_PX);
    let hi = p[0].max(p[1]).max(p[2]) + Vec2::splat(EDGE_TOL_PX);
    let bb = [
        (zwarp_core::round::ceil(lo.x - 0.5) as i32).max(0),
        (zwarp_core::round::ceil(lo.y - 0.5) as i32).max(0),
        (zwarp_core::round::floor(hi.x - 0.5) as i32).min(tw as i32 - 1),
        (zwarp_core::round::floor(hi.y - 0.5) as i32).min(th as i32 - 1),
    ];
    if bb[0] > bb[2] || bb[1] > bb[3] {
        return None;
    }
    let e = |i: usize| (p[(i + 2) % 3] - p[(i + 1) % 3]).length() * EDGE_TOL_PX;
    Some(Tri {
        p,
        z: v.map(|(h, _)| h.z / h.w),
        iw: v.map(|(h, _)| 1.0 / h.w),
        uw: v.map(|(h, t)| t.x / h.w),
        vw: v.map(|(h, t)| t.y / h.w),
        clamp,
        tol: [e(0), e(1), e(2)],
        bb,
        area,
    })
}

/// Rows per raster band (the parallel unit; bands never share pixels).
const BAND: u32 = 16;

/// Warps the quads of `cells` (corners by [`corner_depth`] with the mesh's tree, `None`: all
/// connected) and rasterises them with a depth test, then fetches colour with [`sample`] and
/// the mesh's filter.
/// Summed-area table of a pixel mask: whether a pixel box holds a set pixel, in O(1).
struct MaskSums {
    w: usize,
    sums: Vec<u32>,
}

impl MaskSums {
    fn new(mask: &Image<bool>) -> Self {
        let (w, h) = (mask.width() as usize, mask.height() as usize);
        let mut sums = vec![0u32; (w + 1) * (h + 1)];
        for y in 0..h {
            let mut row = 0;
            for x in 0..w {
                row += *mask.get(x as u32, y as u32) as u32;
                sums[(y + 1) * (w + 1) + x + 1] = sums[y * (w + 1) + x + 1] + row;
            }
        }
        MaskSums { w: w + 1, sums }
    }

    /// `true` if the inclusive pixel box `[x0, y0, x1, y1]` (inside the mask) holds a set pixel.
    fn any(&self, [x0, y0, x1, y1]: [i32; 4]) -> bool {
        let at = |x: i32, y: i32| self.sums[y as usize * self.w + x as usize];
        at(x1 + 1, y1 + 1) + at(x0, y0) > at(x0, y1 + 1) + at(x1 + 1, y0)
    }
}

fn raster_cells(
    src: &Source<'_>,
    dst: &Camera,
    mesh: &Mesh,
    cells: &[Cell],
    only: Option<&MaskSums>,
) -> Result<WarpOutput> {
    let (m, tree) = (&mesh.matrix, mesh.tree.as_ref());
    let (tw, th) = (dst.width, dst.height);
    let tris: Vec<Tri> = cells
        .par_iter()
        .flat_map_iter(|c| {
            let d = corner_depths(src.depth, tree, c);
            let v: [(Vec4, Vec2); 4] = std::array::from_fn(|i| {
                let (cx, cy) = c.corner(i);
                (m.apply(cx as f32, cy as f32, d[i]), Vec2::new(cx as f32, cy as f32))
            });
            let clamp = [c.x0 as f32, c.y0 as f32, c.x1 as f32, c.y1 as f32];
            CELL_TRIANGLES
                .into_iter()
                .filter_map(move |[a, b, c]| make_tri([v[a], v[b], v[c]], clamp, tw, th))
                .filter(move |t| only.is_none_or(|m| m.any(t.bb)))
        })
        .collect();
    let bands = th.div_ceil(BAND) as usize;
    let mut lists: Vec<Vec<u32>> = vec![Vec::new(); bands];
    for (i, t) in tris.iter().enumerate() {
        for b in (t.bb[1] as u32 / BAND)..=(t.bb[3] as u32 / BAND) {
            lists[b as usize].push(i as u32);
        }
    }
    // Per target pixel: depth, source texture coordinate.
    let n = (tw * th) as usize;
    let mut zbuf = vec![f32::INFINITY; n];
    let mut uv = vec![Vec2::ZERO; n];
    zbuf.par_chunks_mut((BAND * tw) as usize).zip(uv.par_chunks_mut((BAND * tw) as usize)).enumerate().for_each(
        |(b, (zb, uvb))| {
            let y0 = b as i32 * BAND as i32;
            let y1 = (y0 + BAND as i32).min(th as i32) - 1;
            #[cfg(target_arch = "x86_64")]
            let avx2 = std::arch::is_x86_feature_detected!("avx2");
            for &ti in &lists[b] {
                let t = &tris[ti as usize];
                for y in t.bb[1].max(y0)..=t.bb[3].min(y1) {
                    let row = (y - y0) as usize * tw as usize;
                    let (zr, uvr) = (&mut zb[row..row + tw as usize], &mut uvb[row..row + tw as usize]);
                    #[cfg(target_arch = "x86_64")]
                    if avx2 {
                        // SAFETY: only taken when the CPU reports AVX2.
                        unsafe { raster_span_avx2(t, y, zr, uvr) };
                        continue;
                    }
                    raster_span(t, y, zr, uvr);
                }
            }
        },
    );
    let filter = match (mesh.filter, tree) {
        (ColorFilter::Adaptive, Some(t)) => Filter::Adaptive(t),
        _ => Filter::Bilinear,
    };
    Ok(resolve(src, m, tw, th, &zbuf, &uv, filter))
}

/// Rasterises row `y` of triangle `t` (its bounding box's columns) into one row of the depth
/// buffer and texture coordinates: the pixel centres inside every edge (within
/// the edge tolerance) and nearer than what the row holds take the triangle's depth and its
/// perspective-correct texture coordinate, clamped inside the cell.
#[inline]
fn raster_span(t: &Tri, y: i32, zr: &mut [f32], uvr: &mut [Vec2]) {
    let inv = 1.0 / t.area;
    let py = y as f32 + 0.5;
    for x in t.bb[0]..=t.bb[2] {
        let q = Vec2::new(x as f32 + 0.5, py);
        let mut l = [0.0f32; 3];
        let mut inside = true;
        for (i, li) in l.iter_mut().enumerate() {
            let (a, bb) = (t.p[(i + 1) % 3], t.p[(i + 2) % 3]);
            let e = (bb - a).perp_dot(q - a) * t.area.signum();
            if e < -t.tol[i] {
                inside = false;
                break;
            }
            *li = e * inv.abs();
        }
        if !inside {
            continue;
        }
        let z = l[0] * t.z[0] + l[1] * t.z[1] + l[2] * t.z[2];
        let k = x as usize;
        if z < zr[k] {
            zr[k] = z;
            let iw = l[0] * t.iw[0] + l[1] * t.iw[1] + l[2] * t.iw[2];
            let u = (l[0] * t.uw[0] + l[1] * t.uw[1] + l[2] * t.uw[2]) / iw;
            let v = (l[0] * t.vw[0] + l[1] * t.vw[1] + l[2] * t.vw[2]) / iw;
            // Inside the cell, off its border by a hair (nearest texel stays in it).
            uvr[k] =
                Vec2::new(u.clamp(t.clamp[0] + 1e-3, t.clamp[2] - 1e-3), v.clamp(t.clamp[1] + 1e-3, t.clamp[3] - 1e-3));
        }
    }
}

/// `f32::clamp` per lane as two compare-selects (below `lo`: `lo`, then above `hi`: `hi`; NaN
/// stays NaN), bit for bit the scalar clamp of the AVX2 twins.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
unsafe fn clamp8(
    v: std::arch::x86_64::__m256,
    lo: std::arch::x86_64::__m256,
    hi: std::arch::x86_64::__m256,
) -> std::arch::x86_64::__m256 {
    use std::arch::x86_64::*;
    let v = _mm256_blendv_ps(v, lo, _mm256_cmp_ps::<_CMP_LT_OQ>(v, lo));
    _mm256_blendv_ps(v, hi, _mm256_cmp_ps::<_CMP_GT_OQ>(v, hi))
}

/// [`raster_span`] over the whole span, eight pixels at a time: the same operations in the same
/// order (no FMA, the clamp as two compare-selects), so the same bits; the last group's lanes
/// beyond the span are masked.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn raster_span_avx2(t: &Tri, y: i32, zr: &mut [f32], uvr: &mut [Vec2]) {
    use std::arch::x86_64::*;
    let (xa, xb) = (t.bb[0], t.bb[2]);
    let s = |v: f32| _mm256_set1_ps(v);
    let sgn = s(t.area.signum());
    let inva = s((1.0 / t.area).abs());
    let py = s(y as f32 + 0.5);
    // Per edge i: its start a, its direction bb - a, and the tolerance.
    let edge = |i: usize| {
        let (a, bb) = (t.p[(i + 1) % 3], t.p[(i + 2) % 3]);
        let d = bb - a;
        (s(a.x), s(a.y), s(d.x), s(d.y), s(-t.tol[i]))
    };
    let edges = [edge(0), edge(1), edge(2)];
    let (lo_u, hi_u, lo_v, hi_v) =
        (s(t.clamp[0] + 1e-3), s(t.clamp[2] - 1e-3), s(t.clamp[1] + 1e-3), s(t.clamp[3] - 1e-3));
    let lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    let mut x = xa;
    while x <= xb {
        let xi = _mm256_add_epi32(_mm256_set1_epi32(x), lane);
        let live = _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(xb + 1), xi));
        let qx = _mm256_add_ps(_mm256_cvtepi32_ps(xi), s(0.5));
        let mut inside = live;
        let mut l = [_mm256_setzero_ps(); 3];
        for (li, &(ax, ay, dx, dy, ntol)) in l.iter_mut().zip(&edges) {
            let e = _mm256_mul_ps(
                _mm256_sub_ps(_mm256_mul_ps(dx, _mm256_sub_ps(py, ay)), _mm256_mul_ps(dy, _mm256_sub_ps(qx, ax))),
                sgn,
            );
            inside = _mm256_andnot_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(e, ntol), inside);
            *li = _mm256_mul_ps(e, inva);
        }
        if _mm256_movemask_ps(inside) != 0 {
            let dot = |w: [f32; 3]| {
                _mm256_add_ps(
                    _mm256_add_ps(_mm256_mul_ps(l[0], s(w[0])), _mm256_mul_ps(l[1], s(w[1]))),
                    _mm256_mul_ps(l[2], s(w[2])),
                )
            };
            let z = dot(t.z);
            let k = x as usize;
            let mi = _mm256_castps_si256(inside);
            let zold = _mm256_maskload_ps(zr.as_ptr().add(k), mi);
            let nearer = _mm256_and_ps(inside, _mm256_cmp_ps::<_CMP_LT_OQ>(z, zold));
            let bits = _mm256_movemask_ps(nearer);
            if bits != 0 {
                _mm256_maskstore_ps(zr.as_mut_ptr().add(k), _mm256_castps_si256(nearer), z);
                let iw = dot(t.iw);
                let u = clamp8(_mm256_div_ps(dot(t.uw), iw), lo_u, hi_u);
                let v = clamp8(_mm256_div_ps(dot(t.vw), iw), lo_v, hi_v);
                let (mut us, mut vs) = ([0f32; 8], [0f32; 8]);
                _mm256_storeu_ps(us.as_mut_ptr(), u);
                _mm256_storeu_ps(vs.as_mut_ptr(), v);
                for j in (0..8).filter(|j| bits >> j & 1 != 0) {
                    uvr[k + j] = Vec2::new(us[j], vs[j]);
                }
            }
        }
        x += 8;
    }
}

/// Texture filtering of the colour fetch.
#[derive(Clone, Copy)]
enum Filter<'a> {
    /// Nearest texel (points).
    Nearest,
    /// Bilinear over all four texels (quads, Didyk: everything is connected).
    Bilinear,
    /// Seed 003 Sec. 5.1: bilinear over the texels connected to the nearest one.
    Adaptive(&'a QuadTree),
}

/// Colour of `color` at source position `uv` (pixel units) with `filter`.
#[inline(always)]
fn sample(color: &Image<[f32; 3]>, uv: Vec2, filter: Filter<'_>) -> [f32; 3] {
    let (w, h) = (color.width() as i32, color.height() as i32);
    let nx = (zwarp_core::round::floor(uv.x) as i32).clamp(0, w - 1);
    let ny = (zwarp_core::round::floor(uv.y) as i32).clamp(0, h - 1);
    if let Filter::Nearest = filter {
        return *color.get(nx as u32, ny as u32);
    }
    let (fx, fy) = (uv.x - 0.5, uv.y - 0.5);
    let (x0, y0) = (zwarp_core::round::floor(fx) as i32, zwarp_core::round::floor(fy) as i32);
    let (ax, ay) = (fx - x0 as f32, fy - y0 as f32);
    let mut acc = [0.0f32; 3];
    let mut wsum = 0.0f32;
    for (dx, dy, wt) in
        [(0, 0, (1.0 - ax) * (1.0 - ay)), (1, 0, ax * (1.0 - ay)), (0, 1, (1.0 - ax) * ay), (1, 1, ax * ay)]
    {
        let (tx, ty) = ((x0 + dx).clamp(0, w - 1), (y0 + dy).clamp(0, h - 1));
        let ok = (tx, ty) == (nx, ny)
            || match filter {
                Filter::Adaptive(t) => t.connected(nx, ny, tx - nx, ty - ny),
                _ => true,
            };
        if ok && wt > 0.0 {
            let c = color.get(tx as u32, ty as u32);
            for i in 0..3 {
                acc[i] += wt * c[i];
            }
            wsum += wt;
        }
    }
    if wsum <= 0.0 {
        return *color.get(nx as u32, ny as u32);
    }
    acc.map(|a| a / wsum)
}

/// One target row of [`resolve`]: the rasterised depth and texture coordinates in, the
/// outputs to fill.
struct ResolveRow<'a> {
    color: &'a mut [[f32; 3]],
    depth: &'a mut [f32],
    hole: &'a mut [bool],
    zbuf: &'a [f32],
    uv: &'a [Vec2],
}

/// [`resolve`] of one row: the colour fetch and the reprojected depth of every covered pixel,
/// black, far and a hole elsewhere.
#[inline(always)]
fn resolve_row(src: &Source<'_>, m: &WarpMatrix, filter: Filter<'_>, row: ResolveRow<'_>) {
    resolve_row_from(src, m, filter, row, 0)
}

/// [`resolve_row`] from column `from` on.
#[inline(always)]
fn resolve_row_from(src: &Source<'_>, m: &WarpMatrix, filter: Filter<'_>, row: ResolveRow<'_>, from: usize) {
    let (sw, sh) = src.depth.size();
    for i in from..row.zbuf.len() {
        let z = row.zbuf[i];
        row.hole[i] = !z.is_finite();
        if row.hole[i] {
            (row.color[i], row.depth[i]) = ([0.0; 3], 1.0);
            continue;
        }
        let q = row.uv[i];
        let (nx, ny) = (
            (zwarp_core::round::floor(q.x) as i32).clamp(0, sw as i32 - 1) as u32,
            (zwarp_core::round::floor(q.y) as i32).clamp(0, sh as i32 - 1) as u32,
        );
        row.depth[i] = match m.project(nx as f32 + 0.5, ny as f32 + 0.5, *src.depth.get(nx, ny)) {
            Some((_, _, z)) if z.is_finite() => z.clamp(0.0, 1.0),
            _ => z.clamp(0.0, 1.0),
        };
        row.color[i] = sample(src.color, q, filter);
    }
}

/// [`resolve_row`] built for AVX2 (chosen at run time): with the bilinear fetch eight pixels at
/// a time (the same operations in the same order: the projection as glam's column sums, the
/// taps' weights, a tap of weight 0 adding `+0`), the rest of the row and the other filters
/// per pixel with the rounding of `floor` as an instruction.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn resolve_row_avx2(src: &Source<'_>, m: &WarpMatrix, filter: Filter<'_>, row: ResolveRow<'_>) {
    use std::arch::x86_64::*;
    if !matches!(filter, Filter::Bilinear) {
        return resolve_row(src, m, filter, row);
    }
    let (sw, sh) = src.depth.size();
    let n8 = row.zbuf.len() & !7;
    let s = |v: f32| _mm256_set1_ps(v);
    let mc = m.0.to_cols_array();
    let (wm, hm) = (_mm256_set1_epi32(sw as i32 - 1), _mm256_set1_epi32(sh as i32 - 1));
    let zi = _mm256_setzero_si256();
    let clampi = |v: __m256i, hi: __m256i| _mm256_min_epi32(_mm256_max_epi32(v, zi), hi);
    let absmask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fff_ffff));
    let wv = _mm256_set1_epi32(sw as i32);
    let depth = src.depth.data().as_ptr();
    let color = src.color.data().as_ptr() as *const f32;
    for i in (0..n8).step_by(8) {
        let z = _mm256_loadu_ps(row.zbuf.as_ptr().add(i));
        let finite = _mm256_cmp_ps::<_CMP_LT_OQ>(_mm256_and_ps(z, absmask), s(f32::INFINITY));
        let fm = _mm256_movemask_ps(finite);
        for j in 0..8 {
            row.hole[i + j] = fm >> j & 1 == 0;
        }
        if fm == 0 {
            for j in 0..8 {
                (row.color[i + j], row.depth[i + j]) = ([0.0; 3], 1.0);
            }
            continue;
        }
        // The eight texture coordinates, de-interleaved.
        let uvp = row.uv.as_ptr().add(i) as *const f32;
        let (a, b) = (_mm256_loadu_ps(uvp), _mm256_loadu_ps(uvp.add(8)));
        let gather = |v: __m256| _mm256_castpd_ps(_mm256_permute4x64_pd::<0b11_01_10_00>(_mm256_castps_pd(v)));
        let qx = gather(_mm256_shuffle_ps::<0b10_00_10_00>(a, b));
        let qy = gather(_mm256_shuffle_ps::<0b11_01_11_01>(a, b));
        // Nearest texel and its reprojected depth (`WarpMatrix::project`'s z / w).
        let nx = clampi(_mm256_cvttps_epi32(_mm256_floor_ps(qx)), wm);
        let ny = clampi(_mm256_cvttps_epi32(_mm256_floor_ps(qy)), hm);
        let ni = _mm256_add_epi32(_mm256_mullo_epi32(ny, wv), nx);
        let d = _mm256_mask_i32gather_ps::<4>(s(0.0), depth, ni, finite);
        let (px, py) = (_mm256_add_ps(_mm256_cvtepi32_ps(nx), s(0.5)), _mm256_add_ps(_mm256_cvtepi32_ps(ny), s(0.5)));
        let comp = |r: usize| {
            let t = _mm256_add_ps(_mm256_mul_ps(s(mc[r]), px), _mm256_mul_ps(s(mc[4 + r]), py));
            let t = _mm256_add_ps(t, _mm256_mul_ps(s(mc[8 + r]), d));
            _mm256_add_ps(t, _mm256_mul_ps(s(mc[12 + r]), s(1.0)))
        };
        let (hz, hw) = (comp(2), comp(3));
        let pz = _mm256_div_ps(hz, hw);
        let ok = _mm256_and_ps(
            _mm256_cmp_ps::<_CMP_GT_OQ>(hw, s(1e-9)),
            _mm256_cmp_ps::<_CMP_LT_OQ>(_mm256_and_ps(pz, absmask), s(f32::INFINITY)),
        );
        let dz = clamp8(_mm256_blendv_ps(z, pz, ok), s(0.0), s(1.0));
        // The bilinear fetch (`sample`): four taps, weights of at most 0 add nothing.
        let (fx, fy) = (_mm256_sub_ps(qx, s(0.5)), _mm256_sub_ps(qy, s(0.5)));
        let (x0, y0) = (_mm256_cvttps_epi32(_mm256_floor_ps(fx)), _mm256_cvttps_epi32(_mm256_floor_ps(fy)));
        let (ax, ay) = (_mm256_sub_ps(fx, _mm256_cvtepi32_ps(x0)), _mm256_sub_ps(fy, _mm256_cvtepi32_ps(y0)));
        let (bx, by) = (_mm256_sub_ps(s(1.0), ax), _mm256_sub_ps(s(1.0), ay));
        let one = _mm256_set1_epi32(1);
        let (x1, y1) = (clampi(_mm256_add_epi32(x0, one), wm), clampi(_mm256_add_epi32(y0, one), hm));
        let (x0, y0) = (clampi(x0, wm), clampi(y0, hm));
        let taps = [
            (x0, y0, _mm256_mul_ps(bx, by)),
            (x1, y0, _mm256_mul_ps(ax, by)),
            (x0, y1, _mm256_mul_ps(bx, ay)),
            (x1, y1, _mm256_mul_ps(ax, ay)),
        ];
        let mut acc = [s(0.0); 3];
        let mut wsum = s(0.0);
        for (tx, ty, wt) in taps {
            let wt = _mm256_and_ps(wt, _mm256_cmp_ps::<_CMP_GT_OQ>(wt, s(0.0)));
            let t3 = _mm256_mullo_epi32(_mm256_add_epi32(_mm256_mullo_epi32(ty, wv), tx), _mm256_set1_epi32(3));
            for (ch, a) in acc.iter_mut().enumerate() {
                let c = _mm256_mask_i32gather_ps::<4>(s(0.0), color.add(ch), t3, finite);
                *a = _mm256_add_ps(*a, _mm256_mul_ps(wt, c));
            }
            wsum = _mm256_add_ps(wsum, wt);
        }
        let rgb = acc.map(|a| _mm256_div_ps(a, wsum));
        let (mut r, mut g, mut bl, mut dd, mut ws) = ([0f32; 8], [0f32; 8], [0f32; 8], [0f32; 8], [0f32; 8]);
        _mm256_storeu_ps(r.as_mut_ptr(), rgb[0]);
        _mm256_storeu_ps(g.as_mut_ptr(), rgb[1]);
        _mm256_storeu_ps(bl.as_mut_ptr(), rgb[2]);
        _mm256_storeu_ps(dd.as_mut_ptr(), dz);
        _mm256_storeu_ps(ws.as_mut_ptr(), wsum);
        for j in 0..8 {
            let k = i + j;
            if fm >> j & 1 == 0 {
                (row.color[k], row.depth[k]) = ([0.0; 3], 1.0);
                continue;
            }
            row.depth[k] = dd[j];
            // No tap of positive weight: the nearest texel, as `sample` falls back.
            row.color[k] = if ws[j] <= 0.0 { sample(src.color, row.uv[k], filter) } else { [r[j], g[j], bl[j]] };
        }
    }
    resolve_row_from(src, m, filter, row, n8)
}

/// Colour fetch and output buffers. The depth of a covered pixel is its source texel
/// reprojected by `m` (the surface's own depth, not the cell's interpolation, which is flat
/// across a rigid cell), clamped to `[0, 1]`.
fn resolve(
    src: &Source<'_>,
    m: &WarpMatrix,
    tw: u32,
    th: u32,
    zbuf: &[f32],
    uv: &[Vec2],
    filter: Filter<'_>,
) -> WarpOutput {
    let n = (tw * th) as usize;
    let mut color = vec![[0.0f32; 3]; n];
    let mut depth = vec![0.0f32; n];
    let mut hole = vec![false; n];
    let t = tw as usize;
    color
        .par_chunks_mut(t)
        .zip(depth.par_chunks_mut(t))
        .zip(hole.par_chunks_mut(t))
        .zip(zbuf.par_chunks(t).zip(uv.par_chunks(t)))
        .for_each(|(((c, d), hl), (z, q))| {
            let row = ResolveRow { color: c, depth: d, hole: hl, zbuf: z, uv: q };
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: only taken when the CPU reports AVX2.
                return unsafe { resolve_row_avx2(src, m, filter, row) };
            }
            resolve_row(src, m, filter, row)
        });
    WarpOutput {
        color: Image::from_vec(tw, th, color).expect("sized"),
        depth: Image::from_vec(tw, th, depth).expect("sized"),
        hole: Image::from_vec(tw, th, hole).expect("sized"),
        primitives: 0,
        cells: Vec::new(),
        ms: StageMs::default(),
    }
}

/// One splat per pixel: each source pixel centre is warped and written to the target pixel it
/// lands in, with a depth test (nearest colour).
fn points(src: &Source<'_>, dst: &Camera, m: &WarpMatrix) -> Result<WarpOutput> {
    let (w, h) = src.depth.size();
    let (tw, th) = (dst.width, dst.height);
    let n = (tw * th) as usize;
    // Pack depth and source index into one u64 so a parallel atomic min keeps the nearest.
    let buf: Vec<std::sync::atomic::AtomicU64> = (0..n).map(|_| std::sync::atomic::AtomicU64::new(u64::MAX)).collect();
    (0..h).into_par_iter().for_each(|y| {
        for x in 0..w {
            let d = *src.depth.get(x, y);
            let Some((tx, ty, tz)) = m.project(x as f32 + 0.5, y as f32 + 0.5, d) else { continue };
            if !(tx >= 0.0 && ty >= 0.0 && tx < tw as f32 && ty < th as f32 && tz.is_finite()) {
                continue;
            }
            let k = ty as usize * tw as usize + tx as usize;
            // Positive f32 bit patterns order like the values; negative depths clamp to 0.
            let key = ((tz.max(0.0).to_bits() as u64) << 32) | (y * w + x) as u64;
            buf[k].fetch_min(key, std::sync::atomic::Ordering::Relaxed);
        }
    });
    let mut zbuf = vec![f32::INFINITY; n];
    let mut uv = vec![Vec2::ZERO; n];
    for (i, a) in buf.iter().enumerate() {
        let v = a.load(std::sync::atomic::Ordering::Relaxed);
        if v != u64::MAX {
            zbuf[i] = f32::from_bits((v >> 32) as u32);
            let s = (v & 0xFFFF_FFFF) as u32;
            uv[i] = Vec2::new((s % w) as f32 + 0.5, (s / w) as f32 + 0.5);
        }
    }
    let mut out = resolve(src, m, tw, th, &zbuf, &uv, Filter::Nearest);
    out.primitives = (w * h) as usize;
    Ok(out)
}

/// Per level (0 = pixels .. [`LEVELS`] = tiles): size and `[min x, max x, min y, max y]` of the
/// per-pixel disparity (target minus source position) below each node. Level 0 holds its size
/// only: a pixel's range is a point (or empty behind the target eye), which no split criterion
/// reads (a one-pixel node is never split).
pub type DisparityPyramid = Vec<(u32, u32, Vec<[f32; 4]>)>;

/// The disparity min-max pyramid of the warp `m` (Didyk et al.'s split criterion): level 1 folded
/// straight from each pair of rows of per-pixel disparities (`disparity_row`), the coarser
/// levels from it.
pub fn disparity_pyramid(src: &Source<'_>, m: &WarpMatrix) -> DisparityPyramid {
    let (w, h) = src.depth.size();
    let (wu, hu) = (w as usize, h as usize);
    let empty = [f32::INFINITY, f32::NEG_INFINITY, f32::INFINITY, f32::NEG_INFINITY];
    // Each texel folds its children row by row, left to right.
    let fold = |row: &mut [[f32; 4]], children: &[[f32; 4]]| {
        for (x, s) in children.iter().enumerate() {
            let t = &mut row[x / 2];
            t[0] = t[0].min(s[0]);
            t[1] = t[1].max(s[1]);
            t[2] = t[2].min(s[2]);
            t[3] = t[3].max(s[3]);
        }
    };
    let mut lv: DisparityPyramid = vec![(w, h, Vec::new())];
    let (nw, nh) = (wu.div_ceil(2), hu.div_ceil(2));
    let mut level1 = vec![empty; nw * nh];
    level1.par_chunks_mut(nw).enumerate().for_each_init(
        || vec![[0.0f32; 4]; wu],
        |px, (ny, row)| {
            for y in (2 * ny)..(2 * ny + 2).min(hu) {
                disparity_row(m, y, &src.depth.data()[y * wu..(y + 1) * wu], px);
                fold(row, px);
            }
        },
    );
    lv.push((nw as u32, nh as u32, level1));
    for _ in 1..LEVELS {
        let (pw, ph, prev) = lv.last().expect("level 1");
        let (pw, ph) = (*pw as usize, *ph as usize);
        let (nw, nh) = (pw.div_ceil(2), ph.div_ceil(2));
        let mut next = vec![empty; nw * nh];
        next.par_chunks_mut(nw).enumerate().for_each(|(ny, row)| {
            for y in (2 * ny)..(2 * ny + 2).min(ph) {
                fold(row, &prev[y * pw..(y + 1) * pw]);
            }
        });
        lv.push((nw as u32, nh as u32, next));
    }
    lv
}

/// Level 0 of [`disparity_pyramid`] for row `y` (depths `drow`): per pixel `[dx, dx, dy, dy]`,
/// its centre projected by `m` minus the centre, or the empty range `[-inf, inf, -inf, inf]`
/// behind the target eye; eight pixels at a time with AVX2 (bit-identical), the rest here.
fn disparity_row(m: &WarpMatrix, y: usize, drow: &[f32], row: &mut [[f32; 4]]) {
    let mut x0 = 0;
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: only taken when the CPU reports AVX2.
        x0 = unsafe { disparity_row_avx2(m, y, drow, row) };
    }
    disparity_row_from(m, y, drow, row, x0);
}

/// The portable [`disparity_row`] of pixels `from..`.
fn disparity_row_from(m: &WarpMatrix, y: usize, drow: &[f32], row: &mut [[f32; 4]], from: usize) {
    let y = y as f32 + 0.5;
    for (x, (o, &d)) in row.iter_mut().zip(drow).enumerate().skip(from) {
        let x = x as f32 + 0.5;
        *o = match m.project(x, y, d) {
            Some((tx, ty, _)) => [tx - x, tx - x, ty - y, ty - y],
            None => [f32::NEG_INFINITY, f32::INFINITY, f32::NEG_INFINITY, f32::INFINITY],
        };
    }
}

/// The AVX2 build of [`disparity_row`] for the pixels `0..8 floor(len / 8)`; returns how many it
/// wrote. `WarpMatrix::project` operation for operation: glam's `Mat4 * Vec4` (columns scaled
/// and summed in order, no FMA), `h.w > 1e-9`, the divisions by `h.w`.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn disparity_row_avx2(m: &WarpMatrix, y: usize, drow: &[f32], row: &mut [[f32; 4]]) -> usize {
    use std::arch::x86_64::*;
    let n8 = row.len().min(drow.len()) / 8 * 8;
    let (half, one) = (_mm256_set1_ps(0.5), _mm256_set1_ps(1.0));
    let py = _mm256_set1_ps(y as f32 + 0.5);
    let lane = _mm256_setr_ps(0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0);
    let eps = _mm256_set1_ps(1e-9);
    let (mut dx, mut dy, mut ok) = ([0.0f32; 8], [0.0f32; 8], [0.0f32; 8]);
    for x in (0..n8).step_by(8) {
        // `x as f32 + 0.5` per pixel: the integer column is exact, so adding the lane first is too.
        let px = _mm256_add_ps(_mm256_add_ps(_mm256_set1_ps(x as f32), lane), half);
        let d = _mm256_loadu_ps(drow.as_ptr().add(x));
        let hc = zwarp_core::simd::avx2::mat4_mul8(&m.0, [px, py, d, one]);
        let valid = _mm256_cmp_ps::<_CMP_GT_OQ>(hc[3], eps);
        _mm256_storeu_ps(dx.as_mut_ptr(), _mm256_sub_ps(_mm256_div_ps(hc[0], hc[3]), px));
        _mm256_storeu_ps(dy.as_mut_ptr(), _mm256_sub_ps(_mm256_div_ps(hc[1], hc[3]), py));
        _mm256_storeu_ps(ok.as_mut_ptr(), valid);
        for k in 0..8 {
            row[x + k] = if ok[k].to_bits() != 0 {
                [dx[k], dx[k], dy[k], dy[k]]
            } else {
                [f32::NEG_INFINITY, f32::INFINITY, f32::NEG_INFINITY, f32::INFINITY]
            };
        }
    }
    n8
}

/// Didyk et al. 2010's adaptive grid: a quadtree over 32x32 tiles split while the range of the
/// per-pixel disparity (target minus source position, both axes) within a node exceeds
/// `threshold` pixels.
pub fn didyk_cells(src: &Source<'_>, m: &WarpMatrix, threshold: f32) -> Result<Vec<Cell>> {
    if !(threshold.is_finite() && threshold >= 0.0) {
        return Err(Error::invalid(format!("didyk threshold must be >= 0 pixels, got {threshold}")));
    }
    let (w, h) = src.depth.size();
    let lv = disparity_pyramid(src, m);
    let mut out = Vec::new();
    #[allow(clippy::too_many_arguments)]
    fn emit(lv: &DisparityPyramid, level: usize, x: u32, y: u32, thr: f32, w: u32, h: u32, out: &mut Vec<Cell>) {
        let s = 1u32 << level;
        let c = Cell { x0: x * s, y0: y * s, x1: ((x + 1) * s).min(w), y1: ((y + 1) * s).min(h) };
        if c.x0 >= c.x1 || c.y0 >= c.y1 {
            return;
        }
        if level == 0 {
            out.push(c);
            return;
        }
        let (lw, _, v) = &lv[level];
        let r = v[(y * lw + x) as usize];
        if r[1] - r[0] <= thr && r[3] - r[2] <= thr {
            out.push(c);
            return;
        }
        for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            emit(lv, level - 1, 2 * x + dx, 2 * y + dy, thr, w, h, out);
        }
    }
    let (tw, th, _) = &lv[LEVELS];
    for ty in 0..*th {
        for tx in 0..*tw {
            emit(&lv, LEVELS, tx, ty, threshold, w, h, &mut out);
        }
    }
    Ok(out)
}

/// The inputs of `fpi`, zwarp's fixed-point colour warp (seed 001 heuristic, 3 iterations,
/// orbit in-painting): the camera-only warp basis from `src` to `dst` (take its field at
/// `FieldParams::temporal(1.0)`) and the heuristic's parameters, seeded with the fixed offset of
/// Sec. 3.3 ([`zwarp_color::fixed_offset`]).
pub fn fpi_setup(src: &Source<'_>, dst: &Camera) -> Result<(WarpBasis, HeuristicParams)> {
    if (dst.width, dst.height) != src.depth.size() {
        return Err(Error::invalid("fpi warp: source and target must have the same size"));
    }
    let motion = zwarp_core::motion_field(src.depth, None, src.cam, dst, &[])?;
    let basis = WarpBasis::temporal(src.depth, &motion)?;
    let offset = zwarp_color::fixed_offset(&basis.field(zwarp_color::FieldParams::temporal(1.0))?);
    Ok((basis, HeuristicParams { seed: Seed::Offset(offset), ..HeuristicParams::default() }))
}

impl WarpOutput {
    /// The output of a warp that fills its own disocclusions (fpi): no hole, no primitive.
    pub fn filled(color: Image<[f32; 3]>, depth: Image<f32>) -> Self {
        let (w, h) = color.size();
        WarpOutput {
            color,
            depth,
            hole: Image::new(w, h, false),
            primitives: 0,
            cells: Vec::new(),
            ms: StageMs::default(),
        }
    }
}

/// The fpi warp on the CPU ([`fpi_setup`]). It fills disocclusions itself, so its hole mask is
/// empty.
fn fpi(src: &Source<'_>, dst: &Camera) -> Result<WarpOutput> {
    let (basis, hp) = fpi_setup(src, dst)?;
    let o = zwarp_color::heuristic_warp(&basis.field(zwarp_color::FieldParams::temporal(1.0))?, src.color, &hp)?;
    Ok(WarpOutput::filled(o.color, o.depth))
}

/// The grid drawn over an image (seed 003 Fig. 12-13 style): cell outlines in `line` over
/// `color` (both in the source's pixels).
pub fn draw_cells(color: &Image<[f32; 3]>, cells: &[Cell], line: [f32; 3]) -> Image<[f32; 3]> {
    let mut out = color.clone();
    let (w, h) = color.size();
    for c in cells {
        for x in c.x0..c.x1.min(w) {
            *out.get_mut(x, c.y0) = line;
        }
        for y in c.y0..c.y1.min(h) {
            *out.get_mut(c.x0, y) = line;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    /// Seeded numbers in `[0, 1]` (xorshift32).
    fn xorshift(mut s: u32) -> impl FnMut() -> f32 {
        move || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s as f32 / u32::MAX as f32
        }
    }

    #[test]
    #[cfg(target_arch = "x86_64")]
    fn the_avx2_disparity_is_the_scalar_disparity() {
        let (w, h) = (45u32, 7u32);
        let a = Camera::perspective(Vec3::new(0.0, 0.5, 6.0), Vec3::ZERO, Vec3::Y, 1.0, 0.1, 50.0, w, h).unwrap();
        // Its eye 3.5 m ahead of a's: the nearest points are behind it.
        let b = Camera::perspective(Vec3::new(0.3, 0.6, 2.5), Vec3::X * 0.2, Vec3::Y, 1.1, 0.1, 50.0, w, h).unwrap();
        let m = WarpMatrix::new(&a, &b).unwrap();
        let mut next = xorshift(7);
        for y in 0..h as usize {
            let drow: Vec<f32> = (0..w).map(|x| if x % 9 == 4 { 1.0 } else { next() }).collect();
            let (mut simd, mut scalar) = (vec![[0.0f32; 4]; w as usize], vec![[0.0f32; 4]; w as usize]);
            disparity_row(&m, y, &drow, &mut simd);
            disparity_row_from(&m, y, &drow, &mut scalar, 0);
            let bits = |r: &[[f32; 4]]| r.iter().flat_map(|v| v.map(f32::to_bits)).collect::<Vec<_>>();
            assert_eq!(bits(&simd), bits(&scalar), "row {y}");
            assert!(y > 0 || scalar.iter().any(|v| v[0] == f32::NEG_INFINITY), "no point behind the target eye");
        }
    }

    #[test]
    fn the_avx2_span_is_the_scalar_span() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        // Seeded triangles of every size and orientation (slivers, both windings, partly off
        // the target), rasterised over rows that already hold depths: same depths and texture
        // coordinates, bit for bit.
        let (tw, th) = (53u32, 29u32);
        let mut rnd = xorshift(0x9e37_79b9);
        let mut drawn = 0;
        for n in 0..400 {
            let span = if n % 3 == 0 { 4.0 } else { 40.0 };
            let v: [(Vec4, Vec2); 3] = std::array::from_fn(|_| {
                let w = 0.5 + rnd();
                let (x, y) = (-5.0 + rnd() * (tw as f32 + 10.0), -5.0 + rnd() * span);
                (Vec4::new(x * w, y * w, rnd() * w, w), Vec2::new(rnd() * 9.0, rnd() * 9.0))
            });
            let Some(t) = make_tri(v, [1.0, 2.0, 6.0, 7.0], tw, th) else { continue };
            for y in t.bb[1]..=t.bb[3] {
                let z0: Vec<f32> = (0..tw).map(|_| if rnd() < 0.3 { f32::INFINITY } else { rnd() }).collect();
                let (mut za, mut zb) = (z0.clone(), z0);
                let (mut ua, mut ub) = (vec![Vec2::splat(-1.0); tw as usize], vec![Vec2::splat(-1.0); tw as usize]);
                raster_span(&t, y, &mut za, &mut ua);
                // SAFETY: checked above.
                unsafe { raster_span_avx2(&t, y, &mut zb, &mut ub) };
                assert_eq!(
                    za.iter().map(|z| z.to_bits()).collect::<Vec<_>>(),
                    zb.iter().map(|z| z.to_bits()).collect::<Vec<_>>()
                );
                assert_eq!(ua, ub, "triangle {n} row {y}");
                drawn += ua.iter().filter(|u| u.x >= 0.0).count();
            }
        }
        assert!(drawn > 1000, "{drawn} pixels drawn");
    }

    #[test]
    #[cfg(target_arch = "x86_64")]
    fn the_avx2_resolve_is_the_scalar_resolve() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        // Seeded rows of covered pixels, holes (inf, NaN) and texture coordinates across the
        // whole source (borders included), with a depth buffer holding near, far and empty
        // texels: colour, depth and hole flags equal bit for bit (the bilinear fetch, the one the
        // eight lanes serve).
        let (w, h) = (37u32, 11u32);
        let mut rnd = xorshift(0x2545_f491);
        let depth = Image::from_fn(w, h, |x, y| [0.3, 0.97, 1.0, 0.999][((x * 7 + y * 3) % 4) as usize]);
        let color = Image::from_fn(w, h, |x, y| [x as f32 / w as f32, y as f32 / h as f32, ((x ^ y) % 5) as f32 / 4.0]);
        let cam = Camera::perspective(Vec3::ZERO, Vec3::Y, Vec3::Z, 1.0, 0.1, 100.0, w, h).unwrap();
        let dst = Camera::perspective(Vec3::new(0.4, 0.1, 0.0), Vec3::Y, Vec3::Z, 1.0, 0.1, 100.0, w, h).unwrap();
        let src = Source { cam: &cam, depth: &depth, color: &color };
        let m = WarpMatrix::new(&cam, &dst).unwrap();
        for rep in 0..40 {
            let n = 3 + rep % 29;
            let zbuf: Vec<f32> = (0..n)
                .map(|_| match rnd() {
                    r if r < 0.15 => f32::INFINITY,
                    r if r < 0.2 => f32::NAN,
                    r => r,
                })
                .collect();
            let uv: Vec<Vec2> = (0..n)
                .map(|_| match rnd() {
                    r if r < 0.1 => Vec2::new(1e-3, h as f32 - 1e-3),
                    r if r < 0.2 => Vec2::new(w as f32 - 1e-3, 1e-3),
                    _ => Vec2::new(rnd() * w as f32, rnd() * h as f32),
                })
                .collect();
            let run = |simd: bool| {
                let (mut c, mut d, mut hl) = (vec![[9.0f32; 3]; n], vec![9.0f32; n], vec![false; n]);
                let row = ResolveRow { color: &mut c, depth: &mut d, hole: &mut hl, zbuf: &zbuf, uv: &uv };
                if simd {
                    // SAFETY: checked above.
                    unsafe { resolve_row_avx2(&src, &m, Filter::Bilinear, row) };
                } else {
                    resolve_row(&src, &m, Filter::Bilinear, row);
                }
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                (c.iter().flat_map(|p| bits(p)).collect::<Vec<_>>(), bits(&d), hl)
            };
            assert_eq!(run(true), run(false), "row {rep}");
        }
    }
}
