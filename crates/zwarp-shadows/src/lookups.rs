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
use zwarp_core::EMPTY_DEPTH;
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
}

impl TexelSet {
    /// An empty set over a `w x h` map.
    pub fn new(w: u32, h: u32) -> Self {
        let tiles_x = w.div_ceil(TEXEL_TILE);
        let tiles_y = h.div_ceil(TEXEL_TILE);
        TexelSet { w, h, tiles_x, masks: vec![0; tiles_x as usize * tiles_y as usize], len: 0 }
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
        let new = self.masks[t] & bit == 0;
        self.masks[t] |= bit;
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
    pub fn list_into(&self, texels: &mut Vec<u32>, slots: &mut Vec<u32>) {
        texels.reserve(self.len);
        slots.reserve(self.len);
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

    /// Removes every texel.
    pub fn clear(&mut self) {
        if self.len > 0 {
            self.masks.fill(0);
            self.len = 0;
        }
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

/// One sample map known only at the texels the receivers look up (see the module docs).
///
/// Per-texel buffers are indexed by [`TexelSet`] slot. Reused across samples:
/// [`SparseMap::collect`] resets it for the next sample.
#[derive(Clone, Debug)]
pub struct SparseMap {
    w: u32,
    h: u32,
    /// Depth per slot at the looked-up texels (and at the hole neighbours warped for the
    /// dilation); every other slot holds a stale value that is never read.
    depth: Vec<f32>,
    state: Vec<PixelState>,
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
            depth: vec![EMPTY_DEPTH; n],
            state: vec![PixelState::Hole; n],
            extra: wanted.clone(),
            wanted,
            list: Vec::new(),
            list_slots: Vec::new(),
            extra_list: Vec::new(),
            extra_slots: Vec::new(),
            per_receiver: Vec::new(),
        }
    }

    /// Collects the texels the receivers read in the map of the sample with pixel shift `shift`
    /// (exactly the texels [`Receivers::accumulate`] reads, [`crate::shade::texel_xy`];
    /// receivers outside the map read nothing). Returns how many distinct texels that is. The
    /// slot of every receiver is kept for [`SparseMap::accumulate`].
    pub fn collect(&mut self, recv: &HotReceivers, shift: Vec2) -> usize {
        self.wanted.clear();
        self.extra.clear();
        self.list.clear();
        self.list_slots.clear();
        self.extra_list.clear();
        self.extra_slots.clear();
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
        self.state[self.wanted.slot(t % self.w, t / self.w) as usize]
    }

    /// Writes warp results of the looked-up texels ([`SparseMap::texels`] order).
    pub fn scatter_looked_up(&mut self, values: &[(f32, PixelState)]) {
        for (&s, &(z, st)) in self.list_slots.iter().zip(values) {
            self.depth[s as usize] = z;
            self.state[s as usize] = st;
        }
    }

    /// Texels warped for the current sample: the looked-up ones plus the hole neighbours
    /// [`SparseMap::dilate`] warped.
    pub fn warped(&self) -> usize {
        self.list.len() + self.extra_list.len()
    }

    /// Number of looked-up texels that are [`PixelState::Hole`].
    pub fn holes(&self) -> usize {
        self.list_slots.iter().filter(|&&s| self.state[s as usize] == PixelState::Hole).count()
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
            .filter(|(_, &s)| self.state[s as usize] == PixelState::Hole)
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
                self.state[s as usize] = st;
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
                    if self.state[s] == PixelState::Converged {
                        return Some((k, self.depth[s]));
                    }
                }
                None
            };
            if let Some(z) = zwarp_warp::hole_fill(zwarp_warp::FillRule::Nearest, probe) {
                self.depth[slot as usize] = z;
                self.state[slot as usize] = PixelState::Filled;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use zwarp_core::Image;

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
