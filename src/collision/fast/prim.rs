//! The fast checker's primitives (spheres, oriented boxes, cylinders, capsules) and their
//! exact or conservative intersection tests; see the parent module.

use nalgebra::{Matrix3, Vector3};

use crate::geometry::{Pose, Shape};

/// Tolerance added to every primitive so rounding can never turn a touching pair free.
pub(super) const EPS: f64 = 1e-9;

#[derive(Debug, Clone, Copy)]
pub(crate) enum Prim {
    Sphere {
        c: Vector3<f64>,
        r: f64,
    },
    Obb {
        c: Vector3<f64>,
        rot: Matrix3<f64>,
        half: Vector3<f64>,
    },
    /// Exact against spheres; `half` is the enclosing box used against boxes.
    Cylinder {
        c: Vector3<f64>,
        rot: Matrix3<f64>,
        r: f64,
        h: f64,
    },
    Capsule {
        c: Vector3<f64>,
        rot: Matrix3<f64>,
        r: f64,
        h: f64,
    },
}

impl Prim {
    /// The primitives of one shape (one, but a mesh gives its cover's boxes: the coarse one on
    /// a `moving` body), padded, appended to `out`; true when they are a mesh's cover (boxes
    /// of one rotation).
    pub(super) fn from_shape(
        origin: &Pose,
        shape: &Shape,
        pad: f64,
        moving: bool,
        out: &mut Vec<Prim>,
    ) -> bool {
        let c = origin.translation.vector;
        let rot = *origin.rotation.to_rotation_matrix().matrix();
        let p = match shape {
            Shape::Sphere { radius } => Prim::Sphere {
                c,
                r: radius + pad + EPS,
            },
            Shape::Box { half_extents } => Prim::Obb {
                c,
                rot,
                half: half_extents.add_scalar(pad + EPS),
            },
            Shape::Cylinder {
                radius,
                half_length,
            } => Prim::Cylinder {
                c,
                rot,
                r: radius + pad + EPS,
                h: half_length + pad + EPS,
            },
            Shape::Capsule {
                radius,
                half_length,
            } => Prim::Capsule {
                c,
                rot,
                r: radius + pad + EPS,
                h: *half_length,
            },
            Shape::Mesh(m) => {
                let cover = if moving {
                    m.moving_cover().0
                } else {
                    m.cover()
                };
                out.extend(cover.into_iter().map(|(mid, half)| Prim::Obb {
                    c: c + rot * mid,
                    rot,
                    half: half.add_scalar(pad + EPS),
                }));
                return true;
            }
        };
        out.push(p);
        false
    }

    /// The primitive moved by a body pose `(rot, t)`.
    #[inline]
    pub(super) fn transformed(&self, r: &Matrix3<f64>, t: &Vector3<f64>) -> Prim {
        match *self {
            Prim::Sphere { c, r: rad } => Prim::Sphere {
                c: r * c + t,
                r: rad,
            },
            Prim::Obb { c, rot, half } => Prim::Obb {
                c: r * c + t,
                rot: r * rot,
                half,
            },
            Prim::Cylinder { c, rot, r: rad, h } => Prim::Cylinder {
                c: r * c + t,
                rot: r * rot,
                r: rad,
                h,
            },
            Prim::Capsule { c, rot, r: rad, h } => Prim::Capsule {
                c: r * c + t,
                rot: r * rot,
                r: rad,
                h,
            },
        }
    }

    /// The primitive grown by `d` (radii and half extents): it contains every point within
    /// `d` of the original.
    #[inline]
    pub(super) fn inflated(&self, d: f64) -> Prim {
        match *self {
            Prim::Sphere { c, r } => Prim::Sphere { c, r: r + d },
            Prim::Obb { c, rot, half } => Prim::Obb {
                c,
                rot,
                half: half.add_scalar(d),
            },
            Prim::Cylinder { c, rot, r, h } => Prim::Cylinder {
                c,
                rot,
                r: r + d,
                h: h + d,
            },
            Prim::Capsule { c, rot, r, h } => Prim::Capsule {
                c,
                rot,
                r: r + d,
                h,
            },
        }
    }

