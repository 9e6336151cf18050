//! Helpers shared by the measurement and diagnostic programs of `src/bin/` (one program per
//! file, usage in each file's docs: `cargo run --release -p zwarp-tools --bin NAME -- ARGS`).

#![deny(missing_docs)]

pub mod common;
