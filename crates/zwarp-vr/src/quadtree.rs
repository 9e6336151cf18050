//! The surface-estimation quadtree of seed 003 Sec. 4.1: per 32x32 tile, built bottom-up from
//! the source depth, each node stores whether the pixels below it form one connected, nearly
//! flat surface, its connectedness to its 8 neighbours (Sec. 4.1.2), the merge type of the
//! irregular grid (Sec. 4.1.3, Fig. 6) and the accumulated estimation error.
//!
//! The collinearity test (eq. 1-2) runs on stored depth: post-projection depth is affine in
//! screen space on a plane, so three pixels of one plane are exactly collinear in it. Stored
//! depth is compressed towards the far plane, so the tolerance of eq. 2 is relative to the
//! local depth differences (plus a floor for the rasteriser's rounding): one threshold then
//! means the same curvature near and far.

use rayon::prelude::*;
use zwarp_core::{Error, Image, Result};

/// Tile size of the quadtree roots (seed 003 Sec. 4.1: "e.g. 32x32 pixel").
pub const TILE: u32 = 32;
/// Levels above the pixels: `2^LEVELS = TILE`.
pub const LEVELS: usize = 5;

/// The 8 neighbour directions `(dx, dy)` of the connectivity bits (Sec. 4.1.2), bit `i` of a
/// mask is direction `DIRS[i]`: right, left, down, up, down-right, down-left, up-right, up-left
/// (y grows downwards, row 0 on top).
pub const DIRS: [(i32, i32); 8] = [(1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (-1, 1), (1, -1), (-1, -1)];
/// Bit of the right neighbour.
pub const RIGHT: u8 = 1 << 0;
/// Bit of the left neighbour.
pub const LEFT: u8 = 1 << 1;
/// Bit of the neighbour below.
pub const DOWN: u8 = 1 << 2;
/// Bit of the neighbour above.
pub const UP: u8 = 1 << 3;
/// Bit of the down-right neighbour.
pub const DOWN_RIGHT: u8 = 1 << 4;
/// Bit of the down-left neighbour.
pub const DOWN_LEFT: u8 = 1 << 5;
/// Bit of the up-right neighbour.
pub const UP_RIGHT: u8 = 1 << 6;
/// Bit of the up-left neighbour.
pub const UP_LEFT: u8 = 1 << 7;
/// All 8 connectivity bits.
pub const ALL: u8 = 0xFF;

/// The bit of direction `(dx, dy)` (each in `-1..=1`, not both 0).
pub fn dir_bit(dx: i32, dy: i32) -> u8 {
    let i = DIRS.iter().position(|&d| d == (dx, dy)).expect("a neighbour direction");
    1 << i
}

/// The epsilon-tolerant collinearity test of seed 003 eq. 1-2.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Collinearity {
    /// Relative tolerance: three depths are collinear iff eq. 1's `f` is below
    /// `epsilon * (|d_{i-1} - d_i| + |d_i - d_{i+1}|) + floor`. A step next to a plane gives
    /// `f` equal to the step (ratio ~1); a plane gives 0; gentle curvature a small ratio.
    pub epsilon: f32,
    /// Absolute floor of the tolerance (stored-depth units): the rounding of rendered depth.
    pub floor: f32,
}

impl Default for Collinearity {
    fn default() -> Self {
        Collinearity { epsilon: 0.2, floor: 1.0e-6 }
    }
}

impl Collinearity {
    /// Errors unless both tolerances are finite and non-negative and `epsilon < 1` (at 1 a step
    /// next to a plane would pass).
    pub fn check(&self) -> Result<()> {
        if !(self.epsilon.is_finite() && (0.0..1.0).contains(&self.epsilon)) {
            return Err(Error::invalid(format!("collinearity epsilon must be in [0, 1), got {}", self.epsilon)));
        }
        if !(self.floor.is_finite() && self.floor >= 0.0) {
            return Err(Error::invalid(format!("collinearity floor must be >= 0, got {}", self.floor)));
        }
        Ok(())
    }

