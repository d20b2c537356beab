//! The analytic S-R-S IK never answers "no solution" for a pose that is reachable within the
//! joint limits: poses from FK of random configurations of the shipped robots' arms, solved with
//! the default 36 swivel steps (`manyhands ik`, `POST /v1/ik`).

use std::f64::consts::PI;
use std::path::PathBuf;

use manyhands::kinematics::srs::{SolutionOrder, SrsArm};
use manyhands::Robot;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn robot(name: &str) -> Robot {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("robots");
    Robot::from_files(
        &dir.join(format!("{name}.urdf")),
        Some(&dir.join(format!("{name}.srdf"))),
    )
    .expect("shipped robot loads")
}

/// A random configuration of the arm's joints within their limits (the rest zero).
fn random_config(r: &Robot, arm: &SrsArm, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let mut q = r.zero_config();
    for &v in arm.vars() {
        let l = r.var_limits(v);
        q[v] = if l.bounded {
            rng.random_range(l.lower..=l.upper)
        } else {
            rng.random_range(-PI..PI)
        };
    }
    q
}

const ARMS: [(&str, &str); 4] = [
    ("armar", "right_arm"),
    ("armar", "left_arm"),
    ("justin", "right_arm"),
    ("justin", "left_arm"),
];

#[test]
fn every_reachable_pose_gets_a_solution_at_36_swivel_steps() {
    const POSES: usize = 10_000;
    for (name, group) in ARMS {
        let r = robot(name);
        let arm = SrsArm::from_group(&r, group).expect("S-R-S arm");
        let chain = arm.chain().clone();
        let mut rng = ChaCha8Rng::seed_from_u64(26);
        let mut out = [[0.0; 7]; 8];
        let (mut uniform_misses, mut misses) = (0, 0);
        for _ in 0..POSES {
            let q = random_config(&r, &arm, &mut rng);
            let t = chain.tip_pose(&r, &q);
            // What the plain 36-step sweep finds (the solver before the limit angles).
            if (0..36).all(|i| arm.solve(&t, -PI + 2.0 * PI * i as f64 / 36.0, &mut out) == 0) {
                uniform_misses += 1;
            }
            let sols = arm.solve_enumerate(&t, 36, SolutionOrder::AsFound, &mut rng);
            if sols.is_empty() {
                misses += 1;
            }
            for s in &sols {
                assert!(arm.within_limits(s), "{name}/{group}: {s:?} outside limits");
                let mut qs = q.clone();
                arm.to_config(s, &mut qs);
                let p = chain.tip_pose(&r, &qs);
                assert!(
                    (p.translation.vector - t.translation.vector).norm() < 1e-8
                        && p.rotation.angle_to(&t.rotation) < 1e-8,
                    "{name}/{group}: {s:?} misses the target"
                );
            }
        }
        println!(
            "{name}/{group}: {POSES} reachable poses, 36 uniform swivel steps miss {uniform_misses}, solve_enumerate misses {misses}"
        );
        assert_eq!(
            misses, 0,
            "{name}/{group}: reachable poses without a solution"
        );
    }
}

/// Between two consecutive limit angles the feasibility does not change: a dense ψ scan agrees
/// with the interval's middle everywhere except within 1e-6 rad of the interval ends.
#[test]
fn feasibility_is_constant_between_limit_angles() {
    for (name, group) in ARMS {
        let r = robot(name);
        let arm = SrsArm::from_group(&r, group).expect("S-R-S arm");
        let chain = arm.chain().clone();
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut out = [[0.0; 7]; 8];
        let (mut scanned, mut narrow) = (0usize, 0usize);
        for _ in 0..200 {
            let q = random_config(&r, &arm, &mut rng);
            let t = chain.tip_pose(&r, &q);
            let prepared = arm.prepare(&t);
            let crit = arm.limit_psi(&prepared);
            let feasible = |psi: f64, out: &mut [[f64; 7]; 8]| arm.solve(&t, psi, out) > 0;
            if crit.is_empty() {
                continue;
            }
            for (k, &lo) in crit.iter().enumerate() {
                let hi = crit.get(k + 1).copied().unwrap_or(crit[0] + 2.0 * PI);
                if hi - lo < 2.0 * PI / 36.0 {
                    narrow += 1;
                }
                let wrap = |x: f64| if x >= PI { x - 2.0 * PI } else { x };
                let expect = feasible(wrap(0.5 * (lo + hi)), &mut out);
                let n = 50;
                for i in 1..n {
                    let psi = lo + (hi - lo) * i as f64 / n as f64;
                    if psi - lo < 1e-6 || hi - psi < 1e-6 {
                        continue;
                    }
                    scanned += 1;
                    assert_eq!(
                        feasible(wrap(psi), &mut out),
                        expect,
                        "{name}/{group}: feasibility changes at ψ = {psi} inside ({lo}, {hi})"
                    );
                }
            }
        }
        println!("{name}/{group}: {scanned} ψ scanned, {narrow} intervals narrower than 10°");
        assert!(scanned > 10_000);
    }
}
