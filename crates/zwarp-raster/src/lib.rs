//! zwarp-raster (being built).
