//! The f32 sphere checker against the exact f64 checker on MotionBenchMaker scenes: never "free"
//! where exact collides, "free" wherever exact is free by more than the sphere model's margin;
//! 8-lane segment checks agree with state-by-state checks.

use std::path::PathBuf;
use std::sync::Arc;

use manyhands::collision::{AutoChecker, CollisionChecker, ExactChecker, SphereChecker};
use manyhands::planning::mbm::MbmFile;
use manyhands::Robot;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn mbm(p: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/benchmarks/mbm")
        .join(p)
}

fn robot(name: &str) -> Arc<Robot> {
    Arc::new(
        Robot::from_files(
            &mbm(&format!("{name}/{name}_spherized.urdf")),
            Some(&mbm(&format!("{name}/{name}.srdf"))),
        )
        .expect("robot"),
    )
}

/// Random configurations, half uniform in the limits, half near the problem's start and goals
/// (where contacts are close); returns (exact collisions, exact free with margin).
fn compare(name: &str, per_problem: usize, padding: f64) -> (usize, usize, usize) {
    let r = robot(name);
    let file = MbmFile::load(&mbm(&format!("{name}/problems.json"))).expect("problems");
    let vars = file.joint_vars(&r).expect("vars");
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let (mut hits, mut clear, mut total) = (0, 0, 0);
    for set in &file.sets {
        for p in set.problems.iter().filter(|p| p.valid).take(3) {
            let world = p.world(r.clone());
            let mut sc = SphereChecker::new(&world, padding).expect("a sphere robot");
            let margin = sc.max_overapproximation();
            assert!(margin < 2.0 * padding + 1e-3);
            let mut exact = ExactChecker::new(&world);
            let base = r.zero_config();
            let anchors: Vec<&Vec<f64>> = std::iter::once(&p.start).chain(&p.goals).collect();
            for k in 0..per_problem {
                let mut q = base.clone();
                for (i, &v) in vars.iter().enumerate() {
                    let l = r.var_limits(v);
                    q[v] = if k % 2 == 0 {
                        rng.random_range(l.lower..=l.upper)
                    } else {
                        let a = anchors[k / 2 % anchors.len()][i];
                        (a + rng.random_range(-0.3..0.3)).clamp(l.lower, l.upper)
                    };
                }
                total += 1;
                let s = sc.is_free(&q);
                if !exact.is_free(&q) {
                    hits += 1;
                    assert!(
                        !s,
                        "{}[{}]: exact collides, spheres free; q = {q:?}",
                        p.set, p.index
                    );
                } else if exact.is_free_with_margin(&q, margin) {
                    clear += 1;
                    assert!(
                        s,
                        "{}[{}]: exact free by > {margin}, spheres collide ({:?}); q = {q:?}",
                        p.set,
                        p.index,
                        sc.first_contact(&q)
                    );
                }
                // Start and goals of valid problems are free for the unpadded model.
                if padding == 0.0 && k == 0 {
                    assert!(sc.is_free(&p.start), "{}[{}] start", p.set, p.index);
                }
            }
        }
    }
    (hits, clear, total)
}

#[test]
fn panda_spheres_agree_with_exact() {
    let (hits, clear, total) = compare("panda", 1500, 0.0);
    assert!(
        hits > total / 10 && clear > total / 10,
        "{hits} {clear} {total}"
    );
}

#[test]
fn panda_padded_spheres_are_conservative() {
    let (hits, clear, total) = compare("panda", 300, 0.005);
    assert!(hits > 0 && clear > 0, "{hits} {clear} {total}");
}

#[test]
fn baxter_spheres_agree_with_exact() {
    let (hits, clear, total) = compare("baxter", 1500, 0.0);
    assert!(
        hits > total / 10 && clear > total / 10,
        "{hits} {clear} {total}"
    );
}

#[test]
fn segment_check_equals_state_by_state() {
    let r = robot("panda");
    let file = MbmFile::load(&mbm("panda/problems.json")).expect("problems");
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for set in &file.sets {
        let p = set.problems.iter().find(|p| p.valid).expect("valid");
        let world = p.world(r.clone());
        let mut sc = SphereChecker::new(&world, 0.0).expect("spheres");
        let mut single = sc.clone();
        for _ in 0..200 {
            let g = &p.goals[rng.random_range(0..p.goals.len())];
            let a: Vec<f64> = p
                .start
                .iter()
                .map(|v| v + rng.random_range(-0.5..0.5))
                .collect();
            let b: Vec<f64> = g.iter().map(|v| v + rng.random_range(-0.5..0.5)).collect();
            let n = rng.random_range(1..60);
            let each = (1..=n).all(|k| {
                let t = k as f64 / n as f64;
                let q: Vec<f64> = a.iter().zip(&b).map(|(x, y)| x + (y - x) * t).collect();
                single.is_free(&q)
            });
            assert_eq!(sc.segment_free(&a, &b, n), each, "{} n = {n}", p.set);
        }
    }
}

#[test]
fn auto_checker_picks_spheres_for_sphere_robots() {
    let r = robot("panda");
    let file = MbmFile::load(&mbm("panda/problems.json")).expect("problems");
    let world = file.sets[0].problems[0].world(r);
    assert_eq!(AutoChecker::new(&world, 0.0).kind(), "spheres");
}
