//! Statistics of repeated timings: every speed figure zwarp reports is the median of warm
//! repetitions with its spread (ARCHITECTURE.md design rule 5, "Measure side by side").

/// Median and spread of repeated timings (milliseconds).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Timing {
    /// Median (the mean of the two middle samples for an even count).
    pub median: f64,
    /// Minimum.
    pub min: f64,
    /// Maximum.
    pub max: f64,
    /// 99th percentile (nearest rank).
    pub p99: f64,
}

impl Timing {
    /// Statistics of `samples` (ms); zeros if empty.
    pub fn of(samples: &[f64]) -> Timing {
        if samples.is_empty() {
            return Timing::default();
        }
        let mut s = samples.to_vec();
        s.sort_by(|a, b| a.total_cmp(b));
        let n = s.len();
        let median = if n % 2 == 1 { s[n / 2] } else { 0.5 * (s[n / 2 - 1] + s[n / 2]) };
        let rank = ((0.99 * n as f64).ceil() as usize).clamp(1, n) - 1;
        Timing { median, min: s[0], max: s[n - 1], p99: s[rank] }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn timing_statistics() {
        let t = Timing::of(&[5.0, 1.0, 3.0, 2.0, 4.0]);
        assert_eq!((t.median, t.min, t.max, t.p99), (3.0, 1.0, 5.0, 5.0));
        assert_eq!(Timing::of(&[1.0, 2.0, 3.0, 4.0]).median, 2.5);
        assert_eq!(Timing::of(&[]), Timing::default());
    }
}
