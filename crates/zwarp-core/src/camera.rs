//! Cameras: view + projection + image size, and the pixel <-> world mappings every stage uses.

use glam::{Mat4, Vec3, Vec4};
use serde::{Deserialize, Serialize};

use crate::{Error, Result};

/// The projection model of a [`Camera`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Projection {
    /// Perspective with vertical field of view in radians.
    Perspective {
        /// Vertical field of view, radians.
        fov_y: f32,
    },
    /// Orthographic with the half height of the view volume (half width = half height * aspect).
    Orthographic {
        /// Half height of the view volume in world units.
        half_height: f32,
    },
}

/// A camera: column-major view and projection matrices plus the image size it renders.
///
/// The projection maps view-space depth to `[0, 1]` (0 = near, 1 = far; glam's `*_rh`
/// projections), so rendered depth follows the crate-level conventions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// World -> view (right-handed, camera looks down -z).
    pub view: Mat4,
    /// View -> clip.
    pub proj: Mat4,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Near plane distance (> 0).
    pub near: f32,
    /// Far plane distance (> near).
    pub far: f32,
    /// Projection model.
    pub projection: Projection,
}

fn check_common(width: u32, height: u32, near: f32, far: f32) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(Error::invalid(format!("zero-size image {width}x{height}")));
    }
    if !(near.is_finite() && far.is_finite()) || near <= 0.0 || near >= far {
        return Err(Error::invalid(format!("need 0 < near < far, got near={near} far={far}")));
    }
    Ok(())
}

fn look_at(eye: Vec3, target: Vec3, up: Vec3) -> Result<Mat4> {
    let dir = target - eye;
    if !eye.is_finite() || !target.is_finite() || !up.is_finite() {
        return Err(Error::invalid("camera eye/target/up must be finite"));
    }
    if dir.length_squared() < 1e-20 {
        return Err(Error::invalid("camera eye and target coincide"));
    }
    if dir.normalize().cross(up.normalize_or_zero()).length_squared() < 1e-12 {
        return Err(Error::invalid("camera up vector is parallel to the view direction"));
    }
    Ok(Mat4::look_at_rh(eye, target, up))
}

impl Camera {
    /// A perspective camera looking from `eye` at `target`.
    #[allow(clippy::too_many_arguments)]
    pub fn perspective(
        eye: Vec3,
        target: Vec3,
        up: Vec3,
        fov_y: f32,
        near: f32,
        far: f32,
        width: u32,
        height: u32,
    ) -> Result<Self> {
        check_common(width, height, near, far)?;
        if !(fov_y > 0.0 && fov_y < std::f32::consts::PI) {
            return Err(Error::invalid(format!(
                "field of view must be in (0, 180) degrees, got {} deg",
                fov_y.to_degrees()
            )));
        }
        let view = look_at(eye, target, up)?;
        let proj = Mat4::perspective_rh(fov_y, width as f32 / height as f32, near, far);
        Ok(Camera { view, proj, width, height, near, far, projection: Projection::Perspective { fov_y } })
    }

    /// An orthographic camera looking from `eye` at `target`; the view volume is
    /// `2 * half_height` tall and `near..far` deep.
    #[allow(clippy::too_many_arguments)]
    pub fn orthographic(
        eye: Vec3,
        target: Vec3,
        up: Vec3,
        half_height: f32,
        near: f32,
        far: f32,
        width: u32,
        height: u32,
    ) -> Result<Self> {
        if !(half_height > 0.0 && half_height.is_finite()) {
            return Err(Error::invalid("orthographic half height must be positive"));
        }
        if width == 0 || height == 0 {
            return Err(Error::invalid(format!("zero-size image {width}x{height}")));
        }
        if !(near.is_finite() && far.is_finite()) || near >= far {
            return Err(Error::invalid(format!("need near < far, got near={near} far={far}")));
        }
        let view = look_at(eye, target, up)?;
        let hw = half_height * width as f32 / height as f32;
        let proj = Mat4::orthographic_rh(-hw, hw, -half_height, half_height, near, far);
        Ok(Camera { view, proj, width, height, near, far, projection: Projection::Orthographic { half_height } })
    }

    /// The same camera rendering at another image size (projection keeps its field of view).
    pub fn with_size(&self, width: u32, height: u32) -> Result<Self> {
        check_common(width, height, self.near.max(f32::MIN_POSITIVE), self.far)?;
        let aspect = width as f32 / height as f32;
        let proj = match self.projection {
            Projection::Perspective { fov_y } => Mat4::perspective_rh(fov_y, aspect, self.near, self.far),
            Projection::Orthographic { half_height } => {
                let hw = half_height * aspect;
                Mat4::orthographic_rh(-hw, hw, -half_height, half_height, self.near, self.far)
            }
        };
        Ok(Camera { proj, width, height, ..*self })
    }

    /// `proj * view`.
    #[inline]
    pub fn view_proj(&self) -> Mat4 {
        self.proj * self.view
    }

    /// World-space eye position.
    pub fn eye(&self) -> Vec3 {
        self.view.inverse().w_axis.truncate()
    }

