//! Lazy synthesis of the sample shadow maps: warp only the texels the receivers look up
//! (seed 000, Sec. 6; the per-pixel independence of backward warping, Sec. 3.2).
//!
//! A backward warp computes every target pixel independently (Fig. 3: one fixed-point search
//! per pixel), so a sample map is only needed where some receiver reads it: texel
//! `floor(p_c + K_i g)` of every receiver ([`crate::Receivers::accumulate`]). At 2048^2 maps and
//! a 640x360 camera that is at most 230K of 4.2M texels. [`SparseMap`] collects those texels per
//! sample ([`TexelSet`], in 4x4-tile order so that consecutive texels share the warp's tile
//! bound stage), and holds the warped depth at exactly those texels in a full-size buffer whose
//! other texels are never read.
//!
//! **Holes.** The dilation of Fig. 8 ([`zwarp_warp::HolePolicy::Dilate`]) fills a hole from its
//! nearest converged neighbours along four directions, which a sparse warp does not compute.
//! [`SparseMap::dilate`] warps the missing neighbours of the holes (a second, much smaller
//! sparse warp) and applies the same rule as `zwarp_warp::holes::dilate_holes`, so the sparse
//! maps equal the full maps at every looked-up texel, bit for bit (tested).

use glam::Vec2;
use zwarp_warp::PixelState;

use rayon::prelude::*;

use crate::shade::{texel_xy, Receivers, OFF_MAP};

/// Side of the tiles a [`TexelSet`] orders its texels by (the warp's tile-bound stage works on
/// 4x4 tiles and reuses a tile's bound while consecutive listed pixels share it).
pub const TEXEL_TILE: u32 = 4;

/// A set of texels of a `w x h` map: one 16-bit mask per 4x4 tile, listed in tile-major order
/// (tiles row by row, the texels of a tile row by row). Insertion is a bit set; listing scans
/// the masks (1/16 of the texel count), so collecting the look-ups of 230K receivers costs well
/// under a millisecond even for 2048^2 maps.
///
/// A texel's **slot** is its position in that order counting every texel of every (padded) tile:
/// `slot = tile * 16 + (y % 4) * 4 + x % 4` with `tile = (y / 4) * tiles_x + x / 4`. Slots index
/// the per-texel buffers of [`SparseMap`], so the hot loops never divide by the map width.
#[derive(Clone, Debug)]
pub struct TexelSet {
    w: u32,
    h: u32,
    tiles_x: u32,
    masks: Vec<u16>,
    len: usize,
    /// Tiles with a texel, in insertion order: a sparse set is listed and cleared through
    /// them instead of scanning every mask (a 2048^2 map has 262K tiles, a sample of a large
    /// scene reads a few hundred).
    touched: Vec<u32>,
}

impl TexelSet {
    /// An empty set over a `w x h` map.
    pub fn new(w: u32, h: u32) -> Self {
        let tiles_x = w.div_ceil(TEXEL_TILE);
        let tiles_y = h.div_ceil(TEXEL_TILE);
        TexelSet { w, h, tiles_x, masks: vec![0; tiles_x as usize * tiles_y as usize], len: 0, touched: Vec::new() }
    }

    /// Map size.
    pub fn size(&self) -> (u32, u32) {
        (self.w, self.h)
    }

    /// Number of slots (texels of the padded tiles).
    pub fn slots(&self) -> usize {
        self.masks.len() * 16
    }

    /// Number of texels in the set.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the set is empty.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The slot of texel `(x, y)` (see the type docs).
    #[inline]
    pub fn slot(&self, x: u32, y: u32) -> u32 {
        ((y / TEXEL_TILE) * self.tiles_x + x / TEXEL_TILE) * 16 + (y % TEXEL_TILE) * TEXEL_TILE + x % TEXEL_TILE
    }

    /// Adds the texel in slot `s` (must be a slot of a texel inside the map); returns whether
    /// it was new.
    #[inline]
    pub fn insert_slot(&mut self, s: u32) -> bool {
        let (t, bit) = ((s >> 4) as usize, 1u16 << (s & 15));
        let m = self.masks[t];
        let new = m & bit == 0;
        if m == 0 {
            self.touched.push(t as u32);
        }
        self.masks[t] = m | bit;
        self.len += new as usize;
        new
    }

    /// Adds texel `(x, y)` (must be inside the map); returns whether it was new.
    #[inline]
    pub fn insert(&mut self, x: u32, y: u32) -> bool {
        debug_assert!(x < self.w && y < self.h);
        self.insert_slot(self.slot(x, y))
    }

    /// Whether texel `(x, y)` is in the set (false outside the map).
    #[inline]
    pub fn contains(&self, x: u32, y: u32) -> bool {
        if x >= self.w || y >= self.h {
            return false;
        }
        let s = self.slot(x, y);
        self.masks[(s >> 4) as usize] & (1 << (s & 15)) != 0
    }

