//! Reference objects shared by benchmarks, tests and examples.

use crate::{Beam, Object, Perturbation, Quadric};
use isolux_core::{Aabb, DVec3, Pcg32, Ray};

/// Form factor of the benchmark bumps: raises a bump about 0.05 high on a
/// sphere of radius 0.6 (`1.2 h = f (0.04 - h^2)^3`).
pub const BUMP_FACTOR: f64 = 1000.0;

/// Centres of `n` points spread evenly over a sphere of radius `r`
/// (Fibonacci lattice: deterministic, no clustering).
pub fn fibonacci_sphere(n: usize, r: f64) -> Vec<DVec3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let rho = (1.0 - z * z).sqrt();
            let phi = golden * i as f64;
            DVec3::new(rho * phi.cos(), rho * phi.sin(), z) * r
        })
        .collect()
}

/// The geometry benchmark object: a sphere of radius 0.6 at the origin
/// with `bumps` perturbations `f max(Q, 0)^3`, each `Q` a sphere of radius
/// 0.2 centred on the surface.
pub fn bumpy_sphere(bumps: usize) -> Object {
    let perts = fibonacci_sphere(bumps, 0.6)
        .into_iter()
        .map(|c| Perturbation {
            quadric: Quadric::sphere(c, 0.2),
            factor: BUMP_FACTOR,
        })
        .collect();
    Object::new(Quadric::sphere(DVec3::ZERO, 0.6), perts, None).expect("valid benchmark object")
}

/// Edge of the square tiles of rays that [`cast_rows`] culls together.
pub const TILE: u32 = 8;

/// Edge, in tiles, of the square blocks that [`cast_rows`] culls through
/// the support BVH before culling their tiles from the block's list
/// ([`Object::cull_within`]).
pub const BLOCK: u32 = 4;

/// Rows per parallel work item when an image is cast with [`cast_rows`] on
/// several threads: whole blocks, so that the threads cull as one does.
pub const BAND: u32 = BLOCK * TILE;

/// The orthographic primary ray through pixel `(x, y)` of a `size x size`
/// image over `[-1, 1]^2`, looking down `-z` from `z = 2` (the view of
/// fidget's 3D heightmap render).
#[inline]
pub fn primary_ray(size: u32, x: u32, y: u32) -> Ray {
    // A product with the pitch, whose division the callers' pixel loops
    // hoist once this is inlined (a division per ray cost as much as a
    // bump-free sphere's intersection). For power-of-two sizes the pitch
    // is a power of two and the product exact, as the quotient was.
    let pitch = 2.0 / size as f64;
    let px = (x as f64 + 0.5) * pitch - 1.0;
    let py = 1.0 - (y as f64 + 0.5) * pitch;
    Ray::new(DVec3::new(px, py, 2.0), -DVec3::Z)
}

/// Casts the primary ray ([`primary_ray`]) of every pixel in `rows` on the
/// calling thread and returns the hit count. With `coherent`, the rays go
/// in tiles of [`TILE`] x [`TILE`] pixels, each culled once through its
/// [`Beam`] and cast together ([`Object::intersect_tile`]); otherwise each
/// ray walks the object's BVH ([`Object::intersect`]). Both find the same hits.
pub fn cast_rows(obj: &Object, size: u32, rows: std::ops::Range<u32>, coherent: bool) -> usize {
    let mut hits = 0;
    if !coherent {
        for y in rows {
            for x in 0..size {
                hits += obj
                    .intersect(&primary_ray(size, x, y), 0.0, f64::INFINITY)
                    .is_some() as usize;
            }
        }
        return hits;
    }
    let (mut coarse, mut culled) = (Vec::new(), Vec::new());
    let mut rays = Vec::with_capacity((TILE * TILE) as usize);
    let mut found = [None; crate::object::TILE_RAYS];
    let beam_of = |x0: u32, x1: u32, y0: u32, y1: u32| {
        let corners = [(x0, y0), (x1 - 1, y0), (x0, y1 - 1), (x1 - 1, y1 - 1)]
            .map(|(x, y)| primary_ray(size, x, y).origin);
        Beam::cylinder(-DVec3::Z, &corners).expect("a tile has rays")
    };
    // Blocks of BLOCK x BLOCK tiles are culled through the support BVH
    // first; their tiles then only test the block's list.
    let block = BLOCK * TILE;
    for by0 in rows.clone().step_by(block as usize) {
        let by1 = (by0 + block).min(rows.end);
        for bx0 in (0..size).step_by(block as usize) {
            let bx1 = (bx0 + block).min(size);
            let outer = beam_of(bx0, bx1, by0, by1);
            if !obj.meets(&outer) {
                continue;
            }
            coarse.clear();
            obj.cull(&outer, &mut coarse);
            for y0 in (by0..by1).step_by(TILE as usize) {
                let y1 = (y0 + TILE).min(by1);
                for x0 in (bx0..bx1).step_by(TILE as usize) {
                    let x1 = (x0 + TILE).min(bx1);
                    let beam = beam_of(x0, x1, y0, y1);
                    if !obj.meets(&beam) {
                        continue;
                    }
                    culled.clear();
                    obj.cull_within(&beam, &coarse, &mut culled);
                    rays.clear();
                    for y in y0..y1 {
                        for x in x0..x1 {
                            rays.push(primary_ray(size, x, y));
                        }
                    }
                    let found = &mut found[..rays.len()];
                    obj.intersect_tile(&rays, 0.0, f64::INFINITY, &culled, found);
                    hits += found.iter().filter(|h| h.is_some()).count();
                }
            }
        }
    }
    hits
}

