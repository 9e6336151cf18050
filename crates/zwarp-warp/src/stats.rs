//! Memory-traffic counters of the warp (issue "Speed": bytes touched per pixel), compiled in
//! only with the `stats` cargo feature; without it [`count`] is empty and [`take`] returns zeros.
//!
//! What is counted (each read of a texel once per use, i.e. bytes *touched*, not DRAM traffic):
//! min-max mipmap texels (16 bytes: look-ups of the bound tightening, Fig. 5), min-depth mipmap
//! texels (4 bytes: the pruning of later layers), motion samples (12 bytes: four per adaptive /
//! bilinear fetch, one per nearest fetch, Sec. 3.2) and output pixels (5 bytes: depth + state).
//! The layer preparation (one pass over depth + motion, see `PreparedLayer::prepare_stack`) is
//! not counted here; it touches about 37 bytes per pixel and layer (+4 per earlier layer).

/// Counter indices.
#[derive(Clone, Copy, Debug)]
#[repr(usize)]
pub enum Counter {
    /// Min-max mipmap texels read (16 bytes each).
    MipTexels = 0,
    /// Min-depth mipmap texels read (4 bytes each).
    DepthTexels = 1,
    /// Motion samples read by fetches (12 bytes each).
    MotionTexels = 2,
    /// Fetches (samples of the fixed-point search, polishing included).
    Fetches = 3,
    /// Output pixels written (5 bytes each).
    Pixels = 4,
    /// Seeds searched (fixed-point walks started).
    Seeds = 5,
    /// Per-pixel bound tightenings (Fig. 5 runs after the tile stage).
    Tightenings = 6,
}

/// Snapshot of the counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counts {
    /// See [`Counter::MipTexels`].
    pub mip_texels: u64,
    /// See [`Counter::DepthTexels`].
    pub depth_texels: u64,
    /// See [`Counter::MotionTexels`].
    pub motion_texels: u64,
    /// See [`Counter::Fetches`].
    pub fetches: u64,
    /// See [`Counter::Pixels`].
    pub pixels: u64,
    /// See [`Counter::Seeds`].
    pub seeds: u64,
    /// See [`Counter::Tightenings`].
    pub tightenings: u64,
}

impl Counts {
    /// Bytes touched: 16 per min-max texel, 4 per min-depth texel, 12 per motion sample, 5 per
    /// output pixel.
    pub fn bytes(&self) -> u64 {
        16 * self.mip_texels + 4 * self.depth_texels + 12 * self.motion_texels + 5 * self.pixels
    }
    /// Bytes touched per output pixel (0 if none).
    pub fn bytes_per_pixel(&self) -> f64 {
        self.bytes() as f64 / self.pixels.max(1) as f64
    }
}

#[cfg(feature = "stats")]
static COUNTERS: [std::sync::atomic::AtomicU64; 7] = [const { std::sync::atomic::AtomicU64::new(0) }; 7];

/// Adds `n` to counter `c` (no-op without the `stats` feature).
#[inline(always)]
pub fn count(c: Counter, n: u64) {
    #[cfg(feature = "stats")]
    COUNTERS[c as usize].fetch_add(n, std::sync::atomic::Ordering::Relaxed);
    #[cfg(not(feature = "stats"))]
    let _ = (c, n);
}

/// `true` if the counters are compiled in.
pub const ENABLED: bool = cfg!(feature = "stats");

/// Returns the counts accumulated since the last call and resets them (all zero without the
/// `stats` feature).
pub fn take() -> Counts {
    #[cfg(feature = "stats")]
    {
        let t = |c: Counter| COUNTERS[c as usize].swap(0, std::sync::atomic::Ordering::Relaxed);
        Counts {
            mip_texels: t(Counter::MipTexels),
            depth_texels: t(Counter::DepthTexels),
            motion_texels: t(Counter::MotionTexels),
            fetches: t(Counter::Fetches),
            pixels: t(Counter::Pixels),
            seeds: t(Counter::Seeds),
            tightenings: t(Counter::Tightenings),
        }
    }
    #[cfg(not(feature = "stats"))]
    Counts::default()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bytes_follow_the_texel_sizes() {
        let c = Counts { mip_texels: 2, depth_texels: 3, motion_texels: 4, fetches: 1, pixels: 1, ..Counts::default() };
        assert_eq!(c.bytes(), 32 + 12 + 48 + 5);
        assert_eq!(c.bytes_per_pixel(), 97.0);
        assert_eq!(Counts::default().bytes_per_pixel(), 0.0);
        count(Counter::Pixels, 1);
        let t = take();
        assert_eq!(t.pixels, if ENABLED { t.pixels.max(1) } else { 0 });
    }
}
