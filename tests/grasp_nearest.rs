//! The collector's grasp score (002 §IV-B) without the full wrench hull: the nearest-facet ε
//! ([`quality_of_wrenches_nearest`]) and the proof ε > s_min ([`score_exceeds_nearest`])
//! against the full hull ([`quality_of_wrenches`]) on random contact sets, the real contact
//! sets of the kitchen_two table grasps, and degenerate ones (coplanar contacts, the origin on
//! the boundary, the origin outside).

use manyhands::grasp::{
    grasp_contacts, object_centre, object_radius, primitive_wrenches, quality_of_wrenches,
    quality_of_wrenches_nearest, score_exceeds_nearest, Contact, GraspQuality, Point6,
    WrenchSpaceSettings,
};
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn v(x: f64, y: f64, z: f64) -> Vector3<f64> {
    Vector3::new(x, y, z)
}

/// Compares both scores of one wrench set; returns the full hull's quality.
fn same(w: &[Point6], what: &str) -> GraspQuality {
    let full = quality_of_wrenches(w, 1.0).expect("full hull");
    let near = quality_of_wrenches_nearest(w, 1.0).expect("nearest");
    assert_eq!(near.rank, full.rank, "{what}: rank");
    assert_eq!(
        near.force_closure, full.force_closure,
        "{what}: verdict (full ε {}, nearest ε {})",
        full.epsilon, near.epsilon
    );
    let rel = (near.epsilon - full.epsilon).abs() / full.epsilon.abs().max(1e-300);
    assert!(
        near.epsilon == full.epsilon || rel <= 1e-9,
        "{what}: ε {} against the full hull's {} (relative {rel:e})",
        near.epsilon,
        full.epsilon
    );
    assert!(
        near.facets <= full.facets,
        "{what}: grew more than the hull"
    );
    // The proof never claims more than the exact score.
    for s in [0.0, 0.5, 0.999, 0.999_999, 1.0, 1.000_001, 1.5] {
        let s_min = s * full.epsilon;
        if score_exceeds_nearest(w, s_min) {
            assert!(
                full.force_closure && full.epsilon > s_min,
                "{what}: proof of ε > {s_min} but ε = {}",
                full.epsilon
            );
        }
    }
    full
}

fn wrenches(contacts: &[Contact], centre: &Vector3<f64>, s: &WrenchSpaceSettings) -> Vec<Point6> {
    primitive_wrenches(contacts, centre, s).expect("wrenches")
}

fn settings(mu: f64, m: usize) -> WrenchSpaceSettings {
    WrenchSpaceSettings {
        mu,
        cone_edges: m,
        lambda: Some(1.0),
        soft_finger: None,
    }
}

#[test]
fn random_contact_sets_match_the_full_hull() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let (mut fc, mut trials) = (0, 0);
    for trial in 0..120 {
        let n = 3 + trial % 10;
        let contacts: Vec<Contact> = (0..n)
            .map(|_| {
                let p = v(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                )
                .normalize()
                    * 0.1;
                let jitter = v(
                    rng.random_range(-0.3..0.3),
                    rng.random_range(-0.3..0.3),
                    rng.random_range(-0.3..0.3),
                );
                Contact::new(p, -p.normalize() + jitter)
            })
            .collect();
        let s = settings(rng.random_range(0.2..1.0), [4, 6, 8][trial % 3]);
        // Off-centre: the origin of wrench space moves toward the boundary and beyond.
        let centre = v(
            rng.random_range(-0.08..0.08),
            rng.random_range(-0.08..0.08),
            rng.random_range(-0.08..0.08),
        );
        let q = same(&wrenches(&contacts, &centre, &s), &format!("trial {trial}"));
        fc += usize::from(q.force_closure);
        trials += 1;
    }
    // Both verdicts occur, so both paths were compared.
    assert!(
        fc > 10 && fc < trials - 10,
        "{fc} of {trials} force closure"
    );
}

