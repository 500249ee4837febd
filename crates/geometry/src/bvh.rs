//! A bounding volume hierarchy over axis-aligned boxes.
//!
//! Used twice: per object over the supports of its perturbations (so a ray
//! only considers the bumps whose box it crosses) and per scene over the
//! objects. Built top-down by median split of centroids along the widest
//! axis; leaves hold at most [`LEAF_SIZE`] items.

use isolux_core::{Aabb, DVec3, Ray};

/// Items per leaf.
pub const LEAF_SIZE: usize = 2;

#[derive(Clone, Debug)]
struct Node {
    bounds: Aabb,
    /// Leaf: first item index. Interior: index of the second child (the
    /// first child follows the node directly).
    offset: u32,
    /// Leaf: number of items (> 0). Interior: 0.
    count: u32,
    axis: u8,
}

/// BVH over a list of boxes; queries report item indices into that list.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    nodes: Vec<Node>,
    items: Vec<u32>,
}

impl Bvh {
    /// Builds the hierarchy over `boxes` (all must be finite and non-empty).
    pub fn build(boxes: &[Aabb]) -> Self {
        let mut items: Vec<u32> = (0..boxes.len() as u32).collect();
        let mut nodes = Vec::with_capacity(2 * boxes.len());
        if !boxes.is_empty() {
            build_rec(boxes, &mut items, 0, boxes.len(), &mut nodes);
        }
        Self { nodes, items }
    }

    /// The nodes depth-first (a node's first child follows it), each as
    /// its box, the index of its second child (interior nodes) and its
    /// items (leaves: 1 to [`LEAF_SIZE`]; interior nodes: none). The
    /// layout the GPU's traversal reads.
    pub fn flatten(&self) -> Vec<(Aabb, u32, Vec<u32>)> {
        self.nodes
            .iter()
            .map(|n| {
                if n.count > 0 {
                    let first = n.offset as usize;
                    let items = self.items[first..first + n.count as usize].to_vec();
                    (n.bounds, 0, items)
                } else {
                    (n.bounds, n.offset, Vec::new())
                }
            })
            .collect()
    }

    /// Whether the hierarchy is empty.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Visits (at least) every item whose box the ray crosses within `[t0, *t1]`, near
    /// subtrees first. The visitor may lower `*t1` (closest-hit search) and
    /// returns `false` to stop the traversal.
    pub fn traverse(
        &self,
        ray: &Ray,
        t0: f64,
        t1: &mut f64,
        mut visit: impl FnMut(u32, &mut f64) -> bool,
    ) {
        if self.nodes.is_empty() {
            return;
        }
        let inv = DVec3::ONE / ray.dir;
        let neg = [inv.x < 0.0, inv.y < 0.0, inv.z < 0.0];
        let mut stack = [0u32; 64];
        let mut sp = 0usize;
        let mut node = 0usize;
        loop {
            let n = &self.nodes[node];
            if slab(&n.bounds, ray.origin, inv, t0, *t1) {
                if n.count > 0 {
                    let first = n.offset as usize;
                    for &it in &self.items[first..first + n.count as usize] {
                        if !visit(it, t1) {
                            return;
                        }
                    }
                } else {
                    let second = n.offset as usize;
                    if neg[n.axis as usize] {
                        stack[sp] = (node + 1) as u32;
                        sp += 1;
                        node = second;
                    } else {
                        stack[sp] = second as u32;
                        sp += 1;
                        node += 1;
                    }
                    continue;
                }
            }
            if sp == 0 {
                return;
            }
            sp -= 1;
            node = stack[sp] as usize;
        }
    }
}

impl Bvh {
    /// Visits every item in a leaf whose subtree's box `meets` accepts,
    /// depth first in node order: a walk for a whole beam of rays
    /// ([`crate::Beam::meets_box`]) instead of one per ray. Items of a
    /// visited leaf are reported whatever their own box, so callers that
    /// want an exact set test each item again.
    pub fn walk(&self, mut meets: impl FnMut(&Aabb) -> bool, mut visit: impl FnMut(u32)) {
        if self.nodes.is_empty() {
            return;
        }
        let mut stack = [0u32; 64];
        let mut sp = 0usize;
        let mut node = 0usize;
        loop {
            let n = &self.nodes[node];
            if meets(&n.bounds) {
                if n.count > 0 {
                    let first = n.offset as usize;
                    for &it in &self.items[first..first + n.count as usize] {
                        visit(it);
                    }
                } else {
                    stack[sp] = n.offset;
                    sp += 1;
                    node += 1;
                    continue;
                }
            }
            if sp == 0 {
                return;
            }
            sp -= 1;
            node = stack[sp] as usize;
        }
    }
}

/// Slab test with a precomputed inverse direction. Plain comparisons: a
/// NaN (`0 * inf`, an axis-parallel ray exactly on a slab plane) fails the
/// comparison and leaves the bound untouched, which keeps the test
/// conservative.
#[inline(always)]
pub fn slab(b: &Aabb, o: DVec3, inv: DVec3, mut lo: f64, mut hi: f64) -> bool {
    for a in 0..3 {
        let ta = (b.min[a] - o[a]) * inv[a];
        let tb = (b.max[a] - o[a]) * inv[a];
        let (near, far) = if ta < tb { (ta, tb) } else { (tb, ta) };
        if near > lo {
            lo = near;
        }
        if far < hi {
            hi = far;
        }
    }
    lo <= hi
}

