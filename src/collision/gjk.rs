//! Boolean GJK (Gilbert–Johnson–Keerthi) intersection test of two convex shapes given by their
//! support functions, in the "nearest simplex" form without distance computation.
//!
//! Used by the fast checker for pairs that have no closed-form test (cylinder or capsule against
//! a box, cylinder against cylinder). Conservative: a degenerate simplex or running out of
//! iterations reports an intersection.

use nalgebra::Vector3;

type V = Vector3<f64>;

const MAX_ITERATIONS: usize = 64;

/// True when the convex sets with support functions `sa` and `sb` intersect. `guess` is any
/// direction (e.g. from A's centre to B's centre).
#[inline]
pub(crate) fn intersect(sa: impl Fn(&V) -> V, sb: impl Fn(&V) -> V, guess: V) -> bool {
    let support = |d: &V| sa(d) - sb(&-d);
    let mut d = if guess.norm_squared() > 1e-24 {
        guess
    } else {
        V::x()
    };
    let mut pts = [V::zeros(); 4];
    pts[0] = support(&d);
    let mut n = 1;
    d = -pts[0];
    for _ in 0..MAX_ITERATIONS {
        if d.norm_squared() < 1e-30 {
            return true;
        }
        let a = support(&d);
        if a.dot(&d) < 0.0 {
            return false;
        }
        pts[n] = a;
        n += 1;
        if next_simplex(&mut pts, &mut n, &mut d) {
            return true;
        }
    }
    true
}

#[inline]
fn triple(a: &V, b: &V, c: &V) -> V {
    // (a × b) × c
    a.cross(b).cross(c)
}

/// Reduces the simplex to the feature nearest the origin and sets the next search direction.
/// Returns true when the simplex encloses the origin.
#[inline]
fn next_simplex(pts: &mut [V; 4], n: &mut usize, d: &mut V) -> bool {
    match *n {
        2 => {
            line(pts, n, d);
            false
        }
        3 => {
            triangle(pts, n, d);
            false
        }
        _ => tetrahedron(pts, n, d),
    }
}

#[inline]
fn line(pts: &mut [V; 4], n: &mut usize, d: &mut V) {
    let (b, a) = (pts[0], pts[1]);
    let ab = b - a;
    let ao = -a;
    if ab.dot(&ao) > 0.0 {
        *d = triple(&ab, &ao, &ab);
        if d.norm_squared() < 1e-30 {
            // Origin on the segment: any perpendicular direction keeps the search going.
            *d = ab.cross(&V::x());
            if d.norm_squared() < 1e-30 {
                *d = ab.cross(&V::y());
            }
        }
    } else {
        pts[0] = a;
        *n = 1;
        *d = ao;
    }
}

#[inline]
fn triangle(pts: &mut [V; 4], n: &mut usize, d: &mut V) {
    let (c, b, a) = (pts[0], pts[1], pts[2]);
    let ab = b - a;
    let ac = c - a;
    let ao = -a;
    let abc = ab.cross(&ac);
    if abc.cross(&ac).dot(&ao) > 0.0 {
        if ac.dot(&ao) > 0.0 {
            pts[0] = c;
            pts[1] = a;
            *n = 2;
            *d = triple(&ac, &ao, &ac);
        } else {
            pts[0] = b;
            pts[1] = a;
            *n = 2;
            line(pts, n, d);
        }
    } else if ab.cross(&abc).dot(&ao) > 0.0 {
        pts[0] = b;
        pts[1] = a;
        *n = 2;
        line(pts, n, d);
    } else if abc.dot(&ao) > 0.0 {
        *d = abc;
    } else {
        pts[0] = b;
        pts[1] = c;
        *d = -abc;
    }
}

#[inline]
fn tetrahedron(pts: &mut [V; 4], n: &mut usize, d: &mut V) -> bool {
    let (dd, c, b, a) = (pts[0], pts[1], pts[2], pts[3]);
    let ab = b - a;
    let ac = c - a;
    let ad = dd - a;
    let ao = -a;
    let abc = ab.cross(&ac);
    let acd = ac.cross(&ad);
    let adb = ad.cross(&ab);
    if abc.dot(&ao) > 0.0 {
        pts[0] = c;
        pts[1] = b;
        pts[2] = a;
    } else if acd.dot(&ao) > 0.0 {
        pts[0] = dd;
        pts[1] = c;
        pts[2] = a;
    } else if adb.dot(&ao) > 0.0 {
        pts[0] = b;
        pts[1] = dd;
        pts[2] = a;
    } else {
        return true;
    }
    *n = 3;
    triangle(pts, n, d);
    false
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Rotation3};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn box_support(c: V, r: Matrix3<f64>, h: V) -> impl Fn(&V) -> V {
        move |d: &V| {
            let l = r.tr_mul(d);
            c + r * V::new(h.x.copysign(l.x), h.y.copysign(l.y), h.z.copysign(l.z))
        }
    }

    /// Brute-force separating-axis test of two boxes (15 axes).
    fn sat(ca: V, ra: Matrix3<f64>, ha: V, cb: V, rb: Matrix3<f64>, hb: V) -> Option<f64> {
        let mut axes = Vec::new();
        for i in 0..3 {
            axes.push(ra.column(i).into_owned());
            axes.push(rb.column(i).into_owned());
            for j in 0..3 {
                let x = ra.column(i).cross(&rb.column(j));
                if x.norm() > 1e-9 {
                    axes.push(x.normalize());
                }
            }
        }
        let mut best = f64::INFINITY;
        for ax in axes {
            let pa = (0..3)
                .map(|i| ha[i] * ra.column(i).dot(&ax).abs())
                .sum::<f64>();
            let pb = (0..3)
                .map(|i| hb[i] * rb.column(i).dot(&ax).abs())
                .sum::<f64>();
            let gap = (cb - ca).dot(&ax).abs() - pa - pb;
            best = best.min(-gap);
        }
        // Positive: overlap depth along the best axis; negative: separation.
        Some(best)
    }

    #[test]
    fn gjk_matches_separating_axes_for_random_boxes() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let mut agree = 0;
        for _ in 0..20_000 {
            let rnd_box = |rng: &mut ChaCha8Rng| {
                let c = V::new(
                    rng.random_range(-0.5..0.5),
                    rng.random_range(-0.5..0.5),
                    rng.random_range(-0.5..0.5),
                );
                let r = *Rotation3::from_euler_angles(
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-3.0..3.0),
                )
                .matrix();
                let h = V::new(
                    rng.random_range(0.01..0.4),
                    rng.random_range(0.01..0.4),
                    rng.random_range(0.01..0.4),
                );
                (c, r, h)
            };
            let (ca, ra, ha) = rnd_box(&mut rng);
            let (cb, rb, hb) = rnd_box(&mut rng);
            let depth = sat(ca, ra, ha, cb, rb, hb).unwrap_or(0.0);
            if depth.abs() < 1e-9 {
                continue;
            }
            let g = intersect(box_support(ca, ra, ha), box_support(cb, rb, hb), cb - ca);
            assert_eq!(g, depth > 0.0, "depth {depth}");
            agree += 1;
        }
        assert!(agree > 19_000);
    }
}
