//! Grasp wrench space: the reference values of `../shared/notes/grasp-quality.md`, the own
//! 6-D hull against brute force, invariances, input errors, and the `grasp quality` command.

#[path = "common/tmp.rs"]
mod tmp;
use std::process::Command;

use manyhands::grasp::{
    grasp_quality, object_centre, primitive_wrenches, quality_of_wrenches, score_object_grasps,
    wrench_rank, Contact, ConvexHull, GraspError, HullError, Point6, WrenchSpaceSettings,
};
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn v(x: f64, y: f64, z: f64) -> Vector3<f64> {
    Vector3::new(x, y, z)
}

/// Contacts at the four side-face centres of the unit cube at the origin, inward normals.
fn cube_sides() -> Vec<Contact> {
    vec![
        Contact::new(v(0.5, 0.0, 0.0), v(-1.0, 0.0, 0.0)),
        Contact::new(v(-0.5, 0.0, 0.0), v(1.0, 0.0, 0.0)),
        Contact::new(v(0.0, 0.5, 0.0), v(0.0, -1.0, 0.0)),
        Contact::new(v(0.0, -0.5, 0.0), v(0.0, 1.0, 0.0)),
    ]
}

fn settings(mu: f64, m: usize) -> WrenchSpaceSettings {
    WrenchSpaceSettings {
        mu,
        cone_edges: m,
        lambda: Some(1.0),
        soft_finger: None,
    }
}

fn eps(contacts: &[Contact], s: &WrenchSpaceSettings) -> f64 {
    grasp_quality(contacts, &Vector3::zeros(), s)
        .expect("quality")
        .epsilon
}

#[test]
fn reference_values_of_the_notes() {
    let c = cube_sides();
    let q = grasp_quality(&c, &Vector3::zeros(), &settings(0.5, 8)).expect("quality");
    assert!(q.force_closure);
    assert_eq!(q.rank, 6);
    assert_eq!(q.wrenches, 32);
    assert!(q.facets > 0);
    assert!((q.epsilon - 0.169650).abs() < 1e-5, "{}", q.epsilon);
    let e = eps(&c, &settings(1.0, 8));
    assert!((e - 0.339299).abs() < 1e-5, "{e}");
    let e = eps(&c, &settings(0.5, 4));
    assert!((e - 0.144338).abs() < 1e-5, "{e}");

    let two = &c[..2];
    let q = grasp_quality(two, &Vector3::zeros(), &settings(0.5, 8)).expect("quality");
    assert_eq!(q.rank, 5);
    assert!(!q.force_closure);
    assert_eq!(q.epsilon, 0.0);
    assert_eq!(q.facets, 0);
}

#[test]
fn default_lambda_is_one_over_the_largest_contact_distance() {
    let c = cube_sides();
    let s = WrenchSpaceSettings::default();
    let q = grasp_quality(&c, &Vector3::zeros(), &s).expect("quality");
    assert!((q.lambda - 2.0).abs() < 1e-12);
    let explicit = WrenchSpaceSettings {
        lambda: Some(2.0),
        ..s
    };
    assert!((q.epsilon - eps(&c, &explicit)).abs() < 1e-12);
}

