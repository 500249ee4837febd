//! The scene schema: sections, keys, defaults and validation.

use crate::reader::{Doc, Result, SceneError, Table, Value};
use isolux_core::{Aabb, DMat3, DMat4, DVec3, Rgb};
use isolux_geometry::{Aggregate, Object, Perturbation, Quadric};
use isolux_materials::Material;
use isolux_render::{
    Camera, Caustics, EnvMap, Environment, FilmSettings, IntegratorSettings, MediumLightSampling,
    PointLight, RefractedLights, Scene,
};
use std::path::Path;

mod materials;

use materials::material;
pub use materials::{MATERIAL_CHOICES, MATERIAL_INTEGERS};

/// Material `type` names accepted by this version.
pub const MATERIAL_TYPES: &[&str] = &[
    "diffuse",
    "phong",
    "blinn_phong",
    "gaussian",
    "cook_torrance",
    "ward",
    "heidrich_seidel",
    "ggx",
    "beckmann",
    "conductor",
    "dielectric",
    "plastic",
    "subsurface",
    "subsurface_brdf",
    "mix",
    "factored",
    "merl",
    "wave",
];

/// Quadric `type` names.
pub const QUADRIC_TYPES: &[&str] = &[
    "sphere",
    "ellipsoid",
    "cylinder",
    "cone",
    "paraboloid",
    "plane",
    "quadric",
];

/// Parses scene text. `file` is used in messages; `base_dir` resolves
/// relative file names.
pub fn parse_str(
    src: &str,
    file: &Path,
    base_dir: &Path,
) -> std::result::Result<Scene, SceneError> {
    let doc = Doc::new(file, src);
    let root = doc.parse()?;
    let t = Table::root(&doc, &root);
    t.allow(&[
        "camera",
        "film",
        "integrator",
        "light",
        "environment",
        "material",
        "object",
    ])?;
    let mut scene = Scene::default();
    let camera_table = t.get("camera").map(|v| v.table()).transpose()?;
    if let Some(c) = &camera_table {
        scene.camera = camera(c)?;
    }
    if let Some(v) = t.get("film") {
        scene.film = film(&v.table()?)?;
    }
    if let Some(v) = t.get("integrator") {
        scene.integrator = integrator(&v.table()?)?;
    }
    if let Err(msg) = scene.camera.rig(scene.film.width, scene.film.height) {
        return Err(match &camera_table {
            Some(c) => c.error(msg),
            None => t.error(msg),
        });
    }
    if let Some(v) = t.get("light") {
        for l in v.tables()? {
            scene.lights.push(light(&l)?);
        }
    }
    if let Some(v) = t.get("environment") {
        scene.environment = environment(&v.table()?, base_dir)?;
    }
    if let Some(v) = t.get("material") {
        for m in v.tables()? {
            let name_v = m.req("name")?;
            let name = name_v.str()?;
            if scene.material_names.iter().any(|n| n == name) {
                return Err(name_v.error(format!("duplicate material name \"{name}\"")));
            }
            let mat = material(&m, &scene.material_names, &scene.materials, base_dir)?;
            scene.materials.push(mat);
            scene.material_names.push(name.to_string());
        }
    }
    let mut objects = Vec::new();
    // The box holding the camera and every bounded object so far.
    let mut extent = Aabb {
        min: scene.camera.position,
        max: scene.camera.position,
    };
    if let Some(v) = t.get("object") {
        for o in v.tables()? {
            let (obj, mat) = object(&o, &scene.material_names)?;
            let b = obj.bbox();
            if b.is_finite() {
                let own = (b.max - b.min).max_element();
                let reach = b.min.abs().max(b.max.abs()).max_element();
                if reach > MAX_REACH * own {
                    return Err(o.error(format!(
                        "the object lies {reach:.3e} units from the world origin, {:.1e} \
                         times its size ({own:.3e}); rays leave surfaces 1e-14 of their \
                         distance from the origin off them, which holds to {MAX_REACH:e} \
                         times the size (docs/geometry.md, \"Scene scale\"): move the \
                         scene nearer the origin",
                        reach / own
                    )));
                }
                extent = extent.union(&b);
                let size = (extent.max - extent.min).max_element();
                if size > MAX_EXTENT {
                    return Err(o.error(format!(
                        "the scene reaches {size:.3e} units across with this object (camera \
                         included); the exact intersection holds to {MAX_EXTENT:e} \
                         (docs/geometry.md, \"Scene scale\"): choose a larger unit"
                    )));
                }
            }
            objects.push(obj);
            scene.object_material.push(mat);
        }
    }
    scene.geometry = Aggregate::new(objects);
    Ok(scene)
}

