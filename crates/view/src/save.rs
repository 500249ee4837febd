//! Saving the viewer's edits as a scene file.
//!
//! `Ctrl+S` (or the panel's *Save scene* button) writes the scene file as
//! opened with the edits made since: the materials' tables, the point
//! lights (added, removed, their `position` and `intensity`), the
//! camera's `position`, `look_at` and `fov_y` when the view was orbited,
//! panned, zoomed or widened, and the environment's `radiance` or map
//! `scale`. Everything else is the file as
//! it was, byte for byte: comments, key order, layout, and every value the
//! viewer did not change (a value is rewritten only where it differs from
//! the file's, and then keeps the comment beside it).
//!
//! Decisions:
//! - The copy goes **next to the scene file**, as `<scene>-view-<n>.toml`
//!   (the first `n` not taken), never over it: the scene's relative paths
//!   (environment maps, heightfields, factored directories) resolve
//!   against its directory, so the copy renders as it is with
//!   `isolux render`.
//! - The camera's eye and target are written to 9 significant digits of
//!   their largest coordinate (the orbit's trigonometry leaves rounding
//!   noise such as `3.0000000000000004`); every other number as the
//!   viewer holds it.
//! - The text is read back by the scene reader before it is written
//!   (`isolux_scene::parse_str`), so a copy that the reader would refuse (a
//!   material edit the panel is still showing as refused) is never saved;
//!   the reader's message says why. The file is written atomically.
//! - Exposure, tone map and the window's size are not scene keys (they
//!   are `render`'s flags), so they are not saved.

use std::path::{Path, PathBuf};

use isolux_render::{Camera, Environment, PointLight};
use toml_edit::{DocumentMut, Item, TableLike, Value};

/// What the viewer edits, as it holds it now.
pub(super) struct Edits<'a> {
    /// The materials' tables, one per `[[material]]` of the file, in order.
    pub materials: &'a [toml::Table],
    /// The point lights.
    pub lights: &'a [PointLight],
    /// For each light, the index of the `[[light]]` table it was read
    /// from, or `None` for a light added in the viewer.
    pub light_origin: &'a [Option<usize>],
    /// The camera, when the view changed from the file's.
    pub camera: Option<Camera>,
    /// The environment.
    pub environment: &'a Environment,
}

/// The scene file `src` with `edits` applied; `path` and `base_dir` are
/// the file's name and directory, for the scene reader's check and
/// messages.
pub(super) fn edited_scene(
    src: &str,
    edits: &Edits,
    path: &Path,
    base_dir: &Path,
) -> Result<String, String> {
    let mut doc: DocumentMut = src
        .parse()
        .map_err(|e| format!("{}: invalid TOML: {e}", path.display()))?;
    let materials = tables_mut(&mut doc, "material");
    if materials.len() != edits.materials.len() {
        return Err(format!(
            "{}: the file has {} [[material]] tables, the viewer {}",
            path.display(),
            materials.len(),
            edits.materials.len()
        ));
    }
    for (t, edited) in materials.into_iter().zip(edits.materials) {
        let stale: Vec<String> = t
            .iter()
            .map(|(k, _)| k.to_string())
            .filter(|k| !edited.contains_key(k))
            .collect();
        for k in stale {
            t.remove(&k);
        }
        for (k, v) in edited {
            set(t, k, value(v)?);
        }
    }
    restructure_lights(&mut doc, edits.light_origin)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let lights = tables_mut(&mut doc, "light");
    if lights.len() != edits.lights.len() {
        return Err(format!(
            "{}: the file has {} [[light]] tables, the viewer {} lights",
            path.display(),
            lights.len(),
            edits.lights.len()
        ));
    }
    for (t, l) in lights.into_iter().zip(edits.lights) {
        set(t, "position", triple(l.position.to_array()));
        set(t, "intensity", triple(l.intensity.to_array()));
    }
    if let Some(c) = &edits.camera {
        let t = table_mut(&mut doc, "camera")?;
        set(t, "position", triple(tidy(c.position.to_array())));
        let old_target = t
            .get("look_at")
            .and_then(|i| i.as_array())
            .map(|a| a.iter().map(number).collect::<Vec<_>>());
        let default = Camera::default().look_at.to_array().map(Some).to_vec();
        if old_target.unwrap_or(default) != c.look_at.to_array().map(Some) {
            set(t, "look_at", triple(tidy(c.look_at.to_array())));
        }
        let old_fov = t.get("fov_y").and_then(Item::as_value).and_then(number);
        if old_fov.unwrap_or(Camera::default().fov_y) != c.fov_y {
            set(t, "fov_y", Value::from(c.fov_y));
        }
    }
    match edits.environment {
        Environment::Constant(c) => {
            let absent = doc.get("environment").is_none();
            if !(absent && *c == isolux_core::Rgb::BLACK) {
                let t = table_mut(&mut doc, "environment")?;
                if absent {
                    t.insert("type", Item::Value(Value::from("constant")));
                }
                set(t, "radiance", triple(c.to_array()));
            }
        }
        Environment::Map(m) => {
            let t = table_mut(&mut doc, "environment")?;
            if t.get("scale")
                .and_then(Item::as_value)
                .and_then(number)
                .unwrap_or(1.0)
                != m.scale()
            {
                set(t, "scale", Value::from(m.scale()));
            }
        }
    }
    let out = doc.to_string();
    isolux_scene::parse_str(&out, path, base_dir)
        .map_err(|e| format!("not saved, the scene reader refuses the edits: {e}"))?;
    Ok(out)
}