    /// Eq. 1: `|(d_{i-1} - d_i) - (d_i - d_{i+1})|`, the change of differences.
    #[inline]
    pub fn deviation(a: f32, b: f32, c: f32) -> f32 {
        ((a - b) - (b - c)).abs()
    }

    /// Eq. 2: `true` iff the three depths are collinear within the tolerance.
    #[inline]
    pub fn test(&self, a: f32, b: f32, c: f32) -> bool {
        Self::deviation(a, b, c) <= self.epsilon * ((a - b).abs() + (b - c).abs()) + self.floor
    }
}

/// The reduction that builds the quadtree (seed 003 Sec. 4.1.1-4.1.3, Fig. 4-6).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reduction {
    /// Sec. 4.1.1: a pixel is a surface iff its horizontal and vertical centred tests pass; a
    /// node iff all its children are (over-tessellates along edges, Fig. 4b).
    Cross,
    /// Sec. 4.1.2: connectivity bits per node; a node is a surface iff its children are and
    /// they are connected to each other (Fig. 4c).
    PartialCross,
    /// Sec. 4.1.3: the partial cross kernel plus 2:1 rectangles by merge type (Fig. 4d, 6).
    Irregular,
}

impl Reduction {
    /// CLI / JSON name.
    pub fn name(self) -> &'static str {
        match self {
            Reduction::Cross => "cross",
            Reduction::PartialCross => "partial",
            Reduction::Irregular => "irregular",
        }
    }
}

/// How the four children of a node merge (seed 003 Fig. 6: 8 types, 3 bits).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Merge {
    /// No two children merge.
    None,
    /// Top-left and top-right form one 2:1 cell.
    Top,
    /// Bottom-left and bottom-right form one 2:1 cell.
    Bottom,
    /// Both horizontal pairs.
    TopBottom,
    /// Top-left and bottom-left form one 1:2 cell.
    Left,
    /// Top-right and bottom-right form one 1:2 cell.
    Right,
    /// Both vertical pairs.
    LeftRight,
    /// All four: the node is one square cell.
    Full,
}

impl Merge {
    /// The merged pairs as child-index pairs (children 0 TL, 1 TR, 2 BL, 3 BR).
    pub fn pairs(self) -> &'static [(usize, usize)] {
        match self {
            Merge::None | Merge::Full => &[],
            Merge::Top => &[(0, 1)],
            Merge::Bottom => &[(2, 3)],
            Merge::TopBottom => &[(0, 1), (2, 3)],
            Merge::Left => &[(0, 2)],
            Merge::Right => &[(1, 3)],
            Merge::LeftRight => &[(0, 2), (1, 3)],
        }
    }
}

/// One quadtree node (seed 003 Sec. 4.1.2: connectedness, flatness and merge type).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Node {
    /// The 8 connectivity bits ([`DIRS`]): set iff every pixel pair across that side (corner)
    /// of the node is collinear; links leaving the image count as connected.
    pub links: u8,
    /// The node's pixels form one connected surface.
    pub surface: bool,
    /// The irregular grid's merge type ([`Merge::Full`] iff `surface`).
    pub merge: Merge,
    /// Accumulated estimation error: the largest eq. 1 deviation (stored depth) among the
    /// passing tests below the node.
    pub err: f32,
}

/// Stands in for children outside the image: neutral for every reduction.
const ABSENT: Node = Node { links: ALL, surface: true, merge: Merge::Full, err: 0.0 };

/// One level of the pyramid (level 0 = pixels, level [`LEVELS`] = tiles).
#[derive(Clone, Debug)]
pub struct Level {
    /// Nodes per row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Row-major nodes.
    pub nodes: Vec<Node>,
}

impl Level {
    /// Node `(x, y)`; outside the level a neutral node (all links, a surface, fully merged, no error).
    #[inline]
    pub fn get(&self, x: u32, y: u32) -> Node {
        if x < self.width && y < self.height {
            self.nodes[(y * self.width + x) as usize]
        } else {
            ABSENT
        }
    }
}

