//! One file per `zwarp` command.

pub mod cull;
pub mod demo;
pub mod eval;
pub mod info;
pub mod render;
pub mod shadows;
