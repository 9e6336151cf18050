//! The evaluation harness every measuring command goes through, so that a new command inherits
//! the protocol instead of rewriting it (ARCHITECTURE.md "Evaluation protocol", "Timings"):
//!
//! - [`frames`]: which frames of the camera path are evaluated ([`PathFrames::pick`] spreads
//!   them evenly over a range) and the time and camera of each and of its neighbours;
//! - [`timing`]: warm, repeated timing ([`time_repeated`], [`time_into`] for reused output
//!   buffers, [`time_stages`] for work that times its own stages), summarised by [`Timing`];
//! - [`compare`]: the quality of a prediction against the rendered reference, one function per
//!   kind of image ([`compare_color`], [`compare_depth`]) and their means over a row's frames;
//! - rows accumulated over frames in first-seen order ([`entry`]) and the progress bar.

pub mod compare;
pub mod frames;
pub mod timing;

pub use compare::{
    compare_color, compare_depth, mean_depth, mean_finite, mean_quality, DepthComparison, Figures, Quality,
};
pub use frames::{Frame, Lone, PathFrames};
pub use timing::{time_into, time_repeated, time_stages, timing_of, Timing};

/// The accumulator of `key` in `accs`, appended (default) the first time the key is seen, so
/// the rows come out in the order their configurations were first measured.
pub fn entry<K: PartialEq, A: Default>(accs: &mut Vec<(K, A)>, key: K) -> &mut A {
    let i = match accs.iter().position(|(k, _)| *k == key) {
        Some(i) => i,
        None => {
            accs.push((key, A::default()));
            accs.len() - 1
        }
    };
    &mut accs[i].1
}

/// The progress bar of a measuring command (hidden when `show` is false).
pub fn progress(len: u64, msg: String, show: bool) -> indicatif::ProgressBar {
    if !show {
        return indicatif::ProgressBar::hidden();
    }
    let b = indicatif::ProgressBar::new(len);
    b.set_style(
        indicatif::ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} {elapsed}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    b.set_message(msg);
    b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn entries_keep_first_seen_order() {
        let mut accs: Vec<(&str, Vec<u32>)> = Vec::new();
        entry(&mut accs, "b").push(1);
        entry(&mut accs, "a").push(2);
        entry(&mut accs, "b").push(3);
        assert_eq!(accs, vec![("b", vec![1, 3]), ("a", vec![2])]);
    }
}