/// The surface-estimation quadtrees of all tiles of one source depth buffer, stored as a
/// pyramid (seed 003 Sec. 4.1.4: "a mipmap pyramid for storing the surface-estimation
/// quadtrees").
#[derive(Clone, Debug)]
pub struct QuadTree {
    /// The reduction that built it.
    pub reduction: Reduction,
    /// Levels 0 (pixels) ..= [`LEVELS`] (32x32 tiles).
    pub levels: Vec<Level>,
}

/// Per-pixel tests of level 0: connectivity bits, the centred cross test, the error.
fn pixel_node(depth: &Image<f32>, x: u32, y: u32, c: &Collinearity, reduction: Reduction) -> Node {
    let (w, h) = (depth.width() as i32, depth.height() as i32);
    let at = |x: i32, y: i32| -> Option<f32> {
        (x >= 0 && y >= 0 && x < w && y < h).then(|| *depth.get(x as u32, y as u32))
    };
    let (xi, yi) = (x as i32, y as i32);
    let dp = *depth.get(x, y);
    let mut links = 0u8;
    let mut err = 0.0f32;
    for (i, &(dx, dy)) in DIRS.iter().enumerate() {
        let Some(dq) = at(xi + dx, yi + dy) else {
            links |= 1 << i;
            continue;
        };
        // Sec. 4.1.2: the pair is connected if it is collinear with at least one side. A side
        // off the image cannot contradict (a pixel pair at the border is judged from inside).
        let mut best = f32::INFINITY;
        let mut border = false;
        match at(xi - dx, yi - dy) {
            Some(da) => {
                if c.test(da, dp, dq) {
                    best = best.min(Collinearity::deviation(da, dp, dq));
                }
            }
            None => border = true,
        }
        match at(xi + 2 * dx, yi + 2 * dy) {
            Some(db) => {
                if c.test(dp, dq, db) {
                    best = best.min(Collinearity::deviation(dp, dq, db));
                }
            }
            None => border = true,
        }
        let connected = best.is_finite() || border;
        if connected {
            links |= 1 << i;
            if best.is_finite() {
                err = err.max(best);
            }
        }
    }
    let surface = match reduction {
        // Sec. 4.1.1: the horizontal and vertical tests centred on the pixel.
        Reduction::Cross => {
            let centred = |dx: i32, dy: i32| match (at(xi - dx, yi - dy), at(xi + dx, yi + dy)) {
                (Some(a), Some(b)) => c.test(a, dp, b),
                _ => true,
            };
            centred(1, 0) && centred(0, 1)
        }
        Reduction::PartialCross | Reduction::Irregular => true,
    };
    Node { links, surface, merge: if surface { Merge::Full } else { Merge::None }, err }
}

/// The connectivity bits and errors of [`pixel_node`] for the interior pixels `2..w - 2` of row
/// `y` (`2 <= y < h - 2`: every neighbour used exists) into `links` / `err` (`w - 4` each): the
/// same tests on direct slice reads, one direction at a time over the whole row, so the loop
/// vectorizes; every pixel sees the same operations in the same order, so the same bits.
#[inline(always)]
fn interior_row(d: &[f32], w: usize, y: usize, c: &Collinearity, links: &mut [u8], err: &mut [f32]) {
    let n = w - 4;
    let i0 = (y * w + 2) as isize;
    let (links, err) = (&mut links[..n], &mut err[..n]);
    links.fill(0);
    err.fill(0.0);
    for (k, &(dx, dy)) in DIRS.iter().enumerate() {
        let off = dy as isize * w as isize + dx as isize;
        let at = |o: isize| &d[(i0 + o) as usize..][..n];
        let (a, p, q, b) = (at(-off), at(0), at(off), at(2 * off));
        for (((((&da, &dp), &dq), &db), l), e) in
            a.iter().zip(p).zip(q).zip(b).zip(links.iter_mut()).zip(err.iter_mut())
        {
            let t1 = c.test(da, dp, dq);
            let t2 = c.test(dp, dq, db);
            let f1 = if t1 { Collinearity::deviation(da, dp, dq) } else { f32::INFINITY };
            let f2 = if t2 { Collinearity::deviation(dp, dq, db) } else { f32::INFINITY };
            let hit = t1 | t2;
            *l |= (hit as u8) << k;
            *e = if hit { e.max(f1.min(f2)) } else { *e };
        }
    }
}

