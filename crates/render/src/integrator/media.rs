//! The random-walk media of a render ([`Media`]) and of a path
//! ([`MediumStack`]).

use crate::scene::FlatBoundary;
use crate::{RefractedLights, Scene};
use isolux_core::DVec3;
use isolux_materials::subsurface_material::SubsurfaceMode;
use isolux_materials::{Material, Subsurface};
use std::sync::atomic::{AtomicU64, Ordering};

/// What the paths of a render share about the random-walk media: those
/// around the camera ([`crate::Scene::media_at`]), the innermost each
/// point light lies in (without null boundaries, scattering events
/// gather only those lights, `medium_light`: the others lie behind the
/// medium's boundary), the materials seen from inside each, and whether
/// null boundaries may occur.
#[derive(Debug, Default)]
pub struct Media<'a> {
    /// The object indices and media the camera is in, outermost first
    /// ([`Scene::media_at`]).
    pub camera: Vec<(usize, &'a Subsurface)>,
    /// Per point light, the object index of the medium it lies in.
    pub lights: Vec<Option<usize>>,
    /// Per random-walk medium (its material's index, once however many
    /// objects share it), the scene's materials seen from inside it
    /// ([`Material::relative_to`] its boundary's index), `None` where one
    /// does not change.
    pub relative: Vec<(usize, Vec<Option<Material>>)>,
    /// Whether the scene may hold a *null boundary*
    /// ([`Scene::may_have_null_boundaries`]): point lights' shadow rays
    /// pass through them (`light_transmittance`); without any, a shadow
    /// ray stops at the first surface, and scattering events try only the
    /// lights of their own medium.
    pub null_boundaries: bool,
    /// The random-walk media bounded by a plane, by object index, with
    /// their planes ([`Scene::flat_boundary`]): point lights outside them
    /// reach inside through the plane by refraction (`refraction`).
    pub flat: Vec<(usize, FlatBoundary)>,
    /// Whether scattering events may gather any point light directly
    /// (`medium_lights`: a light inside a medium, or any light where
    /// null boundaries may be), so that flights look for lights to
    /// sample at all (0.7% of the random walk's instructions per sample
    /// in a scene lit from outside its media, callgrind; docs/benchmarks.md).
    pub gathers: bool,
    /// Whether point lights may reach a medium's inside by refraction
    /// through its boundary (`refraction`): a flat medium, or with
    /// [`RefractedLights::Manifold`] any random-walk medium, and a light.
    pub refracts: bool,
    /// Whether point lights' shadow rays blocked by a glass object look
    /// for the path through it (`caustic`, [`Scene::casts_caustics`]).
    pub caustics: bool,
    /// Paths ended at [`MAX_MEDIUM_EVENTS`](super::MAX_MEDIUM_EVENTS) so
    /// far (of every thread's samples: the sum, the same whatever the
    /// thread count).
    pub capped: AtomicU64,
}

impl Clone for Media<'_> {
    /// A copy whose count of capped paths starts at this one's.
    fn clone(&self) -> Self {
        Media {
            camera: self.camera.clone(),
            lights: self.lights.clone(),
            relative: self.relative.clone(),
            null_boundaries: self.null_boundaries,
            flat: self.flat.clone(),
            gathers: self.gathers,
            refracts: self.refracts,
            caustics: self.caustics,
            capped: AtomicU64::new(self.capped.load(Ordering::Relaxed)),
        }
    }
}

