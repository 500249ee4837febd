//! Parabolic maps of the hemisphere (Heidrich and Seidel 1998): the 2D
//! textures that hold factored BRDFs.
//!
//! ```text
//! (x, y) = (v_x, v_y) / (1 + v_z)                      direction -> map
//! v = (2x, 2y, 1 - x^2 - y^2) / (1 + x^2 + y^2)        map -> direction
//! d(omega) = 4 / (1 + x^2 + y^2)^2  dx dy               solid angle
//! ```
//!
//! A map of resolution `res` has `res x res` texels, row-major with row 0
//! at the top: texel (column `c`, row `r`) sits at
//! `x = (c + 1/2) / res * 2 - 1`, `y = 1 - (r + 1/2) / res * 2`. Texels
//! whose centre lies inside the unit disk are *valid*; every other texel
//! holds a copy of its nearest valid texel, so that bilinear lookups near
//! the rim read only meaningful values. Lookups clamp to the edge.
//!
//! [`ParabolicGrid::taps`] returns the four bilinear taps of a direction
//! *with invalid texels already replaced by their valid stand-ins*: the
//! factorization fits exactly the values that lookups later read.

use isolux_core::DVec3;

/// The geometry of a `res x res` parabolic map: coordinates, bilinear
/// taps, valid texels and their stand-ins. Holds no texel values.
#[derive(Clone, Debug, PartialEq)]
pub struct ParabolicGrid {
    res: usize,
    /// For each texel, the index of the valid texel that stands in for it
    /// (itself when valid).
    alias: Vec<u32>,
    /// Valid texel indices, in row-major order.
    valid: Vec<u32>,
}

/// Smallest and largest supported resolution.
pub const RES_RANGE: std::ops::RangeInclusive<usize> = 4..=512;

impl ParabolicGrid {
    /// A grid of `res x res` texels; `res` must lie in [`RES_RANGE`].
    pub fn new(res: usize) -> Result<Self, String> {
        if !RES_RANGE.contains(&res) {
            return Err(format!(
                "resolution must lie in {}..={}, got {res}",
                RES_RANGE.start(),
                RES_RANGE.end()
            ));
        }
        let n = res * res;
        let mut alias = vec![u32::MAX; n];
        let mut valid = Vec::new();
        for r in 0..res {
            for c in 0..res {
                let (x, y) = Self::center_of(res, c, r);
                if x * x + y * y <= 1.0 {
                    alias[r * res + c] = (r * res + c) as u32;
                    valid.push((r * res + c) as u32);
                }
            }
        }
        // Stand-ins: the valid texel whose centre is nearest. Project the
        // centre radially into the disk and search a small window there.
        for r in 0..res {
            for c in 0..res {
                if alias[r * res + c] != u32::MAX {
                    continue;
                }
                let (x, y) = Self::center_of(res, c, r);
                let len = (x * x + y * y).sqrt();
                let (px, py) = (x / len * 0.999, y / len * 0.999);
                let (fc, fr) = Self::texel_coords(res, px, py);
                let (c0, r0) = (fc.round() as i64, fr.round() as i64);
                let mut best = (f64::INFINITY, u32::MAX);
                for dr in -3..=3 {
                    for dc in -3..=3 {
                        let (cc, rr) = (c0 + dc, r0 + dr);
                        if cc < 0 || rr < 0 || cc >= res as i64 || rr >= res as i64 {
                            continue;
                        }
                        let idx = rr as usize * res + cc as usize;
                        let (vx, vy) = Self::center_of(res, cc as usize, rr as usize);
                        if vx * vx + vy * vy > 1.0 {
                            continue;
                        }
                        let d = (vx - x).powi(2) + (vy - y).powi(2);
                        if d < best.0 {
                            best = (d, idx as u32);
                        }
                    }
                }
                debug_assert!(best.1 != u32::MAX);
                alias[r * res + c] = best.1;
            }
        }
        Ok(Self { res, alias, valid })
    }

    /// Texels per side.
    pub fn res(&self) -> usize {
        self.res
    }

    /// Number of texels, `res^2`.
    pub fn len(&self) -> usize {
        self.res * self.res
    }

    /// Always false (a grid has at least 16 texels).
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Valid texels (centre inside the unit disk), row-major.
    pub fn valid(&self) -> &[u32] {
        &self.valid
    }

    /// For each texel, its position in [`ParabolicGrid::valid`]
    /// (`u32::MAX` for a texel outside the disk): the map from texels to
    /// the unknowns of a fit over the valid texels.
    pub fn valid_order(&self) -> Vec<u32> {
        let mut ord = vec![u32::MAX; self.len()];
        for (k, &i) in self.valid.iter().enumerate() {
            ord[i as usize] = k as u32;
        }
        ord
    }

    /// The valid texel that stands in for texel `i`.
    pub fn alias(&self, i: usize) -> usize {
        self.alias[i] as usize
    }

    fn center_of(res: usize, c: usize, r: usize) -> (f64, f64) {
        let s = 2.0 / res as f64;
        ((c as f64 + 0.5) * s - 1.0, 1.0 - (r as f64 + 0.5) * s)
    }

