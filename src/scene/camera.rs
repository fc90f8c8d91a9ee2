use glam::DVec3;

/// Pinhole camera of README, Conventions: `fov_y_deg` is the full vertical field of
/// view, pixels are square, the image plane is spanned by `r = f × up` and
/// `u = r × f`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Camera {
    pub eye: DVec3,
    pub target: DVec3,
    pub up: DVec3,
    pub fov_y_deg: f64,
    pub near: f64,
    pub far: f64,
}

/// The camera's orthonormal frame and image-plane scale for one resolution:
/// everything a ray generator needs, precomputed once.
#[derive(Clone, Copy, Debug)]
pub struct CameraFrame {
    /// Unit view direction.
    pub forward: DVec3,
    /// Unit right vector (`forward × up`, normalised).
    pub right: DVec3,
    /// Unit up vector of the image (`right × forward`).
    pub up: DVec3,
    /// `tan(fov_y / 2)`.
    pub tan_half_fov: f64,
    /// Width over height.
    pub aspect: f64,
    pub width: u32,
    pub height: u32,
}

impl Camera {
    pub(crate) fn validate(&self) -> Result<(), String> {
        let finite = self.eye.is_finite() && self.target.is_finite() && self.up.is_finite();
        if !finite {
            return Err("`camera.eye`, `camera.target` and `camera.up` must be finite".into());
        }
        let forward = self.target - self.eye;
        if forward.length_squared() == 0.0 {
            return Err(format!(
                "`camera.eye` equals `camera.target` ({}): the view direction is undefined",
                self.eye
            ));
        }
        if self.up.length_squared() == 0.0 {
            return Err(
                "`camera.up` is the zero vector: it must give the image's up direction".into(),
            );
        }
        if forward.normalize().cross(self.up.normalize()).length() <= 1e3 * f64::EPSILON {
            return Err(format!(
                "`camera.up` {} is parallel to the view direction {}",
                self.up,
                forward.normalize()
            ));
        }
        if !(self.fov_y_deg > 0.0 && self.fov_y_deg < 180.0) {
            return Err(format!(
                "`camera.fov_y_deg` must be in (0, 180), got {}",
                self.fov_y_deg
            ));
        }
        if !(self.near > 0.0 && self.far > self.near && self.far.is_finite()) {
            return Err(format!(
                "`camera.near`/`camera.far`: need 0 < near < far < inf, got near {} far {}",
                self.near, self.far
            ));
        }
        Ok(())
    }

    /// The frame for an image of `resolution` pixels.
    pub fn frame(&self, resolution: [u32; 2]) -> CameraFrame {
        let forward = (self.target - self.eye).normalize();
        let right = forward.cross(self.up).normalize();
        let up = right.cross(forward);
        CameraFrame {
            forward,
            right,
            up,
            tan_half_fov: (self.fov_y_deg.to_radians() * 0.5).tan(),
            aspect: resolution[0] as f64 / resolution[1] as f64,
            width: resolution[0],
            height: resolution[1],
        }
    }
}

impl CameraFrame {
    /// Unnormalised ray direction through the image point (`px`, `py`) in
    /// pixel units (pixel centre of (x, y) = (x + 0.5, y + 0.5)). It is affine
    /// in the pixel coordinates, which makes its derivatives constant
    /// ([`Self::direction_dx`], [`Self::direction_dy`]).
    pub fn direction(&self, px: f64, py: f64) -> DVec3 {
        let ndc_x = 2.0 * px / self.width as f64 - 1.0;
        let ndc_y = 1.0 - 2.0 * py / self.height as f64;
        self.forward
            + self.right * (ndc_x * self.tan_half_fov * self.aspect)
            + self.up * (ndc_y * self.tan_half_fov)
    }

    /// d(direction)/dx per pixel.
    pub fn direction_dx(&self) -> DVec3 {
        // d ndc_x / dx = 2 / w, times tan·aspect = tan·2/h.
        self.right * (2.0 * self.tan_half_fov / self.height as f64)
    }

    /// d(direction)/dy per pixel (y grows downward).
    pub fn direction_dy(&self) -> DVec3 {
        self.up * (-2.0 * self.tan_half_fov / self.height as f64)
    }

    /// View-space depth (distance along `forward`) of an eye-relative point.
    pub fn view_depth(&self, eye_relative: DVec3) -> f64 {
        eye_relative.dot(self.forward)
    }
}