    /// This primitive when `d` is 0, else it grown by `d` (made once, kept in `cache`).
    #[inline(always)]
    pub(super) fn grown<'a>(&'a self, d: f64, cache: &'a mut Option<Prim>) -> &'a Prim {
        if d > 0.0 {
            cache.get_or_insert_with(|| self.inflated(d))
        } else {
            self
        }
    }

    /// Centre of the primitive (of its bounding sphere).
    #[inline]
    pub(super) fn centre(&self) -> &Vector3<f64> {
        match self {
            Prim::Sphere { c, .. }
            | Prim::Obb { c, .. }
            | Prim::Cylinder { c, .. }
            | Prim::Capsule { c, .. } => c,
        }
    }

    pub(super) fn bounding(&self) -> (Vector3<f64>, f64) {
        match *self {
            Prim::Sphere { c, r } => (c, r),
            Prim::Obb { c, half, .. } => (c, half.norm()),
            Prim::Cylinder { c, r, h, .. } => (c, (r * r + h * h).sqrt()),
            Prim::Capsule { c, r, h, .. } => (c, r + h),
        }
    }

    /// Farthest point of the primitive in direction `d` (for GJK).
    #[inline]
    pub(crate) fn support(&self, d: &Vector3<f64>) -> Vector3<f64> {
        match *self {
            Prim::Sphere { c, r } => {
                let n = d.norm();
                if n > 0.0 {
                    c + d * (r / n)
                } else {
                    c
                }
            }
            Prim::Obb { c, rot, half } => {
                let l = rot.tr_mul(d);
                c + rot
                    * Vector3::new(
                        half.x.copysign(l.x),
                        half.y.copysign(l.y),
                        half.z.copysign(l.z),
                    )
            }
            Prim::Cylinder { c, rot, r, h } => {
                let l = rot.tr_mul(d);
                let rad = (l.x * l.x + l.y * l.y).sqrt();
                let (x, y) = if rad > 0.0 {
                    (l.x * r / rad, l.y * r / rad)
                } else {
                    (0.0, 0.0)
                };
                c + rot * Vector3::new(x, y, h.copysign(l.z))
            }
            Prim::Capsule { c, rot, r, h } => {
                let n = d.norm();
                let ax = rot.column(2).into_owned();
                let end = if ax.dot(d) >= 0.0 { ax * h } else { -ax * h };
                if n > 0.0 {
                    c + end + d * (r / n)
                } else {
                    c + end
                }
            }
        }
    }

    /// Enclosing box (for tests against boxes).
    #[inline]
    pub(super) fn as_obb(&self) -> (Vector3<f64>, Matrix3<f64>, Vector3<f64>) {
        match *self {
            Prim::Sphere { c, r } => (c, Matrix3::identity(), Vector3::repeat(r)),
            Prim::Obb { c, rot, half } => (c, rot, half),
            Prim::Cylinder { c, rot, r, h } => (c, rot, Vector3::new(r, r, h)),
            Prim::Capsule { c, rot, r, h } => (c, rot, Vector3::new(r, r, h + r)),
        }
    }
}

#[inline]
pub(super) fn sphere_hits(c: &Vector3<f64>, r: f64, other: &Prim) -> bool {
    match *other {
        Prim::Sphere { c: c2, r: r2 } => (c - c2).norm_squared() <= (r + r2) * (r + r2),
        Prim::Obb { c: c2, rot, half } => {
            let p = rot.tr_mul(&(c - c2));
            let d = Vector3::new(
                (p.x.abs() - half.x).max(0.0),
                (p.y.abs() - half.y).max(0.0),
                (p.z.abs() - half.z).max(0.0),
            );
            d.norm_squared() <= r * r
        }
        Prim::Cylinder {
            c: c2,
            rot,
            r: rc,
            h,
        } => {
            let p = rot.tr_mul(&(c - c2));
            let radial = (p.x * p.x + p.y * p.y).sqrt();
            let dr = (radial - rc).max(0.0);
            let dz = (p.z.abs() - h).max(0.0);
            dr * dr + dz * dz <= r * r
        }
        Prim::Capsule {
            c: c2,
            rot,
            r: rc,
            h,
        } => {
            let p = rot.tr_mul(&(c - c2));
            let z = p.z.clamp(-h, h);
            let d2 = p.x * p.x + p.y * p.y + (p.z - z) * (p.z - z);
            d2 <= (r + rc) * (r + rc)
        }
    }
}