    /// Appends the row-major indices `y * w + x` of the set's texels to `texels` and their
    /// slots to `slots`, in tile-major order (increasing slots).
    pub fn list_into(&mut self, texels: &mut Vec<u32>, slots: &mut Vec<u32>) {
        texels.reserve(self.len);
        slots.reserve(self.len);
        if self.is_sparse() {
            self.touched.sort_unstable();
            for &t in &self.touched {
                let mut m = self.masks[t as usize];
                let (tx, ty) = (t % self.tiles_x, t / self.tiles_x);
                while m != 0 {
                    let b = m.trailing_zeros();
                    m &= m - 1;
                    let (x, y) = (tx * TEXEL_TILE + b % TEXEL_TILE, ty * TEXEL_TILE + b / TEXEL_TILE);
                    texels.push(y * self.w + x);
                    slots.push(t * 16 + b);
                }
            }
            return;
        }
        let (mut tx, mut ty) = (0u32, 0u32);
        for (t, &m) in self.masks.iter().enumerate() {
            if m != 0 {
                let mut m = m;
                while m != 0 {
                    let b = m.trailing_zeros();
                    m &= m - 1;
                    let (x, y) = (tx * TEXEL_TILE + b % TEXEL_TILE, ty * TEXEL_TILE + b / TEXEL_TILE);
                    texels.push(y * self.w + x);
                    slots.push(t as u32 * 16 + b);
                }
            }
            tx += 1;
            if tx == self.tiles_x {
                tx = 0;
                ty += 1;
            }
        }
    }

    /// Whether few enough tiles are touched to go through them rather than scan every mask.
    #[inline]
    fn is_sparse(&self) -> bool {
        self.touched.len() * 8 < self.masks.len()
    }

    /// Removes every texel.
    pub fn clear(&mut self) {
        if self.len > 0 {
            if self.is_sparse() {
                for &t in &self.touched {
                    self.masks[t as usize] = 0;
                }
            } else {
                self.masks.fill(0);
            }
            self.len = 0;
        }
        self.touched.clear();
    }
}

/// The part of every receiver the per-sample passes read (centre-map position, shift parameter
/// `g`, depth threshold), packed in 16 bytes: the lazy synthesis streams the receivers twice per
/// sample (collect, accumulate), and a 640x360 frame's [`crate::Receiver`]s are ~13 MB.
#[derive(Clone, Debug)]
pub struct HotReceivers {
    hot: Vec<Hot>,
}

#[derive(Clone, Copy, Debug)]
struct Hot {
    p_c: Vec2,
    g: f32,
    threshold: f32,
}

impl HotReceivers {
    /// Packs `recv` (same order as `recv.list`).
    pub fn new(recv: &Receivers) -> Self {
        HotReceivers { hot: recv.list.iter().map(|r| Hot { p_c: r.p_c, g: r.g, threshold: r.threshold }).collect() }
    }

    /// Number of receivers.
    pub fn len(&self) -> usize {
        self.hot.len()
    }

    /// Whether there are no receivers.
    pub fn is_empty(&self) -> bool {
        self.hot.is_empty()
    }
}

/// The [`PixelState`] stored as `state as u8` in a [`SparseMap`].
#[inline]
fn state_of(s: u8) -> PixelState {
    match s {
        0 => PixelState::Converged,
        1 => PixelState::Filled,
        _ => PixelState::Hole,
    }
}

/// One sample map known only at the texels the receivers look up (see the module docs).
///
/// Per-texel buffers are indexed by [`TexelSet`] slot. Reused across samples:
/// [`SparseMap::collect`] resets it for the next sample.
#[derive(Clone, Debug)]
pub struct SparseMap {
    w: u32,
    h: u32,
    /// Depth per slot at the looked-up texels (and at the hole neighbours warped for the
    /// dilation); every other slot holds a stale value that is never read. Both buffers start
    /// zeroed (a zeroed allocation maps its pages on first write: a sample touches a few
    /// thousand of the 2048^2 slots, and filling 20 MB per map was a visible page-fault cost).
    depth: Vec<f32>,
    /// `PixelState as u8` per slot.
    state: Vec<u8>,
    wanted: TexelSet,
    extra: TexelSet,
    list: Vec<u32>,
    list_slots: Vec<u32>,
    extra_list: Vec<u32>,
    extra_slots: Vec<u32>,
    /// Slot each receiver reads ([`OFF_MAP`] off the map).
    per_receiver: Vec<u32>,
}

impl SparseMap {
    /// An empty sparse map of a `w x h` shadow map.
    pub fn new(w: u32, h: u32) -> Self {
        let wanted = TexelSet::new(w, h);
        let n = wanted.slots();
        SparseMap {
            w,
            h,
            depth: vec![0.0; n],
            state: vec![0u8; n],
            extra: wanted.clone(),
            wanted,
            list: Vec::new(),
            list_slots: Vec::new(),
            extra_list: Vec::new(),
            extra_slots: Vec::new(),
            per_receiver: Vec::new(),
        }
    }

    /// Empties the texel sets and lists before collecting the texels of the next sample.
    fn clear_lists(&mut self) {
        self.wanted.clear();
        self.extra.clear();
        self.list.clear();
        self.list_slots.clear();
        self.extra_list.clear();
        self.extra_slots.clear();
    }

