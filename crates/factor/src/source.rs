//! What a factorization fits: a BRDF that can be evaluated anywhere (a
//! library material or a MERL table), or scattered measurements from a
//! CSV file; and how the fitting and held-out samples are drawn.

use crate::FactorError;
use isolux_core::{DVec3, Pcg32, Rgb};
use isolux_materials::{BxdfModel, Material, Merl};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// One BRDF measurement in the local frame (`z` = normal).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Toward the viewer.
    pub wo: DVec3,
    /// Toward the light.
    pub wi: DVec3,
    /// `f(wo, wi)` (1/sr); `None` where the source has no data.
    pub f: Option<Rgb>,
}

/// A BRDF to factor.
#[derive(Clone, Debug)]
pub enum Source {
    /// A material of the library, by name from a scene file.
    Material {
        /// A label for reports (`NAME from SCENE`).
        label: String,
        /// The model.
        material: Box<Material>,
    },
    /// A MERL measured table.
    Merl {
        /// The file.
        path: PathBuf,
        /// The table.
        merl: Merl,
    },
    /// Scattered measurements.
    Samples {
        /// The CSV file.
        path: PathBuf,
        /// Its rows.
        samples: Vec<Sample>,
        /// Rows outside the angular domain or below the horizon.
        outside: usize,
    },
}

impl Source {
    /// A one-line description for reports and `factors.toml`.
    pub fn describe(&self) -> String {
        match self {
            Source::Material { label, .. } => format!("material {label}"),
            Source::Merl { path, .. } => format!("merl {}", path.display()),
            Source::Samples { path, .. } => format!("samples {}", path.display()),
        }
    }

    /// `f(wo, wi)`, where the source can be evaluated at any direction
    /// pair; `Some(None)` where a table has no data; `None` for scattered
    /// samples, which cannot.
    pub fn eval(&self, wo: DVec3, wi: DVec3) -> Option<Option<Rgb>> {
        match self {
            Source::Material { material, .. } => Some(Some(material.f(wo, wi))),
            Source::Merl { merl, .. } => Some(merl.lookup(wo, wi)),
            Source::Samples { .. } => None,
        }
    }

    /// Whether [`Source::eval`] works (not scattered samples).
    pub fn is_evaluable(&self) -> bool {
        !matches!(self, Source::Samples { .. })
    }

    /// The source as a renderable material, where it is one.
    pub fn material(&self) -> Option<Material> {
        match self {
            Source::Material { material, .. } => Some((**material).clone()),
            Source::Merl { merl, .. } => Some(Material::Merl(merl.clone())),
            Source::Samples { .. } => None,
        }
    }
}

/// A direction uniformly distributed in solid angle over the cap
/// `theta <= theta_max`.
pub fn uniform_cap(u: [f64; 2], cos_max: f64) -> DVec3 {
    let z = 1.0 - u[0] * (1.0 - cos_max);
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * std::f64::consts::PI * u[1];
    DVec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// `n` direction pairs, each direction uniform in solid angle over the
/// cap, evaluated by the source (in parallel; deterministic for a seed).
pub fn draw(source: &Source, n: usize, theta_max_deg: f64, seed: u64) -> Vec<Sample> {
    let cos_max = theta_max_deg.to_radians().cos();
    let mut rng = Pcg32::new(seed, 0xFAC7);
    let dirs: Vec<(DVec3, DVec3)> = (0..n)
        .map(|_| {
            let wo = uniform_cap(rng.next_2d(), cos_max);
            let wi = uniform_cap(rng.next_2d(), cos_max);
            (wo, wi)
        })
        .collect();
    dirs.into_par_iter()
        .map(|(wo, wi)| Sample {
            wo,
            wi,
            f: source.eval(wo, wi).flatten(),
        })
        .collect()
}

/// Reads scattered samples: one row `wo_x, wo_y, wo_z, wi_x, wi_y, wi_z,
/// r, g, b` per line, an optional header line, `#` comments and blank
/// lines ignored. Directions are normalized; rows whose directions lie
/// below the horizon or beyond `theta_max_deg` are skipped and counted.
/// Negative values are missing data, zero is a value (the fit takes it at
/// its floor); a value that is not finite or beyond f32 is an error naming
/// the line and field.
pub fn read_csv(path: &Path, theta_max_deg: f64) -> Result<Source, FactorError> {
    let text = std::fs::read_to_string(path).map_err(|e| FactorError::Input {
        what: path.display().to_string(),
        message: format!("cannot read: {e}"),
    })?;
    let cos_max = theta_max_deg.to_radians().cos() - 1e-12;
    let mut samples = Vec::new();
    let mut outside = 0;
    // Until the first data row, a non-numeric line is the header.
    let mut header_allowed = true;
    for (k, line) in text.lines().enumerate() {
        let err = |message: String| FactorError::Input {
            what: format!("{}:{}", path.display(), k + 1),
            message,
        };
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let nums: Result<Vec<f64>, _> = fields.iter().map(|f| f.parse::<f64>()).collect();
        let nums = match nums {
            Ok(v) => v,
            Err(_) if header_allowed => {
                header_allowed = false;
                continue;
            }
            Err(_) => {
                let bad = fields
                    .iter()
                    .position(|f| f.parse::<f64>().is_err())
                    .unwrap_or(0);
                return Err(err(format!(
                    "field {} (`{}`) is not a number",
                    bad + 1,
                    fields[bad]
                )));
            }
        };
        header_allowed = false;
        if nums.len() != 9 {
            return Err(err(format!(
                "expected 9 fields (wo_x, wo_y, wo_z, wi_x, wi_y, wi_z, r, g, b), got {}",
                nums.len()
            )));
        }
        let dir = |o: usize, name: &str| -> Result<DVec3, FactorError> {
            let v = DVec3::new(nums[o], nums[o + 1], nums[o + 2]);
            let l = v.length();
            if !(l > 0.0) || !l.is_finite() {
                return Err(err(format!(
                    "{name} = {:?} is not a direction",
                    v.to_array()
                )));
            }
            Ok(v / l)
        };
        let (wo, wi) = (dir(0, "wo")?, dir(3, "wi")?);
        // Negative values are missing data (the fit excludes and counts
        // them), zero is fitted at the floor; a value that is not finite, or that f32 cannot
        // hold, is a damaged file. Such rows used to be excluded like
        // missing data (infinity) or to fail the fit with "the fitted
        // scale [inf, ...] is out of range" (1e300).
        for (o, name) in [(6, "r"), (7, "g"), (8, "b")] {
            let v = nums[o];
            if !v.is_finite() {
                return Err(err(format!(
                    "field {} ({name}) is {v}, not a finite value",
                    o + 1
                )));
            }
            if v.abs() > f32::MAX as f64 {
                return Err(err(format!(
                    "field {} ({name}) is {v:e}, beyond f32 (the factor textures' type, at most {:e})",
                    o + 1,
                    f32::MAX
                )));
            }
        }
        if wo.z < cos_max || wi.z < cos_max {
            outside += 1;
            continue;
        }
        samples.push(Sample {
            wo,
            wi,
            f: Some(Rgb::new(nums[6], nums[7], nums[8])),
        });
    }
    if samples.is_empty() {
        return Err(FactorError::Input {
            what: path.display().to_string(),
            message: format!(
                "no samples inside the domain (theta <= {theta_max_deg} degrees); {outside} outside"
            ),
        });
    }
    Ok(Source::Samples {
        path: path.to_path_buf(),
        samples,
        outside,
    })
}
