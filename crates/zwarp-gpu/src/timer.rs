//! Timing GPU work (ARCHITECTURE.md "Timings": warm, repeated, median and spread).
//!
//! With `TIMESTAMP_QUERY` the GPU itself stamps the start and
//! end of the recorded work; otherwise the wall clock measures submit + wait (fenced), which
//! includes submission overhead and is labelled as such.

use std::time::{Duration, Instant};

use zwarp_core::{Error, Result};

use crate::readback::map_blocking;
use crate::GpuContext;

/// How a [`GpuTimer`] measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TimingMethod {
    /// GPU timestamp queries (device time of the recorded commands).
    Timestamps,
    /// Wall clock around submit + blocking wait (includes driver submission overhead).
    FencedWallClock,
}

impl std::fmt::Display for TimingMethod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            TimingMethod::Timestamps => "gpu timestamps",
            TimingMethod::FencedWallClock => "fenced wall clock",
        })
    }
}

/// Measures the GPU time of recorded command sequences.
pub struct GpuTimer {
    ctx: GpuContext,
    queries: Option<(wgpu::QuerySet, wgpu::Buffer, wgpu::Buffer)>,
}

impl GpuTimer {
    /// A timer on `ctx`: GPU timestamps if the device has them enabled and is a hardware GPU,
    /// else the fenced wall clock. Software adapters are excluded because their timestamps
    /// are not ordered with compute work: on lavapipe the motion kernel at 1920x1080 reads
    /// 0.07 ms between pass timestamps but 94 ms fenced (render passes agree within noise).
    pub fn new(ctx: &GpuContext) -> Self {
        if ctx.adapter.device_type == "Cpu" {
            Self::wall_clock(ctx)
        } else {
            Self::with_timestamps(ctx).unwrap_or_else(|| Self::wall_clock(ctx))
        }
    }

    /// A timer that uses GPU timestamps, or `None` if the device has no timestamp queries.
    pub fn with_timestamps(ctx: &GpuContext) -> Option<Self> {
        if !ctx.has_timestamps() {
            return None;
        }
        let set = ctx.device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("zwarp timer"),
            ty: wgpu::QueryType::Timestamp,
            count: 2,
        });
        let resolve = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("zwarp timer resolve"),
            size: 2 * wgpu::QUERY_SIZE as u64,
            usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let read = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("zwarp timer read"),
            size: 2 * wgpu::QUERY_SIZE as u64,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        Some(GpuTimer { ctx: ctx.clone(), queries: Some((set, resolve, read)) })
    }

    /// A timer that always uses the fenced wall clock (to compare both methods).
    pub fn wall_clock(ctx: &GpuContext) -> Self {
        GpuTimer { ctx: ctx.clone(), queries: None }
    }

    /// The method this timer uses.
    pub fn method(&self) -> TimingMethod {
        if self.queries.is_some() {
            TimingMethod::Timestamps
        } else {
            TimingMethod::FencedWallClock
        }
    }

    /// Waits for pending work, then records `record` into one encoder, submits it and returns
    /// the time the GPU took for it.
    pub fn measure(&self, record: impl FnOnce(&mut wgpu::CommandEncoder) -> Result<()>) -> Result<Duration> {
        self.ctx.wait()?;
        let mut enc = self.ctx.device.create_command_encoder(&Default::default());
        match &self.queries {
            Some((set, resolve, read)) => {
                // Timestamps are written by empty compute passes around the recorded work:
                // pass-level timestamps keep their place in the pass order, while encoder-level
                // `write_timestamp` may be reordered against passes (wgpu docs).
                let stamp = |enc: &mut wgpu::CommandEncoder, begin: Option<u32>, end: Option<u32>| {
                    enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                        label: Some("zwarp timer"),
                        timestamp_writes: Some(wgpu::ComputePassTimestampWrites {
                            query_set: set,
                            beginning_of_pass_write_index: begin,
                            end_of_pass_write_index: end,
                        }),
                    });
                };
                stamp(&mut enc, Some(0), None);
                record(&mut enc)?;
                stamp(&mut enc, None, Some(1));
                enc.resolve_query_set(set, 0..2, resolve, 0);
                enc.copy_buffer_to_buffer(resolve, 0, read, 0, 2 * wgpu::QUERY_SIZE as u64);
                self.ctx.queue.submit([enc.finish()]);
                map_blocking(&self.ctx, read)?;
                let ticks: Vec<u64> = {
                    let view = read
                        .get_mapped_range(..)
                        .map_err(|e| Error::Unavailable(format!("reading GPU timestamps failed: {e}")))?;
                    bytemuck::pod_collect_to_vec(&view[..])
                };
                read.unmap();
                let period = self.ctx.queue.get_timestamp_period() as f64;
                let ns = ticks[1].saturating_sub(ticks[0]) as f64 * period;
                Ok(Duration::from_nanos(ns.round() as u64))
            }
            None => {
                record(&mut enc)?;
                let cmd = enc.finish();
                let start = Instant::now();
                self.ctx.queue.submit([cmd]);
                self.ctx.wait()?;
                Ok(start.elapsed())
            }
        }
    }
}

/// Median and spread of repeated timings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimingStats {
    /// Median.
    pub median: Duration,
    /// Fastest run.
    pub min: Duration,
    /// Slowest run.
    pub max: Duration,
    /// Number of runs.
    pub runs: usize,
}

impl TimingStats {
    /// Statistics of `samples`; errors if empty.
    pub fn from_samples(samples: &[Duration]) -> Result<Self> {
        if samples.is_empty() {
            return Err(Error::invalid("no timing samples"));
        }
        let mut s = samples.to_vec();
        s.sort();
        let n = s.len();
        let median = if n % 2 == 1 { s[n / 2] } else { (s[n / 2 - 1] + s[n / 2]) / 2 };
        Ok(TimingStats { median, min: s[0], max: s[n - 1], runs: n })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats_median_even_and_odd() {
        let ms = Duration::from_millis;
        let s = TimingStats::from_samples(&[ms(5), ms(1), ms(3)]).unwrap();
        assert_eq!((s.median, s.min, s.max, s.runs), (ms(3), ms(1), ms(5), 3));
        let s = TimingStats::from_samples(&[ms(4), ms(1), ms(2), ms(8)]).unwrap();
        assert_eq!(s.median, ms(3));
        assert!(TimingStats::from_samples(&[]).is_err());
    }
}
