//! # MERL measured BRDF
//!
//! An isotropic BRDF measured by Matusik, Pfister, Brand and McMillan
//! (the MERL database, 100 materials), tabulated over Rusinkiewicz's
//! half/difference angles `(theta_h, theta_d, phi_d)`:
//!
//! ```text
//! file   = int32 dims[3] = (90, 90, 180), then 3 planes (R, G, B) of
//!          90 * 90 * 180 = 1,458,000 little-endian f64 values
//! index  = phi_d + 180 * theta_d + 16200 * theta_h
//! theta_h index = sqrt(theta_h / (pi/2)) * 90     (dense near the highlight)
//! theta_d index = theta_d / (pi/2) * 90
//! phi_d   index = phi_d / pi * 180                (phi_d folded into [0, pi))
//! f = value * (1/1500, 1.15/1500, 1.66/1500)      (R, G, B)
//! ```
//!
//! Negative entries mean *no measurement*. Lookups interpolate trilinearly
//! between the stored samples (sample `i` sits at index coordinate `i`,
//! so a lookup at a sample returns it exactly, as the reference code's
//! truncating lookup does; `phi_d` wraps with period `pi`, the isotropic
//! BRDF's symmetry), skipping missing samples and renormalizing the
//! weights; where all eight are missing there is no data
//! ([`Merl::lookup`] returns `None`, the material returns black).
//! Sampling is cosine-weighted.
//!
//! | name | type | default | meaning |
//! |---|---|---|---|
//! | `file` | path | required | a MERL `.binary` file, relative to the scene file |
//!
//! Source: W. Matusik, H. Pfister, M. Brand and L. McMillan, "A
//! Data-Driven Reflectance Model", SIGGRAPH 2003; S. Rusinkiewicz, "A New
//! Change of Variables for Efficient BRDF Representation", EGWR 1998.
//!
//! ```
//! let scene = r#"
//! [[material]]
//! name = "paint"
//! type = "merl"
//! file = "brdfs/blue-metallic-paint.binary"
//! "#;
//! let doc: toml::Table = toml::from_str(scene).unwrap();
//! assert_eq!(doc["material"][0]["type"].as_str(), Some("merl"));
//! ```

use crate::bxdf::{BsdfSample, BxdfFlags, BxdfModel};
use isolux_core::{sampling, DVec3, Rgb};
use std::f64::consts::{FRAC_PI_2, PI};
use std::path::Path;
use std::sync::Arc;

/// Table sizes `(theta_h, theta_d, phi_d)`.
pub const DIMS: [usize; 3] = [90, 90, 180];
/// Values per colour plane.
pub const PLANE: usize = 90 * 90 * 180;
/// Per-channel scale of the stored values.
pub const SCALE: [f64; 3] = [1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0];

/// A MERL table: scaled values, `f32`, negative where missing.
#[derive(Clone)]
pub struct Merl {
    /// `[R plane, G plane, B plane]`, each [`PLANE`] long, already scaled.
    data: Arc<Vec<f32>>,
    missing: usize,
}

impl std::fmt::Debug for Merl {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Merl")
            .field("missing", &self.missing)
            .finish_non_exhaustive()
    }
}

impl PartialEq for Merl {
    fn eq(&self, o: &Self) -> bool {
        Arc::ptr_eq(&self.data, &o.data) || self.data == o.data
    }
}

