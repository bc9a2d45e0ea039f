//! Lights: punctual lights (`KHR_lights_punctual`) and emissive triangles.

use glam::Vec3;

/// The kind of a punctual light, with its cone for spots.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PunctualKind {
    /// Emits equally in all directions; intensity in candela (W/sr in pathlight's units).
    Point,
    /// A point light limited to a cone around `direction`; angles in radians from the axis.
    Spot { inner_cone: f32, outer_cone: f32 },
    /// Light from infinitely far away, travelling along `direction`; intensity is illuminance
    /// in lux (W/m^2 in pathlight's units).
    Directional,
}

/// A punctual light in world space.
#[derive(Debug, Clone, PartialEq)]
pub struct PunctualLight {
    pub name: String,
    pub kind: PunctualKind,
    /// World position (unused for directional lights).
    pub position: Vec3,
    /// Unit direction the light travels (spot axis; directional light direction).
    pub direction: Vec3,
    /// Linear colour times intensity.
    pub intensity: Vec3,
    /// Distance beyond which the light has no effect (`None`: infinite).
    pub range: Option<f32>,
}

/// One emitting triangle of the world: an instance's triangle whose material emits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EmissiveTriangle {
    /// Index into [`Scene::instances`](crate::Scene::instances).
    pub instance: u32,
    /// Triangle index within the instance's mesh.
    pub triangle: u32,
    /// World-space area.
    pub area: f32,
    /// Mean emitted radiance over the triangle (emissive factor times texture), linear RGB.
    pub radiance: Vec3,
    /// Emitted power in watts: pi * area * radiance, times 2 when both sides emit.
    pub power: Vec3,
    /// Both faces emit (double-sided material).
    pub two_sided: bool,
}

/// The minimal and maximal corners of an axis-aligned box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds {
    pub min: Vec3,
    pub max: Vec3,
}

impl Bounds {
    pub const EMPTY: Self = Self {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    pub fn is_empty(&self) -> bool {
        self.min.cmpgt(self.max).any()
    }

    pub fn grow(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    pub fn union(&self, other: &Self) -> Self {
        Self {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    pub fn center(&self) -> Vec3 {
        0.5 * (self.min + self.max)
    }

    pub fn diagonal(&self) -> Vec3 {
        self.max - self.min
    }
}

/// `count` point lights at deterministic pseudo-random positions, uniform inside `bounds`, as
/// seed 004 adds them, all white and equally bright. Each has intensity `(diagonal / 4)^2`
/// candela times `scale`, so a surface a quarter of the scene's diagonal away receives `scale`
/// lux from it whatever the scene's units.
pub fn random_point_lights(
    count: usize,
    bounds: &Bounds,
    seed: u64,
    scale: f32,
) -> Vec<PunctualLight> {
    if bounds.is_empty() || count == 0 {
        return Vec::new();
    }
    let mut state = seed ^ 0x9E37_79B9_7F4A_7C15;
    let mut next = || {
        // SplitMix64: a small, well-mixed generator, stable across platforms.
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 40) as f32 / (1u64 << 24) as f32
    };
    let d = bounds.diagonal();
    let intensity = ((d.length() / 4.0).powi(2) * scale).max(f32::MIN_POSITIVE);
    (0..count)
        .map(|i| {
            let t = Vec3::new(next(), next(), next());
            PunctualLight {
                name: format!("random point light {i}"),
                kind: PunctualKind::Point,
                position: bounds.min + t * d,
                direction: Vec3::NEG_Z,
                intensity: Vec3::splat(intensity),
                range: None,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn random_point_lights_are_inside_and_deterministic() {
        let b = Bounds {
            min: Vec3::new(-1.0, 0.0, 5.0),
            max: Vec3::new(1.0, 2.0, 9.0),
        };
        let a = random_point_lights(100, &b, 7, 1.0);
        assert_eq!(a, random_point_lights(100, &b, 7, 1.0));
        assert_ne!(a, random_point_lights(100, &b, 8, 1.0));
        assert_eq!(a.len(), 100);
        for l in &a {
            assert!(l.position.cmpge(b.min).all() && l.position.cmple(b.max).all());
        }
        // Spread over the box, not clustered: every octant gets some.
        let mut octants = [0; 8];
        for l in &a {
            let o = (l.position - b.center()).cmpgt(Vec3::ZERO).bitmask();
            octants[o as usize] += 1;
        }
        assert!(octants.iter().all(|&n| n >= 4), "{octants:?}");
    }
}
