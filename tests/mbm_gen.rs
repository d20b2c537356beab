//! MotionBenchMaker-like problems for a robot of this project's own (`tests/robots/arm6.urdf`, a
//! 6-DoF arm; issue 28 item 3): the generator's file reads back as a benchmark file, its
//! problems are well posed (start and goal free under the exact checker, the straight motion
//! between them in collision), the same seed gives the same file, and the valid problems are
//! solved by RRT-Connect with paths free under the exact checker. No `../shared` needed.

mod common;

use std::sync::Arc;
use std::time::Duration;

use manyhands::benchmark::mbm::MbmFile;
use manyhands::benchmark::mbm_gen::{generate, solve_settings, GenSettings, SETS};
use manyhands::collision::{AutoChecker, ExactChecker};
use manyhands::geometry::{Pose, Shape};
use manyhands::kinematics::forward;
use manyhands::planning::{RrtConnect, SpaceValidator, Termination};
use manyhands::Robot;
use nalgebra::Vector3;

fn arm6() -> Arc<Robot> {
    let dir = common::root().join("tests/robots");
    Arc::new(Robot::from_files(&dir.join("arm6.urdf"), Some(&dir.join("arm6.srdf"))).expect("arm6"))
}

fn settings() -> GenSettings {
    GenSettings {
        per_set: 3,
        seed: 5,
        solve_iterations: 5_000,
    }
}

#[test]
fn generated_problems_are_well_posed_deterministic_and_solvable() {
    let robot = arm6();
    let (value, stats) = generate(robot.clone(), &[], &settings()).expect("generate");
    assert_eq!(stats.problems, 3 * SETS.len());
    let (again, _) = generate(robot.clone(), &[], &settings()).expect("generate again");
    assert_eq!(value, again, "same seed, same file");
    let (other, _) = generate(
        robot.clone(),
        &[],
        &GenSettings {
            seed: 6,
            ..settings()
        },
    )
    .expect("generate, other seed");
    assert_ne!(value["problems"], other["problems"], "the seed matters");

    let file = MbmFile::parse(&value.to_string(), "generated").expect("reads back");
    assert!(file.generated);
    assert_eq!(file.joints.len(), 6);
    let vars = file.joint_vars(&robot).expect("joints");
    let names: Vec<&str> = file.sets.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, SETS);
    assert!(SETS.contains(&"box"), "the bin scenes are a set");
    let tip_name = value["generator"]["tip_link"].as_str().expect("tip link");
    let tip = robot
        .links
        .iter()
        .position(|l| l.name == tip_name)
        .expect("tip link of the robot");
    let mut solved = 0;
    for p in file.sets.iter().flat_map(|s| &s.problems) {
        assert!(!p.obstacles.is_empty());
        let world = p.world(robot.clone());
        let space = p.space(&world, &vars).expect("space");
        let mut exact = SpaceValidator::new(
            space.clone(),
            &world,
            ExactChecker::new(&world),
            0.25f64.to_radians(),
            0.005,
        );
        let goal = &p.goals[0];
        if p.set == "box" {
            // The goal's tip reaches down into the open bin: below its walls' top, within them.
            let walls: Vec<_> = p
                .obstacles
                .iter()
                .filter(|o| o.name.starts_with("bin_"))
                .collect();
            assert_eq!(walls.len(), 4, "box[{}]: four bin walls", p.index);
            let centre = walls
                .iter()
                .fold(Vector3::zeros(), |c, o| c + o.pose.translation.vector)
                / 4.0;
            let top = walls
                .iter()
                .map(|o| match o.shape {
                    Shape::Box { half_extents } => o.pose.translation.z + half_extents.z,
                    _ => f64::NAN,
                })
                .fold(f64::NEG_INFINITY, f64::max);
            // Two walls at half the bin's length from its centre, two at half its width.
            let d: Vec<f64> = walls
                .iter()
                .map(|o| (o.pose.translation.vector - centre).xy().norm())
                .collect();
            let (near, far) = d
                .iter()
                .fold((f64::INFINITY, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
            let half_diagonal = near.hypot(far);
            let mut poses = vec![Pose::identity(); robot.links.len()];
            forward(&robot, &Pose::identity(), &space.to_world(goal), &mut poses);
            let tip = poses[tip].translation.vector;
            assert!(tip.z < top, "box[{}]: goal tip above the bin", p.index);
            assert!(
                (tip - centre).xy().norm() < half_diagonal,
                "box[{}]: goal tip outside the bin",
                p.index
            );
        }
        assert!(
            exact.is_state_valid(&p.start),
            "{}[{}] start",
            p.set,
            p.index
        );
        assert!(exact.is_state_valid(goal), "{}[{}] goal", p.set, p.index);
        assert!(
            !exact.is_motion_valid(&p.start, goal),
            "{}[{}]: the straight motion is free (a trivial problem)",
            p.set,
            p.index
        );
        if !p.valid {
            continue;
        }
        let mut planner = RrtConnect::with_checker(
            space.clone(),
            &world,
            AutoChecker::new(&world, 0.0),
            solve_settings(&world, &space),
        )
        .expect("planner");
        let mut term = Termination::new().with_time_limit(Duration::from_secs(20));
        let r = planner
            .plan(&p.start, &p.goals, &mut term, 11)
            .unwrap_or_else(|e| panic!("{}[{}] marked valid, not solved: {e}", p.set, p.index));
        common::assert_exactly_free(&world, &space, &r.path);
        solved += 1;
    }
    assert!(
        solved >= SETS.len(),
        "only {solved} of {} generated problems are valid",
        stats.problems
    );
}
