use glam::DVec3;

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