    /// Maps NDC x/y (in `[-1, 1]`, y up) to continuous pixel coordinates (row 0 at the top).
    #[inline]
    pub fn ndc_to_pixel(&self, ndc_x: f32, ndc_y: f32) -> (f32, f32) {
        ((ndc_x + 1.0) * 0.5 * self.width as f32, (1.0 - ndc_y) * 0.5 * self.height as f32)
    }

    /// Maps continuous pixel coordinates to NDC x/y.
    #[inline]
    pub fn pixel_to_ndc(&self, px: f32, py: f32) -> (f32, f32) {
        (px / self.width as f32 * 2.0 - 1.0, 1.0 - py / self.height as f32 * 2.0)
    }

    /// Projects a world point to `(pixel x, pixel y, depth)`; `None` if it is behind the eye
    /// (clip w <= 0). The depth is not clamped: values outside `[0, 1]` are outside near/far.
    #[inline]
    pub fn project(&self, world: Vec3) -> Option<Vec3> {
        project_with(&self.view_proj(), self.width, self.height, world)
    }

    /// Unprojects continuous pixel coordinates and a stored depth to a world point.
    #[inline]
    pub fn unproject(&self, px: f32, py: f32, depth: f32) -> Vec3 {
        unproject_with(&self.view_proj().inverse(), self.width, self.height, px, py, depth)
    }

    /// Linear view-space distance (along the view axis) of a stored depth value.
    #[inline]
    pub fn linear_depth(&self, depth: f32) -> f32 {
        let perspective = matches!(self.projection, Projection::Perspective { .. });
        linear_depth_of(perspective, self.near, self.far, depth)
    }

    /// Inverse of [`Camera::linear_depth`]: stored depth of a view-space distance.
    #[inline]
    pub fn stored_depth(&self, linear: f32) -> f32 {
        match self.projection {
            Projection::Perspective { .. } => {
                let (n, f) = (self.near, self.far);
                f * (linear - n) / ((f - n) * linear)
            }
            Projection::Orthographic { .. } => (linear - self.near) / (self.far - self.near),
        }
    }
}

/// Projects `world` with a precomputed view-projection matrix (hot-loop form of
/// [`Camera::project`]).
#[inline]
pub fn project_with(view_proj: &Mat4, width: u32, height: u32, world: Vec3) -> Option<Vec3> {
    let c = *view_proj * world.extend(1.0);
    if c.w <= 0.0 {
        return None;
    }
    let inv_w = 1.0 / c.w;
    let (nx, ny, nz) = (c.x * inv_w, c.y * inv_w, c.z * inv_w);
    Some(Vec3::new((nx + 1.0) * 0.5 * width as f32, (1.0 - ny) * 0.5 * height as f32, nz))
}

/// Unprojects pixel coordinates + depth with a precomputed inverse view-projection matrix
/// (hot-loop form of [`Camera::unproject`]).
#[inline]
pub fn unproject_with(inv_view_proj: &Mat4, width: u32, height: u32, px: f32, py: f32, depth: f32) -> Vec3 {
    let nx = px / width as f32 * 2.0 - 1.0;
    let ny = 1.0 - py / height as f32 * 2.0;
    let p: Vec4 = *inv_view_proj * Vec4::new(nx, ny, depth, 1.0);
    p.truncate() / p.w
}

/// [`Camera::linear_depth`] of a view with planes `near`, `far` and a perspective (`true`) or
/// orthographic projection: the one formula, also `ParallaxMotion`'s.
#[inline]
pub fn linear_depth_of(perspective: bool, near: f32, far: f32, depth: f32) -> f32 {
    let (n, f) = (near, far);
    if perspective {
        f * n / (f - depth * (f - n))
    } else {
        n + depth * (f - n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn project_unproject_roundtrip_and_linear_depth() {
        let cam = Camera::perspective(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y, 1.0, 0.1, 100.0, 64, 48).unwrap();
        let p = Vec3::new(0.3, -0.2, 1.0);
        let s = cam.project(p).unwrap();
        let back = cam.unproject(s.x, s.y, s.z);
        assert!((back - p).length() < 1e-4);
        assert!((cam.linear_depth(s.z) - 4.0).abs() < 1e-3);
        assert!((cam.stored_depth(4.0) - s.z).abs() < 1e-6);
        // Centre of view maps to the image centre.
        let c = cam.project(Vec3::ZERO).unwrap();
        assert!((c.x - 32.0).abs() < 1e-4 && (c.y - 24.0).abs() < 1e-4);
        assert_eq!(cam.linear_depth(0.0), 0.1);
        assert!((cam.linear_depth(1.0) - 100.0).abs() < 1e-2, "f32 rounding of f - (f - n)");
    }

    #[test]
    fn rejects_bad_cameras() {
        assert!(Camera::perspective(Vec3::Z, Vec3::ZERO, Vec3::Y, 1.0, 1.0, 1.0, 4, 4).is_err());
        assert!(Camera::perspective(Vec3::Z, Vec3::ZERO, Vec3::Y, 1.0, 0.1, 10.0, 0, 4).is_err());
        assert!(Camera::perspective(Vec3::Z, Vec3::ZERO, Vec3::Z, 1.0, 0.1, 10.0, 4, 4).is_err());
        assert!(Camera::perspective(Vec3::Z, Vec3::Z, Vec3::Y, 1.0, 0.1, 10.0, 4, 4).is_err());
    }
}
