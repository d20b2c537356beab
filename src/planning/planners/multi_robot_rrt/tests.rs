//! Unit tests of Multi-Robot-RRT on the shipped kitchen_two scene.
use super::*;
use crate::model::load_robot_dir;
use crate::reachability::GridCache;

fn kitchen_two() -> Scene {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let lib = load_robot_dir(&root.join("robots")).expect("robots");
    Scene::from_file(&root.join("scenes/kitchen_two.json"), &lib).expect("scene")
}

/// Two Armar robots of kitchen_two side by side (a at world y -0.7, b at +0.7, both facing
/// +x) with a combination of grasps that passes the score, for collector checks of paths
/// built by hand: `base_x`/`base_y` move each base in its own frame.
struct Crossing {
    p: MultiRobotProblem,
    settings: MultiRobotSettings,
    bx: usize,
    by: usize,
    start_a: Vec<f64>,
    start_b: Vec<f64>,
    ga: (usize, usize),
    gb: (usize, usize),
}

impl Crossing {
    fn new() -> Crossing {
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
        Crossing {
            p,
            settings,
            bx,
            by,
            start_a,
            start_b,
            ga,
            gb,
        }
    }

    /// Robot a's start moved to (`x`, `y`) in its base frame (b's frame is a's shifted by
    /// +1.4 m in y).
    fn a_at(&self, x: f64, y: f64) -> Vec<f64> {
        let mut q = self.start_a.clone();
        q[self.bx] = x;
        q[self.by] = y;
        q
    }

    fn b_at(&self, x: f64, y: f64) -> Vec<f64> {
        let mut q = self.start_b.clone();
        q[self.bx] = x;
        q[self.by] = y;
        q
    }

    /// Offers a's path, then b's path, to a fresh collector: whether the combination was
    /// accepted, and the collector's statistics.
    fn offer(&self, path_a: Vec<Vec<f64>>, path_b: Vec<Vec<f64>>) -> (bool, MultiRobotStats) {
        let mut c = Collector::new(&self.p, &self.settings);
        let sol = |member, path, grasps| Solution {
            member,
            path,
            grasps,
            stats: PlanStats::default(),
        };
        assert!(c.add(sol(0, path_a, self.ga), &mut |_| {}).is_none());
        let r = c.add(sol(1, path_b, self.gb), &mut |_| {});
        (r.is_some(), c.stats.clone())
    }

    /// The combination is rejected by the deadlock check alone.
    fn assert_deadlock(&self, path_a: Vec<Vec<f64>>, path_b: Vec<Vec<f64>>, what: &str) {
        let (accepted, stats) = self.offer(path_a, path_b);
        assert!(!accepted, "{what}: a deadlocked combination was accepted");
        assert_eq!(stats.rejected_deadlock, 1, "{what}: {stats:?}");
        assert_eq!(stats.rejected_collision, 0, "{what}: {stats:?}");
        assert_eq!(stats.rejected_score, 0, "{what}: {stats:?}");
    }
}

/// A combination where robot b's trajectory drives through robot a's final configuration
/// is rejected by the deadlock check (002 eq. 2) although the final poses are free and the
/// score passes; without the check it would be accepted.
#[test]
fn crossing_trajectories_are_a_deadlock() {
    let x = Crossing::new();
    // Robot a drives to (world) x = -2.6 at its own y (-0.7); robot b (placed at y +0.7)
    // crosses that spot: base_y -1.4 in its frame is world y -0.7.
    let goal_a = x.a_at(2.0, 0.0);
    let via_b = x.b_at(2.0, -1.4);
    let goal_b = x.b_at(2.0, 0.6);
    x.assert_deadlock(
        vec![x.start_a.clone(), goal_a.clone()],
        vec![x.start_b.clone(), via_b, goal_b.clone()],
        "b through a's goal",
    );
    // The same goals reached without the crossing pass.
    let (accepted, stats) = x.offer(
        vec![x.start_a.clone(), goal_a],
        vec![x.start_b.clone(), goal_b],
    );
    assert!(accepted, "{stats:?}");
}

/// Eq. 2 holds both ways: here it is the *first* robot's trajectory that drives through the
/// second robot's final configuration (a check of a's start and goal against b's path alone
/// accepts it).
#[test]
fn the_first_robot_crossing_the_second_ones_goal_is_a_deadlock() {
    let x = Crossing::new();
    // a: along its lane to x = -2.6, over to b's lane (world y +0.7), back below its own.
    let path_a = vec![
        x.start_a.clone(),
        x.a_at(2.0, 0.0),
        x.a_at(2.0, 1.4),
        x.a_at(2.0, -0.6),
    ];
    // b: along its own lane to x = -2.6 and stops there.
    let path_b = vec![x.start_b.clone(), x.b_at(2.0, 0.0)];
    x.assert_deadlock(path_a, path_b, "a through b's goal");
    // Without the detour into b's lane, the same goals pass.
    let (accepted, stats) = x.offer(
        vec![x.start_a.clone(), x.a_at(2.0, 0.0), x.a_at(2.0, -0.6)],
        vec![x.start_b.clone(), x.b_at(2.0, 0.0)],
    );
    assert!(accepted, "{stats:?}");
}

/// Start configurations count as much as goals: b's trajectory visits the spot where a
/// *starts* (and returns) before driving to its goal, far from a's goal and path; checking
/// only the final configurations against the paths accepts it.
#[test]
fn a_trajectory_through_the_other_robots_start_is_a_deadlock() {
    let x = Crossing::new();
    let path_a = vec![x.start_a.clone(), x.a_at(2.0, 0.0)];
    let path_b = vec![
        x.start_b.clone(),
        x.b_at(0.0, -1.4),
        x.start_b.clone(),
        x.b_at(2.0, 0.6),
    ];
    x.assert_deadlock(path_a, path_b, "b through a's start");
}

/// The deadlock check follows the continuous motion between waypoints: b's first segment
/// runs diagonally from its start across a's lane, passing exactly through a's goal, while
/// every waypoint of b stays at least 2 m from a's start and goal (checking the waypoints
/// alone accepts it).
#[test]
fn a_segment_through_the_other_robots_goal_between_free_waypoints_is_a_deadlock() {
    let x = Crossing::new();
    let path_a = vec![x.start_a.clone(), x.a_at(2.0, 0.0)];
    // From (0, 0) to (4, -2.8) in b's frame: at x = 2 the segment is at y = -1.4, a's goal.
    let path_b = vec![x.start_b.clone(), x.b_at(4.0, -2.8), x.b_at(4.0, 0.6)];
    x.assert_deadlock(path_a, path_b, "b's segment through a's goal");
}
