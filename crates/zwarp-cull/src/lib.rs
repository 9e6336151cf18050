//! zwarp-cull: warping-based occlusion culling (WOC, seed 000 Sec. 5; thesis seed 002).
//!
//! The building blocks, usable on their own with any depth buffer:
//! - [`frustum`]: view-frustum culling (VFC) of world AABBs, the first test of WOC;
//! - [`screen`]: screen-space bounds (pixel rectangle + nearest depth) of an AABB proxy;
//! - [`maxdepth`]: max-depth structures answering `is_occluded(rect, nearest)` — max mipmap
//!   (HOM), N-buffers (exact) and Y-maps — plus the 1-pixel erosion of the thesis.
//!
//! Depth follows the zwarp convention: post-projection depth in `[0, 1]`, 0 = near, 1 = far
//! and "no surface"; holes of a warped buffer are kept at 1 and never occlude.

pub mod frustum;
pub mod maxdepth;
pub mod screen;

pub use frustum::{vfc, Frustum};
pub use maxdepth::{
    erode_max, max_in_rect, reduce_max_2x2, MaxDepthKind, MaxDepthMap, MaxDepthQuery, MaxMipmap, NBuffer, YMap,
};
pub use screen::{screen_rect, screen_rect_with, PixelRect, ScreenRect};