    /// Collects the texels the receivers read in the map of the sample with pixel shift `shift`
    /// (exactly the texels [`Receivers::accumulate`] reads, [`crate::shade::texel_xy`];
    /// receivers outside the map read nothing). Returns how many distinct texels that is. The
    /// slot of every receiver is kept for [`SparseMap::accumulate`].
    pub fn collect(&mut self, recv: &HotReceivers, shift: Vec2) -> usize {
        self.clear_lists();
        let (w, h) = (self.w, self.h);
        self.per_receiver.resize(recv.hot.len(), OFF_MAP);
        let set = &self.wanted;
        self.per_receiver.par_chunks_mut(8192).zip(recv.hot.par_chunks(8192)).for_each(|(o, hot)| {
            for (s, r) in o.iter_mut().zip(hot) {
                *s = texel_xy(r.p_c, r.g, shift, w, h).map_or(OFF_MAP, |(x, y)| set.slot(x, y));
            }
        });
        // Neighbouring camera pixels mostly read the same texel: skipping repeats avoids a
        // chain of read-modify-writes of one mask word (store-to-load forwarding latency).
        let mut prev = OFF_MAP;
        for &s in &self.per_receiver {
            if s != prev && s != OFF_MAP {
                self.wanted.insert_slot(s);
            }
            prev = s;
        }
        self.wanted.list_into(&mut self.list, &mut self.list_slots);
        self.list.len()
    }

    /// Adds the current sample's lit tests to `lit` ([`Receivers::accumulate`] on this map,
    /// with the texels [`SparseMap::collect`] found for `recv`, which must be the same
    /// receivers): 1 where the texel's depth is `>= threshold` or the receiver is off the map.
    pub fn accumulate(&self, recv: &HotReceivers, lit: &mut [u32]) {
        let data = &self.depth;
        lit.par_chunks_mut(8192).zip(recv.hot.par_chunks(8192)).zip(self.per_receiver.par_chunks(8192)).for_each(
            |((acc, hot), ss)| {
                for ((a, r), &s) in acc.iter_mut().zip(hot).zip(ss) {
                    *a += (s == OFF_MAP || data[s as usize] >= r.threshold) as u32;
                }
            },
        );
    }

    /// The looked-up texels of the current sample (row-major indices, tile-major order).
    pub fn texels(&self) -> &[u32] {
        &self.list
    }

    /// The depth at row-major texel `t` (only meaningful at warped texels).
    pub fn depth_at(&self, t: u32) -> f32 {
        self.depth[self.wanted.slot(t % self.w, t / self.w) as usize]
    }

    /// The state at row-major texel `t` (only meaningful at warped texels).
    pub fn state(&self, t: u32) -> PixelState {
        state_of(self.state[self.wanted.slot(t % self.w, t / self.w) as usize])
    }

    /// Writes warp results of the looked-up texels ([`SparseMap::texels`] order).
    pub fn scatter_looked_up(&mut self, values: &[(f32, PixelState)]) {
        for (&s, &(z, st)) in self.list_slots.iter().zip(values) {
            self.depth[s as usize] = z;
            self.state[s as usize] = st as u8;
        }
    }

    /// Texels warped for the current sample: the looked-up ones plus the hole neighbours
    /// [`SparseMap::dilate`] warped.
    pub fn warped(&self) -> usize {
        self.list.len() + self.extra_list.len()
    }

    /// Number of looked-up texels that are [`PixelState::Hole`].
    pub fn holes(&self) -> usize {
        self.list_slots.iter().filter(|&&s| self.state[s as usize] == PixelState::Hole as u8).count()
    }

    /// Fig. 8 dilation of radius `radius` at the looked-up holes. `warp` computes the
    /// undilated warp (far-depth holes) at a list of row-major texels; it is called once, for
    /// the texels within `radius` of a hole along the four dilation directions that were not
    /// looked up (not at all when there are no holes). Same rule and tie-breaking as
    /// `zwarp_warp::holes::dilate_holes`: only converged neighbours are read, so filling holes
    /// in place does not change the result.
    pub fn dilate(
        &mut self,
        radius: u32,
        mut warp: impl FnMut(&[u32]) -> zwarp_core::Result<Vec<(f32, PixelState)>>,
    ) -> zwarp_core::Result<()> {
        let (w, h) = (self.w, self.h);
        let r = radius as i64;
        let holes: Vec<(u32, u32)> = self
            .list
            .iter()
            .zip(&self.list_slots)
            .filter(|(_, &s)| self.state[s as usize] == PixelState::Hole as u8)
            .map(|(&t, &s)| (t, s))
            .collect();
        if holes.is_empty() {
            return Ok(());
        }
        for &(t, _) in &holes {
            let (x, y) = ((t % w) as i64, (t / w) as i64);
            for (dx, dy) in zwarp_warp::FILL_DIRECTIONS {
                for sgn in [-1i64, 1] {
                    for k in 1..=r {
                        let (xx, yy) = (x + sgn * dx * k, y + sgn * dy * k);
                        if xx < 0 || yy < 0 || xx >= w as i64 || yy >= h as i64 {
                            break;
                        }
                        if !self.wanted.contains(xx as u32, yy as u32) {
                            self.extra.insert(xx as u32, yy as u32);
                        }
                    }
                }
            }
        }
        let (mut extra, mut slots) = (std::mem::take(&mut self.extra_list), std::mem::take(&mut self.extra_slots));
        extra.clear();
        slots.clear();
        self.extra.list_into(&mut extra, &mut slots);
        if !extra.is_empty() {
            let values = warp(&extra)?;
            for (&s, &(z, st)) in slots.iter().zip(&values) {
                self.depth[s as usize] = z;
                self.state[s as usize] = st as u8;
            }
        }
        self.extra_list = extra;
        self.extra_slots = slots;
        for &(t, slot) in &holes {
            let (x, y) = ((t % w) as i64, (t / w) as i64);
            let probe = |dx: i64, dy: i64| -> Option<(i64, f32)> {
                for k in 1..=r {
                    let (xx, yy) = (x + dx * k, y + dy * k);
                    if xx < 0 || yy < 0 || xx >= w as i64 || yy >= h as i64 {
                        return None;
                    }
                    let s = self.wanted.slot(xx as u32, yy as u32) as usize;
                    if self.state[s] == PixelState::Converged as u8 {
                        return Some((k, self.depth[s]));
                    }
                }
                None
            };
            if let Some(z) = zwarp_warp::hole_fill(zwarp_warp::FillRule::Nearest, probe) {
                self.depth[slot as usize] = z;
                self.state[slot as usize] = PixelState::Filled as u8;
            }
        }
        Ok(())
    }
}

