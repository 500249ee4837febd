//! Rays and axis-aligned bounding boxes.

use glam::DVec3;

/// A ray `p(t) = origin + t * dir`. `dir` need not be unit length for
/// intersection, but the renderer always passes unit directions so that `t`
/// is a distance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Origin.
    pub origin: DVec3,
    /// Direction.
    pub dir: DVec3,
}

impl Ray {
    /// A ray from `origin` along `dir`.
    pub fn new(origin: DVec3, dir: DVec3) -> Self {
        Self { origin, dir }
    }

    /// The point at parameter `t`.
    #[inline]
    pub fn at(&self, t: f64) -> DVec3 {
        self.origin + t * self.dir
    }
}

/// An axis-aligned box `[min, max]`. The empty box has `min > max`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Lower corner.
    pub min: DVec3,
    /// Upper corner.
    pub max: DVec3,
}

impl Aabb {
    /// The empty box (union identity).
    pub const EMPTY: Aabb = Aabb {
        min: DVec3::splat(f64::INFINITY),
        max: DVec3::splat(f64::NEG_INFINITY),
    };

    /// The box that contains everything.
    pub const EVERYTHING: Aabb = Aabb {
        min: DVec3::splat(f64::NEG_INFINITY),
        max: DVec3::splat(f64::INFINITY),
    };

    /// The box with corners `a` and `b` (in any order).
    pub fn new(a: DVec3, b: DVec3) -> Self {
        Self {
            min: a.min(b),
            max: a.max(b),
        }
    }

    /// Whether the box contains no point.
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x || self.min.y > self.max.y || self.min.z > self.max.z
    }

    /// Whether every extent is finite.
    pub fn is_finite(&self) -> bool {
        self.min.is_finite() && self.max.is_finite()
    }

    /// The box moved by `v` (an unbounded side stays unbounded).
    pub fn translated(&self, v: DVec3) -> Aabb {
        Aabb {
            min: self.min + v,
            max: self.max + v,
        }
    }

    /// Smallest box containing both.
    pub fn union(&self, o: &Aabb) -> Aabb {
        Aabb {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    /// Largest box contained in both (possibly empty).
    pub fn intersection(&self, o: &Aabb) -> Aabb {
        Aabb {
            min: self.min.max(o.min),
            max: self.max.min(o.max),
        }
    }

    /// Centre point.
    pub fn center(&self) -> DVec3 {
        0.5 * (self.min + self.max)
    }

    /// Corner `k` (0..8): bit 0 of `k` picks `max.x` over `min.x`, bit 1
    /// `max.y`, bit 2 `max.z`.
    pub fn corner(&self, k: usize) -> DVec3 {
        DVec3::new(
            if k & 1 == 0 { self.min.x } else { self.max.x },
            if k & 2 == 0 { self.min.y } else { self.max.y },
            if k & 4 == 0 { self.min.z } else { self.max.z },
        )
    }

    /// Whether `p` lies inside or on the box.
    pub fn contains(&self, p: DVec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }

    /// Slab test: the parameter interval of `ray` inside the box, clipped to
    /// `[t0, t1]`, or `None` when they do not overlap. Works with infinite
    /// boxes and axis-parallel rays (IEEE infinities do the right thing; the
    /// `0 * inf` NaN case is handled explicitly).
    #[inline]
    pub fn clip(&self, ray: &Ray, t0: f64, t1: f64) -> Option<(f64, f64)> {
        let mut lo = t0;
        let mut hi = t1;
        for a in 0..3 {
            let o = ray.origin[a];
            let d = ray.dir[a];
            let (bmin, bmax) = (self.min[a], self.max[a]);
            if d == 0.0 {
                if o < bmin || o > bmax {
                    return None;
                }
                continue;
            }
            let inv = 1.0 / d;
            let mut ta = (bmin - o) * inv;
            let mut tb = (bmax - o) * inv;
            if ta > tb {
                std::mem::swap(&mut ta, &mut tb);
            }
            // NaN-safe: only tighten with real numbers.
            if ta > lo {
                lo = ta;
            }
            if tb < hi {
                hi = tb;
            }
            if lo > hi {
                return None;
            }
        }
        Some((lo, hi))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corners_are_the_eight_extremes() {
        let b = Aabb::new(DVec3::new(-1.0, 2.0, 3.0), DVec3::new(4.0, -5.0, 6.0));
        let corners: Vec<DVec3> = (0..8).map(|k| b.corner(k)).collect();
        for x in [-1.0, 4.0] {
            for y in [-5.0, 2.0] {
                for z in [3.0, 6.0] {
                    assert!(corners.contains(&DVec3::new(x, y, z)));
                }
            }
        }
        assert_eq!(b.corner(0), b.min);
        assert_eq!(b.corner(7), b.max);
    }

    #[test]
    fn clip_unit_box() {
        let b = Aabb::new(DVec3::splat(-1.0), DVec3::splat(1.0));
        let r = Ray::new(DVec3::new(-5.0, 0.0, 0.0), DVec3::X);
        let (a, c) = b.clip(&r, 0.0, f64::INFINITY).unwrap();
        assert!((a - 4.0).abs() < 1e-12 && (c - 6.0).abs() < 1e-12);
        let r = Ray::new(DVec3::new(-5.0, 2.0, 0.0), DVec3::X);
        assert!(b.clip(&r, 0.0, f64::INFINITY).is_none());
        assert!(Aabb::EVERYTHING.clip(&r, 0.0, 1.0).is_some());
    }
}
