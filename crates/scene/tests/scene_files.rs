//! Scene files: every documented key, every example, and bad input.

use isolux_core::{DVec3, Rgb};
use isolux_render::Environment;
use std::path::Path;

fn parse(src: &str) -> Result<isolux_render::Scene, String> {
    isolux_scene::parse_str(src, Path::new("s.toml"), Path::new(".")).map_err(|e| e.to_string())
}

/// Every key of docs/scene-format.md in one file.
const ALL_KEYS: &str = r#"
[camera]
position = [1.0, 2.0, 3.0]
look_at = [0.0, 0.5, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 45

[film]
width = 320
height = 200
spp = 9

[integrator]
max_depth = 12
seed = 77

[[light]]
type = "point"
position = [0.0, 5.0, 0.0]
intensity = [10.0, 9.0, 8.0]

[environment]
type = "constant"
radiance = [0.1, 0.2, 0.3]

[[material]]
name = "a"
type = "diffuse"
reflectance = [0.9, 0.5, 0.1]

[[material]]
name = "b"
type = "diffuse"

[[material]]
name = "gold"
type = "ggx"
roughness_u = 0.1
roughness_v = 0.4
tangent = [0.0, 1.0, 0.0]
metal = "Au"

[[material]]
name = "satin"
type = "beckmann"
roughness = 0.3
eta = [0.2, 0.9, 1.1]
k = [3.9, 2.4, 2.2]

[[material]]
name = "coat"
type = "ggx"
roughness = 0.2
ior = 1.5

[[material]]
name = "paint"
type = "beckmann"
schlick = [0.04, 0.04, 0.04]

[[material]]
name = "mirror"
type = "conductor"

[[material]]
name = "glass"
type = "dielectric"
ior = 1.33

[[material]]
name = "shiny"
type = "phong"
exponent = 50
specular = [0.2, 0.2, 0.2]
reflectance = [0.7, 0.7, 0.7]

[[material]]
name = "lacquer"
type = "blinn_phong"
exponent = 120

[[material]]
name = "gauss"
type = "gaussian"
m = 0.3
specular = [0.3, 0.3, 0.3]
reflectance = [0.2, 0.2, 0.2]

[[material]]
name = "ct"
type = "cook_torrance"
roughness = 0.2
distribution = "ggx"
masking = "smith"
metal = "Cu"
reflectance = [0.1, 0.1, 0.1]

[[material]]
name = "wardish"
type = "ward"
alpha_u = 0.1
alpha_v = 0.3
specular = [0.4, 0.4, 0.4]
tangent = [1.0, 0.0, 0.0]

[[material]]
name = "toy"
type = "plastic"
ior = 1.4
reflectance = [0.8, 0.1, 0.1]
roughness = 0.2

[[material]]
name = "blend"
type = "mix"
components = [{ material = "b", weight = 0.5 }, { material = "gold", weight = 0.25 }]

[[object]]
name = "blob"
material = "a"
base = { type = "sphere", center = [0.0, 0.0, 0.0], radius = 1.0 }
transform = { translate = [0.0, 1.0, 0.0], rotate = [0.0, 30.0, 0.0], scale = 0.5 }
[[object.perturbation]]
quadric = { type = "sphere", center = [0.0, 1.0, 0.0], radius = 0.3 }
factor = 100.0
[[object.perturbation]]
quadric = { type = "ellipsoid", center = [1.0, 0.0, 0.0], radii = [0.3, 0.2, 0.1], rotate = [10.0, 20.0, 30.0] }
factor = -50.0
[[object.perturbation]]
quadric = { type = "quadric", coefficients = [-1.0, -1.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, -0.91] }
factor = 10.0

[[object]]
material = "b"
base = { type = "plane", point = [0.0, -1.0, 0.0], normal = [0.0, 1.0, 0.0] }
bounds = { min = [-5.0, -2.0, -5.0], max = [5.0, 0.0, 5.0] }

[[object]]
material = "b"
base = { type = "cylinder", center = [3.0, 0.0, 0.0], axis = [0.0, 1.0, 0.0], radius = 0.2, transform = { translate = [0.0, 0.0, 1.0] } }
bounds = { min = [2.0, -1.0, -1.0], max = [4.0, 1.0, 3.0] }

[[object]]
material = "b"
base = { type = "cone", apex = [-3.0, 1.0, 0.0], axis = [0.0, -1.0, 0.0], angle = 20.0 }
bounds = { min = [-4.0, -1.0, -1.0], max = [-2.0, 1.0, 1.0] }

[[object]]
material = "b"
base = { type = "paraboloid", vertex = [0.0, -1.0, -3.0], axis = [0.0, 1.0, 0.0], focal_length = 0.25 }
bounds = { min = [-1.0, -1.0, -4.0], max = [1.0, 0.5, -2.0] }
"#;

#[test]
fn every_documented_key_is_parsed() {
    let s = parse(ALL_KEYS).unwrap();
    assert_eq!(s.camera.position, DVec3::new(1.0, 2.0, 3.0));
    assert_eq!(s.camera.look_at, DVec3::new(0.0, 0.5, 0.0));
    assert_eq!(s.camera.fov_y, 45.0);
    assert_eq!((s.film.width, s.film.height, s.film.spp), (320, 200, 9));
    assert_eq!((s.integrator.max_depth, s.integrator.seed), (12, 77));
    assert_eq!(s.lights.len(), 1);
    assert_eq!(s.lights[0].intensity, Rgb::new(10.0, 9.0, 8.0));
    assert!(matches!(s.environment, Environment::Constant(c) if c == Rgb::new(0.1, 0.2, 0.3)));
    assert_eq!(
        s.material_names,
        vec![
            "a", "b", "gold", "satin", "coat", "paint", "mirror", "glass", "shiny", "lacquer",
            "gauss", "ct", "wardish", "toy", "blend"
        ]
    );
    use isolux_materials::{Fresnel, Material};
    match &s.materials[2] {
        Material::Ggx(g) => {
            assert_eq!(
                (g.lobe.distribution.alpha_x, g.lobe.distribution.alpha_y),
                (0.1, 0.4)
            );
            assert_eq!(g.tangent, Some(DVec3::Y));
            assert!(matches!(g.lobe.fresnel, Fresnel::Conductor { .. }));
        }
        m => panic!("{m:?}"),
    }
    assert!(
        matches!(&s.materials[3], Material::Beckmann(b) if b.lobe.distribution.alpha_x == 0.3 && matches!(b.lobe.fresnel, Fresnel::Conductor { eta, .. } if eta.r == 0.2))
    );
    assert!(
        matches!(&s.materials[4], Material::Ggx(g) if g.lobe.fresnel == Fresnel::Dielectric { ior: 1.5 })
    );
    assert!(
        matches!(&s.materials[5], Material::Beckmann(b) if matches!(b.lobe.fresnel, Fresnel::Schlick { .. }) && b.lobe.distribution.alpha_x == 0.2)
    );
    assert!(matches!(&s.materials[6], Material::Conductor(c) if c.fresnel == Fresnel::One));
    assert!(matches!(&s.materials[7], Material::Dielectric(d) if d.ior == 1.33));
    assert!(
        matches!(&s.materials[8], Material::Phong(p) if p.0.lobe.exponent == 50.0 && p.0.reflectance.r == 0.7)
    );
    assert!(
        matches!(&s.materials[9], Material::BlinnPhong(p) if p.0.lobe.exponent == 120.0 && p.0.specular.g == 0.5)
    );
    assert!(matches!(&s.materials[10], Material::Gaussian(g) if g.specular.r == 0.3));
    assert!(
        matches!(&s.materials[11], Material::CookTorrance(c) if c.masking == isolux_materials::cook_torrance::Masking::Smith && c.reflectance.g == 0.1)
    );
    assert!(
        matches!(&s.materials[12], Material::Ward(w) if w.inner.lobe.alpha_y == 0.3 && w.tangent == Some(DVec3::X))
    );
    assert!(
        matches!(&s.materials[13], Material::Plastic(p) if p.ior == 1.4 && p.coat.is_some() && p.reflectance.r == 0.8)
    );
    assert!(
        matches!(&s.materials[14], Material::Mix(m) if m.components.len() == 2 && m.components[1].1 == 0.25)
    );
    assert_eq!(s.object_material, vec![0, 1, 1, 1, 1]);
    let objs = s.geometry.objects();
    assert_eq!(objs.len(), 5);
    assert_eq!(objs[0].perturbations().len(), 3);
    // The base quadrics, in world coordinates.
    let base = |i: usize| objs[i].base().translated(objs[i].origin());
    // The transform moved the unit sphere to radius 0.5 around (0, 1, 0).
    assert!(base(0).eval(DVec3::new(0.5, 1.0, 0.0)).abs() < 1e-12);
    assert!(base(0).eval(DVec3::new(0.0, 1.0, 0.0)) > 0.0);
    // Bounded plane and cylinder got finite boxes.
    assert!(objs[1].bbox().is_finite() && objs[2].bbox().is_finite());
    // The cylinder's own transform moved its axis to z = 1.
    assert!(base(2).eval(DVec3::new(3.0, 0.0, 1.0)) > 0.0);
    assert!(base(2).eval(DVec3::new(3.0, 0.0, 0.0)) < 0.0);
}

#[test]
fn defaults_fill_a_minimal_scene() {
    let s = parse("").unwrap();
    assert_eq!((s.film.width, s.film.height, s.film.spp), (640, 480, 16));
    assert_eq!(s.integrator.max_depth, 8);
    assert!(matches!(s.environment, Environment::Constant(c) if c == Rgb::BLACK));
}

#[test]
fn every_example_scene_loads() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
    let mut n = 0;
    for dir in ["scenes", "bench", "tests"] {
        for e in std::fs::read_dir(root.join(dir)).unwrap() {
            let p = e.unwrap().path();
            if p.extension().is_some_and(|x| x == "toml") {
                isolux_scene::load(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
                n += 1;
            }
        }
    }
    assert!(n >= 3);
}

/// The benchmark's control scene (examples/bench/gallery-diffuse.toml)
/// is the gallery with every material diffuse: the same objects, in the
/// same order with the same materials' names, camera, lights and film.
#[test]
fn the_diffuse_gallery_keeps_the_gallerys_geometry() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
    let g = isolux_scene::load(&root.join("scenes/gallery.toml")).unwrap();
    let d = isolux_scene::load(&root.join("bench/gallery-diffuse.toml")).unwrap();
    assert_eq!(g.material_names, d.material_names);
    assert_eq!(g.object_material, d.object_material);
    assert!(d.materials.iter().all(|m| m.type_name() == "diffuse"));
    assert_eq!(format!("{:?}", g.camera), format!("{:?}", d.camera));
    assert_eq!(format!("{:?}", g.lights), format!("{:?}", d.lights));
    assert_eq!(g.film.width, d.film.width);
    let (go, dobj) = (g.geometry.objects(), d.geometry.objects());
    assert_eq!(go.len(), dobj.len());
    for (a, b) in go.iter().zip(dobj) {
        assert_eq!(format!("{:?}", a.bbox()), format!("{:?}", b.bbox()));
    }
}

