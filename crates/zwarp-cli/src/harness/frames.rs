//! Which frames of the camera path a command evaluates, and the time and camera of each frame
//! and of its neighbours.

use std::ops::RangeInclusive;

use anyhow::{bail, Result};
use zwarp_core::Camera;
use zwarp_scene::CameraPath;

/// Where a single frame (a count of 1) sits in the range it is picked from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lone {
    /// The first frame of the range.
    First,
    /// The middle frame (the lower one of two).
    Middle,
}

/// `count` frame indices spread evenly over `range` (both ends when `count > 1`), at most one
/// per frame of the range; a single one where `lone` says. Empty for an empty range.
pub fn spread(count: usize, range: RangeInclusive<usize>, lone: Lone) -> Vec<usize> {
    let (lo, hi) = (*range.start(), *range.end());
    if hi < lo {
        return Vec::new();
    }
    let count = count.min(hi - lo + 1);
    (0..count)
        .map(|i| match (count, lone) {
            (1, Lone::First) => lo,
            (1, Lone::Middle) => lo + (hi - lo) / 2,
            _ => lo + i * (hi - lo) / (count - 1),
        })
        .collect()
}

/// One frame of the path: its index, scene time and camera.
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    /// Index along the path at the speed of its [`PathFrames`].
    pub k: usize,
    /// Scene time (s).
    pub t: f32,
    /// The camera at `t`.
    pub cam: Camera,
}

/// The frames of a camera path at one motion speed and image size.
pub struct PathFrames<'p> {
    path: &'p CameraPath,
    speed: f32,
    width: u32,
    height: u32,
    /// Times held at the path's end, as [`CameraPath::frames`] gives them (the culling and
    /// shadow commands, which take their frames from there); otherwise frame `k` is at
    /// `time_of_frame(k)`, a hair past the end for the last frame at some speeds.
    held_at_end: bool,
}

impl<'p> PathFrames<'p> {
    /// The frames of `path` at `speed` (frame `k` at time `k * speed / fps`) seen at
    /// `width` x `height`.
    pub fn new(path: &'p CameraPath, speed: f32, width: u32, height: u32) -> Self {
        PathFrames { path, speed, width, height, held_at_end: false }
    }

    /// The same frames with their times held at the path's end ([`CameraPath::frames`]).
    pub fn held_at_end(self) -> Self {
        PathFrames { held_at_end: true, ..self }
    }

    /// Frames on the path at this speed.
    pub fn total(&self) -> usize {
        self.path.frame_count_at(self.speed)
    }

    /// The path's total frame count, or the error `too_short(total)` when it has fewer than
    /// `need` (each command words what it needs the frames for).
    pub fn require(&self, need: usize, too_short: impl FnOnce(usize) -> String) -> Result<usize> {
        let total = self.total();
        if total < need {
            bail!("{}", too_short(total));
        }
        Ok(total)
    }

    /// Frame `k`.
    pub fn frame(&self, k: usize) -> Result<Frame> {
        let t = self.path.time_of_frame(k, self.speed);
        let t = if self.held_at_end { t.min(self.path.end()) } else { t };
        Ok(Frame { k, t, cam: self.camera(t)? })
    }

    /// The frame before `f`.
    pub fn previous(&self, f: &Frame) -> Result<Frame> {
        self.frame(f.k - 1)
    }

    /// The frame after `f`.
    pub fn next(&self, f: &Frame) -> Result<Frame> {
        self.frame(f.k + 1)
    }

    /// The camera of the path at any time `t` (between frames, too), at this image size.
    pub fn camera(&self, t: f32) -> Result<Camera> {
        Ok(self.path.camera_at(t, self.width, self.height)?)
    }

    /// [`spread`] `count` frames over `range`.
    pub fn pick(&self, count: usize, range: RangeInclusive<usize>, lone: Lone) -> Result<Vec<Frame>> {
        spread(count, range, lone).into_iter().map(|k| self.frame(k)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spread_covers_both_ends_and_clamps_the_count() {
        assert_eq!(spread(3, 0..=10, Lone::First), vec![0, 5, 10]);
        assert_eq!(spread(4, 2..=8, Lone::Middle), vec![2, 4, 6, 8]);
        assert_eq!(spread(9, 1..=3, Lone::Middle), vec![1, 2, 3]);
        assert_eq!(spread(5, 0..=4, Lone::First), vec![0, 1, 2, 3, 4]);
    }

    #[test]
    fn a_lone_frame_sits_where_asked() {
        assert_eq!(spread(1, 0..=10, Lone::First), vec![0]);
        assert_eq!(spread(1, 1..=10, Lone::Middle), vec![5]);
        assert_eq!(spread(1, 4..=4, Lone::Middle), vec![4]);
        #[allow(clippy::reversed_empty_ranges)]
        let empty = 3..=2;
        assert!(spread(2, empty, Lone::First).is_empty());
    }

    #[test]
    fn frames_follow_the_path() {
        let path = CameraPath::default_for(&zwarp_core::Scene::default());
        let frames = PathFrames::new(&path, 1.0, 32, 16);
        let total = frames.require(2, |n| format!("{n}")).unwrap();
        assert_eq!(total, path.frame_count());
        let f = frames.frame(3).unwrap();
        assert_eq!((f.k, f.t), (3, path.time_of_frame(3, 1.0)));
        assert_eq!(frames.next(&f).unwrap().k, 4);
        assert_eq!(frames.previous(&f).unwrap().k, 2);
        assert_eq!(
            frames.require(total + 1, |n| format!("only {n}")).unwrap_err().to_string(),
            format!("only {total}")
        );
        let late = PathFrames::new(&path, 1.0, 32, 16).held_at_end().frame(total + 5).unwrap();
        assert_eq!(late.t, path.end());
    }
}