/// [`interior_row`] built for AVX2 (chosen at run time; the same function, wider lanes).
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn interior_row_avx2(d: &[f32], w: usize, y: usize, c: &Collinearity, links: &mut [u8], err: &mut [f32]) {
    interior_row(d, w, y, c, links, err)
}

/// Level 0 of row `y` into `row`: [`interior_row`] for the interior pixels of interior rows,
/// [`pixel_node`] for the two-pixel frame of the image. `links` / `err` are scratch (`w` each).
fn level0_row(
    depth: &Image<f32>,
    y: usize,
    c: &Collinearity,
    reduction: Reduction,
    row: &mut [Node],
    scratch: &mut (Vec<u8>, Vec<f32>),
) {
    let (w, h) = (depth.width() as usize, depth.height() as usize);
    let interior = y >= 2 && y + 2 < h && w > 4;
    if !interior {
        for (x, n) in row.iter_mut().enumerate() {
            *n = pixel_node(depth, x as u32, y as u32, c, reduction);
        }
        return;
    }
    let d = depth.data();
    let (links, err) = scratch;
    links.resize(w, 0);
    err.resize(w, 0.0);
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: only taken when the CPU reports AVX2.
        unsafe { interior_row_avx2(d, w, y, c, links, err) };
    } else {
        interior_row(d, w, y, c, links, err);
    }
    #[cfg(not(target_arch = "x86_64"))]
    interior_row(d, w, y, c, links, err);
    for (x, n) in row.iter_mut().enumerate() {
        if x < 2 || x + 2 >= w {
            *n = pixel_node(depth, x as u32, y as u32, c, reduction);
            continue;
        }
        let i = y * w + x;
        let surface = match reduction {
            // Sec. 4.1.1: the horizontal and vertical tests centred on the pixel.
            Reduction::Cross => c.test(d[i - 1], d[i], d[i + 1]) && c.test(d[i - w], d[i], d[i + w]),
            Reduction::PartialCross | Reduction::Irregular => true,
        };
        let merge = if surface { Merge::Full } else { Merge::None };
        *n = Node { links: links[x - 2], surface, merge, err: err[x - 2] };
    }
}

/// The parent of four children (TL, TR, BL, BR) under `reduction`.
fn reduce(ch: [Node; 4], reduction: Reduction) -> Node {
    let [tl, tr, bl, br] = ch;
    let links = ((tr.links & br.links) & RIGHT)
        | ((tl.links & bl.links) & LEFT)
        | ((bl.links & br.links) & DOWN)
        | ((tl.links & tr.links) & UP)
        | (br.links & DOWN_RIGHT)
        | (bl.links & DOWN_LEFT)
        | (tr.links & UP_RIGHT)
        | (tl.links & UP_LEFT);
    let err = tl.err.max(tr.err).max(bl.err).max(br.err);
    let all = tl.surface && tr.surface && bl.surface && br.surface;
    let surface = match reduction {
        Reduction::Cross => all,
        // Sec. 4.1.2: children are surfaces and connected in the corresponding directions.
        Reduction::PartialCross | Reduction::Irregular => {
            all && tl.links & RIGHT != 0
                && bl.links & RIGHT != 0
                && tl.links & DOWN != 0
                && tr.links & DOWN != 0
                && tl.links & DOWN_RIGHT != 0
                && tr.links & DOWN_LEFT != 0
        }
    };
    let merge = if surface {
        Merge::Full
    } else if reduction == Reduction::Irregular {
        let top = tl.surface && tr.surface && tl.links & RIGHT != 0;
        let bottom = bl.surface && br.surface && bl.links & RIGHT != 0;
        let left = tl.surface && bl.surface && tl.links & DOWN != 0;
        let right = tr.surface && br.surface && tr.links & DOWN != 0;
        match (top, bottom, left, right) {
            (true, true, _, _) => Merge::TopBottom,
            (_, _, true, true) => Merge::LeftRight,
            (true, false, _, _) => Merge::Top,
            (false, true, _, _) => Merge::Bottom,
            (false, false, true, false) => Merge::Left,
            (false, false, false, true) => Merge::Right,
            _ => Merge::None,
        }
    } else {
        Merge::None
    };
    Node { links, surface, merge, err }
}

