//! Orthonormal frames: the shading frame of a BxDF has `z` along the normal.

use glam::DVec3;

/// An orthonormal basis `(s, t, n)`; local coordinates have `z` along `n`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// First tangent.
    pub s: DVec3,
    /// Second tangent.
    pub t: DVec3,
    /// Normal.
    pub n: DVec3,
}

impl Frame {
    /// A frame around the unit normal `n`, with tangents from the branchless
    /// construction of Duff et al., "Building an Orthonormal Basis,
    /// Revisited" (JCGT 2017). Continuous except across `n.z = 0` sign flips.
    pub fn from_normal(n: DVec3) -> Self {
        let sign = 1.0f64.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let s = DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let t = DVec3::new(b, sign + n.y * n.y * a, -n.y);
        Self { s, t, n }
    }

    /// A frame around `n` whose first tangent is the projection of `tangent`
    /// onto the tangent plane (`T = normalize(D - (D.N) N)`); falls back to
    /// [`Frame::from_normal`] when `tangent` is parallel to `n`.
    pub fn from_normal_tangent(n: DVec3, tangent: DVec3) -> Self {
        let s = tangent - tangent.dot(n) * n;
        let len = s.length();
        if !(len > 1e-9) {
            return Self::from_normal(n);
        }
        let s = s / len;
        Self {
            s,
            t: n.cross(s),
            n,
        }
    }

    /// World to local coordinates.
    #[inline]
    pub fn to_local(&self, v: DVec3) -> DVec3 {
        DVec3::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }

    /// Local to world coordinates.
    #[inline]
    pub fn to_world(&self, v: DVec3) -> DVec3 {
        v.x * self.s + v.y * self.t + v.z * self.n
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Pcg32;

    #[test]
    fn frames_are_orthonormal_and_invert() {
        let mut rng = Pcg32::new(1, 2);
        for _ in 0..1000 {
            let n = crate::sampling::uniform_sphere([rng.next_f64(), rng.next_f64()]);
            let f = Frame::from_normal(n);
            assert!((f.s.length() - 1.0).abs() < 1e-12);
            assert!((f.t.length() - 1.0).abs() < 1e-12);
            assert!(f.s.dot(f.t).abs() < 1e-12 && f.s.dot(n).abs() < 1e-12);
            assert!((f.s.cross(f.t) - n).length() < 1e-12, "right-handed");
            let v = DVec3::new(0.3, -0.2, 0.9);
            assert!((f.to_local(f.to_world(v)) - v).length() < 1e-12);
        }
    }
}
