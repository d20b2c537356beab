//! The MotionBenchMaker loader and planning on its problems: both problem files load, one Panda
//! problem per set is solved by RRT-Connect and its path verified by the exact checker, and a
//! path through an obstacle is rejected. The benchmark's files are outside the repository
//! (`manyhands::benchmark::mbm_data`: skipped without them); the loader's errors and planning on a
//! problem file in the same form for the suite's own `tests/robots/twin_arms` always run.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use manyhands::benchmark::mbm::{MbmError, MbmFile, MbmProblem};
use manyhands::benchmark::mbm_data::data_for_test;
use manyhands::collision::CollisionWorld;
use manyhands::collision::{CollisionChecker, ExactChecker, FastChecker};
use manyhands::geometry::Shape;
use manyhands::planning::{
    PlanResult, RrtConnect, RrtConnectSettings, SegmentChecker, SpaceValidator, Termination,
};
use manyhands::Robot;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn panda(dir: &Path) -> Arc<Robot> {
    Arc::new(
        Robot::from_files(
            &dir.join("panda/panda_spherized.urdf"),
            Some(&dir.join("panda/panda.srdf")),
        )
        .expect("panda"),
    )
}

fn twin_arms() -> Arc<Robot> {
    let d = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/robots");
    Arc::new(
        Robot::from_files(&d.join("twin_arms.urdf"), Some(&d.join("twin_arms.srdf")))
            .expect("tests/robots/twin_arms"),
    )
}

const RES: f64 = 0.5; // degrees, planning and exact re-check

/// Plans problem `p` of `set` with `planner` (seeded) and checks the path: it starts at the
/// start, ends at the goal it names, and passes the exact checker at `check_rad`.
fn plan_and_check_exactly<C: SegmentChecker>(
    planner: &mut RrtConnect<C>,
    world: &CollisionWorld,
    set: &str,
    p: &MbmProblem,
    seed: u64,
    check_rad: f64,
) -> PlanResult {
    let mut term = Termination::new().with_time_limit(Duration::from_secs(20));
    let r = planner
        .plan(&p.start, &p.goals, &mut term, seed)
        .unwrap_or_else(|e| panic!("{set}[{}]: {e}", p.index));
    assert_eq!(r.path.first(), Some(&p.start));
    assert_eq!(r.path.last(), Some(&p.goals[r.goal_index]));
    let mut exact = SpaceValidator::new(
        planner.space().clone(),
        world,
        ExactChecker::new(world),
        check_rad,
        0.005,
    );
    assert_eq!(exact.validate_path(&r.path), Ok(()), "{set}[{}]", p.index);
    r
}

#[test]
fn loads_both_problem_files() {
    let Some(dir) = data_for_test() else { return };
    let mbm = |p: &str| dir.join(p);
    let p = MbmFile::load(&mbm("panda/problems.json")).expect("panda problems");
    assert_eq!(p.robot, "panda");
    assert_eq!(p.joints.len(), 7);
    let names: Vec<&str> = p.sets.iter().map(|s| s.name.as_str()).collect();
    for s in [
        "table_pick",
        "table_under_pick",
        "box",
        "bookshelf_small",
        "bookshelf_tall",
        "bookshelf_thin",
        "cage",
    ] {
        assert!(names.contains(&s), "{s} missing from {names:?}");
    }
    let total: usize = p.sets.iter().map(|s| s.problems.len()).sum();
    let valid: usize = p
        .sets
        .iter()
        .flat_map(|s| &s.problems)
        .filter(|q| q.valid)
        .count();
    assert_eq!((total, valid), (700, 699));
    let r = panda(&dir);
    assert_eq!(
        p.joint_vars(&r).expect("joints map"),
        (0..7).collect::<Vec<_>>()
    );
    // First box problem: a can (cylinder, length 0.14) and the box's walls.
    let b = &p.set("box").expect("box set").problems[0];
    assert!(b.obstacles.iter().any(|o| o.shape
        == Shape::Cylinder {
            radius: 0.03,
            half_length: 0.07
        }));
    assert!(b
        .obstacles
        .iter()
        .any(|o| matches!(o.shape, Shape::Box { .. })));
    assert_eq!(b.start.len(), 7);
    assert!(!b.goals.is_empty() && b.goals.iter().all(|g| g.len() == 7));

    let x = MbmFile::load(&mbm("baxter/problems.json")).expect("baxter problems");
    assert_eq!(x.joints.len(), 14);
    assert_eq!(x.sets.len(), 3);
    let valid: usize = x
        .sets
        .iter()
        .flat_map(|s| &s.problems)
        .filter(|q| q.valid)
        .count();
    assert_eq!(valid, 1470);
    let baxter = Robot::from_files(
        &mbm("baxter/baxter_spherized.urdf"),
        Some(&mbm("baxter/baxter.srdf")),
    )
    .expect("baxter");
    let vars = x.joint_vars(&baxter).expect("baxter joints map");
    assert_eq!(vars.len(), 14);
    // Every valid Baxter start is collision-free for our checkers (same model as the benchmark).
    let q = x.sets[0]
        .problems
        .iter()
        .find(|q| q.valid)
        .expect("a valid problem");
    let world = q.world(Arc::new(baxter));
    let space = q.space(&world, &vars).expect("space");
    let mut v = SpaceValidator::new(
        space,
        &world,
        ExactChecker::new(&world),
        RES.to_radians(),
        0.005,
    );
    assert_eq!(v.invalidity(&q.start), None);
}