#[test]
fn bad_scenes_are_rejected_with_file_line_column_and_key() {
    let cases: &[(&str, &str)] = &[
        ("[film]\nwidth = 0\n", "s.toml:2:9: film.width: must lie in 1..=65536, got 0"),
        ("[film]\nwidth = 60000\nheight = 60000\n", "s.toml:3:10: film.height: 60000 x 60000 is 3600000000 pixels, more than the 268435456 (16384 x 16384) an image may hold"),
        ("[film]\nspp = 2000000\n", "s.toml:2:7: film.spp: must lie in 1..=1048576, got 2000000"),
        ("[integrator]\nmax_depth = 1000001\n", "s.toml:2:13: integrator.max_depth: must lie in 0..=1000000, got 1000001"),
        ("[film]\nwidht = 10\n", "s.toml:2:1: film.widht: unknown key (valid keys here: height, spp, width)"),
        ("[film]\nwidth = \"big\"\n", "s.toml:2:9: film.width: expected an integer, found a string"),
        ("[camera]\nfov_y = nan\n", "s.toml:2:9: camera.fov_y: must be a finite number, got NaN"),
        ("[camera]\nposition = [1.0, inf, 0.0]\n", "s.toml:2:18: camera.position[1]: must be a finite number, got inf"),
        ("[camera]\nposition = [1.0, 2.0]\n", "s.toml:2:12: camera.position: expected an array of 3 numbers, found 2"),
        ("[camera]\nposition = [0.0, 0.0, 0.0]\n", "s.toml:1:1: camera: camera position equals look_at"),
        ("[camera]\nfov_y = 180\n", "s.toml:2:9: camera.fov_y: must lie strictly between 0 and 180 degrees, got 180"),
        ("[[light]]\ntype = \"spot\"\n", "s.toml:2:8: light[0].type: unknown value \"spot\" (valid: point)"),
        ("[integrator]\nmedium_light_sampling = \"uniform\"\n", "s.toml:2:25: integrator.medium_light_sampling: unknown value \"uniform\" (valid: equiangular, distance)"),
        ("[integrator]\nrefracted_lights = \"none\"\n", "s.toml:2:20: integrator.refracted_lights: unknown value \"none\" (valid: manifold, flat)"),
        ("[integrator]\ncaustics = \"photons\"\n", "s.toml:2:12: integrator.caustics: unknown value \"photons\" (valid: manifold, none)"),
        ("[[light]]\ntype = \"point\"\nposition = [0, 1, 0]\n", "s.toml:1:1: light[0].intensity: missing required key"),
        ("[[light]]\ntype = \"point\"\nposition = [0, 1, 0]\nintensity = [1, -1, 1]\n", "s.toml:4:13: light[0].intensity: components must be non-negative"),
        ("[environment]\ntype = \"map\"\nfile = \"nope.hdr\"\n", "s.toml:3:8: environment.file: ./nope.hdr: file not found"),
        ("[[material]]\nname = \"m\"\ntype = \"velvet\"\n", "s.toml:3:8: material[0].type: unknown value \"velvet\" (valid: diffuse, phong, blinn_phong, gaussian, cook_torrance, ward, heidrich_seidel, ggx, beckmann, conductor, dielectric, plastic, subsurface, subsurface_brdf, mix, factored, merl, wave)"),
        ("[[material]]\nname = \"m\"\ntype = \"diffuse\"\nreflectance = [1.2, 0.5, 0.5]\n", "s.toml:4:15: material[0].reflectance: reflectance above 1 would create energy"),
        ("[[material]]\nname = \"m\"\ntype = \"diffuse\"\n[[material]]\nname = \"m\"\ntype = \"diffuse\"\n", "s.toml:5:8: material[1].name: duplicate material name \"m\""),
        ("[[object]]\nmaterial = \"x\"\nbase = { type = \"sphere\", center = [0, 0, 0], radius = 1 }\n", "s.toml:2:12: object[0].material: unknown material \"x\": the scene defines no [[material]]"),
        ("[[material]]\nname = \"m\"\ntype = \"diffuse\"\n[[object]]\nmaterial = \"m\"\nbase = { type = \"sphere\", center = [0, 0, 0], radius = -1 }\n", "s.toml:6:56: object[0].base.radius: must be positive, got -1"),
        ("[[material]]\nname = \"m\"\ntype = \"diffuse\"\n[[object]]\nmaterial = \"m\"\nbase = { type = \"torus\" }\n", "s.toml:6:17: object[0].base.type: unknown value \"torus\" (valid: sphere, ellipsoid, cylinder, cone, paraboloid, plane, quadric)"),
        ("[[material]]\nname = \"m\"\ntype = \"diffuse\"\n[[object]]\nmaterial = \"m\"\nbase = { type = \"sphere\", center = [0, 0, 0], radius = 1, colour = 3 }\n", "s.toml:6:59: object[0].base.colour: unknown key"),
        ("[[material]]\nname = \"m\"\ntype = \"diffuse\"\n[[object]]\nmaterial = \"m\"\nbase = { type = \"plane\", point = [0, 0, 0], normal = [0, 1, 0] }\n[[object.perturbation]]\nquadric = { type = \"cylinder\", center = [0, 0, 0], axis = [0, 1, 0], radius = 1 }\nfactor = 1\n", "s.toml:4:1: object[0]: perturbation 0 has unbounded support"),
        ("[[material]]\nname = \"m\"\ntype = \"diffuse\"\n[[object]]\nmaterial = \"m\"\nbase = { type = \"sphere\", center = [0, 0, 0], radius = 1 }\n[[object.perturbation]]\nquadric = { type = \"sphere\", center = [0, 0, 0], radius = 1 }\n", "s.toml:7:1: object[0].perturbation[0].factor: missing required key"),
        ("[[material]]\nname = \"m\"\ntype = \"diffuse\"\n[[object]]\nmaterial = \"m\"\nbase = { type = \"sphere\", center = [0, 0, 0], radius = 1 }\nbounds = { min = [1, 1, 1], max = [0, 2, 2] }\n", "s.toml:7:10: object[0].bounds: bounds.min must be below bounds.max on every axis"),
        // Too large for the exact intersection (MAX_EXTENT): the second
        // object takes the scene past it, and is named.
        ("[[material]]\nname = \"m\"\ntype = \"diffuse\"\n[[object]]\nmaterial = \"m\"\nbase = { type = \"sphere\", center = [0, 0, 0], radius = 4e6 }\n[[object]]\nmaterial = \"m\"\nbase = { type = \"sphere\", center = [0, 0, 9e6], radius = 1 }\n", "s.toml:7:1: object[1]: the scene reaches 1.300e7 units across with this object (camera included)"),
        // Too far from the world origin for its size (MAX_REACH).
        ("[[material]]\nname = \"m\"\ntype = \"diffuse\"\n[[object]]\nmaterial = \"m\"\nbase = { type = \"sphere\", center = [3e11, 0, 0], radius = 1 }\n", "s.toml:4:1: object[0]: the object lies 3.000e11 units from the world origin, 1.5e11 times its size (2.000e0)"),
        ("[[material]]\nname = \"m\"\ntype = \"ggx\"\nroughness = 0.1\nroughness_u = 0.2\n", "s.toml:1:1: material[0]: give either `roughness` or `roughness_u` with `roughness_v`, not both"),
        ("[[material]]\nname = \"m\"\ntype = \"beckmann\"\nroughness_u = 0.2\n", "s.toml:1:1: material[0]: `roughness_u` and `roughness_v` go together: give both"),
        ("[[material]]\nname = \"m\"\ntype = \"ggx\"\nroughness = 0\n", "s.toml:4:13: material[0].roughness: roughness must lie in (0, 10], got 0"),
        ("[[material]]\nname = \"m\"\ntype = \"ggx\"\nroughness = nan\n", "s.toml:4:13: material[0].roughness: must be a finite number, got NaN"),
        ("[[material]]\nname = \"m\"\ntype = \"conductor\"\nmetal = \"Pt\"\n", "s.toml:4:9: material[0].metal: unknown metal \"Pt\" (valid: Ag, Al, Au, Cr, Cu, Fe, Ni, Ti)"),
        ("[[material]]\nname = \"m\"\ntype = \"conductor\"\nmetal = \"Au\"\nior = 1.5\n", "s.toml:1:1: material[0]: conflicting Fresnel keys: give only one of `metal`, `eta` + `k`, `ior`, `schlick`"),
        ("[[material]]\nname = \"m\"\ntype = \"ggx\"\nior = 0\n", "s.toml:4:7: material[0].ior: ior must be positive, got 0"),
        ("[[material]]\nname = \"m\"\ntype = \"ggx\"\neta = [0.2, 0.3, 1.0]\n", "s.toml:1:1: material[0].k: missing required key"),
        ("[[material]]\nname = \"m\"\ntype = \"ggx\"\nschlick = [0.5, 1.5, 0.5]\n", "s.toml:4:11: material[0].schlick: schlick F0 must lie in [0, 1]"),
        ("[[material]]\nname = \"m\"\ntype = \"conductor\"\nroughness = 0.1\n", "s.toml:4:1: material[0].roughness: unknown key (valid keys here: eta, ior, k, metal, name, schlick, type)"),
        ("[[material]]\nname = \"g\"\ntype = \"dielectric\"\nior = -1.5\n", "s.toml:4:7: material[0].ior: ior must be positive, got -1.5"),
        ("[[material]]\nname = \"p\"\ntype = \"phong\"\nspecular = [0.6, 0.6, 0.6]\nreflectance = [0.5, 0.3, 0.3]\n", "s.toml:1:1: material[0]: reflectance + specular = [1.1, 0.9, 0.9] exceeds 1: the material would create energy"),
        ("[[material]]\nname = \"a\"\ntype = \"diffuse\"\n[[material]]\nname = \"x\"\ntype = \"mix\"\ncomponents = [{ material = \"a\", weight = 0.7 }, { material = \"a\", weight = 0.4 }]\n", "s.toml:7:14: material[1].components: weights sum to 1.1"),
        ("[[material]]\nname = \"a\"\ntype = \"diffuse\"\n[[material]]\nname = \"x\"\ntype = \"mix\"\ncomponents = [{ material = \"a\", weight = 0.6 }, { material = \"a\", weight = 0.54 }]\n", "s.toml:7:14: material[1].components: weights sum to 1.14, above 1: the mix would create energy"),
        ("[[material]]\nname = \"x\"\ntype = \"mix\"\ncomponents = [{ material = \"later\", weight = 0.5 }]\n", "s.toml:4:28: material[0].components[0].material: unknown material \"later\": a mix refers to materials defined before it (defined: none)"),
        ("[[material]]\nname = \"g\"\ntype = \"dielectric\"\n[[material]]\nname = \"x\"\ntype = \"mix\"\ncomponents = [{ material = \"g\", weight = 0.5 }]\n", "s.toml:7:28: material[1].components[0].material: \"g\" is a delta (dielectric) material"),
        ("[[material]]\nname = \"c\"\ntype = \"cook_torrance\"\ndistribution = \"gaussian\"\nmasking = \"smith\"\n", "s.toml:5:11: material[0].masking: smith masking needs distribution"),
        ("[[material]]\nname = \"c\"\ntype = \"cook_torrance\"\ndistribution = \"phong\"\n", "s.toml:4:16: material[0].distribution: unknown value \"phong\" (valid: beckmann, ggx, gaussian)"),
        ("[[material]]\nname = \"c\"\ntype = \"gaussian\"\nm = 1.5\n", "s.toml:4:5: material[0].m: m must lie in [1e-3, 1] radians, got 1.5"),
        // Narrower than the sampling table's bins; at 1e-4 the old
        // normalization made it 62,000 times too bright.
        ("[[material]]\nname = \"c\"\ntype = \"gaussian\"\nm = 1e-4\n", "s.toml:4:5: material[0].m: m must lie in [1e-3, 1] radians, got 0.0001 (a narrower highlight is a mirror: use `conductor`, or `ggx` with a small roughness)"),
        ("[[material]]\nname = \"w\"\ntype = \"ward\"\nalpha_u = -0.1\n", "s.toml:4:11: material[0].alpha_u: alpha_u must lie in (0, 10], got -0.1"),
        ("[[material]]\nname = \"s\"\ntype = \"subsurface_brdf\"\nmedium = \"jelly\"\n", "s.toml:4:10: material[0].medium: unknown medium \"jelly\" (valid: apple, chicken1, chicken2, cream, ketchup, marble, potato, skimmilk, skin1, skin2, spectralon, wholemilk)"),
        ("[[material]]\nname = \"s\"\ntype = \"subsurface_brdf\"\nsigma_s = [1, 1, 1]\nsigma_a = [0.1, -0.1, 0.1]\n", "s.toml:5:11: material[0].sigma_a: sigma_a must be non-negative"),
        ("[[material]]\nname = \"s\"\ntype = \"subsurface_brdf\"\nmedium = \"marble\"\ng = 1.0\n", "s.toml:5:5: material[0].g: g must lie strictly between -1 and 1, got 1"),
        ("[[material]]\nname = \"s\"\ntype = \"subsurface_brdf\"\nmedium = \"marble\"\nior = 0\n", "s.toml:5:7: material[0].ior: ior must be positive, got 0"),
        ("[[material]]\nname = \"s\"\ntype = \"subsurface_brdf\"\nmedium = \"marble\"\nsigma_a = [1, 1, 1]\n", "s.toml:1:1: material[0]: give either `medium` or explicit coefficients, not both"),
        ("[[material]]\nname = \"s\"\ntype = \"subsurface\"\nmedium = \"marble\"\nmode = \"diffusion\"\n", "s.toml:5:8: material[0].mode: unknown value \"diffusion\" (valid: dipole, random_walk)"),
        ("[[material]]\nname = \"s\"\ntype = \"subsurface\"\nmedium = \"marble\"\nscale = 0\nmode = \"random_walk\"\n", "s.toml:5:9: material[0].scale: must be positive, got 0"),
        ("[[material]]\nname = \"s\"\ntype = \"subsurface\"\nmedium = \"marble\"\nsingle_scattering = 1\n", "s.toml:5:21: material[0].single_scattering: expected a boolean (true or false), found an integer"),
        ("[[material]]\nname = \"w\"\ntype = \"wave\"\nheightfield = \"nope.exr\"\n", "s.toml:4:15: material[0].heightfield: ./nope.exr: file not found"),
        ("[[material]]\nname = \"w\"\ntype = \"wave\"\nheightfield = \"../../examples/heightfields/grating.exr\"\nmodel = \"kirchhoff\"\n", "s.toml:5:9: material[0].model: unknown value \"kirchhoff\" (valid: ghs, ohs)"),
        ("[[material]]\nname = \"w\"\ntype = \"wave\"\nheightfield = \"../../examples/heightfields/grating.exr\"\nobliquity = \"cos\"\n", "s.toml:5:13: material[0].obliquity: unknown value \"cos\" (valid: reciprocal, seed)"),
        ("[[material]]\nname = \"w\"\ntype = \"wave\"\nheightfield = \"../../examples/heightfields/grating.exr\"\nmapping = \"spherical\"\naxis = \"x\"\n", "s.toml:1:1: material[0]: `axis` applies to mapping = \"planar\" only"),
        ("[[material]]\nname = \"w\"\ntype = \"wave\"\nheightfield = \"../../examples/heightfields/grating.exr\"\ncoherence_um = 0\n", "s.toml:5:16: material[0].coherence_um: must be positive, got 0"),
        // A window no render could sum (the fuzzer's 1e5 hung the CPU).
        ("[[material]]\nname = \"w\"\ntype = \"wave\"\nheightfield = \"../../examples/heightfields/grating.exr\"\ncoherence_um = 1e4\n", "s.toml:5:16: material[0].coherence_um: coherence_um = 10000 um puts about 5.8e10 Gabor kernels of this heightfield (0.25 um texels) in each query's window, beyond the 1e8 a render can sum; use at most 417 um"),
        ("[[material]]\nname = \"w\"\ntype = \"wave\"\nheightfield = \"../../examples/heightfields/grating.exr\"\ncoherence_um = 0.1\n", "s.toml:5:16: material[0].coherence_um: coherence_um = 0.1 um is less than two texels of this heightfield (0.25 um): too few Gabor kernels for the model, whose BRDF then loses its energy; use at least 0.5 um"),
        ("[[material]]\nname = \"w\"\ntype = \"wave\"\nheightfield = \"../../examples/heightfields/grating.exr\"\nmetal = \"Au\"\nior = 1.5\n", "s.toml:1:1: material[0]: conflicting Fresnel keys: give only one of `metal`, `ior`"),
        ("[scene]\n", "s.toml:1:2: scene: unknown key (valid keys here: camera, environment, film, integrator, light, material, object)"),
        ("[film\nwidth = 3\n", "s.toml:1:6: TOML syntax error"),
        ("[film]\nspp = 4\nspp = 5\n", "s.toml:3:1: TOML syntax error: duplicate key `spp`"),
        ("[film]\nspp = 4\n[film]\n", "s.toml:3:2: TOML syntax error: duplicate key `film`"),
    ];
    for (src, want) in cases {
        let got = parse(src)
            .err()
            .unwrap_or_else(|| panic!("accepted:\n{src}"));
        assert!(
            got.starts_with(want),
            "\nscene:\n{src}\nwant prefix: {want}\ngot:         {got}"
        );
        assert!(!got.contains('\n'), "one-line message: {got}");
    }
}

#[test]
fn load_reports_missing_file() {
    let e = isolux_scene::load(Path::new("/no/such/scene.toml")).unwrap_err();
    assert!(e
        .to_string()
        .starts_with("/no/such/scene.toml: cannot read scene file"));
}