/// ε by brute force: every 6-subset spans a candidate facet plane; it is a hull facet iff all
/// points lie on one side; ε = min distance of the origin over those planes (0 if outside).
fn brute_force_depth(pts: &[Point6]) -> f64 {
    let n = pts.len();
    let mut best = f64::INFINITY;
    let mut idx = [0usize; 6];
    fn rec(pts: &[Point6], start: usize, k: usize, idx: &mut [usize; 6], best: &mut f64, n: usize) {
        if k == 6 {
            let m =
                nalgebra::SMatrix::<f64, 5, 6>::from_fn(|r, c| pts[idx[r + 1]][c] - pts[idx[0]][c]);
            let svd = m.transpose().svd(true, false);
            let Some(u) = svd.u else { return };
            // Null vector of the 5×6 matrix: the left singular vector of the 6×5 transpose
            // orthogonal to the 5 columns = the one not among the first five.
            let full =
                nalgebra::SMatrix::<f64, 6, 6>::from_fn(|r, c| if c < 5 { u[(r, c)] } else { 0.0 });
            let qr = full.qr();
            let q = qr.q();
            let normal: Vec<f64> = (0..6).map(|r| q[(r, 5)]).collect();
            let off: f64 = (0..6).map(|t| normal[t] * pts[idx[0]][t]).sum();
            let dists: Vec<f64> = pts
                .iter()
                .map(|p| (0..6).map(|t| normal[t] * p[t]).sum::<f64>() - off)
                .collect();
            let (above, below) = dists.iter().fold((0, 0), |(a, b), &d| {
                (a + usize::from(d > 1e-9), b + usize::from(d < -1e-9))
            });
            if above == 0 || below == 0 {
                // Facet; outward normal points to the empty side.
                let depth = if above == 0 { off } else { -off };
                *best = best.min(depth);
            }
            return;
        }
        for i in start..n {
            idx[k] = i;
            rec(pts, i + 1, k + 1, idx, best, n);
        }
    }
    rec(pts, 0, 0, &mut idx, &mut best, n);
    best.max(0.0)
}

#[test]
fn hull_matches_brute_force_on_random_points() {
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    let mut inside = 0;
    for trial in 0..60 {
        let n = if trial % 3 == 1 {
            12
        } else {
            rng.random_range(7..=10)
        };
        let shift = if trial % 3 == 0 { 0.8 } else { 0.0 };
        let mut pts: Vec<Point6> = (0..n)
            .map(|_| {
                std::array::from_fn(|i| {
                    rng.random_range(-1.0..1.0) + if i == 0 { shift } else { 0.0 }
                })
            })
            .collect();
        if trial % 3 == 1 {
            // Pairs p, −s p (12 points): the origin is inside more often.
            for k in 0..n / 2 {
                let s = rng.random_range(0.3..1.5);
                pts[n / 2 + k] = pts[k].map(|x| -s * x);
            }
        }
        let hull = ConvexHull::new(&pts).expect("hull");
        let own = hull.origin_depth().max(0.0);
        let polished = hull.support_depth(&pts).max(0.0);
        let bf = brute_force_depth(&pts);
        assert!(
            (own - bf).abs() < 1e-4,
            "trial {trial}: joggled hull {own} vs brute force {bf}"
        );
        assert!(
            (polished - bf).abs() < 1e-9,
            "trial {trial}: polished {polished} vs brute force {bf}"
        );
        // Facet count of the hull equals the brute-force facet count.
        if own > 0.0 {
            inside += 1;
        }
        for f in hull.facets() {
            for p in &pts {
                let d: f64 = (0..6).map(|t| f.normal[t] * p[t]).sum::<f64>() - f.offset;
                assert!(d < 1e-5, "trial {trial}: point above a facet by {d}");
            }
        }
    }
    assert!(
        inside > 5,
        "too few trials with the origin inside ({inside})"
    );
}

#[test]
fn quality_matches_brute_force_on_random_three_finger_grasps() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut fc = 0;
    for trial in 0..40 {
        // Three contacts on a unit sphere, normals pointing roughly inward.
        let contacts: Vec<Contact> = (0..3)
            .map(|_| {
                let p = v(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                )
                .normalize();
                let jitter = v(
                    rng.random_range(-0.3..0.3),
                    rng.random_range(-0.3..0.3),
                    rng.random_range(-0.3..0.3),
                );
                Contact::new(p, -p + jitter)
            })
            .collect();
        let s = WrenchSpaceSettings {
            mu: 0.6,
            cone_edges: 3,
            lambda: Some(1.0),
            soft_finger: None,
        };
        let w = primitive_wrenches(&contacts, &Vector3::zeros(), &s).expect("wrenches");
        assert_eq!(w.len(), 9);
        let q = grasp_quality(&contacts, &Vector3::zeros(), &s).expect("quality");
        let bf = brute_force_depth(&w);
        assert!(
            (q.epsilon - bf).abs() < 1e-7,
            "trial {trial}: {} vs {bf}",
            q.epsilon
        );
        assert_eq!(q.force_closure, q.epsilon > 0.0);
        fc += usize::from(q.force_closure);
    }
    assert!(fc > 0, "no force-closure trial");
}