impl<'a> Media<'a> {
    /// The media of `scene` for paths from `origin`.
    pub fn new(scene: &'a Scene, origin: DVec3) -> Self {
        let lit = !scene.lights.is_empty();
        let lights: Vec<_> = scene
            .lights
            .iter()
            .map(|l| scene.medium_at(l.position).map(|(i, _)| i))
            .collect();
        let null_boundaries = scene.may_have_null_boundaries();
        let flat = scene.flat_media();
        Media {
            camera: scene.media_at(origin),
            gathers: lit && (null_boundaries || lights.iter().any(Option::is_some)),
            refracts: lit
                && (!flat.is_empty()
                    || (scene.integrator.refracted_lights == RefractedLights::Manifold
                        && scene.media().next().is_some())),
            caustics: scene.casts_caustics(),
            lights,
            relative: scene
                .materials
                .iter()
                .enumerate()
                .filter_map(|(j, m)| match m {
                    Material::Subsurface(m) if m.mode == SubsurfaceMode::RandomWalk => {
                        let n = m.boundary.ior;
                        let seen = scene.materials.iter().map(|x| x.relative_to(n));
                        Some((j, seen.collect()))
                    }
                    _ => None,
                })
                .collect(),
            null_boundaries,
            flat,
            capped: AtomicU64::new(0),
        }
    }

    /// The material of object `obj` seen from inside the medium of
    /// object `inside` (`None`: outside every medium): a surface in a
    /// medium sees it on its outer side, so its indices of refraction
    /// count relative to the medium's ([`MediumStack::outside_of`]).
    pub fn material<'s>(
        &'s self,
        scene: &'s Scene,
        obj: usize,
        inside: Option<usize>,
    ) -> &'s Material {
        let mi = scene.object_material[obj];
        inside
            .map(|m| scene.object_material[m])
            .and_then(|m| self.relative.iter().find(|(j, _)| *j == m))
            .and_then(|(_, r)| r[mi].as_ref())
            .unwrap_or(&scene.materials[mi])
    }
}

/// The deepest nesting of random-walk media a path follows (a path
/// entering a ninth ends there).
pub const MAX_NESTED_MEDIA: usize = 8;

/// The random-walk media a path is in, outermost first, by object index:
/// media nest (a marble under water). Entering a medium's object pushes
/// it; crossing the boundary of one the path is in takes it out.
#[derive(Clone, Copy, Debug, Default)]
pub struct MediumStack {
    ids: [usize; MAX_NESTED_MEDIA],
    len: usize,
}

impl MediumStack {
    /// The innermost medium (the one the path travels in).
    pub fn top(&self) -> Option<usize> {
        self.len.checked_sub(1).map(|k| self.ids[k])
    }

    /// Whether the path is inside no medium.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Whether the path is inside object `obj`'s medium.
    pub fn contains(&self, obj: usize) -> bool {
        self.ids[..self.len].contains(&obj)
    }

    /// Enters `obj`'s medium; `false` when already [`MAX_NESTED_MEDIA`]
    /// deep.
    pub fn push(&mut self, obj: usize) -> bool {
        if self.len == MAX_NESTED_MEDIA {
            return false;
        }
        self.ids[self.len] = obj;
        self.len += 1;
        true
    }

    /// Leaves `obj`'s medium (the innermost, unless media overlap).
    pub fn remove(&mut self, obj: usize) {
        if let Some(k) = self.ids[..self.len].iter().rposition(|&i| i == obj) {
            self.ids.copy_within(k + 1..self.len, k);
            self.len -= 1;
        }
    }

    /// Crosses the boundary of object `obj`'s medium: out of it if the
    /// path is in it, else into it. `Some(true)` when it entered, `None`
    /// when it would enter a medium beyond [`MAX_NESTED_MEDIA`].
    pub fn cross(&mut self, obj: usize) -> Option<bool> {
        if self.contains(obj) {
            self.remove(obj);
            Some(false)
        } else {
            self.push(obj).then_some(true)
        }
    }

    /// The medium on the outer side of object `obj`'s surface for this
    /// path: the innermost one, or where `obj` is itself the innermost
    /// (the path leaving it), the one around it.
    pub fn outside_of(&self, obj: usize) -> Option<usize> {
        match self.top() {
            Some(t) if t == obj => self.len.checked_sub(2).map(|k| self.ids[k]),
            t => t,
        }
    }
}
