//! zwarp-viz: the images a person looks at when judging a warp (the last stage of the data flow
//! in ARCHITECTURE.md: "reports (tables, JSON, images)").
//!
//! - Colour maps ([`colormap`]): depth ([`depth_to_rgb8`], turbo on linear depth), item ids
//!   ([`items_to_rgb8`]), motion ([`motion_to_rgb8`], Middlebury flow wheel), linear colour
//!   ([`color_to_rgb8`], sRGB), signed depth differences ([`diff_heatmap`], the culling-safety
//!   split of seed 002 Sec. V.1: red = predicted nearer = unsafe), masks ([`mask_to_rgb8`]),
//!   scalar maps such as SSIM maps ([`scalar_to_rgb8`]).
//! - Layout ([`side_by_side`], [`stacked`], [`labelled`], [`fit_width`]): panels in a row with
//!   a 4-pixel gap, like the paper figures (seed 000 Fig. 1: source, warped, reference,
//!   difference), each with its label above and its legend below.
//! - Figures ([`figure`]): labelled depth and error panels with their colour bars, and strips
//!   of them in one PNG.
//! - Legends ([`legend`]): colour bars with their range in metres ([`depth_colorbar`],
//!   [`diff_colorbar`]); text from an 8x8 bitmap font ([`text`]).
//! - Files ([`io`]): PNG (8-bit RGB / gray) and OpenEXR (f32 depth, RGB, motion with channels
//!   `vx`, `vy`, `depth`) writers plus readers for round trips. Errors are
//!   [`zwarp_core::Error::Io`] / [`zwarp_core::Error::Parse`] naming the file.

#![deny(missing_docs)]
pub mod colormap;
pub mod figure;
pub mod io;
pub mod layout;
pub mod legend;
pub mod text;

pub use colormap::{
    color_to_rgb8, depth_range, depth_scale_is_log, depth_to_rgb8, depth_to_rgb8_in_range, depth_to_rgb8_scaled,
    diff_heatmap, heat_color, items_to_rgb8, linear_to_srgb8, mask_to_rgb8, motion_to_rgb8, scalar_to_rgb8, turbo,
    DEPTH_TURBO_MIN, FLOW_WHEEL, LOG_DEPTH_RATIO,
};
pub use figure::{depth_panel, diff_panel, strip};
pub use io::{
    read_exr_f32, read_exr_motion, read_exr_rgb, read_png, write_exr_f32, write_exr_motion, write_exr_rgb, write_png,
    write_png_gray,
};
pub use layout::{fit_width, labelled, side_by_side, stacked, GAP, GAP_COLOR};
pub use legend::{colorbar, depth_colorbar, diff_colorbar, metres};
pub use text::{draw_text, text_size};
