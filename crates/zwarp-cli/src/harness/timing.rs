//! Warm, repeated timing (ARCHITECTURE.md "Timings"): every measurement runs once untimed (first
//! use allocates buffers, fills caches and compiles GPU kernels), then `reps` times timed; the
//! rows report the median and spread of the samples through [`Timing`].

use std::time::Instant;

use anyhow::Result;

pub use zwarp_metrics::Timing;

/// One untimed run of `f`, then `reps` (at least 1) timed ones; `sample` turns each timed run's
/// output and wall-clock time (ms) into its sample. Returns the last output and the samples.
fn repeat<T, S>(reps: usize, mut f: impl FnMut() -> Result<T>, sample: impl Fn(&T, f64) -> S) -> Result<(T, Vec<S>)> {
    let mut out = f()?;
    let mut samples = Vec::with_capacity(reps.max(1));
    for _ in 0..reps.max(1) {
        let t0 = Instant::now();
        out = f()?;
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        samples.push(sample(&out, ms));
    }
    Ok((out, samples))
}

/// Times `f` `reps` times after one warm-up run; returns the last result and the samples (ms).
pub fn time_repeated<T>(reps: usize, f: impl FnMut() -> Result<T>) -> Result<(T, Vec<f64>)> {
    repeat(reps, f, |_, ms| ms)
}

/// [`time_repeated`] for work that writes into `slot`, whose buffers carry over from run to run
/// (an engine keeps its output buffers across frames, and so does the next measurement through
/// the same slot); returns a copy of the last output and the samples.
pub fn time_into<S: Clone>(
    reps: usize,
    slot: &mut S,
    mut f: impl FnMut(&mut S) -> Result<()>,
) -> Result<(S, Vec<f64>)> {
    let (_, samples) = repeat(reps, || f(slot), |_, ms| ms)?;
    Ok((slot.clone(), samples))
}

/// [`time_repeated`] for work that times its own stages: each timed run's sample is what
/// `stages` reads from its output (the stage times measured inside the work, not the wall clock
/// around it).
pub fn time_stages<T, S>(reps: usize, f: impl FnMut() -> Result<T>, stages: impl Fn(&T) -> S) -> Result<(T, Vec<S>)> {
    repeat(reps, f, |out, _| stages(out))
}

/// The [`Timing`] of one field of per-stage or per-frame samples.
pub fn timing_of<S>(samples: &[S], field: impl Fn(&S) -> f64) -> Timing {
    Timing::of(&samples.iter().map(field).collect::<Vec<_>>())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_warm_up_then_the_timed_runs() {
        let mut calls = 0;
        let (last, samples) = time_repeated(3, || {
            calls += 1;
            Ok(calls)
        })
        .unwrap();
        assert_eq!((calls, last, samples.len()), (4, 4, 3));
        // At least one timed run, whatever `reps` says.
        assert_eq!(time_repeated(0, || Ok(())).unwrap().1.len(), 1);
    }

    #[test]
    fn the_slot_keeps_its_buffers_and_the_last_output_is_copied() {
        let mut slot = Vec::new();
        let (last, samples) = time_into(2, &mut slot, |s: &mut Vec<u32>| {
            s.push(s.len() as u32);
            Ok(())
        })
        .unwrap();
        assert_eq!((&last, samples.len()), (&vec![0, 1, 2], 2));
        assert_eq!(slot, last);
    }

    #[test]
    fn stage_samples_come_from_the_outputs() {
        let mut n = 0.0;
        let (last, stages) = time_stages(
            2,
            || {
                n += 1.0;
                Ok((n, 10.0 * n))
            },
            |o| o.1,
        )
        .unwrap();
        assert_eq!((last, stages), ((3.0, 30.0), vec![20.0, 30.0]));
        assert_eq!(timing_of(&[(1.0, 5.0), (2.0, 7.0)], |s| s.1).median, 6.0);
    }
}
