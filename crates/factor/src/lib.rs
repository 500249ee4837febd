//! # isolux-factor
//!
//! Homomorphic factorization of BRDFs (McCool, Ang and Ahmad, SIGGRAPH
//! 2001; seed 004): any BRDF, analytic or measured, as
//!
//! ```text
//! f(wo, wi) ~= scale * p(wo) * q(h) * p(wi) * r(theta_h, theta_d)    per colour channel
//! ```
//!
//! with `p` and `q` positive parabolic-map textures and `r` a small
//! positive table over the half and difference angles (optional: `--hd-res
//! 0` gives the paper's plain `p q p`), found by linear least squares on
//! `ln f` ([`fit()`]). Positive by construction (the unknowns are
//! logarithms), reciprocal by construction (`p` appears at both ends, `h`,
//! `theta_h` and `theta_d` are symmetric), and the error it minimizes is
//! relative. [`svd`] is the baseline, Kautz and
//! McCool's separable approximation; [`metrics`] measures both on held-out
//! samples; [`output`] writes the files the `factored` material reads.
//!
//! ```
//! use isolux_factor::{factorize, RunOptions, Source};
//! use isolux_materials::{Diffuse, Material};
//! let source = Source::Material {
//!     label: "chalk".into(),
//!     material: Box::new(Material::Diffuse(Diffuse::default())),
//! };
//! let mut opts = RunOptions::default();
//! opts.fit.res = 8;
//! opts.samples = 2_000;
//! opts.held_out = 500;
//! opts.svd_ranks = 0;
//! let (fact, report) = factorize(&source, &opts).unwrap();
//! // A constant BRDF is exactly a product of constants.
//! assert!(report.factored.relative_rms < 1e-6);
//! let value = fact.scale.r * fact.p[0].r.powi(2) * fact.q[0].r * fact.r[0].r;
//! assert!((value - 0.5 / std::f64::consts::PI).abs() < 1e-6);
//! ```
#![warn(missing_docs)]

pub mod fit;
pub mod metrics;
pub mod output;
pub mod source;
pub mod svd;

pub use fit::{
    fit, Factorization, FitOptions, FitStats, CG_MAX_ITERATIONS, CG_TOLERANCE, DENSE_MAX_RES,
};
pub use metrics::{evaluate, Metrics};
pub use output::write_dir;
pub use source::{draw, read_csv, Sample, Source};
pub use svd::Separable;

use std::fmt;

/// Errors of a factorization, each naming what was wrong.
#[derive(Debug, thiserror::Error)]
pub enum FactorError {
    /// A bad file, flag or value: `what` names it.
    #[error("{what}: {message}")]
    Input {
        /// The file (with line) or flag.
        what: String,
        /// What is wrong.
        message: String,
    },
    /// The fit could not be computed.
    #[error("factorization failed: {0}")]
    Fit(String),
    /// Writing the results failed.
    #[error(transparent)]
    Io(#[from] isolux_io::IoError),
}

impl FactorError {
    /// [`FactorError::Input`] for the flag or file `what`, as an `Err`
    /// (the options' checks return it as it is).
    pub(crate) fn input<T>(what: &str, message: String) -> Result<T, Self> {
        Err(Self::Input {
            what: what.to_string(),
            message,
        })
    }
}

/// Settings of a whole run: the fit, the samples, the baseline.
#[derive(Clone, Debug, PartialEq)]
pub struct RunOptions {
    /// The fit itself.
    pub fit: FitOptions,
    /// Fitting samples drawn from an evaluable source (ignored for CSV
    /// data, which is used as given).
    pub samples: usize,
    /// Held-out samples drawn from an evaluable source (for CSV data,
    /// every fifth row is held out instead).
    pub held_out: usize,
    /// Seed of the sample directions.
    pub seed: u64,
    /// Largest SVD rank reported (0: no baseline). The baseline is
    /// computed for evaluable sources at `res <= 64`.
    pub svd_ranks: usize,
}

impl RunOptions {
    /// The most fitting or held-out samples drawn: about 5 GB of memory
    /// and half a minute of fitting on 2 cores (200,000, the default, take
    /// 125 MB and a second); 2^32 failed to allocate.
    pub const MAX_SAMPLES: usize = 10_000_000;
    /// The largest SVD rank reported (each rank is a row of the report).
    pub const MAX_SVD_RANK: usize = 32;

