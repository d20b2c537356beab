//! Non-convex meshes checked as what they are (issue 24 item 1, paper 003 §IV-A): the shipped
//! horse statuette `scenes/meshes/statuette.obj` (closed parts joined by overlap) is a solid;
//! the exact checker uses its true surface and inside, so a finger between its legs is free
//! where the convex hull would refuse it; the fast checker's box cover is conservative (never
//! free where the exact checker finds a collision) and not loose (free wherever the exact
//! clearance exceeds its stated over-approximation); certified motions past the legs are free
//! under a dense exact re-check.

mod common;

use std::path::Path;
use std::sync::Arc;

use manyhands::collision::{
    AttachedBody, CollisionChecker, CollisionWorld, ExactChecker, FastChecker, StaticBody,
    StaticKind,
};
use manyhands::geometry::{
    iso_from_rpy, Geometry, Mesh, Pose, Shape, COVER_CELLS, MAX_MOVING_COVER_BOXES,
};
use manyhands::Robot;
use nalgebra::{Point3, Vector3};
use parry3d_f64::math::Vector as PVector;
use parry3d_f64::query::PointQuery;
use parry3d_f64::shape::ConvexPolyhedron;

fn statuette() -> Arc<Mesh> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/meshes/statuette.obj");
    Arc::new(Mesh::load(&path, [1.0; 3]).expect("the shipped statuette loads"))
}

/// A free-floating probe (prismatic x, y, z) carrying one shape, among `statics`.
fn probe_world(geometry: &str, statics: Vec<StaticBody>) -> CollisionWorld {
    let urdf = common::probe_urdf(geometry, 2.0);
    let r = Arc::new(Robot::from_strings(&urdf, None, Path::new(".")).unwrap());
    let mut w = CollisionWorld::single(r, Pose::identity());
    w.statics = statics;
    w
}

fn statuette_body(mesh: &Arc<Mesh>) -> StaticBody {
    StaticBody {
        name: "statuette".into(),
        kind: StaticKind::Object,
        pose: iso_from_rpy([0.0; 3], [0.0; 3]),
        shapes: vec![Geometry {
            origin: Pose::identity(),
            shape: Shape::Mesh(mesh.clone()),
        }],
    }
}

/// Dense exact re-check of the probe's straight motion `a → b` (0.5 mm steps at most): asserts
/// every state free, answers the smallest clearance.
fn densely_free(exact: &mut ExactChecker, a: &[f64], b: &[f64]) -> f64 {
    let len = (0..3).map(|k| (b[k] - a[k]).powi(2)).sum::<f64>().sqrt();
    let n = (len / 0.0005).ceil().max(1.0) as usize;
    let mut min_d = f64::INFINITY;
    for s in 0..=n {
        let t = s as f64 / n as f64;
        let q: Vec<f64> = (0..3).map(|k| a[k] + (b[k] - a[k]) * t).collect();
        let d = exact.clearance(&q);
        assert!(
            d > 0.0,
            "certified motion {a:?} → {b:?} collides at t = {t}"
        );
        min_d = min_d.min(d);
    }
    min_d
}

/// Certifies `n` straight motions of the probe from `motion` (0.06 m coarse inflation) and
/// re-checks each certified one densely ([`densely_free`]): how many were certified, and how
/// many of those pass within 2 cm of the mesh.
fn certify_motions(
    fast: &mut FastChecker,
    exact: &mut ExactChecker,
    n: usize,
    mut motion: impl FnMut() -> (Vec<f64>, Vec<f64>),
) -> (usize, usize) {
    let (mut certified, mut near) = (0, 0);
    for _ in 0..n {
        let (a, b) = motion();
        if !fast.segment_certified(&a, &b, 0.06) {
            continue;
        }
        certified += 1;
        if densely_free(exact, &a, &b) < 0.02 {
            near += 1;
        }
    }
    (certified, near)
}

const FINGER: &str = r#"<geometry><sphere radius="0.01"/></geometry>"#;

/// Deterministic uniform numbers in [0, 1) (SplitMix64).
struct Mix(u64);
impl Mix {
    /// A uniformly random direction.
    fn dir(&mut self) -> Vector3<f64> {
        Vector3::new(self.next() - 0.5, self.next() - 0.5, self.next() - 0.5).normalize()
    }

    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
}

