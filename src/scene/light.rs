use glam::{DVec3, Vec3};

/// Largest accepted angular radius of a directional light's disk, in
/// degrees. The soft-shadow construction treats the sun as a disk on the
/// plane one unit along its centre direction, radius tan r; far below 90°
/// so that plane stays a faithful stand-in for the cone (the real sun:
/// 0.27°; the widest setting the bench uses: 3°).
pub const MAX_ANGULAR_RADIUS_DEG: f64 = 30.0;

/// The light of a scene. `direction` of a directional light is the way the
/// light travels (from the light into the scene), normalised on load.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "type", rename_all = "lowercase")]
pub enum Light {
    Directional { direction: DVec3 },
    Point { position: DVec3 },
}

impl Light {
    /// A directional light travelling along `direction` (any length > 0).
    pub fn directional(direction: DVec3) -> Self {
        Light::Directional {
            direction: direction.normalize_or_zero(),
        }
    }

    pub(crate) fn validate(&self) -> Result<(), String> {
        match self {
            Light::Directional { direction } => {
                if !direction.is_finite() || direction.length_squared() == 0.0 {
                    return Err(format!(
                        "`light.direction` of a directional light must be a finite non-zero vector, got {direction}"
                    ));
                }
            }
            Light::Point { position } => {
                if !position.is_finite() {
                    return Err(format!(
                        "`light.position` of a point light must be finite, got {position}"
                    ));
                }
            }
        }
        Ok(())
    }

    /// Checks a light size in the units of [`LightSize`]'s constructor
    /// for this kind of light: `angular_radius_deg` (directional) or
    /// `radius` (point), finite, ≥ 0, and for a directional light at most
    /// [`MAX_ANGULAR_RADIUS_DEG`].
    pub(crate) fn validate_size(&self, size: f64) -> Result<(), String> {
        let field = self.size_field();
        if !size.is_finite() || size < 0.0 {
            return Err(format!(
                "`light.{field}` must be a finite number ≥ 0, got {size}"
            ));
        }
        if matches!(self, Light::Directional { .. }) && size > MAX_ANGULAR_RADIUS_DEG {
            return Err(format!(
                "`light.{field}` is {size}°: at most {MAX_ANGULAR_RADIUS_DEG}° is supported \
                 (the sun is 0.27°)"
            ));
        }
        Ok(())
    }

    /// Checks that a point light's sphere of radius `radius` is no wider
    /// than the scene (`scene_radius`, half its bounds' diagonal), as a
    /// directional light's disk is capped at [`MAX_ANGULAR_RADIUS_DEG`]:
    /// the soft-shadow passes stand a disk facing each receiver in for the
    /// sphere, a faithful model of a lamp, not of a light that swallows
    /// the scene (a sphere may still cut a surface: the receiver's horizon
    /// hides the part below it). Nothing to check for a directional light.
    pub(crate) fn validate_sphere_size(
        &self,
        radius: f64,
        scene_radius: f64,
    ) -> Result<(), String> {
        if matches!(self, Light::Point { .. }) && radius > scene_radius {
            return Err(format!(
                "`light.radius` is {radius}, wider than the scene itself (radius \
                 {scene_radius:.4e}, half its bounds' diagonal): a sphere light is a lamp \
                 within the scene; for light from a wide sky use a directional light's \
                 `angular_radius_deg` (at most {MAX_ANGULAR_RADIUS_DEG}°)"
            ));
        }
        Ok(())
    }

    /// The radius of the light's disk ([`LightDisk`]) for a light of size
    /// `light_radius` ([`Scene::light_radius`](super::Scene::light_radius)):
    /// tan r for a directional light (its disk lies one unit away), R for
    /// a point light.
    pub fn disk_radius(&self, light_radius: f64) -> f64 {
        match self {
            Light::Directional { .. } => light_radius.tan(),
            Light::Point { .. } => light_radius,
        }
    }

