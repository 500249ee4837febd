//! The `[[material]]` tables: every model's keys, defaults and checks,
//! the media's coefficients, roughness, Fresnel terms and wave surfaces.

use super::{direction, reflectance, vec3, MATERIAL_TYPES};
use crate::reader::{Result, Table, Value};
use isolux_core::{DVec3, Rgb};
use isolux_materials::cook_torrance::{Masking, NormalDistribution};
use isolux_materials::gaussian::GaussianDistribution;
use isolux_materials::metals::Metal;
use isolux_materials::microfacet::{Kind, Microfacet};
use isolux_materials::subsurface::Medium;
use isolux_materials::subsurface_material::SubsurfaceMode;
use isolux_materials::{
    Beckmann, BlinnPhong, BxdfModel, Conductor, CookTorrance, Dielectric, Diffuse, Fresnel,
    Gaussian, Ggx, Material, Mix, Phong,
};
use isolux_materials::{HeidrichSeidel, Plastic, Subsurface, SubsurfaceBrdf, Ward};
use std::path::Path;

/// Keys that select a Fresnel term.
const FRESNEL_KEYS: &[&str] = &["metal", "eta", "k", "ior", "schlick"];

/// Material keys whose value is one of a fixed set of strings, with those
/// strings. The parser reads each key through the same list, so this table
/// cannot drift from it; `isolux view` offers the lists as menus. (`metal`
/// takes [`Metal::names`], a list built at run time, and `type` takes
/// [`MATERIAL_TYPES`].)
pub const MATERIAL_CHOICES: &[(&str, &[&str])] = &[
    ("distribution", DISTRIBUTIONS),
    ("masking", MASKINGS),
    ("mode", SUBSURFACE_MODES),
    ("model", WAVE_MODELS),
    ("obliquity", OBLIQUITIES),
    ("mapping", MAPPINGS),
    ("axis", AXES),
];

/// Material keys whose value is an integer, with the range the parser
/// accepts (inclusive): `isolux view` edits them in whole steps within it.
/// Every other numeric key takes a float (an integer written for it, as in
/// `exponent = 40`, is read as one).
pub const MATERIAL_INTEGERS: &[(&str, u64, u64)] = &[("wavelengths", WAVELENGTHS.0, WAVELENGTHS.1)];

/// `cook_torrance.distribution`.
const DISTRIBUTIONS: &[&str] = &["beckmann", "ggx", "gaussian"];
/// `cook_torrance.masking`.
const MASKINGS: &[&str] = &["cook_torrance", "smith"];
/// `subsurface.mode`.
const SUBSURFACE_MODES: &[&str] = &["dipole", "random_walk"];
/// `wave.model`.
const WAVE_MODELS: &[&str] = &["ghs", "ohs"];
/// `wave.obliquity`.
const OBLIQUITIES: &[&str] = &["reciprocal", "seed"];
/// `wave.mapping`.
const MAPPINGS: &[&str] = &["planar", "spherical", "cylindrical"];
/// `wave.axis`.
const AXES: &[&str] = &["x", "y", "z"];
/// `wave.wavelengths`: the range of the number of wavelengths.
const WAVELENGTHS: (u64, u64) = (1, isolux_materials::wave::MAX_WAVELENGTHS as u64);

