//! Property tests of the kinematics: Jacobians against finite differences, analytic S-R-S IK
//! (round trips, feasible swivel angles, reach), numeric IK, analytic/numeric agreement.
//! All randomness is seeded.

use std::f64::consts::PI;
use std::path::{Path, PathBuf};
use std::time::Instant;

use manyhands::geometry::Pose;
use manyhands::kinematics::{
    pose_error, Chain, IkSettings, NumericIk, SolutionOrder, SrsArm, SrsError,
};
use manyhands::Robot;
use nalgebra::{Point3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A hand-made S-R-S arm with rotated joint origins, offsets along joint axes, an elbow offset,
/// non-orthogonal wrist axes, a rotated TCP and a prismatic lift (for the Jacobian test).
const SRS_URDF: &str = r#"<?xml version="1.0"?>
<robot name="srs_test">
  <link name="world"/>
  <link name="torso"/>
  <link name="l1"/><link name="l2"/><link name="l3"/><link name="l4"/>
  <link name="l5"/><link name="l6"/><link name="l7"/>
  <link name="tcp"/>
  <joint name="lift" type="prismatic">
    <parent link="world"/><child link="torso"/>
    <origin xyz="0.1 -0.2 0.3" rpy="0.1 0.2 0.3"/>
    <axis xyz="0.2 0.1 1"/>
    <limit lower="-0.3" upper="0.5" velocity="1" effort="1"/>
  </joint>
  <joint name="j1" type="revolute">
    <parent link="torso"/><child link="l1"/>
    <origin xyz="0.1 0.25 0.5" rpy="0.3 -0.4 0.2"/>
    <axis xyz="0 0 1"/>
    <limit lower="-2.8" upper="2.8" velocity="1" effort="1"/>
  </joint>
  <joint name="j2" type="revolute">
    <parent link="l1"/><child link="l2"/>
    <origin xyz="0 0 0" rpy="1.5707963267948966 0 0.1"/>
    <axis xyz="1 0 0"/>
    <limit lower="-1.9" upper="1.9" velocity="1" effort="1"/>
  </joint>
  <joint name="j3" type="revolute">
    <parent link="l2"/><child link="l3"/>
    <origin xyz="0 0 0.1" rpy="0 0 0"/>
    <axis xyz="0 0 1"/>
    <limit lower="-2.8" upper="2.8" velocity="1" effort="1"/>
  </joint>
  <joint name="j4" type="revolute">
    <parent link="l3"/><child link="l4"/>
    <origin xyz="0.02 0 0.3" rpy="0 0 0.5"/>
    <axis xyz="0 1 0"/>
    <limit lower="-2.6" upper="2.6" velocity="1" effort="1"/>
  </joint>
  <joint name="j5" type="revolute">
    <parent link="l4"/><child link="l5"/>
    <origin xyz="-0.02 0.01 0.28" rpy="0.2 0 0"/>
    <axis xyz="0 0 1"/>
    <limit lower="-2.8" upper="2.8" velocity="1" effort="1"/>
  </joint>
  <joint name="j6" type="revolute">
    <parent link="l5"/><child link="l6"/>
    <origin xyz="0 0 0" rpy="0 0 0.3"/>
    <axis xyz="0 1 0.25"/>
    <limit lower="-1.8" upper="1.8" velocity="1" effort="1"/>
  </joint>
  <joint name="j7" type="revolute">
    <parent link="l6"/><child link="l7"/>
    <origin xyz="0 0 0.05" rpy="0 0 0"/>
    <axis xyz="0 0 1"/>
    <limit lower="-2.9" upper="2.9" velocity="1" effort="1"/>
  </joint>
  <joint name="tcp_joint" type="fixed">
    <parent link="l7"/><child link="tcp"/>
    <origin xyz="0.03 -0.02 0.12" rpy="1.0 0.2 -0.5"/>
  </joint>
</robot>
"#;

const SRS_SRDF: &str = r#"<?xml version="1.0"?>
<robot name="srs_test">
  <group name="arm"><chain base_link="torso" tip_link="tcp"/></group>
  <group name="lift_arm"><chain base_link="world" tip_link="tcp"/></group>
</robot>
"#;

fn srs_robot() -> Robot {
    Robot::from_strings(SRS_URDF, Some(SRS_SRDF), Path::new(".")).unwrap()
}

fn manifest(p: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(p)
}

/// The suite's own two-arm robot with the Panda's arm kinematics (`tests/robots/twin_arms.py`):
/// a 7-DoF arm that is not S-R-S (offset elbow and wrist).
fn twin_arms() -> Robot {
    Robot::from_files(
        &manifest("tests/robots/twin_arms.urdf"),
        Some(&manifest("tests/robots/twin_arms.srdf")),
    )
    .expect("tests/robots/twin_arms.urdf + .srdf must load")
}

fn armar() -> Robot {
    Robot::from_files(
        &manifest("robots/armar.urdf"),
        Some(&manifest("robots/armar.srdf")),
    )
    .expect("robots/armar.urdf + .srdf must load")
}

fn justin() -> Robot {
    Robot::from_files(
        &manifest("robots/justin.urdf"),
        Some(&manifest("robots/justin.srdf")),
    )
    .expect("robots/justin.urdf + .srdf must load")
}

/// All S-R-S arms under test: (label, robot, group).
fn srs_arms() -> Vec<(String, Robot, &'static str)> {
    let mut v = vec![("srs_test/arm".to_string(), srs_robot(), "arm")];
    for (name, r) in [("armar", armar()), ("justin", justin())] {
        for g in ["left_arm", "right_arm"] {
            v.push((format!("{name}/{g}"), r.clone(), g));
        }
    }
    v
}

fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

/// Zero configuration with the given variables random within their limits.
fn random_config(robot: &Robot, vars: &[usize], rng: &mut ChaCha8Rng) -> Vec<f64> {
    let mut q = robot.zero_config();
    for &v in vars {
        let l = robot.var_limits(v);
        q[v] = if l.bounded {
            rng.random_range(l.lower..=l.upper)
        } else {
            rng.random_range(-PI..PI)
        };
    }
    q
}

/// Rotation vector of a unit quaternion, accurate for tiny angles.
fn rotvec(q: &UnitQuaternion<f64>) -> Vector3<f64> {
    let (mut w, mut v) = (q.scalar(), q.imag());
    if w < 0.0 {
        w = -w;
        v = -v;
    }
    let s = v.norm();
    if s < 1e-300 {
        return v * 2.0;
    }
    v * (2.0 * s.atan2(w) / s)
}

fn assert_exact(label: &str, got: &Pose, want: &Pose, tol: f64) {
    let (ep, er) = pose_error(got, want);
    assert!(
        ep <= tol && er <= tol,
        "{label}: FK error {ep:.3e} m, {er:.3e} rad exceeds {tol:.0e}"
    );
}

fn jacobian_check(label: &str, robot: &Robot, chain: &Chain, samples: usize, seed: u64) {
    let mut r = rng(seed);
    let h = 1e-6;
    let mut worst = 0.0f64;
    for _ in 0..samples {
        let q = random_config(robot, &chain.vars, &mut r);
        let jac = chain.jacobian(robot, &q);
        assert_eq!(jac.ncols(), chain.vars.len());
        if chain.base_link == 0 {
            // The root-to-tip path's matrix pass (the J+ steps' Jacobian) gives the same.
            let path = manyhands::kinematics::FkPath::new(robot, chain.tip_link);
            let cols = path.jacobian_columns(&chain.vars);
            let mut pj = nalgebra::Matrix6xX::zeros(chain.vars.len());
            let f = path.jacobian_into(&q, &cols, &mut pj);
            let diff = (&pj - &jac).abs().max();
            assert!(
                diff <= 1e-12,
                "{label}: FkPath Jacobian differs by {diff:e}"
            );
            let tip = chain.tip_pose(robot, &q).translation.vector;
            assert!((f.t - tip).norm() <= 1e-12, "{label}: FkPath tip frame");
        }
        for (c, &v) in chain.vars.iter().enumerate() {
            let mut qp = q.clone();
            let mut qm = q.clone();
            qp[v] += h;
            qm[v] -= h;
            let tp = chain.tip_pose(robot, &qp);
            let tm = chain.tip_pose(robot, &qm);
            let lin = (tp.translation.vector - tm.translation.vector) / (2.0 * h);
            let ang = rotvec(&(tp.rotation * tm.rotation.inverse())) / (2.0 * h);
            for i in 0..3 {
                let e1 = (jac[(i, c)] - lin[i]).abs();
                let e2 = (jac[(i + 3, c)] - ang[i]).abs();
                worst = worst.max(e1).max(e2);
                assert!(
                    e1 <= 1e-6 && e2 <= 1e-6,
                    "{label}: Jacobian column {c} ({}) row {i}: lin {} vs fd {}, ang {} vs fd {}",
                    robot.var_name(v),
                    jac[(i, c)],
                    lin[i],
                    jac[(i + 3, c)],
                    ang[i]
                );
            }
        }
    }
    println!("{label}: Jacobian vs central differences, worst {worst:.2e}");
}

#[test]
fn jacobian_matches_finite_differences() {
    let p = twin_arms();
    jacobian_check(
        "twin_arms/left_arm",
        &p,
        &Chain::from_group(&p, "left_arm").unwrap(),
        100,
        1,
    );
    let s = srs_robot();
    jacobian_check(
        "srs arm",
        &s,
        &Chain::from_group(&s, "arm").unwrap(),
        100,
        2,
    );
    let lift = Chain::from_group(&s, "lift_arm").unwrap();
    assert_eq!(
        lift.vars.len(),
        8,
        "lift_arm has the prismatic lift + 7 joints"
    );
    jacobian_check("srs lift_arm (prismatic)", &s, &lift, 100, 3);
    let a = armar();
    let whole = Chain::new(&a, 0, a.link("left_tcp").unwrap()).unwrap();
    assert!(
        whole.vars.len() >= 12,
        "armar root→left_tcp includes the mobile base"
    );
    jacobian_check("armar root→left_tcp (prismatic base)", &a, &whole, 50, 4);
    let right = Chain::new(&a, 0, a.link("right_tcp").unwrap()).unwrap();
    jacobian_check("armar root→right_tcp", &a, &right, 50, 5);
    let tip = Chain::from_group(&p, "left_arm").unwrap().tip_link;
    jacobian_check(
        "twin_arms root→left tip",
        &p,
        &Chain::new(&p, 0, tip).unwrap(),
        50,
        6,
    );
    let tip = lift.tip_link;
    jacobian_check(
        "srs root→lift_arm tip",
        &s,
        &Chain::new(&s, 0, tip).unwrap(),
        50,
        7,
    );
}

#[test]
fn srs_fk_matches_chain() {
    for (label, robot, group) in srs_arms() {
        let arm = SrsArm::from_group(&robot, group).unwrap();
        let mut r = rng(5);
        for _ in 0..50 {
            let q = random_config(&robot, arm.vars(), &mut r);
            let q7 = arm.from_config(&q);
            assert_exact(
                &label,
                &arm.fk(&q7),
                &arm.chain().tip_pose(&robot, &q),
                1e-12,
            );
        }
    }
}

#[test]
fn analytic_round_trip() {
    for (label, robot, group) in srs_arms() {
        let arm = SrsArm::from_group(&robot, group).unwrap();
        let chain = arm.chain().clone();
        let mut r = rng(10);
        let n = if label.starts_with("srs_test") {
            2000
        } else {
            1000
        };
        let mut total_solutions = 0;
        let mut out = [[0.0; 7]; 8];
        for _ in 0..n {
            let q = random_config(&robot, arm.vars(), &mut r);
            let q7 = arm.from_config(&q);
            let t = chain.tip_pose(&robot, &q);
            let psi = arm.arm_angle(&q7);
            assert!((-PI..=PI).contains(&psi));
            let ns = arm.solve(&t, psi, &mut out);
            total_solutions += ns;
            let found = out[..ns]
                .iter()
                .any(|s| s.iter().zip(&q7).all(|(a, b)| (a - b).abs() <= 1e-8));
            assert!(
                found,
                "{label}: q = {q7:?} (ψ = {psi}) not among the {ns} solutions {:?}",
                &out[..ns]
            );
            for s in &out[..ns] {
                assert!(
                    arm.within_limits(s),
                    "{label}: solution {s:?} outside limits"
                );
                let mut qs = q.clone();
                arm.to_config(s, &mut qs);
                assert_exact(&label, &chain.tip_pose(&robot, &qs), &t, 1e-9);
            }
        }
        println!(
            "{label}: {n} round trips ok, {:.2} solutions per call on average",
            total_solutions as f64 / n as f64
        );
    }
}

/// Wrist-centre target of a tip pose.
fn wrist_target(arm: &SrsArm, t: &Pose) -> Vector3<f64> {
    let tip0 = arm.fk(&[0.0; 7]);
    (t * (tip0.inverse() * Point3::from(arm.wrist_centre()))).coords
}

/// The same orientation, translated so that the wrist centre is at distance `dist` from the
/// shoulder along the same direction.
fn with_wrist_distance(arm: &SrsArm, t: &Pose, dist: f64) -> Pose {
    let s = arm.shoulder_centre();
    let wt = wrist_target(arm, t);
    let new_wt = s + (wt - s).normalize() * dist;
    let mut t2 = *t;
    t2.translation.vector += new_wt - wt;
    t2
}

#[test]
fn analytic_feasible_psi_and_reach() {
    for (label, robot, group) in srs_arms() {
        let arm = SrsArm::from_group(&robot, group).unwrap();
        let chain = arm.chain().clone();
        let mut r = rng(20);
        let (mut psi_in, mut tried, mut with_sol) = (0, 0, 0);
        for _ in 0..100 {
            let q = random_config(&robot, arm.vars(), &mut r);
            let t = chain.tip_pose(&robot, &q);
            let psi_q = arm.arm_angle(&arm.from_config(&q));
            let iv = arm.feasible_psi(&t, 72);
            assert!(iv.iter().all(|&(a, b)| -PI <= a && a <= b && b <= PI));
            if iv
                .iter()
                .any(|&(a, b)| a - 1e-6 <= psi_q && psi_q <= b + 1e-6)
            {
                psi_in += 1;
            }
            for &(a, b) in &iv {
                for _ in 0..5 {
                    let psi = if b > a { r.random_range(a..b) } else { a };
                    let sols = arm.solve_all(&t, psi);
                    tried += 1;
                    with_sol += (!sols.is_empty()) as usize;
                    for s in &sols {
                        assert!(arm.within_limits(s), "{label}: {s:?} outside limits");
                        let mut qs = q.clone();
                        arm.to_config(s, &mut qs);
                        assert_exact(&label, &chain.tip_pose(&robot, &qs), &t, 1e-9);
                    }
                }
            }
            // Beyond reach: no solution, no panic, no NaN.
            let far = with_wrist_distance(&arm, &t, arm.reach() + 0.05);
            assert_eq!(arm.solve_all(&far, psi_q).len(), 0, "{label}: beyond reach");
            assert!(arm.feasible_psi(&far, 16).is_empty());
            let mut rr = rng(0);
            assert!(arm
                .solve_enumerate(&far, 16, SolutionOrder::Random, &mut rr)
                .is_empty());
        }
        println!(
            "{label}: ψ(q) inside a feasible interval for {psi_in}/100 targets; random ψ in the intervals had solutions {with_sol}/{tried}"
        );
        assert!(
            psi_in >= 97,
            "{label}: ψ(q) in feasible intervals only {psi_in}/100"
        );
        assert!(
            with_sol as f64 >= 0.95 * tried as f64,
            "{label}: {with_sol}/{tried} ψ samples in intervals had solutions"
        );
        // NaN / garbage input.
        let mut bad = Pose::identity();
        bad.translation.vector.x = f64::NAN;
        assert_eq!(arm.solve_all(&bad, 0.0).len(), 0);
        assert_eq!(arm.solve_all(&Pose::identity(), f64::NAN).len(), 0);
    }
}

#[test]
fn analytic_stretched_arm() {
    // Justin's and Armar's elbows are stretched at 0.
    for (label, robot, group) in srs_arms().into_iter().skip(1) {
        let arm = SrsArm::from_group(&robot, group).unwrap();
        let chain = arm.chain().clone();
        let mut r = rng(30);
        for _ in 0..200 {
            let mut q = random_config(&robot, arm.vars(), &mut r);
            q[arm.vars()[3]] = 0.0;
            let q7 = arm.from_config(&q);
            let t = chain.tip_pose(&robot, &q);
            let dist = (wrist_target(&arm, &t) - arm.shoulder_centre()).norm();
            assert!((dist - arm.reach()).abs() < 1e-12, "{label}: not stretched");
            let sols = arm.solve_all(&t, arm.arm_angle(&q7));
            assert!(
                sols.len() <= 4,
                "{label}: stretched arm has one elbow branch"
            );
            assert!(
                sols.iter()
                    .any(|s| s.iter().zip(&q7).all(|(a, b)| (a - b).abs() <= 1e-8)),
                "{label}: stretched q {q7:?} not found in {sols:?}"
            );
            for s in &sols {
                let mut qs = q.clone();
                arm.to_config(s, &mut qs);
                assert_exact(&label, &chain.tip_pose(&robot, &qs), &t, 1e-9);
            }
        }
    }
}

#[test]
fn analytic_enumerate_orders() {
    let robot = justin();
    let arm = SrsArm::from_group(&robot, "left_arm").unwrap();
    let mut r = rng(40);
    let q = random_config(&robot, arm.vars(), &mut r);
    let q7 = arm.from_config(&q);
    let t = arm.fk(&q7);
    let all = arm.solve_enumerate(&t, 64, SolutionOrder::AsFound, &mut r);
    assert!(!all.is_empty());
    let near = arm.solve_enumerate(&t, 64, SolutionOrder::NearestTo(q7), &mut r);
    assert_eq!(near.len(), all.len());
    let d = |s: &[f64; 7]| -> f64 { s.iter().zip(&q7).map(|(a, b)| (a - b).powi(2)).sum() };
    assert!(near.windows(2).all(|w| d(&w[0]) <= d(&w[1])));
    let shuffled = arm.solve_enumerate(&t, 64, SolutionOrder::Random, &mut r);
    assert_eq!(shuffled.len(), all.len());
    assert_ne!(shuffled, all);
}

#[test]
fn numeric_converges() {
    let p = twin_arms();
    let s = srs_robot();
    let j = justin();
    let cases: Vec<(&str, &Robot, Chain, bool, usize)> = vec![
        (
            "twin_arms/left_arm",
            &p,
            Chain::from_group(&p, "left_arm").unwrap(),
            false,
            100,
        ),
        (
            "srs arm",
            &s,
            Chain::from_group(&s, "arm").unwrap(),
            false,
            100,
        ),
        (
            "srs lift_arm",
            &s,
            Chain::from_group(&s, "lift_arm").unwrap(),
            false,
            50,
        ),
        (
            "justin left_arm",
            &j,
            Chain::from_group(&j, "left_arm").unwrap(),
            false,
            50,
        ),
        // 3-DoF finger, position only.
        (
            "justin left_index",
            &j,
            Chain::from_group(&j, "left_index").unwrap(),
            true,
            100,
        ),
    ];
    for (label, robot, chain, position_only, n) in cases {
        if position_only {
            assert_eq!(chain.vars.len(), 3);
        }
        let mut ik = NumericIk::new(robot, &chain);
        ik.settings = IkSettings {
            position_only,
            ..IkSettings::default()
        };
        let mut r = rng(50);
        let mut attempts = 0;
        let mut iters = 0;
        for _ in 0..n {
            let q = random_config(robot, &chain.vars, &mut r);
            let t = chain.tip_pose(robot, &q);
            let seed = random_config(robot, &chain.vars, &mut r);
            let sol = ik
                .solve(&t, &seed, &mut r)
                .unwrap_or_else(|e| panic!("{label}: {e}"));
            attempts += ik.stats.attempts;
            iters += ik.stats.iterations;
            robot.check_config(&sol).unwrap();
            let got = chain.tip_pose(robot, &sol);
            if position_only {
                let e = (got.translation.vector - t.translation.vector).norm();
                assert!(e <= 1e-9, "{label}: position error {e:.3e}");
            } else {
                assert_exact(label, &got, &t, 1e-9);
            }
            // Values outside the chain are kept from the seed.
            for v in 0..robot.dof() {
                if !chain.vars.contains(&v) {
                    assert_eq!(sol[v], seed[v]);
                }
            }
        }
        println!(
            "{label}: {n} numeric solves ok, {:.2} attempts and {:.1} iterations per solve",
            attempts as f64 / n as f64,
            iters as f64 / n as f64
        );
    }
}

#[test]
fn numeric_failure_reports() {
    let s = srs_robot();
    let chain = Chain::from_group(&s, "arm").unwrap();
    let arm = SrsArm::new(&s, &chain).unwrap();
    let mut ik = NumericIk::new(&s, &chain);
    ik.settings.max_restarts = 3;
    let mut r = rng(60);
    let q = random_config(&s, &chain.vars, &mut r);
    let far = with_wrist_distance(&arm, &chain.tip_pose(&s, &q), arm.reach() + 0.2);
    let e = ik.solve(&far, &q, &mut r).unwrap_err();
    assert_eq!(e.attempts, 4);
    assert!(e.best_position_error > 0.1 && e.best_position_error.is_finite());
    assert_eq!(e.best.len(), s.dof());
    assert!(e.to_string().contains("did not converge"));
}

#[test]
fn analytic_and_numeric_agree() {
    let robot = srs_robot();
    let arm = SrsArm::from_group(&robot, "arm").unwrap();
    let chain = arm.chain().clone();
    let mut ik = NumericIk::new(&robot, &chain);
    let mut r = rng(70);
    let (mut fk_disagree, mut far_disagree) = (Vec::new(), Vec::new());
    for i in 0..200 {
        let q = random_config(&robot, arm.vars(), &mut r);
        let mut t = chain.tip_pose(&robot, &q);
        let reachable_by_construction = i % 2 == 0;
        if !reachable_by_construction {
            let d = arm.reach() + 0.05 + r.random_range(0.0..0.3);
            // Wrist centre at least 5 cm beyond the maximal shoulder–wrist distance.
            t = with_wrist_distance(&arm, &t, d);
        }
        let analytic = !arm
            .solve_enumerate(&t, 64, SolutionOrder::AsFound, &mut r)
            .is_empty();
        let seed = random_config(&robot, arm.vars(), &mut r);
        let numeric = ik.solve(&t, &seed, &mut r);
        if let Ok(sol) = &numeric {
            assert_exact("numeric", &chain.tip_pose(&robot, sol), &t, 1e-9);
        }
        let numeric = numeric.is_ok();
        if analytic != numeric {
            if reachable_by_construction {
                fk_disagree.push((i, analytic, numeric));
            } else {
                far_disagree.push((i, analytic, numeric));
            }
        }
        if reachable_by_construction {
            assert!(analytic, "target {i} (FK of {q:?}) not found analytically");
        } else {
            assert!(
                !analytic && !numeric,
                "target {i} beyond reach found reachable"
            );
        }
    }
    assert!(
        fk_disagree.is_empty() && far_disagree.is_empty(),
        "disagreements (target, analytic, numeric): FK-generated {fk_disagree:?}, beyond reach {far_disagree:?}"
    );
}

#[test]
fn srs_errors_name_the_reason() {
    let p = twin_arms();
    let chain = Chain::from_group(&p, "left_arm").unwrap();
    let e = SrsArm::new(&p, &chain).unwrap_err();
    let msg = e.to_string();
    println!("twin_arms/left_arm: {msg}");
    assert!(msg.contains("not an S-R-S arm"), "{msg}");
    assert!(
        matches!(e, SrsError::NotIntersecting { part: "wrist", .. }),
        "{e:?}"
    );
    let s = srs_robot();
    let e = SrsArm::from_group(&s, "lift_arm").unwrap_err();
    assert!(matches!(e, SrsError::JointCount { found: 8, .. }), "{e:?}");
    assert!(e.to_string().contains("not an S-R-S arm"));
    assert!(matches!(
        SrsArm::from_group(&s, "nope"),
        Err(SrsError::NoChain(_))
    ));
}

/// Prints median timings (run with `--nocapture`); asserts nothing about time.
#[test]
fn timing_report() {
    let robot = justin();
    let arm = SrsArm::from_group(&robot, "left_arm").unwrap();
    let chain = arm.chain().clone();
    let mut r = rng(80);
    // Targets with all 8 solutions at ψ(q).
    let mut targets = Vec::new();
    let mut out = [[0.0; 7]; 8];
    while targets.len() < 200 {
        let q = random_config(&robot, arm.vars(), &mut r);
        let q7 = arm.from_config(&q);
        let t = arm.fk(&q7);
        let psi = arm.arm_angle(&q7);
        if arm.solve(&t, psi, &mut out) == 8 {
            targets.push((t, psi, q));
        }
    }
    let mut times = Vec::new();
    let mut count = 0;
    for (t, psi, _) in &targets {
        let start = Instant::now();
        for _ in 0..20 {
            count += arm.solve(std::hint::black_box(t), *psi, &mut out);
        }
        times.push(start.elapsed().as_secs_f64() / 20.0);
    }
    times.sort_by(f64::total_cmp);
    println!(
        "SrsArm::solve (justin left_arm, 8 solutions): median {:.2} µs per call ({count} solutions)",
        times[times.len() / 2] * 1e6
    );
    let mut ik = NumericIk::new(&robot, &chain);
    let mut times = Vec::new();
    for (t, _, _) in &targets {
        let seed = random_config(&robot, arm.vars(), &mut r);
        let start = Instant::now();
        let ok = ik.solve(t, &seed, &mut r).is_ok();
        times.push(start.elapsed().as_secs_f64());
        assert!(ok);
    }
    times.sort_by(f64::total_cmp);
    println!(
        "NumericIk::solve (justin left_arm, random seed): median {:.1} µs per call, {} iterations in the last call",
        times[times.len() / 2] * 1e6,
        ik.stats.iterations
    );
}

/// `FkPathPair::poses` (the hand-off goal sampler's TCP and other arm base from one pass) gives
/// bit for bit the two `FkPath::pose` calls, on ARMAR's right TCP with the left arm's base
/// (shared base and hip); a path that does not start with the other's joints pairs with none.
#[test]
fn path_pair_poses_equal_the_two_paths() {
    use manyhands::kinematics::randomized::ArmChain;
    use manyhands::kinematics::FkPath;
    let robot = armar();
    let right = ArmChain::new(&robot, "torso_right_arm").expect("right arm");
    let left = ArmChain::new(&robot, "torso_left_arm").expect("left arm");
    let tcp = FkPath::new(&robot, right.chain.tip_link);
    let pair = tcp
        .with_prefix(&left.base_path)
        .expect("the hip starts the TCP path");
    let vars: Vec<usize> = (0..robot.dof()).collect();
    let mut r = rng(27);
    for _ in 0..200 {
        let q = random_config(&robot, &vars, &mut r);
        let (a, b) = pair.poses(&q);
        assert_eq!(a, tcp.pose(&q));
        assert_eq!(b, left.base_path.pose(&q));
    }
    let left_tcp = FkPath::new(&robot, left.chain.tip_link);
    assert!(left_tcp.with_prefix(&tcp).is_none());
    let whole = left
        .base_path
        .with_prefix(&left.base_path)
        .expect("a path starts itself");
    let q = random_config(&robot, &vars, &mut r);
    let base = left.base_path.pose(&q);
    assert_eq!(whole.poses(&q), (base, base));
}
