//! Mass properties of bodies of overlapping parts (`src/grasp/mass.rs`): the centre of mass and
//! volume of the union (overlaps counted once), the largest distance of the surface from that
//! centre, and their use as the grasp lists' centre and torque scale λ = 1 / radius.

use std::path::Path;
use std::sync::Arc;

use manyhands::geometry::{Geometry, Mesh, Pose, Shape};
use manyhands::grasp::mass::{mass_properties, mass_properties_with};
use manyhands::grasp::{object_centre, object_radius, GraspObject};
use nalgebra::{Point3, Translation3, UnitQuaternion, Vector3};

/// A closed, outward box of half extents `h` about `c`, appended to `v`/`t`.
fn add_box(v: &mut Vec<Point3<f64>>, t: &mut Vec<[u32; 3]>, c: Vector3<f64>, h: Vector3<f64>) {
    let b = v.len() as u32;
    for k in 0..8 {
        let s = |bit: usize, e: f64| if k & bit != 0 { e } else { -e };
        v.push(Point3::from(
            c + Vector3::new(s(1, h.x), s(2, h.y), s(4, h.z)),
        ));
    }
    for f in [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ] {
        t.push([b + f[0], b + f[1], b + f[2]]);
        t.push([b + f[0], b + f[2], b + f[3]]);
    }
}

/// A unit cube at the origin and a cube of side 0.5 centred at (0.5, 0, 0), as one mesh of two
/// components, moved by `pose`.
fn two_cubes(pose: &Pose) -> Vec<Geometry> {
    let (mut v, mut t) = (Vec::new(), Vec::new());
    add_box(&mut v, &mut t, Vector3::zeros(), Vector3::repeat(0.5));
    add_box(
        &mut v,
        &mut t,
        Vector3::new(0.5, 0.0, 0.0),
        Vector3::repeat(0.25),
    );
    let v = v.into_iter().map(|p| pose * p).collect();
    let m = Mesh::from_triangles("two cubes".into(), v, t).unwrap();
    assert_eq!(m.solid.as_ref().unwrap().components, 2);
    vec![Geometry {
        origin: Pose::identity(),
        shape: Shape::Mesh(Arc::new(m)),
    }]
}

/// By hand: A = [-0.5, 0.5]³ (volume 1, centre 0), B = [0.25, 0.75] × [-0.25, 0.25]² (0.125,
/// centre x 0.5), A ∩ B = [0.25, 0.5] × [-0.25, 0.25]² (0.0625, centre x 0.375): union volume
/// 1.0625, moment x 0.125 · 0.5 − 0.0625 · 0.375 = 0.0390625, centre x = 0.0390625 / 1.0625;
/// the farthest points are A's corners at x = −0.5.
const UNION_VOLUME: f64 = 1.0625;
const UNION_CX: f64 = 0.0390625 / 1.0625;

fn union_radius() -> f64 {
    ((0.5 + UNION_CX).powi(2) + 0.5).sqrt()
}

#[test]
fn two_overlapping_cubes_give_the_union_centre() {
    let g = two_cubes(&Pose::identity());
    let m = mass_properties(&g);
    assert!((m.volume - UNION_VOLUME).abs() < 1e-4, "{m:?}");
    let want = Vector3::new(UNION_CX, 0.0, 0.0);
    assert!((m.centre - want).norm() < 1e-4, "{m:?} want {want}");
    assert!((m.radius - union_radius()).abs() < 1e-4, "{m:?}");
    // The parts' volume-weighted centre (overlap counted twice) would be 0.0625 / 1.125.
    assert!((m.centre.x - 0.0625 / 1.125).abs() > 0.01);
    // object_centre and object_radius say the same.
    let (c, r) = object_centre(&g);
    assert_eq!((c, r), (m.centre, m.radius));
    assert!((object_radius(&g, &c) - r).abs() < 1e-15);
}

