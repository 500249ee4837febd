//! Live material editing: a material is kept as its TOML table (as in the
//! scene file) and every edit is re-read by
//! [`isolux_scene::parse_material`], so the viewer applies exactly the
//! scene format's validation and defaults, and shows its messages.
//!
//! [`template`] gives the table a model starts from when the user switches
//! a material's `type`: the scene format's defaults, written out so that
//! each parameter appears in the panel.

use isolux_materials::metals::Metal;
use isolux_materials::subsurface::Medium;
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
    /// A whole number in `min..=max` (the scene format's integer keys,
    /// [`isolux_scene::MATERIAL_INTEGERS`]).
    Integer(u64, u64),
    /// `true` or `false` (a checkbox).
    Toggle,
    /// Linear RGB weights in `[0, 1]` (a colour picker and three numbers).
    Color,
    /// Three numbers (a direction, `eta`, `k`).
    Vector,
    /// One of a fixed set of strings ([`isolux_scene::MATERIAL_CHOICES`],
    /// and the names of the metals and of the measured media).
    Choice(Vec<&'static str>),
    /// A mix's components: each one's material (a menu of the materials
    /// defined before the mix, as the scene format requires) and weight.
    Components,
    /// Shown, not editable (file names).
    ReadOnly,
}

/// The editor for `key = value` in a material table.
pub fn editor(key: &str, value: &Value) -> Editor {
    let numbers3 = matches!(value, Value::Array(a)
        if a.len() == 3 && a.iter().all(|x| matches!(x, Value::Float(_) | Value::Integer(_))));
    let integer = isolux_scene::MATERIAL_INTEGERS
        .iter()
        .find(|(k, ..)| *k == key);
    let choices = isolux_scene::MATERIAL_CHOICES
        .iter()
        .find(|(k, _)| *k == key);
    match value {
        Value::Float(_) | Value::Integer(_) => match integer {
            Some(&(_, min, max)) => Editor::Integer(min, max),
            None => Editor::Number,
        },
        Value::Boolean(_) => Editor::Toggle,
        _ if key == "components" && components(value).is_some() => Editor::Components,
        _ if numbers3 => match key {
            "reflectance" | "specular" | "isotropic" | "schlick" => Editor::Color,
            _ => Editor::Vector,
        },
        Value::String(_) => match key {
            "metal" => Editor::Choice(Metal::names()),
            "medium" => Editor::Choice(Medium::names()),
            _ => match choices {
                Some((_, c)) => Editor::Choice(c.to_vec()),
                None => Editor::ReadOnly,
            },
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

/// A mix's `components` as `(material, weight)` pairs, if every entry has
/// both keys and nothing else.
pub fn components(v: &Value) -> Option<Vec<(String, f64)>> {
    let Value::Array(a) = v else { return None };
    a.iter()
        .map(|c| {
            let t = c.as_table().filter(|t| t.len() == 2)?;
            Some((
                t.get("material")?.as_str()?.to_string(),
                number(t.get("weight")?)?,
            ))
        })
        .collect()
}

/// A mix's `components` array from `(material, weight)` pairs.
pub fn components_value(c: &[(String, f64)]) -> Value {
    Value::Array(
        c.iter()
            .map(|(m, w)| {
                let mut t = Table::new();
                t.insert("material".into(), Value::String(m.clone()));
                t.insert("weight".into(), Value::Float(*w));
                Value::Table(t)
            })
            .collect(),
    )
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

    /// The material tables of the example scenes (the scene files' own
    /// tables, as the viewer keeps them), with the directory their paths
    /// are relative to.
    fn example_tables() -> Vec<(String, Table)> {
        let dir = "../../examples/scenes";
        let mut out = Vec::new();
        for e in std::fs::read_dir(dir).unwrap() {
            let path = e.unwrap().path();
            if path.extension().is_none_or(|x| x != "toml") {
                continue;
            }
            let doc: Table = toml::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
            let Some(Value::Array(ms)) = doc.get("material") else {
                continue;
            };
            for m in ms {
                let t = m.as_table().unwrap().clone();
                out.push((format!("{}: {}", path.display(), t["name"]), t));
            }
        }
        assert!(out.len() > 20, "{} example materials", out.len());
        out
    }

    fn parse_in_examples(
        t: &Table,
    ) -> Result<isolux_materials::Material, isolux_scene::SceneError> {
        isolux_scene::parse_material(
            &to_source(t),
            "edit".as_ref(),
            &[],
            &[],
            "../../examples/scenes".as_ref(),
        )
    }

    /// On every material of the example scenes that stands alone (a mix
    /// names others): every key but file names and references gets a
    /// control; each menu holds the key's current value, and every entry of
    /// it is one the scene format knows (an entry may still conflict with
    /// another key, which the panel reports); an integer key's whole range
    /// parses; a checkbox's other state parses.
    #[test]
    fn example_materials_are_editable_within_the_scene_format() {
        let mut menus = 0;
        let mut integers = 0;
        let mut toggles = 0;
        let mut mixes = 0;
        for (label, table) in example_tables() {
            if table["type"].as_str() == Some("mix") {
                // Read with the materials before it: the test below.
                let c = &table["components"];
                assert_eq!(editor("components", c), Editor::Components, "{label}");
                mixes += 1;
                continue;
            }
            parse_in_examples(&table).unwrap_or_else(|e| panic!("{label}: {e}"));
            for (k, v) in table.iter() {
                if k == "name" || k == "type" {
                    continue;
                }
                let edited = |x: Value| {
                    let mut t = table.clone();
                    t.insert(k.clone(), x);
                    parse_in_examples(&t)
                };
                match editor(k, v) {
                    Editor::ReadOnly => {
                        assert!(
                            ["heightfield", "raw_size", "file", "dir"].contains(&k.as_str()),
                            "{label}: {k} = {v} is read-only"
                        )
                    }
                    Editor::Choice(options) => {
                        menus += 1;
                        assert!(
                            options.contains(&v.as_str().unwrap()),
                            "{label}: {k} = {v} not in {options:?}"
                        );
                        for o in options {
                            if let Err(e) = edited(Value::String(o.into())) {
                                let e = e.to_string();
                                assert!(!e.contains("unknown"), "{label}: {k} = {o}: {e}");
                            }
                        }
                    }
                    Editor::Integer(min, max) => {
                        integers += 1;
                        for x in [min, max] {
                            edited(Value::Integer(x as i64))
                                .unwrap_or_else(|e| panic!("{label}: {k} = {x}: {e}"));
                        }
                        let e = edited(Value::Integer(max as i64 + 1))
                            .unwrap_err()
                            .to_string();
                        assert!(e.contains("must lie in"), "{label}: {e}");
                    }
                    Editor::Toggle => {
                        toggles += 1;
                        let b = !v.as_bool().unwrap();
                        edited(Value::Boolean(b))
                            .unwrap_or_else(|e| panic!("{label}: {k} = {b}: {e}"));
                    }
                    Editor::Number | Editor::Color | Editor::Vector | Editor::Components => {}
                }
            }
        }
        // The examples use menus (metal, medium, mode, wave keys), an
        // integer (a wave material's wavelengths) and a mix.
        assert!(
            menus >= 15 && integers >= 1 && mixes >= 1,
            "{menus} menus, {integers} integers, {toggles} toggles, {mixes} mixes"
        );
    }

    /// The editors the scene format's key lists give, including a key the
    /// examples do not write (`single_scattering`).
    #[test]
    fn integer_boolean_and_choice_keys_get_their_editors() {
        let max = isolux_materials::wave::MAX_WAVELENGTHS as u64;
        assert_eq!(
            editor("wavelengths", &Value::Integer(4)),
            Editor::Integer(1, max)
        );
        // A float key written as an integer stays a float.
        assert_eq!(editor("exponent", &Value::Integer(40)), Editor::Number);
        assert_eq!(
            editor("single_scattering", &Value::Boolean(true)),
            Editor::Toggle
        );
        assert_eq!(
            editor("mode", &Value::String("dipole".into())),
            Editor::Choice(vec!["dipole", "random_walk"])
        );
        let mut t = Table::new();
        t.insert("name".into(), Value::String("s".into()));
        t.insert("type".into(), Value::String("subsurface".into()));
        t.insert("medium".into(), Value::String(Medium::names()[0].into()));
        for b in [false, true] {
            t.insert("single_scattering".into(), Value::Boolean(b));
            match parse(&t).unwrap() {
                isolux_materials::Material::Subsurface(s) => assert_eq!(s.single_scattering, b),
                m => panic!("{}", m.type_name()),
            }
        }
    }

    /// A mix's components get their editor; an edit of the weights or of
    /// a component's material round-trips through the TOML text and the
    /// scene reader, and weights above 1 in sum are refused with its
    /// message.
    #[test]
    fn mix_components_edit_through_the_scene_reader() {
        let names = ["d".to_string(), "g".to_string(), "p".to_string()];
        let earlier: Vec<_> = [("d", "diffuse"), ("g", "ggx"), ("p", "phong")]
            .iter()
            .map(|(n, ty)| parse(&template(n, ty)).unwrap())
            .collect();
        let read = |c: &[(String, f64)]| {
            let mut t = Table::new();
            t.insert("name".into(), Value::String("mix".into()));
            t.insert("type".into(), Value::String("mix".into()));
            t.insert("components".into(), components_value(c));
            assert_eq!(editor("components", &t["components"]), Editor::Components);
            assert_eq!(components(&t["components"]).as_deref(), Some(c));
            isolux_scene::parse_material(
                &to_source(&t),
                "edit".as_ref(),
                &names,
                &earlier,
                ".".as_ref(),
            )
        };
        let c = vec![("d".to_string(), 0.6), ("g".to_string(), 0.4)];
        let weights = |m: isolux_materials::Material| match m {
            isolux_materials::Material::Mix(m) => m
                .components
                .iter()
                .map(|(m, w)| (m.type_name(), *w))
                .collect::<Vec<_>>(),
            m => panic!("{}", m.type_name()),
        };
        assert_eq!(weights(read(&c).unwrap()), [("diffuse", 0.6), ("ggx", 0.4)]);
        let c = vec![("p".to_string(), 0.25), ("g".to_string(), 0.5)];
        assert_eq!(weights(read(&c).unwrap()), [("phong", 0.25), ("ggx", 0.5)]);
        let c = vec![("d".to_string(), 0.7), ("g".to_string(), 0.4)];
        let e = read(&c).unwrap_err().to_string();
        assert!(e.contains("above 1"), "{e}");
        // Not a components array: shown only.
        assert_eq!(
            editor("components", &Value::String("d".into())),
            Editor::ReadOnly
        );
        let extra = Value::Array(vec![Value::Table(template("x", "diffuse"))]);
        assert_eq!(components(&extra), None);
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
