//! The set of objects of a scene, with a BVH over their boxes.

use crate::beam::Beam;
use crate::bvh::Bvh;
use crate::object::{Hit, Object};
use isolux_core::{Aabb, Ray};

/// All objects of a scene; bounded ones in a BVH, unbounded ones (an
/// infinite plane) tested one by one.
#[derive(Clone, Debug)]
pub struct Aggregate {
    objects: Vec<Object>,
    bvh: Bvh,
    bounded: Vec<u32>,
    unbounded: Vec<u32>,
    /// [`Aggregate::length`].
    length: f64,
}

impl Default for Aggregate {
    fn default() -> Self {
        Self::new(Vec::new())
    }
}

/// The objects and perturbations a beam of rays may meet, from
/// [`Aggregate::cull`].
#[derive(Clone, Debug, Default)]
pub struct Culled {
    /// `(object, first item, end item)` per object the beam may meet.
    objects: Vec<(u32, u32, u32)>,
    /// Perturbation lists of those objects, concatenated.
    items: Vec<u32>,
}

impl Culled {
    /// How many objects the beam may meet.
    pub fn object_count(&self) -> usize {
        self.objects.len()
    }

    /// How many perturbations (over all objects) the beam may meet.
    pub fn perturbation_count(&self) -> usize {
        self.items.len()
    }
}

impl Aggregate {
    /// Builds the aggregate.
    pub fn new(mut objects: Vec<Object>) -> Self {
        let mut boxes = Vec::new();
        let mut bounded = Vec::new();
        let mut unbounded = Vec::new();
        for (i, o) in objects.iter().enumerate() {
            if o.bbox().is_finite() {
                boxes.push(o.bbox());
                bounded.push(i as u32);
            } else {
                unbounded.push(i as u32);
            }
        }
        // Unbounded objects take the length of the bounded ones
        // (`Object::length`), so that a scene modelled in small units
        // offsets rays off its planes at its own scale.
        let all = boxes.iter().fold(Aabb::EMPTY, |all, b| all.union(b));
        let length = crate::object::length_of(&all);
        for &i in &unbounded {
            objects[i as usize].set_length(length);
        }
        Self {
            bvh: Bvh::build(&boxes),
            length,
            objects,
            bounded,
            unbounded,
        }
    }

    /// The length of the scene's bounded objects: the largest side of the
    /// box that holds them all, at most 1 (1 where none is bounded;
    /// [`crate::object::length_of`]). Each unbounded object takes it as its
    /// [`Object::length`]; the GPU scales its spawn offset by it.
    pub fn length(&self) -> f64 {
        self.length
    }

    /// The objects, in scene order.
    pub fn objects(&self) -> &[Object] {
        &self.objects
    }

    /// Closest hit with `t` in `[t_min, t_max]`: object index and hit.
    pub fn intersect(&self, ray: &Ray, t_min: f64, t_max: f64) -> Option<(usize, Hit)> {
        let mut best: Option<(usize, Hit)> = None;
        let mut t1 = t_max;
        // Hits stay in their object's frame until the nearest is known.
        for &i in &self.unbounded {
            if let Some(h) = self.objects[i as usize].intersect_local(ray, t_min, t1) {
                t1 = h.t;
                best = Some((i as usize, h));
            }
        }
        self.bvh.traverse(ray, t_min, &mut t1, |item, t1| {
            let i = self.bounded[item as usize] as usize;
            if let Some(h) = self.objects[i].intersect_local(ray, t_min, *t1) {
                *t1 = h.t;
                best = Some((i, h));
            }
            true
        });
        best.map(|(i, h)| (i, self.objects[i].world(h)))
    }

