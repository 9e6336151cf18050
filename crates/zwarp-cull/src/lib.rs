//! zwarp-cull: warping-based occlusion culling (WOC, seed 000 Sec. 5; thesis seed 002).
//!
//! The building blocks, usable on their own with any depth buffer:
//! - [`bounds`]: the objects' world boxes kept across frames (static ones stored once);
//! - [`frustum`]: view-frustum culling (VFC) of world AABBs, the first test of WOC;
//! - [`screen`]: screen-space bounds (pixel rectangle + nearest depth) of an AABB proxy;
//! - [`maxdepth`]: max-depth structures answering `is_occluded(rect, nearest)` — max mipmap
//!   (HOM), N-buffers (exact) and Y-maps — plus the 1-pixel erosion of the thesis;
//! - [`mod@woc`]: the per-frame WOC pipeline (motion, single-layer warp, erosion, rapid-motion
//!   objects, max-depth test, hybrid query) and the baselines NOCULL, VFC, last-frame depth,
//!   two-phase, REF and the ideal screen-space test, plus the culling-accuracy figures;
//! - [`sequence`]: runs a method along a camera path (cull, draw the visible set, feed it to
//!   the next frame) with REF rendered side by side, for the evaluation tables;
//! - `gpu` (feature `gpu`): the WGSL twins of the max-depth structures, the cull, the WOC
//!   pipeline and the sequences on a `zwarp_gpu::GpuContext`.
//!
//! Depth follows the zwarp convention: post-projection depth in `[0, 1]`, 0 = near, 1 = far
//! and "no surface"; holes of a warped buffer are kept at 1 and never occlude.

#![deny(missing_docs)]

pub mod bounds;
pub mod diagnose;
pub mod frustum;
#[cfg(feature = "gpu")]
pub mod gpu;
pub mod holebound;
pub mod maxdepth;
pub mod objects;
pub mod screen;
pub mod sequence;
pub mod woc;

/// The AVX2 builds of this crate (VFC's eight-box test, the coarse reduction of the previous
/// frame): on where the CPU has AVX2.
pub(crate) static AVX2: zwarp_core::SimdSwitch = zwarp_core::SimdSwitch::avx2();

/// Enables (default) or disables this crate's AVX2 builds ([`Frustum::intersects8`], WOC's coarse
/// reduction of the previous frame). Results are bit-identical either way; this exists for tests
/// and for timing the portable builds.
#[doc(hidden)]
pub fn set_simd(enabled: bool) {
    AVX2.set(enabled);
}

/// Held by the tests that flip [`set_simd`], so that each compares the two builds it means to.
#[cfg(test)]
pub(crate) static SIMD_TEST_LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());

pub use bounds::ObjectBounds;
pub use diagnose::{culled_visible, CulledVisible};
pub use frustum::{vfc, Frustum};
pub use holebound::{bound_far_pixels, StaticRays};
pub use maxdepth::{
    erode_max, max_in_rect, reduce_max_2x2, MaxDepthKind, MaxDepthMap, MaxDepthQuery, MaxMipmap, NBuffer, YMap,
};
pub use objects::{object_screen_speed, BoxObject, CullObjects, SceneObjects};
pub use screen::{
    hull_of_corners, hull_x_range_in_strip, project_corner_lanes, project_corners, rect_of_corners, screen_hull_with,
    screen_rect, screen_rect_with, square_meets_hull, CornerLanes, PixelRect, ScreenRect,
};
pub use sequence::{run_sequence, run_sequence_repeated, summarize, FrameReport, MapAccuracy, Method, SequenceSummary};
pub use woc::{
    aabb_triangles, accuracy, coarse_camera, cull_against_depth, cull_against_depth_with, downsample_max, hybrid_cull,
    ideal_screen_space, lastframe, max_over_footprints, nocull, open_rims_in_target, opening_rim_dirs, opening_rims,
    reference, screen_speed, twophase, twophase_with, vfc_cull, vfc_cull_with, visible_from_items, woc,
    woc_motion_field, woc_objects, woc_with, CullAccuracy, CullResult, CullStats, CullTimings, PrevFrame, RimMode,
    TwoPhaseResult, WocParams, DEPTH_TOLERANCE, HOLE_BOUND_RADIUS, HULL_TEST_MAX_AREA, MAX_DOWNSAMPLE, NEIGHBOURS,
    RIM_MARGIN,
};