/// Rebuilds the file's lights in the viewer's order: the table each light
/// was read from (its comments with it), and a new `type = "point"` table
/// for each light added (its `position` and `intensity` are set after).
/// The file's lights as they were, when none was added, removed or moved.
fn restructure_lights(doc: &mut DocumentMut, origin: &[Option<usize>]) -> Result<(), String> {
    let count = tables_mut(doc, "light").len();
    if origin.len() == count && origin.iter().enumerate().all(|(i, o)| *o == Some(i)) {
        return Ok(());
    }
    if let Some(bad) = origin.iter().flatten().find(|&&k| k >= count) {
        return Err(format!(
            "light {bad} is not in the file's {count} [[light]] tables"
        ));
    }
    let new_table = || {
        let mut t = toml_edit::Table::new();
        t.insert("type", Item::Value(Value::from("point")));
        t
    };
    match doc.get_mut("light") {
        Some(Item::Value(Value::Array(a))) => {
            let old: Vec<Value> = a.iter().cloned().collect();
            // One element a line, as the file had them, or all on one.
            let lines = a.to_string().contains('\n');
            let mut fresh = toml_edit::Array::new();
            for o in origin {
                let mut v = match o {
                    Some(k) => old[*k].clone(),
                    None => Value::InlineTable(new_table().into_inline_table()),
                };
                if lines {
                    v.decor_mut().set_prefix("\n  ");
                    v.decor_mut().set_suffix("");
                }
                fresh.push_formatted(v);
            }
            if lines {
                fresh.set_trailing_comma(true);
                fresh.set_trailing("\n");
            } else {
                fresh.fmt();
            }
            *a = fresh;
        }
        Some(Item::ArrayOfTables(a)) => {
            let old: Vec<toml_edit::Table> = a.iter().cloned().collect();
            let mut fresh = toml_edit::ArrayOfTables::new();
            for o in origin {
                fresh.push(match o {
                    Some(k) => old[*k].clone(),
                    None => new_table(),
                });
            }
            *a = fresh;
        }
        _ => {
            let mut fresh = toml_edit::ArrayOfTables::new();
            for _ in origin {
                fresh.push(new_table());
            }
            doc.insert("light", Item::ArrayOfTables(fresh));
        }
    }
    if origin.is_empty() {
        doc.remove("light");
    }
    Ok(())
}

/// `<dir>/<stem>-view-<n>.toml` for the first `n` from 1 not taken.
pub(super) fn free_path(dir: &Path, stem: &str) -> PathBuf {
    (1..)
        .map(|n| dir.join(format!("{stem}-view-{n:03}.toml")))
        .find(|p| !p.exists())
        .expect("some number is free")
}