#[test]
fn unknown_joint_and_bad_problems_are_errors() {
    let text =
        r#"{"robot": "twin_arms", "joints": ["left_joint1", "nope"], "problems": {"s": []}}"#;
    let f = MbmFile::parse(text, "t.json").expect("parses");
    match f.joint_vars(&twin_arms()) {
        Err(MbmError::UnknownJoint { joint, .. }) => assert_eq!(joint, "nope"),
        other => panic!("expected UnknownJoint, got {other:?}"),
    }
    let short = r#"{"robot": "r", "joints": ["a", "b"], "problems": {"s": [
        {"start": [0.0], "goals": [[0.0, 0.0]], "valid": true, "index": 3}]}}"#;
    assert!(matches!(
        MbmFile::parse(short, "t.json"),
        Err(MbmError::Problem { index: 3, .. })
    ));
    let bad_box = r#"{"robot": "r", "joints": ["a"], "problems": {"s": [
        {"start": [0.0], "goals": [[0.0]], "valid": true,
         "box": [{"name": "b", "half_extents": [0.1, -1, 0.1], "position": [0, 0, 0], "orientation_quat_xyzw": [0, 0, 0, 1]}]}]}}"#;
    assert!(matches!(
        MbmFile::parse(bad_box, "t.json"),
        Err(MbmError::Problem { .. })
    ));
    assert!(matches!(
        MbmFile::parse("{", "t.json"),
        Err(MbmError::Syntax { .. })
    ));
}

#[test]
fn one_panda_problem_per_set_is_solved_and_exactly_valid() {
    let Some(dir) = data_for_test() else { return };
    let file = MbmFile::load(&dir.join("panda/problems.json")).expect("panda problems");
    let robot = panda(&dir);
    let vars = file.joint_vars(&robot).expect("joints");
    let settings = RrtConnectSettings {
        angular_resolution: RES.to_radians(),
        ..RrtConnectSettings::default()
    };
    for set in &file.sets {
        let p = set
            .problems
            .iter()
            .find(|p| p.valid)
            .expect("a valid problem");
        let world = p.world(robot.clone());
        let space = p.space(&world, &vars).expect("space");
        let mut planner = RrtConnect::new(space, &world, settings).expect("planner");
        let r = plan_and_check_exactly(&mut planner, &world, &set.name, p, 7, RES.to_radians());
        assert!(r.stats.length_simplified <= r.stats.length_raw + 1e-9);
    }
}

