//! Closed-form lower bounds of the distance between the fast model's primitives, used by the
//! certified motion check (`sweep.rs`) to record how far a pair is from contact at a checked
//! state in one pass instead of a halving search of boolean tests.
//!
//! Every bound is a true lower bound of the Euclidean distance between the two (solid)
//! primitives, ≤ 0 when they may touch:
//! - a sphere against anything: the exact distance of its centre to the other primitive
//!   (box, cylinder, capsule, sphere) minus its radius;
//! - boxes, and cylinders and capsules through the boxes around them ([`Prim::as_obb`], which
//!   contain them): the largest separation of the two boxes' projections on the 15 axes of the
//!   separating-axis test (Gottschalk, Lin & Manocha, SIGGRAPH 1996), each axis normalised.
//!   Two sets whose projections on a unit axis are `s` apart are at least `s` apart; a cross
//!   axis shorter than 1e-3 (nearly parallel edges) is left out, which only lowers the bound.
//!   The radii of the projections use `|R| + 1e-12` as the boolean test does (larger radii,
//!   smaller bound).
//!
//! A pair whose distance bound is at least `d` is free with its moving primitives grown by `d`
//! in the sense the certificate needs: every point within `d` of them lies outside the other
//! body. The fast model's primitives are already grown by 1e-9 m over the exact geometry, which
//! covers the rounding of these formulas. Checked against parry's exact distances
//! (random poses and near-contact placements) in this file's tests.

use nalgebra::{Matrix3, Vector3};

use super::Prim;

/// Shortest normalised cross axis of the separating-axis bound (shorter ones are skipped).
const MIN_CROSS: f64 = 1e-3;

/// A lower bound of the distance between the primitives `a` and `b` (≤ 0 when they may touch).
/// May stop early once the bound reaches `enough` (the answer is then at least `enough`, and
/// still a lower bound); `f64::INFINITY` computes it in full.
#[inline]
pub(super) fn prims_distance_lb(a: &Prim, b: &Prim, enough: f64) -> f64 {
    match (a, b) {
        (Prim::Sphere { c, r }, other) | (other, Prim::Sphere { c, r }) => {
            point_distance(c, other) - r
        }
        _ => {
            let (ca, ra, ha) = a.as_obb();
            let (cb, rb, hb) = b.as_obb();
            obb_separation(&ca, &ra, &ha, &cb, &rb, &hb, enough)
        }
    }
}

/// Distance from the point `p` to the solid primitive `prim` (0 inside).
#[inline]
fn point_distance(p: &Vector3<f64>, prim: &Prim) -> f64 {
    match *prim {
        Prim::Sphere { c, r } => ((p - c).norm() - r).max(0.0),
        Prim::Obb { c, rot, half } => {
            let l = rot.tr_mul(&(p - c));
            Vector3::new(
                (l.x.abs() - half.x).max(0.0),
                (l.y.abs() - half.y).max(0.0),
                (l.z.abs() - half.z).max(0.0),
            )
            .norm()
        }
        Prim::Cylinder { c, rot, r, h } => {
            let l = rot.tr_mul(&(p - c));
            let dr = ((l.x * l.x + l.y * l.y).sqrt() - r).max(0.0);
            let dz = (l.z.abs() - h).max(0.0);
            (dr * dr + dz * dz).sqrt()
        }
        Prim::Capsule { c, rot, r, h } => {
            let l = rot.tr_mul(&(p - c));
            let z = l.z.clamp(-h, h);
            let d2 = l.x * l.x + l.y * l.y + (l.z - z) * (l.z - z);
            (d2.sqrt() - r).max(0.0)
        }
    }
}

