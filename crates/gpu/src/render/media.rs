//! The random-walk media of a scene as the GPU's kernels follow them:
//! the packed media of a path (`path.medium`: slots of [`medium_bits`],
//! [`medium_of`]), the media's materials listed first so that they nest
//! deepest ([`media_first`]), the scenes nested deeper than the slots hold
//! ([`nested_too_deep`]), and the routes of point lights into media
//! through their boundaries: flat ones by the light's record
//! ([`refracted_media`]), the others by each medium's list of objects
//! ([`manifold_media`]). Used by [`Gpu::prepare`](crate::Gpu::prepare)
//! (render.rs) before anything is uploaded.

use crate::layout::GpuMaterials;
use crate::GpuError;
use isolux_render::Scene;

/// The random-walk media that hold `at`, as the kernels' `path.medium`
/// packs them: `1 +` the material of the innermost in the lowest slot of
/// `bits` bits ([`medium_bits`]), of each one around it in the next (0:
/// none). `media` are in the order they nest
/// (`isolux_render::Scene::media_nested`, outermost first), so the
/// innermost is the last that holds `at`. For `GpuParams::camera`; each
/// light's `position.w` takes the lowest slot ([`innermost`]). Deeper
/// nesting than the slots hold is refused before ([`nested_too_deep`]).
pub(super) fn medium_of(
    media: &[(isolux_geometry::Object, u32)],
    at: glam::DVec3,
    bits: u32,
) -> u32 {
    media
        .iter()
        .filter(|(o, _)| o.contains(at))
        .fold(0, |packed, (_, m)| {
            packed.checked_shl(bits).unwrap_or(0) | *m
        })
}

/// The innermost medium of a packed [`medium_of`].
pub(super) fn innermost(packed: u32, bits: u32) -> u32 {
    packed & ((1 << bits) - 1)
}

/// The width in bits of each medium's slot in the kernels' packed media
/// (`path.medium`, `params.camera.w`; `medium_bits()` in direct.wgsl),
/// the narrowest that names every random-walk medium's `1 +` material
/// index below the slot's mask (all ones is kept out of the slots, so
/// that no packing equals `MEDIA_TOO_DEEP`), the media's materials
/// coming first on the GPU (`media_first`): 4, eight deep as on the CPU
/// (`isolux_render::integrator::MAX_NESTED_MEDIA`), where the scene's
/// random-walk media take at most 14 materials; 8, four deep, at most
/// 254; else 16, two deep, at most 65534, which [`nested_too_deep`]
/// checks.
pub fn medium_bits(scene: &Scene) -> u32 {
    slot_bits(media_materials(scene).len())
}

/// The width of [`medium_bits`]' slots for media of `count` materials.
fn slot_bits(count: usize) -> u32 {
    MEDIUM_SLOTS
        .iter()
        .find(|(.., most)| count <= *most)
        .map_or(16, |(bits, ..)| *bits)
}

/// The materials of `scene`'s random-walk media, ascending, each once.
fn media_materials(scene: &Scene) -> Vec<usize> {
    let mut ms: Vec<usize> = scene
        .media()
        .map(|(i, ..)| scene.object_material[i])
        .collect();
    ms.sort_unstable();
    ms.dedup();
    ms
}

/// `scene` with the materials of its random-walk media first (in their
/// order in the file, then the others in theirs; `material_names` and
/// `object_material` to match), or `None` where they come first already.
/// The kernels name a medium by `1 +` its material in slots of 4 bits
/// ([`medium_bits`]), so that media nest eight deep where their materials
/// are among the first 14: reordered, any scene whose media take at most
/// 14 materials nests them eight deep, however many materials come
/// before them in the file (until 2026-12-05 such a scene nested four
/// deep, or two, and `--gpu` asked for the media's materials to be listed
/// first). Messages name materials by name and objects by index, which
/// the order does not change.
pub(super) fn media_first(scene: &Scene) -> Option<Scene> {
    let media = media_materials(scene);
    if media.iter().enumerate().all(|(k, &m)| k == m) {
        return None;
    }
    let order: Vec<usize> = media
        .iter()
        .copied()
        .chain((0..scene.materials.len()).filter(|m| media.binary_search(m).is_err()))
        .collect();
    let mut place = vec![0; order.len()];
    for (new, &old) in order.iter().enumerate() {
        place[old] = new;
    }
    let mut out = scene.clone();
    out.materials = order.iter().map(|&m| scene.materials[m].clone()).collect();
    out.material_names = order
        .iter()
        .map(|&m| scene.material_names.get(m).cloned().unwrap_or_default())
        .collect();
    out.object_material = scene.object_material.iter().map(|&m| place[m]).collect();
    Some(out)
}

