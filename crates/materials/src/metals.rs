//! Measured optical constants of metals: complex index `n + i k`.
//!
//! Tables over the visible range (about 380-780 nm) from
//! - Au, Ag, Cu: P. B. Johnson and R. W. Christy, "Optical constants of the
//!   noble metals", Phys. Rev. B 6, 4370 (1972);
//! - Cr, Fe, Ni, Ti: P. B. Johnson and R. W. Christy, "Optical constants of
//!   transition metals: Ti, V, Cr, Mn, Fe, Co, Ni, and Pd", Phys. Rev. B 9,
//!   5056 (1974);
//! - Al: A. D. Rakić, "Algorithm for the determination of intrinsic optical
//!   constants of metal films: application to aluminum", Appl. Opt. 34,
//!   4755 (1995) (Johnson and Christy did not measure aluminium);
//!
//! as transcribed by the refractiveindex.info database (public domain,
//! CC0). Values are linearly interpolated in wavelength.
//!
//! ## RGB
//! For RGB rendering each metal is evaluated at the dominant wavelengths of
//! the sRGB primaries, [`RGB_WAVELENGTHS_NM`] = 612, 549, 465 nm. The
//! spectral tables stay available for spectral rendering (wave optics).

/// Wavelengths (nm) at which RGB conductor Fresnel is evaluated: the
/// dominant wavelengths of the sRGB red, green and blue primaries.
pub const RGB_WAVELENGTHS_NM: [f64; 3] = [612.0, 549.0, 465.0];

/// A tabulated metal: rows of (wavelength um, n, k).
#[derive(Debug, PartialEq)]
pub struct Metal {
    /// Chemical symbol used in scene files.
    pub name: &'static str,
    /// Source of the data.
    pub source: &'static str,
    table: &'static [(f64, f64, f64)],
}

const JC72: &str = "Johnson & Christy, Phys. Rev. B 6, 4370 (1972)";
const JC74: &str = "Johnson & Christy, Phys. Rev. B 9, 5056 (1974)";

/// The named metals, in alphabetical order.
// Measured data: a k of 3.14 (Cr at 451 nm) is a measurement, not pi.
#[allow(clippy::approx_constant)]
pub static METALS: &[Metal] = &[
    Metal {
        name: "Ag",
        source: JC72,
        table: &[
            (0.3679, 0.07, 1.657),
            (0.3815, 0.05, 1.864),
            (0.3974, 0.05, 2.070),
            (0.4133, 0.05, 2.275),
            (0.4305, 0.04, 2.462),
            (0.4509, 0.04, 2.657),
            (0.4714, 0.05, 2.869),
            (0.4959, 0.05, 3.093),
            (0.5209, 0.05, 3.324),
            (0.5486, 0.06, 3.586),
            (0.5821, 0.05, 3.858),
            (0.6168, 0.06, 4.152),
            (0.6595, 0.05, 4.483),
            (0.7045, 0.04, 4.838),
            (0.7560, 0.03, 5.242),
            (0.8211, 0.04, 5.727),
        ],
    },
    Metal {
        name: "Al",
        source: "Rakić, Appl. Opt. 34, 4755 (1995)",
        table: &[
            (0.36466, 0.39877, 4.3957),
            (0.41328, 0.52135, 5.0008),
            (0.44280, 0.60790, 5.3676),
            (0.47687, 0.72780, 5.7781),
            (0.51660, 0.87340, 6.2418),
            (0.56357, 1.0728, 6.7839),
            (0.61993, 1.3660, 7.4052),
            (0.65225, 1.5724, 7.7354),
            (0.68881, 1.8301, 8.0601),
            (0.72932, 2.1606, 8.3565),
            (0.77491, 2.6154, 8.4914),
            (0.79478, 2.7675, 8.3866),
        ],
    },
    Metal {
        name: "Au",
        source: JC72,
        table: &[
            (0.3679, 1.48, 1.895),
            (0.3815, 1.46, 1.933),
            (0.3974, 1.47, 1.952),
            (0.4133, 1.46, 1.958),
            (0.4305, 1.45, 1.948),
            (0.4509, 1.38, 1.914),
            (0.4714, 1.31, 1.849),
            (0.4959, 1.04, 1.833),
            (0.5209, 0.62, 2.081),
            (0.5486, 0.43, 2.455),
            (0.5821, 0.29, 2.863),
            (0.6168, 0.21, 3.272),
            (0.6595, 0.14, 3.697),
            (0.7045, 0.13, 4.103),
            (0.7560, 0.14, 4.542),
            (0.8211, 0.16, 5.083),
        ],
    },
    Metal {
        name: "Cr",
        source: JC74,
        table: &[
            (0.368, 1.87, 2.69),
            (0.381, 1.92, 2.74),
            (0.397, 2.00, 2.83),
            (0.413, 2.08, 2.93),
            (0.431, 2.19, 3.04),
            (0.451, 2.33, 3.14),
            (0.471, 2.51, 3.24),
            (0.496, 2.75, 3.30),
            (0.521, 2.94, 3.33),
            (0.549, 3.18, 3.33),
            (0.582, 3.22, 3.30),
            (0.617, 3.17, 3.30),
            (0.659, 3.09, 3.34),
            (0.704, 3.05, 3.39),
            (0.756, 3.08, 3.42),
            (0.821, 3.20, 3.48),
        ],
    },
    Metal {
        name: "Cu",
        source: JC72,
        table: &[
            (0.3679, 1.36, 1.975),
            (0.3815, 1.33, 2.045),
            (0.3974, 1.32, 2.116),
            (0.4133, 1.28, 2.207),
            (0.4305, 1.25, 2.305),
            (0.4509, 1.24, 2.397),
            (0.4714, 1.25, 2.483),
            (0.4959, 1.22, 2.564),
            (0.5209, 1.18, 2.608),
            (0.5486, 1.02, 2.577),
            (0.5821, 0.70, 2.704),
            (0.6168, 0.30, 3.205),
            (0.6595, 0.22, 3.747),
            (0.7045, 0.21, 4.205),
            (0.7560, 0.24, 4.665),
            (0.8211, 0.26, 5.180),
        ],
    },
    Metal {
        name: "Fe",
        source: JC74,
        table: &[
            (0.368, 2.02, 2.43),
            (0.381, 2.12, 2.50),
            (0.397, 2.24, 2.58),
            (0.413, 2.35, 2.65),
            (0.431, 2.48, 2.71),
            (0.451, 2.59, 2.77),
            (0.471, 2.67, 2.82),
            (0.496, 2.74, 2.88),
            (0.521, 2.86, 2.91),
            (0.549, 2.95, 2.93),
            (0.582, 2.94, 2.99),
            (0.617, 2.88, 3.05),
            (0.659, 2.92, 3.10),
            (0.704, 2.86, 3.19),
            (0.756, 2.87, 3.28),
            (0.821, 2.94, 3.39),
        ],
    },
    Metal {
        name: "Ni",
        source: JC74,
        table: &[
            (0.368, 1.70, 2.40),
            (0.381, 1.72, 2.48),
            (0.397, 1.72, 2.57),
            (0.413, 1.70, 2.69),
            (0.431, 1.71, 2.82),
            (0.451, 1.73, 2.95),
            (0.471, 1.78, 3.09),
            (0.496, 1.82, 3.25),
            (0.521, 1.85, 3.42),
            (0.549, 1.92, 3.61),
            (0.582, 1.96, 3.80),
            (0.617, 1.99, 4.02),
            (0.659, 1.99, 4.26),
            (0.704, 2.06, 4.50),
            (0.756, 2.13, 4.73),
            (0.821, 2.26, 4.97),
        ],
    },
    Metal {
        name: "Ti",
        source: JC74,
        table: &[
            (0.368, 1.90, 2.90),
            (0.381, 1.99, 2.93),
            (0.397, 2.08, 2.95),
            (0.413, 2.14, 2.98),
            (0.431, 2.21, 3.01),
            (0.451, 2.27, 3.04),
            (0.471, 2.32, 3.10),
            (0.496, 2.36, 3.19),
            (0.521, 2.44, 3.30),
            (0.549, 2.54, 3.43),
            (0.582, 2.60, 3.58),
            (0.617, 2.67, 3.72),
            (0.659, 2.76, 3.84),
            (0.704, 2.86, 3.96),
            (0.756, 3.00, 4.01),
            (0.821, 3.21, 4.01),
        ],
    },
];