#[test]
fn a_path_through_an_obstacle_is_invalid() {
    let Some(dir) = data_for_test() else { return };
    let file = MbmFile::load(&dir.join("panda/problems.json")).expect("panda problems");
    let robot = panda(&dir);
    let vars = file.joint_vars(&robot).expect("joints");
    let p = file
        .set("table_pick")
        .and_then(|s| s.problems.iter().find(|p| p.valid))
        .expect("problem");
    let world = p.world(robot.clone());
    let space = p.space(&world, &vars).expect("space");
    // Without the obstacles, to tell obstacle contacts from self-collisions.
    let bare = manyhands::collision::CollisionWorld::single(
        robot.clone(),
        manyhands::geometry::Pose::identity(),
    );
    let mut bare_v = SpaceValidator::new(
        space.clone(),
        &bare,
        ExactChecker::new(&bare),
        RES.to_radians(),
        0.005,
    );
    let mut ev = SpaceValidator::new(
        space.clone(),
        &world,
        ExactChecker::new(&world),
        RES.to_radians(),
        0.005,
    );
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let mut a = vec![0.0; 7];
    let mut b = vec![0.0; 7];
    // Two free configurations whose segment is free of self-collision but meets an obstacle.
    let found = (0..5000).any(|_| {
        space.sample_uniform(&mut rng, &mut a);
        space.sample_uniform(&mut rng, &mut b);
        for q in [&mut a, &mut b] {
            for v in q.iter_mut() {
                *v *= 0.5 + 0.5 * rng.random::<f64>();
            }
        }
        ev.is_state_valid(&a)
            && ev.is_state_valid(&b)
            && bare_v.validate_path(&[a.clone(), b.clone()]).is_ok()
            && !ev.is_motion_valid(&a, &b)
    });
    assert!(found, "no segment through an obstacle found");
    assert!(ev.checker().first_contact(&a).is_none() && ev.checker().first_contact(&b).is_none());
    let path = vec![a, b];
    assert_eq!(ev.validate_path(&path), Err(1));
    let mut fv = SpaceValidator::new(
        space,
        &world,
        FastChecker::new(&world),
        RES.to_radians(),
        0.005,
    );
    assert_eq!(fv.validate_path(&path), Err(1));
}

/// The benchmark's configuration: the 8-lane sphere checker (no padding), planning resolution
/// equal to the exact re-check's, no re-validation; every path must pass the exact check.
#[test]
fn sphere_checker_solves_two_panda_problems_per_set_exactly_valid() {
    use manyhands::collision::AutoChecker;
    let Some(dir) = data_for_test() else { return };
    let file = MbmFile::load(&dir.join("panda/problems.json")).expect("panda problems");
    let robot = panda(&dir);
    let vars = file.joint_vars(&robot).expect("joints");
    let res = 0.25f64.to_radians();
    let settings = RrtConnectSettings {
        angular_resolution: res,
        revalidate: false,
        ..RrtConnectSettings::default()
    };
    for set in &file.sets {
        for p in set.problems.iter().filter(|p| p.valid).take(2) {
            let world = p.world(robot.clone());
            let space = p.space(&world, &vars).expect("space");
            let checker = AutoChecker::new(&world, 0.0);
            assert_eq!(checker.kind(), "spheres");
            let mut planner =
                RrtConnect::with_checker(space, &world, checker, settings).expect("planner");
            plan_and_check_exactly(&mut planner, &world, &set.name, p, 11, res);
        }
    }
}

/// `bench mbm`'s default configuration: certified motion checks (4 cm), range and
/// dynamic-domain radius derived from the robot and space (`planning::base::range`), balanced trees.
/// Every path must pass the exact check at `check_deg`.
fn certified_bench_settings_solve(name: &str, per_set: usize, check_deg: f64) {
    let Some(dir) = data_for_test() else { return };
    let file = MbmFile::load(&dir.join(format!("{name}/problems.json"))).expect("problems");
    let robot = Arc::new(
        Robot::from_files(
            &dir.join(format!("{name}/{name}_spherized.urdf")),
            Some(&dir.join(format!("{name}/{name}.srdf"))),
        )
        .expect("robot"),
    );
    certified_settings_solve(&robot, &file, per_set, check_deg);
}