/// The largest side of the box that holds the camera and every bounded
/// object. The closed form of a quadric along a ray treats its t^2
/// coefficient as zero below 1e-15 of its other coefficients; for a
/// sphere from a point at distance D that ratio is 1 / D^2 (in the
/// sphere's normalization, whatever its radius), so rays lose spheres
/// from about 3e7 units away (docs/geometry.md, "Scene scale"). A scene
/// that large is refused with its object's line rather than rendered
/// with objects missing.
pub(crate) const MAX_EXTENT: f64 = 1.0e7;

/// How far from the world origin, in units of its own size, a bounded
/// object may lie. Each object is intersected in its own frame, so its
/// hits hold anywhere; what grows with the distance `D` from the origin
/// is the spawn offset's part `1e-14 D` (`Hit::offset`, which covers the
/// rounding of world coordinates). A scene moved `1e12` times its small
/// sphere's size renders within noise of itself at the origin (1.31
/// times the seed-to-seed noise where another seed reads 1.28), one
/// moved `1e13` times 3.06 times it (contact shadows lost); the limit
/// keeps a factor of ten (docs/geometry.md, "Scene scale").
pub(crate) const MAX_REACH: f64 = 1.0e11;

/// Parses one material from TOML text holding its keys at the top level
/// (`name = "gold"`, `type = "ggx"`, ...), as `[[material]]` would in a
/// scene: `names` and `earlier` are the materials defined before it (a
/// `mix` refers to them), `base_dir` resolves file names. Used by `isolux
/// view` to rebuild a material edited live, with the scene file's checks
/// and messages.
///
/// ```
/// let m = isolux_scene::parse_material(
///     "name = \"gold\"\ntype = \"ggx\"\nroughness = 0.3\nmetal = \"Au\"\n",
///     "edit".as_ref(), &[], &[], ".".as_ref(),
/// ).unwrap();
/// assert_eq!(m.type_name(), "ggx");
/// let err = isolux_scene::parse_material(
///     "name = \"x\"\ntype = \"ggx\"\nroughness = -1\n",
///     "edit".as_ref(), &[], &[], ".".as_ref(),
/// ).unwrap_err();
/// assert_eq!(err.to_string(), "edit:3:13: roughness: roughness must lie in (0, 10], got -1");
/// ```
pub fn parse_material(
    src: &str,
    file: &Path,
    names: &[String],
    earlier: &[Material],
    base_dir: &Path,
) -> std::result::Result<Material, SceneError> {
    let doc = Doc::new(file, src);
    let root = doc.parse()?;
    let t = Table::root(&doc, &root);
    t.req("name")?.str()?;
    material(&t, names, earlier, base_dir)
}

fn vec3(v: &Value) -> Result<DVec3> {
    Ok(DVec3::from_array(v.numbers::<3>()?))
}

fn direction(v: &Value) -> Result<DVec3> {
    let d = vec3(v)?;
    d.try_normalize()
        .ok_or_else(|| v.error("must be a non-zero vector"))
}

fn rgb_nonneg(v: &Value) -> Result<Rgb> {
    let c = v.numbers::<3>()?;
    if c.iter().any(|&x| x < 0.0) {
        return Err(v.error(format!("components must be non-negative, got {c:?}")));
    }
    Ok(Rgb::from_array(c))
}

fn reflectance(v: &Value) -> Result<Rgb> {
    let c = rgb_nonneg(v)?;
    if c.max_component() > 1.0 {
        return Err(v.error(format!(
            "reflectance above 1 would create energy, got {:?}",
            c.to_array()
        )));
    }
    Ok(c)
}

