//! zwarp-scene (being built).
