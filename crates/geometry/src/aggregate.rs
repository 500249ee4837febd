//! The set of objects of a scene, with a BVH over their boxes.

use crate::beam::Beam;
use crate::bvh::Bvh;
use crate::object::{Hit, Object};
use isolux_core::Ray;

/// All objects of a scene; bounded ones in a BVH, unbounded ones (an
/// infinite plane) tested one by one.
#[derive(Clone, Debug, Default)]
pub struct Aggregate {
    objects: Vec<Object>,
    bvh: Bvh,
    bounded: Vec<u32>,
    unbounded: Vec<u32>,
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
    pub fn new(objects: Vec<Object>) -> Self {
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
        Self {
            bvh: Bvh::build(&boxes),
            objects,
            bounded,
            unbounded,
        }
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
