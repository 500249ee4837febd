//! Spectral sampling and colour: wavelengths across the visible band, the
//! CIE 1931 2-degree colour-matching functions at those wavelengths, and
//! XYZ to linear sRGB.
//!
//! Wavelengths are placed **uniformly in wavenumber** `kappa = 1 / lambda`
//! (1/um), midpoints of `n` equal cells over `[1/0.78, 1/0.38]`. The
//! diffraction integral depends on `lambda` only through `kappa` (every
//! phase is `2 pi kappa (...)`), so on such a comb the phase factors of
//! neighbouring wavelengths differ by one constant complex ratio per kernel:
//! [`crate::gabor`] evaluates all `n` wavelengths with two complex
//! exponentials per kernel plus `n` complex products, instead of `n`
//! exponentials.
//!
//! The colour of a spectral BRDF is `rgb = sum_j f(lambda_j) W_j`, with
//! `W_j = M cmf(lambda_j) lambda_j^2 dkappa` (`dlambda = lambda^2 dkappa`)
//! and `M` the XYZ to linear sRGB (D65) matrix. The CIE functions are taken
//! **at the same wavelengths** the BRDF is evaluated at (SPEC §3 notes that
//! the public reference code mixes two grids). Each channel is normalized
//! so that a spectrally flat reflectance of 1 gives `rgb = (1, 1, 1)`
//! (equal-energy white, the convention of an RGB renderer whose lights are
//! specified in RGB): for a fixed comb by its own sum (exactly white), for
//! randomly shifted ("hero") combs by the band integral (unbiased on
//! average).

use crate::cie_table::CIE_1931_2DEG_5NM;

/// Shortest wavelength of the visible band (um).
pub const LAMBDA_MIN_UM: f64 = 0.38;
/// Longest wavelength of the visible band (um).
pub const LAMBDA_MAX_UM: f64 = 0.78;

/// XYZ to linear sRGB (D65 white), IEC 61966-2-1.
pub const XYZ_TO_SRGB: [[f64; 3]; 3] = [
    [3.2404542, -1.5371385, -0.4985314],
    [-0.9692660, 1.8760108, 0.0415560],
    [0.0556434, -0.2040259, 1.0572252],
];

/// CIE 1931 2-degree colour-matching functions `[x, y, z]` at `lambda_nm`,
/// linearly interpolated in the 5 nm table; zero outside 380-780 nm.
pub fn cmf(lambda_nm: f64) -> [f64; 3] {
    if !(380.0..=780.0).contains(&lambda_nm) {
        return [0.0; 3];
    }
    let t = (lambda_nm - 380.0) / 5.0;
    let i = (t.floor() as usize).min(79);
    let f = t - i as f64;
    let (a, b) = (CIE_1931_2DEG_5NM[i], CIE_1931_2DEG_5NM[i + 1]);
    [
        a[0] + (b[0] - a[0]) * f,
        a[1] + (b[1] - a[1]) * f,
        a[2] + (b[2] - a[2]) * f,
    ]
}

/// Linear sRGB of a monochromatic unit spectrum at `lambda_nm`.
pub fn srgb_of_wavelength(lambda_nm: f64) -> [f64; 3] {
    let x = cmf(lambda_nm);
    let m = XYZ_TO_SRGB;
    [0, 1, 2].map(|r| m[r][0] * x[0] + m[r][1] * x[1] + m[r][2] * x[2])
}

/// [`srgb_of_wavelength`] divided by the band integral per channel, at
/// the nodes of the CIE table (380, 385, ..., 780 nm): interpolated
/// linearly, as [`cmf`] is, these give the hero comb's colour weights
/// (`Comb::shifted`) without the Jacobian. The GPU's copy.
pub fn normalized_srgb_nodes() -> Vec<[f64; 3]> {
    let norm = band_integral();
    (0..=80)
        .map(|i| {
            let c = srgb_of_wavelength(380.0 + 5.0 * i as f64);
            [0, 1, 2].map(|k| c[k] / norm[k])
        })
        .collect()
}

/// `integral srgb(lambda) dlambda` over the band, per channel (nm units),
/// computed once (every hero comb of every shading point needs it).
fn band_integral() -> [f64; 3] {
    static BAND: std::sync::OnceLock<[f64; 3]> = std::sync::OnceLock::new();
    *BAND.get_or_init(integrate_band)
}

fn integrate_band() -> [f64; 3] {
    let n = 4000;
    let d = 400.0 / n as f64;
    let mut s = [0.0; 3];
    for i in 0..n {
        let c = srgb_of_wavelength(380.0 + (i as f64 + 0.5) * d);
        for k in 0..3 {
            s[k] += c[k] * d;
        }
    }
    s
}

/// A comb of wavelengths uniform in wavenumber: `kappa_j = k0 + j dk`.
#[derive(Clone, Debug, PartialEq)]
pub struct Comb {
    /// First wavenumber (1/um), the longest wavelength.
    pub k0: f64,
    /// Wavenumber step (1/um); 0 for a single wavelength.
    pub dk: f64,
    /// Number of wavelengths.
    pub n: usize,
    /// Colour weight of each wavelength (see the module docs).
    pub rgb: Vec<[f64; 3]>,
}