/// Side of a [`ReceiverGroups`] cell in shadow-map texels (of the centre map).
pub const GROUP_CELL: f32 = 0.5;

/// Largest spread `max |K_i| (g_hi - g_lo)` of the per-sample shifts inside one group, in
/// texels: with [`GROUP_CELL`] a group's look-ups span at most 0.75 texel per axis, i.e. one
/// or two texels.
pub const GROUP_SHIFT_SPREAD: f32 = 0.25;

/// Largest look-up box (texels) a group is tested as a whole with; a group whose box is larger
/// in some sample (clamped far-away cells) is tested receiver by receiver in that sample.
pub const GROUP_MAX_BOX: u32 = 9;

/// Receivers grouped by centre-map cell and shift parameter, so that a sample's visibility is
/// decided for most of a group at once from the few texels its receivers can read (seed 000,
/// Sec. 6: the visibility pass of the lazy synthesis, made cheaper where many camera pixels
/// share a shadow-map texel).
///
/// **Why.** When a shadow-map texel covers many camera pixels (large scenes whose light map
/// spans far more than the view: at the paper's full-size city a 2048^2 texel covers ~250
/// pixels of a 640x360 view), the per-receiver passes ([`SparseMap::collect`],
/// [`SparseMap::accumulate`]) dominate the per-sample cost. A group holds the receivers of one
/// [`GROUP_CELL`]-texel cell of the centre map whose shift parameters `g` differ by at most
/// [`GROUP_SHIFT_SPREAD`]` / max |K_i|`, sorted by threshold; in every sample its receivers
/// read texels inside a box of one or two texels per axis, computed from the group's bounds.
///
/// **Exact.** Let `[d_lo, d_hi]` be the warped depths over that box. Every receiver with
/// threshold `<= d_lo` is lit (`depth >= threshold`; receivers off the map are lit anyway): a
/// prefix of the group, found by binary search and counted with a difference array. If the box
/// lies inside the map, every receiver with threshold `> d_hi` is not lit. Only the receivers
/// in between — a one-texel box has none; else a depth edge or a surface's own depth inside the
/// box — are tested one by one as in [`crate::Receivers::accumulate`]. The box bounds use the
/// same float operations as [`texel_xy`] (`p_c + K g`, monotone rounding), so they contain
/// every receiver's texel and the lit counts equal the per-receiver ones exactly (tested).
#[derive(Clone, Debug)]
pub struct ReceiverGroups {
    /// Receivers in group order (each group sorted by threshold).
    hot: Vec<Hot>,
    /// Index into `Receivers::list` of each receiver in group order.
    index: Vec<u32>,
    /// Thresholds in group order (ascending within a group): the binary searches read only
    /// these, 4 bytes per receiver.
    thresholds: Vec<f32>,
    groups: Vec<Group>,
    /// Receivers with a non-finite position or shift parameter: every sample sends them off
    /// the map ([`texel_xy`]), i.e. lit, so they are never looked up.
    always_lit: Vec<u32>,
}

/// Bounds of one group (see [`ReceiverGroups`]).
#[derive(Clone, Copy, Debug)]
struct Group {
    p_lo: Vec2,
    p_hi: Vec2,
    g_lo: f32,
    g_hi: f32,
    /// Smallest and largest threshold (first and last of the group).
    t_lo: f32,
    t_hi: f32,
    start: u32,
    end: u32,
}

/// A group's texel box in one sample map.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum GroupBox {
    /// Every receiver is off the map (lit).
    Off,
    /// Inclusive texel box (clipped to the map); `inside`: no receiver is off the map.
    Box { x0: u32, y0: u32, x1: u32, y1: u32, inside: bool },
    /// The box is larger than [`GROUP_MAX_BOX`]: test receiver by receiver.
    Each,
}