/// Writes `text` to `path` atomically.
pub(super) fn write(path: &Path, text: &str) -> Result<(), String> {
    use std::io::Write as _;
    isolux_io::atomic_write(path, |f| {
        f.write_all(text.as_bytes())
            .map_err(|source| isolux_io::IoError::Io {
                path: path.to_path_buf(),
                source,
            })
    })
    .map_err(|e| e.to_string())
}

/// Sets `key` to `v` unless it holds that value already; a rewritten value
/// keeps the old one's surrounding whitespace and comment.
fn set(t: &mut dyn TableLike, key: &str, mut v: Value) {
    match t.get_mut(key) {
        Some(Item::Value(old)) => {
            if same(old, &v) {
                return;
            }
            *v.decor_mut() = old.decor().clone();
            *old = v;
        }
        Some(item) => *item = Item::Value(v),
        None => {
            v.decor_mut().clear();
            t.insert(key, Item::Value(v));
        }
    }
}

/// Whether two TOML values are equal as values, not as text: `1.0` and
/// `1.00` are the same number, and so are `4` and `4.0` (the scene reader
/// takes an integer wherever it takes a number).
fn same(a: &Value, b: &Value) -> bool {
    fn eq(a: &toml::Value, b: &toml::Value) -> bool {
        use toml::Value::{Array, Float, Integer, Table};
        match (a, b) {
            (Integer(i), Float(x)) | (Float(x), Integer(i)) => *i as f64 == *x,
            (Array(a), Array(b)) => a.len() == b.len() && a.iter().zip(b).all(|(x, y)| eq(x, y)),
            (Table(a), Table(b)) => {
                a.len() == b.len() && a.iter().all(|(k, x)| b.get(k).is_some_and(|y| eq(x, y)))
            }
            (a, b) => a == b,
        }
    }
    let read = |v: &Value| {
        toml::from_str::<toml::Table>(&format!("x = {}", v.to_string().trim()))
            .ok()
            .and_then(|mut t| t.remove("x"))
    };
    match (read(a), read(b)) {
        (Some(x), Some(y)) => eq(&x, &y),
        _ => false,
    }
}

/// A `toml` value as a `toml_edit` one.
fn value(v: &toml::Value) -> Result<Value, String> {
    v.to_string()
        .parse::<Value>()
        .map_err(|e| format!("cannot write the value {v}: {e}"))
}

fn triple(a: [f64; 3]) -> Value {
    Value::Array(a.into_iter().collect())
}

/// A number written as a float or an integer.
fn number(v: &Value) -> Option<f64> {
    v.as_float().or_else(|| v.as_integer().map(|x| x as f64))
}

/// A vector rounded to 9 significant digits of its largest coordinate, so
/// that the orbit's rounding noise (and `-0`) is not written out.
fn tidy(a: [f64; 3]) -> [f64; 3] {
    round_to(a, 9)
}

/// A vector rounded to `digits` significant digits of its largest
/// coordinate (printed and read back, so that it prints short), `-0` as 0.
pub(super) fn round_to(a: [f64; 3], digits: i32) -> [f64; 3] {
    let big = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if !(big > 0.0 && big.is_finite()) {
        return a;
    }
    round_decimals(a, digits - 1 - big.log10().floor() as i32)
}

/// A vector rounded to `decimals` decimal places (none where negative),
/// printed and read back so that it prints short, `-0` as 0.
pub(super) fn round_decimals(a: [f64; 3], decimals: i32) -> [f64; 3] {
    let decimals = decimals.max(0) as usize;
    a.map(|x| format!("{x:.decimals$}").parse::<f64>().unwrap_or(x) + 0.0)
}

/// The tables of an array of tables `key`, written either as `[[key]]`
/// sections or as an inline array of inline tables.
fn tables_mut<'d>(doc: &'d mut DocumentMut, key: &str) -> Vec<&'d mut dyn TableLike> {
    match doc.get_mut(key) {
        Some(Item::ArrayOfTables(a)) => a.iter_mut().map(|t| t as &mut dyn TableLike).collect(),
        Some(Item::Value(Value::Array(a))) => a
            .iter_mut()
            .filter_map(|v| v.as_inline_table_mut())
            .map(|t| t as &mut dyn TableLike)
            .collect(),
        _ => Vec::new(),
    }
}