    /// Refuses sample counts and ranks beyond the limits above, and
    /// [`FitOptions::validate`]'s refinement count, naming the flag.
    pub fn validate(&self) -> Result<(), FactorError> {
        let bad = FactorError::input;
        for (what, n) in [
            ("--fit-samples", self.samples),
            ("--held-out", self.held_out),
        ] {
            if n > Self::MAX_SAMPLES {
                return bad(
                    what,
                    format!("must be at most {}, got {n}", Self::MAX_SAMPLES),
                );
            }
        }
        if self.svd_ranks > Self::MAX_SVD_RANK {
            return bad(
                "--svd-rank",
                format!(
                    "must be at most {}, got {}",
                    Self::MAX_SVD_RANK,
                    self.svd_ranks
                ),
            );
        }
        Ok(())
    }
}

impl Default for RunOptions {
    fn default() -> Self {
        Self {
            fit: FitOptions::default(),
            samples: 200_000,
            held_out: 50_000,
            seed: 1,
            svd_ranks: 2,
        }
    }
}

/// One baseline row of the report.
#[derive(Clone, Debug, PartialEq)]
pub struct Baseline {
    /// SVD rank.
    pub rank: usize,
    /// Texels stored per channel (`2 rank res^2`).
    pub storage_texels: usize,
    /// Held-out errors.
    pub metrics: Metrics,
}

/// What a run measured.
#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    /// The source, described.
    pub source: String,
    /// Texels per side.
    pub res: usize,
    /// Texels per side of the `r(theta_h, theta_d)` table (0: none).
    pub hd_res: usize,
    /// The smoothness weight used.
    pub smoothness: f64,
    /// The dynamic range of the fit's floor ([`FitOptions::dynamic_range`]).
    pub dynamic_range: f64,
    /// Held-out samples.
    pub held_out: usize,
    /// Errors of the homomorphic factors.
    pub factored: Metrics,
    /// Texels stored per channel by the factors (`2 res^2 + hd_res^2`).
    pub storage_texels: usize,
    /// SVD baselines, by rank.
    pub baselines: Vec<Baseline>,
    /// Why there is no baseline, when there is none, or how it was
    /// computed, when that differs from the usual.
    pub baseline_note: Option<String>,
    /// CSV rows outside the domain.
    pub outside: usize,
}

impl fmt::Display for Report {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "held-out errors ({} samples, {}):",
            self.held_out, self.source
        )?;
        writeln!(
            f,
            "| method | texels per channel | relative RMS | cosine-weighted abs RMS (1/sr) |"
        )?;
        writeln!(f, "|---|---:|---:|---:|")?;
        let method = if self.hd_res > 0 {
            format!(
                "homomorphic p(wo) q(h) p(wi) r(theta_h, theta_d), {r} x {r} and {d} x {d}",
                r = self.res,
                d = self.hd_res
            )
        } else {
            format!("homomorphic p(wo) q(h) p(wi), {r} x {r}", r = self.res)
        };
        writeln!(
            f,
            "| {method} | {} | {:.4} | {:.4} |",
            self.storage_texels, self.factored.relative_rms, self.factored.cosine_abs_rms,
        )?;
        for b in &self.baselines {
            writeln!(
                f,
                "| SVD rank {} (Kautz-McCool, h/d){} | {} | {:.4} | {:.4} |",
                b.rank,
                if b.storage_texels == self.storage_texels {
                    ", equal storage"
                } else if b.rank == 1 {
                    ", the closest storage"
                } else {
                    ""
                },
                b.storage_texels,
                b.metrics.relative_rms,
                b.metrics.cosine_abs_rms
            )?;
        }
        if let Some(n) = &self.baseline_note {
            if self.baselines.is_empty() {
                writeln!(f, "(no SVD baseline: {n})")?;
            } else {
                writeln!(f, "(SVD baseline {n})")?;
            }
        }
        Ok(())
    }
}