impl Group {
    /// The texel box of the group's look-ups in the `w x h` map of the sample with pixel
    /// shift `shift` (see [`ReceiverGroups`] for why it contains every receiver's texel).
    #[inline]
    fn texel_box(&self, shift: Vec2, w: u32, h: u32) -> GroupBox {
        // Per axis `p + K g` with the operations of `texel_xy` (`Vec2 * f32`, then `+`): both
        // roundings are monotone, so the extremes over the group bound every receiver's value.
        let (ax, bx) = (shift.x * self.g_lo, shift.x * self.g_hi);
        let (ay, by) = (shift.y * self.g_lo, shift.y * self.g_hi);
        let lo = Vec2::new(self.p_lo.x + ax.min(bx), self.p_lo.y + ay.min(by));
        let hi = Vec2::new(self.p_hi.x + ax.max(bx), self.p_hi.y + ay.max(by));
        let (wf, hf) = (w as f32, h as f32);
        if !(hi.x >= 0.0 && hi.y >= 0.0 && lo.x < wf && lo.y < hf) {
            return GroupBox::Off;
        }
        let inside = lo.x >= 0.0 && lo.y >= 0.0 && hi.x < wf && hi.y < hf;
        // Receivers inside the map have 0 <= v < w, so floor(v) lies in [x0, x1].
        let x0 = if lo.x >= 0.0 { lo.x as u32 } else { 0 };
        let y0 = if lo.y >= 0.0 { lo.y as u32 } else { 0 };
        let x1 = if hi.x < wf { (hi.x as u32).min(w - 1) } else { w - 1 };
        let y1 = if hi.y < hf { (hi.y as u32).min(h - 1) } else { h - 1 };
        if (x1 - x0 + 1) as u64 * (y1 - y0 + 1) as u64 > GROUP_MAX_BOX as u64 {
            return GroupBox::Each;
        }
        GroupBox::Box { x0, y0, x1, y1, inside }
    }
}

/// Order-preserving map of an `f32` to a `u32` (total order, `-inf` first).
#[inline]
fn ordered_bits(x: f32) -> u32 {
    let b = x.to_bits();
    if b >> 31 == 1 {
        !b
    } else {
        b | (1 << 31)
    }
}

impl ReceiverGroups {
    /// Groups `recv` for the samples with pixel shifts `shifts` (see the type docs): sorts the
    /// receivers by (cell row, cell column, `g` bin, threshold) and splits the runs.
    pub fn new(recv: &HotReceivers, shifts: &[Vec2]) -> Self {
        let kmax = shifts.iter().map(|k| k.abs().max_element()).fold(0.0f32, f32::max);
        // Bin width of g: the spread of K_i g inside a bin is at most GROUP_SHIFT_SPREAD texels.
        let inv_dg = if kmax > 0.0 && kmax.is_finite() { kmax / GROUP_SHIFT_SPREAD } else { 0.0 };
        let inv_cell = 1.0 / GROUP_CELL;
        let mut always_lit = Vec::new();
        let mut keyed: Vec<(u64, u32, u32)> = Vec::with_capacity(recv.hot.len());
        for (k, r) in recv.hot.iter().enumerate() {
            if !(r.p_c.is_finite() && r.g.is_finite()) {
                always_lit.push(k as u32);
                continue;
            }
            // Saturating casts: far-away cells share the extreme keys (their boxes are then
            // large and tested receiver by receiver, still exact).
            let cx = (zwarp_core::round::floor(r.p_c.x * inv_cell) as i32).clamp(-(1 << 15), (1 << 15) - 1) + (1 << 15);
            let cy = (zwarp_core::round::floor(r.p_c.y * inv_cell) as i32).clamp(-(1 << 15), (1 << 15) - 1) + (1 << 15);
            let gb = (zwarp_core::round::floor(r.g * inv_dg) as i64).clamp(i32::MIN as i64, i32::MAX as i64)
                - i32::MIN as i64;
            let key = ((cy as u64) << 48) | ((cx as u64) << 32) | gb as u64;
            keyed.push((key, ordered_bits(r.threshold), k as u32));
        }
        keyed.par_sort_unstable();
        let hot: Vec<Hot> = keyed.iter().map(|&(_, _, k)| recv.hot[k as usize]).collect();
        let index: Vec<u32> = keyed.iter().map(|&(_, _, k)| k).collect();
        let mut groups = Vec::new();
        let mut start = 0usize;
        while start < keyed.len() {
            let key = keyed[start].0;
            let mut g = Group {
                p_lo: hot[start].p_c,
                p_hi: hot[start].p_c,
                g_lo: hot[start].g,
                g_hi: hot[start].g,
                t_lo: hot[start].threshold,
                t_hi: hot[start].threshold,
                start: start as u32,
                end: 0,
            };
            let mut end = start;
            while end < keyed.len() && keyed[end].0 == key {
                let r = &hot[end];
                g.p_lo = g.p_lo.min(r.p_c);
                g.p_hi = g.p_hi.max(r.p_c);
                g.g_lo = g.g_lo.min(r.g);
                g.g_hi = g.g_hi.max(r.g);
                g.t_lo = g.t_lo.min(r.threshold);
                g.t_hi = g.t_hi.max(r.threshold);
                end += 1;
            }
            g.end = end as u32;
            groups.push(g);
            start = end;
        }
        let thresholds = hot.iter().map(|r| r.threshold).collect();
        ReceiverGroups { hot, index, thresholds, groups, always_lit }
    }

    /// Number of groups.
    pub fn len(&self) -> usize {
        self.groups.len()
    }

    /// Whether there are no groups.
    pub fn is_empty(&self) -> bool {
        self.groups.is_empty()
    }

    /// Number of grouped receivers (all but the always-lit ones).
    pub fn receivers(&self) -> usize {
        self.hot.len()
    }