    /// Continuous texel coordinates (column, row) of map point `(x, y)`,
    /// with texel centres at integers.
    fn texel_coords(res: usize, x: f64, y: f64) -> (f64, f64) {
        let h = res as f64 * 0.5;
        ((x + 1.0) * h - 0.5, (1.0 - y) * h - 0.5)
    }

    /// Map coordinates `(x, y)` of the centre of texel `(c, r)`.
    pub fn center(&self, c: usize, r: usize) -> (f64, f64) {
        Self::center_of(self.res, c, r)
    }

    /// The direction at the centre of texel `i` (valid texels only give a
    /// direction in the upper hemisphere).
    pub fn texel_direction(&self, i: usize) -> DVec3 {
        let (x, y) = self.center(i % self.res, i / self.res);
        from_parabolic(x, y)
    }

    /// The four bilinear taps (texel index, weight) of direction `v`
    /// (`v.z >= 0`), with stand-ins substituted; weights sum to 1.
    #[inline]
    pub fn taps(&self, v: DVec3) -> [(u32, f64); 4] {
        let (x, y) = to_parabolic(v);
        let (fc, fr) = Self::texel_coords(self.res, x, y);
        let max = (self.res - 1) as f64;
        let (fc, fr) = (fc.clamp(0.0, max), fr.clamp(0.0, max));
        let (c0, r0) = (
            (fc.floor() as usize).min(self.res - 2),
            (fr.floor() as usize).min(self.res - 2),
        );
        let (tx, ty) = (fc - c0 as f64, fr - r0 as f64);
        let i = r0 * self.res + c0;
        let a = |k: usize| self.alias[k];
        [
            (a(i), (1.0 - tx) * (1.0 - ty)),
            (a(i + 1), tx * (1.0 - ty)),
            (a(i + self.res), (1.0 - tx) * ty),
            (a(i + self.res + 1), tx * ty),
        ]
    }
}

/// Parabolic coordinates of a unit direction with `v.z >= 0`.
#[inline]
pub fn to_parabolic(v: DVec3) -> (f64, f64) {
    let d = 1.0 + v.z.max(0.0);
    (v.x / d, v.y / d)
}

/// The direction at parabolic coordinates `(x, y)`.
#[inline]
pub fn from_parabolic(x: f64, y: f64) -> DVec3 {
    let r2 = x * x + y * y;
    DVec3::new(2.0 * x, 2.0 * y, 1.0 - r2) / (1.0 + r2)
}

/// `d(omega) / (dx dy)` at parabolic coordinates `(x, y)`.
#[inline]
pub fn solid_angle_jacobian(x: f64, y: f64) -> f64 {
    let r2 = 1.0 + x * x + y * y;
    4.0 / (r2 * r2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_jacobian() {
        for &(x, y) in &[(0.0, 0.0), (0.3, -0.4), (-0.7, 0.2), (0.6, 0.79)] {
            let v = from_parabolic(x, y);
            assert!((v.length() - 1.0).abs() < 1e-12);
            let (a, b) = to_parabolic(v);
            assert!((a - x).abs() < 1e-12 && (b - y).abs() < 1e-12);
            // Jacobian by finite differences: |dv/dx x dv/dy|.
            let h = 1e-6;
            let dx = (from_parabolic(x + h, y) - from_parabolic(x - h, y)) / (2.0 * h);
            let dy = (from_parabolic(x, y + h) - from_parabolic(x, y - h)) / (2.0 * h);
            let j = dx.cross(dy).length();
            assert!((j - solid_angle_jacobian(x, y)).abs() < 1e-6 * j);
        }
        // The disk covers the hemisphere: its solid angle integrates to 2 pi.
        let n = 2000;
        let mut sum = 0.0;
        for i in 0..n {
            for j in 0..n {
                let x = (i as f64 + 0.5) / n as f64 * 2.0 - 1.0;
                let y = (j as f64 + 0.5) / n as f64 * 2.0 - 1.0;
                if x * x + y * y <= 1.0 {
                    sum += solid_angle_jacobian(x, y) * (2.0 / n as f64).powi(2);
                }
            }
        }
        assert!((sum - 2.0 * std::f64::consts::PI).abs() < 1e-3, "{sum}");
    }

    #[test]
    fn taps_hit_texel_centres_and_stand_ins_are_valid() {
        let g = ParabolicGrid::new(8).unwrap();
        for &i in g.valid() {
            let t = g.taps(g.texel_direction(i as usize));
            let w: f64 = t.iter().filter(|p| p.0 == i).map(|p| p.1).sum();
            assert!((w - 1.0).abs() < 1e-9, "texel {i}: {t:?}");
        }
        for i in 0..g.len() {
            let a = g.alias(i);
            let (x, y) = g.center(a % 8, a / 8);
            assert!(x * x + y * y <= 1.0);
        }
        assert!(ParabolicGrid::new(3).is_err() && ParabolicGrid::new(513).is_err());
    }
}
