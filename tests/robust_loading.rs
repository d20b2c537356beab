//! Robust loading of real robot descriptions (issue 28, item 2): a robot whose SRDF lacks a
//! link pair that collides in every configuration, and problems whose joint values sit at ±π
//! (or a few µrad outside a limit), are planned instead of refused. The robots are the
//! suite's sphere robot `tests/robots/twin_arms.urdf` modified here and written to a
//! temporary folder.

#[path = "common/tmp.rs"]
mod tmp;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use rand::SeedableRng;

use manyhands::collision::{always, AutoChecker, CollisionChecker, CollisionWorld, ExactChecker};
use manyhands::geometry::Pose;
use manyhands::planning::{
    JointSpace, PlanError, RrtConnect, RrtConnectSettings, SpaceValidator, Termination,
};
use manyhands::Robot;

/// The URDF limit of a continuous joint written as revolute (5 digits of π, as real URDFs).
#[allow(clippy::approx_constant)]
const LIMIT_PI: f64 = 3.14159;

fn robots_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/robots")
}

fn read(name: &str) -> String {
    std::fs::read_to_string(robots_dir().join(name)).expect("twin_arms files")
}

/// A fresh temporary folder for this test.
fn temp_dir(tag: &str) -> PathBuf {
    let d = tmp::run_root().join(format!("manyhands-robust-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("temp dir");
    d
}

fn write_robot(dir: &Path, urdf: &str, srdf: &str) -> (PathBuf, PathBuf) {
    let (u, s) = (dir.join("robot.urdf"), dir.join("robot.srdf"));
    std::fs::write(&u, urdf).expect("write urdf");
    std::fs::write(&s, srdf).expect("write srdf");
    (u, s)
}

/// The left arm's variables of `robot`.
fn left_arm(robot: &Robot) -> Vec<usize> {
    robot.group("left_arm").expect("left_arm").vars.clone()
}

/// A collision-free configuration of the left arm (others at `ready`), by seeded sampling;
/// `fix` = (variable, value) is held (the test of freedom uses the value clamped into the
/// limits).
fn free_config(
    world: &CollisionWorld,
    robot: &Robot,
    vars: &[usize],
    seed: u64,
    fix: Option<(usize, f64)>,
) -> Vec<f64> {
    let mut exact = ExactChecker::new(world);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut q = robot.named_config("ready").expect("ready");
    for _ in 0..10_000 {
        robot.sample_vars(vars, &mut q, &mut rng);
        if let Some((v, x)) = fix {
            q[v] = x;
        }
        let mut c = q.clone();
        robot.clamp_config(&mut c);
        if exact.is_free(&c) {
            return q;
        }
    }
    panic!("no free configuration found");
}

/// Plans `start → goal` (world configurations) in the left arm's space with the planners'
/// sphere checker and certified motions, and re-checks the path exactly.
fn plan(world: &CollisionWorld, vars: &[usize], start: &[f64], goal: &[f64]) -> Vec<Vec<f64>> {
    let base = world.robots[0].robot.named_config("ready").expect("ready");
    let space = JointSpace::new(world, vars, base).expect("space");
    let settings = RrtConnectSettings {
        certify: Some(0.04),
        dynamic_domain: Some(4.0),
        balance: true,
        ..RrtConnectSettings::default()
    };
    let checker = AutoChecker::new(world, 0.0);
    assert_eq!(checker.kind(), "spheres");
    let mut planner =
        RrtConnect::with_checker(space.clone(), world, checker, settings).expect("planner");
    let mut term = Termination::new().with_time_limit(std::time::Duration::from_secs(20));
    let r = planner
        .plan(
            &space.from_world(start),
            &[space.from_world(goal)],
            &mut term,
            7,
        )
        .unwrap_or_else(|e| panic!("planning failed: {e}"));
    let mut exact = SpaceValidator::new(
        space,
        world,
        ExactChecker::new(world),
        0.25f64.to_radians(),
        0.005,
    );
    exact
        .validate_path(&r.path)
        .unwrap_or_else(|k| panic!("exact re-check failed at {k}"));
    r.path
}

#[test]
fn an_srdf_lacking_an_always_colliding_pair_is_planned_with_a_warning() {
    let srdf = read("twin_arms.srdf");
    // left_link3's sphere at (0.08, 0.04, 0) reaches left_link4's at its joint origin
    // (0.0825, 0, 0) in every configuration: the SRDF's only reason not to check them.
    let line = r#"<disable_collisions link1="left_link3" link2="left_link4" reason="Adjacent"/>"#;
    assert!(srdf.contains(line), "twin_arms.srdf changed: {line}");
    let stripped = srdf.replace(line, "");
    let dir = temp_dir("always");
    let (u, s) = write_robot(&dir, &read("twin_arms.urdf"), &stripped);
    let robot = Robot::from_files(&u, Some(&s)).expect("load");
    let (a, b) = (
        robot.link("left_link3").unwrap(),
        robot.link("left_link4").unwrap(),
    );
    assert_eq!(
        robot.always_colliding.len(),
        1,
        "{:?}",
        robot.always_colliding
    );
    let c = robot.always_colliding[0];
    assert_eq!((c.a, c.b), (a.min(b), a.max(b)));
    assert!(c.fraction >= always::MIN_FRACTION, "{}", c.fraction);
    assert!(robot.is_disabled(a, b), "the pair is treated as disabled");
    let want = r#"<disable_collisions link1="left_link3" link2="left_link4" reason="Always"/>"#;
    assert_eq!(always::srdf_line(&robot, &c), want);
    assert!(
        robot.warnings.iter().any(|w| w.contains(want)),
        "{:?}",
        robot.warnings
    );
    // The pair does collide everywhere: without the detection every state is in collision.
    let mut raw = robot.clone();
    let n = raw.links.len();
    raw.disabled[a * n + b] = false;
    raw.disabled[b * n + a] = false;
    let raw_world = CollisionWorld::single(Arc::new(raw), Pose::identity());
    let mut raw_exact = ExactChecker::new(&raw_world);

    let robot = Arc::new(robot);
    let world = CollisionWorld::single(robot.clone(), Pose::identity());
    let vars = left_arm(&robot);
    let start = free_config(&world, &robot, &vars, 1, None);
    let goal = free_config(&world, &robot, &vars, 2, None);
    assert!(!raw_exact.is_free(&start) && !raw_exact.is_free(&goal));
    let path = plan(&world, &vars, &start, &goal);
    assert!(path.len() >= 2);

    // The shipped description itself has no such pair (its loading is unchanged).
    let shipped = Robot::from_files(
        &robots_dir().join("twin_arms.urdf"),
        Some(&robots_dir().join("twin_arms.srdf")),
    )
    .expect("shipped");
    assert!(shipped.always_colliding.is_empty());
    assert!(shipped.is_disabled(a, b), "by its SRDF line");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_continuous_joint_written_as_revolute_pi_is_planned_at_plus_minus_pi() {
    let urdf = read("twin_arms.urdf");
    let old = r#"<joint name="left_joint1" type="revolute"><parent link="left_link0"/><child link="left_link1"/><origin xyz="0 0 0.333" rpy="0 0 0"/><axis xyz="0 0 1"/><limit lower="-2.8973" upper="2.8973""#;
    assert!(urdf.contains(old), "twin_arms.urdf changed");
    let new = old.replace(
        r#"lower="-2.8973" upper="2.8973""#,
        r#"lower="-3.14159" upper="3.14159""#,
    );
    let dir = temp_dir("pi");
    let (u, s) = write_robot(&dir, &urdf.replace(old, &new), &read("twin_arms.srdf"));
    let robot = Arc::new(Robot::from_files(&u, Some(&s)).expect("load"));
    let v = robot.var("left_joint1").unwrap();
    assert!(robot.var_limits(v).is_revolute_pi());
    assert_eq!(
        robot.var_limits(v).upper,
        LIMIT_PI,
        "limits are not changed"
    );
    let world = CollisionWorld::single(robot.clone(), Pose::identity());
    let vars = left_arm(&robot);
    let pi = std::f64::consts::PI;
    let start = free_config(&world, &robot, &vars, 3, Some((v, -pi)));
    let goal = free_config(&world, &robot, &vars, 4, Some((v, pi)));
    let mut exact = ExactChecker::new(&world);
    // Free at the clamped values (the problem's own values lie outside the limits).
    let clamp = |q: &[f64]| {
        let mut c = q.to_vec();
        robot.clamp_config(&mut c);
        c
    };
    assert!(exact.is_free(&clamp(&start)) && exact.is_free(&clamp(&goal)));
    assert!(robot.check_config(&start).is_err(), "π is outside ±3.14159");
    let path = plan(&world, &vars, &start, &goal);
    let k = vars.iter().position(|&w| w == v).unwrap();
    assert_eq!(path[0][k], -LIMIT_PI, "start clamped into the limit");
    assert_eq!(
        path.last().unwrap()[k],
        LIMIT_PI,
        "goal clamped into the limit"
    );

    // Beyond the tolerance it is a clear error naming the joint.
    let base = robot.named_config("ready").unwrap();
    let space = JointSpace::new(&world, &vars, base).unwrap();
    let mut planner = RrtConnect::with_checker(
        space.clone(),
        &world,
        AutoChecker::new(&world, 0.0),
        RrtConnectSettings::default(),
    )
    .unwrap();
    let mut far = space.from_world(&start);
    far[k] = -LIMIT_PI - 2e-5;
    let mut term = Termination::new().with_time_limit(std::time::Duration::from_secs(5));
    match planner.plan(&far, &[space.from_world(&goal)], &mut term, 1) {
        Err(PlanError::InvalidStart { reason }) => {
            assert!(reason.contains("left_joint1"), "{reason}")
        }
        other => panic!("expected InvalidStart, got {other:?}"),
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn values_within_the_tolerance_of_a_limit_are_clamped_farther_are_refused() {
    let robot = Robot::from_files(
        &robots_dir().join("twin_arms.urdf"),
        Some(&robots_dir().join("twin_arms.srdf")),
    )
    .unwrap();
    let v = robot.var("left_joint4").unwrap();
    let l = *robot.var_limits(v);
    assert_eq!(l.clamp_near(l.upper + 0.9e-5), Some(l.upper));
    assert_eq!(l.clamp_near(l.lower - 0.9e-5), Some(l.lower));
    assert_eq!(l.clamp_near(l.upper + 1.1e-5), None);
    assert_eq!(l.clamp_near(f64::NAN), None);
    let mut q = robot.named_config("ready").unwrap();
    q[v] = l.upper + 0.5e-5;
    assert!(robot.check_config(&q).is_err());
    let mut full = q.clone();
    robot.clamp_config(&mut q);
    assert_eq!(q[v], l.upper);
    assert!(robot.check_config(&q).is_ok());
    // A full configuration as a user writes it: accepted within the tolerance, clamped.
    assert!(robot.accept_config(&mut full).is_ok());
    assert_eq!(full[v], l.upper);
    full[v] = l.upper + 2e-5;
    let e = robot.accept_config(&mut full).unwrap_err();
    assert!(e.contains("left_joint4"), "{e}");
}