/// Three significant digits, in exponent form outside 1e-3..1e4.
fn short(v: f64) -> String {
    if v != 0.0 && v.is_finite() && !(1e-3..1e4).contains(&v.abs()) {
        format!("{v:.2e}")
    } else {
        format!("{v:.4}")
    }
}

/// Runs the whole pipeline: samples, fit, held-out errors, baseline.
pub fn factorize(
    source: &Source,
    opts: &RunOptions,
) -> Result<(Factorization, Report), FactorError> {
    opts.fit.validate()?;
    opts.validate()?;
    let theta = opts.fit.theta_max_deg;
    let (train, held, outside) = match source {
        Source::Samples {
            samples, outside, ..
        } => {
            let (mut a, mut b) = (Vec::new(), Vec::new());
            for (k, s) in samples.iter().enumerate() {
                if k % 5 == 4 {
                    b.push(*s);
                } else {
                    a.push(*s);
                }
            }
            (a, b, *outside)
        }
        _ => {
            // Too few fitting samples leave the fit undetermined; no
            // held-out ones would report an error of 0, as if exact.
            for (what, n) in [
                ("--fit-samples", opts.samples),
                ("--held-out", opts.held_out),
            ] {
                if n < 16 {
                    return FactorError::input(what, format!("must be at least 16, got {n}"));
                }
            }
            (
                draw(source, opts.samples, theta, opts.seed),
                draw(source, opts.held_out, theta, opts.seed.wrapping_add(0x9E37)),
                0,
            )
        }
    };
    let fact = fit(&train, &opts.fit)?;
    let material = fact.material()?;
    use isolux_materials::BxdfModel;
    let factored = evaluate(&held, fact.floor, |wo, wi| material.f(wo, wi));
    // A fit whose error exceeds the BRDF itself is not an approximation of
    // it: with `--smoothness 0` the texels no sample reaches are left free,
    // and their products reached 1e12 (cosine-weighted error 7e12 on a
    // Cook-Torrance lobe of RMS 0.1), a result that used to be written.
    if !(factored.cosine_abs_rms <= factored.reference_rms) {
        return Err(FactorError::Fit(format!(
            "the factors miss the BRDF: their cosine-weighted error on the held-out samples, \
             {}, exceeds the BRDF's own RMS, {} (zero would approximate it better); \
             adjust --smoothness (now {}), or fit more samples",
            short(factored.cosine_abs_rms),
            short(factored.reference_rms),
            isolux_core::short_number(opts.fit.smoothness)
        )));
    }
    let nd = opts.fit.hd_res();
    let storage = 2 * opts.fit.res * opts.fit.res + nd * nd;
    let (baselines, baseline_note) = if opts.svd_ranks == 0 {
        (Vec::new(), Some("disabled".to_string()))
    } else if opts.fit.res > 64 {
        (
            Vec::new(),
            Some("computed only up to res 64 (its matrix has res^4 entries)".to_string()),
        )
    } else {
        let fits = if source.is_evaluable() {
            Separable::fit(source, opts.fit.res, theta, opts.svd_ranks)
        } else {
            Separable::fit_scattered(&train, opts.fit.res, opts.svd_ranks)
        };
        (
            fits.unwrap_or_default()
                .iter()
                .map(|s| Baseline {
                    rank: s.rank(),
                    storage_texels: s.storage_texels(),
                    metrics: evaluate(&held, fact.floor, |wo, wi| s.eval(wo, wi)),
                })
                .collect(),
            (!source.is_evaluable()).then(|| {
                "binned: each fitting sample's value goes to the matrix entry of its nearest h and d texels".to_string()
            }),
        )
    };
    let report = Report {
        source: source.describe(),
        res: opts.fit.res,
        hd_res: nd,
        smoothness: opts.fit.smoothness,
        dynamic_range: opts.fit.dynamic_range,
        held_out: held.len(),
        factored,
        storage_texels: storage,
        baselines,
        baseline_note,
        outside,
    };
    Ok((fact, report))
}
