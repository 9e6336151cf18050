//! zwarp-metrics (being built).