#[test]
fn kitchen_two_table_grasps_match_the_full_hull() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let lib = manyhands::model::load_robot_dir(&root.join("robots")).expect("robots");
    let scene = manyhands::model::Scene::from_file(&root.join("scenes/kitchen_two.json"), &lib)
        .expect("scene");
    let table = scene.object("table").expect("table");
    let (centre, _) = object_centre(&table.body.shapes);
    let radius = object_radius(&table.body.shapes, &centre);
    let grasps: Vec<Vec<Contact>> = table.grasps.iter().map(grasp_contacts).collect();
    assert!(grasps.len() >= 20);
    let s = WrenchSpaceSettings {
        lambda: Some(1.0 / radius),
        ..WrenchSpaceSettings::default()
    };
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let mut fc = 0;
    // Four hands (two robots, 8 contacts) as the collector scores them, and ten grasps
    // (20 contacts, as in 002 Fig. 7).
    for trial in 0..40 {
        let hands = if trial % 4 == 3 { 10 } else { 4 };
        let mut contacts = Vec::new();
        for _ in 0..hands {
            contacts.extend_from_slice(&grasps[rng.random_range(0..grasps.len())]);
        }
        let q = same(
            &wrenches(&contacts, &centre, &s),
            &format!("kitchen_two trial {trial}"),
        );
        fc += usize::from(q.force_closure);
    }
    assert!(fc > 20, "{fc} of 40 force closure");
}

#[test]
fn degenerate_sets_match_the_full_hull() {
    // Coplanar contacts: every point on z = 0, normals tilted up and down.
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    for trial in 0..12 {
        let contacts: Vec<Contact> = (0..6)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / 6.0 + rng.random_range(-0.2..0.2);
                let p = v(a.cos(), a.sin(), 0.0) * 0.1;
                let up = if i % 2 == 0 { 0.3 } else { -0.3 };
                Contact::new(p, -p.normalize() + v(0.0, 0.0, up))
            })
            .collect();
        same(
            &wrenches(&contacts, &Vector3::zeros(), &settings(0.5, 8)),
            &format!("coplanar {trial}"),
        );
    }
    // The four side-face centres of the unit cube (the notes' reference, 0.169650) and the
    // same grasp with the origin moved onto and beyond a hull facet.
    let cube = [
        Contact::new(v(0.5, 0.0, 0.0), v(-1.0, 0.0, 0.0)),
        Contact::new(v(-0.5, 0.0, 0.0), v(1.0, 0.0, 0.0)),
        Contact::new(v(0.0, 0.5, 0.0), v(0.0, -1.0, 0.0)),
        Contact::new(v(0.0, -0.5, 0.0), v(0.0, 1.0, 0.0)),
    ];
    let w = wrenches(&cube, &Vector3::zeros(), &settings(0.5, 8));
    let q = same(&w, "cube sides");
    assert!((q.epsilon - 0.169650).abs() < 1e-6, "{}", q.epsilon);
    let full = manyhands::grasp::ConvexHull::new(&w).expect("hull");
    let f = full
        .facets()
        .iter()
        .min_by(|a, b| a.offset.total_cmp(&b.offset))
        .copied()
        .expect("facet");
    for (k, t) in [0.5, 0.999, 1.0, 1.001, 1.5, 3.0].into_iter().enumerate() {
        // Shift every wrench by −t·ε·n: the origin moves toward the nearest facet, onto it at
        // t = 1 and outside beyond.
        let d = t * q.epsilon;
        let moved: Vec<Point6> = w
            .iter()
            .map(|p| std::array::from_fn(|i| p[i] - d * f.normal[i]))
            .collect();
        let m = same(&moved, &format!("cube shifted {k} (t = {t})"));
        assert_eq!(m.force_closure, t < 0.999_999, "t = {t}: {}", m.epsilon);
    }
    // Far outside: every wrench translated by a large force.
    let far: Vec<Point6> = w
        .iter()
        .map(|p| {
            let mut p = *p;
            p[2] += 5.0;
            p
        })
        .collect();
    assert!(!same(&far, "far outside").force_closure);
    // Rank 5 (two opposite contacts) and flat sets.
    let two = [cube[0], cube[1]];
    assert_eq!(
        same(
            &wrenches(&two, &Vector3::zeros(), &settings(0.5, 8)),
            "two contacts"
        )
        .rank,
        5
    );
}