/// Each width of [`medium_bits`]' slots, in bits, how many media they
/// hold, and how many materials the scene's media may take for them
/// (`1 +` the last one's index below the slot's mask, `2^bits - 1`).
const MEDIUM_SLOTS: [(u32, &str, usize); 3] =
    [(4, "eight", 14), (8, "four", 254), (16, "two", 65534)];

/// Lists, for manifold next-event estimation of point lights through
/// curved boundaries (`manifold_refraction` in manifold.wgsl, as the CPU's
/// `RefractedLights::Manifold`), the objects of each random-walk medium
/// that is not flat, or is flat but in `listed`, those some light reaches
/// so ([`flat_routes`]): in `materials`' data, `[count, objects...]` (as
/// `f32`), whose offset `+ 1` goes to the medium's record's `c.w` (0:
/// none; the GPU follows media by material, and finds the object the
/// path is in among those that share it). Whether any was listed (and
/// the scene has a point light): the kernels then carry the code. An
/// offset past `2^24`, which `f32` cannot hold exactly, is refused.
pub(super) fn manifold_media(
    scene: &Scene,
    listed: &[usize],
    materials: &mut GpuMaterials,
) -> Result<bool, GpuError> {
    if scene.integrator.refracted_lights != isolux_render::RefractedLights::Manifold
        || scene.lights.is_empty()
    {
        return Ok(false);
    }
    // Flat media go by their lights' records, but for those the records
    // cannot name.
    let flat: Vec<usize> = scene
        .flat_media()
        .iter()
        .map(|(i, _)| *i)
        .filter(|i| !listed.contains(i))
        .collect();
    let mut listed = false;
    for mi in 0..scene.materials.len() {
        let objs: Vec<usize> = scene
            .media()
            .filter(|(i, ..)| scene.object_material[*i] == mi && !flat.contains(i))
            .map(|(i, ..)| i)
            .collect();
        if objs.is_empty() {
            continue;
        }
        let at = materials.data.len();
        if at + 1 >= 1 << 24 {
            return Err(GpuError::Setup(format!(
                "material \"{}\": its list of objects for point lights refracted through \
                 its boundary lies past the first 2^24 words of material data, which the \
                 GPU's record cannot address; set integrator.refracted_lights = \"flat\", \
                 or render without --gpu",
                scene.material_names.get(mi).map_or("?", |n| n.as_str())
            )));
        }
        materials.data.push(objs.len() as f32);
        materials.data.extend(objs.iter().map(|&i| i as f32));
        materials.materials[mi].c[3] = (at + 1) as f32;
        listed = true;
    }
    Ok(listed)
}

/// Whether a flat boundary has `bounds` (a finite face of its box), so
/// that the kernels test the crossing point against its object's box
/// (`GpuLight::flat`).
pub(super) fn bounded(b: &isolux_render::FlatBoundary) -> bool {
    let [min, max] = [b.bbox.min, b.bbox.max].map(|v| v.to_array());
    min.into_iter().chain(max).any(f64::is_finite)
}