fn random_grasp(rng: &mut ChaCha8Rng, n: usize) -> Vec<Contact> {
    (0..n)
        .map(|_| {
            let p = v(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            )
            .normalize()
                * 0.1;
            let jitter = v(
                rng.random_range(-0.2..0.2),
                rng.random_range(-0.2..0.2),
                rng.random_range(-0.2..0.2),
            );
            Contact::new(p, -p.normalize() + jitter)
        })
        .collect()
}

#[test]
fn permutation_lambda_scaling_and_monotonicity() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let c0 = Vector3::new(0.01, -0.02, 0.005);
    let mut checked = 0;
    for _ in 0..20 {
        let contacts = random_grasp(&mut rng, 5);
        let s = WrenchSpaceSettings {
            mu: 0.5,
            cone_edges: 8,
            lambda: Some(10.0),
            soft_finger: None,
        };
        let q = grasp_quality(&contacts, &c0, &s).expect("quality");
        // Permutations of the contacts.
        for k in 1..5 {
            let mut p = contacts.clone();
            p.rotate_left(k);
            p.swap(0, 2);
            let qp = grasp_quality(&p, &c0, &s).expect("quality");
            assert!(
                (qp.epsilon - q.epsilon).abs() < 1e-9,
                "{} vs {}",
                qp.epsilon,
                q.epsilon
            );
            assert_eq!(qp.force_closure, q.force_closure);
        }
        if !q.force_closure {
            continue;
        }
        checked += 1;
        // λ scaling: torques scale by s, so min(1,s) ε ≤ ε(sλ) ≤ max(1,s) ε; force closure kept.
        for f in [0.25, 0.5, 2.0, 4.0] {
            let qs = grasp_quality(
                &contacts,
                &c0,
                &WrenchSpaceSettings {
                    lambda: Some(10.0 * f),
                    ..s
                },
            )
            .expect("quality");
            assert!(qs.force_closure);
            let (lo, hi) = (f64::min(1.0, f), f64::max(1.0, f));
            assert!(
                qs.epsilon >= lo * q.epsilon - 1e-9 && qs.epsilon <= hi * q.epsilon + 1e-9,
                "λ×{f}: {} not in [{}, {}]",
                qs.epsilon,
                lo * q.epsilon,
                hi * q.epsilon
            );
        }
        // Adding a contact never decreases ε (fixed λ).
        let mut more = contacts.clone();
        more.extend(random_grasp(&mut rng, 1));
        let qm = grasp_quality(&more, &c0, &s).expect("quality");
        assert!(
            qm.epsilon >= q.epsilon - 1e-9,
            "{} < {}",
            qm.epsilon,
            q.epsilon
        );
        // A larger μ never decreases ε.
        let qmu =
            grasp_quality(&contacts, &c0, &WrenchSpaceSettings { mu: 0.8, ..s }).expect("quality");
        assert!(qmu.epsilon >= q.epsilon - 1e-9);
        // Soft fingers add wrenches, so ε does not decrease either.
        let qsf = grasp_quality(
            &contacts,
            &c0,
            &WrenchSpaceSettings {
                soft_finger: Some(0.05),
                ..s
            },
        )
        .expect("quality");
        assert_eq!(qsf.wrenches, 5 * 10);
        assert!(qsf.epsilon >= q.epsilon - 1e-9);
    }
    assert!(checked >= 5, "only {checked} force-closure grasps");
}

