//! zwarp-shadows (being built).