/// A plane lying on a face of its own box: the normal `side` (+1 or -1)
/// along `axis`, at `offset` on that axis, the box 0.1 thick on the
/// normal's side of it and 3 across (a floor `y = 0` whose `bounds` start
/// at `y = 0`). Rays crossing that face meet the plane exactly where they
/// cross the box's face, which rounding decides independently
/// (`Object::intersect_in`'s `FACE_ULPS`).
pub struct FacePlane {
    /// The plane, bounded by its box.
    pub object: Object,
    /// The axis of its normal.
    pub axis: usize,
    /// Where the plane lies on that axis.
    pub offset: f64,
    /// The normal's direction along the axis.
    pub side: f64,
}

/// [`FacePlane`]s on every face of the box: each axis, each side, at
/// offsets 0, 0.3 (no f32 holds it) and -7.25.
pub fn planes_on_their_boxs_face() -> Vec<FacePlane> {
    let mut out = Vec::new();
    for axis in 0..3 {
        for side in [-1.0, 1.0] {
            for offset in [0.0, 0.3, -7.25] {
                let mut n = DVec3::ZERO;
                n[axis] = side;
                let mut point = DVec3::new(0.999, -0.37, 3e3);
                point[axis] = offset;
                let (mut min, mut max) = (DVec3::splat(-1.5), DVec3::splat(1.5));
                if side > 0.0 {
                    (min[axis], max[axis]) = (offset, offset + 0.1);
                } else {
                    (min[axis], max[axis]) = (offset - 0.1, offset);
                }
                let object =
                    Object::new(Quadric::plane(point, n), vec![], Some(Aabb::new(min, max)))
                        .expect("a bounded plane");
                out.push(FacePlane {
                    object,
                    axis,
                    offset,
                    side,
                });
            }
        }
    }
    out
}

impl FacePlane {
    /// `n` rays `(from, to)` to random points `to` of the plane's face:
    /// the even ones through the box first (leaving it by the face), the
    /// odd ones from outside (entering by it), at least 0.05 of the way
    /// along the axis, from 0.05, 2.6 and 40 units away in turn.
    pub fn rays(&self, n: usize, rng: &mut Pcg32) -> Vec<(DVec3, DVec3)> {
        (0..n)
            .map(|k| {
                let mut to = DVec3::new(
                    -1.4 + 2.8 * rng.next_f64(),
                    -1.4 + 2.8 * rng.next_f64(),
                    -1.4 + 2.8 * rng.next_f64(),
                );
                to[self.axis] = self.offset;
                let mut dir =
                    isolux_core::sampling::uniform_sphere([rng.next_f64(), rng.next_f64()]);
                let sign = if k % 2 == 0 { self.side } else { -self.side };
                dir[self.axis] = -sign * (0.05 + dir[self.axis].abs());
                let far = [0.05, 2.6, 40.0][k % 3];
                (to - far * dir.normalize(), to)
            })
            .collect()
    }
}
