//! Linear RGB colour (Rec. 709 / sRGB primaries) and the sRGB transfer curve.

use std::ops::{Add, AddAssign, Div, Mul, MulAssign};

/// Linear RGB triple. Radiance, reflectance and throughput all use it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Rgb {
    /// Red.
    pub r: f64,
    /// Green.
    pub g: f64,
    /// Blue.
    pub b: f64,
}

impl Rgb {
    /// Black.
    pub const BLACK: Rgb = Rgb::splat(0.0);
    /// White (1, 1, 1).
    pub const WHITE: Rgb = Rgb::splat(1.0);

    /// A colour from its components.
    pub const fn new(r: f64, g: f64, b: f64) -> Self {
        Self { r, g, b }
    }

    /// Grey `(v, v, v)`.
    pub const fn splat(v: f64) -> Self {
        Self { r: v, g: v, b: v }
    }

    /// From an array.
    pub const fn from_array(a: [f64; 3]) -> Self {
        Self::new(a[0], a[1], a[2])
    }

    /// As an array.
    pub fn to_array(self) -> [f64; 3] {
        [self.r, self.g, self.b]
    }

    /// Largest component.
    pub fn max_component(self) -> f64 {
        self.r.max(self.g).max(self.b)
    }

    /// Whether all components are zero.
    pub fn is_black(self) -> bool {
        self.r == 0.0 && self.g == 0.0 && self.b == 0.0
    }

    /// Whether all components are finite.
    pub fn is_finite(self) -> bool {
        self.r.is_finite() && self.g.is_finite() && self.b.is_finite()
    }

    /// Relative luminance Y (Rec. 709 weights).
    pub fn luminance(self) -> f64 {
        0.2126 * self.r + 0.7152 * self.g + 0.0722 * self.b
    }

    /// Component-wise map.
    pub fn map(self, f: impl Fn(f64) -> f64) -> Self {
        Self::new(f(self.r), f(self.g), f(self.b))
    }
}

impl Add for Rgb {
    type Output = Rgb;
    fn add(self, o: Rgb) -> Rgb {
        Rgb::new(self.r + o.r, self.g + o.g, self.b + o.b)
    }
}
impl AddAssign for Rgb {
    fn add_assign(&mut self, o: Rgb) {
        *self = *self + o;
    }
}
impl Mul for Rgb {
    type Output = Rgb;
    fn mul(self, o: Rgb) -> Rgb {
        Rgb::new(self.r * o.r, self.g * o.g, self.b * o.b)
    }
}
impl MulAssign for Rgb {
    fn mul_assign(&mut self, o: Rgb) {
        *self = *self * o;
    }
}
impl Mul<f64> for Rgb {
    type Output = Rgb;
    fn mul(self, s: f64) -> Rgb {
        Rgb::new(self.r * s, self.g * s, self.b * s)
    }
}
impl Mul<Rgb> for f64 {
    type Output = Rgb;
    fn mul(self, c: Rgb) -> Rgb {
        c * self
    }
}
impl MulAssign<f64> for Rgb {
    fn mul_assign(&mut self, s: f64) {
        *self = *self * s;
    }
}
impl Div<f64> for Rgb {
    type Output = Rgb;
    fn div(self, s: f64) -> Rgb {
        Rgb::new(self.r / s, self.g / s, self.b / s)
    }
}

/// The sRGB opto-electronic transfer function (IEC 61966-2-1) for a linear
/// value in `[0, 1]`; inputs outside are clamped.
pub fn srgb_encode(v: f64) -> f64 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    if v <= 0.0031308 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// Inverse of [`srgb_encode`].
pub fn srgb_decode(v: f64) -> f64 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trip_and_knee() {
        for i in 0..=100 {
            let v = i as f64 / 100.0;
            assert!((srgb_decode(srgb_encode(v)) - v).abs() < 1e-12);
        }
        // 18% grey encodes to about 118/255.
        assert!((srgb_encode(0.18) * 255.0 - 117.9).abs() < 0.5);
        assert_eq!(srgb_encode(f64::NAN), 0.0);
    }
}