    /// The light's disk seen from `p` ([`LightDisk`], `f64`) for a light of
    /// size `light_radius`. The light and `p` must be in one frame, and a
    /// directional light's direction unit ([`Light::relative_to`] makes
    /// both so).
    pub fn disk_from(&self, light_radius: f64, p: DVec3) -> LightDisk<DVec3> {
        let radius = self.disk_radius(light_radius);
        match *self {
            Light::Directional { direction } => light_disk(-direction, radius),
            Light::Point { position } => light_disk(position - p, radius),
        }
    }

    /// The spec field that sizes this kind of light.
    pub fn size_field(&self) -> &'static str {
        match self {
            Light::Directional { .. } => "angular_radius_deg",
            Light::Point { .. } => "radius",
        }
    }

    /// The light's radius in the units every pass uses (see
    /// [`Scene::light_radius`](super::Scene::light_radius)) from the spec's
    /// unit: degrees become radians for a directional light.
    pub fn radius_from_spec(&self, size: f64) -> f64 {
        match self {
            Light::Directional { .. } => size.to_radians(),
            Light::Point { .. } => size,
        }
    }

    /// The light expressed relative to `origin` (positions shift, directions
    /// do not): the eye-relative form every pass uses.
    pub fn relative_to(&self, origin: DVec3) -> Light {
        match *self {
            Light::Directional { direction } => Light::Directional {
                direction: direction.normalize(),
            },
            Light::Point { position } => Light::Point {
                position: position - origin,
            },
        }
    }

    /// Unit vector from `p` toward the light and the distance to it
    /// (infinite for a directional light). `p` and the light must be in the
    /// same frame.
    pub fn toward(&self, p: DVec3) -> (DVec3, f64) {
        match *self {
            Light::Directional { direction } => (-direction.normalize(), f64::INFINITY),
            Light::Point { position } => {
                let d = position - p;
                let len = d.length();
                (d / len, len)
            }
        }
    }
}

/// A light of finite size as seen from one receiver point P: a disk, its
/// samples at `centre + (u − ½)·axis_u + (v − ½)·axis_v` for (u, v) in
/// the disk inscribed in [0, 1)² (the light pattern,
/// [`crate::lut::light_pattern`]), every vector relative to P.
///
/// - Directional light of angular radius r: the disk of radius tan r on
///   the plane one unit from P along the unit vector toward the light,
///   perpendicular to it; a sample is a *direction* (the sun at infinity).
/// - Point light of radius R (a sphere): the disk of radius R through its
///   centre, facing P; a sample is the offset from P to a *point*.
///
/// The axes are the orthonormal basis of Duff et al. 2017 (branchless,
/// continuous except where the centre direction crosses z = 0), scaled to
/// the disk's diameter, so a µQuad-style edge function over (u, v)
/// reads the same as the pixel's and the same LUT machinery applies.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightDisk<V> {
    pub centre: V,
    pub axis_u: V,
    pub axis_v: V,
}

macro_rules! light_disk_impl {
    ($v:ty, $s:ty, $name:ident) => {
        /// The disk of a light with centre vector `centre` (toward a
        /// directional light, unit; or the point light minus P) and disk
        /// radius `radius` (tan r, or R). See [`LightDisk`].
        pub fn $name(centre: $v, radius: $s) -> LightDisk<$v> {
            // Spelled out (not `normalize`): the GPU repeats these very
            // operations, in this order, for a point light's disk.
            let n = centre * (1.0 / centre.length());
            let sign = (1.0 as $s).copysign(n.z);
            let a = -1.0 / (sign + n.z);
            let b = n.x * n.y * a;
            let u = <$v>::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
            let v = <$v>::new(b, sign + n.y * n.y * a, -n.y);
            let diameter = 2.0 * radius;
            LightDisk {
                centre,
                axis_u: u * diameter,
                axis_v: v * diameter,
            }
        }
    };
}
light_disk_impl!(DVec3, f64, light_disk);
light_disk_impl!(Vec3, f32, light_disk_f32);

impl LightDisk<DVec3> {
    /// The vector from P to the light sample at `uv` of the pattern.
    pub fn sample(&self, uv: [f32; 2]) -> DVec3 {
        self.centre + (uv[0] as f64 - 0.5) * self.axis_u + (uv[1] as f64 - 0.5) * self.axis_v
    }
}