pub(super) fn material(
    t: &Table,
    names: &[String],
    earlier: &[Material],
    base_dir: &Path,
) -> Result<Material> {
    let ty = t.req("type")?.choice(MATERIAL_TYPES)?;
    let allow = |extra: &[&str]| {
        let mut keys = vec!["name", "type"];
        keys.extend_from_slice(extra);
        t.allow(&keys)
    };
    match ty {
        "diffuse" => {
            allow(&["reflectance"])?;
            let mut d = Diffuse::default();
            if let Some(v) = t.get("reflectance") {
                d.reflectance = reflectance(&v)?;
            }
            Ok(Material::Diffuse(d))
        }
        "phong" | "blinn_phong" => {
            allow(&["exponent", "specular", "reflectance"])?;
            let exponent = match t.get("exponent") {
                Some(v) => {
                    let n = v.f64()?;
                    if !(0.0..=1e6).contains(&n) {
                        return Err(v.error(format!("exponent must lie in [0, 1e6], got {n}")));
                    }
                    n
                }
                None => 32.0,
            };
            let (specular, diffuse) = lobe_weights(t)?;
            Ok(if ty == "phong" {
                Material::Phong(Phong::new(exponent, specular, diffuse))
            } else {
                Material::BlinnPhong(BlinnPhong::new(exponent, specular, diffuse))
            })
        }
        "gaussian" => {
            allow(&["m", "specular", "reflectance"])?;
            let m = match t.get("m") {
                Some(v) => {
                    let m = v.f64()?;
                    let least = isolux_materials::gaussian::MIN_M;
                    if !(m >= least && m <= 1.0) {
                        return Err(v.error(format!(
                            "m must lie in [{least:e}, 1] radians, got {m} (a narrower highlight \
                             is a mirror: use `conductor`, or `ggx` with a small roughness)"
                        )));
                    }
                    m
                }
                None => 0.2,
            };
            let (specular, diffuse) = lobe_weights(t)?;
            Ok(Material::Gaussian(Gaussian::new(m, specular, diffuse)))
        }
        "ward" => {
            allow(&["alpha_u", "alpha_v", "specular", "reflectance", "tangent"])?;
            let alpha = |key: &str| -> Result<f64> {
                t.get(key).map_or(Ok(0.15), |v| roughness_value(&v, key))
            };
            let (specular, diffuse) = lobe_weights(t)?;
            let mut w = Ward::new(alpha("alpha_u")?, alpha("alpha_v")?, specular, diffuse);
            w.tangent = t.get("tangent").map(|v| direction(&v)).transpose()?;
            Ok(Material::Ward(w))
        }
        "heidrich_seidel" => {
            allow(&[
                "exponent",
                "specular",
                "isotropic",
                "reflectance",
                "tangent",
            ])?;
            let exponent = match t.get("exponent") {
                Some(v) => {
                    let n = v.f64()?;
                    if !(n > 0.0 && n <= 1e4) {
                        return Err(v.error(format!("exponent must lie in (0, 1e4], got {n}")));
                    }
                    n
                }
                None => 40.0,
            };
            let (specular, diffuse) = lobe_weights(t)?;
            let iso = match t.get("isotropic") {
                Some(v) => reflectance(&v)?,
                None => Rgb::BLACK,
            };
            let sum = specular + diffuse + iso;
            if sum.max_component() > 1.0 + 1e-12 {
                return Err(t.error(format!(
                    "reflectance + specular + isotropic = [{}] exceeds 1: the material would create energy",
                    sum.to_array().map(decimals12).join(", ")
                )));
            }
            let mut m = HeidrichSeidel::new(exponent, specular, iso, diffuse);
            m.tangent = t.get("tangent").map(|v| direction(&v)).transpose()?;
            Ok(Material::HeidrichSeidel(m))
        }
        "cook_torrance" => {
            let mut keys = vec!["roughness", "distribution", "masking", "reflectance"];
            keys.extend_from_slice(FRESNEL_KEYS);
            allow(&keys)?;
            let dist = match t.get("distribution") {
                Some(v) => v.choice(DISTRIBUTIONS)?,
                None => "beckmann",
            };
            let masking = match t.get("masking") {
                Some(v) => match v.choice(MASKINGS)? {
                    "smith" if dist == "gaussian" => {
                        return Err(v.error(
                            "smith masking needs distribution = \"beckmann\" or \"ggx\" (the Gaussian has no closed-form Lambda)",
                        ))
                    }
                    "smith" => Masking::Smith,
                    _ => Masking::VGroove,
                },
                None => Masking::VGroove,
            };
            let rough = t
                .get("roughness")
                .map_or(Ok(0.3), |v| roughness_value(&v, "roughness"))?;
            let distribution = match dist {
                "ggx" => NormalDistribution::Analytic(Microfacet::isotropic(Kind::Ggx, rough)),
                "beckmann" => {
                    NormalDistribution::Analytic(Microfacet::isotropic(Kind::Beckmann, rough))
                }
                _ => NormalDistribution::Gaussian(GaussianDistribution::new(rough)),
            };
            let fresnel = if FRESNEL_KEYS.iter().any(|k| t.get(k).is_some()) {
                fresnel(t)?
            } else {
                Fresnel::Dielectric { ior: 1.5 }
            };
            let reflectance = match t.get("reflectance") {
                Some(v) => reflectance(&v)?,
                None => Rgb::BLACK,
            };
            Ok(Material::CookTorrance(CookTorrance {
                distribution,
                masking,
                fresnel,
                reflectance,
            }))
        }
        "factored" => {
            allow(&["dir"])?;
            let dv = t.req("dir")?;
            let dir = base_dir.join(dv.str()?);
            let m = crate::factored_files::load_factored(&dir).map_err(|e| dv.error(e))?;
            Ok(Material::Factored(m))
        }
        "merl" => {
            allow(&["file"])?;
            let fv = t.req("file")?;
            let file = base_dir.join(fv.str()?);
            let m = isolux_materials::Merl::read(&file).map_err(|e| fv.error(e))?;
            Ok(Material::Merl(m))
        }
        "wave" => {
            allow(&[
                "heightfield",
                "texel_um",
                "vertical_scale",
                "raw_size",
                "model",
                "obliquity",
                "metal",
                "ior",
                "coherence_um",
                "mapping",
                "axis",
                "center",
                "um_per_unit",
                "wavelengths",
            ])?;
            wave_material(t, base_dir)
        }
        "mix" => {
            allow(&["components"])?;
            let cv = t.req("components")?;
            let mut components = Vec::new();
            let mut total = 0.0;
            for c in cv.array()? {
                let ct = c.table()?;
                ct.allow(&["material", "weight"])?;
                let mv = ct.req("material")?;
                let name = mv.str()?;
                let idx = names.iter().position(|n| n == name).ok_or_else(|| {
                    mv.error(format!(
                        "unknown material \"{name}\": a mix refers to materials defined before it (defined: {})",
                        if names.is_empty() { "none".to_string() } else { names.join(", ") }
                    ))
                })?;
                let m = earlier[idx].clone();
                if m.flags().is_specular() {
                    return Err(mv.error(format!(
                        "\"{name}\" is a delta ({}) material: mix components must be non-delta reflection models",
                        m.type_name()
                    )));
                }
                let wv = ct.req("weight")?;
                let w = wv.f64()?;
                if w < 0.0 {
                    return Err(wv.error(format!("weight must be non-negative, got {w}")));
                }
                total += w;
                components.push((m, w));
            }
            if components.is_empty() {
                return Err(cv.error("a mix needs at least one component"));
            }
            if total > 1.0 + 1e-12 {
                return Err(cv.error(format!(
                    "weights sum to {}, above 1: the mix would create energy",
                    decimals12(total)
                )));
            }
            Ok(Material::Mix(Mix { components }))
        }
        "ggx" | "beckmann" => {
            let mut keys = vec!["roughness", "roughness_u", "roughness_v", "tangent"];
            keys.extend_from_slice(FRESNEL_KEYS);
            allow(&keys)?;
            let (ax, ay) = roughness(t)?;
            let f = fresnel(t)?;
            let tangent = t.get("tangent").map(|v| direction(&v)).transpose()?;
            Ok(if ty == "ggx" {
                let mut m = Ggx::new(ax, ay, f);
                m.tangent = tangent;
                Material::Ggx(m)
            } else {
                let mut m = Beckmann::new(ax, ay, f);
                m.tangent = tangent;
                Material::Beckmann(m)
            })
        }
        "dielectric" => {
            allow(&["ior"])?;
            let mut d = Dielectric::default();
            if let Some(v) = t.get("ior") {
                let ior = v.f64()?;
                if !(ior > 0.0) {
                    return Err(v.error(format!("ior must be positive, got {ior}")));
                }
                d.ior = ior;
            }
            Ok(Material::Dielectric(d))
        }
        "plastic" => {
            allow(&["ior", "reflectance", "roughness"])?;
            let ior = match t.get("ior") {
                Some(v) => {
                    let ior = v.f64()?;
                    if !(ior > 0.0) {
                        return Err(v.error(format!("ior must be positive, got {ior}")));
                    }
                    ior
                }
                None => 1.5,
            };
            let rho = match t.get("reflectance") {
                Some(v) => reflectance(&v)?,
                None => Rgb::splat(0.5),
            };
            let rough = t
                .get("roughness")
                .map(|v| roughness_value(&v, "roughness"))
                .transpose()?;
            Ok(Material::Plastic(Plastic::new(ior, rho, rough)))
        }
        "subsurface_brdf" => {
            allow(&[
                "medium",
                "sigma_s",
                "sigma_s_reduced",
                "sigma_a",
                "g",
                "ior",
                "scale",
            ])?;
            let m = medium_coefficients(t)?;
            Ok(Material::SubsurfaceBrdf(SubsurfaceBrdf::new(
                m.sigma_s_reduced,
                m.sigma_a,
                m.g,
                m.eta,
            )))
        }
        "subsurface" => {
            allow(&[
                "medium",
                "sigma_s",
                "sigma_s_reduced",
                "sigma_a",
                "g",
                "ior",
                "scale",
                "mode",
                "single_scattering",
            ])?;
            let m = medium_coefficients(t)?;
            let mode = match t.get("mode") {
                Some(v) => match v.choice(SUBSURFACE_MODES)? {
                    "random_walk" => SubsurfaceMode::RandomWalk,
                    _ => SubsurfaceMode::Dipole,
                },
                None => SubsurfaceMode::Dipole,
            };
            let mut sub =
                Subsurface::new(m.sigma_s * m.scale, m.sigma_a * m.scale, m.g, m.eta, mode);
            if let Some(v) = t.get("single_scattering") {
                sub.single_scattering = v.bool()?;
            }
            Ok(Material::Subsurface(sub))
        }
        "conductor" => {
            allow(FRESNEL_KEYS)?;
            Ok(Material::Conductor(Conductor {
                fresnel: fresnel(t)?,
            }))
        }
        _ => unreachable!("choice() validated the type"),
    }
}

