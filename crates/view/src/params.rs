//! Live material editing: a material is kept as its TOML table (as in the
//! scene file) and every edit is re-read by
//! [`isolux_scene::parse_material`], so the viewer applies exactly the
//! scene format's validation and defaults, and shows its messages.
//!
//! [`template`] gives the table a model starts from when the user switches
//! a material's `type`: the scene format's defaults, written out so that
//! each parameter appears in the panel.

use isolux_materials::metals::Metal;
use toml::{Table, Value};

/// Models the panel can switch a material to: the analytic reflection and
/// transmission models that run on the GPU (`mix`, `factored`, `merl`,
/// `wave` and the subsurface models need files or other materials).
pub const SWITCHABLE: &[&str] = &[
    "diffuse",
    "phong",
    "blinn_phong",
    "gaussian",
    "ward",
    "heidrich_seidel",
    "cook_torrance",
    "beckmann",
    "ggx",
    "conductor",
    "dielectric",
    "plastic",
];

fn rgb(v: f64) -> Value {
    Value::Array(vec![Value::Float(v), Value::Float(v), Value::Float(v)])
}

/// The table of a material `name` of model `ty` with the scene format's
/// defaults written out (a diffuse lobe of 0.3 is added to the glossy
/// models, whose default is none, so that switching keeps the object
/// visible under point lights).
pub fn template(name: &str, ty: &str) -> Table {
    let mut t = Table::new();
    t.insert("name".into(), Value::String(name.into()));
    t.insert("type".into(), Value::String(ty.into()));
    let mut set = |k: &str, v: Value| {
        t.insert(k.into(), v);
    };
    match ty {
        "diffuse" => set("reflectance", rgb(0.5)),
        "phong" | "blinn_phong" => {
            set("exponent", Value::Float(32.0));
            set("specular", rgb(0.5));
            set("reflectance", rgb(0.3));
        }
        "gaussian" => {
            set("m", Value::Float(0.2));
            set("specular", rgb(0.5));
            set("reflectance", rgb(0.3));
        }
        "ward" => {
            set("alpha_u", Value::Float(0.15));
            set("alpha_v", Value::Float(0.15));
            set("specular", rgb(0.5));
            set("reflectance", rgb(0.3));
        }
        "heidrich_seidel" => {
            set("exponent", Value::Float(40.0));
            set("specular", rgb(0.5));
            set("reflectance", rgb(0.3));
        }
        "cook_torrance" => {
            set("roughness", Value::Float(0.3));
            set("ior", Value::Float(1.5));
            set("reflectance", rgb(0.3));
        }
        "beckmann" | "ggx" => {
            set("roughness", Value::Float(0.2));
            set("metal", Value::String("Au".into()));
        }
        "conductor" => set("metal", Value::String("Au".into())),
        "dielectric" => set("ior", Value::Float(1.5)),
        "plastic" => {
            set("ior", Value::Float(1.5));
            set("reflectance", rgb(0.5));
            set("roughness", Value::Float(0.1));
        }
        _ => {}
    }
    t
}

/// How the panel edits one key of a material table.
#[derive(Clone, Debug, PartialEq)]
pub enum Editor {
    /// A number (drag to change).
    Number,
    /// Linear RGB weights in `[0, 1]` (a colour picker and three numbers).
    Color,
    /// Three numbers (a direction, `eta`, `k`).
    Vector,
    /// One of a fixed set of strings.
    Choice(Vec<&'static str>),
    /// Shown, not editable (file names, mix components).
    ReadOnly,
}

/// The editor for `key = value` in a material table.
pub fn editor(key: &str, value: &Value) -> Editor {
    let numbers3 = matches!(value, Value::Array(a)
        if a.len() == 3 && a.iter().all(|x| matches!(x, Value::Float(_) | Value::Integer(_))));
    match value {
        Value::Float(_) | Value::Integer(_) => Editor::Number,
        _ if numbers3 => match key {
            "reflectance" | "specular" | "isotropic" | "schlick" => Editor::Color,
            _ => Editor::Vector,
        },
        Value::String(_) => match key {
            "metal" => Editor::Choice(Metal::names()),
            "distribution" => Editor::Choice(vec!["beckmann", "ggx", "gaussian"]),
            "masking" => Editor::Choice(vec!["cook_torrance", "smith"]),
            _ => Editor::ReadOnly,
        },
        _ => Editor::ReadOnly,
    }
}

/// A number of a table as f64 (TOML integers included).
pub fn number(v: &Value) -> Option<f64> {
    match v {
        Value::Float(x) => Some(*x),
        Value::Integer(i) => Some(*i as f64),
        _ => None,
    }
}

/// Three numbers of a table as f64.
pub fn numbers3(v: &Value) -> Option<[f64; 3]> {
    let Value::Array(a) = v else { return None };
    if a.len() != 3 {
        return None;
    }
    Some([number(&a[0])?, number(&a[1])?, number(&a[2])?])
}

/// Three numbers as a TOML array.
pub fn array3(c: [f64; 3]) -> Value {
    Value::Array(c.iter().map(|&x| Value::Float(x)).collect())
}

/// The TOML text of a material table, for [`isolux_scene::parse_material`].
pub fn to_source(t: &Table) -> String {
    toml::to_string(t).unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(t: &Table) -> Result<isolux_materials::Material, isolux_scene::SceneError> {
        isolux_scene::parse_material(&to_source(t), "edit".as_ref(), &[], &[], ".".as_ref())
    }

    /// Every model the panel switches to parses from its template, is the
    /// model asked for, and runs on the GPU.
    #[test]
    fn every_template_parses_and_runs_on_the_gpu() {
        for &ty in SWITCHABLE {
            assert!(isolux_scene::MATERIAL_TYPES.contains(&ty), "{ty}");
            let m = parse(&template("m", ty)).unwrap_or_else(|e| panic!("{ty}: {e}"));
            assert_eq!(m.type_name(), ty);
            assert!(isolux_gpu::layout::supported(&m), "{ty} is not on the GPU");
        }
    }

    /// Every key of every template gets an editable control, and an edit
    /// that breaks the scene format's rules is refused with its message.
    #[test]
    fn template_keys_are_editable_and_bad_edits_are_refused() {
        for &ty in SWITCHABLE {
            for (k, v) in template("m", ty).iter() {
                if k == "name" || k == "type" {
                    continue;
                }
                assert_ne!(editor(k, v), Editor::ReadOnly, "{ty}.{k}");
            }
        }
        let mut t = template("m", "phong");
        t.insert("specular".into(), array3([0.9, 0.9, 0.9]));
        let err = parse(&t).unwrap_err().to_string();
        assert!(err.contains("exceeds 1"), "{err}");
        let mut t = template("m", "ggx");
        t.insert("metal".into(), Value::String("gold".into()));
        let err = parse(&t).unwrap_err().to_string();
        assert!(err.contains("unknown metal"), "{err}");
    }

    #[test]
    fn numbers_read_floats_and_integers() {
        assert_eq!(number(&Value::Integer(40)), Some(40.0));
        assert_eq!(
            numbers3(&Value::Array(vec![
                Value::Integer(1),
                Value::Float(0.5),
                Value::Integer(0)
            ])),
            Some([1.0, 0.5, 0.0])
        );
        assert_eq!(numbers3(&Value::String("x".into())), None);
    }
}