/// Every valid problem (at most `per_set` per set) of `file` solved with `bench mbm`'s default
/// settings and exactly valid at `check_deg`.
fn certified_settings_solve(robot: &Arc<Robot>, file: &MbmFile, per_set: usize, check_deg: f64) {
    use manyhands::collision::AutoChecker;
    let vars = file.joint_vars(robot).expect("joints");
    let p0 = &file.sets[0].problems[0];
    let world0 = p0.world(robot.clone());
    let derived = manyhands::planning::base::range::DerivedSettings::of(
        &world0,
        &p0.space(&world0, &vars).expect("space"),
    )
    .expect("derived settings");
    let settings = RrtConnectSettings {
        range: Some(derived.range),
        certify: Some(0.04),
        dynamic_domain: Some(derived.dynamic_domain),
        balance: true,
        revalidate: false,
        ..RrtConnectSettings::default()
    };
    for set in &file.sets {
        for p in set.problems.iter().filter(|p| p.valid).take(per_set) {
            let world = p.world(robot.clone());
            let space = p.space(&world, &vars).expect("space");
            let checker = AutoChecker::new(&world, 0.0);
            let mut planner =
                RrtConnect::with_checker(space, &world, checker, settings).expect("planner");
            let check = check_deg.to_radians();
            plan_and_check_exactly(&mut planner, &world, &set.name, p, 5, check);
        }
    }
}

#[test]
fn certified_planning_solves_panda_problems_exactly_valid_at_fine_resolution() {
    certified_bench_settings_solve("panda", 2, 0.05);
}

#[test]
fn certified_planning_solves_baxter_problems_exactly_valid() {
    certified_bench_settings_solve("baxter", 1, 0.25);
}

/// A problem file in the benchmark's form for `twin_arms`, written here: a table under the
/// arms, a post between them and a ball and a can in front, start `ready`. The goals are
/// drawn by the test (seeded): free configurations that the straight motion from the start
/// does not reach, so the planner has to go around.
const TWIN_PROBLEMS: &str = r#"{"robot": "twin_arms",
  "joints": ["left_joint1", "left_joint2", "left_joint3", "left_joint4", "left_joint5",
             "left_joint6", "left_joint7", "right_joint1", "right_joint2", "right_joint3",
             "right_joint4", "right_joint5", "right_joint6", "right_joint7"],
  "problems": {"table": [
    {"index": 1, "valid": true,
     "box": [{"name": "table", "half_extents": [0.3, 0.7, 0.02], "position": [0.65, 0.0, 0.35],
              "orientation_quat_xyzw": [0, 0, 0, 1]},
             {"name": "post", "half_extents": [0.04, 0.04, 0.3], "position": [0.45, 0.0, 0.7],
              "orientation_quat_xyzw": [0, 0, 0.3826834, 0.9238795]}],
     "sphere": [{"name": "ball", "radius": 0.06, "position": [0.55, 0.35, 0.45]}],
     "cylinder": [{"name": "can", "radius": 0.03, "length": 0.14, "position": [0.6, -0.35, 0.44],
                   "orientation_quat_xyzw": [0, 0, 0, 1]}],
     "start": [0, -0.785, 0, -2.356, 0, 1.571, 0.785, 0, -0.785, 0, -2.356, 0, 1.571, 0.785],
     "goals": [[0, -0.785, 0, -2.356, 0, 1.571, 0.785, 0, -0.785, 0, -2.356, 0, 1.571, 0.785]]}]}}"#;

#[test]
fn twin_arms_problem_is_solved_with_the_bench_settings_and_exactly_valid() {
    let mut file = MbmFile::parse(TWIN_PROBLEMS, "twin problems").expect("parses");
    let robot = twin_arms();
    let vars = file.joint_vars(&robot).expect("joints");
    let p = &mut file.sets[0].problems[0];
    let world = p.world(robot.clone());
    let space = p.space(&world, &vars).expect("space");
    let mut v = SpaceValidator::new(
        space.clone(),
        &world,
        ExactChecker::new(&world),
        RES.to_radians(),
        0.005,
    );
    assert_eq!(v.invalidity(&p.start), None, "start");
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let mut g = vec![0.0; vars.len()];
    p.goals.clear();
    while p.goals.len() < 3 {
        space.sample_uniform(&mut rng, &mut g);
        if v.is_state_valid(&g) && !v.is_motion_valid(&p.start, &g) {
            p.goals.push(g.clone());
        }
    }
    certified_settings_solve(&robot, &file, 1, 0.25);
}