/// Separating-axis test of two oriented boxes (Gottschalk et al.).
#[inline]
pub(super) fn obb_obb(
    ca: &Vector3<f64>,
    ra: &Matrix3<f64>,
    ha: &Vector3<f64>,
    cb: &Vector3<f64>,
    rb: &Matrix3<f64>,
    hb: &Vector3<f64>,
) -> bool {
    let r = ra.tr_mul(rb);
    let t = ra.tr_mul(&(cb - ca));
    let mut abs_r = Matrix3::zeros();
    for i in 0..3 {
        for j in 0..3 {
            abs_r[(i, j)] = r[(i, j)].abs() + 1e-12;
        }
    }
    for i in 0..3 {
        let rb_proj = hb.x * abs_r[(i, 0)] + hb.y * abs_r[(i, 1)] + hb.z * abs_r[(i, 2)];
        if t[i].abs() > ha[i] + rb_proj {
            return false;
        }
    }
    for j in 0..3 {
        let ra_proj = ha.x * abs_r[(0, j)] + ha.y * abs_r[(1, j)] + ha.z * abs_r[(2, j)];
        let tp = t.x * r[(0, j)] + t.y * r[(1, j)] + t.z * r[(2, j)];
        if tp.abs() > ra_proj + hb[j] {
            return false;
        }
    }
    for i in 0..3 {
        let i1 = (i + 1) % 3;
        let i2 = (i + 2) % 3;
        for j in 0..3 {
            let j1 = (j + 1) % 3;
            let j2 = (j + 2) % 3;
            let ra_p = ha[i1] * abs_r[(i2, j)] + ha[i2] * abs_r[(i1, j)];
            let rb_p = hb[j1] * abs_r[(i, j2)] + hb[j2] * abs_r[(i, j1)];
            let tp = t[i2] * r[(i1, j)] - t[i1] * r[(i2, j)];
            if tp.abs() > ra_p + rb_p {
                return false;
            }
        }
    }
    true
}

/// Whether any primitive of `pa` (grown by `d` ≥ 0) touches any of `pb`, with the primitives'
/// bounding radii `rad_a`, `rad_b`: bounding spheres first (most primitive pairs of two nearby
/// bodies are apart), then the exact test.
#[inline]
pub(super) fn prim_sets_hit(
    pa: &[Prim],
    rad_a: &[f64],
    pb: &[Prim],
    rad_b: &[f64],
    d: f64,
) -> bool {
    pa.iter().zip(rad_a).any(|(x, &xr)| {
        let mut grown = None;
        pb.iter().zip(rad_b).any(|(y, &yr)| {
            let r = xr + yr + d;
            (x.centre() - y.centre()).norm_squared() <= r * r
                && prims_hit(x.grown(d, &mut grown), y)
        })
    })
}

#[inline]
pub(super) fn prims_hit(a: &Prim, b: &Prim) -> bool {
    match (a, b) {
        (Prim::Sphere { c, r }, other) | (other, Prim::Sphere { c, r }) => {
            sphere_hits(c, *r, other)
        }
        _ => {
            let (ca, ra, ha) = a.as_obb();
            let (cb, rb, hb) = b.as_obb();
            if !obb_obb(&ca, &ra, &ha, &cb, &rb, &hb) {
                return false;
            }
            if matches!((a, b), (Prim::Obb { .. }, Prim::Obb { .. })) {
                return true;
            }
            super::super::gjk::intersect(|d| a.support(d), |d| b.support(d), cb - ca)
        }
    }
}

/// World-aligned box around a primitive.
pub(super) fn aabb(p: &Prim) -> (Vector3<f64>, Vector3<f64>) {
    match *p {
        Prim::Sphere { c, r } => (c.add_scalar(-r), c.add_scalar(r)),
        _ => {
            let (c, rot, half) = p.as_obb();
            let ext = rot.abs() * half;
            (c - ext, c + ext)
        }
    }
}

