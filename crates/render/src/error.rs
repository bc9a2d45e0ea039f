//! The configuration's error: a value out of range, named as the configuration names it. A
//! leaf module: every technique's settings check themselves with it.

/// A configuration value out of range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{field} {value}: must be {requirement}")]
pub struct ConfigError {
    /// The field's name as in the configuration (`fov_y`, `camera.lens_radius` is `lens_radius`).
    pub field: &'static str,
    pub value: String,
    pub requirement: String,
}

impl ConfigError {
    /// The field's name as a command-line option (`fov_y` is `--fov-y`); a technique's
    /// field, which has no flag of its own, by its place in the configuration file
    /// (`frame.adaptive.min_spp`).
    pub fn option(&self) -> String {
        if self.field.contains('.') {
            self.field.to_owned()
        } else {
            format!("--{}", self.field.replace('_', "-"))
        }
    }

    /// A value out of range.
    pub fn new(
        field: &'static str,
        value: impl std::fmt::Display,
        requirement: impl Into<String>,
    ) -> Self {
        Self {
            field,
            value: value.to_string(),
            requirement: requirement.into(),
        }
    }
}

/// The reconstruction filter's settings out of range, as the configuration's error.
impl From<pathlight_denoise::FilterError> for ConfigError {
    fn from(e: pathlight_denoise::FilterError) -> Self {
        match e {
            pathlight_denoise::FilterError::Parameter {
                field,
                value,
                requirement,
            } => Self {
                field,
                value,
                requirement,
            },
            other => Self::new("frame.filter", "", other.to_string()),
        }
    }
}