#[test]
fn the_union_centre_moves_with_the_mesh_off_the_ray_grid() {
    // A generic rotation and translation: the rays no longer align with any face.
    let pose = Pose::from_parts(
        Translation3::new(0.3, -1.1, 0.7),
        UnitQuaternion::from_euler_angles(0.4, -0.7, 1.9),
    );
    let g = two_cubes(&pose);
    let m = mass_properties(&g);
    let want = (pose * Point3::new(UNION_CX, 0.0, 0.0)).coords;
    assert!(
        (m.volume - UNION_VOLUME).abs() < 2e-4 * UNION_VOLUME,
        "{m:?}"
    );
    assert!((m.centre - want).norm() < 1e-4, "{m:?} want {want}");
    assert!((m.radius - union_radius()).abs() < 1e-4, "{m:?}");
    // More rays converge on the exact value.
    let fine = mass_properties_with(&g, 1024);
    assert!((fine.centre - want).norm() < 2e-5, "{fine:?} want {want}");
    // The same body as two primitive boxes (rays through primitives), posed the same way.
    let boxes = vec![
        Geometry {
            origin: pose,
            shape: Shape::Box {
                half_extents: Vector3::repeat(0.5),
            },
        },
        Geometry {
            origin: pose
                * Pose::from_parts(Translation3::new(0.5, 0.0, 0.0), UnitQuaternion::identity()),
            shape: Shape::Box {
                half_extents: Vector3::repeat(0.25),
            },
        },
    ];
    let p = mass_properties(&boxes);
    assert!(
        (p.volume - UNION_VOLUME).abs() < 2e-4 * UNION_VOLUME,
        "{p:?}"
    );
    assert!((p.centre - want).norm() < 1e-4, "{p:?} want {want}");
    assert!((p.radius - union_radius()).abs() < 1e-9, "{p:?}");
}

#[test]
fn disjoint_parts_are_exact_and_primitives_mix_with_meshes() {
    // A sphere of radius 0.1 at (1, 0, 0) and the unit cube at the origin: no overlap.
    let (mut v, mut t) = (Vec::new(), Vec::new());
    add_box(&mut v, &mut t, Vector3::zeros(), Vector3::repeat(0.5));
    let cube = Mesh::from_triangles("cube".into(), v, t).unwrap();
    let g = vec![
        Geometry {
            origin: Pose::identity(),
            shape: Shape::Mesh(Arc::new(cube)),
        },
        Geometry {
            origin: Pose::from_parts(Translation3::new(1.0, 0.0, 0.0), UnitQuaternion::identity()),
            shape: Shape::Sphere { radius: 0.1 },
        },
    ];
    let vs = 4.0 / 3.0 * std::f64::consts::PI * 1e-3;
    let m = mass_properties(&g);
    assert!((m.volume - (1.0 + vs)).abs() < 1e-12, "{m:?}");
    assert!((m.centre.x - vs / (1.0 + vs)).abs() < 1e-12, "{m:?}");
    assert!((m.radius - (1.1 - m.centre.x)).abs() < 1e-12, "{m:?}");
    // A cylinder (axis z) through the cube: union = cube + the two stubs outside it.
    let cyl = Geometry {
        origin: Pose::identity(),
        shape: Shape::Cylinder {
            radius: 0.1,
            half_length: 1.0,
        },
    };
    let g2 = vec![g[0].clone(), cyl];
    let m2 = mass_properties(&g2);
    let stubs = std::f64::consts::PI * 0.01 * 1.0;
    assert!((m2.volume - (1.0 + stubs)).abs() < 2e-3 * stubs, "{m2:?}");
    assert!(m2.centre.norm() < 1e-6, "{m2:?}");
    assert!((m2.radius - (1.01f64).sqrt()).abs() < 1e-12, "{m2:?}");
}

#[test]
fn statuette_centre_and_radius_are_the_solids() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mesh = Mesh::load(&root.join("scenes/meshes/statuette.obj"), [1.0; 3]).unwrap();
    let g = vec![Geometry {
        origin: Pose::identity(),
        shape: Shape::Mesh(Arc::new(mesh)),
    }];
    let t0 = std::time::Instant::now();
    let m = mass_properties_with(&g, manyhands::grasp::mass::OVERLAP_RAYS);
    let secs = t0.elapsed().as_secs_f64();
    println!("statuette: {m:?} in {:.1} ms", secs * 1e3);
    let want = Vector3::new(0.01851, 0.0, 0.1429);
    assert!((m.centre - want).norm() < 1e-4, "{m:?} want {want}");
    assert!((m.radius - 0.265).abs() < 1e-3, "{m:?}");
    // Converged: 4× the rays moves the centre by < 2e-5 m and the volume by < 0.05 %.
    let fine = mass_properties_with(&g, 4 * manyhands::grasp::mass::OVERLAP_RAYS);
    println!("statuette, 4× rays: {fine:?}");
    assert!((fine.centre - m.centre).norm() < 2e-5);
    assert!((fine.volume - m.volume).abs() < 5e-4 * m.volume);
    // The grasp lists' object uses it: centre and λ = 1 / radius.
    let obj = GraspObject::from_mesh_file(&root.join("scenes/meshes/statuette.obj")).unwrap();
    assert_eq!(obj.centre, m.centre);
    assert_eq!(obj.radius, m.radius);
}