#[test]
fn statuette_is_a_closed_solid_of_joined_parts() {
    let m = statuette();
    let solid = m.solid.as_ref().expect("closed and consistently oriented");
    assert!(
        (300..=1400).contains(&m.triangles.len()),
        "{} triangles",
        m.triangles.len()
    );
    // Plinth, body, four legs, neck, head, two ears, tail.
    assert_eq!(solid.components, 11);
    let (lo, hi) = m.aabb();
    assert!((solid.cell - (hi - lo).max() / COVER_CELLS as f64).abs() < 1e-12);
    // Inside the body and a leg; outside between the legs and in front of the chest.
    assert!(solid.winding(&Vector3::new(0.0, 0.0, 0.19)) > 0.99);
    assert!(solid.contains(&Vector3::new(0.07, 0.031, 0.03)));
    assert!(solid.contains(&Vector3::new(0.05, 0.0, 0.2)));
    assert!(!solid.contains(&Vector3::new(0.0, 0.0, 0.08)));
    assert!(solid.winding(&Vector3::new(0.0, 0.0, 0.08)).abs() < 1e-9);
    assert!(!solid.contains(&Vector3::new(0.13, 0.0, 0.1)));
    // The cover holds every vertex and every point the winding number puts inside.
    let in_cover = |p: &Vector3<f64>| {
        solid
            .cover
            .iter()
            .any(|(c, h)| (p - c).abs().iter().zip(h.iter()).all(|(d, h)| *d <= *h))
    };
    assert!(m.vertices.iter().all(|v| in_cover(&v.coords)));
    // The coarse cover of moving bodies: few boxes, and it holds the solid too.
    assert!(!solid.moving_cover.is_empty() && solid.moving_cover.len() <= MAX_MOVING_COVER_BOXES);
    let in_moving_cover = |p: &Vector3<f64>| {
        solid
            .moving_cover
            .iter()
            .any(|(c, h)| (p - c).abs().iter().zip(h.iter()).all(|(d, h)| *d <= *h))
    };
    assert!(m.vertices.iter().all(|v| in_moving_cover(&v.coords)));
    let mut rng = Mix(7);
    let mut inside = 0;
    for _ in 0..20_000 {
        let p = Vector3::new(
            lo.x + (hi.x - lo.x) * rng.next(),
            lo.y + (hi.y - lo.y) * rng.next(),
            lo.z + (hi.z - lo.z) * rng.next(),
        );
        if solid.winding(&p) > 0.5 {
            inside += 1;
            assert!(in_cover(&p), "{p:?} inside the solid, outside its cover");
            assert!(
                in_moving_cover(&p),
                "{p:?} inside the solid, outside its moving cover"
            );
        }
    }
    assert!(inside > 500, "{inside} of 20000 samples inside");
    // The cover is far tighter than the box: less than half its volume.
    let cover_volume: f64 = solid.cover.iter().map(|(_, h)| 8.0 * h.x * h.y * h.z).sum();
    let box_volume = (hi - lo).x * (hi - lo).y * (hi - lo).z;
    assert!(
        cover_volume < 0.5 * box_volume,
        "{cover_volume} vs {box_volume}"
    );
    println!(
        "statuette: {} triangles, {} parts, cover {} boxes of {:.1} mm cells, {:.0} % of its box, \
         moving cover {} boxes (protrusion {:.1} mm)",
        m.triangles.len(),
        solid.components,
        solid.cover.len(),
        solid.cell * 1e3,
        100.0 * cover_volume / box_volume,
        solid.moving_cover.len(),
        solid.moving_protrusion * 1e3
    );
}

