//! Axis-aligned bounding boxes for the builder.

use glam::Vec3;

#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Aabb {
    /// The empty box (`min > max`), the identity of [`Aabb::union`].
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };

    #[inline]
    pub fn of_triangle(t: &[Vec3; 3]) -> Aabb {
        Aabb {
            min: t[0].min(t[1]).min(t[2]),
            max: t[0].max(t[1]).max(t[2]),
        }
    }

    #[inline]
    pub fn grow(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    #[inline]
    pub fn union(self, o: Aabb) -> Aabb {
        Aabb {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    pub fn is_empty(&self) -> bool {
        !(self.min.cmple(self.max).all())
    }

    /// The centre, computed without overflow for huge boxes.
    #[inline]
    pub fn center(&self) -> Vec3 {
        self.min * 0.5 + self.max * 0.5
    }

    /// Half the surface area, in f64 so that huge boxes don't overflow. Zero when empty.
    #[inline]
    pub fn half_area(&self) -> f64 {
        if self.is_empty() {
            return 0.0;
        }
        let d = self.max.as_dvec3() - self.min.as_dvec3();
        d.x * d.y + d.y * d.z + d.z * d.x
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_union_and_area() {
        assert!(Aabb::EMPTY.is_empty());
        assert_eq!(Aabb::EMPTY.half_area(), 0.0);
        let b = Aabb::of_triangle(&[Vec3::ZERO, Vec3::X, Vec3::new(0.0, 2.0, 3.0)]);
        assert_eq!(Aabb::EMPTY.union(b), b);
        assert_eq!(b.half_area(), 2.0 + 6.0 + 3.0);
        let huge = Aabb::of_triangle(&[Vec3::splat(-3e38), Vec3::splat(3e38), Vec3::ZERO]);
        assert!(huge.half_area().is_finite() && huge.center().is_finite());
    }
}
