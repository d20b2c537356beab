//! The conservative sphere model of any robot (`model::spherize`, issue 28 item 3): the spheres
//! of every primitive contain it (points sampled inside each primitive lie in a sphere), the
//! reported protrusion bounds how far they reach out, and the spherized shipped robots load and
//! are served by the SIMD sphere checker.

mod common;

use std::sync::Arc;

use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use manyhands::collision::{CollisionWorld, SphereChecker};
use manyhands::geometry::{Pose, Shape};
use manyhands::model::spherize::{shape_spheres, spherize, SpherizeSettings};
use manyhands::model::{to_srdf, to_urdf};
use manyhands::Robot;

/// Whether a point (in the shape frame) is inside the shape.
type Inside = fn(&Shape, &Vector3<f64>) -> bool;

/// A point drawn uniformly in the primitive's bounding box, kept when inside the primitive.
fn inside(shape: &Shape, rng: &mut ChaCha8Rng) -> Vector3<f64> {
    loop {
        let (h, ok): (Vector3<f64>, Inside) = match shape {
            Shape::Box { half_extents } => (*half_extents, |_, _| true),
            Shape::Cylinder {
                radius,
                half_length,
            } => (Vector3::new(*radius, *radius, *half_length), |s, p| {
                let Shape::Cylinder { radius, .. } = s else {
                    return false;
                };
                p.x * p.x + p.y * p.y <= radius * radius
            }),
            Shape::Capsule {
                radius,
                half_length,
            } => (
                Vector3::new(*radius, *radius, half_length + radius),
                |s, p| {
                    let Shape::Capsule {
                        radius,
                        half_length,
                    } = s
                    else {
                        return false;
                    };
                    let z = p.z.clamp(-half_length, *half_length);
                    (p - Vector3::new(0.0, 0.0, z)).norm() <= *radius
                },
            ),
            Shape::Sphere { radius } => (Vector3::repeat(*radius), |s, p| {
                let Shape::Sphere { radius } = s else {
                    return false;
                };
                p.norm() <= *radius
            }),
            Shape::Mesh(_) => unreachable!("no meshes drawn here"),
        };
        let p = Vector3::new(
            rng.random_range(-h.x..=h.x),
            rng.random_range(-h.y..=h.y),
            rng.random_range(-h.z..=h.z),
        );
        if ok(shape, &p) {
            return p;
        }
    }
}

#[test]
fn spheres_contain_every_primitive_and_protrusion_is_a_bound() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let settings = SpherizeSettings::default();
    for k in 0..400 {
        let a = rng.random_range(0.005..0.5);
        let b = rng.random_range(0.005..0.5);
        let c = rng.random_range(0.005..0.5);
        let shape = match k % 4 {
            0 => Shape::Box {
                half_extents: Vector3::new(a, b, c),
            },
            1 => Shape::Cylinder {
                radius: a,
                half_length: b,
            },
            2 => Shape::Capsule {
                radius: a,
                half_length: b,
            },
            _ => Shape::Sphere { radius: a },
        };
        let (spheres, protrusion) = shape_spheres(&shape, &settings);
        assert!(!spheres.is_empty() && spheres.len() <= settings.max_per_shape);
        for _ in 0..500 {
            let p = inside(&shape, &mut rng);
            assert!(
                spheres.iter().any(|(c, r)| (p - c).norm() <= r + 1e-12),
                "{shape:?}: point {p:?} inside it is in no sphere"
            );
        }
        // No sphere point is farther out than the reported protrusion: probe along random
        // directions from each centre, at its radius.
        for (c, r) in &spheres {
            for _ in 0..20 {
                let d = Vector3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                )
                .normalize();
                let q = c + d * *r;
                // Distance from the primitive: its bounding-box distance is a lower bound.
                let h = match &shape {
                    Shape::Box { half_extents } => *half_extents,
                    Shape::Cylinder {
                        radius,
                        half_length,
                    } => Vector3::new(*radius, *radius, *half_length),
                    Shape::Capsule {
                        radius,
                        half_length,
                    } => Vector3::new(*radius, *radius, half_length + radius),
                    Shape::Sphere { radius } => Vector3::repeat(*radius),
                    Shape::Mesh(_) => unreachable!(),
                };
                let out = Vector3::new(
                    (q.x.abs() - h.x).max(0.0),
                    (q.y.abs() - h.y).max(0.0),
                    (q.z.abs() - h.z).max(0.0),
                )
                .norm();
                assert!(
                    out <= protrusion + 1e-9,
                    "{shape:?}: a sphere reaches {out} out, protrusion says {protrusion}"
                );
            }
        }
        // Below the sphere cap the tolerance holds (at the cap, one more step would pass it).
        if matches!(shape, Shape::Box { .. } | Shape::Capsule { .. })
            && spheres.len() * 2 <= settings.max_per_shape
        {
            assert!(
                protrusion <= settings.tolerance + 1e-12,
                "{shape:?}: protrusion {protrusion} above the tolerance with {} spheres",
                spheres.len()
            );
        }
    }
}

#[test]
fn spherized_shipped_robots_load_and_use_the_sphere_checker() {
    for name in ["armar", "justin"] {
        let dir = common::root().join("robots");
        let r = Robot::from_files(
            &dir.join(format!("{name}.urdf")),
            Some(&dir.join(format!("{name}.srdf"))),
        )
        .expect("robot");
        let (s, report) = spherize(&r, &SpherizeSettings::default());
        assert_eq!(s.dof(), r.dof());
        assert!(report.iter().all(|l| l.spheres >= l.primitives));
        assert!(s
            .links
            .iter()
            .flat_map(|l| &l.collision)
            .all(|g| matches!(g.shape, Shape::Sphere { .. })));
        let back = Arc::new(
            Robot::from_strings(&to_urdf(&s), Some(&to_srdf(&s)), &dir).expect("reads back"),
        );
        assert_eq!(back.name, format!("{name}_spherized"));
        let world = CollisionWorld::single(back, Pose::identity());
        assert!(
            SphereChecker::new(&world, 0.0).is_some(),
            "{name}: the sphere checker refuses the spherized model"
        );
    }
}