#[test]
fn degenerate_inputs_do_not_panic() {
    // Duplicated contacts, contacts at the centre, coplanar cube corners, many symmetric contacts.
    let mut c = cube_sides();
    c.extend(cube_sides());
    let q = grasp_quality(&c, &Vector3::zeros(), &settings(0.5, 8)).expect("quality");
    assert!((q.epsilon - 0.169650).abs() < 1e-5);
    let at_centre = vec![Contact::new(Vector3::zeros(), v(0.0, 0.0, 1.0)); 3];
    let q = grasp_quality(
        &at_centre,
        &Vector3::zeros(),
        &WrenchSpaceSettings::default(),
    )
    .expect("quality");
    assert!(!q.force_closure && q.rank == 3 && q.lambda == 1.0);
    let q =
        grasp_quality(&[], &Vector3::zeros(), &WrenchSpaceSettings::default()).expect("quality");
    assert_eq!((q.rank, q.wrenches, q.force_closure), (0, 0, false));
    // All six face centres with 32 edges and soft fingers: very symmetric input.
    let mut six = cube_sides();
    six.push(Contact::new(v(0.0, 0.0, 0.5), v(0.0, 0.0, -1.0)));
    six.push(Contact::new(v(0.0, 0.0, -0.5), v(0.0, 0.0, 1.0)));
    let s = WrenchSpaceSettings {
        mu: 0.5,
        cone_edges: 32,
        lambda: Some(1.0),
        soft_finger: Some(0.1),
    };
    let q = grasp_quality(&six, &Vector3::zeros(), &s).expect("quality");
    assert!(q.force_closure && q.epsilon > 0.169650);
    // The wrench matrix rank alone.
    let w =
        primitive_wrenches(&cube_sides()[..2], &Vector3::zeros(), &settings(0.5, 8)).expect("w");
    assert_eq!(wrench_rank(&w), 5);
    // Wrenches on an affine hyperplane: rank 6 but flat → not force closure.
    let flat: Vec<Point6> = (0..12)
        .map(|i| {
            let a = i as f64;
            [
                1.0,
                a.sin(),
                a.cos(),
                (2.0 * a).sin(),
                (3.0 * a).cos(),
                0.1 * a,
            ]
        })
        .collect();
    let q = quality_of_wrenches(&flat, 1.0).expect("quality");
    assert_eq!(q.rank, 6);
    assert!(!q.force_closure);
    assert_eq!(ConvexHull::new(&flat).unwrap_err(), HullError::Flat);
}

#[test]
fn errors_name_the_field() {
    let c = cube_sides();
    let z = Vector3::zeros();
    let err = |contacts: &[Contact], centre: &Vector3<f64>, s: WrenchSpaceSettings| {
        grasp_quality(contacts, centre, &s).expect_err("must fail")
    };
    let e = err(&c, &z, settings(0.0, 8));
    assert_eq!((e.field(), e.clone()), ("mu", GraspError::Mu(0.0)));
    assert_eq!(err(&c, &z, settings(f64::NAN, 8)).field(), "mu");
    assert_eq!(err(&c, &z, settings(0.5, 2)), GraspError::ConeEdges(2));
    assert_eq!(err(&c, &z, settings(0.5, 33)).field(), "cone_edges");
    assert_eq!(
        err(
            &c,
            &z,
            WrenchSpaceSettings {
                lambda: Some(-1.0),
                ..settings(0.5, 8)
            }
        )
        .field(),
        "lambda"
    );
    assert_eq!(
        err(
            &c,
            &z,
            WrenchSpaceSettings {
                soft_finger: Some(f64::INFINITY),
                ..settings(0.5, 8)
            }
        )
        .field(),
        "soft_finger"
    );
    assert_eq!(
        err(&c, &v(f64::NAN, 0.0, 0.0), settings(0.5, 8)).field(),
        "centre"
    );
    let mut bad = c.clone();
    bad[2].point.y = f64::INFINITY;
    assert_eq!(err(&bad, &z, settings(0.5, 8)).field(), "contacts[2].point");
    let mut bad = c.clone();
    bad[3].normal = Vector3::zeros();
    let e = err(&bad, &z, settings(0.5, 8));
    assert_eq!(e.field(), "contacts[3].normal");
    assert!(e.to_string().contains("zero length"), "{e}");
    let mut bad = c.clone();
    bad[1].normal.x = f64::NAN;
    assert_eq!(
        err(&bad, &z, settings(0.5, 8)).field(),
        "contacts[1].normal"
    );
    let many = vec![c[0]; 65];
    let e = err(&many, &z, settings(0.5, 8));
    assert_eq!(e.field(), "contacts");
    assert!(e.reason().contains("at most 64"), "{}", e.reason());
}

