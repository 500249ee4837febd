//! A bounding volume hierarchy over axis-aligned boxes.
//!
//! Used twice: per object over the supports of its perturbations (so a ray
//! only considers the bumps whose box it crosses) and per scene over the
//! objects. Built top-down by the surface area heuristic over the boxes'
//! centres; leaves hold at most [`LEAF_SIZE`] items.

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
            build_rec(boxes, &mut items, 0, boxes.len(), &mut nodes, 0);
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

/// Relative cost of a node's box test against an item's test in the
/// surface area heuristic: about the same. An item's test is the dearer
/// in arithmetic (an object's record and box, or a perturbation's
/// quadratic along the ray, against one slab test), but each step of the
/// GPU's stackless walk is a loop iteration that a SIMT group runs for
/// all its threads, leaf or not (lavapipe runs a leaf's item test under
/// an empty lane mask; a warp whose threads stand at different nodes runs
/// both paths). A split costs two box tests (the GPU walk and the CPU's
/// both test each child's box) wherever its node's box is met, so a pair
/// of items stays one leaf: with 0.5, splitting the perturbed sphere's
/// sphere and floor cost lavapipe 14-17% more instructions (docs/gpu.md,
/// "The object hierarchy by the surface area heuristic").
const SAH_NODE_COST: f64 = 1.0;

/// Depth below which splits follow the surface area heuristic; deeper
/// ones (rare: the heuristic can cut one item off at a time where boxes
/// nest) split at the median, which halves, so a hierarchy stays within
/// `SAH_DEPTH + 32` levels for up to 2^32 items: the traversals' stacks
/// (64 entries) hold it.
const SAH_DEPTH: u32 = 30;

/// Surface area of a box (half of it: only ratios matter), finite for
/// unbounded and empty boxes (extents clamped to `[0, 1e100]`).
fn half_area(b: &Aabb) -> f64 {
    let e = (b.max - b.min).clamp(DVec3::ZERO, DVec3::splat(1e100));
    e.x * e.y + e.y * e.z + e.z * e.x
}