    /// Fills `out` with the objects, and their perturbations, that some
    /// ray of `beam` may meet (see [`crate::beam`]); `out` is cleared
    /// first, so one [`Culled`] serves tile after tile without allocating.
    pub fn cull(&self, beam: &Beam, out: &mut Culled) {
        out.objects.clear();
        out.items.clear();
        let mut add = |i: u32| {
            let o = &self.objects[i as usize];
            if o.meets(beam) {
                let first = out.items.len() as u32;
                o.cull(beam, &mut out.items);
                out.objects.push((i, first, out.items.len() as u32));
            }
        };
        for &i in &self.unbounded {
            add(i);
        }
        // The object BVH walked once for the whole beam: a scene of
        // thousands of objects costs a tile its depth, not its length.
        self.bvh.walk(
            |b| beam.meets_box(b),
            |item| add(self.bounded[item as usize]),
        );
        // Scene order, as a linear scan gives: ties in `t` between
        // objects resolve as before.
        out.objects.sort_unstable_by_key(|&(i, ..)| i);
    }

    /// [`Aggregate::intersect`] for a ray inside the beam that `culled`
    /// was filled for: the same closest hit, tested against the culled
    /// objects and perturbations only.
    pub fn intersect_culled(
        &self,
        ray: &Ray,
        t_min: f64,
        t_max: f64,
        culled: &Culled,
    ) -> Option<(usize, Hit)> {
        let mut best: Option<(usize, Hit)> = None;
        let mut t1 = t_max;
        for &(i, a, b) in &culled.objects {
            let items = &culled.items[a as usize..b as usize];
            if let Some(h) = self.objects[i as usize].intersect_culled_local(ray, t_min, t1, items)
            {
                t1 = h.t;
                best = Some((i as usize, h));
            }
        }
        best.map(|(i, h)| (i, self.objects[i].world(h)))
    }

    /// Whether anything crosses the ray within `[t_min, t_max]`.
    pub fn occluded(&self, ray: &Ray, t_min: f64, t_max: f64) -> bool {
        if self
            .unbounded
            .iter()
            .any(|&i| self.objects[i as usize].occludes(ray, t_min, t_max))
        {
            return true;
        }
        let mut found = false;
        let mut t1 = t_max;
        self.bvh.traverse(ray, t_min, &mut t1, |item, _| {
            let i = self.bounded[item as usize] as usize;
            found = self.objects[i].occludes(ray, t_min, t_max);
            !found
        });
        found
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Quadric;
    use isolux_core::DVec3;

    /// A bounded object's length is its box's largest side, at most 1; an
    /// unbounded one's, in an aggregate, the bounded objects' together (1
    /// where there are none), and the hits' offsets scale with it.
    #[test]
    fn objects_take_their_own_length_and_unbounded_ones_the_scenes() {
        let sphere = |c: DVec3, r: f64| Object::new(Quadric::sphere(c, r), vec![], None).unwrap();
        let plane = || {
            Object::new(
                Quadric::plane(DVec3::new(0.0, -1e-3, 0.0), DVec3::Y),
                vec![],
                None,
            )
            .unwrap()
        };
        let near = |a: f64, b: f64| (a / b - 1.0).abs() < 1e-6;
        assert!(near(sphere(DVec3::ZERO, 1e-3).length(), 2e-3));
        assert_eq!(sphere(DVec3::ZERO, 10.0).length(), 1.0);
        assert_eq!(plane().length(), 1.0);
        assert_eq!(Aggregate::new(vec![plane()]).length(), 1.0);
        assert_eq!(Aggregate::default().length(), 1.0);
        let small = Aggregate::new(vec![
            sphere(DVec3::ZERO, 1e-3),
            sphere(DVec3::new(3e-3, 0.0, 0.0), 1e-3),
            plane(),
        ]);
        assert!(near(small.length(), 5e-3), "{}", small.length());
        let lengths: Vec<f64> = small.objects().iter().map(Object::length).collect();
        assert!(near(lengths[0], 2e-3) && near(lengths[1], 2e-3));
        assert!(near(lengths[2], 5e-3), "{lengths:?}");
        // A ray down onto the plane: its offset is 1e-7 of the scene's
        // length plus the point's, not 1e-7 of a unit.
        let ray = Ray::new(DVec3::new(1e-2, 1e-3, 0.0), -DVec3::Y);
        let (i, hit) = small.intersect(&ray, 0.0, f64::INFINITY).unwrap();
        assert_eq!(i, 2);
        assert!(
            hit.offset > 0.0 && hit.offset < 1e-7 * 2e-2,
            "{}",
            hit.offset
        );
    }
}
