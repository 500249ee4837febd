//! # Mixture of materials
//!
//! A weighted average of lobes, as the seed combines specular models with
//! a diffuse base:
//!
//! ```text
//! f(wo, wi) = sum_i w_i f_i(wo, wi),   sum_i w_i <= 1
//! ```
//!
//! Each component conserves energy, so the mixture does. Sampling picks
//! component `i` with probability `w_i / sum w`, samples it, and reports
//! the full mixture density `sum_j (w_j / sum w) pdf_j` (one-sample MIS
//! with the balance heuristic). Components must be non-delta reflection
//! models (a delta lobe and a density cannot share one pdf); the mixture
//! shades in one frame, whose tangent is the first component's.
//!
//! | name | type | default | meaning |
//! |---|---|---|---|
//! | `components` | array of `{ material = "name", weight = w }` | required | earlier materials and their weights (`w >= 0`, sum <= 1) |
//!
//! Source: seed 002 (lobe mixtures); Veach 1997 §9.2.4 (one-sample MIS).
//!
//! ```
//! let scene = r#"
//! [[material]]
//! name = "base"
//! type = "diffuse"
//! reflectance = [0.8, 0.2, 0.2]
//!
//! [[material]]
//! name = "sheen"
//! type = "ggx"
//! roughness = 0.1
//!
//! [[material]]
//! name = "car_paint"
//! type = "mix"
//! components = [{ material = "base", weight = 0.7 }, { material = "sheen", weight = 0.3 }]
//! "#;
//! let doc: toml::Table = toml::from_str(scene).unwrap();
//! assert_eq!(doc["material"][2]["components"].as_array().unwrap().len(), 2);
//! ```

use crate::bxdf::{BsdfSample, BxdfFlags, BxdfModel};
use crate::Material;
use isolux_core::{DVec3, Rgb};

/// Weighted mixture of non-delta materials.
#[derive(Clone, Debug, PartialEq)]
pub struct Mix {
    /// Components and weights.
    pub components: Vec<(Material, f64)>,
}

impl Mix {
    fn total(&self) -> f64 {
        self.components.iter().map(|c| c.1).sum()
    }
}

impl BxdfModel for Mix {
    fn f(&self, wo: DVec3, wi: DVec3) -> Rgb {
        let mut f = Rgb::BLACK;
        for (m, w) in &self.components {
            f += m.f(wo, wi) * *w;
        }
        f
    }

    fn sample(&self, wo: DVec3, uc: f64, u: [f64; 2]) -> Option<BsdfSample> {
        let total = self.total();
        if !(total > 0.0) {
            return None;
        }
        let mut acc = 0.0;
        let mut chosen = self.components.len() - 1;
        let mut uc_rest = uc;
        for (i, (_, w)) in self.components.iter().enumerate() {
            let p = w / total;
            if uc < acc + p || i + 1 == self.components.len() {
                chosen = i;
                uc_rest = if p > 0.0 {
                    ((uc - acc) / p).clamp(0.0, 1.0 - f64::EPSILON)
                } else {
                    0.0
                };
                break;
            }
            acc += p;
        }
        let s = self.components[chosen].0.sample(wo, uc_rest, u)?;
        let pdf = self.pdf(wo, s.wi);
        Some(BsdfSample {
            wi: s.wi,
            f: self.f(wo, s.wi),
            pdf,
            flags: s.flags,
            eta: 1.0,
        })
    }

    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        let total = self.total();
        if !(total > 0.0) {
            return 0.0;
        }
        self.components
            .iter()
            .map(|(m, w)| w / total * m.pdf(wo, wi))
            .sum()
    }

    fn flags(&self) -> BxdfFlags {
        self.components
            .iter()
            .fold(BxdfFlags::default(), |f, (m, _)| f | m.flags())
    }

    fn albedo(&self) -> Rgb {
        let mut a = Rgb::BLACK;
        for (m, w) in &self.components {
            a += m.albedo() * *w;
        }
        a
    }
}
