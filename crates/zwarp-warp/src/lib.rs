//! zwarp-warp (being built).