#[test]
fn a_finger_between_the_legs_is_free_where_the_hull_refuses_it() {
    let m = statuette();
    let world = probe_world(FINGER, vec![statuette_body(&m)]);
    let mut exact = ExactChecker::new(&world);
    let mut fast = FastChecker::new(&world);
    // Under the belly, between the four legs, above the plinth.
    let between = [0.0, 0.0, 0.08];
    assert!(exact.is_free(&between));
    assert!(fast.is_free(&between));
    // The convex hull of the vertices (what the checkers used before) contains that point.
    let pts: Vec<PVector> = m
        .vertices
        .iter()
        .map(|v| PVector::new(v.x, v.y, v.z))
        .collect();
    let hull = ConvexPolyhedron::from_convex_hull(&pts).unwrap();
    assert!(hull.contains_local_point(PVector::new(0.0, 0.0, 0.08)));
    // Two fingers pinching a front leg from either side in x: both free, 1 cm from the leg.
    let leg = Point3::new(0.0736, 0.031, 0.05);
    for dx in [-0.04, 0.04] {
        let q = [leg.x + dx, leg.y, leg.z];
        assert!(exact.is_free(&q), "{q:?}");
        assert!(fast.is_free(&q), "{q:?}");
    }
    // Into the leg: both refuse.
    assert!(!exact.is_free(&[leg.x, leg.y, leg.z]));
    assert!(!fast.is_free(&[leg.x, leg.y, leg.z]));
    // A finger wholly inside the body (no surface contact) collides: the inside counts.
    assert!(!exact.is_free(&[0.0, 0.0, 0.19]));
    assert_eq!(exact.clearance(&[0.0, 0.0, 0.19]), 0.0);
    assert!(!fast.is_free(&[0.0, 0.0, 0.19]));
    // A box holding the whole statuette collides too (the mesh inside the shape).
    let big = probe_world(
        r#"<geometry><box size="0.5 0.3 0.5"/></geometry>"#,
        vec![statuette_body(&m)],
    );
    assert!(!ExactChecker::new(&big).is_free(&[0.0, 0.0, 0.18]));
    // Clearance on the true surface: behind the hind legs, in front of the tail's tip.
    let d = exact.clearance(&[-0.11, 0.0, 0.05]);
    assert!(d > 0.005 && d < 0.025, "{d}");
}

#[test]
fn the_fast_cover_is_conservative_and_not_loose() {
    let m = statuette();
    let (lo, hi) = m.aabb();
    for (name, geometry) in [
        ("sphere", FINGER),
        (
            "box",
            r#"<geometry><box size="0.012 0.02 0.008"/></geometry>"#,
        ),
        (
            "capsule",
            r#"<geometry><capsule radius="0.006" length="0.03"/></geometry>"#,
        ),
    ] {
        let world = probe_world(geometry, vec![statuette_body(&m)]);
        let mut exact = ExactChecker::new(&world);
        let mut fast = FastChecker::new(&world);
        let loose = fast.max_overapproximation();
        assert!(loose.is_finite() && loose < 0.03, "{name}: {loose}");
        let mut rng = Mix(11);
        let (mut hits, mut free, mut refused_far) = (0, 0, 0);
        for _ in 0..3000 {
            let q = [
                lo.x - 0.03 + (hi.x - lo.x + 0.06) * rng.next(),
                lo.y - 0.03 + (hi.y - lo.y + 0.06) * rng.next(),
                lo.z + (hi.z - lo.z + 0.03) * rng.next(),
            ];
            let d = exact.clearance(&q);
            let f = fast.is_free(&q);
            if d <= 0.0 {
                hits += 1;
                assert!(!f, "{name} at {q:?}: exact collision, fast free");
            } else {
                free += 1;
                if d > loose && !f {
                    refused_far += 1;
                }
            }
        }
        assert!(
            hits > 200 && free > 1000,
            "{name}: {hits} hits, {free} free"
        );
        assert_eq!(
            refused_far, 0,
            "{name}: refused beyond its over-approximation"
        );
    }
}

#[test]
fn certified_motions_past_the_legs_are_free_under_a_dense_exact_check() {
    let m = statuette();
    let world = probe_world(FINGER, vec![statuette_body(&m)]);
    let mut exact = ExactChecker::new(&world);
    let mut fast = FastChecker::new(&world);
    let mut rng = Mix(3);
    // Motions through the space under the belly, in random directions.
    let (certified, grazing) = certify_motions(&mut fast, &mut exact, 300, || {
        let c = [
            -0.06 + 0.12 * rng.next(),
            -0.02 + 0.04 * rng.next(),
            0.04 + 0.08 * rng.next(),
        ];
        let dir = rng.dir();
        let a: Vec<f64> = (0..3).map(|k| c[k] - 0.06 * dir[k]).collect();
        let b: Vec<f64> = (0..3).map(|k| c[k] + 0.06 * dir[k]).collect();
        (a, b)
    });
    println!("{certified} of 300 motions certified, {grazing} within 2 cm");
    assert!(certified > 30, "{certified} of 300 motions certified");
    assert!(grazing > 5, "{grazing} certified motions pass within 2 cm");
}