/// Per point light of `scene`, the random-walk medium bounded by a
/// plane (with or without `bounds`) that the light lies above (its
/// object and plane, `Scene::flat_boundary`), whose inside it reaches by
/// refraction through the plane (`refraction` in subsurface.wgsl, as on the
/// CPU), where the light's record can name it: `None` for a light above
/// no such medium, and, with `integrator.refracted_lights = "manifold"`,
/// for a light whose flat media the GPU cannot tell by the record (the
/// medium's material also on another object: its media are materials,
/// not objects; a light above two flat media), which reaches them
/// through the medium's list of objects instead (`flat_routes`,
/// `manifold_media`: the kernels find the object holding the path among
/// them and run the same closed form on its plane). With `"flat"` those
/// are refused: `Err` with why.
pub fn refracted_media(
    scene: &Scene,
) -> Result<Vec<Option<(usize, isolux_render::FlatBoundary)>>, String> {
    flat_routes(scene).map(|(lights, _)| lights)
}

/// [`refracted_media`], and the flat media that some light reaches
/// through their material's list of objects (listed with the curved
/// media by [`manifold_media`]).
#[allow(clippy::type_complexity)]
pub(super) fn flat_routes(
    scene: &Scene,
) -> Result<
    (
        Vec<Option<(usize, isolux_render::FlatBoundary)>>,
        Vec<usize>,
    ),
    String,
> {
    let flat = scene.flat_media();
    let manifold = scene.integrator.refracted_lights == isolux_render::RefractedLights::Manifold;
    let fix = "set integrator.refracted_lights = \"manifold\" (the default), or render \
               without --gpu";
    let (mut out, mut by_manifold) = (Vec::new(), Vec::new());
    for (k, l) in scene.lights.iter().enumerate() {
        let above: Vec<_> = flat
            .iter()
            .filter(|(_, b)| b.normal.dot(l.position) > b.offset)
            .collect();
        match above[..] {
            [] => out.push(None),
            [&(i, b)] => {
                let mi = scene.object_material[i];
                let Some(j) = (0..scene.object_material.len())
                    .find(|&j| j != i && scene.object_material[j] == mi)
                else {
                    out.push(Some((i, b)));
                    continue;
                };
                if !manifold {
                    return Err(format!(
                        "light[{k}] reaches the medium of object[{i}] through its flat surface, \
                         and object[{j}] has the same material: the GPU follows media by \
                         material and cannot tell them apart; give object[{i}] a material of \
                         its own, {fix}"
                    ));
                }
                out.push(None);
                by_manifold.push(i);
            }
            [&(i, _), &(j, _), ..] => {
                if !manifold {
                    return Err(format!(
                        "light[{k}] lies above the flat surfaces of two random-walk media \
                         (object[{i}] and object[{j}]): the GPU refracts a point light into \
                         one by its record; {fix}"
                    ));
                }
                out.push(None);
                by_manifold.extend(above.iter().map(|(i, _)| *i));
            }
        }
    }
    by_manifold.sort_unstable();
    by_manifold.dedup();
    Ok((out, by_manifold))
}

/// Random-walk media of `scene` whose bounding boxes all overlap, one
/// more than the kernels' packed media hold ([`medium_bits`]: eight deep
/// as on the CPU, a fish in a jelly in a drop under water and more, where
/// the media take at most 14 materials; four where at most 254; two
/// beyond), so that a path could be inside them all; or media of more
/// materials than the kernels' 16 bits name: why `--gpu` refuses the
/// scene. (Boxes that overlap pairwise share a point,
/// so growing a set while its boxes' common part is not empty finds every
/// such set.)
pub fn nested_too_deep(scene: &Scene) -> Option<String> {
    let media: Vec<_> = scene.media_nested();
    let count = media_materials(scene).len();
    if count + 1 >= 0xffff {
        return Some(format!(
            "{count} materials of random-walk media, more than the GPU's kernels can name \
             (65534): render without --gpu"
        ));
    }
    let bits = slot_bits(count);
    let depth = (32 / bits) as usize;
    let boxes: Vec<_> = media.iter().map(|(i, o, _)| (*i, o.bbox())).collect();
    let mut set = Vec::new();
    if !overlapping(&boxes, depth + 1, &mut set, None) {
        return None;
    }
    set.sort();
    let ids = set
        .iter()
        .map(|i| i.to_string())
        .collect::<Vec<_>>()
        .join(", ");
    // The deeper nestings narrower slots allow.
    let deeper: Vec<_> = MEDIUM_SLOTS
        .iter()
        .filter(|(b, ..)| *b < bits)
        .map(|(_, depth, most)| format!("{depth} where they take at most {most}"))
        .collect();
    let why = if deeper.is_empty() {
        String::new()
    } else {
        format!(
            " (the scene's random-walk media take {count} materials; {})",
            deeper.join(", ")
        )
    };
    Some(format!(
        "objects {ids}: {} random-walk media whose bounding boxes overlap, so that a path \
         could be inside them all; the GPU follows media nested {depth} deep{why}: render \
         without --gpu",
        depth + 1
    ))
}