impl QuadTree {
    /// Builds the quadtrees of all 32x32 tiles of `depth` (any size; partial tiles at the right
    /// and bottom borders). Errors on an empty or non-finite depth buffer or a bad tolerance.
    pub fn build(depth: &Image<f32>, reduction: Reduction, c: &Collinearity) -> Result<Self> {
        depth.check_nonempty("quadtree depth")?;
        c.check()?;
        if !depth.all_finite() {
            return Err(Error::invalid("quadtree: depth buffer holds NaN or infinite values"));
        }
        let (w, h) = depth.size();
        let mut nodes = vec![ABSENT; (w * h) as usize];
        nodes.par_chunks_mut(w as usize).enumerate().for_each_init(
            || (Vec::new(), Vec::new()),
            |scratch, (y, row)| level0_row(depth, y, c, reduction, row, scratch),
        );
        let mut levels = vec![Level { width: w, height: h, nodes }];
        for _ in 0..LEVELS {
            let prev = levels.last().expect("level 0");
            let (pw, ph) = (prev.width.div_ceil(2), prev.height.div_ceil(2));
            let mut nodes = vec![ABSENT; (pw * ph) as usize];
            nodes.par_chunks_mut(pw as usize).enumerate().for_each(|(y, row)| {
                let y = y as u32;
                for (x, n) in row.iter_mut().enumerate() {
                    let x = x as u32;
                    let ch = [
                        prev.get(2 * x, 2 * y),
                        prev.get(2 * x + 1, 2 * y),
                        prev.get(2 * x, 2 * y + 1),
                        prev.get(2 * x + 1, 2 * y + 1),
                    ];
                    *n = reduce(ch, reduction);
                }
            });
            levels.push(Level { width: pw, height: ph, nodes });
        }
        Ok(QuadTree { reduction, levels })
    }

    /// Source image size.
    pub fn size(&self) -> (u32, u32) {
        (self.levels[0].width, self.levels[0].height)
    }

    /// The connectivity bits of pixel `(x, y)`.
    #[inline]
    pub fn pixel_links(&self, x: u32, y: u32) -> u8 {
        self.levels[0].get(x, y).links
    }

    /// `true` iff pixels `(x, y)` and `(x + dx, y + dy)` (neighbours) are connected; `false`
    /// if either lies outside the image.
    #[inline]
    pub fn connected(&self, x: i32, y: i32, dx: i32, dy: i32) -> bool {
        let (w, h) = self.size();
        let inside = |x: i32, y: i32| x >= 0 && y >= 0 && x < w as i32 && y < h as i32;
        inside(x, y) && inside(x + dx, y + dy) && self.pixel_links(x as u32, y as u32) & dir_bit(dx, dy) != 0
    }
}

/// A rectangular grid cell in source pixels: `[x0, x1) x [y0, y1)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Cell {
    /// Left column.
    pub x0: u32,
    /// Top row.
    pub y0: u32,
    /// One past the right column.
    pub x1: u32,
    /// One past the bottom row.
    pub y1: u32,
}

impl Cell {
    /// Corner `i` (pixel-corner coordinates): 0 top-left, 1 top-right, 2 bottom-left,
    /// 3 bottom-right.
    #[inline]
    pub fn corner(&self, i: usize) -> (u32, u32) {
        (if i.is_multiple_of(2) { self.x0 } else { self.x1 }, if i < 2 { self.y0 } else { self.y1 })
    }

    /// Pixels covered.
    pub fn area(&self) -> u32 {
        (self.x1 - self.x0) * (self.y1 - self.y0)
    }
}