/// The table `key` (a section or an inline table), added as a section at
/// the end when the file has none.
fn table_mut<'d>(doc: &'d mut DocumentMut, key: &str) -> Result<&'d mut dyn TableLike, String> {
    if doc.get(key).is_none() {
        doc.insert(key, Item::Table(toml_edit::Table::new()));
    }
    doc.get_mut(key)
        .and_then(|i| i.as_table_like_mut())
        .ok_or_else(|| format!("`{key}` is not a table"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use isolux_render::Scene;

    fn examples() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/scenes")
    }

    /// A scene file, the scene read from it and its material tables.
    fn read(name: &str) -> (String, Scene, Vec<toml::Table>, PathBuf) {
        let path = examples().join(name);
        let src = std::fs::read_to_string(&path).unwrap();
        let scene = isolux_scene::load(&path).unwrap();
        let doc: toml::Table = toml::from_str(&src).unwrap();
        let tables = doc
            .get("material")
            .and_then(|v| v.as_array())
            .map(|a| a.iter().map(|m| m.as_table().unwrap().clone()).collect())
            .unwrap_or_default();
        (src, scene, tables, path)
    }

    fn save(
        src: &str,
        scene: &Scene,
        tables: &[toml::Table],
        camera: Option<Camera>,
        path: &Path,
    ) -> Result<String, String> {
        let origin: Vec<Option<usize>> = (0..scene.lights.len()).map(Some).collect();
        save_lights(src, scene, tables, camera, path, &origin)
    }

    fn save_lights(
        src: &str,
        scene: &Scene,
        tables: &[toml::Table],
        camera: Option<Camera>,
        path: &Path,
        light_origin: &[Option<usize>],
    ) -> Result<String, String> {
        let edits = Edits {
            materials: tables,
            lights: &scene.lights,
            light_origin,
            camera,
            environment: &scene.environment,
        };
        edited_scene(src, &edits, path, path.parent().unwrap())
    }

    /// With no edit the copy is the file byte for byte, for every example
    /// scene (however it writes its tables).
    #[test]
    fn no_edit_saves_the_file_unchanged() {
        let mut n = 0;
        for e in std::fs::read_dir(examples()).unwrap() {
            let name = e.unwrap().file_name().into_string().unwrap();
            if !name.ends_with(".toml") {
                continue;
            }
            let (src, scene, tables, path) = read(&name);
            let out = save(&src, &scene, &tables, None, &path).unwrap();
            assert_eq!(out, src, "{name}");
            n += 1;
        }
        assert!(n >= 10, "{n} example scenes");
    }

    /// Every kind of edit comes back from the saved text through the scene
    /// reader as the viewer holds it, and the file's comments survive.
    #[test]
    fn edits_come_back_through_the_scene_reader() {
        let (src, mut scene, mut tables, path) = read("gallery.toml");
        // A parameter changed, and a material switched to another model.
        let i = tables
            .iter()
            .position(|t| t.get("type").and_then(|v| v.as_str()) == Some("ggx"))
            .expect("the gallery has a ggx material");
        tables[i].insert("roughness".into(), toml::Value::Float(0.37));
        let name = tables[0]["name"].as_str().unwrap().to_string();
        tables[0] = crate::params::template(&name, "ward");
        // A light moved and dimmed.
        scene.lights[0].position.x += 0.75;
        scene.lights[0].intensity.g = 3.25;
        // The view orbited and widened.
        let mut orbit = crate::orbit::Orbit::from_camera(&scene.camera);
        orbit.drag(40.0, -25.0);
        orbit.zoom(1.5);
        orbit.fov_y = 47.5;
        orbit.pan(30.0, -10.0, 400.0);
        // The environment map brightened.
        let Environment::Map(m) = &scene.environment else {
            panic!("the gallery has an environment map")
        };
        scene.environment = Environment::Map(m.with_scale(1.75).unwrap());

        let out = save(&src, &scene, &tables, Some(orbit.camera()), &path).unwrap();
        let back = isolux_scene::parse_str(&out, &path, path.parent().unwrap()).unwrap();
        let doc: toml::Table = toml::from_str(&out).unwrap();
        let saved: Vec<&toml::Table> = doc["material"]
            .as_array()
            .unwrap()
            .iter()
            .map(|m| m.as_table().unwrap())
            .collect();
        for (s, t) in saved.iter().zip(&tables) {
            assert_eq!(*s, t);
        }
        assert_eq!(back.material_names, scene.material_names);
        assert_eq!(back.materials[0].type_name(), "ward");
        assert_eq!(back.lights, scene.lights);
        let c = orbit.camera();
        assert!((back.camera.position - c.position).length() < 1e-7 * c.position.length());
        assert_eq!(back.camera.fov_y, 47.5);
        assert!((back.camera.look_at - c.look_at).length() < 1e-7 * c.position.length());
        assert!(
            (c.look_at - scene.camera.look_at).length() > 0.05,
            "the pan moved it"
        );
        let Environment::Map(b) = &back.environment else {
            panic!("map lost")
        };
        assert_eq!(b.scale(), 1.75);
        for line in src.lines().filter(|l| l.trim_start().starts_with('#')) {
            assert!(out.contains(line), "comment lost: {line}");
        }
        // Lines the edits did not touch are kept as they were.
        let kept = src.lines().filter(|l| out.lines().any(|o| o == *l)).count();
        assert!(
            kept * 10 >= src.lines().count() * 8,
            "{kept} of {} lines kept",
            src.lines().count()
        );
    }

    /// A constant environment the file left out is added when it is lit, a
    /// camera the file left out gets a section, and a refused edit is
    /// never saved.
    #[test]
    fn missing_sections_are_added_and_refused_edits_not_saved() {
        let src = "[[light]]\ntype = \"point\"\nposition = [0, 4, 0]\nintensity = [5, 5, 5]\n\n\
                   [[material]]\nname = \"m\"\ntype = \"diffuse\"\nreflectance = [0.5, 0.5, 0.5]\n";
        let path = Path::new("in-memory.toml");
        let mut scene = isolux_scene::parse_str(src, path, Path::new(".")).unwrap();
        let doc: toml::Table = toml::from_str(src).unwrap();
        let mut tables = vec![doc["material"][0].as_table().unwrap().clone()];
        scene.environment = Environment::Constant(isolux_core::Rgb::new(0.25, 0.5, 1.0));
        let mut orbit = crate::orbit::Orbit::from_camera(&scene.camera);
        orbit.zoom(-2.0);
        let out = save(src, &scene, &tables, Some(orbit.camera()), path).unwrap();
        let back = isolux_scene::parse_str(&out, path, Path::new(".")).unwrap();
        assert_eq!(
            back.environment.eval(glam::DVec3::Y),
            isolux_core::Rgb::new(0.25, 0.5, 1.0)
        );
        assert!((back.camera.position - orbit.eye()).length() < 1e-7 * orbit.distance);
        assert!(out.starts_with(src), "{out}");

        tables[0].insert(
            "reflectance".into(),
            toml::Value::Array(vec![toml::Value::Float(1.5); 3]),
        );
        let e = save(src, &scene, &tables, None, path).unwrap_err();
        assert!(e.contains("not saved") && e.contains("reflectance"), "{e}");
    }

    /// Lights added, removed and reordered come back in the viewer's
    /// order; a removed light takes its comments with it, the others keep
    /// theirs; removing them all leaves no `light` key.
    #[test]
    fn lights_added_and_removed_come_back_in_order() {
        let (src, mut scene, tables, path) = read("translucent.toml");
        assert_eq!(scene.lights.len(), 2);
        let new = PointLight {
            position: glam::DVec3::new(1.5, 4.0, -2.25),
            intensity: isolux_core::Rgb::new(10.0, 8.0, 6.0),
        };
        // Drop the first, keep the second, add one, in that order.
        scene.lights = vec![scene.lights[1], new];
        let out = save_lights(&src, &scene, &tables, None, &path, &[Some(1), None]).unwrap();
        let back = isolux_scene::parse_str(&out, &path, path.parent().unwrap()).unwrap();
        assert_eq!(back.lights, scene.lights);
        // Reversed, as inline tables: the same lights back.
        let inline =
            "light = [\n  { type = \"point\", position = [0, 4, 0], intensity = [5, 5, 5] },\n  \
                      { type = \"point\", position = [2, 4, 0], intensity = [1, 2, 3] },\n]\n";
        let p = Path::new("inline.toml");
        let mut s2 = isolux_scene::parse_str(inline, p, Path::new(".")).unwrap();
        s2.lights = vec![s2.lights[1], new, s2.lights[0]];
        let out = save_lights(inline, &s2, &[], None, p, &[Some(1), None, Some(0)]).unwrap();
        let back = isolux_scene::parse_str(&out, p, Path::new(".")).unwrap();
        assert_eq!(back.lights, s2.lights);
        // None left, then one added to a file without lights.
        scene.lights.clear();
        let out = save_lights(&src, &scene, &tables, None, &path, &[]).unwrap();
        assert!(!out.contains("[[light]]"), "{out}");
        let back = isolux_scene::parse_str(&out, &path, path.parent().unwrap()).unwrap();
        assert!(back.lights.is_empty());
        scene.lights = vec![new];
        let again = save_lights(&out, &scene, &tables, None, &path, &[None]).unwrap();
        let back = isolux_scene::parse_str(&again, &path, path.parent().unwrap()).unwrap();
        assert_eq!(back.lights, vec![new]);
        // A light the file does not have is an error, not a panic.
        let e = save_lights(&src, &scene, &tables, None, &path, &[Some(7)]).unwrap_err();
        assert!(e.contains("light 7"), "{e}");
    }

    #[test]
    fn values_compare_as_values() {
        let v = |s: &str| s.parse::<Value>().unwrap();
        assert!(same(&v("[0, 4, 0.5]"), &v("[0.0, 4.00, 5e-1]")));
        let mut commented = v("1.0");
        commented.decor_mut().set_suffix("   # W/sr");
        assert!(same(&commented, &v("1")));
        assert!(same(
            &v("{ a = 1, b = \"x\" }"),
            &v("{ b = \"x\", a = 1.0 }")
        ));
        assert!(!same(&v("[0, 4]"), &v("[0, 4, 0]")));
        assert!(!same(&v("\"1\""), &v("1")));
        // Integers compare exactly, not through f64.
        assert!(!same(&v("9223372036854775807"), &v("9223372036854775806")));
    }

    #[test]
    fn tidy_drops_rounding_noise_only() {
        assert_eq!(
            tidy([3.0000000000000004, -1e-17, 0.30000000000000004]),
            [3.0, 0.0, 0.3]
        );
        assert_eq!(tidy([1234.5678912345, 0.5, -2.0]), [1234.56789, 0.5, -2.0]);
        assert_eq!(tidy([0.0; 3]), [0.0; 3]);
        let x = [0.123456789123, 1e-3, 0.0];
        let t = tidy(x);
        assert!((t[0] - x[0]).abs() < 1e-9 && t[1] == 1e-3);
        assert_eq!(
            round_to([2.2e-16, 2.749493173818168, 3.6], 4),
            [0.0, 2.749, 3.6]
        );
        assert_eq!(round_to([20.24726339549089; 3], 3), [20.2; 3]);
    }

    #[test]
    fn free_paths_count_past_taken_ones() {
        let dir = tempfile::tempdir().unwrap();
        assert_eq!(
            free_path(dir.path(), "s"),
            dir.path().join("s-view-001.toml")
        );
        std::fs::write(dir.path().join("s-view-001.toml"), "").unwrap();
        assert_eq!(
            free_path(dir.path(), "s"),
            dir.path().join("s-view-002.toml")
        );
    }
}