/// Grows `set` (object indices) by boxes of `boxes` after those in it
/// until it holds `n` whose common part (`common`; `None`: everything) is
/// not empty; `false` where no such `n` exist.
fn overlapping(
    boxes: &[(usize, isolux_core::Aabb)],
    n: usize,
    set: &mut Vec<usize>,
    common: Option<isolux_core::Aabb>,
) -> bool {
    if set.len() == n {
        return true;
    }
    for (x, (i, b)) in boxes.iter().enumerate() {
        let part = common.map_or(*b, |c| c.intersection(b));
        if part.is_empty() {
            continue;
        }
        set.push(*i);
        if overlapping(&boxes[x + 1..], n, set, Some(part)) {
            return true;
        }
        set.pop();
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scene of `n` random-walk spheres nested around the origin, each
    /// of its own material, after `padding` unused diffuse materials.
    fn nested_spheres(n: usize, padding: usize) -> Scene {
        nested_spheres_at(n, padding, 0.0)
    }

    /// [`nested_spheres`] with the `k`-th sphere's centre at `x = k
    /// spacing`.
    fn nested_spheres_at(n: usize, padding: usize, spacing: f64) -> Scene {
        nested_spheres_beside(n, padding, spacing, 0)
    }

    /// [`nested_spheres_at`] and `beside` more random-walk media, each of
    /// its own material, small spheres side by side far from the others.
    fn nested_spheres_beside(n: usize, padding: usize, spacing: f64, beside: usize) -> Scene {
        let mut text =
            String::from("[camera]\nposition = [0.0, 0.0, 9.0]\nlook_at = [0.0, 0.0, 0.0]\n");
        for k in 0..padding {
            text += &format!("[[material]]\nname = \"pad{k}\"\ntype = \"diffuse\"\n");
        }
        // A random-walk medium of its own material: a sphere.
        let medium = |name: String, x: f64, y: f64, radius: f64| {
            format!(
                "[[material]]\nname = \"{name}\"\ntype = \"subsurface\"\nmode = \"random_walk\"\n\
                 sigma_s = [1.0, 1.0, 1.0]\nsigma_a = [0.0, 0.0, 0.0]\n\
                 [[object]]\nmaterial = \"{name}\"\n\
                 base = {{ type = \"sphere\", center = [{x}, {y}, 0.0], radius = {radius} }}\n"
            )
        };
        for k in 0..beside {
            text += &medium(format!("side{k}"), k as f64, 50.0, 0.1);
        }
        for k in 0..n {
            text += &medium(
                format!("m{k}"),
                k as f64 * spacing,
                0.0,
                4.0 - k as f64 * 0.4,
            );
        }
        isolux_scene::parse_str(
            &text,
            std::path::Path::new("nested.toml"),
            std::path::Path::new("."),
        )
        .unwrap()
    }

    #[test]
    fn media_nest_as_deep_as_their_slots_hold() {
        // The table's limits are the slots' masks less one (all ones is
        // kept out).
        for (bits, _, first) in MEDIUM_SLOTS {
            assert_eq!(first, (1 << bits) - 2);
        }
        // 4-bit slots: eight deep, as on the CPU.
        let eight = nested_spheres(8, 0);
        assert_eq!(medium_bits(&eight), 4);
        assert_eq!(
            isolux_render::integrator::MAX_NESTED_MEDIA,
            8,
            "the CPU's depth changed: see medium_bits"
        );
        assert_eq!(nested_too_deep(&eight), None);
        let packed = medium_of(
            &eight
                .media_nested()
                .iter()
                .map(|(i, o, _)| ((*o).clone(), eight.object_material[*i] as u32 + 1))
                .collect::<Vec<_>>(),
            glam::DVec3::ZERO,
            4,
        );
        assert_eq!(packed, 0x1234_5678);
        assert_eq!(innermost(packed, 4), 8);
        let nine = nested_spheres(9, 0);
        let why = nested_too_deep(&nine).expect("nine deep refused");
        assert!(
            why.starts_with("objects 0, 1, 2, 3, 4, 5, 6, 7, 8: 9 random-walk media")
                && why.contains("nested 8 deep: render"),
            "{why}"
        );
        assert!(!why.contains("  "), "{why}");
        // Media behind other materials: the GPU lists their materials
        // first (`media_first`), so 4-bit slots still name them (until
        // 2026-12-05, five deep behind 10 materials were refused).
        let five = nested_spheres(5, 10);
        assert_eq!(medium_bits(&five), 4);
        assert_eq!(nested_too_deep(&five), None);
        let first = media_first(&five).expect("reordered");
        assert_eq!(first.object_material, vec![0, 1, 2, 3, 4]);
        for (i, &m) in five.object_material.iter().enumerate() {
            let r = first.object_material[i];
            assert_eq!(five.material_names[m], first.material_names[r]);
            assert_eq!(
                format!("{:?}", five.materials[m]),
                format!("{:?}", first.materials[r])
            );
        }
        assert_eq!(first.materials.len(), 15);
        assert_eq!(first.material_names[5], "pad0");
        assert!(media_first(&first).is_none());
        assert!(media_first(&eight).is_none());
        // Media of 15 materials (a 16th `1 +` material is the 4-bit mask):
        // 8-bit slots, four deep.
        assert_eq!(medium_bits(&nested_spheres_beside(4, 3, 0.0, 10)), 4);
        let five = nested_spheres_beside(5, 3, 0.0, 10);
        assert_eq!(medium_bits(&five), 8);
        assert_eq!(nested_too_deep(&nested_spheres_beside(4, 3, 0.0, 11)), None);
        let why = nested_too_deep(&five).expect("five deep at 8 bits refused");
        assert!(
            why.contains(
                "nested 4 deep (the scene's random-walk media take 15 materials; eight where \
                 they take at most 14): render without --gpu"
            ),
            "{why}"
        );
        // Media of 255 materials: 16-bit slots, two deep.
        let late = nested_spheres_beside(3, 0, 0.0, 252);
        assert_eq!(medium_bits(&late), 16);
        assert_eq!(medium_bits(&nested_spheres_beside(3, 0, 0.0, 251)), 8);
        let why = nested_too_deep(&late).expect("three deep at 16 bits refused");
        assert!(
            why.contains(
                "nested 2 deep (the scene's random-walk media take 255 materials; eight where \
                 they take at most 14, four where they take at most 254)"
            ),
            "{why}"
        );
        assert_eq!(
            nested_too_deep(&nested_spheres_beside(2, 0, 0.0, 253)),
            None
        );
        // Nine media side by side, and eight nested beside a ninth: none
        // holds more than eight.
        assert_eq!(nested_too_deep(&nested_spheres_at(9, 0, 10.0)), None);
        let mut beside = nested_spheres(8, 0);
        let other = nested_spheres_at(2, 0, 10.0);
        beside.geometry = isolux_geometry::Aggregate::new(
            beside
                .geometry
                .objects()
                .iter()
                .chain(&other.geometry.objects()[1..])
                .cloned()
                .collect(),
        );
        beside.object_material.push(beside.object_material[0]);
        assert_eq!(nested_too_deep(&beside), None);
    }
}