fn camera(t: &Table) -> Result<Camera> {
    t.allow(&["position", "look_at", "up", "fov_y"])?;
    let mut c = Camera::default();
    if let Some(v) = t.get("position") {
        c.position = vec3(&v)?;
    }
    if let Some(v) = t.get("look_at") {
        c.look_at = vec3(&v)?;
    }
    if let Some(v) = t.get("up") {
        c.up = direction(&v)?;
    }
    if let Some(v) = t.get("fov_y") {
        let f = v.f64()?;
        if !(f > 0.0 && f < 180.0) {
            return Err(v.error(format!(
                "must lie strictly between 0 and 180 degrees, got {f}"
            )));
        }
        c.fov_y = f;
    }
    Ok(c)
}

fn film(t: &Table) -> Result<FilmSettings> {
    t.allow(&["width", "height", "spp"])?;
    let mut f = FilmSettings::default();
    let side = FilmSettings::MAX_SIDE as u64;
    if let Some(v) = t.get("width") {
        f.width = v.uint(1, side)? as u32;
    }
    if let Some(v) = t.get("height") {
        f.height = v.uint(1, side)? as u32;
    }
    if let Some(v) = t.get("spp") {
        f.spp = v.uint(1, FilmSettings::MAX_SPP as u64)? as u32;
    }
    // Each side within bounds, the pixel count too (at the height, or the
    // width where the height is the default).
    if let Some(p) = f.problem() {
        let at = t.get("height").or_else(|| t.get("width"));
        return Err(match at {
            Some(v) => v.error(p.message),
            None => t.error(p.message),
        });
    }
    Ok(f)
}

fn integrator(t: &Table) -> Result<IntegratorSettings> {
    t.allow(&[
        "max_depth",
        "seed",
        "medium_light_sampling",
        "refracted_lights",
        "caustics",
    ])?;
    let mut s = IntegratorSettings::default();
    if let Some(v) = t.get("caustics") {
        s.caustics = match v.choice(&["manifold", "none"])? {
            "none" => Caustics::None,
            _ => Caustics::Manifold,
        };
    }
    if let Some(v) = t.get("refracted_lights") {
        s.refracted_lights = match v.choice(&["manifold", "flat"])? {
            "flat" => RefractedLights::Flat,
            _ => RefractedLights::Manifold,
        };
    }
    if let Some(v) = t.get("medium_light_sampling") {
        s.medium_lights = match v.choice(&["equiangular", "distance"])? {
            "distance" => MediumLightSampling::Distance,
            _ => MediumLightSampling::Equiangular,
        };
    }
    if let Some(v) = t.get("max_depth") {
        s.max_depth = v.uint(0, IntegratorSettings::MAX_DEPTH as u64)? as u32;
    }
    if let Some(v) = t.get("seed") {
        s.seed = v.uint(0, i64::MAX as u64)?;
    }
    Ok(s)
}

fn light(t: &Table) -> Result<PointLight> {
    t.req("type")?.choice(&["point"])?;
    t.allow(&["type", "position", "intensity"])?;
    Ok(PointLight {
        position: vec3(&t.req("position")?)?,
        intensity: rgb_nonneg(&t.req("intensity")?)?,
    })
}

fn environment(t: &Table, base_dir: &Path) -> Result<Environment> {
    match t.req("type")?.choice(&["constant", "map"])? {
        "constant" => {
            t.allow(&["type", "radiance"])?;
            Ok(Environment::Constant(rgb_nonneg(&t.req("radiance")?)?))
        }
        _ => {
            t.allow(&["type", "file", "scale"])?;
            let fv = t.req("file")?;
            let file = base_dir.join(fv.str()?);
            let scale = match t.get("scale") {
                Some(v) => {
                    let s = v.f64()?;
                    if s < 0.0 {
                        return Err(v.error(format!("must be non-negative, got {s}")));
                    }
                    s
                }
                None => 1.0,
            };
            let img = isolux_io::read_rgb_image(&file).map_err(|e| fv.error(e.to_string()))?;
            let texels = img
                .pixels
                .iter()
                .map(|p| Rgb::new(p[0] as f64, p[1] as f64, p[2] as f64))
                .collect();
            let map = EnvMap::new(img.width, img.height, texels, scale)
                .map_err(|e| fv.error(format!("{}: {e}", file.display())))?;
            Ok(Environment::Map(map))
        }
    }
}