#[test]
fn object_centre_of_scene_shapes() {
    use manyhands::geometry::{Geometry, Pose, Shape};
    let shapes = [
        Geometry {
            origin: Pose::translation(0.0, 0.0, 1.0),
            shape: Shape::Box {
                half_extents: v(0.5, 0.5, 0.5),
            },
        },
        Geometry {
            origin: Pose::translation(0.0, 0.0, -1.0),
            shape: Shape::Box {
                half_extents: v(0.5, 0.5, 0.5),
            },
        },
        Geometry {
            origin: Pose::translation(3.0, 0.0, 0.0),
            shape: Shape::Sphere { radius: 0.0 },
        },
    ];
    let (c, r) = object_centre(&shapes[..2]);
    assert!(c.norm() < 1e-12);
    // The farthest surface point from the centre: a far corner (0.5, 0.5, 1.5).
    assert!((r - 2.75f64.sqrt()).abs() < 1e-12, "{r}");
    let (c, _) = object_centre(&shapes[..1]);
    assert!((c - v(0.0, 0.0, 1.0)).norm() < 1e-12);
}

/// A unit cube object (box of half extent 0.5 at the origin) with grasps holding `contacts`.
fn cube_object(grasps: Vec<(&str, Vec<Contact>)>) -> manyhands::model::Object {
    use manyhands::geometry::{Geometry, Pose, Shape};
    use manyhands::model::{Body, ContactPoint, Grasp, GraspType, Object};
    Object {
        body: Body {
            name: "cube".into(),
            pose: Pose::identity(),
            shapes: vec![Geometry {
                origin: Pose::identity(),
                shape: Shape::Box {
                    half_extents: v(0.5, 0.5, 0.5),
                },
            }],
        },
        mass: Some(1.0),
        grasps: grasps
            .into_iter()
            .map(|(name, cs)| Grasp {
                name: name.into(),
                end_effector: "hand".into(),
                tcp: Pose::identity(),
                pregrasp_offset: Vector3::zeros(),
                kind: GraspType::Precision,
                contacts: cs
                    .iter()
                    .map(|c| ContactPoint {
                        point: c.point.into(),
                        normal: c.normal.into(),
                    })
                    .collect(),
                quality: 0.5,
            })
            .collect(),
        goal: None,
    }
}

#[test]
fn scene_object_grasps_share_the_centre_and_lambda() {
    let c = cube_sides();
    let obj = cube_object(vec![
        ("sides", c.clone()),
        ("pinch", c[..2].to_vec()),
        ("none", Vec::new()),
    ]);
    let s = WrenchSpaceSettings::default();
    let scores = score_object_grasps(&obj, &obj.grasps, None, &s).expect("scores");
    let r = 0.75f64.sqrt();
    assert!(scores.centre.norm() < 1e-12);
    assert!((scores.radius - r).abs() < 1e-12);
    assert_eq!(scores.settings.lambda, Some(1.0 / r));
    let expected = grasp_quality(
        &c,
        &Vector3::zeros(),
        &WrenchSpaceSettings {
            lambda: Some(1.0 / r),
            ..s
        },
    )
    .expect("quality");
    assert_eq!(scores.grasps[0], expected);
    assert!(expected.force_closure);
    assert_eq!(
        (scores.grasps[1].rank, scores.grasps[1].force_closure),
        (5, false)
    );
    assert_eq!((scores.grasps[2].rank, scores.grasps[2].wrenches), (0, 0));
    // A given centre moves the radius with it; a given λ is kept.
    let shifted =
        score_object_grasps(&obj, &obj.grasps[..1], Some(v(0.1, 0.0, 0.0)), &s).expect("scores");
    // The farthest corner from (0.1, 0, 0): (−0.5, ±0.5, ±0.5).
    assert!(
        (shifted.radius - 0.86f64.sqrt()).abs() < 1e-12,
        "{}",
        shifted.radius
    );
    assert_eq!(shifted.grasps.len(), 1);
    let fixed = WrenchSpaceSettings {
        lambda: Some(1.0),
        ..s
    };
    let scores = score_object_grasps(&obj, &obj.grasps[..1], None, &fixed).expect("scores");
    assert!((scores.grasps[0].epsilon - 0.169650).abs() < 1e-5);
    // Errors: settings and centre before any grasp, then the grasp named.
    let bad_mu = WrenchSpaceSettings { mu: 0.0, ..s };
    let e = score_object_grasps(&obj, &[], None, &bad_mu).expect_err("mu");
    assert_eq!(e.field(), "mu");
    let e = score_object_grasps(&obj, &[], Some(v(f64::NAN, 0.0, 0.0)), &s).expect_err("centre");
    assert_eq!(e.field(), "centre");
    let many = cube_object(vec![("many", vec![c[0]; 65])]);
    let e = score_object_grasps(&many, &many.grasps, None, &s).expect_err("65 contacts");
    assert_eq!(e.field(), "contacts");
    assert!(e.to_string().starts_with("grasp 'many': contacts:"), "{e}");
}

