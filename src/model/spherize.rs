//! A conservative sphere model of any robot (issue 28 item 3: "spherize armar or justin
//! automatically"; issue 27 item 1 names the same route): every collision primitive of every link
//! is replaced by spheres whose union **contains** it, so a sphere-model checker (the SIMD
//! [`crate::collision::SphereChecker`] with its certified segments) never says free where the
//! primitive model collides. The price is protrusion: how far the spheres reach beyond the
//! primitive's surface, bounded per shape and reported.
//!
//! Per primitive (in its own frame):
//! - sphere: itself;
//! - box (half extents h): a grid of n_x × n_y × n_z cells, one sphere per cell through its
//!   corners (radius = the cell's half diagonal). The counts start at 1 and grow along the axis of
//!   the longest cell half-side while the protrusion — the radius minus the smallest cell
//!   half-side, which is how far a sphere passes the nearest face — exceeds the tolerance, up to
//!   `max_per_shape` spheres;
//! - cylinder (radius r, half length l): slabs of thickness s along the axis, one sphere per slab
//!   through its two rim circles (radius √(r² + s²/4)); s = 2r (the slab count rounded up), where
//!   the radial and the axial protrusion are equal, (√2 − 1) r: a disk is never covered by one
//!   sphere more tightly, and several spheres per slab are not tried here;
//! - capsule (radius r, half length l): spheres of radius r + s/2 at spine points s apart
//!   (protrusion s/2), s from the tolerance, both end points included;
//! - mesh: the box around its vertices, as above (a superset of the mesh, so still conservative).
//!
//! Containment is what the tests check, by sampling points in every primitive.

use nalgebra::{Translation3, Vector3};

use super::Robot;
use crate::geometry::{Geometry, Shape};

/// How to spherize.
#[derive(Debug, Clone, Copy)]
pub struct SpherizeSettings {
    /// Largest protrusion wanted beyond a box's face or a capsule's surface, metres.
    pub tolerance: f64,
    /// Most spheres for one primitive (the tolerance gives way above it).
    pub max_per_shape: usize,
}

impl Default for SpherizeSettings {
    fn default() -> Self {
        SpherizeSettings {
            tolerance: 0.01,
            max_per_shape: 64,
        }
    }
}

/// What spherizing one link gave.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct LinkSpheres {
    pub link: String,
    pub primitives: usize,
    pub spheres: usize,
    /// Largest protrusion of a sphere beyond its primitive, metres.
    pub max_protrusion: f64,
}

fn box_spheres(h: Vector3<f64>, s: &SpherizeSettings) -> (Vec<(Vector3<f64>, f64)>, f64) {
    let mut n = [1usize; 3];
    let cell =
        |n: &[usize; 3]| Vector3::new(h.x / n[0] as f64, h.y / n[1] as f64, h.z / n[2] as f64);
    let protrusion = |c: &Vector3<f64>| c.norm() - c.min();
    loop {
        let c = cell(&n);
        if protrusion(&c) <= s.tolerance {
            break;
        }
        let axis = c.imax();
        let mut next = n;
        next[axis] += 1;
        if next.iter().product::<usize>() > s.max_per_shape {
            break;
        }
        n = next;
    }
    let c = cell(&n);
    let r = c.norm();
    let mut out = Vec::with_capacity(n.iter().product());
    for i in 0..n[0] {
        for j in 0..n[1] {
            for k in 0..n[2] {
                let centre = Vector3::new(
                    -h.x + c.x * (2 * i + 1) as f64,
                    -h.y + c.y * (2 * j + 1) as f64,
                    -h.z + c.z * (2 * k + 1) as f64,
                );
                out.push((centre, r));
            }
        }
    }
    (out, protrusion(&c))
}

/// How far a sphere (centre `c`, radius `rr`) reaches beyond the cylinder of radius `r` and half
/// length `l` along z: its radius minus the centre's signed depth inside the cylinder.
fn cylinder_protrusion(c: &Vector3<f64>, rr: f64, r: f64, l: f64) -> f64 {
    let rho = (c.x * c.x + c.y * c.y).sqrt();
    let (dr, dz) = (rho - r, c.z.abs() - l);
    let depth = if dr <= 0.0 && dz <= 0.0 {
        (-dr).min(-dz)
    } else {
        -(dr.max(0.0).powi(2) + dz.max(0.0).powi(2)).sqrt()
    };
    rr - depth
}