/// `transform = { translate, rotate, scale }`: `M = T R S`, rotation in
/// degrees about x, then y, then z.
fn transform(t: &Table) -> Result<DMat4> {
    t.allow(&["translate", "rotate", "scale"])?;
    let translate = match t.get("translate") {
        Some(v) => vec3(&v)?,
        None => DVec3::ZERO,
    };
    let rot = match t.get("rotate") {
        Some(v) => rotation(&v)?,
        None => DMat3::IDENTITY,
    };
    let scale = match t.get("scale") {
        Some(v) => {
            let s = if v.array().is_ok() {
                vec3(&v)?
            } else {
                DVec3::splat(v.f64()?)
            };
            if s.x == 0.0 || s.y == 0.0 || s.z == 0.0 {
                return Err(v.error("scale factors must be non-zero"));
            }
            s
        }
        None => DVec3::ONE,
    };
    Ok(DMat4::from_translation(translate) * DMat4::from_mat3(rot) * DMat4::from_scale(scale))
}

fn rotation(v: &Value) -> Result<DMat3> {
    let [rx, ry, rz] = v.numbers::<3>()?;
    Ok(DMat3::from_rotation_z(rz.to_radians())
        * DMat3::from_rotation_y(ry.to_radians())
        * DMat3::from_rotation_x(rx.to_radians()))
}

/// A quadric form as a scene writes it: its shape about its own point
/// (`center`, `apex`, `vertex` or `point`; none for `coefficients`), that
/// point, and its own `transform`. Kept apart so that an object's
/// quadrics can be written about a point near the object
/// ([`Form::in_frame`]) rather than expanded about the world origin, where
/// far from it their constant terms would lose the object's size to
/// rounding (docs/geometry.md, "Scene scale").
struct Form {
    /// The shape with its own point at zero.
    shape: Quadric,
    /// The shape's own point.
    at: DVec3,
    /// The quadric's own `transform`.
    transform: Option<DMat4>,
}

impl Form {
    /// The affine map from the shape's coordinates to the world: the
    /// shape's point, its `transform`, then the object's `outer` one.
    fn map(&self, outer: Option<&DMat4>) -> DMat4 {
        let mut m = DMat4::from_translation(self.at);
        if let Some(x) = &self.transform {
            m = *x * m;
        }
        if let Some(x) = outer {
            m = *x * m;
        }
        m
    }

    /// Where the shape's own point lies in the world.
    fn world_point(&self, outer: Option<&DMat4>) -> DVec3 {
        self.map(outer).w_axis.truncate()
    }

    /// The quadric in the frame whose zero is the world point `origin`.
    fn in_frame(&self, outer: Option<&DMat4>, origin: DVec3) -> Quadric {
        let mut m = self.map(outer);
        m.w_axis -= origin.extend(0.0);
        if self.transform.is_none() && outer.is_none() {
            self.shape.translated(m.w_axis.truncate())
        } else {
            self.shape.transformed(&m)
        }
    }
}