impl Merl {
    /// Parses a `.binary` file's bytes.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, String> {
        if bytes.len() < 12 {
            return Err(format!(
                "truncated MERL file: {} bytes, the header alone needs 12",
                bytes.len()
            ));
        }
        let dim = |k: usize| i32::from_le_bytes(bytes[4 * k..4 * k + 4].try_into().unwrap());
        let dims = [dim(0), dim(1), dim(2)];
        if dims != [90, 90, 180] {
            return Err(format!(
                "not a MERL BRDF: header dimensions {dims:?}, expected [90, 90, 180]"
            ));
        }
        let want = 12 + 3 * PLANE * 8;
        if bytes.len() != want {
            return Err(format!(
                "{} MERL file: {} bytes, expected {want}",
                if bytes.len() < want {
                    "truncated"
                } else {
                    "oversized"
                },
                bytes.len()
            ));
        }
        let mut data = Vec::with_capacity(3 * PLANE);
        let mut missing = 0;
        for (k, chunk) in bytes[12..].chunks_exact(8).enumerate() {
            let v = f64::from_le_bytes(chunk.try_into().unwrap());
            if v.is_nan() {
                return Err(format!("MERL value {k} is NaN"));
            }
            if v < 0.0 {
                missing += 1;
                data.push(-1.0);
            } else {
                // The table is f32: +inf, or a value that overflows it
                // once scaled, would reach the renderer (and the fit) as
                // an infinite BRDF rather than as a damaged file.
                let scaled = v * SCALE[k / PLANE];
                if scaled > f32::MAX as f64 {
                    return Err(format!(
                        "MERL value {k} is {v:e}, beyond f32 once scaled (the table's type)"
                    ));
                }
                data.push(scaled as f32);
            }
        }
        Ok(Self {
            data: Arc::new(data),
            missing,
        })
    }

    /// Reads a `.binary` file.
    pub fn read(path: &Path) -> Result<Self, String> {
        let bytes =
            std::fs::read(path).map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
        Self::from_bytes(&bytes).map_err(|e| format!("{}: {e}", path.display()))
    }

    /// Encodes raw (unscaled) planes `[R, G, B]` as a `.binary` file.
    pub fn encode(raw: &[f64]) -> Vec<u8> {
        assert_eq!(raw.len(), 3 * PLANE);
        let mut out = Vec::with_capacity(12 + raw.len() * 8);
        for d in DIMS {
            out.extend_from_slice(&(d as i32).to_le_bytes());
        }
        for v in raw {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out
    }

    /// Number of missing (negative) entries over the three planes.
    pub fn missing(&self) -> usize {
        self.missing
    }

    /// The whole table: the R, G and B planes, [`PLANE`] values each,
    /// already scaled, negative where missing (index `phi_d + 180 theta_d
    /// + 16200 theta_h` within a plane). The GPU uploads it as is.
    pub fn table(&self) -> &[f32] {
        &self.data
    }

    /// The stored (scaled) value at table indices, `None` if missing.
    pub fn entry(&self, channel: usize, th: usize, td: usize, pd: usize) -> Option<f64> {
        let v = self.data[channel * PLANE + pd + 180 * td + 16200 * th];
        (v >= 0.0).then_some(v as f64)
    }

    /// Continuous table coordinates `(theta_h, theta_d, phi_d)` of a
    /// direction pair (upper hemisphere).
    pub fn coords(wo: DVec3, wi: DVec3) -> [f64; 3] {
        let (th, td, pd) = half_diff(wo, wi);
        [
            (th / FRAC_PI_2).max(0.0).sqrt() * 90.0,
            td / FRAC_PI_2 * 90.0,
            pd / PI * 180.0,
        ]
    }

    /// Interpolated `f(wo, wi)`, `None` where the neighbouring samples are
    /// all missing.
    pub fn lookup(&self, wo: DVec3, wi: DVec3) -> Option<Rgb> {
        let c = Self::coords(wo, wi);
        let axis = |x: f64, n: usize| -> ([usize; 2], f64) {
            let x = x.clamp(0.0, (n - 1) as f64);
            let i = (x.floor() as usize).min(n - 2);
            ([i, i + 1], x - i as f64)
        };
        let (ih, th) = axis(c[0], 90);
        let (id, td) = axis(c[1], 90);
        let p = c[2].rem_euclid(180.0);
        let p0 = (p.floor() as usize).min(179);
        let (ip, tp) = ([p0, (p0 + 1) % 180], p - p0 as f64);
        let mut sum = [0.0; 3];
        let mut wsum = [0.0; 3];
        for (a, wa) in [(ih[0], 1.0 - th), (ih[1], th)] {
            for (b, wb) in [(id[0], 1.0 - td), (id[1], td)] {
                for (cc, wc) in [(ip[0], 1.0 - tp), (ip[1], tp)] {
                    let w = wa * wb * wc;
                    if w == 0.0 {
                        continue;
                    }
                    for k in 0..3 {
                        if let Some(v) = self.entry(k, a, b, cc) {
                            sum[k] += w * v;
                            wsum[k] += w;
                        }
                    }
                }
            }
        }
        if wsum.iter().any(|w| *w <= 0.0) {
            return None;
        }
        Some(Rgb::new(
            sum[0] / wsum[0],
            sum[1] / wsum[1],
            sum[2] / wsum[2],
        ))
    }
}