/// Coefficients of a homogeneous medium (per millimetre) and its settings.
struct MediumSpec {
    sigma_s: Rgb,
    sigma_s_reduced: Rgb,
    sigma_a: Rgb,
    g: f64,
    eta: f64,
    scale: f64,
}

/// `medium`, or `sigma_a` with `sigma_s` or `sigma_s_reduced`; `g`, `ior`,
/// `scale`.
fn medium_coefficients(t: &Table) -> Result<MediumSpec> {
    let g = match t.get("g") {
        Some(v) => {
            let g = v.f64()?;
            if !(g > -1.0 && g < 1.0) {
                return Err(v.error(format!("g must lie strictly between -1 and 1, got {g}")));
            }
            g
        }
        None => 0.0,
    };
    let scale = match t.get("scale") {
        Some(v) => v.positive()?,
        None => 1.0,
    };
    let coefficients = |key: &str| -> Result<Option<Rgb>> {
        match t.get(key) {
            Some(v) => {
                let c = v.numbers::<3>()?;
                if c.iter().any(|&x| x < 0.0) {
                    return Err(v.error(format!("{key} must be non-negative, got {c:?}")));
                }
                Ok(Some(Rgb::from_array(c)))
            }
            None => Ok(None),
        }
    };
    let explicit = ["sigma_s", "sigma_s_reduced", "sigma_a"]
        .iter()
        .any(|k| t.get(k).is_some());
    let (sigma_s, sigma_s_reduced, sigma_a, mut eta) = match t.get("medium") {
        Some(v) => {
            if explicit {
                return Err(t.error("give either `medium` or explicit coefficients, not both"));
            }
            let name = v.str()?;
            let m = Medium::by_name(name).ok_or_else(|| {
                v.error(format!(
                    "unknown medium \"{name}\" (valid: {})",
                    Medium::names().join(", ")
                ))
            })?;
            let red = Rgb::from_array(m.sigma_s_reduced);
            (red / (1.0 - g), red, Rgb::from_array(m.sigma_a), m.eta)
        }
        None => {
            let sa = coefficients("sigma_a")?.ok_or_else(|| {
                t.error("give `medium`, or `sigma_a` with `sigma_s` or `sigma_s_reduced`")
            })?;
            let (ss, red) = match (coefficients("sigma_s")?, coefficients("sigma_s_reduced")?) {
                (Some(_), Some(_)) => {
                    return Err(t.error("give `sigma_s` or `sigma_s_reduced`, not both"))
                }
                (Some(s), None) => (s, s * (1.0 - g)),
                (None, Some(r)) => (r / (1.0 - g), r),
                (None, None) => {
                    return Err(t.error("give `sigma_s` or `sigma_s_reduced` with `sigma_a`"))
                }
            };
            if (red + sa).max_component() <= 0.0 {
                return Err(t.error("the medium neither scatters nor absorbs"));
            }
            (ss, red, sa, 1.3)
        }
    };
    if let Some(v) = t.get("ior") {
        let ior = v.f64()?;
        if !(ior > 0.0) {
            return Err(v.error(format!("ior must be positive, got {ior}")));
        }
        eta = ior;
    }
    Ok(MediumSpec {
        sigma_s,
        sigma_s_reduced,
        sigma_a,
        g,
        eta,
        scale,
    })
}