/// One of the quadric forms (see `docs/scene-format.md`).
fn quadric(t: &Table) -> Result<Form> {
    let ty = t.req("type")?.choice(QUADRIC_TYPES)?;
    let keys: &[&str] = match ty {
        "sphere" => &["center", "radius"],
        "ellipsoid" => &["center", "radii", "rotate"],
        "cylinder" => &["center", "axis", "radius"],
        "cone" => &["apex", "axis", "angle"],
        "paraboloid" => &["vertex", "axis", "focal_length"],
        "plane" => &["point", "normal"],
        _ => &["coefficients"],
    };
    let mut all = vec!["type", "transform"];
    all.extend_from_slice(keys);
    t.allow(&all)?;
    let z = DVec3::ZERO;
    let (q, at) = match ty {
        "sphere" => (
            Quadric::sphere(z, t.req("radius")?.positive()?),
            vec3(&t.req("center")?)?,
        ),
        "ellipsoid" => {
            let rv = t.req("radii")?;
            let r = vec3(&rv)?;
            if r.min_element() <= 0.0 {
                return Err(rv.error("radii must be positive"));
            }
            let rot = match t.get("rotate") {
                Some(v) => rotation(&v)?,
                None => DMat3::IDENTITY,
            };
            (Quadric::ellipsoid(z, r, rot), vec3(&t.req("center")?)?)
        }
        "cylinder" => (
            Quadric::cylinder(z, direction(&t.req("axis")?)?, t.req("radius")?.positive()?),
            vec3(&t.req("center")?)?,
        ),
        "cone" => {
            let av = t.req("angle")?;
            let a = av.f64()?;
            if !(a > 0.0 && a < 90.0) {
                return Err(av.error(format!(
                    "half-angle must lie strictly between 0 and 90 degrees, got {a}"
                )));
            }
            (
                Quadric::cone(z, direction(&t.req("axis")?)?, a.to_radians()),
                vec3(&t.req("apex")?)?,
            )
        }
        "paraboloid" => (
            Quadric::paraboloid(
                z,
                direction(&t.req("axis")?)?,
                t.req("focal_length")?.positive()?,
            ),
            vec3(&t.req("vertex")?)?,
        ),
        "plane" => (
            Quadric::plane(z, direction(&t.req("normal")?)?),
            vec3(&t.req("point")?)?,
        ),
        _ => {
            let cv = t.req("coefficients")?;
            let c = cv.numbers::<10>()?;
            if c.iter().all(|&x| x == 0.0) {
                return Err(cv.error("all coefficients are zero"));
            }
            (Quadric::from_coefficients(c), z)
        }
    };
    let transform = match t.get("transform") {
        Some(v) => Some(transform(&v.table()?)?),
        None => None,
    };
    Ok(Form {
        shape: q,
        at,
        transform,
    })
}

fn object(t: &Table, material_names: &[String]) -> Result<(Object, usize)> {
    t.allow(&[
        "name",
        "material",
        "base",
        "bounds",
        "transform",
        "perturbation",
    ])?;
    let mv = t.req("material")?;
    let mname = mv.str()?;
    let mat = material_names
        .iter()
        .position(|n| n == mname)
        .ok_or_else(|| {
            mv.error(if material_names.is_empty() {
                format!("unknown material \"{mname}\": the scene defines no [[material]]")
            } else {
                format!(
                    "unknown material \"{mname}\" (defined: {})",
                    material_names.join(", ")
                )
            })
        })?;
    let xf = match t.get("transform") {
        Some(v) => Some(transform(&v.table()?)?),
        None => None,
    };
    // The object's quadrics are written about its base's own point (a
    // sphere's centre, say): `Object::in_frame`.
    let base = quadric(&t.req("base")?.table()?)?;
    let origin = base.world_point(xf.as_ref());
    let base = base.in_frame(xf.as_ref(), origin);
    let mut perts = Vec::new();
    if let Some(v) = t.get("perturbation") {
        for p in v.tables()? {
            p.allow(&["quadric", "factor"])?;
            let q = quadric(&p.req("quadric")?.table()?)?.in_frame(xf.as_ref(), origin);
            perts.push(Perturbation {
                quadric: q,
                factor: p.req("factor")?.f64()?,
            });
        }
    }
    let bounds = match t.get("bounds") {
        Some(v) => {
            let b = v.table()?;
            b.allow(&["min", "max"])?;
            let lo = vec3(&b.req("min")?)?;
            let hi = vec3(&b.req("max")?)?;
            if !(lo.cmplt(hi).all()) {
                return Err(v.error("bounds.min must be below bounds.max on every axis"));
            }
            Some(Aabb { min: lo, max: hi }.translated(-origin))
        }
        None => None,
    };
    let obj = Object::in_frame(origin, base, perts, bounds).map_err(|e| t.error(e.to_string()))?;
    Ok((obj, mat))
}