/// A cylinder: slabs with one sphere each, or — when that protrudes more than the tolerance
/// and a grid does better (flat, wide cylinders) — the box grid of its bounding box without the
/// cells that miss the disk (every kept sphere still contains its cell, so the union contains
/// the cylinder). The protrusion is computed sphere by sphere.
fn cylinder_spheres(r: f64, l: f64, s: &SpherizeSettings) -> (Vec<(Vector3<f64>, f64)>, f64) {
    let worst = |list: &[(Vector3<f64>, f64)]| {
        list.iter()
            .map(|(c, rr)| cylinder_protrusion(c, *rr, r, l))
            .fold(0.0, f64::max)
    };
    let n = ((l / r).ceil() as usize).clamp(1, s.max_per_shape);
    let half_slab = l / n as f64;
    let rr = (r * r + half_slab * half_slab).sqrt();
    let slabs: Vec<_> = (0..n)
        .map(|k| {
            (
                Vector3::new(0.0, 0.0, -l + half_slab * (2 * k + 1) as f64),
                rr,
            )
        })
        .collect();
    let p_slabs = worst(&slabs);
    if p_slabs <= s.tolerance {
        return (slabs, p_slabs);
    }
    let (cells, _) = box_spheres(Vector3::new(r, r, l), s);
    // Cell half sides: the same for every cell of the grid.
    let grid: Vec<_> = cells
        .into_iter()
        .filter(|(c, rr)| {
            // The cell's xy rectangle meets the disk (its half sides are below rr).
            let hx = rr.min(r);
            let nearest = Vector3::new((c.x.abs() - hx).max(0.0), (c.y.abs() - hx).max(0.0), 0.0);
            nearest.norm() <= r
        })
        .collect();
    let p_grid = worst(&grid);
    if p_grid < p_slabs {
        (grid, p_grid)
    } else {
        (slabs, p_slabs)
    }
}

/// Spheres (centre in the shape frame, radius) whose union contains `shape`, and their largest
/// protrusion beyond it.
pub fn shape_spheres(shape: &Shape, s: &SpherizeSettings) -> (Vec<(Vector3<f64>, f64)>, f64) {
    match shape {
        Shape::Sphere { radius } => (vec![(Vector3::zeros(), *radius)], 0.0),
        Shape::Box { half_extents } => box_spheres(*half_extents, s),
        Shape::Mesh(m) => {
            // The boxes of its moving-body cover (a solid's coarse one, or the box around its
            // vertices), each spherized; the protrusion adds the cover's own.
            let mut all = Vec::new();
            let mut protrusion: f64 = 0.0;
            let (cover, own) = m.moving_cover();
            for (mid, half) in cover {
                let (spheres, p) = box_spheres(half, s);
                all.extend(spheres.into_iter().map(|(c, r)| (c + mid, r)));
                protrusion = protrusion.max(p);
            }
            // A mesh that is not a solid: its box, measured against the box as before.
            let own = if own.is_finite() { own } else { 0.0 };
            (all, protrusion + own)
        }
        Shape::Cylinder {
            radius,
            half_length,
        } => cylinder_spheres(*radius, *half_length, s),
        Shape::Capsule {
            radius,
            half_length,
        } => {
            let gaps =
                ((half_length / s.tolerance).ceil() as usize).clamp(1, s.max_per_shape.max(2) - 1);
            let step = 2.0 * half_length / gaps as f64;
            let r = radius + 0.5 * step;
            let spheres = (0..=gaps)
                .map(|k| (Vector3::new(0.0, 0.0, -half_length + step * k as f64), r))
                .collect();
            (spheres, 0.5 * step)
        }
    }
}

/// `robot` with every collision primitive replaced by spheres containing it (module docs), the
/// name `NAME_spherized`, and per link what it became. Kinematics, limits, groups and the
/// disabled pairs are unchanged.
pub fn spherize(robot: &Robot, s: &SpherizeSettings) -> (Robot, Vec<LinkSpheres>) {
    let mut out = robot.clone();
    out.name = format!("{}_spherized", robot.name);
    let mut report = Vec::new();
    for link in &mut out.links {
        if link.collision.is_empty() {
            continue;
        }
        let mut spheres = Vec::new();
        let mut worst: f64 = 0.0;
        for g in &link.collision {
            let (list, protrusion) = shape_spheres(&g.shape, s);
            worst = worst.max(protrusion);
            for (c, r) in list {
                spheres.push(Geometry {
                    origin: g.origin * Translation3::from(c),
                    shape: Shape::Sphere { radius: r },
                });
            }
        }
        report.push(LinkSpheres {
            link: link.name.clone(),
            primitives: link.collision.len(),
            spheres: spheres.len(),
            max_protrusion: worst,
        });
        link.collision = spheres;
    }
    (out, report)
}