/// `specular` (default 0.5) and `reflectance` (default 0), summing to <= 1.
fn lobe_weights(t: &Table) -> Result<(Rgb, Rgb)> {
    let specular = match t.get("specular") {
        Some(v) => reflectance(&v)?,
        None => Rgb::splat(0.5),
    };
    let diffuse = match t.get("reflectance") {
        Some(v) => reflectance(&v)?,
        None => Rgb::BLACK,
    };
    let sum = specular + diffuse;
    if sum.max_component() > 1.0 + 1e-12 {
        return Err(t.error(format!(
            "reflectance + specular = [{}] exceeds 1: the material would create energy",
            sum.to_array().map(decimals12).join(", ")
        )));
    }
    Ok((specular, diffuse))
}

/// A roughness value in (0, 10].
fn roughness_value(v: &Value, key: &str) -> Result<f64> {
    let r = v.f64()?;
    if !(r > 0.0 && r <= 10.0) {
        return Err(v.error(format!("{key} must lie in (0, 10], got {r}")));
    }
    Ok(r)
}

/// `roughness`, or `roughness_u` with `roughness_v`; default 0.2.
fn roughness(t: &Table) -> Result<(f64, f64)> {
    match (
        t.get("roughness"),
        t.get("roughness_u"),
        t.get("roughness_v"),
    ) {
        (Some(r), None, None) => {
            let a = roughness_value(&r, "roughness")?;
            Ok((a, a))
        }
        (None, Some(u), Some(v)) => Ok((
            roughness_value(&u, "roughness_u")?,
            roughness_value(&v, "roughness_v")?,
        )),
        (None, None, None) => Ok((0.2, 0.2)),
        (Some(_), _, _) => {
            Err(t.error("give either `roughness` or `roughness_u` with `roughness_v`, not both"))
        }
        _ => Err(t.error("`roughness_u` and `roughness_v` go together: give both")),
    }
}

