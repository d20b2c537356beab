//! Unit tests of Multi-Robot-RRT on the shipped kitchen_two scene.
use super::*;
use crate::model::load_robot_dir;
use crate::reachability::GridCache;

fn kitchen_two() -> Scene {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let lib = load_robot_dir(&root.join("robots")).expect("robots");
    Scene::from_file(&root.join("scenes/kitchen_two.json"), &lib).expect("scene")
}

/// A combination where robot b's trajectory drives through robot a's final configuration
/// is rejected by the deadlock check (002 eq. 2) although the final poses are free and the
/// score passes; without the check it would be accepted.
#[test]
fn crossing_trajectories_are_a_deadlock() {
    let scene = kitchen_two();
    let names = vec!["armar_a".to_string(), "armar_b".to_string()];
    let cache = GridCache::new(None);
    let recipe = GridRecipe {
        samples: 100_000,
        ..GridRecipe::default()
    };
    let p = MultiRobotProblem::with_grids(
        &scene,
        &names,
        "torso_left_arm",
        "torso_right_arm",
        "table",
        &cache,
        recipe,
        BimanualSettings::default(),
    )
    .expect("problem");
    let settings = MultiRobotSettings::default();
    let model = &p.world.robots[0].robot;
    let bx = model.var("base_x").expect("base_x");
    let by = model.var("base_y").expect("base_y");
    let start_a = p
        .world
        .robot_config(p.members[0].robot, &p.world_q)
        .to_vec();
    let start_b = p
        .world
        .robot_config(p.members[1].robot, &p.world_q)
        .to_vec();
    // Robot a drives to (world) x = -2.6 at its own y (-0.7); robot b (placed at y +0.7)
    // crosses that spot: base_y -1.4 in its frame is world y -0.7.
    let mut goal_a = start_a.clone();
    goal_a[bx] = 2.0;
    let mut via_b = start_b.clone();
    via_b[bx] = 2.0;
    via_b[by] = -1.4;
    let mut goal_b = start_b.clone();
    goal_b[bx] = 2.0;
    goal_b[by] = 0.6;
    let sol = |member, path: Vec<Vec<f64>>, grasps| Solution {
        member,
        path,
        grasps,
        stats: PlanStats::default(),
    };
    // Grasps of a force-closure combination: the left and right grasps the names say.
    let find = |m: &MultiRobotMember, l: &str, r: &str| {
        (
            m.problem
                .left_names
                .iter()
                .position(|n| n == l)
                .expect("left"),
            m.problem
                .right_names
                .iter()
                .position(|n| n == r)
                .expect("right"),
        )
    };
    let ga = find(&p.members[0], "table_l_04", "table_r_08");
    let gb = find(&p.members[1], "table_l_23", "table_r_18");
    assert!(
        p.score(&[ga, gb], &settings.wrench)
            .expect("score")
            .force_closure
    );
    let mut c = Collector::new(&p, &settings);
    assert!(c
        .add(
            sol(0, vec![start_a.clone(), goal_a.clone()], ga),
            &mut |_| {}
        )
        .is_none());
    let r = c.add(
        sol(1, vec![start_b.clone(), via_b, goal_b.clone()], gb),
        &mut |_| {},
    );
    assert!(r.is_none(), "a deadlocked combination was accepted");
    assert_eq!(c.stats.rejected_deadlock, 1, "{:?}", c.stats);
    assert_eq!(c.stats.rejected_collision, 0);
    // The same goals reached without the crossing pass.
    let r = c.add(sol(1, vec![start_b, goal_b], gb), &mut |_| {});
    assert!(r.is_some(), "{:?}", c.stats);
}