    /// Adds the per-receiver lit counts (order of `Receivers::list`) of `counts`, accumulated
    /// over `samples` samples by [`SparseMap::accumulate_groups`], to `lit`.
    pub fn lit_counts(&self, counts: &GroupCounts, samples: u32, lit: &mut [u32]) {
        let mut run = 0i64;
        for (j, (&k, &m)) in self.index.iter().zip(&counts.each).enumerate() {
            run += counts.prefix[j] as i64;
            lit[k as usize] += run as u32 + m;
        }
        for &k in &self.always_lit {
            lit[k as usize] += samples;
        }
    }
}

/// Lit counts of grouped receivers (group order) being accumulated: the lit prefixes of the
/// groups as a difference array, plus the receivers tested one by one.
#[derive(Clone, Debug)]
pub struct GroupCounts {
    /// `prefix[j]` - `prefix[j - 1]`-style difference array: a lit prefix `[a, b)` adds 1 at
    /// `a` and -1 at `b` (length: receivers + 1).
    prefix: Vec<i32>,
    /// Lit counts of the receivers tested one by one.
    each: Vec<u32>,
}

impl GroupCounts {
    /// Zero counts for `groups`.
    pub fn new(groups: &ReceiverGroups) -> Self {
        GroupCounts { prefix: vec![0; groups.receivers() + 1], each: vec![0; groups.receivers()] }
    }

    /// Adds `other` (counts of other samples, same groups).
    pub fn add(&mut self, other: &GroupCounts) {
        self.prefix.iter_mut().zip(&other.prefix).for_each(|(a, b)| *a += b);
        self.each.iter_mut().zip(&other.each).for_each(|(a, b)| *a += b);
    }

    #[inline]
    fn lit_range(&mut self, a: usize, b: usize) {
        if a < b {
            self.prefix[a] += 1;
            self.prefix[b] -= 1;
        }
    }
}

impl SparseMap {
    /// [`SparseMap::collect`] for grouped receivers: the texel box of every group in the map
    /// of the sample with pixel shift `shift` (every texel of a group whose box is larger than
    /// [`GROUP_MAX_BOX`]: its receivers' texels). A superset of the texels the receivers read;
    /// returns how many distinct texels that is.
    pub fn collect_groups(&mut self, groups: &ReceiverGroups, shift: Vec2) -> usize {
        self.clear_lists();
        let (w, h) = (self.w, self.h);
        for g in &groups.groups {
            match g.texel_box(shift, w, h) {
                GroupBox::Off => {}
                GroupBox::Box { x0, y0, x1, y1, .. } => {
                    for y in y0..=y1 {
                        for x in x0..=x1 {
                            self.wanted.insert(x, y);
                        }
                    }
                }
                GroupBox::Each => {
                    for r in &groups.hot[g.start as usize..g.end as usize] {
                        if let Some((x, y)) = texel_xy(r.p_c, r.g, shift, w, h) {
                            self.wanted.insert(x, y);
                        }
                    }
                }
            }
        }
        self.wanted.list_into(&mut self.list, &mut self.list_slots);
        self.list.len()
    }

    /// [`SparseMap::accumulate`] for grouped receivers after [`SparseMap::collect_groups`]
    /// with the same `groups` and `shift` (see [`ReceiverGroups`]): adds this sample's lit
    /// tests to `counts`. Returns how many receivers were tested one by one.
    pub fn accumulate_groups(&self, groups: &ReceiverGroups, shift: Vec2, counts: &mut GroupCounts) -> usize {
        let (w, h) = (self.w, self.h);
        let data = &self.depth;
        let set = &self.wanted;
        let mut tested = 0;
        for g in &groups.groups {
            let (start, end) = (g.start as usize, g.end as usize);
            let members = &groups.hot[start..end];
            // The receivers [a, b) of the group are tested one by one.
            let (a, b) = match g.texel_box(shift, w, h) {
                GroupBox::Off => {
                    counts.lit_range(start, end);
                    continue;
                }
                GroupBox::Box { x0, y0, x1, y1, inside } => {
                    let (mut d_lo, mut d_hi) = (f32::INFINITY, f32::NEG_INFINITY);
                    for y in y0..=y1 {
                        for x in x0..=x1 {
                            let d = data[set.slot(x, y) as usize];
                            d_lo = d_lo.min(d);
                            d_hi = d_hi.max(d);
                        }
                    }
                    // Thresholds ascend within the group: a prefix reads depths >= its
                    // thresholds whichever box texel it reads. Whole groups (lit, or in
                    // umbra) are the common case: no search for them.
                    let thr = &groups.thresholds[start..end];
                    let count_le = |d: f32| {
                        if d >= g.t_hi {
                            thr.len()
                        } else if d < g.t_lo {
                            0
                        } else {
                            thr.partition_point(|&t| t <= d)
                        }
                    };
                    let a = count_le(d_lo);
                    counts.lit_range(start, start + a);
                    (a, if inside { count_le(d_hi) } else { thr.len() })
                }
                GroupBox::Each => (0, members.len()),
            };
            tested += b - a;
            for (r, c) in members[a..b].iter().zip(&mut counts.each[start + a..start + b]) {
                *c += match texel_xy(r.p_c, r.g, shift, w, h) {
                    None => 1,
                    Some((x, y)) => (data[set.slot(x, y) as usize] >= r.threshold) as u32,
                };
            }
        }
        tested
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use zwarp_core::{Image, EMPTY_DEPTH};

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// The set holds exactly the inserted texels, lists each once in tile-major order, and
        /// `clear` empties it (odd sizes: partial tiles on the right and bottom).
        #[test]
        fn texel_set_lists_each_inserted_texel_once(
            w in 1u32..23, h in 1u32..19, pts in proptest::collection::vec((0u32..64, 0u32..64), 0..80),
        ) {
            let mut set = TexelSet::new(w, h);
            let mut want = std::collections::BTreeSet::new();
            for (x, y) in pts {
                let (x, y) = (x % w, y % h);
                prop_assert_eq!(set.insert(x, y), want.insert((x, y)));
            }
            prop_assert_eq!(set.len(), want.len());
            let (mut list, mut slots) = (Vec::new(), Vec::new());
            set.list_into(&mut list, &mut slots);
            prop_assert_eq!(list.len(), want.len());
            prop_assert!(slots.windows(2).all(|p| p[0] < p[1]));
            for (&t, &s) in list.iter().zip(&slots) {
                prop_assert_eq!(set.slot(t % w, t / w), s);
                prop_assert!((s as usize) < set.slots());
            }
            let key = |t: u32| {
                let (x, y) = (t % w, t / w);
                (y / TEXEL_TILE, x / TEXEL_TILE, y % TEXEL_TILE, x % TEXEL_TILE)
            };
            prop_assert!(list.windows(2).all(|p| key(p[0]) < key(p[1])), "not tile-major: {:?}", list);
            for &t in &list {
                prop_assert!(want.contains(&(t % w, t / w)));
                prop_assert!(set.contains(t % w, t / w));
            }
            prop_assert!(!set.contains(w, 0) && !set.contains(0, h));
            set.clear();
            prop_assert!(set.is_empty());
            list.clear();
            slots.clear();
            set.list_into(&mut list, &mut slots);
            prop_assert!(list.is_empty() && slots.is_empty());
        }
    }

