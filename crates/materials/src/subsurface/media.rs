//! Measured media of Jensen et al. 2001 (their figure 5 table): reduced
//! scattering `sigma_s'` and absorption `sigma_a` in 1/mm for red, green,
//! blue, relative index 1.3 for all (as SPEC §4 states).
//!
//! Where published copies disagree: Mitsuba's table gives chicken1 and
//! chicken2 a red absorption of 0.0015 and 0.0018; other reproductions
//! (and the monotonic red-to-blue growth of the other two channels, a
//! factor of about 5 per step) give 0.015 and 0.018, which we use: the
//! former look like decimal slips. Mitsuba also gives marble an index of
//! 1.5; we keep the paper's uniform 1.3.

/// A named homogeneous medium.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Medium {
    /// Scene-file name.
    pub name: &'static str,
    /// Reduced scattering coefficient, 1/mm, RGB.
    pub sigma_s_reduced: [f64; 3],
    /// Absorption coefficient, 1/mm, RGB.
    pub sigma_a: [f64; 3],
    /// Relative index of refraction.
    pub eta: f64,
}

const fn m(name: &'static str, s: [f64; 3], a: [f64; 3]) -> Medium {
    Medium {
        name,
        sigma_s_reduced: s,
        sigma_a: a,
        eta: 1.3,
    }
}

/// The measured media, alphabetically.
pub static MEDIA: &[Medium] = &[
    m("apple", [2.29, 2.39, 1.97], [0.0030, 0.0034, 0.046]),
    m("chicken1", [0.15, 0.21, 0.38], [0.015, 0.077, 0.19]),
    m("chicken2", [0.19, 0.25, 0.32], [0.018, 0.088, 0.20]),
    m("cream", [7.38, 5.47, 3.15], [0.0002, 0.0028, 0.0163]),
    m("ketchup", [0.18, 0.07, 0.03], [0.061, 0.97, 1.45]),
    m("marble", [2.19, 2.62, 3.00], [0.0021, 0.0041, 0.0071]),
    m("potato", [0.68, 0.70, 0.55], [0.0024, 0.0090, 0.12]),
    m("skimmilk", [0.70, 1.22, 1.90], [0.0014, 0.0025, 0.0142]),
    m("skin1", [0.74, 0.88, 1.01], [0.032, 0.17, 0.48]),
    m("skin2", [1.09, 1.59, 1.79], [0.013, 0.070, 0.145]),
    m("spectralon", [11.6, 20.4, 14.9], [0.00, 0.00, 0.00]),
    m("wholemilk", [2.55, 3.21, 3.77], [0.0011, 0.0024, 0.014]),
];

impl Medium {
    /// Looks a medium up by name.
    pub fn by_name(name: &str) -> Option<&'static Medium> {
        MEDIA.iter().find(|m| m.name == name)
    }

    /// All names, for error messages.
    pub fn names() -> Vec<&'static str> {
        MEDIA.iter().map(|m| m.name).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::subsurface::Dipole;

    #[test]
    fn twelve_media_with_plausible_albedos() {
        assert_eq!(MEDIA.len(), 12);
        for m in MEDIA {
            for c in 0..3 {
                let d = Dipole::new(m.sigma_s_reduced[c], m.sigma_a[c], m.eta);
                let r = d.total();
                assert!((0.0..=1.0).contains(&r), "{} {c}: {r}", m.name);
            }
        }
        // Milk is brighter in red than in blue (absorption rises to blue);
        // ketchup is red.
        let k = Medium::by_name("ketchup").unwrap();
        let rd = |c: usize| Dipole::new(k.sigma_s_reduced[c], k.sigma_a[c], 1.3).total();
        assert!(rd(0) > 3.0 * rd(1) && rd(0) > 3.0 * rd(2));
    }
}