/// One of `metal`, `eta` + `k`, `ior`, `schlick`; none means `F = 1`.
/// `type = "wave"` (see `isolux_materials::wave` for the keys).
fn wave_material(t: &Table, base_dir: &Path) -> Result<Material> {
    use isolux_materials::wave::{Mapping, Wave, WaveFresnel};
    use isolux_wave::{GaborSurface, Heightfield, LoadOptions, Model};
    let hv = t.req("heightfield")?;
    let file = base_dir.join(hv.str()?);
    let mut opts = LoadOptions::default();
    if let Some(v) = t.get("texel_um") {
        opts.texel_um = Some(v.positive()?);
    }
    if let Some(v) = t.get("vertical_scale") {
        opts.vertical_scale = v.f64()?;
    }
    if let Some(v) = t.get("raw_size") {
        let [w, h] = v.numbers::<2>()?;
        if !(w >= 1.0 && h >= 1.0 && w.fract() == 0.0 && h.fract() == 0.0) {
            return Err(v.error(format!(
                "raw_size must be two positive integers, got [{w}, {h}]"
            )));
        }
        opts.raw_size = Some((w as usize, h as usize));
    }
    let field = Heightfield::load(&file, &opts).map_err(|e| hv.error(e.to_string()))?;
    let model = match t.get("model") {
        Some(v) => Model::parse(v.choice(WAVE_MODELS)?).unwrap_or_default(),
        None => Model::Ghs,
    };
    if t.get("metal").is_some() && t.get("ior").is_some() {
        return Err(t.error("conflicting Fresnel keys: give only one of `metal`, `ior`"));
    }
    let fresnel = if let Some(v) = t.get("metal") {
        let name = v.str()?;
        WaveFresnel::Metal(Metal::by_name(name).ok_or_else(|| {
            v.error(format!(
                "unknown metal \"{name}\" (valid: {})",
                Metal::names().join(", ")
            ))
        })?)
    } else if let Some(v) = t.get("ior") {
        WaveFresnel::Dielectric(v.positive()?)
    } else {
        WaveFresnel::None
    };
    let mut m = Wave::new(
        std::sync::Arc::new(GaborSurface::new(field)),
        model,
        fresnel,
    );
    if let Some(v) = t.get("coherence_um") {
        m.coherence_um = v.positive()?;
        if let Some(why) = m.coherence_problem(m.coherence_um) {
            return Err(v.error(format!("coherence_um = {why}")));
        }
    }
    if let Some(v) = t.get("um_per_unit") {
        m.um_per_unit = v.positive()?;
    }
    if let Some(v) = t.get("wavelengths") {
        m.wavelengths = v.uint(WAVELENGTHS.0, WAVELENGTHS.1)? as usize;
    }
    if let Some(v) = t.get("obliquity") {
        m.settings.obliquity =
            isolux_wave::Obliquity::parse(v.choice(OBLIQUITIES)?).unwrap_or_default();
    }
    let center = match t.get("center") {
        Some(v) => vec3(&v)?,
        None => DVec3::ZERO,
    };
    let mapping = match t.get("mapping") {
        Some(v) => v.choice(MAPPINGS)?,
        None => "planar",
    };
    if mapping != "planar" && t.get("axis").is_some() {
        return Err(t.error("`axis` applies to mapping = \"planar\" only"));
    }
    m.mapping = match mapping {
        "spherical" => Mapping::Spherical(center),
        "cylindrical" => Mapping::Cylindrical(center),
        _ => {
            let axis = match t.get("axis") {
                Some(v) => match v.choice(AXES)? {
                    "x" => 0,
                    "y" => 1,
                    _ => 2,
                },
                None => 2,
            };
            Mapping::Planar(axis)
        }
    };
    m.query.sigma_um = m.coherence_um;
    Ok(Material::Wave(m))
}

