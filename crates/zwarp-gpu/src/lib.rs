//! zwarp-gpu (being built).
