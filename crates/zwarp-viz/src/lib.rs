//! zwarp-viz (being built).