/// Squared distance from a point to a world-aligned box.
#[inline]
pub(super) fn dist2_point_aabb(c: &Vector3<f64>, lo: &Vector3<f64>, hi: &Vector3<f64>) -> f64 {
    let dx = (lo.x - c.x).max(0.0).max(c.x - hi.x);
    let dy = (lo.y - c.y).max(0.0).max(c.y - hi.y);
    let dz = (lo.z - c.z).max(0.0).max(c.z - hi.z);
    dx * dx + dy * dy + dz * dz
}

pub(super) fn bounding_of(prims: &[Prim]) -> (Vector3<f64>, f64) {
    if prims.is_empty() {
        return (Vector3::zeros(), 0.0);
    }
    // Centre: middle of the box around the primitive spheres; radius covers them all.
    let mut lo = Vector3::repeat(f64::INFINITY);
    let mut hi = Vector3::repeat(f64::NEG_INFINITY);
    for p in prims {
        let (c, r) = p.bounding();
        lo = lo.inf(&c.add_scalar(-r));
        hi = hi.sup(&c.add_scalar(r));
    }
    let c = (lo + hi) * 0.5;
    let r = prims
        .iter()
        .map(|p| {
            let (pc, pr) = p.bounding();
            (pc - c).norm() + pr
        })
        .fold(0.0, f64::max);
    (c, r * (1.0 + 1e-12) + EPS)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn obb(c: [f64; 3], yaw: f64, h: [f64; 3]) -> Prim {
        Prim::Obb {
            c: Vector3::from(c),
            rot: *nalgebra::Rotation3::from_euler_angles(0.0, 0.0, yaw).matrix(),
            half: Vector3::from(h),
        }
    }

    #[test]
    fn obb_separation_on_edge_axes() {
        // Two unit cubes, one turned 45° about z: corner-to-face distances decide.
        let a = obb([0.0, 0.0, 0.0], 0.0, [0.5, 0.5, 0.5]);
        let touching = obb(
            [0.5 + 0.70, 0.0, 0.0],
            std::f64::consts::FRAC_PI_4,
            [0.5, 0.5, 0.5],
        );
        let apart = obb(
            [0.5 + 0.72, 0.0, 0.0],
            std::f64::consts::FRAC_PI_4,
            [0.5, 0.5, 0.5],
        );
        assert!(prims_hit(&a, &touching));
        assert!(!prims_hit(&a, &apart));
    }

    #[test]
    fn sphere_against_cylinder_is_exact() {
        let cyl = Prim::Cylinder {
            c: Vector3::zeros(),
            rot: Matrix3::identity(),
            r: 0.1,
            h: 0.2,
        };
        // Beside the mantle.
        assert!(sphere_hits(&Vector3::new(0.149, 0.0, 0.0), 0.05, &cyl));
        assert!(!sphere_hits(&Vector3::new(0.151, 0.0, 0.0), 0.05, &cyl));
        // Diagonal from the rim: distance sqrt(0.03² + 0.04²) = 0.05.
        assert!(sphere_hits(&Vector3::new(0.13, 0.0, 0.239), 0.05, &cyl));
        assert!(!sphere_hits(&Vector3::new(0.13, 0.0, 0.241), 0.05, &cyl));
    }

    #[test]
    fn sphere_against_capsule_and_box() {
        let cap = Prim::Capsule {
            c: Vector3::zeros(),
            rot: Matrix3::identity(),
            r: 0.1,
            h: 0.2,
        };
        assert!(sphere_hits(&Vector3::new(0.0, 0.0, 0.349), 0.05, &cap));
        assert!(!sphere_hits(&Vector3::new(0.0, 0.0, 0.351), 0.05, &cap));
        let b = obb([0.0, 0.0, 0.0], 0.0, [0.1, 0.2, 0.3]);
        assert!(sphere_hits(&Vector3::new(0.0, 0.249, 0.0), 0.05, &b));
        assert!(!sphere_hits(&Vector3::new(0.0, 0.251, 0.0), 0.05, &b));
    }
}