/// The largest normalised separation of two oriented boxes over the 15 separating axes: a
/// lower bound of their distance (≤ 0 when they overlap). Stops at the first axis whose
/// separation reaches `enough` (a maximum over fewer axes is still a lower bound).
#[inline]
fn obb_separation(
    ca: &Vector3<f64>,
    ra: &Matrix3<f64>,
    ha: &Vector3<f64>,
    cb: &Vector3<f64>,
    rb: &Matrix3<f64>,
    hb: &Vector3<f64>,
    enough: f64,
) -> f64 {
    let r = ra.tr_mul(rb);
    let t = ra.tr_mul(&(cb - ca));
    let abs_r = r.map(|x| x.abs() + 1e-12);
    let mut best = f64::NEG_INFINITY;
    for i in 0..3 {
        let rb_proj = hb.x * abs_r[(i, 0)] + hb.y * abs_r[(i, 1)] + hb.z * abs_r[(i, 2)];
        best = best.max(t[i].abs() - ha[i] - rb_proj);
    }
    if best >= enough {
        return best;
    }
    for j in 0..3 {
        let ra_proj = ha.x * abs_r[(0, j)] + ha.y * abs_r[(1, j)] + ha.z * abs_r[(2, j)];
        let tp = t.x * r[(0, j)] + t.y * r[(1, j)] + t.z * r[(2, j)];
        best = best.max(tp.abs() - ra_proj - hb[j]);
    }
    if best >= enough {
        return best;
    }
    for i in 0..3 {
        let i1 = (i + 1) % 3;
        let i2 = (i + 2) % 3;
        for j in 0..3 {
            // |a_i × b_j|² = 1 − (a_i · b_j)².
            let n2 = 1.0 - r[(i, j)] * r[(i, j)];
            if n2 < MIN_CROSS * MIN_CROSS {
                continue;
            }
            let j1 = (j + 1) % 3;
            let j2 = (j + 2) % 3;
            let ra_p = ha[i1] * abs_r[(i2, j)] + ha[i2] * abs_r[(i1, j)];
            let rb_p = hb[j1] * abs_r[(i, j2)] + hb[j2] * abs_r[(i, j1)];
            let tp = t[i2] * r[(i1, j)] - t[i1] * r[(i2, j)];
            best = best.max((tp.abs() - ra_p - rb_p) / n2.sqrt());
            if best >= enough {
                return best;
            }
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collision::exact::{parry_shape, to_parry};
    use crate::geometry::{Geometry, Pose, Shape};
    use nalgebra::{Translation3, UnitQuaternion};
    use parry3d_f64::query;
    use rand::{Rng, SeedableRng};

    fn random_shape(rng: &mut impl Rng) -> Shape {
        let kind = rng.random_range(0..4);
        let mut s = || rng.random_range(0.01..0.3);
        match kind {
            0 => Shape::Sphere { radius: s() },
            1 => Shape::Box {
                half_extents: Vector3::new(s(), s(), s()),
            },
            2 => Shape::Cylinder {
                radius: s(),
                half_length: s(),
            },
            _ => Shape::Capsule {
                radius: s(),
                half_length: s(),
            },
        }
    }

    fn random_rotation(rng: &mut impl Rng) -> UnitQuaternion<f64> {
        // Axis-aligned and nearly axis-aligned poses too: parallel edges are the hard case.
        match rng.random_range(0..3) {
            0 => UnitQuaternion::identity(),
            1 => UnitQuaternion::from_euler_angles(
                rng.random_range(-1e-4..1e-4),
                rng.random_range(-1e-4..1e-4),
                rng.random_range(-3.2..3.2),
            ),
            _ => UnitQuaternion::from_euler_angles(
                rng.random_range(-3.2..3.2),
                rng.random_range(-3.2..3.2),
                rng.random_range(-3.2..3.2),
            ),
        }
    }

    struct Case {
        ga: Geometry,
        gb: Geometry,
    }

    impl Case {
        fn prims(&self) -> (Prim, Prim) {
            (
                Prim::from_shape(&self.ga.origin, &self.ga.shape, 0.0),
                Prim::from_shape(&self.gb.origin, &self.gb.shape, 0.0),
            )
        }

        /// parry's distance of the exact shapes (0 when they intersect) and whether they do.
        fn exact(&self) -> (f64, bool) {
            let (sa, pa) = parry_shape(&self.ga);
            let (sb, pb) = parry_shape(&self.gb);
            let (pa, pb) = (to_parry(&pa), to_parry(&pb));
            let hit = query::intersection_test(&pa, sa.as_ref(), &pb, sb.as_ref())
                .unwrap()
                .intersecting;
            let d = query::distance(&pa, sa.as_ref(), &pb, sb.as_ref())
                .unwrap()
                .distance
                .max(0.0);
            (d, hit)
        }

        fn with_b_at(&self, t: Vector3<f64>) -> Case {
            let mut gb = self.gb.clone();
            gb.origin = Pose::from_parts(Translation3::from(t), gb.origin.rotation);
            Case {
                ga: self.ga.clone(),
                gb,
            }
        }
    }

    fn random_case(rng: &mut impl Rng) -> Case {
        let ga = Geometry {
            origin: Pose::from_parts(
                Translation3::new(
                    rng.random_range(-0.1..0.1),
                    rng.random_range(-0.1..0.1),
                    rng.random_range(-0.1..0.1),
                ),
                random_rotation(rng),
            ),
            shape: random_shape(rng),
        };
        let gb = Geometry {
            origin: Pose::from_parts(
                Translation3::new(
                    rng.random_range(-0.8..0.8),
                    rng.random_range(-0.8..0.8),
                    rng.random_range(-0.8..0.8),
                ),
                random_rotation(rng),
            ),
            shape: random_shape(rng),
        };
        Case { ga, gb }
    }

    /// A stopping level for the early-stopped bound: below, at and above the full bound.
    fn rng_enough(lb: f64) -> f64 {
        let k = (lb.to_bits() % 3) as f64;
        lb * (0.5 + 0.5 * k) - 1e-6
    }

    /// The bound never exceeds the exact distance, and is never positive for intersecting
    /// shapes: random poses, then each pair moved along its centre line to contact (bisection
    /// with parry) and placed just outside, at contact and just inside.
    #[test]
    fn distance_bound_is_below_the_exact_distance() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(27);
        let mut positive = 0;
        let mut near = 0;
        for _ in 0..6000 {
            let case = random_case(&mut rng);
            let check = |c: &Case, what: &str| -> f64 {
                let (pa, pb) = c.prims();
                let lb = prims_distance_lb(&pa, &pb, f64::INFINITY);
                let lb2 = prims_distance_lb(&pb, &pa, f64::INFINITY);
                // Stopped early: at least `enough` or the full bound, never above it.
                let enough = rng_enough(lb);
                let lb3 = prims_distance_lb(&pa, &pb, enough);
                assert!(lb3 <= lb && (lb3 >= enough || lb3 == lb));
                let (d, hit) = c.exact();
                for l in [lb, lb2] {
                    assert!(
                        !(hit && l > 0.0),
                        "{what}: bound {l} > 0 for intersecting {:?} / {:?}",
                        c.ga,
                        c.gb
                    );
                    assert!(
                        l <= d + 1e-9,
                        "{what}: bound {l} above exact distance {d} for {:?} / {:?}",
                        c.ga,
                        c.gb
                    );
                }
                lb
            };
            if check(&case, "random") > 0.0 {
                positive += 1;
            }
            // Bisect the placement of b along the line from a's centre to contact.
            let ca = case.ga.origin.translation.vector;
            let dir = case.gb.origin.translation.vector - ca;
            if dir.norm() < 1e-6 {
                continue;
            }
            let dir = dir.normalize();
            let (mut lo, mut hi) = (0.0, 2.0);
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if case.with_b_at(ca + dir * mid).exact().1 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            for off in [-1e-4, -1e-6, 0.0, 1e-7, 1e-6, 1e-5, 1e-4, 1e-3, 1e-2] {
                let c = case.with_b_at(ca + dir * (hi + off));
                let lb = check(&c, "near contact");
                if off >= 1e-3 && lb > 0.0 {
                    near += 1;
                }
            }
        }
        // Not vacuous: the bound proves most separated pairs apart, near contact too.
        assert!(
            positive > 2000,
            "only {positive} random pairs bounded apart"
        );
        assert!(near > 3000, "only {near} near-contact pairs bounded apart");
    }

    /// Separated along a face normal, two boxes' bound is their exact distance; a sphere's bound
    /// is exact against every primitive.
    #[test]
    fn bound_is_exact_where_closed_form() {
        let b = |c: [f64; 3], h: [f64; 3]| Prim::Obb {
            c: Vector3::from(c),
            rot: Matrix3::identity(),
            half: Vector3::from(h),
        };
        let a = b([0.0, 0.0, 0.0], [0.1, 0.2, 0.3]);
        let c = b([0.35, 0.05, 0.0], [0.2, 0.1, 0.1]);
        assert!((prims_distance_lb(&a, &c, f64::INFINITY) - 0.05).abs() < 1e-9);
        let s = Prim::Sphere {
            c: Vector3::new(0.0, 0.0, 0.5),
            r: 0.1,
        };
        let cyl = Prim::Cylinder {
            c: Vector3::zeros(),
            rot: Matrix3::identity(),
            r: 0.1,
            h: 0.2,
        };
        assert!((prims_distance_lb(&s, &cyl, f64::INFINITY) - 0.2).abs() < 1e-12);
        assert!((prims_distance_lb(&a, &s, f64::INFINITY) - 0.1).abs() < 1e-12);
    }
}