#[test]
fn an_open_mesh_keeps_its_hull() {
    // A cube missing one face: not a solid; the checkers keep the hull and the box.
    let mut v = Vec::new();
    for i in 0..8 {
        let s = |b: usize| if i & b != 0 { 0.1 } else { -0.1 };
        v.push(Point3::new(s(1), s(2), s(4)));
    }
    let t = vec![
        [0, 2, 3],
        [0, 3, 1],
        [4, 5, 7],
        [4, 7, 6],
        [0, 1, 5],
        [0, 5, 4],
        [2, 6, 7],
        [2, 7, 3],
        [0, 4, 6],
        [0, 6, 2],
    ];
    let m = Mesh::from_triangles("open".into(), v, t).unwrap();
    let why = m.solid.as_ref().unwrap_err();
    assert!(why.contains("not closed"), "{why}");
    assert_eq!(m.cover().len(), 1);
    let world = probe_world(FINGER, vec![statuette_body(&Arc::new(m))]);
    // The finger inside the open box: the hull says collision.
    assert!(!ExactChecker::new(&world).is_free(&[0.0, 0.0, 0.0]));
    assert!(!FastChecker::new(&world).is_free(&[0.0, 0.0, 0.0]));
    // A triangle naming a vertex that does not exist is refused with its number.
    let bad = Mesh::from_triangles(
        "bad".into(),
        vec![Point3::origin(); 4],
        vec![[0, 1, 2], [0, 1, 9]],
    );
    assert!(bad.unwrap_err().contains("triangle 1 uses vertex 9"));
}

/// A post (box) and a bar (cylinder) for the held statuette to pass.
fn obstacles() -> Vec<StaticBody> {
    let body = common::obstacle;
    vec![
        body(
            "post",
            [0.0, 0.0, 0.0],
            [0.0; 3],
            Shape::Box {
                half_extents: Vector3::new(0.01, 0.04, 0.15),
            },
        ),
        body(
            "bar",
            [0.0, 0.0, 0.0],
            [std::f64::consts::FRAC_PI_2, 0.0, 0.0],
            Shape::Cylinder {
                radius: 0.006,
                half_length: 0.2,
            },
        ),
    ]
}

/// The statuette held by the probe (attached to its tool link, its fine cover of up to 256
/// boxes: the fast checker tests it in groups), carried past a post and a bar: the fast checker
/// is never free where the exact checker finds a collision of the true mesh, and certified
/// motions are free under a dense exact re-check.
#[test]
fn a_held_statuette_is_checked_conservatively_and_its_motions_certified() {
    let m = statuette();
    let (lo, hi) = m.aabb();
    let urdf = common::probe_urdf(FINGER, 2.0);
    let r = Arc::new(Robot::from_strings(&urdf, None, Path::new(".")).unwrap());
    let tool = r.link("tool").expect("tool link");
    let mut world = CollisionWorld::single(r, Pose::identity());
    world.statics = obstacles();
    world.attached.push(AttachedBody {
        name: "statuette".into(),
        robot: 0,
        link: tool,
        // The statuette beside the finger, so the finger never meets the obstacles first.
        rel: iso_from_rpy([0.0, 0.0, 0.05], [0.0, 0.0, 0.3]),
        shapes: vec![Geometry {
            origin: Pose::identity(),
            shape: Shape::Mesh(m.clone()),
        }],
        touch: vec![tool],
    });
    let mut exact = ExactChecker::new(&world);
    let mut fast = FastChecker::new(&world);
    let size = hi - lo;
    let span = [size.x + 0.06, size.y + 0.12, size.z + 0.1];
    let mut rng = Mix(29);
    let sample = |rng: &mut Mix| -> Vec<f64> {
        (0..3)
            .map(|k| -0.5 * span[k] - lo[k] - 0.5 * size[k] + span[k] * rng.next())
            .collect()
    };
    let (mut hits, mut free) = (0, 0);
    for _ in 0..3000 {
        let q = sample(&mut rng);
        if exact.clearance(&q) <= 0.0 {
            hits += 1;
            assert!(!fast.is_free(&q), "at {q:?}: exact collision, fast free");
        } else {
            free += 1;
        }
    }
    assert!(hits > 200 && free > 300, "{hits} hits, {free} free");
    let (certified, near) = certify_motions(&mut fast, &mut exact, 400, || {
        let a = sample(&mut rng);
        let dir = rng.dir();
        let b: Vec<f64> = (0..3).map(|k| a[k] + 0.08 * dir[k]).collect();
        (a, b)
    });
    println!("{hits} colliding / {free} free states; {certified} of 400 motions certified, {near} within 2 cm");
    assert!(certified > 40, "{certified} of 400 motions certified");
    assert!(near > 5, "{near} certified motions pass within 2 cm");
}
