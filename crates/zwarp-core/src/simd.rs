//! The run-time choice between a kernel's AVX2 build and its portable build (x86-64), one switch
//! per crate. Every AVX2 build in zwarp computes bit-identical results to its portable twin; the
//! switch exists so that tests can prove it and benchmarks can time the portable build.

use std::sync::atomic::{AtomicBool, Ordering};

/// A crate's AVX2 switch: on by default, active where it is on and the CPU reports AVX2.
#[derive(Debug)]
pub struct Avx2Switch(AtomicBool);

impl Avx2Switch {
    /// A switch that is on (for a `static`).
    pub const fn new() -> Self {
        Avx2Switch(AtomicBool::new(true))
    }

    /// Turns the AVX2 builds on (default) or off.
    pub fn set(&self, enabled: bool) {
        self.0.store(enabled, Ordering::Relaxed);
    }

    /// `true` if the AVX2 builds run: the switch is on and the CPU reports AVX2 (never off
    /// x86-64).
    #[inline]
    pub fn active(&self) -> bool {
        #[cfg(target_arch = "x86_64")]
        {
            self.0.load(Ordering::Relaxed) && std::arch::is_x86_feature_detected!("avx2")
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            false
        }
    }
}

impl Default for Avx2Switch {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_switch_turned_off_is_never_active() {
        let s = Avx2Switch::new();
        s.set(false);
        assert!(!s.active());
        s.set(true);
        #[cfg(target_arch = "x86_64")]
        assert_eq!(s.active(), std::arch::is_x86_feature_detected!("avx2"));
        #[cfg(not(target_arch = "x86_64"))]
        assert!(!s.active());
    }
}