/// Builds the subtree over `items[lo..hi]`. Splits by the surface area
/// heuristic (MacDonald and Booth 1990; a ray meets a convex box with a
/// probability proportional to its surface area): over the three axes,
/// every split of the items sorted by their boxes' centres, the one of
/// least expected cost `2 SAH_NODE_COST + (n_l A_l + n_r A_r) / A` in item
/// tests, for a ray that meets the node's box `A`. A node of
/// at most [`LEAF_SIZE`] items stays a leaf unless splitting it costs
/// less than its `n` item tests. Ties go to the first axis and the first
/// split, so the hierarchy depends on the boxes alone. `depth`: the node's
/// (the root's 0).
fn build_rec(
    boxes: &[Aabb],
    items: &mut [u32],
    lo: usize,
    hi: usize,
    nodes: &mut Vec<Node>,
    depth: u32,
) {
    let bounds = items[lo..hi]
        .iter()
        .fold(Aabb::EMPTY, |b, &i| b.union(&boxes[i as usize]));
    let me = nodes.len();
    nodes.push(Node {
        bounds,
        offset: lo as u32,
        count: (hi - lo) as u32,
        axis: 0,
    });
    let n = hi - lo;
    if n == 1 {
        return;
    }
    let by_axis = |items: &mut [u32], axis: usize| {
        items[lo..hi].sort_by(|&a, &b| {
            let ca = boxes[a as usize].center()[axis];
            let cb = boxes[b as usize].center()[axis];
            ca.total_cmp(&cb).then(a.cmp(&b))
        });
    };
    let (axis, mid) = if depth < SAH_DEPTH {
        // (cost, axis, split): the first `split` items go left.
        let mut best = (f64::INFINITY, 0usize, lo + n / 2);
        let area = half_area(&bounds);
        let mut right = vec![0.0f64; n];
        for axis in 0..3 {
            by_axis(items, axis);
            let mut acc = Aabb::EMPTY;
            for k in (1..n).rev() {
                acc = acc.union(&boxes[items[lo + k] as usize]);
                right[k] = half_area(&acc);
            }
            let mut acc = Aabb::EMPTY;
            for k in 1..n {
                acc = acc.union(&boxes[items[lo + k - 1] as usize]);
                let cost = 2.0 * SAH_NODE_COST
                    + (k as f64 * half_area(&acc) + (n - k) as f64 * right[k]) / area.max(1e-300);
                if cost < best.0 {
                    best = (cost, axis, lo + k);
                }
            }
        }
        if n <= LEAF_SIZE && !(best.0 < n as f64) {
            return;
        }
        (best.1, best.2)
    } else {
        if n <= LEAF_SIZE {
            return;
        }
        // The median along the centres' widest axis.
        let cb = items[lo..hi].iter().fold(Aabb::EMPTY, |b, &i| {
            let c = boxes[i as usize].center();
            b.union(&Aabb::new(c, c))
        });
        let ext = cb.max - cb.min;
        let axis = if ext.x >= ext.y && ext.x >= ext.z {
            0
        } else if ext.y >= ext.z {
            1
        } else {
            2
        };
        (axis, (lo + hi) / 2)
    };
    by_axis(items, axis);
    build_rec(boxes, items, lo, mid, nodes, depth + 1);
    let second = nodes.len();
    build_rec(boxes, items, mid, hi, nodes, depth + 1);
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

    /// Items and node boxes a ray's traversal tests: (nodes, items).
    fn work(bvh: &Bvh, ray: &Ray) -> (usize, usize) {
        let (mut nodes, mut items) = (0, 0);
        bvh.walk(
            |b| {
                nodes += 1;
                b.clip(ray, 0.0, f64::INFINITY).is_some()
            },
            |_| items += 1,
        );
        (nodes, items)
    }

    /// A median split built in the test: the hierarchy before the surface
    /// area heuristic, as the reference the heuristic must beat.
    fn median(boxes: &[Aabb]) -> Bvh {
        fn rec(boxes: &[Aabb], items: &mut [u32], lo: usize, hi: usize, nodes: &mut Vec<Node>) {
            let bounds = items[lo..hi]
                .iter()
                .fold(Aabb::EMPTY, |b, &i| b.union(&boxes[i as usize]));
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
            let e = bounds.max - bounds.min;
            let axis = if e.x >= e.y && e.x >= e.z {
                0
            } else if e.y >= e.z {
                1
            } else {
                2
            };
            items[lo..hi].sort_by(|&a, &b| {
                boxes[a as usize].center()[axis].total_cmp(&boxes[b as usize].center()[axis])
            });
            let mid = (lo + hi) / 2;
            rec(boxes, items, lo, mid, nodes);
            let second = nodes.len();
            rec(boxes, items, mid, hi, nodes);
            nodes[me].offset = second as u32;
            nodes[me].count = 0;
        }
        let mut items: Vec<u32> = (0..boxes.len() as u32).collect();
        let mut nodes = Vec::new();
        rec(boxes, &mut items, 0, boxes.len(), &mut nodes);
        Bvh { nodes, items }
    }

    /// The gallery's layout: a large flat floor under a grid of small
    /// objects. The median split puts the floor in a half whose box then
    /// spans the scene, so rays down into the grid test it and its
    /// neighbours; the surface area heuristic sets the floor apart. Rays
    /// from above, as a camera's: the heuristic tests fewer items (at
    /// least a quarter fewer; measured 31%) for about as many node boxes, and every box a
    /// ray crosses is still reported (`traversal_equals_brute_force`).
    #[test]
    fn the_surface_area_heuristic_sets_a_floor_apart() {
        let mut boxes = vec![Aabb::new(
            DVec3::new(-30.0, -2.0, -30.0),
            DVec3::new(30.0, 0.0, 30.0),
        )];
        for i in 0..5 {
            for j in 0..3 {
                let c = DVec3::new(1.25 * i as f64 - 2.5, 0.0, 1.35 * j as f64 - 1.35);
                boxes.push(Aabb::new(c - DVec3::splat(0.5), c + DVec3::splat(0.5)));
            }
        }
        let (sah, med) = (Bvh::build(&boxes), median(&boxes));
        let mut rng = Pcg32::new(5, 0);
        let (mut s, mut m) = ((0, 0), (0, 0));
        for _ in 0..2000 {
            let target = DVec3::new(6.0 * rng.next_f64() - 3.0, -0.5, 4.0 * rng.next_f64() - 2.0);
            let ray = Ray::new(
                DVec3::new(0.0, 3.4, 7.2),
                (target - DVec3::new(0.0, 3.4, 7.2)).normalize(),
            );
            let (a, b) = (work(&sah, &ray), work(&med, &ray));
            s = (s.0 + a.0, s.1 + a.1);
            m = (m.0 + b.0, m.1 + b.1);
        }
        eprintln!("per 2000 rays, (node boxes, items): surface area {s:?}, median {m:?}");
        assert!(4 * s.1 < 3 * m.1, "items: {s:?} against {m:?}");
        assert!(s.0 + s.1 / 2 < m.0 + m.1 / 2, "{s:?} against {m:?}");
    }

    /// Nested boxes, where the heuristic would cut one item off per level:
    /// the hierarchy stays shallow enough for the traversals' 64-entry
    /// stacks (median splits below `SAH_DEPTH`), and traversal still
    /// reports every box.
    #[test]
    fn nested_boxes_keep_the_hierarchy_within_the_stacks() {
        let n = 4000;
        let boxes: Vec<Aabb> = (0..n)
            .map(|i| {
                let h = DVec3::new(1.0 + i as f64, 1.0 + 0.5 * i as f64, 1.0 + 0.25 * i as f64);
                Aabb::new(-h, h + DVec3::splat(0.01 * i as f64))
            })
            .collect();
        let bvh = Bvh::build(&boxes);
        fn depth(bvh: &Bvh, node: usize) -> usize {
            let n = &bvh.nodes[node];
            if n.count > 0 {
                1
            } else {
                1 + depth(bvh, node + 1).max(depth(bvh, n.offset as usize))
            }
        }
        let d = depth(&bvh, 0);
        assert!(d <= SAH_DEPTH as usize + 13 + 1, "depth {d}");
        let ray = Ray::new(DVec3::ZERO, DVec3::new(0.3, 0.5, 0.8).normalize());
        let mut got = 0;
        let mut t1 = f64::INFINITY;
        bvh.traverse(&ray, 0.0, &mut t1, |_, _| {
            got += 1;
            true
        });
        assert_eq!(got, n, "every box contains the origin");
    }
}
