//! zwarp-core: the plain buffers and conventions every stage of zwarp shares.
//!
//! Conventions (ARCHITECTURE.md "Conventions", kept everywhere):
//! - **Depth** is post-projection depth in `[0, 1]`, 0 = near plane, 1 = far plane. The value
//!   `1.0` also means "no surface" (the paper's `s.z < 1` test for a valid sample). Use
//!   [`Camera::linear_depth`] to get view-space distance.
//! - **Pixels**: pixel `(x, y)` covers `[x, x+1) x [y, y+1)`, its sample point is the centre
//!   `(x + 0.5, y + 0.5)`, row 0 is the top of the image.
//! - **Motion** is in pixels from the source view to the target view: a point at `q` in the
//!   source appears at `q + v(q)` in the target; each motion sample also carries the point's depth
//!   in the target view ([`Motion`]).
//! - **Matrices** are column-major glam types; projections map view-space depth to `[0, 1]`
//!   (`perspective_rh` / `orthographic_rh`).

#![deny(missing_docs)]
pub mod camera;
pub mod error;
pub mod geom;
pub mod image;
pub mod material;
pub mod motion;
pub mod pages;
pub mod round;
pub mod scene;
pub mod simd;

pub use camera::{Camera, Projection};
pub use error::{Error, Result};
pub use geom::Aabb;
pub use image::Image;
pub use material::{linear_to_srgb, srgb_to_linear, ColorMap, Material, MeshPart, Texture, Wrap, DEFAULT_MATERIAL};
pub use motion::{
    check_motion_inputs, motion_field, motion_field_into, motion_field_with, motion_field_with_into,
    motion_planes_into, Motion, ParallaxMotion,
};
pub use scene::{translate_placed, Animation, AreaLight, Instance, LightShape, Mesh, Scene, NO_ITEM};
pub use simd::SimdSwitch;

/// Depth value that means "no surface here" (the far plane).
pub const EMPTY_DEPTH: f32 = 1.0;

/// `true` if a stored depth is a real surface (the paper's `s.z < 1`).
#[inline]
pub fn is_surface(depth: f32) -> bool {
    depth < EMPTY_DEPTH
}