impl Metal {
    /// Looks a metal up by name (case-sensitive chemical symbol).
    pub fn by_name(name: &str) -> Option<&'static Metal> {
        METALS.iter().find(|m| m.name == name)
    }

    /// Names of all metals, for error messages.
    pub fn names() -> Vec<&'static str> {
        METALS.iter().map(|m| m.name).collect()
    }

    /// `(n, k)` at `lambda_nm`, linearly interpolated (clamped at the ends
    /// of the table).
    pub fn nk(&self, lambda_nm: f64) -> (f64, f64) {
        let l = lambda_nm * 1e-3;
        let t = self.table;
        if l <= t[0].0 {
            return (t[0].1, t[0].2);
        }
        for w in t.windows(2) {
            let (a, b) = (w[0], w[1]);
            if l <= b.0 {
                let s = (l - a.0) / (b.0 - a.0);
                return (a.1 + s * (b.1 - a.1), a.2 + s * (b.2 - a.2));
            }
        }
        let last = t[t.len() - 1];
        (last.1, last.2)
    }

    /// The measured rows `(wavelength um, n, k)`, ascending, which
    /// [`Metal::nk`] interpolates (the GPU's copy).
    pub fn table(&self) -> &'static [(f64, f64, f64)] {
        self.table
    }

    /// `(eta, k)` at the RGB wavelengths.
    pub fn rgb(&self) -> ([f64; 3], [f64; 3]) {
        let v = RGB_WAVELENGTHS_NM.map(|l| self.nk(l));
        (v.map(|x| x.0), v.map(|x| x.1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_cover_the_visible_range_and_are_sorted() {
        for m in METALS {
            assert!(
                m.table[0].0 <= 0.38 && m.table[m.table.len() - 1].0 >= 0.78,
                "{}",
                m.name
            );
            assert!(m.table.windows(2).all(|w| w[0].0 < w[1].0), "{}", m.name);
        }
        assert_eq!(
            Metal::names(),
            vec!["Ag", "Al", "Au", "Cr", "Cu", "Fe", "Ni", "Ti"]
        );
    }

    #[test]
    fn interpolation_hits_table_rows() {
        let au = Metal::by_name("Au").unwrap();
        let (n, k) = au.nk(548.6);
        assert!((n - 0.43).abs() < 1e-12 && (k - 2.455).abs() < 1e-12);
        let (n, k) = au.nk(535.0);
        assert!(n < 0.62 && n > 0.43 && k > 2.081 && k < 2.455);
    }
}