/// Rusinkiewicz's half/difference angles `(theta_h, theta_d, phi_d)` of a
/// direction pair, `phi_d` folded into `[0, pi)`.
pub fn half_diff(wo: DVec3, wi: DVec3) -> (f64, f64, f64) {
    let (h, d) = half_diff_vectors(wo, wi);
    let theta_h = h.z.clamp(-1.0, 1.0).acos();
    let theta_d = d.z.clamp(-1.0, 1.0).acos();
    let phi_d = d.y.atan2(d.x).rem_euclid(PI);
    (theta_h, theta_d, phi_d)
}

/// `(h, d)`: the half vector, and `wi` in the frame where `h` is `+z`
/// (rotated by `-phi_h` about `z`, then by `-theta_h` about `y`).
pub fn half_diff_vectors(wo: DVec3, wi: DVec3) -> (DVec3, DVec3) {
    let h = (wo + wi).normalize();
    let (theta_h, phi_h) = (h.z.clamp(-1.0, 1.0).acos(), h.y.atan2(h.x));
    let (s, c) = (-phi_h).sin_cos();
    let t = DVec3::new(c * wi.x - s * wi.y, s * wi.x + c * wi.y, wi.z);
    let (s, c) = (-theta_h).sin_cos();
    (h, DVec3::new(c * t.x + s * t.z, t.y, -s * t.x + c * t.z))
}

impl BxdfModel for Merl {
    fn f(&self, wo: DVec3, wi: DVec3) -> Rgb {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Rgb::BLACK;
        }
        self.lookup(wo, wi).unwrap_or(Rgb::BLACK)
    }

    fn sample(&self, wo: DVec3, _uc: f64, u: [f64; 2]) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        BsdfSample::reflected(self, wo, sampling::cosine_hemisphere(u), BxdfFlags::GLOSSY)
    }

    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        sampling::cosine_hemisphere_pdf(wi.z)
    }

    fn flags(&self) -> BxdfFlags {
        BxdfFlags::REFLECTION | BxdfFlags::GLOSSY
    }

    fn albedo(&self) -> Rgb {
        let wi = DVec3::new(0.5f64.sin(), 0.0, 0.5f64.cos());
        (self.f(DVec3::Z, wi) * PI).map(|v| v.min(1.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn half_diff_of_mirror_pair_and_symmetry() {
        let wi = DVec3::new(0.3, 0.2, 0.9).normalize();
        let wo = DVec3::new(-wi.x, -wi.y, wi.z);
        let (th, td, _) = half_diff(wo, wi);
        assert!(th.abs() < 1e-9);
        assert!((td - wi.z.acos()).abs() < 1e-9);
        // Reciprocity: swapping the directions only shifts phi_d by pi.
        let a = DVec3::new(0.5, -0.1, 0.7).normalize();
        let b = DVec3::new(-0.2, 0.6, 0.5).normalize();
        let (x, y) = (half_diff(a, b), half_diff(b, a));
        assert!((x.0 - y.0).abs() < 1e-12 && (x.1 - y.1).abs() < 1e-12);
        assert!((x.2 - y.2).abs() < 1e-9 || ((x.2 - y.2).abs() - PI).abs() < 1e-9);
    }

    #[test]
    fn header_and_length_errors() {
        assert!(Merl::from_bytes(&[0; 5]).unwrap_err().contains("truncated"));
        let mut b = vec![0u8; 12];
        b[0] = 91;
        assert!(Merl::from_bytes(&b).unwrap_err().contains("header"));
        let mut ok = Vec::new();
        for d in DIMS {
            ok.extend_from_slice(&(d as i32).to_le_bytes());
        }
        ok.extend_from_slice(&[0u8; 800]);
        assert!(Merl::from_bytes(&ok).unwrap_err().contains("truncated"));
        // Values: negative is missing, NaN and infinite are damage.
        let mut raw = vec![0.5; 3 * PLANE];
        raw[7] = -1.0;
        let m = Merl::from_bytes(&Merl::encode(&raw)).unwrap();
        assert_eq!(m.missing(), 1);
        raw[7] = f64::NAN;
        let e = Merl::from_bytes(&Merl::encode(&raw)).unwrap_err();
        assert_eq!(e, "MERL value 7 is NaN");
        for v in [f64::INFINITY, 1e300] {
            raw[7] = v;
            let e = Merl::from_bytes(&Merl::encode(&raw)).unwrap_err();
            assert!(
                e.starts_with("MERL value 7 is ") && e.contains("beyond f32"),
                "{e}"
            );
        }
    }
}