    /// Per-receiver lit counts of a full map (the definition, [`texel_xy`]).
    fn lit_direct(hot: &HotReceivers, map: &Image<f32>, shift: Vec2, lit: &mut [u32]) {
        let (w, h) = map.size();
        for (r, a) in hot.hot.iter().zip(lit) {
            *a += match texel_xy(r.p_c, r.g, shift, w, h) {
                None => 1,
                Some((x, y)) => (*map.get(x, y) >= r.threshold) as u32,
            };
        }
    }

    /// Grouped lit counts over several samples: the map known only at the collected texels
    /// (the rest stale), decided per group or per receiver.
    fn lit_grouped(hot: &HotReceivers, maps: &[(Image<f32>, Vec2)], lit: &mut [u32]) -> (usize, usize) {
        let (w, h) = maps[0].0.size();
        let groups = ReceiverGroups::new(hot, &maps.iter().map(|m| m.1).collect::<Vec<_>>());
        let mut sparse = SparseMap::new(w, h);
        let mut counts = GroupCounts::new(&groups);
        let (mut looked_up, mut tested) = (0, 0);
        for (s, (map, shift)) in maps.iter().enumerate() {
            // Poison the buffer so a texel read without being collected shows up: below every
            // threshold (a wrong "lit") or above every one (a wrong "shadowed").
            sparse.depth.fill(if s % 2 == 0 { -1.0 } else { 2.0 });
            looked_up += sparse.collect_groups(&groups, *shift);
            let vals: Vec<_> =
                sparse.texels().iter().map(|&t| (map.data()[t as usize], PixelState::Converged)).collect();
            sparse.scatter_looked_up(&vals);
            tested += sparse.accumulate_groups(&groups, *shift, &mut counts);
        }
        groups.lit_counts(&counts, maps.len() as u32, lit);
        (looked_up, tested)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        /// Grouped receivers give exactly the per-receiver lit counts: clustered receivers
        /// (many per texel), some off the map or non-finite, thresholds around the map depths,
        /// shifts of both signs and some pushing receivers off the map.
        #[test]
        fn grouped_lit_counts_equal_per_receiver_counts(
            w in 4u32..40, h in 4u32..40, seed in 0u64..1_000_000, n in 1usize..600,
            kx in -30.0f32..30.0, ky in -30.0f32..30.0, samples in 1usize..6,
        ) {
            let mut rng = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
            let mut next = move || {
                rng ^= rng << 13;
                rng ^= rng >> 7;
                rng ^= rng << 17;
                (rng >> 11) as f32 / (1u64 << 53) as f32
            };
            // A blocky map (depth edges) with values in [0.2, 1].
            let blocks: Vec<f32> = (0..64).map(|_| 0.2 + 0.8 * next()).collect();
            let maps: Vec<(Image<f32>, Vec2)> = (0..samples)
                .map(|s| {
                    let off = s as u32 * 3;
                    let map = Image::from_fn(w, h, |x, y| blocks[(((x + off) / 3) % 8 + ((y / 3) % 8) * 8) as usize]);
                    let shift = Vec2::new(kx, ky) * (s as f32 - 1.5) / 2.0;
                    (map, shift)
                })
                .collect();
            let hot: Vec<Hot> = (0..n)
                .map(|k| {
                    let c = Vec2::new((k % 7) as f32 * w as f32 / 7.0, (k % 5) as f32 * h as f32 / 5.0);
                    let p_c = match k % 50 {
                        0 => Vec2::new(f32::NAN, 1.0),
                        1 => Vec2::new(-5.0 * w as f32, 0.5),
                        _ => c + Vec2::new(next(), next()) * 1.5 - Vec2::splat(0.2),
                    };
                    let g = if k % 97 == 3 { f32::INFINITY } else { 0.02 + 0.05 * next() };
                    let threshold = if k % 31 == 0 { f32::NEG_INFINITY } else { 0.1 + 0.95 * next() };
                    Hot { p_c, g, threshold }
                })
                .collect();
            let hot = HotReceivers { hot };
            let mut want = vec![0u32; n];
            for (map, shift) in &maps {
                lit_direct(&hot, map, *shift, &mut want);
            }
            let mut got = vec![0u32; n];
            lit_grouped(&hot, &maps, &mut got);
            prop_assert_eq!(got, want);
        }
    }

