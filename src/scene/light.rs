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

    /// Checks that a point light's sphere of radius `radius` subtends at
    /// most [`MAX_ANGULAR_RADIUS_DEG`] seen from every triangle, as a
    /// directional light's disk must: the disk the soft-shadow passes put
    /// in its place stays a faithful stand-in only there, and a sphere
    /// reaching a surface has no meaning at all. Brute force over the
    /// triangles (`f64`, about 20 ns each); nothing to check for a
    /// directional light or a point-like one.
    pub(crate) fn validate_sphere_clearance(
        &self,
        radius: f64,
        triangles: &[super::Triangle],
    ) -> Result<(), String> {
        let Light::Point { position } = *self else {
            return Ok(());
        };
        if radius <= 0.0 {
            return Ok(());
        }
        let nearest = triangles
            .iter()
            .enumerate()
            .map(|(id, t)| {
                (
                    id,
                    (closest_point_on_triangle(position, t) - position).length(),
                )
            })
            .min_by(|a, b| a.1.total_cmp(&b.1));
        let Some((id, distance)) = nearest else {
            return Ok(());
        };
        let largest = distance * MAX_ANGULAR_RADIUS_DEG.to_radians().sin();
        if radius > largest {
            return Err(format!(
                "`light.radius` is {radius}, but triangle {id} lies {distance:.4e} from the                  light's centre: a sphere of that radius subtends more than                  {MAX_ANGULAR_RADIUS_DEG}° there (at most {largest:.4e} is supported)"
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

/// The point of triangle `t` nearest `p` (Ericson 2005, §5.1.5: the
/// Voronoi regions of the vertices, the edges and the face in turn).
fn closest_point_on_triangle(p: DVec3, t: &[DVec3; 3]) -> DVec3 {
    let [a, b, c] = *t;
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = 1.0 / (va + vb + vc);
    a + ab * (vb * denom) + ac * (vc * denom)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The closest point against a dense sampling of the triangle: never
    /// farther than the nearest sample, and on the triangle.
    #[test]
    fn closest_point_is_no_farther_than_any_sampled_point() {
        let t = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(2.0, 0.2, 0.0),
            DVec3::new(0.5, 1.5, 0.3),
        ];
        let mut checked = 0;
        for p in [
            DVec3::new(-1.0, -1.0, 0.5),
            DVec3::new(3.0, 0.0, -1.0),
            DVec3::new(0.6, 2.5, 0.0),
            DVec3::new(0.8, 0.5, 2.0),
            DVec3::new(1.5, 1.2, -0.4),
            DVec3::new(-0.5, 0.8, 0.1),
        ] {
            let q = closest_point_on_triangle(p, &t);
            let best = (0..=200)
                .flat_map(|i| (0..=200 - i).map(move |j| (i, j)))
                .map(|(i, j)| {
                    let (u, v) = (i as f64 / 200.0, j as f64 / 200.0);
                    t[0] + (t[1] - t[0]) * u + (t[2] - t[0]) * v
                })
                .map(|s| (s - p).length())
                .fold(f64::INFINITY, f64::min);
            let d = (q - p).length();
            assert!(d <= best + 1e-12, "{p}: {d} above the sampled {best}");
            assert!(d > best - 0.02, "{p}: {d} far below the sampled {best}");
            checked += 1;
        }
        assert_eq!(checked, 6);
    }
}