fn build_rec(boxes: &[Aabb], items: &mut [u32], lo: usize, hi: usize, nodes: &mut Vec<Node>) {
    let mut bounds = Aabb::EMPTY;
    let mut cb = Aabb::EMPTY;
    for &i in &items[lo..hi] {
        let b = &boxes[i as usize];
        bounds = bounds.union(b);
        let c = b.center();
        cb = cb.union(&Aabb::new(c, c));
    }
    let me = nodes.len();
    nodes.push(Node {
        bounds,
        offset: lo as u32,
        count: (hi - lo) as u32,
        axis: 0,
    });
    if hi - lo <= LEAF_SIZE {
        return;
    }
    let ext = cb.max - cb.min;
    let axis = if ext.x >= ext.y && ext.x >= ext.z {
        0
    } else if ext.y >= ext.z {
        1
    } else {
        2
    };
    let mid = (lo + hi) / 2;
    items[lo..hi].sort_unstable_by(|&a, &b| {
        let ca = boxes[a as usize].center()[axis];
        let cb = boxes[b as usize].center()[axis];
        ca.total_cmp(&cb)
    });
    build_rec(boxes, items, lo, mid, nodes);
    let second = nodes.len();
    build_rec(boxes, items, mid, hi, nodes);
    nodes[me].offset = second as u32;
    nodes[me].count = 0;
    nodes[me].axis = axis as u8;
}

#[cfg(test)]
mod tests {
    use super::*;
    use isolux_core::Pcg32;

    /// The beam walk reports every item whose box a ray of the beam
    /// crosses (brute force: rays sampled over the beam's cross-section,
    /// each clipped against every box), each item once, and skips whole
    /// subtrees (far fewer items than a linear scan).
    #[test]
    fn beam_walk_finds_every_box_a_ray_of_the_beam_crosses() {
        let mut rng = Pcg32::new(12, 0);
        let boxes: Vec<Aabb> = (0..300)
            .map(|_| {
                let c = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 10.0;
                let h = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 0.3;
                Aabb::new(c - h, c + h)
            })
            .collect();
        let bvh = Bvh::build(&boxes);
        let (mut visited, mut crossed) = (0, 0);
        for _ in 0..300 {
            let dir = isolux_core::sampling::uniform_sphere(rng.next_2d());
            let o = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 10.0;
            let (u, v) = dir.any_orthonormal_pair();
            let w = 0.5 * rng.next_f64();
            let origins = [o + w * u, o - w * u, o + w * v, o - w * v];
            let beam = crate::Beam::cylinder(dir, &origins).unwrap();
            let mut got = vec![];
            bvh.walk(|b| beam.meets_box(b), |i| got.push(i));
            visited += got.len();
            let mut dedup = got.clone();
            dedup.sort();
            dedup.dedup();
            assert_eq!(dedup.len(), got.len(), "an item reported twice");
            for _ in 0..200 {
                // A parallel ray (both ways) through the origins' hull.
                let (a, b) = (rng.next_f64(), rng.next_f64());
                let p = o + w * ((a - b) * u + (a + b - 1.0) * v);
                for d in [dir, -dir] {
                    let ray = Ray::new(p, d);
                    for (i, bx) in boxes.iter().enumerate() {
                        if bx.clip(&ray, 0.0, f64::INFINITY).is_some() {
                            crossed += 1;
                            assert!(got.contains(&(i as u32)), "box {i} crossed, not reported");
                        }
                    }
                }
            }
        }
        assert!(crossed > 1000, "{crossed}");
        // Subtrees are skipped: far fewer items visited than a scan.
        assert!(visited < 300 * boxes.len() / 4, "{visited}");
    }

    #[test]
    fn traversal_equals_brute_force() {
        let mut rng = Pcg32::new(11, 0);
        let boxes: Vec<Aabb> = (0..200)
            .map(|_| {
                let c = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 10.0;
                let h = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 0.5;
                Aabb::new(c - h, c + h)
            })
            .collect();
        let bvh = Bvh::build(&boxes);
        for _ in 0..500 {
            let o = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 10.0;
            let d = isolux_core::sampling::uniform_sphere(rng.next_2d());
            let ray = Ray::new(o, d);
            let mut got = vec![];
            let mut t1 = 4.0;
            bvh.traverse(&ray, 0.0, &mut t1, |i, _| {
                got.push(i);
                true
            });
            got.sort();
            // Leaves report all their items (conservative): every box the
            // ray crosses must be among them, each exactly once.
            let want: Vec<u32> = (0..boxes.len() as u32)
                .filter(|&i| boxes[i as usize].clip(&ray, 0.0, 4.0).is_some())
                .collect();
            assert!(want.iter().all(|w| got.contains(w)), "{want:?} {got:?}");
            let mut dedup = got.clone();
            dedup.dedup();
            assert_eq!(dedup, got);
        }
    }
}