    /// Many receivers per texel (a flat lit plane partly under an occluder block): most groups
    /// are decided as a whole, exact counts, and the boxes add at most a few texels.
    #[test]
    fn dense_receivers_are_decided_per_group() {
        let (w, h) = (32u32, 32u32);
        // Ground at depth 0.8 everywhere except an occluder block at depth 0.3.
        let map = |dx: u32| {
            Image::from_fn(
                w,
                h,
                move |x, y| if (8 + dx..16 + dx).contains(&x) && (8..16).contains(&y) { 0.3 } else { 0.8 },
            )
        };
        let maps: Vec<(Image<f32>, Vec2)> = (0..4).map(|s| (map(s), Vec2::new(s as f32 * 20.0 - 30.0, 10.0))).collect();
        // 64 receivers per texel on the ground (threshold just below the ground depth).
        let mut hot = Vec::new();
        for y in 0..128 {
            for x in 0..128 {
                let p_c = Vec2::new(x as f32 + 0.5, y as f32 + 0.5) / 4.0;
                hot.push(Hot { p_c, g: 0.05 + 0.0001 * x as f32, threshold: 0.79 });
            }
        }
        let hot = HotReceivers { hot };
        let mut want = vec![0u32; hot.len()];
        for (m, s) in &maps {
            lit_direct(&hot, m, *s, &mut want);
        }
        let mut got = vec![0u32; hot.len()];
        let (looked_up, tested) = lit_grouped(&hot, &maps, &mut got);
        assert_eq!(got, want);
        assert!(want.contains(&0) && want.contains(&4), "no umbra or no lit region");
        // Only groups whose box straddles the block's edge are tested receiver by receiver.
        let tests = hot.len() * maps.len();
        assert!(tested * 5 < tests, "{tested} of {tests} receiver tests not decided per group");
        assert!(looked_up <= 4 * (w * h) as usize);
    }

    /// The sparse dilation equals `zwarp_warp::holes::dilate_holes` at the looked-up texels of
    /// a random map of converged pixels and holes.
    #[test]
    fn sparse_dilation_equals_full_dilation() {
        let (w, h) = (37u32, 29u32);
        let mut rng = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            rng
        };
        let mut full_depth = Image::new(w, h, EMPTY_DEPTH);
        let mut full_state = Image::new(w, h, PixelState::Hole);
        for i in 0..(w * h) as usize {
            if next() % 4 != 0 {
                full_depth.data_mut()[i] = (next() % 1000) as f32 / 1000.0;
                full_state.data_mut()[i] = PixelState::Converged;
            }
        }
        let undilated: Vec<(f32, PixelState)> =
            full_depth.data().iter().copied().zip(full_state.data().iter().copied()).collect();
        let (mut dd, mut ds) = (full_depth.clone(), full_state.clone());
        zwarp_warp::holes::dilate_holes(&mut dd, &mut ds, 2);
        assert!(ds.data().contains(&PixelState::Filled) && ds.data().contains(&PixelState::Hole));
        // Look up a random third of the texels.
        let mut sparse = SparseMap::new(w, h);
        for t in 0..w * h {
            if next() % 3 == 0 {
                sparse.wanted.insert(t % w, t / w);
            }
        }
        sparse.wanted.list_into(&mut sparse.list, &mut sparse.list_slots);
        let list = sparse.list.clone();
        let vals: Vec<_> = list.iter().map(|&t| undilated[t as usize]).collect();
        sparse.scatter_looked_up(&vals);
        let mut calls = 0;
        sparse
            .dilate(2, |ts| {
                calls += 1;
                // Only texels that were not looked up are requested.
                assert!(ts.iter().all(|t| !list.contains(t)));
                Ok(ts.iter().map(|&t| undilated[t as usize]).collect())
            })
            .unwrap();
        assert_eq!(calls, 1);
        for &t in &list {
            assert_eq!(sparse.state(t), ds.data()[t as usize], "texel {t}");
            assert_eq!(sparse.depth_at(t).to_bits(), dd.data()[t as usize].to_bits(), "texel {t}");
        }
        assert_eq!(sparse.holes(), list.iter().filter(|&&t| ds.data()[t as usize] == PixelState::Hole).count());
    }
}
