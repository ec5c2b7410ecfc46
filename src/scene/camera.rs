//! Pinhole camera. Convention (a contract): pixel (i, j), i to the right, j = 0 the
//! top row; the ray passes through film point ((i + 0.5) / W, (j + 0.5) / H); vfov
//! spans the image height; directions are unit length so t is a distance.
//! GLSL twin: `camera_ray` in shaders/common/camera.glsl.

use glam::Vec3;

/// Where the camera is and where it looks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    pub eye: Vec3,
    pub look_at: Vec3,
    pub up: Vec3,
    /// Vertical field of view in degrees, spanning the image height.
    pub vfov: f32,
}

/// The orthonormal frame the kernels use.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraBasis {
    pub eye: Vec3,
    pub right: Vec3,
    pub up: Vec3,
    pub forward: Vec3,
    pub tan_half: f32,
    pub aspect: f32,
}

impl Camera {
    /// Checks the camera can form a frame; returns what is wrong otherwise.
    pub fn check(&self) -> Result<(), String> {
        if !(self.eye.is_finite() && self.look_at.is_finite() && self.up.is_finite() && self.vfov.is_finite()) {
            return Err("camera has a non-finite value".into());
        }
        if !(self.vfov > 0.0 && self.vfov < 180.0) {
            return Err(format!("camera vfov must be in (0, 180) degrees, got {}", self.vfov));
        }
        let f = self.look_at - self.eye;
        if f.length_squared() == 0.0 || !f.normalize().is_finite() {
            return Err("camera eye and look_at are the same point".into());
        }
        if f.normalize().cross(self.up).length_squared() < 1e-12 {
            return Err("camera up is parallel to the view direction".into());
        }
        Ok(())
    }

    /// The frame for an image of `width` x `height`.
    pub fn basis(&self, width: u32, height: u32) -> CameraBasis {
        let forward = (self.look_at - self.eye).normalize();
        let right = forward.cross(self.up).normalize();
        let up = right.cross(forward);
        CameraBasis {
            eye: self.eye,
            right,
            up,
            forward,
            tan_half: (self.vfov.to_radians() * 0.5).tan(),
            aspect: width as f32 / height as f32,
        }
    }
}

impl CameraBasis {
    /// The unit direction through film offset (fx, fy) in pixel (i, j) of a W x H
    /// image; (0.5, 0.5) is the pixel centre.
    pub fn ray_dir(&self, i: u32, j: u32, fx: f32, fy: f32, width: u32, height: u32) -> Vec3 {
        let x = (2.0 * ((i as f32 + fx) / width as f32) - 1.0) * self.tan_half * self.aspect;
        let y = (1.0 - 2.0 * ((j as f32 + fy) / height as f32)) * self.tan_half;
        let d = self.forward + self.right * x + self.up * y;
        d / d.length()
    }
}