/// `x` to 12 decimals with the trailing zeros dropped, for the energy
/// checks' messages: a sum of values written as decimals prints as written
/// (1.14, not 1.1400000000000001), and an excess over 1 large enough to
/// fail the checks' 1e-12 tolerance still shows.
fn decimals12(x: f64) -> String {
    let s = format!("{x:.12}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

fn fresnel(t: &Table) -> Result<Fresnel> {
    let groups = [
        t.get("metal").is_some(),
        t.get("eta").is_some() || t.get("k").is_some(),
        t.get("ior").is_some(),
        t.get("schlick").is_some(),
    ];
    if groups.iter().filter(|&&g| g).count() > 1 {
        return Err(t.error(
            "conflicting Fresnel keys: give only one of `metal`, `eta` + `k`, `ior`, `schlick`",
        ));
    }
    if let Some(v) = t.get("metal") {
        let name = v.str()?;
        let metal = Metal::by_name(name).ok_or_else(|| {
            v.error(format!(
                "unknown metal \"{name}\" (valid: {})",
                Metal::names().join(", ")
            ))
        })?;
        let (eta, k) = metal.rgb();
        return Ok(Fresnel::Conductor {
            eta: Rgb::from_array(eta),
            k: Rgb::from_array(k),
        });
    }
    if groups[1] {
        let ev = t.req("eta")?;
        let eta = ev.numbers::<3>()?;
        if eta.iter().any(|&x| x <= 0.0) {
            return Err(ev.error(format!("eta must be positive, got {eta:?}")));
        }
        let kv = t.req("k")?;
        let k = kv.numbers::<3>()?;
        if k.iter().any(|&x| x < 0.0) {
            return Err(kv.error(format!("k must be non-negative, got {k:?}")));
        }
        return Ok(Fresnel::Conductor {
            eta: Rgb::from_array(eta),
            k: Rgb::from_array(k),
        });
    }
    if let Some(v) = t.get("ior") {
        let ior = v.f64()?;
        if !(ior > 0.0) {
            return Err(v.error(format!("ior must be positive, got {ior}")));
        }
        return Ok(Fresnel::Dielectric { ior });
    }
    if let Some(v) = t.get("schlick") {
        let f0 = v.numbers::<3>()?;
        if f0.iter().any(|&x| !(0.0..=1.0).contains(&x)) {
            return Err(v.error(format!("schlick F0 must lie in [0, 1], got {f0:?}")));
        }
        return Ok(Fresnel::Schlick {
            f0: Rgb::from_array(f0),
        });
    }
    Ok(Fresnel::One)
}