#[test]
fn overflowing_and_non_finite_wrenches_are_errors() {
    let z = Vector3::zeros();
    let s = WrenchSpaceSettings::default();
    // Finite inputs whose difference or wrenches overflow name the contact.
    let far = [Contact::new(v(1.5e308, 0.0, 0.0), v(0.0, 1.0, 0.0))];
    let e = grasp_quality(&far, &v(-1.5e308, 0.0, 0.0), &s).expect_err("overflow");
    assert_eq!(e.field(), "contacts[0].point");
    let huge = WrenchSpaceSettings {
        lambda: Some(1e300),
        ..s
    };
    let e = grasp_quality(
        &[Contact::new(v(1e10, 0.0, 0.0), v(0.0, 1.0, 0.0))],
        &z,
        &huge,
    )
    .expect_err("overflow");
    assert_eq!(e.field(), "contacts[0]");
    assert!(matches!(e, GraspError::Overflow { .. }), "{e}");
    // A huge (finite) normal is normalised without overflow.
    let mut big = cube_sides();
    for c in &mut big {
        c.normal *= 1e308;
    }
    let l1 = settings(0.5, 8);
    assert!((eps(&big, &l1) - 0.169650).abs() < 1e-5);
    // Given wrenches: a non-finite one is named; the rank of such input is 0.
    let mut w = primitive_wrenches(&cube_sides(), &z, &l1).expect("wrenches");
    w[1][4] = f64::NAN;
    let e = quality_of_wrenches(&w, 1.0).expect_err("NaN");
    assert_eq!(e.field(), "wrenches[1]");
    assert_eq!(wrench_rank(&w), 0);
}