impl Comb {
    /// One wavelength (um), grey: equal R, G and B weights of 1.
    pub fn single(lambda_um: f64) -> Self {
        Self {
            k0: 1.0 / lambda_um,
            dk: 0.0,
            n: 1,
            rgb: vec![[1.0; 3]],
        }
    }

    /// `n` wavelengths at the midpoints of equal wavenumber cells across the
    /// visible band, normalized so that a flat spectrum is exactly white.
    pub fn visible(n: usize) -> Self {
        let mut c = Self::shifted(n.max(1), 0.5);
        for ch in 0..3 {
            let s: f64 = c.rgb.iter().map(|w| w[ch]).sum();
            if s.abs() > 0.0 {
                for w in &mut c.rgb {
                    w[ch] /= s;
                }
            }
        }
        c
    }

    /// `n` wavelengths at offset `xi` in [0, 1) inside equal wavenumber
    /// cells (a hero-wavelength comb), weighted so that
    /// `sum_j f(lambda_j) W_j` is an unbiased estimate of the band integral
    /// when `xi` is uniform.
    pub fn shifted(n: usize, xi: f64) -> Self {
        let (kmin, kmax) = (1.0 / LAMBDA_MAX_UM, 1.0 / LAMBDA_MIN_UM);
        let dk = (kmax - kmin) / n as f64;
        let k0 = kmin + xi.clamp(0.0, 1.0 - 1e-12) * dk;
        let norm = band_integral();
        let rgb = (0..n)
            .map(|j| {
                let lambda_nm = 1000.0 / (k0 + j as f64 * dk);
                // dlambda = lambda^2 dkappa, in nm: (lambda_nm^2 / 1000) dk.
                let jac = lambda_nm * lambda_nm / 1000.0 * dk;
                let c = srgb_of_wavelength(lambda_nm);
                [0, 1, 2].map(|k| c[k] * jac / norm[k])
            })
            .collect();
        Self { k0, dk, n, rgb }
    }

    /// Wavelength `j` in um.
    pub fn lambda_um(&self, j: usize) -> f64 {
        1.0 / (self.k0 + j as f64 * self.dk)
    }

    /// Colour of per-wavelength values `f_j`, negative channels (spectral
    /// colours outside the sRGB gamut) clamped to zero.
    pub fn to_rgb(&self, f: &[f64]) -> [f64; 3] {
        let mut s = [0.0; 3];
        for (v, w) in f.iter().zip(&self.rgb) {
            for k in 0..3 {
                s[k] += v * w[k];
            }
        }
        s.map(|x| x.max(0.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cmf_peaks_and_white() {
        // y_bar peaks at 555 nm with value 1 (the definition of the table).
        assert_eq!(cmf(555.0)[1], 1.0);
        assert_eq!(cmf(300.0), [0.0; 3]);
        // Equal-energy white has equal X, Y and Z integrals (CIE design).
        let mut s = [0.0; 3];
        for i in 0..400 {
            let c = cmf(380.0 + i as f64 + 0.5);
            for k in 0..3 {
                s[k] += c[k];
            }
        }
        assert!((s[0] / s[1] - 1.0).abs() < 0.01, "{s:?}");
        assert!((s[2] / s[1] - 1.0).abs() < 0.01, "{s:?}");
    }

    #[test]
    fn d65_white_point_maps_to_srgb_white() {
        // The matrix maps the D65 white (x, y) = (0.3127, 0.3290), Y = 1, to
        // R = G = B = 1.
        let (x, y) = (0.3127, 0.3290);
        let xyz = [x / y, 1.0, (1.0 - x - y) / y];
        let m = XYZ_TO_SRGB;
        for r in m {
            let v = r[0] * xyz[0] + r[1] * xyz[1] + r[2] * xyz[2];
            assert!((v - 1.0).abs() < 2e-3, "{v}");
        }
    }

    #[test]
    fn flat_spectrum_is_white() {
        let c = Comb::visible(16);
        assert_eq!(c.n, 16);
        let rgb = c.to_rgb(&[1.0; 16]);
        for v in rgb {
            assert!((v - 1.0).abs() < 1e-12);
        }
        // A hero comb is white on average over its offset.
        let mut s = [0.0; 3];
        let m = 64;
        for i in 0..m {
            let c = Comb::shifted(4, (i as f64 + 0.5) / m as f64);
            let v = c.to_rgb(&[1.0; 4]);
            for k in 0..3 {
                s[k] += v[k] / m as f64;
            }
        }
        for v in s {
            assert!((v - 1.0).abs() < 0.02, "{s:?}");
        }
    }

    #[test]
    fn monochromatic_colours() {
        let red = srgb_of_wavelength(650.0);
        assert!(red[0] > 0.0 && red[0] > 10.0 * red[1].max(0.0) && red[2].abs() < 0.05 * red[0]);
        let blue = srgb_of_wavelength(450.0);
        assert!(blue[2] > blue[0] && blue[2] > blue[1]);
    }
}
