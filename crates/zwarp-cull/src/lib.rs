//! zwarp-cull (being built).