impl QuadTree {
    /// The adaptive grid (seed 003 Sec. 4.1.4): starting from one cell per tile, a node becomes
    /// one cell if it is a surface whose estimated deviation from a plane, `split(err, size,
    /// cell)`, allows it; otherwise its merged pairs (irregular grid) become 2:1 cells and the
    /// other children are refined, down to single pixels. `split` returns `true` when the cell
    /// must be split (the caller converts the depth error into pixels of the target view).
    pub fn cells(&self, split: impl Fn(f32, Cell) -> bool + Sync) -> Vec<Cell> {
        self.cells_with(split, |_, _, _| false)
    }

    /// [`QuadTree::cells`] where, in addition, a node for which `rigid(level, x, y)` holds is
    /// one cell whatever its surface flag (a view-dependent bound: content that moves by less
    /// than a threshold needs no split, Didyk et al.'s criterion).
    pub fn cells_with(
        &self,
        split: impl Fn(f32, Cell) -> bool + Sync,
        rigid: impl Fn(usize, u32, u32) -> bool + Sync,
    ) -> Vec<Cell> {
        let (w, h) = self.size();
        let top = &self.levels[LEVELS];
        let tiles: Vec<(u32, u32)> = (0..top.height).flat_map(|y| (0..top.width).map(move |x| (x, y))).collect();
        tiles
            .par_iter()
            .flat_map_iter(|&(tx, ty)| {
                let mut out = Vec::new();
                self.emit(LEVELS, tx, ty, w, h, &split, &rigid, &mut out);
                out
            })
            .collect()
    }

    fn rect(level: usize, x: u32, y: u32, w: u32, h: u32) -> Option<Cell> {
        let s = 1u32 << level;
        let c = Cell { x0: x * s, y0: y * s, x1: ((x + 1) * s).min(w), y1: ((y + 1) * s).min(h) };
        (c.x0 < c.x1 && c.y0 < c.y1).then_some(c)
    }

    #[allow(clippy::too_many_arguments)]
    fn emit(
        &self,
        level: usize,
        x: u32,
        y: u32,
        w: u32,
        h: u32,
        split: &(impl Fn(f32, Cell) -> bool + Sync),
        rigid: &(impl Fn(usize, u32, u32) -> bool + Sync),
        out: &mut Vec<Cell>,
    ) {
        let Some(rect) = Self::rect(level, x, y, w, h) else { return };
        let n = self.levels[level].get(x, y);
        if level == 0 || (n.surface && !split(n.err, rect)) || rigid(level, x, y) {
            out.push(rect);
            return;
        }
        let kids = [(2 * x, 2 * y), (2 * x + 1, 2 * y), (2 * x, 2 * y + 1), (2 * x + 1, 2 * y + 1)];
        let mut done = [false; 4];
        let below = &self.levels[level - 1];
        for &(a, b) in n.merge.pairs() {
            let (ra, rb) =
                (Self::rect(level - 1, kids[a].0, kids[a].1, w, h), Self::rect(level - 1, kids[b].0, kids[b].1, w, h));
            let c = match (ra, rb) {
                (Some(ra), Some(rb)) => {
                    Cell { x0: ra.x0.min(rb.x0), y0: ra.y0.min(rb.y0), x1: ra.x1.max(rb.x1), y1: ra.y1.max(rb.y1) }
                }
                _ => continue,
            };
            let err = below.get(kids[a].0, kids[a].1).err.max(below.get(kids[b].0, kids[b].1).err);
            if !split(err, c) {
                out.push(c);
                done[a] = true;
                done[b] = true;
            }
        }
        for (i, &(cx, cy)) in kids.iter().enumerate() {
            if !done[i] {
                self.emit(level - 1, cx, cy, w, h, split, rigid, out);
            }
        }
    }
}

/// The general per-pixel path, for tests of the interior fast path.
#[cfg(test)]
pub(crate) fn pixel_node_general(depth: &Image<f32>, x: u32, y: u32, c: &Collinearity, reduction: Reduction) -> Node {
    pixel_node(depth, x, y, c, reduction)
}