fn cli(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_manyhands"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run manyhands");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn cli_scores_scene_grasps_and_contact_files() {
    let (code, out, err) = cli(&[
        "grasp", "quality", "--scene", "kitchen", "--object", "wok", "--json",
    ]);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).expect("json");
    let grasps = v["grasps"].as_array().expect("grasps");
    assert_eq!(grasps.len(), 25);
    assert!(grasps
        .iter()
        .all(|g| g["rank"].as_u64().is_some() && g["epsilon"].as_f64().is_some()));
    let (code, out, err) = cli(&[
        "grasp", "quality", "--scene", "kitchen", "--object", "wok", "--grasp", "wok_r_00",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("wok_r_00"), "{out}");
    let (code, _, err) = cli(&["grasp", "quality", "--scene", "kitchen", "--object", "nope"]);
    assert_ne!(code, 0);
    assert!(err.contains("nope"), "{err}");

    let dir = tmp::run_root().join(format!("manyhands-grasp-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let file = dir.join("cube.json");
    let body = serde_json::json!({"contacts": [
        {"point": [0.5, 0, 0], "normal": [-1, 0, 0]}, {"point": [-0.5, 0, 0], "normal": [1, 0, 0]},
        {"point": [0, 0.5, 0], "normal": [0, -1, 0]}, {"point": [0, -0.5, 0], "normal": [0, 1, 0]}],
        "centre": [0, 0, 0]});
    std::fs::write(&file, body.to_string()).expect("write");
    let f = file.to_string_lossy().into_owned();
    let (code, out, err) = cli(&[
        "grasp",
        "quality",
        "--contacts",
        &f,
        "--lambda",
        "1",
        "--json",
    ]);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).expect("json");
    assert_eq!(v["force_closure"], true);
    assert!(
        (v["epsilon"].as_f64().unwrap_or(0.0) - 0.169650).abs() < 1e-5,
        "{v}"
    );
    let (code, _, err) = cli(&["grasp", "quality", "--contacts", &f, "--edges", "2"]);
    assert_ne!(code, 0);
    assert!(err.contains("cone_edges"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The hull of real wrench spaces (5–6 contacts, 8 cone edges: co-flat cone wrenches, sliver
/// facets, sometimes a joggle retry) contains every unjoggled wrench, and its joggled origin
/// depth agrees with the polished one. Bounds: a joggled point moves by at most √6 × joggle
/// (unit facet normals), and the local-convexity check admits one more joggle.
#[test]
fn wrench_hulls_contain_every_wrench() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let c0 = Vector3::new(0.01, -0.02, 0.005);
    let s = WrenchSpaceSettings {
        mu: 0.5,
        cone_edges: 8,
        lambda: Some(10.0),
        soft_finger: None,
    };
    let mut inside = 0;
    for trial in 0..20 {
        let contacts = random_grasp(&mut rng, 5 + trial % 2);
        let w = primitive_wrenches(&contacts, &c0, &s).expect("wrenches");
        let hull = ConvexHull::new(&w).expect("hull");
        assert!(!hull.facets().is_empty());
        let bound = (6f64.sqrt() + 1.0) * hull.joggle() + 1e-9 * hull.scale();
        for f in hull.facets() {
            for (i, p) in w.iter().enumerate() {
                let d: f64 = (0..6).map(|t| f.normal[t] * p[t]).sum::<f64>() - f.offset;
                assert!(
                    d <= bound,
                    "trial {trial}: wrench {i} above a facet by {d:e} (bound {bound:e})"
                );
            }
        }
        let polished = hull.support_depth(&w);
        if polished > 0.0 {
            inside += 1;
            let joggled = hull.origin_depth();
            assert!(
                (polished - joggled).abs() <= bound,
                "trial {trial}: polished depth {polished} vs joggled {joggled} (bound {bound:e})"
            );
        }
    }
    assert!(inside >= 5, "only {inside} wrench spaces hold the origin");
}

/// The grasp lists' pre-test (`forces_one_sided`, 003 §IV-A-3) never rules out a grasp the
/// wrench hull finds in force closure, and rules out the grasps whose forces all push one way.
#[test]
fn forces_one_sided_never_rules_out_force_closure() {
    use manyhands::grasp::wrench_space::forces_one_sided;
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    let s = settings(0.5, 6);
    let (mut one_sided, mut closure) = (0, 0);
    for i in 0..600 {
        let n = 3 + i % 3;
        // Points on the unit sphere, inward normals; every third set on the upper half only.
        let contacts: Vec<Contact> = (0..n)
            .map(|_| {
                let mut p = v(
                    rng.random::<f64>() - 0.5,
                    rng.random::<f64>() - 0.5,
                    rng.random::<f64>() - 0.5,
                )
                .normalize();
                if i % 3 == 0 {
                    p.z = p.z.abs() + 0.8;
                    p = p.normalize();
                }
                Contact::new(p, -p)
            })
            .collect();
        let w = primitive_wrenches(&contacts, &Vector3::zeros(), &s).expect("wrenches");
        let q = quality_of_wrenches(&w, 1.0).expect("quality");
        if forces_one_sided(&w) {
            one_sided += 1;
            assert!(
                !q.force_closure,
                "set {i}: ruled out, but in force closure (ε = {})",
                q.epsilon
            );
        }
        closure += usize::from(q.force_closure);
    }
    assert!(one_sided >= 200, "{one_sided} sets ruled out");
    assert!(closure >= 50, "{closure} sets in force closure");
}
