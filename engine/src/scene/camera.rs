//! Pinhole cameras in one convention, converted to at the loaders and never in shaders.
//!
//! Camera space is OpenCV's: +X right, +Y down, +Z forward. A world point `p` maps to camera
//! space as `q = R p + t` and to continuous pixel coordinates as
//! `(fx q.x / q.z + cx, fy q.y / q.z + cy)`, where the centre of pixel (i, j) is (i + ½, j + ½)
//! (COLMAP's convention). World space is right-handed, +Y up, in metres.

use glam::{Mat3, Vec2, Vec3};

#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    pub width: u32,
    pub height: u32,
    pub fx: f32,
    pub fy: f32,
    pub cx: f32,
    pub cy: f32,
    /// World-to-camera rotation `R`.
    pub rotation: Mat3,
    /// World-to-camera translation `t`.
    pub translation: Vec3,
}

/// The camera as shaders read it (`common/camera.glsl`): rows of [R | t], intrinsics, and
/// (width, height, near, far).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuCamera {
    pub r0: [f32; 4],
    pub r1: [f32; 4],
    pub r2: [f32; 4],
    pub intrinsics: [f32; 4],
    pub size_clip: [f32; 4],
}

impl Camera {
    /// A camera at `position` looking at `target`, `up` being world-space up.
    pub fn look_at(
        position: Vec3,
        target: Vec3,
        up: Vec3,
        width: u32,
        height: u32,
        fx: f32,
    ) -> Camera {
        let z = (target - position).normalize();
        let x = z.cross(up).normalize();
        let y = z.cross(x);
        Camera::from_camera_to_world(Mat3::from_cols(x, y, z), position, width, height, fx, fx)
    }

    /// From the camera's axes in world space (columns: right, down, forward) and its centre.
    pub fn from_camera_to_world(
        axes: Mat3,
        position: Vec3,
        width: u32,
        height: u32,
        fx: f32,
        fy: f32,
    ) -> Camera {
        let rotation = axes.transpose();
        Camera {
            width,
            height,
            fx,
            fy,
            cx: width as f32 * 0.5,
            cy: height as f32 * 0.5,
            rotation,
            translation: -(rotation * position),
        }
    }

    /// Camera centre in world space.
    pub fn center(&self) -> Vec3 {
        -(self.rotation.transpose() * self.translation)
    }

    pub fn to_camera(&self, p: Vec3) -> Vec3 {
        self.rotation * p + self.translation
    }

    /// Continuous pixel coordinates and camera depth of `p`; `None` behind the camera.
    pub fn project(&self, p: Vec3) -> Option<(Vec2, f32)> {
        let q = self.to_camera(p);
        (q.z > 1e-6).then(|| {
            (
                Vec2::new(self.fx * q.x / q.z + self.cx, self.fy * q.y / q.z + self.cy),
                q.z,
            )
        })
    }

    /// World-space direction through continuous pixel coordinates `px` (z component 1 in
    /// camera space, so `t` along it is camera depth).
    pub fn ray_dir(&self, px: Vec2) -> Vec3 {
        let d = Vec3::new((px.x - self.cx) / self.fx, (px.y - self.cy) / self.fy, 1.0);
        self.rotation.transpose() * d
    }

    pub fn to_gpu(&self, near: f32, far: f32) -> GpuCamera {
        let r = self.rotation;
        let t = self.translation;
        GpuCamera {
            r0: [r.x_axis.x, r.y_axis.x, r.z_axis.x, t.x],
            r1: [r.x_axis.y, r.y_axis.y, r.z_axis.y, t.y],
            r2: [r.x_axis.z, r.y_axis.z, r.z_axis.z, t.z],
            intrinsics: [self.fx, self.fy, self.cx, self.cy],
            size_clip: [self.width as f32, self.height as f32, near, far],
        }
    }

    /// Checks the values a loader produced; `what` names the camera in the message.
    pub fn validate(&self) -> Result<(), String> {
        if self.width == 0 || self.height == 0 {
            return Err(format!(
                "image size {}x{}: width and height must be positive",
                self.width, self.height
            ));
        }
        if self.width > crate::scene::MAX_IMAGE_DIM || self.height > crate::scene::MAX_IMAGE_DIM {
            return Err(format!(
                "image size {}x{} exceeds the {} pixel limit per side",
                self.width,
                self.height,
                crate::scene::MAX_IMAGE_DIM
            ));
        }
        for (n, v) in [("fx", self.fx), ("fy", self.fy)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!(
                    "focal length {n} = {v}; expected a positive finite number"
                ));
            }
        }
        for (n, v) in [("cx", self.cx), ("cy", self.cy)] {
            if !v.is_finite() {
                return Err(format!(
                    "principal point {n} = {v}; expected a finite number"
                ));
            }
        }
        let r = self.rotation;
        if !r.to_cols_array().iter().all(|v| v.is_finite()) || !self.translation.is_finite() {
            return Err("pose has non-finite values".into());
        }
        let ortho = (r * r.transpose() - Mat3::IDENTITY)
            .to_cols_array()
            .iter()
            .fold(0f32, |m, v| m.max(v.abs()));
        if ortho > 1e-3 || (r.determinant() - 1.0).abs() > 1e-3 {
            return Err(format!(
                "rotation is not a proper rotation (|R Rᵀ - I| = {ortho:.2e}, det = {:.4})",
                r.determinant()
            ));
        }
        Ok(())
    }
}
