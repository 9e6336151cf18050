//! One file per `zwarp` command.

pub mod blur;
pub mod colorwarp;
pub mod cull;
pub mod demo;
pub mod eval;
pub mod info;
pub mod render;
pub mod report;
pub mod shadows;
pub mod stereo;
pub mod upsample;
pub mod vr;
